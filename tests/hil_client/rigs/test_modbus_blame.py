"""Who a hole in a real-time run's rows is due to, against real ``rig-emulator serve``
processes: another client that changed the server's speed, a server that stalled, or a
unit whose replies came late, is not the client falling behind; and what another client
changed of the server's clock is said as such."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from hil_client.cli import main
from hil_client.modbus_client import Connection, write_registers_pdu
from rig_emulator.faults.wire import KIND_CODES
from rig_emulator.registers import encode, load_map
from tests.hil_client.timed_protocol import timed_protocol

BOILER = "windhager_12kw"
SPEED = 100.0  # rows 10 s apart (the server's 10-Hz tick), the first cooling 6 s of wall
# phases ended by time-outs; the first cooling (600 s, 60 rows) is where things happen
RT = timed_protocol("rt", [("stationary_100", 100, 60)], cooling_1_s=600, cooling_2_after_t2_s=700)
CLIENT_BLAMED = "the client fell behind"


def _when_cooling(out: Path, rows: int, then) -> threading.Thread:
    """``then()`` once the log holds ``rows`` rows of the first cooling (enough steps for
    the run to know its typical one)."""

    def watch() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            lines = out.read_text().splitlines()[1:] if out.exists() else []
            if sum(1 for line in lines if ",cooling_1," in line) >= rows:
                then()
                return
            time.sleep(0.01)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def _run_while(port: int, out: Path, then) -> int:
    """``hil-client run`` of :data:`RT` to ``out``; ``then()`` from another thread 15 rows
    into its first cooling (:func:`_when_cooling`). The run's exit code."""
    protocol = out.with_name("rt.yaml")
    protocol.write_text(RT)
    other = _when_cooling(out, 15, then)
    rig = f"modbus://127.0.0.1:{port}"
    code = main(["run", str(protocol), "--boiler", BOILER, "--quiet", "--rig", rig,
                 "--out", str(out)])  # fmt: skip
    other.join(timeout=10)
    return code


def _write(port: int, *points: tuple[str, float]) -> None:
    """Another client writes points of the simulation control, in one request each."""
    register_map = load_map()
    conn = Connection("127.0.0.1", port, 5.0)
    for name, value in points:
        dev, point = register_map.point(name)
        conn.send([(dev.unit_id, write_registers_pdu(point.address, encode(point, value)))])
        conn.receive()
    conn.close()


def _write_block(port: int, *points: tuple[str, float]) -> None:
    """Another client writes points of the simulation control that lie one after another,
    in one request (a fault's set comes with its whole block)."""
    register_map = load_map()
    (dev, first), *_ = [register_map.point(name) for name, _ in points]
    words: list[int] = []
    for name, value in points:
        _, point = register_map.point(name)
        assert point.address == first.address + len(words), name  # one after another
        words += encode(point, value)
    conn = Connection("127.0.0.1", port, 5.0)
    conn.send([(dev.unit_id, write_registers_pdu(first.address, words))])
    conn.receive()
    conn.close()


def _meta(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + ".meta.json").read_text())


def test_another_client_advancing_a_real_time_server_is_a_break(serve_process, tmp_path):
    """A stranger's probe: another client stepped a real-time server a day ahead (lockstep
    mode, an advance of 86,400 s, real time again); the run logged a hole "the server
    answered late (it stalled ...)", kept rig_epoch 0 and recorded no gap, and the analyses
    took both sides for one plant. It is a break, as in lockstep."""
    srv = serve_process("--speed", f"{SPEED:g}", "--allow-control")
    out = tmp_path / "advanced.csv"

    def advance() -> None:
        _write(srv.port, ("clock_mode", 1.0), ("lockstep_advance_s", 86400.0), ("clock_mode", 0.0))

    assert _run_while(srv.port, out, advance) == 1  # --on-restart abort, the default
    meta = _meta(out)
    (gap,) = meta["gaps"]
    assert gap["reason"].startswith("another client advanced the server"), gap
    assert gap["action"] == "abort", gap
    assert not [n for n in meta["notes"] if "stalled" in n or CLIENT_BLAMED in n], meta


