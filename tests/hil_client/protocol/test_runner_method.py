"""The runner against real ``rig-emulator serve`` processes (real sockets, real files): the
log says what the server took, a run that cannot carry out its test method is not
complete (exit 1, the log kept, a note), a sequence lost to a break the run went on from
is no such run, and a restarted phase moves no mark."""

from __future__ import annotations

import json
import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from hil_client.modbus_client import Connection, write_registers_pdu
from hil_client.wait_for_port import free_port
from rig_emulator.registers import encode, load_map
from tests.hil_client.test_restarts import ServerProcess
from tests.hil_client.timed_protocol import timed_protocol

BOILER = "windhager_12kw"
SHIPPED_MAP = Path(__file__).resolve().parents[3] / "register_maps" / "wieselburg_bench.yaml"
FLOW_POINT = (
    "      - {name: flow_setpoint, signal: water_flow_setpoint_kg_h, table: holding, address: 0,\n"
    "         datatype: float32, access: rw}\n"
)
MAP_ID_POINT = (
    "      - {name: map_id, signal: map_id, table: input, address: 30, datatype: uint32}\n"
)

# phases ended by their time-outs (rules that cannot be met) but the start-up's:
# t0 = 60, t1 within a minute, t2 = t1 + 240 (two 120-s sequences), t3 = t2 + 3600
TIMED = timed_protocol(
    "timed",
    [("peak", 100, 120), ("ramp", (100, 40), 120)],
    cooling_1_s=3600,
    cooling_2_after_t2_s=3700,
)
TEST_S = 240.0  # the two sequences


@pytest.fixture
def timed(tmp_path) -> Path:
    path = tmp_path / "timed.yaml"
    path.write_text(TIMED)
    return path


def _run(protocol: Path | str, port: int, out: Path, *extra: str) -> int:
    rig = f"modbus://127.0.0.1:{port}"
    args = ["run", str(protocol), "--boiler", BOILER, "--quiet", "--rig", rig, "--out", str(out)]
    return main([*args, *extra])


def _meta(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + ".meta.json").read_text())


def _map(tmp_path: Path, name: str, flow_point: str, map_id: bool = True) -> Path:
    """The shipped map with another flow-setpoint point (and without ``map_id``)."""
    text = SHIPPED_MAP.read_text()
    assert FLOW_POINT in text and MAP_ID_POINT in text  # (the shipped map as this test knows it)
    text = text.replace(FLOW_POINT, flow_point)
    if not map_id:
        text = text.replace(MAP_ID_POINT, "")
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_log_says_the_flow_setpoint_the_server_holds(serve_process, timed, tmp_path):
    """A stranger's probe: with a map whose flow setpoint is a uint16 x0.5, 27,307 of
    52,118 rows logged a setpoint that is no multiple of 0.5 (137.4702 where the register
    held 137.5, and the flow settled at 137.5). The log says what was written: the value
    as the point's encoding carries it."""
    half = _map(
        tmp_path,
        "half.yaml",
        FLOW_POINT.replace("datatype: float32,", "datatype: uint16, scale: 0.5,"),
    )
    srv = serve_process("--lockstep", "--map", str(half))
    out = tmp_path / "half.csv"
    assert _run(timed, srv.port, out, "--map", str(half)) == 0
    log = read_log(out)
    setpoint = log["water_flow_setpoint_kg_h"]
    pumped = setpoint[setpoint > 0]
    # the ramp's 100 -> 40 % asks for flows between the half steps: every one carried
    assert len(np.unique(pumped)) > 20
    assert np.all(pumped * 2 == np.round(pumped * 2)), pumped[pumped * 2 != np.round(pumped * 2)]
    # the first cooling's setpoint (20 % load: 137.4702 kg/h asked) as the server held it,
    # and the flow it settled at (the clean profile's float32 reading: 1e-4 kg/h)
    cooling_1 = np.array(log.text["phase"]) == "cooling_1"
    assert np.all(setpoint[cooling_1] == 137.5), np.unique(setpoint[cooling_1])
    assert log["water_flow_kg_h"][cooling_1][-1] == pytest.approx(137.5, abs=1e-3)


def test_a_setpoint_refused_as_illegal_stops_the_run_and_says_so(
    serve_process, timed, tmp_path, capsys
):
    """A stranger's probe: a server whose map narrowed the flow setpoint to 0..500 kg/h
    refused every setpoint write of a 6-h stationary run with exception 03; the run exited
    0, ``"complete": true``, a test of 0 kWh and one warning. The server's map here has no
    ``map_id`` (the client cannot tell the range before it writes): the first refused
    write stops the run, one line naming the command and the exception, the log kept, the
    meta file not complete and saying why, exit 1."""
    narrow = _map(
        tmp_path,
        "narrow.yaml",
        FLOW_POINT.replace("access: rw}", "access: rw, min: 0, max: 500}"),
        map_id=False,
    )
    srv = serve_process("--lockstep", "--map", str(narrow))
    out = tmp_path / "narrow.csv"
    assert _run(timed, srv.port, out) == 1  # (the client's own map: the shipped one)
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0, err
    assert "water_flow_setpoint_kg_h" in err and "exception 03" in err, err
    assert "the log keeps the 1 row written" in err, err
    log = read_log(out)  # the step's row: the preheat's 687 kg/h never taken, left empty
    assert len(log) == 1 and np.isnan(log["water_flow_setpoint_kg_h"][0])
    meta = _meta(out)
    assert meta["complete"] is False
    assert any("exception 03" in n and "water_flow_setpoint_kg_h" in n for n in meta["notes"])


