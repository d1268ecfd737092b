"""Pacing of simulated time against an absolute monotonic clock (no asyncio here).

Real-time mode: tick k is due at ``start + k * period`` of the monotonic clock, never "sleep
the period again" (which would accumulate every delay); at each tick the simulation is
brought to ``sim_anchor + speed * (deadline - wall_anchor)``. A change of speed re-anchors.
A tick that is more than a whole period late skips the missed deadlines instead of bursting.
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
class Pacer:
    """Deadlines of a periodic tick on an absolute clock.

    Attributes:
        period_s: tick period [s of wall time].
        start_s: monotonic time of tick 0 [s].
    """

    period_s: float
    start_s: float
    index: int = 0

    def next_deadline(self, now_s: float) -> float:
        """Deadline of the next tick; skips deadlines already a whole period in the past."""
        self.index += 1
        behind = math.floor((now_s - self.start_s) / self.period_s)
        if behind > self.index:
            self.index = behind
        return self.start_s + self.index * self.period_s


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
