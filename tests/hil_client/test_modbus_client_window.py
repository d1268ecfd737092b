"""A stranger's own Modbus/TCP bench device, written from the docs: one that takes fewer
transactions at once than the client pipelines, one that reads a request per segment, one
that answers with transaction ID 0, one with an absent instrument at real time. Over real
sockets: the quirk in a relay (:mod:`tests.hil_client.rigs.plc_h`) in front of a real
``rig-emulator serve``, and the real ``hil-client run``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from hil_client.modbus_client import (
    REOPEN_AFTER,
    Connection,
    ModbusExceptionResponse,
    read_pdu,
)
from tests.hil_client.rigs.plc_h import QuirkyDevice

#: the stranger's short protocol (/tmp quick.yaml): about 250 simulated seconds
PROTOCOL = """\
name: quick
test: stationary
description: short protocol for device probing
acquisition_period_s: 1
flow_spread_K: 15
preheat: {temperature_C: 30, tolerance_K: 3, hold_s: 5, load_pct: 100, max_duration_s: 60}
start_up:
  return_setpoint_C: 35
  t1_window_s: 20
  t1_max_rise_K_min: 50
  min_duration_s: 20
  max_duration_s: 60
test_sequence:
  return_setpoint_C: 35
  sequences:
    - {name: s100, load_pct: 100, duration: "00:00:40"}
cooling_1: {load_pct: 20, return_setpoint_C: 35, until_forward_C: 90, max_duration_s: 30}
cooling_2: {until_after_t2_s: 60}
"""
#: the requests of one step against the shipped map: well over four (the stranger's limit)
STEP_REQUESTS = 20


@pytest.fixture
def device():
    """``device(upstream_port, quirk, limit)``: a :class:`QuirkyDevice`, closed after."""
    started: list[QuirkyDevice] = []

    def start(port: int, quirk: str, limit: int = 1) -> QuirkyDevice:
        started.append(QuirkyDevice(port, quirk, limit))
        return started[-1]

    yield start
    for relay in started:
        relay.close()


class _Connections:
    """The client's connections as it opens them, and the segments they send (each send of
    one or more requests): what a run did with its window, watched, not changed."""

    def __init__(self) -> None:
        self.opened: list[Connection] = []
        self.segments = 0


@pytest.fixture
def connections(monkeypatch) -> _Connections:
    """Watch the :class:`Connection` s of a run (:class:`_Connections`)."""
    seen = _Connections()
    init, transmit = Connection.__init__, Connection._transmit

    def watched_init(self, *args, **kwargs) -> None:
        init(self, *args, **kwargs)
        seen.opened.append(self)

    def watched_transmit(self) -> None:
        unsent = len(self._unsent)
        transmit(self)
        seen.segments += unsent != len(self._unsent)

    monkeypatch.setattr(Connection, "__init__", watched_init)
    monkeypatch.setattr(Connection, "_transmit", watched_transmit)
    return seen


def _run(tmp_path: Path, port: int, *extra: str) -> tuple[int, Path]:
    protocol = tmp_path / "quick.yaml"
    protocol.write_text(PROTOCOL)
    out = tmp_path / "log.csv"
    argv = ["run", str(protocol), "--boiler", "windhager_12kw"]
    argv += ["--rig", f"modbus://127.0.0.1:{port}", "--out", str(out), *extra]
    return main(argv), out


def _events(out: Path) -> list[dict]:
    path = out.with_name(out.stem + ".modbus_events.jsonl")
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def test_a_device_taking_four_transactions_at_a_time_gets_a_whole_run(
    serve_process, device, tmp_path, capsys, connections
):
    """A stranger's probe: a device that takes 4 outstanding transactions and answers 06
    (server busy) to the rest, as the TCP guide allows, stopped the run before its first
    row ("unit 100: function 4 refused with exception 06; no row was acquired")."""
    server = serve_process("--boiler", "windhager_12kw", "--lockstep")
    relay = device(server.port, "busy", 4)
    code, out = _run(tmp_path, relay.port)
    err = capsys.readouterr().err
    assert code == 0, err
    assert "exception 06" not in err
    log = read_log(out)
    assert len(log) > 100  # (about 250 rows of 1 s: the protocol ran)
    assert not any(e["event"] == "exception" for e in _events(out))
    # the limit is kept once shown twice (the window narrowed at the first burst, opened
    # again after REOPEN_AFTER clean replies, narrowed once more): 4, not opened again
    assert connections.opened and connections.opened[-1].window == 4
    # the busy answers came while the client learnt the limit, not every step: fewer than
    # two steps' requests (two narrowings; it was 06 to 9 of the first 13, then the run
    # stopped)
    assert 0 < relay.busy_answers < 2 * STEP_REQUESTS


def test_a_passing_busy_fault_does_not_narrow_the_window_for_good(
    serve_process, tmp_path, capsys, connections
):
    """A stranger's re-probe: a 0.5-s busy fault (exception 06 on unit 1) at a lockstep
    run's start: the coil writes queued behind the setpoint write got 06, were asked again
    alone after the step's advance (the fault over), were answered, and the window of 1 was
    kept for the whole run: 1818 segments instead of 184, the run twice as long."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 1, code: 6, at_s: 0, for_s: 0.5}\n")
    server = serve_process("--boiler", "windhager_12kw", "--lockstep", "--faults", str(faults))
    code, out = _run(tmp_path, server.port)
    err = capsys.readouterr().err
    assert code == 0, err
    rows = len(read_log(out))
    assert rows > 100  # (about 250 rows of 1 s: the protocol ran)
    assert [conn.window for conn in connections.opened] == [None]  # opened again
    # a step is one segment with the window open (the connect's reads and the first
    # REOPEN_AFTER replies one at a time aside); one at a time it was seven a row
    assert connections.segments < rows + REOPEN_AFTER


