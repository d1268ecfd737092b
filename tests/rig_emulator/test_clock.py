"""Pacing on an absolute clock, and the real-time and lockstep modes over Modbus."""

from __future__ import annotations

import time

import pytest

from rig_emulator.clock import Pacer, SimClock
from tests.modbus_helpers import ADVANCE, client, write


def test_pacer_deadlines_do_not_accumulate_delays():
    pacer = Pacer(period_s=0.1, start_s=100.0)
    # a tick that runs late does not shift the following deadlines
    assert pacer.next_deadline(100.0) == pytest.approx(100.1)
    assert pacer.next_deadline(100.17) == pytest.approx(100.2)
    assert pacer.next_deadline(100.2) == pytest.approx(100.3)
    # more than a whole period behind: the missed deadlines are skipped, not burst; the
    # latest one (100.9, 0.05 s ago) is served now
    assert pacer.next_deadline(100.95) == pytest.approx(100.9)
    assert pacer.next_deadline(100.96) == pytest.approx(101.0)


def test_sim_clock_maps_wall_to_sim_time():
    clock = SimClock(speed=60.0, mode=0)
    clock.anchor(wall_s=10.0, sim_s=500.0)
    assert clock.target(12.5) == pytest.approx(650.0)


def test_real_time_mode_advances_with_the_wall_clock(serve):
    srv = serve(lockstep=False, speed=200.0, allow_control=True)
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
