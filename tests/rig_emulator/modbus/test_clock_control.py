"""The clock cannot be wedged and the simulation control is guarded (issue 11), over real
sockets on 127.0.0.1."""

from __future__ import annotations

import signal
import struct
import subprocess
import threading
import time

from hil_client.demo import rig_emulator_serve
from rig_emulator.emulator import Emulator
from rig_emulator.instruments import load_profile
from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, client, point, read_point, start_boiler, write
from tests.rig_emulator.modbus.raw import ask, write_registers_pdu


def test_speed_100000_with_lab_profile_answers_reads_and_stops_on_sigterm():
    """The wedge of issue 11: before the fix this server answered nothing and ignored SIGTERM."""
    with rig_emulator_serve(
        "windhager_12kw", "--profile", "lab", "--speed", "100000", stderr=subprocess.PIPE
    ) as (port, proc):
        from rig_emulator.registers import load_map

        register_map = load_map()
        dev = register_map.device("sim_control")
        sim_time = next(p for p in dev.points if p.name == "sim_time")
        achieved = next(p for p in dev.points if p.name == "achieved_speed")
        c = client(port)
        first = read_point(c, dev, sim_time)
        speed = 0.0
        deadline = time.monotonic() + 60  # generous: the first ticks wait for numba's compiler
        while speed == 0.0 and time.monotonic() < deadline:
            time.sleep(0.2)
            speed = read_point(c, dev, achieved)
        second = read_point(c, dev, sim_time)
        c.close()
        assert second > first  # time moves and reads are answered
        assert 0 < speed < 100_000  # published: the lab profile cannot reach x100000 here
        proc.send_signal(signal.SIGTERM)
        # a bound, not a target: the tick yields every period, so SIGTERM is served at once
        # on a quiet machine; a wedged server (issue 11) never exits at all
        code = proc.wait(timeout=90)
        stderr = proc.stderr.read().decode()
    assert code == 0, stderr
    assert "Traceback" not in stderr


def test_one_day_advance_lets_other_clients_in(serve):
    """Another client's reads are answered while a 86,400 s advance runs (ordering only)."""
    srv = serve(profile="lab")
    dev, sim_time = point(srv, "sim_control", "sim_time")
    # a generous bound, not a timing target: on a loaded shared machine the lab profile's
    # one-day advance takes several seconds (1.6 s on a quiet one, issue 11)
    advancer = client(srv.port, timeout_s=120)
    reader = client(srv.port)
    done = threading.Event()
    result = {}

    def advance_one_day() -> None:
        result["reply"] = write(advancer, srv, *ADVANCE, 86_400)
        done.set()

    thread = threading.Thread(target=advance_one_day)
    thread.start()
    # wait until the advance is under way (its simulation is no longer at 0)
    deadline = time.monotonic() + 30
    while srv.server.emulator.sim_time_s == 0 and time.monotonic() < deadline:
        time.sleep(0.001)
    answered_during = 0
    while not done.is_set() and answered_during < 5:
        before = read_point(reader, dev, sim_time)
        if not done.is_set():
            assert before == 0.0  # registers keep the old state until the advance is done
            answered_during += 1
    thread.join(timeout=60)
    assert not result["reply"].isError()
    assert answered_during > 0, "no read was answered while the one-day advance ran"
    assert read_point(reader, dev, sim_time) == 86_400.0
    advancer.close()
    reader.close()


def _registers(c, srv, name: str) -> list[int]:
    dev, p = point(srv, "sim_control", name)
    r = c.read_holding_registers(p.address, count=p.width, device_id=dev.unit_id)
    assert not r.isError()
    return r.registers


def test_control_guard(serve, caplog):
    realtime = serve(lockstep=False)
    c = client(realtime.port)
    for _ in range(20):  # a flood of refusals is logged once
        assert write(c, realtime, "sim_control", "speed_factor", 3.0).exception_code == 1
    logged = [r for r in caplog.records if "refused a write of speed_factor" in r.getMessage()]
    assert len(logged) == 1
    for name, value in (
        ("speed_factor", 10.0),
        ("clock_mode", 1),
        ("reset", 1),
        ("lockstep_advance", 60),
    ):
        before = _registers(c, realtime, name)
        reply = write(c, realtime, "sim_control", name, value)
        assert reply.isError() and reply.exception_code == 1, (name, reply)
        assert _registers(c, realtime, name) == before, name
    assert realtime.server.clock.speed == 1.0 and realtime.server.clock.mode == 0
    c.close()
    # one line for one write of several commands (a fault block's wrote six: a re-probe)
    fresh = serve(lockstep=False)
    c = client(fresh.port)
    caplog.clear()
    words = [*encode(point(fresh, "sim_control", "speed_factor")[1], 2.0), 1]  # + clock_mode
    reply = c.write_registers(0, words, device_id=100)
    assert reply.isError() and reply.exception_code == 1
    refused = [r.getMessage() for r in caplog.records if "refused a write of" in r.getMessage()]
    assert len(refused) == 1 and "clock_mode, speed_factor" in refused[0], refused
    c.close()

    allowed = serve(lockstep=False, allow_control=True)
    c = client(allowed.port)
    assert not write(c, allowed, "sim_control", "speed_factor", 10.0).isError()
    assert allowed.server.clock.speed == 10.0
    assert not write(c, allowed, "sim_control", "clock_mode", 1).isError()
    assert not write(c, allowed, *ADVANCE, 60).isError()
    c.close()

    lockstep = serve()
    c = client(lockstep.port)
    assert not write(c, lockstep, *ADVANCE, 60).isError()
    assert not write(c, lockstep, "sim_control", "speed_factor", 5.0).isError()
    assert not write(c, lockstep, "sim_control", "reset", 1).isError()
    assert lockstep.server.emulator.sim_time_s == 0.0
    c.close()