def test_a_device_that_drops_pipelined_requests_is_read_one_at_a_time(
    serve_process, device, tmp_path, capsys
):
    """A stranger's probe: a device that serves one request per segment and drops the rest
    gave "cannot reach modbus://...: no reply within the timeout", though it was reached."""
    server = serve_process("--boiler", "windhager_12kw", "--lockstep")
    relay = device(server.port, "one_at_a_time")
    code, out = _run(tmp_path, relay.port, "--reply-timeout", "1")
    err = capsys.readouterr().err
    assert code == 0, err
    assert "cannot reach" not in err
    assert len(read_log(out)) > 100
    assert not _events(out)  # no unit went unread: the fallback is the connection's
    # dropped only in the first pipelined burst (13 requests at most), never again
    assert 0 < relay.dropped < STEP_REQUESTS


def test_replies_with_transaction_id_0_are_named_not_a_timeout(
    serve_process, device, tmp_path, capsys
):
    """A stranger's probe: a device answering every request with transaction ID 0 gave
    "cannot reach ...: no reply within the timeout", though it answered every request."""
    server = serve_process("--boiler", "windhager_12kw", "--lockstep")
    relay = device(server.port, "tid0")
    code, _ = _run(tmp_path, relay.port, "--reply-timeout", "1")
    err = capsys.readouterr().err
    assert code == 1
    assert "replies came with transaction id 0, not the requests' " in err, err
    assert "no reply within the timeout" not in err and "cannot reach" not in err


