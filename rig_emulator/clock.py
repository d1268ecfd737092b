"""Pacing of simulated time against an absolute monotonic clock (no asyncio here).

Real-time mode: tick k is due at ``start + k * period`` of the monotonic clock, never "sleep
the period again" (which would accumulate every delay); at each tick the simulation is
brought to ``sim_anchor + speed * (deadline - wall_anchor)``. A change of speed re-anchors.
A tick that begins a whole period or more after its deadline (the process was stopped, the
machine overloaded) simulates what its deadline asked for and no more: the schedule restarts
at the tick and the simulated clock gives the time in between up, reported as overrun, so no
later tick chases it (a stranger's probe: a server stopped for 2 s ran 190 s of simulation
in one tick and published x335690 for a requested x100, with no overrun).
Lockstep mode: time only moves when a client asks (``lockstep_advance``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

REALTIME = 0
LOCKSTEP = 1


@dataclass(slots=True)
class SimClock:
    """Maps wall time to simulated time in real-time mode, or holds it in lockstep.

    Attributes:
        speed: simulated seconds per wall second.
        mode: REALTIME or LOCKSTEP.
    """

    speed: float
    mode: int
    wall_anchor_s: float = 0.0
    sim_anchor_s: float = 0.0

    def anchor(self, wall_s: float, sim_s: float) -> None:
        """Re-anchor (at start, after a speed or mode change, after a reset)."""
        self.wall_anchor_s = wall_s
        self.sim_anchor_s = sim_s

    def target(self, wall_s: float) -> float:
        """Simulated time due at wall time ``wall_s`` (real-time mode)."""
        return self.sim_anchor_s + self.speed * (wall_s - self.wall_anchor_s)

    def drop(self, wall_s: float) -> None:
        """Give up ``wall_s`` seconds of the schedule: every later target comes that much
        wall time later, so the simulation a stall or an overrun missed is never chased."""
        self.wall_anchor_s += wall_s


@dataclass(slots=True)
class Tick:
    """One real-time tick: what :meth:`RealTimeTicks.begin` found and asks it to simulate,
    then, after :meth:`RealTimeTicks.finish`, what it fell short by.

    Attributes:
        began_s: loop time the tick began [s].
        lateness_s: how long after its deadline it began [s].
        dropped_s: schedule given up because it began a whole period late [s of wall time].
        due_s: simulated time the tick is to advance [s].
        speed: the requested speed when it began.
        overrun_ms: schedule given up in all (``dropped_s`` and what the physics could not
            do in its budget) [ms of wall time].
        achieved_speed: simulated seconds per wall second of the schedule the tick covered.
    """

    began_s: float
    lateness_s: float
    dropped_s: float
    due_s: float
    speed: float
    overrun_ms: float = 0.0
    achieved_speed: float = 0.0


@dataclass(slots=True)
class RealTimeTicks:
    """The real-time tick's absolute schedule and what each tick is to simulate.

    A tick a little late (under a period) simulates what its deadline asked for and the
    next one, due a period after that deadline, makes the lateness up. A tick a whole period
    late or more restarts the schedule at itself and drops the time since its deadline from
    ``clock``: it does one tick's work, not the stall's. The achieved speed is the share of
    the schedule simulated, so a catch-up never reports more than the requested speed.

    Attributes:
        clock: the simulated clock the ticks serve.
        period_s: tick period [s of wall time].
        start_s: loop time of tick 0 [s].
        index: number of the tick whose deadline was last given out.
    """

    clock: SimClock
    period_s: float
    start_s: float
    index: int = 0

    def next_deadline(self) -> float:
        """Deadline of the next tick, on the absolute schedule (in the past if it is late)."""
        self.index += 1
        return self._deadline()

    def _deadline(self) -> float:
        return self.start_s + self.index * self.period_s

    def begin(self, now_s: float, sim_s: float) -> Tick:
        """The tick whose deadline was last given out begins at ``now_s``, the simulation
        being at ``sim_s``; a whole period late, the schedule restarts here and the clock
        drops the lateness, in any mode (a stopped lockstep server does not burst idle
        ticks when it resumes either)."""
        deadline_s = self._deadline()
        lateness_s = max(now_s - deadline_s, 0.0)
        dropped_s = 0.0
        if lateness_s >= self.period_s:
            dropped_s = lateness_s
            self.start_s, self.index = now_s, 0
            self.clock.drop(dropped_s)
        due_s = self.clock.target(deadline_s + dropped_s) - sim_s
        return Tick(now_s, lateness_s, dropped_s, due_s, self.clock.speed)

    def finish(self, tick: Tick, missing_sim_s: float) -> None:
        """``tick`` simulated its due less ``missing_sim_s`` (its budget ran out): drop that
        too, and set its overrun and achieved speed."""
        if missing_sim_s > 0.0:
            self.clock.drop(missing_sim_s / tick.speed)
        scheduled_sim_s = max(tick.due_s, 0.0)
        tick.overrun_ms = (tick.dropped_s + missing_sim_s / tick.speed) * 1000.0
        covered_wall_s = scheduled_sim_s / tick.speed + tick.dropped_s
        tick.achieved_speed = (
            (scheduled_sim_s - missing_sim_s) / covered_wall_s
            if covered_wall_s > 0.0
            else tick.speed  # nothing was due: a tick right after a re-anchor
        )


@dataclass(slots=True)
class LatenessStats:
    """The last ``size`` tick latenesses [s], with percentiles for benchmarks."""

    size: int = 100_000
    samples: deque[float] = field(default_factory=deque)
    last_s: float = 0.0

    def add(self, lateness_s: float) -> None:
        self.last_s = lateness_s
        self.samples.append(lateness_s)
        if len(self.samples) > self.size:
            self.samples.popleft()

    def summary_ms(self) -> dict[str, float]:
        """p50, p99 and max lateness [ms] and the number of ticks."""
        if not self.samples:
            return {"ticks": 0, "p50_ms": math.nan, "p99_ms": math.nan, "max_ms": math.nan}
        data = np.array(self.samples) * 1000.0
        return {
            "ticks": float(len(data)),
            "p50_ms": float(np.percentile(data, 50)),
            "p99_ms": float(np.percentile(data, 99)),
            "max_ms": float(data.max()),
        }