def test_a_lockstep_server_switched_to_real_time_can_be_switched_back(serve):
    """A stranger's probe: one write of clock_mode = 0 to a lockstep server made it refuse
    every clock and fault command after (exception 01, "real time without
    --allow-control"), so nothing could bring it back, nor clear a fault set before. A
    server started in lockstep keeps its clients' right to the clock."""
    srv = serve()
    c = client(srv.port)
    assert not write(c, srv, "sim_control", "clock_mode", 0).isError()
    assert srv.server.clock.mode == 0
    assert not write(c, srv, "sim_control", "speed_factor", 2.0).isError()
    assert not write(c, srv, "sim_control", "clock_mode", 1).isError()
    assert srv.server.clock.mode == 1
    time_before = srv.server.emulator.sim_time_s
    assert not write(c, srv, *ADVANCE, 60).isError()
    assert srv.server.emulator.sim_time_s == time_before + 60.0
    c.close()


def _advance_a_day_while_another_client_writes(srv, during: bool) -> dict[str, float] | None:
    """Client A advances a day; client B writes the flow setpoint while the advance runs
    (``during``) or after it. The state read at the end, and the simulated time B's write
    was answered at; None where the advance ended before B could write (a loaded machine
    did not schedule B's thread during the 1-s advance: nothing is tested)."""
    a, b = client(srv.port, timeout_s=120), client(srv.port, timeout_s=120)
    start_boiler(a, srv, seconds=600)
    done = threading.Event()

    def advance() -> None:
        assert not write(a, srv, *ADVANCE, 86_400).isError()
        done.set()

    thread = threading.Thread(target=advance)
    thread.start()
    if during:  # once the advance is under way
        deadline = time.monotonic() + 30
        while srv.server.emulator.sim_time_s <= 600 and time.monotonic() < deadline:
            time.sleep(0.001)
        if done.is_set():
            thread.join(timeout=120)
            a.close()
            b.close()
            return None
    else:
        done.wait(timeout=120)
    assert not write(b, srv, "bench_plc", "flow_setpoint", 300.0).isError()
    answered_at = srv.server.emulator.sim_time_s
    thread.join(timeout=120)
    assert not write(a, srv, *ADVANCE, 3600).isError()
    state = {
        name: read_point(a, *point(srv, device, name))
        for device, name in (("bench_plc", "boiler_water_temp"), ("balance", "mass"))
    }
    a.close()
    b.close()
    return {"answered_at_s": answered_at, **state}


def test_another_clients_write_lands_after_an_advance_not_inside_it(serve):
    """A stranger's probe: B's setpoint, written 50 ms into A's one-day advance, landed
    inside it at a simulated time the machine's load chose (three runs of the same
    sequence: 202.25, 200.87 and 200.07 kg). A write waits for the advance under way and
    lands after it: the same as writing once the advance is done, to the last bit."""
    for _ in range(3):  # each on a fresh server, until B's write comes during the advance
        during = _advance_a_day_while_another_client_writes(serve(), during=True)
        if during is not None:
            break
    assert during is not None, "the advance ended before the write three times: nothing tested"
    after = _advance_a_day_while_another_client_writes(serve(), during=False)
    assert during["answered_at_s"] == 600.0 + 86_400.0
    assert during == after


def test_the_documented_ends_of_a_float_range_can_be_written(serve):
    """A stranger's probe: the speed's documented minimum, 0.01, was refused (exception 03):
    the float32 a client's encoder sends for it is 0.0099999998, below 0.01. A float within
    its type's rounding of a bound is that bound; one step of float32 further is refused."""
    srv = serve()
    dev, speed = point(srv, "sim_control", "speed_factor")
    c = client(srv.port)
    nearest = struct.unpack(">f", struct.pack(">f", 0.01))[0]
    assert nearest < 0.01  # the premise: float32 has no 0.01
    registers = list(struct.unpack(">HH", struct.pack(">f", 0.01)))
    assert not c.write_registers(speed.address, registers, device_id=dev.unit_id).isError()
    assert srv.server.clock.speed == 0.01
    below = struct.pack(">I", struct.unpack(">I", struct.pack(">f", 0.01))[0] - 1)
    reply = c.write_registers(speed.address, list(struct.unpack(">HH", below)), device_id=100)
    assert reply.isError() and reply.exception_code == 3
    assert srv.server.clock.speed == 0.01
    # a bound the type carries exactly is met exactly: the float64 fault_at's 0 (a re-probe:
    # -1e-300 was taken as 0)
    dev, at = point(srv, "sim_control", "fault_at")
    words = list(struct.unpack(">HHHH", struct.pack(">d", -1e-300)))
    reply = c.write_registers(at.address, words, device_id=dev.unit_id)
    assert reply.isError() and reply.exception_code == 3
    c.close()


