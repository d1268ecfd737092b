"""Pacing on an absolute clock, and the real-time and lockstep modes over Modbus."""

from __future__ import annotations

import time

import numpy as np
import pytest

from rig_emulator.clock import REALTIME, RealTimeTicks, SimClock
from tests.modbus_helpers import ADVANCE, client, write


def test_sim_clock_maps_wall_to_sim_time():
    clock = SimClock(speed=60.0, mode=0)
    clock.anchor(wall_s=10.0, sim_s=500.0)
    assert clock.target(12.5) == pytest.approx(650.0)


def _ticks(speed: float = 100.0) -> RealTimeTicks:
    """Ticks of 0.1 s from loop time 0, the simulation anchored at 0 there."""
    clock = SimClock(speed=speed, mode=REALTIME)
    clock.anchor(wall_s=0.0, sim_s=0.0)
    return RealTimeTicks(clock, period_s=0.1, start_s=0.0)


def test_ticks_make_up_a_lateness_under_a_period():
    """The absolute schedule: a tick a little late does its deadline's work and the next
    one keeps its place, so small delays never accumulate and nothing is dropped."""
    ticks = _ticks()
    assert ticks.next_deadline() == pytest.approx(0.1)
    tick = ticks.begin(0.17, sim_s=0.0)  # 70 ms late: simulates what 0.1 s asked for
    assert (tick.lateness_s, tick.dropped_s, tick.due_s) == pytest.approx((0.07, 0.0, 10.0))
    ticks.finish(tick, missing_sim_s=0.0)
    assert (tick.overrun_ms, tick.achieved_speed) == (0.0, 100.0)
    # the next deadline keeps its place on the absolute schedule
    assert ticks.next_deadline() == pytest.approx(0.2)
    assert ticks.begin(0.2, sim_s=10.0).due_s == pytest.approx(10.0)


def test_a_tick_a_whole_period_late_does_one_ticks_work_and_restarts_the_schedule():
    """A stranger's probe: a server stopped for 2 s simulated the stall's 190 s in one tick
    after the resume and published x335690 for x100, with no overrun."""
    ticks = _ticks()
    ticks.next_deadline()
    ticks.finish(ticks.begin(0.1, sim_s=0.0), missing_sim_s=0.0)
    assert ticks.next_deadline() == pytest.approx(0.2)
    stall = ticks.begin(2.2, sim_s=10.0)  # the process was stopped for 2 s
    assert (stall.lateness_s, stall.dropped_s) == pytest.approx((2.0, 2.0))
    assert stall.due_s == pytest.approx(10.0)  # one period at x100, not 210 s
    ticks.finish(stall, missing_sim_s=0.0)
    assert stall.overrun_ms == pytest.approx(2000.0)
    assert stall.achieved_speed == pytest.approx(10.0 / 2.1)  # 10 s over 0.1 + 2 s of wall
    # re-anchored: the next tick is a period after this one, with a period's work
    assert ticks.next_deadline() == pytest.approx(2.3)
    assert ticks.begin(2.3, sim_s=20.0).due_s == pytest.approx(10.0)
    # an overloaded machine: the previous tick's work ran 1.5 periods past this deadline
    assert ticks.next_deadline() == pytest.approx(2.4)
    overloaded = ticks.begin(2.55, sim_s=30.0)
    assert (overloaded.dropped_s, overloaded.due_s) == pytest.approx((0.15, 10.0))
    assert ticks.next_deadline() == pytest.approx(2.65)


def test_physics_over_its_budget_is_dropped_not_chased():
    """What the physics could not do in its budget is dropped from the clock and reported
    as overrun; the next tick does one period's work, not that plus the rest."""
    ticks = _ticks()
    ticks.next_deadline()
    tick = ticks.begin(0.1, sim_s=0.0)
    ticks.finish(tick, missing_sim_s=4.0)  # the budget ran out 4 simulated seconds short
    assert (tick.overrun_ms, tick.achieved_speed) == pytest.approx((40.0, 60.0))
    ticks.next_deadline()
    assert ticks.begin(0.2, sim_s=6.0).due_s == pytest.approx(10.0)  # not 14