def test_a_pipelining_server_keeps_the_window_open_and_a_units_own_busy_is_its_exception(
    serve_process, tmp_path
):
    """The pipelined path stays one segment for a server that pipelines (the emulator), and
    a unit under an ``exception`` fault with code 06 (busy of its own, CONTRACT section 5)
    is its exception, not a limit of the server: the window stays open."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 3, code: 6, at_s: 0}\n")
    server = serve_process("--boiler", "windhager_12kw", "--lockstep", "--faults", str(faults))
    conn = Connection("127.0.0.1", server.port, 3.0)
    try:
        for _ in range(2):
            requests = [(100, read_pdu(4, 0, 4))] * 6 + [(3, read_pdu(4, 0, 1))]
            requests += [(1, read_pdu(4, 0, 2))] * 6
            conn.send(requests)
            replies, _ = conn.receive_all(len(requests))
            assert isinstance(replies[6], ModbusExceptionResponse) and replies[6].code == 6
            assert all(isinstance(r, bytes) for i, r in enumerate(replies) if i != 6), replies
            assert conn.window is None
    finally:
        conn.close()


def test_slow_rows_name_the_unit_that_timed_out_not_the_servers_clock(
    serve_process, device, tmp_path, capsys
):
    """A stranger's probe: with an FID that never answered, every row waited the reply
    timeout, rows came 50 s apart at x10, and the warning blamed the server's clock; the
    unit timing out on every row was only in the events file."""
    server = serve_process("--boiler", "windhager_12kw", "--speed", "20")
    relay = device(server.port, "silent_unit", 3)
    code, out = _run(tmp_path, relay.port, "--reply-timeout", "1")
    err = capsys.readouterr().err
    assert code == 0, err
    warning = next(line for line in err.splitlines() if "rows came" in line)
    assert "each row waited for unit 3 (flue_gas_OGC_ppm: no reply within the reply " in warning
    assert "ran faster than the client could read" not in warning
    meta = json.loads(out.with_name(out.stem + ".meta.json").read_text())
    assert any("each row waited for unit 3" in note for note in meta["notes"])


def _delayed_unit_1_run(serve_process, tmp_path, capsys, delay_ms: int, reply_timeout: str):
    """A run at x20 with a delay fault on unit 1 (the bench PLC): its log and the warning
    on its rows' spacing, which names unit 1 with its readings."""
    faults = tmp_path / "faults.yaml"
    faults.write_text(f"faults:\n  - {{kind: delay, unit: 1, delay_ms: {delay_ms}}}\n")
    server = serve_process("--boiler", "windhager_12kw", "--speed", "20", "--faults", str(faults))
    code, out = _run(tmp_path, server.port, "--reply-timeout", reply_timeout)
    err = capsys.readouterr().err
    assert code == 0, err
    warning = next(line for line in err.splitlines() if "rows came" in line)
    assert "each row waited for unit 1 (water_flow_kg_h, water_in_temp_C, " in warning
    return out, warning


def test_slow_rows_name_the_unit_whose_reads_timed_out_with_its_readings(
    serve_process, tmp_path, capsys
):
    """A stranger's re-probe: a 3-s delay fault on unit 1 (real time, reply timeout 1 s):
    the warning named unit 1 with no readings ("unit 1 (: no reply ...") and unit 7, which
    has no fault: its only timeouts were its coil write held behind unit 1's delayed
    replies. Read timeouts only count, and the unit is named with its readings."""
    out, warning = _delayed_unit_1_run(serve_process, tmp_path, capsys, 3000, "1")
    # unit 7's coil writes did time out behind unit 1 (what misled the warning)
    assert any(e["unit"] == 7 and e["event"] == "timeout" for e in _events(out))
    assert "unit 7" not in warning and "(: " not in warning, warning


def test_slow_rows_name_the_unit_whose_replies_came_late_within_the_timeout(
    serve_process, tmp_path, capsys
):
    """A stranger's probe: a unit whose replies came 4.5 s late, within the 5-s reply
    timeout, made every row 4.5 s late (30 ``late`` events), and the warning blamed the
    server's clock ("ran faster than the client could read ... a slower --speed, a faster
    tick or --lockstep keeps the period"), which is not what slowed them. Here a 0.6-s
    delay on unit 1 under a 2-s timeout at x20."""
    out, warning = _delayed_unit_1_run(serve_process, tmp_path, capsys, 600, "2")
    assert not any(e["event"] == "timeout" for e in _events(out))  # late, never timed out
    assert "s late a row (median) on " in warning and "within the reply timeout, 2 s)" in warning
    assert "ran faster than the client could read" not in warning, warning