def test_allow_control_option_of_serve():
    """``serve --allow-control`` lets a client change the speed of a real-time server."""
    from rig_emulator.registers import load_map

    dev = load_map().device("sim_control")
    speed = next(p for p in dev.points if p.name == "speed_factor")
    with rig_emulator_serve("windhager_12kw", "--allow-control") as (port, _):
        c = client(port)
        assert not c.write_registers(speed.address, encode(speed, 7.0), device_id=100).isError()
        assert read_point(c, dev, speed) == 7.0
        c.close()
    with rig_emulator_serve("windhager_12kw") as (port, _):
        c = client(port)
        reply = c.write_registers(speed.address, encode(speed, 7.0), device_id=100)
        assert reply.isError() and reply.exception_code == 1
        assert read_point(c, dev, speed) == 1.0
        c.close()


class _SlowKernels(Emulator):
    """An emulator whose kernels take 3 s to load, as a cold numba cache does (tens of
    seconds on a fresh machine)."""

    def compile_kernels(self) -> None:
        time.sleep(3.0)
        super().compile_kernels()


def test_replies_go_on_while_the_kernels_load(serve, params_12kw):
    srv = serve(emulator=_SlowKernels(params_12kw, load_profile("clean"), 0))
    dev, sim_time = point(srv, "sim_control", "sim_time")
    advancer, reader = client(srv.port, timeout_s=60), client(srv.port)
    done = threading.Event()
    result = {}

    def advance() -> None:
        result["reply"] = write(advancer, srv, *ADVANCE, 60)
        done.set()

    thread = threading.Thread(target=advance)
    thread.start()
    reads_while_loading = 0
    while not done.is_set():
        now = read_point(reader, dev, sim_time)
        if now != 0.0:  # the advance ended between the check and the read (a CI run's race)
            assert now == 60.0  # in one go, never part of it
            break
        reads_while_loading += 1  # answered, and time stands
        time.sleep(0.05)
    thread.join(timeout=60)
    assert not result["reply"].isError()
    assert reads_while_loading >= 5  # the 3-s load did not block the loop
    assert read_point(reader, dev, sim_time) == 60.0
    advancer.close()
    reader.close()


def test_the_clock_guard_answers_01_whatever_the_values(serve):
    """A stranger's probe: on a real-time server without --allow-control a clock or fault
    command got 01 or 03 depending on its value (an advance of 5 s 01, of 0 s 03; a speed
    of 2 01, of 0.001 03; clock_mode 1 01, 2 03; reset 2 03; fault_kind 10 03). The guard
    is the server's state (spec section 7, 01: "the server is in the wrong state to process
    a request of this type"), checked before the values: every write touching such a
    command gets 01, raw frames over a real socket, nothing changed; the dashboard's path
    gives the guard as its reason."""
    srv = serve(lockstep=False)
    sim = {name: point(srv, "sim_control", name)[1] for name in ("speed_factor", "reset")}
    advance = point(srv, *ADVANCE)[1]
    fc6 = lambda address, value: struct.pack(">BHH", 6, address, value)  # noqa: E731
    writes = [
        ("lockstep_advance = 5", write_registers_pdu(advance.address, encode(advance, 5))),
        ("lockstep_advance = 0", write_registers_pdu(advance.address, [0, 0])),
        ("speed_factor = 2", write_registers_pdu(0, encode(sim["speed_factor"], 2.0))),
        ("speed_factor = 0.001", write_registers_pdu(0, encode(sim["speed_factor"], 0.001))),
        ("clock_mode = 1", fc6(2, 1)),
        ("clock_mode = 2", fc6(2, 2)),
        ("reset = 1", fc6(sim["reset"].address, 1)),
        ("reset = 2", fc6(sim["reset"].address, 2)),
        ("fault_kind = 10", fc6(10, 10)),
        ("fault block, fault_kind = 10", write_registers_pdu(10, [10, 1])),
    ]
    before = srv.values()
    for label, pdu in writes:
        assert ask(srv.port, 100, pdu) == bytes([pdu[0] | 0x80, 0x01]), label
    after = srv.values()
    for name in ("speed_factor", "clock_mode", "lockstep_counter", "fault_kind"):
        assert after[name] == before[name], name
    assert srv.server.emulator.sim_time_s >= before["sim_time_s"]  # no reset: time went on
    why = srv.call(srv.server.write_signal("speed_factor", 0.001))
    assert why is not None and "exception 01" in why and "--allow-control" in why, why