@pytest.mark.parametrize("seed", range(20))
def test_no_burst_of_ticks_runs_the_clock_ahead(seed: int):
    """The guarantee the SIGSTOP test reads over the wire: whatever the delays (a tick's
    wake-up a little or whole periods late, work up to its budget, physics cut short),
    simulated time published at wall times a <= b moves at most ``speed * (b - a + 2
    periods)``, and never ahead of the requested speed's schedule. Driven as the server's
    tick loop drives it: sleep to the deadline (or not at all when late), begin, work,
    finish, publish."""
    rng = np.random.default_rng(seed)
    speed, period_s = 100.0, 0.1
    ticks = _ticks(speed)
    now_s, sim_s = 0.0, 0.0
    published: list[tuple[float, float]] = [(0.0, 0.0)]  # (wall time, simulated time)
    for _ in range(400):
        deadline_s = ticks.next_deadline()
        delay_s = rng.choice(
            [0.0, rng.uniform(0, period_s), rng.uniform(period_s, 3.0)], p=[0.6, 0.35, 0.05]
        )
        now_s = max(now_s, deadline_s) + delay_s
        tick = ticks.begin(now_s, sim_s)
        missing_s = max(tick.due_s, 0.0) * rng.choice([0.0, rng.uniform(0, 1)], p=[0.8, 0.2])
        sim_s += max(tick.due_s, 0.0) - missing_s
        now_s += rng.uniform(0, 0.4 * period_s)  # the physics, in its budget
        ticks.finish(tick, missing_s)
        assert tick.achieved_speed <= speed * (1 + 1e-9)
        published.append((now_s, sim_s))
    wall = np.array([w for w, _ in published])
    sim = np.array([s for _, s in published])
    assert np.all(np.diff(sim) >= 0)
    # every pair (a, b): sim[b] - sim[a] <= speed * (wall[b] - wall[a] + 2 periods)
    # (the floating point sum of 400 ticks: 1e-9 relative)
    excess = (sim[None, :] - sim[:, None]) - speed * (wall[None, :] - wall[:, None] + 2 * period_s)
    upper = np.triu(np.ones_like(excess, dtype=bool))
    assert excess[upper].max() <= 1e-9 * sim[-1]


def test_real_time_mode_advances_with_the_wall_clock(serve):
    srv = serve(lockstep=False, speed=200.0, allow_control=True)
    deadline = time.monotonic() + 60  # generous: the first ticks wait for numba's compiler
    while srv.values()["sim_time_s"] == 0.0 and time.monotonic() < deadline:
        time.sleep(0.05)  # the kernels still load (a cold cache): the clock stands
    t0, s0 = time.monotonic(), srv.values()["sim_time_s"]
    time.sleep(1.0)
    t1, s1 = time.monotonic(), srv.values()["sim_time_s"]
    # functional check with a wide margin (the machine is shared): about speed x wall time
    assert 0.5 * 200 * (t1 - t0) < s1 - s0 < 1.5 * 200 * (t1 - t0) + 40
    c = client(srv.port)
    r = write(c, srv, *ADVANCE, 10)
    assert r.isError() and r.exception_code == 3  # no lockstep advance in real-time mode
    c.close()


def test_switch_to_lockstep_and_reset_over_modbus(serve):
    srv = serve(lockstep=False, speed=100.0, allow_control=True)
    c = client(srv.port)
    assert not write(c, srv, "sim_control", "clock_mode", 1).isError()
    frozen = srv.values()["sim_time_s"]
    time.sleep(0.3)
    assert srv.values()["sim_time_s"] == frozen
    assert not write(c, srv, *ADVANCE, 60).isError()
    assert srv.values()["sim_time_s"] == pytest.approx(frozen + 60)
    assert srv.values()["lockstep_counter"] == 1
    assert not write(c, srv, "sim_control", "reset", 1).isError()
    assert srv.values()["sim_time_s"] == 0.0
    c.close()