def test_another_client_changing_the_speed_is_recorded_not_blamed_on_the_client(
    serve_process, tmp_path, capsys
):
    """A stranger's probe: another client changed a real-time server's speed mid-run (x100
    -> x10000, through the simulation control); the notes said "the client fell behind the
    server's real-time clock (held up: paused, swapped out or overloaded)" four times and
    the meta file still said x100. The speed is read each step: the change is a gap in the
    meta file, naming both speeds, and no hole is blamed on the client.

    A re-probe (x20 -> x40): the meta's ``clock`` still said x20, the coarse-rows note
    quoted x20 alone, and stderr called the change a "break ... the run goes on from the
    plant as it is", though no row was missing. The meta says the clock as it ended and
    every speed seen, the note quotes both, and stderr says what happened."""
    srv = serve_process("--speed", f"{SPEED:g}", "--allow-control")
    out = tmp_path / "speed.csv"
    assert _run_while(srv.port, out, lambda: _write(srv.port, ("speed_factor", 10000.0))) == 0
    meta = _meta(out)
    (gap,) = meta["gaps"]
    assert "speed changed from x100 to x10000" in gap["reason"], gap
    assert gap["rig_epoch"] == 0 and gap["action"] == "continue"  # the same plant
    assert (gap["speed_before"], gap["speed_after"]) == (100.0, 10000.0)
    assert not [n for n in meta["notes"] if CLIENT_BLAMED in n], meta["notes"]
    assert meta["clock"] == "real time x10000" and meta["clock_speeds"] == [100.0, 10000.0]
    # rows 10 s apart at x100 (a 10-Hz tick), then 1000 s: coarse, at both speeds
    (coarse,) = [n for n in meta["notes"] if n.startswith("rows came")]
    assert "(real time x100, then x10000)" in coarse, coarse
    err = capsys.readouterr().err
    told = [line for line in err.splitlines() if "speed changed" in line]
    assert told and "break" not in told[0] and "no row missed" in told[0], err


def test_a_server_that_stalled_is_not_blamed_on_the_client(serve_process, tmp_path):
    """A stranger's probe: the server process SIGSTOPped for a few seconds, its clock
    catching up once it went on, left a hole the notes blamed on the client ("held up:
    paused, swapped out or overloaded"). The client kept its pace, waiting on the
    server's replies: the note says the server answered late."""
    srv = serve_process("--speed", f"{SPEED:g}")
    out = tmp_path / "stall.csv"

    def stall() -> None:
        os.kill(srv.proc.pid, signal.SIGSTOP)
        time.sleep(2.0)  # 200 simulated seconds, under the client's reply timeout
        os.kill(srv.proc.pid, signal.SIGCONT)

    assert _run_while(srv.port, out, stall) == 0
    meta = _meta(out)
    holes = [n for n in meta["notes"] if n.startswith("no row from time_s")]
    # the server now drops a stall rather than chase it (rig_emulator.clock.RealTimeTicks),
    # so it leaves no hole; a server that chases one (an older emulator, another rig) leaves
    # a hole said to be the server's, never the client's
    assert not [n for n in holes if CLIENT_BLAMED in n], meta["notes"]
    assert all("the server answered" in n for n in holes), holes
    assert meta["gaps"] == []


