"""The client over Modbus: equal to the in-process run, nothing lost, clear errors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from rig_emulator.registers import load_map, precision
from tests.tcp_proxy import CuttableProxy

SHORT = str(Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml")
TEXT = ("phase", "sequence")


def _run(args: list[str]) -> int:
    return main(["run", SHORT, "--boiler", "windhager_12kw", "--quiet", *args])


@pytest.fixture(scope="module")
def local_log(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "local.csv"
    assert _run(["--rig", "local", "--out", str(out)]) == 0
    return read_log(out)


def _tolerance(column: str, value: np.ndarray) -> np.ndarray:
    """Encoding precision of the column's map point, plus the CSV's decimals, plus the
    effect of the setpoints' own encoding: they travel as float32 (6e-8 relative), and the
    ideal controller amplifies a state difference by C / (m cp dt), about 250, so readings
    may differ by up to 1e-5 relative."""
    from hil_client.lablog import DECIMALS

    csv = 10.0 ** -DECIMALS.get(column, 5) + 1e-5 * np.abs(value)
    try:
        _, p = load_map().point(column)
    except KeyError:
        return np.full_like(value, csv)
    return np.array([precision(p, v) for v in value]) + csv + 1e-9


def assert_logs_equal(a, b) -> None:
    assert list(a.columns) == list(b.columns)
    assert len(a) == len(b)
    for name in TEXT:
        assert a.text[name] == b.text[name]
    for name, values in a.columns.items():
        other = b.columns[name]
        both = ~np.isnan(values)
        assert np.array_equal(both, ~np.isnan(other)), name
        diff = np.abs(values[both] - other[both])
        assert np.all(diff <= _tolerance(name, values[both])), (name, diff.max())


def test_modbus_lockstep_run_equals_the_local_run(serve, tmp_path, local_log):
    srv = serve(lockstep=True)
    proxy = CuttableProxy(srv.port)  # never cut here: it counts what the client sends
    out = tmp_path / "modbus.csv"
    assert _run(["--rig", f"modbus://127.0.0.1:{proxy.port}", "--out", str(out)]) == 0
    proxy.close()
    remote = read_log(out)
    # a step (setpoints, advance, seven reads) goes out pipelined in one segment, not in nine;
    # the slack covers the reads at connect and a rare split segment
    assert proxy.segments_to_server <= 1.05 * len(remote) + 20
    assert remote.meta["clock"] == "lockstep" and remote.meta["complete"] is True
    assert remote.meta["gaps"] == []
    assert remote.meta["sampling_median_s"] == 1.0  # the protocol's period, kept
    for key in ("t0_s", "t1_s", "t2_s", "t3_s", "t4_s"):
        assert remote.meta[key] == local_log.meta[key]
    assert_logs_equal(local_log, remote)


def test_a_lockstep_run_goes_on_across_the_counters_wrap(serve, tmp_path):
    """The lockstep counter (uint16) wraps at 65536 advances. It was served 65534 where it
    stood at 65535 (0xFFFF, kept for a dropout of a reading), so every lockstep run stopped at
    its 65,535th step with "another client advanced the server" (a stranger's probe): any
    protocol over 18.2 simulated hours, or a second run on a used server."""
    srv = serve(lockstep=True)
    srv.server.lockstep_counter = 65536 - 200  # a used server: the wrap 200 steps in
    srv.call(srv.server.publish())
    out = tmp_path / "wrap.csv"
    assert _run(["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out)]) == 0
    log = read_log(out)
    assert log.meta["complete"] is True and log.meta["gaps"] == []
    assert len(log) > 400 and srv.server.lockstep_counter > 65536


def test_a_server_running_another_map_is_named_before_the_first_row(serve, tmp_path, capsys):
    """A server whose map lacks the forward temperature answers 02 to the client's read of
    unit 1: the client ran the whole protocol blind (27,521 rows of empty columns, exit 0; a
    stranger's probe). It stops before the first row, naming the unit, the signals and the
    fix."""
    import yaml

    from rig_emulator.registers import map_from_mapping
    from rig_emulator.registers.schema import MAP_DIR

    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    plc = next(d for d in data["devices"] if d["unit_id"] == 1)
    plc["points"] = [p for p in plc["points"] if p["signal"] != "water_out_temp_C"]
    out = tmp_path / "blind.csv"
    srv = serve(register_map=map_from_mapping(data, "theirs.yaml"))
    assert _run(["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out)]) == 2
    # (exit 2: the client's --map is the wrong one, as a wrong --boiler is; a stranger's
    # probe found it 1)
    err = capsys.readouterr().err  # its map id differs: stopped by that first
    assert err.count("\n") == 1 and "serves another register map" in err and "--map" in err
    # a server without a map id (an older one) is asked for every block of readings
    control = next(d for d in data["devices"] if d["unit_id"] == 100)
    control["points"] = [p for p in control["points"] if p["signal"] != "map_id"]
    srv = serve(register_map=map_from_mapping(data, "theirs.yaml"))
    assert _run(["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "answers exception 02" in err
    assert "water_out_temp_C" in err and "--map" in err and not out.exists()


@pytest.mark.parametrize("change", ["swap", "word_order", "scale"])
def test_a_map_that_differs_in_what_a_point_carries_stops_the_run(serve, tmp_path, capsys, change):
    """Differences the blocks' check cannot see read wrong values as readings, exit 0 (a
    re-probe): two same-length points swapped (forward and return temperature), the
    analyser's word order, the flue gas's scale. The server's map id tells them."""
    import yaml

    from rig_emulator.registers import map_from_mapping
    from rig_emulator.registers.schema import MAP_DIR

    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    points = {p["signal"]: p for d in data["devices"] for p in d["points"]}
    if change == "swap":
        a, b = points["water_in_temp_C"], points["water_out_temp_C"]
        a["address"], b["address"] = b["address"], a["address"]
    elif change == "word_order":
        points["flue_gas_O2_pct"]["word_order"] = "ABCD"
    else:
        points["flue_gas_temp_C"]["scale"] = 0.1
    srv = serve(register_map=map_from_mapping(data, "theirs.yaml"))
    out = tmp_path / "wrong.csv"
    assert _run(["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "serves another register map" in err and not out.exists()


def test_a_server_faster_than_the_client_reads_is_a_coarse_log_said_so(serve, tmp_path, capsys):
    """At x2000 a client cannot read every simulated second: the rows come tens of seconds
    apart. The meta said "acquisition_period_s: 1" and nothing else; now it gives the rows'
    median spacing and a note, and the run warns (the phase marks are that coarse too)."""
    srv = serve(lockstep=False, speed=2000.0)
    out = tmp_path / "fast.csv"
    assert _run(["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out)]) == 0
    log = read_log(out)
    spacing = float(np.median(np.diff(log.t)))
    assert log.meta["sampling_median_s"] == pytest.approx(spacing)
    if spacing <= 1.5:  # a machine fast enough to keep up: nothing to say
        pytest.skip(f"the client kept up with x2000 (rows {spacing:g} s apart)")
    assert any("rows came" in note and "x2000" in note for note in log.meta["notes"])
    assert "warning: rows came" in capsys.readouterr().err


def test_dropped_connections_are_retried_and_nothing_is_lost(serve, tmp_path, local_log):
    srv = serve(lockstep=True)
    proxy = CuttableProxy(srv.port)
    out = tmp_path / "dropped.csv"
    cutter_done = threading.Event()

    def cutter() -> None:
        # cut twice once rows are flowing
        while not out.exists() or out.stat().st_size < 20_000:
            time.sleep(0.05)
        proxy.cut()
        time.sleep(1.0)
        proxy.cut()
        cutter_done.set()

    threading.Thread(target=cutter, daemon=True).start()
    assert _run(["--rig", f"modbus://127.0.0.1:{proxy.port}", "--out", str(out)]) == 0
    proxy.close()
    assert cutter_done.is_set()
    log = read_log(out)
    assert len(log.meta["gaps"]) >= 1  # the outage is marked in the meta file
    for gap in log.meta["gaps"]:  # in the log's time base; no row lost in lockstep
        assert gap["action"] == "resumed" and gap["rig_epoch"] == 0
        assert gap["end_time_s"] == gap["start_time_s"] + 1.0
    assert set(log.columns["rig_epoch"]) == {0.0}
    # lockstep: the client settles the interrupted advance, so every row is there and equal
    assert_logs_equal(local_log, log)


def test_unreachable_server_gives_one_line_error(tmp_path, capsys):
    out = tmp_path / "x.csv"
    code = _run(["--rig", "modbus://127.0.0.1:1", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1
    assert "cannot reach modbus://127.0.0.1:1" in err and err.count("\n") == 1
    assert not out.exists()


def _start_client(port: int, out: Path, *extra: str) -> subprocess.Popen:
    """``hil-client run`` as a process that stops on a hangup, whatever the test run's own
    disposition of SIGHUP (a CI started under nohup ignores it, and so would the client)."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "hil_client.cli",
            "run",
            SHORT,
            "--boiler",
            "windhager_12kw",
            "--rig",
            f"modbus://127.0.0.1:{port}",
            "--out",
            str(out),
            "--quiet",
            *extra,
        ],
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
        # Ctrl-C as a terminal gives it: a pytest-xdist worker ignores SIGINT, and a child
        # that starts with SIGINT ignored keeps ignoring it (Python installs no handler)
        preexec_fn=_default_stop_signals,
    )


def _default_stop_signals() -> None:
    for how in (signal.SIGINT, signal.SIGHUP):
        signal.signal(how, signal.SIG_DFL)


def _wait_rows(out: Path, n: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if out.exists() and out.read_text().count("\n") > n:
            return
        time.sleep(0.05)
    raise AssertionError("no rows arrived")


def _assert_valid_partial(out: Path) -> int:
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    assert all(len(line.split(",")) == len(header) for line in lines[1:])
    log = read_log(out)  # parses and validates
    assert np.all(np.diff(log.t) == 1.0)
    return len(log)


def test_killed_client_leaves_a_valid_log_and_the_events_of_its_rows(serve, tmp_path):
    """kill -9 leaves every row acquired, and (written as they come, as the rows are) the
    Modbus events of those rows: the events file used to be written only at the end, so
    fault-report refused a killed run's log."""
    from rig_emulator.faults import faults_from_list

    srv = serve(
        lockstep=True,
        faults=faults_from_list([{"kind": "exception", "unit": 5, "code": 6, "at_s": 50}]),
    )
    out = tmp_path / "killed.csv"
    proc = _start_client(srv.port, out)
    _wait_rows(out, 300)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    rows = _assert_valid_partial(out)
    assert rows >= 300
    meta = read_log(out).meta
    assert meta["complete"] is False  # written at the start, updated at each phase
    events = [
        json.loads(line)
        for line in (tmp_path / "killed.modbus_events.jsonl").read_text().splitlines()
    ]
    # one exception a row from 50 s (the balance, unit 5), up to the last row or so
    times = {e["time_s"] for e in events if e["event"] == "exception" and e["unit"] == 5}
    assert min(times) == 50.0 and max(times) >= 300.0


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_stopped_client_keeps_its_log_and_its_events(serve, tmp_path, how):
    """Ctrl-C, or SIGTERM (timeout, a CI job cancelled, docker stop), or SIGHUP (the
    terminal closed): one line, exit 1, the log valid and the Modbus events file written.
    SIGTERM ended the client silently without its events file, and fault-report then
    refused the log (a new user's probe); SIGHUP ended it at once, rc 129, the meta saying
    nothing (a probe)."""
    srv = serve(lockstep=True)
    out = tmp_path / "stopped.csv"
    proc = _start_client(srv.port, out)
    _wait_rows(out, 100)
    proc.send_signal(how)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert err.count("\n") == 1 and "interrupted" in err and "Traceback" not in err
    rows = _assert_valid_partial(out)
    assert rows >= 100
    assert (tmp_path / "stopped.modbus_events.jsonl").exists()
    # the meta says why the run is not complete (it said nothing: a stranger's probe)
    meta = read_log(out).meta
    assert meta["complete"] is False and meta["interrupted"] is True
    assert f"interrupted (Ctrl-C, SIGTERM or SIGHUP) after {rows} rows" in meta["notes"]


def test_killed_server_ends_the_client_cleanly(tmp_path):
    from tests.conftest import RunningServer

    srv = RunningServer(lockstep=True)
    out = tmp_path / "server_killed.csv"
    proc = _start_client(srv.port, out, "--reconnect-timeout", "1")
    _wait_rows(out, 300)
    srv.stop()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1
    assert "not back within 1 s; the log keeps the " in err and " rows written" in err
    assert "Traceback" not in err
    assert _assert_valid_partial(out) >= 300


def test_profile_and_seed_are_the_servers_and_the_reply_timeout_is_the_users(
    serve, tmp_path, capsys
):
    """--profile and --seed make a local rig's readings; given with a Modbus rig they were
    silently ignored, now a warning says whose they are. --reply-timeout is taken (how long
    it waits is not asserted: no timed bounds here) and a unit under no_reply leaves its
    fields empty for the fault's rows."""
    from rig_emulator.faults import faults_from_list

    srv = serve(faults=faults_from_list([{"kind": "no_reply", "unit": 2, "at_s": 30, "for_s": 20}]))
    out = tmp_path / "log.csv"
    argv = ["--rig", f"modbus://127.0.0.1:{srv.port}", "--out", str(out), "--profile", "lab"]
    assert _run([*argv, "--seed", "4", "--reply-timeout", "0.3"]) == 0
    err = capsys.readouterr().err
    assert "--profile and --seed apply to --rig local" in err
    log = read_log(out)
    silent = np.isnan(log["flue_gas_O2_pct"])
    assert 15 <= silent.sum() <= 25  # the 20 s of the fault, a row a second
    assert log.meta["profile"] == "set by the server"


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupt_between_a_row_and_its_count_waits_for_the_count(how):
    """The sink writes a row and counts it with Ctrl-C and SIGTERM held: a signal that came
    between the two made the meta's row count one short of the log (a flaky CI run)."""
    from hil_client.cli import _restore_signals, _signals_held, _stop_on_signals

    previous = _stop_on_signals()
    if not previous:
        pytest.skip("signal handlers are set on the main thread only; this test runs off it")
    counted = []
    try:
        with pytest.raises(KeyboardInterrupt), _signals_held():
            os.kill(os.getpid(), how)
            time.sleep(0.05)  # delivered here without the hold
            counted.append(1)
        counted.append(2)  # once out of the block, a signal interrupts at once
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), how)
            time.sleep(0.05)
            counted.append(3)
    finally:
        _restore_signals(previous)
    assert counted == [1, 2]