def test_an_injected_exception_03_is_a_fault_the_run_rides_out(serve_process, timed, tmp_path):
    """The other side of the refusal: a fault that answers every request of the bench PLC
    with exception 03 for 20 s is the unit's state, not the server's range (its reads get
    it too): the writes are sent again, and the run completes."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 1, code: 3, at_s: 200, for_s: 20}\n")
    srv = serve_process("--lockstep", "--faults", str(faults))
    out = tmp_path / "fault.csv"
    assert _run(timed, srv.port, out) == 0
    meta = _meta(out)
    assert meta["complete"] is True and meta["modbus_event_count"] > 0


def _rows(out: Path) -> list[list[str]]:
    if not out.exists():
        return []
    return [line.split(",") for line in out.read_text().splitlines()[1:] if line.count(",") > 3]


def _advance_when(port: int, out: Path, ready, seconds: float) -> threading.Thread:
    """Another client advances the lockstep server by ``seconds`` once ``ready(rows)``."""

    def other() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not ready(_rows(out)):
            time.sleep(0.01)
        dev, point = load_map().point("lockstep_advance_s")
        conn = Connection("127.0.0.1", port, 5.0)
        conn.send([(dev.unit_id, write_registers_pdu(point.address, encode(point, seconds)))])
        conn.receive()
        conn.close()

    thread = threading.Thread(target=other, daemon=True)
    thread.start()
    return thread


def _column_marks(log) -> dict[str, float]:
    """The marks as the phase column gives them (the last row before each phase's first)."""
    phase = log.text["phase"]
    marks = {}
    for i in range(1, len(phase)):
        if phase[i] != phase[i - 1]:
            key = {"start_up": "t0_s", "test": "t1_s", "cooling_1": "t2_s", "cooling_2": "t3_s"}
            marks.setdefault(key[phase[i]], float(log.t[i - 1]))
    return marks


@pytest.mark.parametrize("where", ["cooling_1", "test"])
def test_a_restarted_phase_moves_no_mark(serve_process, timed, tmp_path, where):
    """A stranger's probe: ``--on-restart restart-phase`` with a break in the first cooling
    moved t2, the END of the test, from 3518 to 5107 s; the balance took 1487 cooling rows
    for a 0.913-h test at 91.1 % instead of 0.5 h at 80.6 %. A break in the test left the
    abandoned attempt's rows ``test`` while t1 moved to the restart, and the restarted
    test's first row said ``ramp``, not ``peak``. No mark moves: the meta file's marks are
    the phase column's, the test lasts its 240 s, and the restarted phase's first row is
    its first sequence's."""
    srv = serve_process("--lockstep")
    out = tmp_path / f"restart_{where}.csv"
    if where == "cooling_1":  # 600 s into the first cooling (its 3600 s)

        def ready(rows):
            return len(rows) >= 960 and rows[-1][1] == "cooling_1"
    else:  # in the ramp

        def ready(rows):
            return bool(rows) and rows[-1][2] == "ramp"

    other = _advance_when(srv.port, out, ready, 100.0)
    assert _run(timed, srv.port, out, "--on-restart", "restart-phase") == 0
    other.join(timeout=10)
    log = read_log(out)
    meta = log.meta
    marks = _column_marks(log)
    assert {k: meta[k] for k in marks} == marks  # the meta file's marks are the column's
    (gap,) = meta["gaps"]
    restart = gap["end_time_s"]
    first = int(np.searchsorted(log.t, restart))
    assert log.text["phase"][first] == where and log["rig_epoch"][first] == 1
    assert meta["t0_s"] == 60.0  # where the preheat timed out
    if where == "cooling_1":
        assert meta["t2_s"] - meta["t1_s"] == TEST_S  # the test as it was played
        assert meta["t3_s"] == restart + 3600.0  # the restarted cooling's full length
    else:  # the restarted test plays its sequences from the first, on the new plant
        assert log.text["sequence"][first] == "peak"
        assert meta["t2_s"] == restart + TEST_S
        sequences = log.text["sequence"][first : int(np.searchsorted(log.t, meta["t2_s"])) + 1]
        # the restart's row (its elapsed 0, as t1's row is the start-up's), then each
        # sequence its 120 rows
        assert sequences[1:].count("peak") == 120 and sequences[1:].count("ramp") == 120
    assert any(f"{where} restarted at time_s = {restart:g} s" in n for n in meta["notes"])
    assert gap["action"] == "restart-phase" and gap["phase_restarted"] == where


def test_a_sequence_a_fast_server_skipped_leaves_the_run_not_complete(
    serve_process, timed, tmp_path, capsys
):
    """A stranger's probe: at ``--speed 100000`` with 1-s acquisitions against a
    real-time server rows came 10000 s apart; the ``ramp`` sequence never had a row and
    its setpoint was never written, the 240-s test lasted 2 h 47 min, and the meta file
    said ``"complete": true`` with a generic "rows came 10000 s apart". The run stops
    there, naming the sequence on one line and in the meta file, exit 1."""
    srv = serve_process("--speed", "100000")
    out = tmp_path / "fast.csv"
    assert _run(timed, srv.port, out) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "'ramp'" in err and "got no row" in err, err
    meta = _meta(out)
    assert meta["complete"] is False
    assert any("'ramp'" in n and "could not be carried out" in n for n in meta["notes"])
    log = read_log(out)
    assert "ramp" not in log.text["sequence"] and "peak" in log.text["sequence"]


def test_several_skipped_sequences_are_named_in_one_sentence(
    serve_process, timed, tmp_path, capsys
):
    """A re-probe: with several sequences skipped, the stop said "sequence 's3' (...),
    's4' (...), 's5' (...) got no row and its setpoint was never written". The sentence
    names them as a list, in the plural."""
    three = tmp_path / "three.yaml"
    ramp = "    - {name: ramp, load_pct: [100, 40], duration: 120}\n"
    three.write_text(timed.read_text().replace(ramp, ramp + ramp.replace("ramp", "tail")))
    srv = serve_process("--speed", "100000")
    out = tmp_path / "three.csv"
    assert _run(three, srv.port, out) == 1
    err = capsys.readouterr().err.strip()
    named = (
        "sequences 'ramp' (test_sequence.sequences[1]) and 'tail' (test_sequence.sequences[2]) "
        "got no row and their setpoints were never written"
    )
    assert named in err, err
    assert any(named in n for n in _meta(out)["notes"])


# phases ended by time-outs; five 20-s sequences (the test's 100 s: 5 s of wall at x20)
SHORT_RT = timed_protocol(
    "short_rt",
    [("s1", 100, 20), ("s2", 80, 20), ("s3", 60, 20), ("s4", 40, 20), ("s5", 30, 20)],
    cooling_1_s=20,
    cooling_2_after_t2_s=60,
    preheat_s=20,
    start_up_s=(10, 10, 20),
)
SEQUENCES = {"s1", "s2", "s3", "s4", "s5"}


def test_sequences_lost_to_a_break_the_run_went_on_from_leave_it_complete(tmp_path, capsys):
    """A stranger's probe: a real-time server (x20) restarted during the second of five
    sequences, the client run with ``--on-restart continue``; rows came again 127 s later,
    and the run stopped, exit 1: "sequence 's3' ..., 's4' ..., 's5' ... got no row and
    its setpoint was never written (... --lockstep or a slower --speed ...)". Those
    sequences were lost to the break the user asked the run to go on from, not skipped by
    a coarse step: the run completes, and a note names them as lost to the break."""
    protocol = tmp_path / "short_rt.yaml"
    protocol.write_text(SHORT_RT)
    out = tmp_path / "restart.csv"
    port = free_port()
    args = ("--speed", "20", "--tick-hz", "20")  # a row a simulated second
    first = ServerProcess(port, *args)
    restarted: list[ServerProcess] = []

    def restart() -> None:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            rows = _rows(out)
            if rows and rows[-1][1:3] == ["test", "s2"]:
                first.kill()
                # 2 s of wall, 40 simulated seconds at x20, with the server's start: the
                # rest of s2 and all of s3 at least (each sequence 20 s)
                time.sleep(2.0)
                restarted.append(ServerProcess(port, *args))
                return
            time.sleep(0.01)

    other = threading.Thread(target=restart, daemon=True)
    other.start()
    try:
        code = _run(protocol, port, out, "--on-restart", "continue")
        other.join(timeout=70)
    finally:
        first.kill()
        for server in restarted:
            server.kill()
    err = capsys.readouterr().err
    assert restarted, "the server was never restarted"
    assert code == 0, err
    meta = _meta(out)
    assert meta["complete"] is True and len(meta["gaps"]) == 1, meta
    assert not [n for n in meta["notes"] if "could not be carried out" in n], meta["notes"]
    (lost,) = [n for n in meta["notes"] if "lost to the break" in n]
    # complete, but the test is no one continuous record, and the note says so
    assert [n for n in meta["notes"] if "its test is not one continuous record" in n], meta["notes"]
    named = set(re.findall(r"'(s\d)'", lost))
    logged = set(read_log(out).text["sequence"]) - {""}
    # each sequence either had rows or is named as lost, never both
    assert named and named | logged == SEQUENCES and not named & logged, (named, logged)