def test_a_hole_from_a_unit_s_late_replies_names_the_unit(serve_process, tmp_path):
    """A stranger's probe: a 4000-ms delay fault on unit 1 of a real-time server (x2) left
    "no row from time_s = 54 to 59.8 s (5 acquisitions missed): the server answered 0.0 s
    late (it stalled ...), while the client kept its pace": the wait came in the step
    before, after it had read the server's time, and the hole showed in the next. The
    note says the client waited on late replies of unit 1. Here another client sets a
    1500-ms delay on unit 1 for 150 simulated seconds (1.5 s of wall at x100, rows 10 s
    apart), which leaves a hole of at least a hundred seconds."""
    srv = serve_process("--speed", f"{SPEED:g}", "--allow-control")
    out = tmp_path / "delay.csv"
    fault = (
        ("fault_kind", KIND_CODES["delay"]),
        ("fault_target", 1),
        ("fault_parameter", 600.0),
        ("fault_duration_s", 150.0),
        ("fault_at_s", 0.0),  # now
        ("fault_command", 1),
    )
    assert _run_while(srv.port, out, lambda: _write_block(srv.port, *fault)) == 0
    meta = _meta(out)
    holes = [n for n in meta["notes"] if n.startswith("no row from time_s")]
    assert holes, meta["notes"]
    for hole in holes:
        assert "late replies of unit 1 (a slow unit, or a delay fault on it)" in hole, holes
    assert meta["gaps"] == []


def test_a_lockstep_server_switched_to_real_time_is_named(serve_process, tmp_path, capsys):
    """A tester's note: a lockstep run whose server another client switched to real time
    stopped with "unit 100: function 16 refused with exception 03" alone. The message
    and the meta file's gap say the server's clock left lockstep."""
    srv = serve_process("--lockstep")
    out = tmp_path / "left.csv"
    assert _run_while(srv.port, out, lambda: _write(srv.port, ("clock_mode", 0.0))) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "the server's clock left lockstep" in err, err
    (gap,) = _meta(out)["gaps"]
    assert "left lockstep" in gap["reason"] and gap["action"] == "abort", gap


def test_a_client_stopped_while_it_waited_on_a_late_unit_is_named_held_up(serve_process, tmp_path):
    """A re-probe of the hold-up heartbeat: a client stopped while it waits on a reply finds
    the reply there when it goes on, so the stop looked like that wait, and a client
    SIGSTOPped 4 s while a 1500-ms delay fault held unit 1's replies was noted as "the
    client waited ... on late replies of unit 1". Its heartbeat saw it stand still: the
    hole is the client's, held up the 4 s. (The fault is 600 ms here: each step now waits
    on unit 1 four times, its write, its readings and the setpoints and switches read back,
    and at 1500 ms those 6 s outweighed the 4-s stop, which the note rightly names then.)"""
    srv = serve_process("--speed", f"{SPEED:g}", "--allow-control")
    out = tmp_path / "stopped.csv"
    protocol = tmp_path / "rt.yaml"
    protocol.write_text(RT)
    argv = ["run", str(protocol), "--boiler", BOILER, "--quiet", "--out", str(out),
            "--rig", f"modbus://127.0.0.1:{srv.port}"]  # fmt: skip
    client = subprocess.Popen([sys.executable, "-m", "hil_client.cli", *argv])
    fault = (
        ("fault_kind", KIND_CODES["delay"]),
        ("fault_target", 1),
        ("fault_parameter", 600.0),
        ("fault_duration_s", 1000.0),  # 10 s of wall at x100: every step waits on unit 1
        ("fault_at_s", 0.0),  # now
        ("fault_command", 1),
    )

    def stop_in_a_wait() -> None:
        _write_block(srv.port, *fault)
        time.sleep(2.0)  # the client now spends 2.4 s of each step in those waits
        os.kill(client.pid, signal.SIGSTOP)
        time.sleep(4.0)
        os.kill(client.pid, signal.SIGCONT)

    watcher = _when_cooling(out, 15, stop_in_a_wait)
    try:
        assert client.wait(timeout=180) == 0
    finally:
        client.kill()
        watcher.join(timeout=10)
    holes = [n for n in _meta(out)["notes"] if n.startswith("no row from time_s")]
    held = [n for n in holes if CLIENT_BLAMED in n]
    assert held, holes
    # the 4-s stop, less a heartbeat period's lateness (0.05 s) and scheduling
    assert float(held[0].split("held up ")[1].split(" s")[0]) >= 3.5, held
