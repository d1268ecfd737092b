"""A lab log never splices two plants (CONTRACT section 7): real servers killed with SIGKILL
and restarted on the same port, a second client on a shared lockstep server, a server that
comes back with another seed. Each run ends in a log equal to the uninterrupted one, a
marked break (``rig_epoch``, a gap in the log's time) or a clean abort (exit 1, one line)."""

from __future__ import annotations

import json
import os
import random
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
from hil_client.modbus_client import Connection, read_pdu, registers_of, write_registers_pdu
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.registers import decode, encode, load_map
from tests.hil_client.test_modbus_rig import SHORT, _start_client, assert_logs_equal

BOILER = "windhager_12kw"
_SERVE = (sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", BOILER)


class ServerProcess:
    """``rig-emulator serve`` in its own process on a fixed port; :meth:`kill` is SIGKILL."""

    def __init__(self, port: int, *args: str) -> None:
        self.port = port
        self.proc = subprocess.Popen(
            [*_SERVE, "--port", str(port), *args],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        if not wait_for_port("127.0.0.1", port, 60.0):
            self.kill()
            raise AssertionError(f"no server on port {port}")

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=30)


@pytest.fixture
def servers():
    """``servers(port, *args)`` starts a server process; all are killed after the test."""
    started: list[ServerProcess] = []

    def start(port: int, *args: str) -> ServerProcess:
        server = ServerProcess(port, *args)
        started.append(server)
        return server

    yield start
    for server in started:
        server.kill()


def _rows(out: Path) -> int:
    return out.read_text().count("\n") - 1 if out.exists() else 0


def _wait(predicate, what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


def _run(port: int, out: Path, *extra: str) -> int:
    rig = f"modbus://127.0.0.1:{port}"
    args = ["run", SHORT, "--boiler", BOILER, "--quiet", "--rig", rig, "--out", str(out)]
    return main([*args, "--reconnect-timeout", "30", *extra])


def _meta(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + ".meta.json").read_text())


def _prefix(log, n: int):
    """The first ``n`` rows of a read log (columns and text)."""
    log.columns = {k: v[:n] for k, v in log.columns.items()}
    log.text = {k: v[:n] for k, v in log.text.items()}
    return log


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The short protocol through Modbus in lockstep, never interrupted: (log, CSV text)."""
    from tests.conftest import RunningServer

    srv = RunningServer(lockstep=True)
    out = tmp_path_factory.mktemp("whole") / "whole.csv"
    try:
        assert _run(srv.port, out) == 0
    finally:
        srv.stop()
    return read_log(out), out.read_text()


@pytest.fixture(scope="module")
def local(tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "local.csv"
    assert (
        main(["run", SHORT, "--boiler", BOILER, "--quiet", "--rig", "local", "--out", str(out)])
        == 0
    )
    return out


def test_lockstep_server_killed_twice_is_replayed_into_an_equal_log(
    servers, tmp_path, uninterrupted, local, capsys
):
    port = free_port()
    current = [servers(port, "--lockstep")]
    total = len(uninterrupted[0])
    kill_rows = sorted(random.Random(12).sample(range(200, total - 500), 2))  # seeded points
    out = tmp_path / "replayed.csv"
    killed: list[int] = []

    def killer() -> None:
        for row in kill_rows:
            _wait(lambda row=row: _rows(out) >= row, f"row {row}")
            current[-1].kill()
            killed.append(_rows(out))
            current.append(servers(port, "--lockstep"))

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    assert _run(port, out) == 0
    thread.join(timeout=60)
    assert len(killed) == 2 and max(killed) < total  # both kills came mid-run
    meta = _meta(out)
    replays = [g for g in meta["gaps"] if g["action"] == "replayed"]
    assert len(replays) == 2, meta["gaps"]
    assert meta["complete"] is True
    # each break said on stderr as it came (only a dict on stdout at the end said it; a
    # stranger's probe), in a sentence
    told = [line for line in capsys.readouterr().err.splitlines() if "break after" in line]
    assert len(told) == 2 and all("the server restarted" in line for line in told), told
    assert all("replayed" in line and "{" not in line for line in told), told
    # the log equals the uninterrupted Modbus run byte for byte, and the in-process run to
    # encoding precision (the tolerance of test_modbus_rig)
    assert out.read_text() == uninterrupted[1]
    assert_logs_equal(read_log(local), read_log(out))


def test_server_back_with_another_map_stops_cleanly(servers, tmp_path, capsys):
    """A stranger's probe: a server killed and restarted with the analyser's word order
    changed in its map: the run replayed its commands on it and went on into the same log
    (O2 read as 1.3e11 from then on), exit 0. The map is checked again when a server comes
    back: the run stops where it was, in one line."""
    import yaml

    from rig_emulator.registers.schema import MAP_DIR

    data = yaml.safe_load((MAP_DIR / "wieselburg_bench.yaml").read_text())
    analyser = next(d for d in data["devices"] if d["unit_id"] == 2)
    analyser["word_order"] = "ABCD" if analyser.get("word_order") != "ABCD" else "CDAB"
    other = tmp_path / "other_map.yaml"
    other.write_text(yaml.safe_dump(data))
    port = free_port()
    first = servers(port, "--lockstep")
    out = tmp_path / "map.csv"

    def killer() -> None:
        _wait(lambda: _rows(out) >= 1000, "row 1000")
        first.kill()
        servers(port, "--lockstep", "--map", str(other))

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    code = _run(port, out)
    # the second server is registered once it listens, which the run may see first: wait
    # for it, so the fixture stops it (it outlived a CI run otherwise)
    thread.join(timeout=90)
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "came back as another plant (the server serves another register map" in err
    log = read_log(out)
    assert len(log) >= 1000 and set(log.columns["rig_epoch"]) == {0.0}
    assert _meta(out)["gaps"][-1]["action"] == "abort"


def test_server_back_with_another_seed_stops_cleanly(servers, tmp_path, capsys, local):
    port = free_port()
    first = servers(port, "--lockstep", "--seed", "0")
    out = tmp_path / "seed.csv"

    def killer() -> None:
        _wait(lambda: _rows(out) >= 1000, "row 1000")
        first.kill()
        servers(port, "--lockstep", "--seed", "7")

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    code = _run(port, out)
    # the second server is registered once it listens, which the run may see first: wait
    # for it, so the fixture stops it (it outlived a CI run otherwise)
    thread.join(timeout=90)
    err = capsys.readouterr().err
    assert code == 1
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "came back as another plant (seed 7, was 0)" in err
    log = read_log(out)  # valid up to the break
    assert len(log) >= 1000 and set(log.columns["rig_epoch"]) == {0.0}
    assert_logs_equal(_prefix(read_log(local), len(log)), log)
    meta = _meta(out)
    assert meta["complete"] is False
    assert meta["gaps"][-1]["action"] == "abort" and "seed 7" in meta["gaps"][-1]["reason"]
    assert meta["gaps"][-1]["start_time_s"] == log.t[-1]


def _advance_from_another_client(port: int, seconds: float) -> None:
    dev, point = load_map().point("lockstep_advance_s")
    conn = Connection("127.0.0.1", port, 5.0)
    conn.send([(dev.unit_id, write_registers_pdu(point.address, encode(point, seconds)))])
    conn.receive()
    conn.close()


def test_another_client_advancing_a_lockstep_server_aborts_by_default(
    serve, tmp_path, capsys, local
):
    srv = serve(lockstep=True)
    out = tmp_path / "shared.csv"

    def other() -> None:
        _wait(lambda: _rows(out) >= 500, "row 500")
        _advance_from_another_client(srv.port, 3600)

    threading.Thread(target=other, daemon=True).start()
    code = _run(srv.port, out)
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1
    assert "another client advanced the server" in err and "--on-restart abort" in err
    log = read_log(out)
    # no row of the advanced plant: every row equals the undisturbed run's
    assert_logs_equal(_prefix(read_log(local), len(log)), log)
    assert _meta(out)["gaps"][-1]["action"] == "abort"


def test_a_second_run_on_a_busy_server_names_no_row_it_never_wrote(serve, tmp_path, capsys):
    """Two runs on one lockstep server: the second finds it advanced by the first before
    it wrote a row. Its gap says so: ``start_time_s`` is the last row before the break,
    None when there is none (it was 0.0, a row that never existed)."""
    srv = serve(lockstep=True)
    first, second = tmp_path / "first.csv", tmp_path / "second.csv"
    codes: list[int] = []
    thread = threading.Thread(target=lambda: codes.append(_run(srv.port, first)), daemon=True)
    thread.start()
    _wait(lambda: _rows(first) >= 200, "row 200 of the first run")
    assert _run(srv.port, second) == 1
    thread.join(timeout=120)
    # it said the server was not fresh (it started without a word: a stranger's probe)
    assert "warning: the server is not fresh (simulated time" in capsys.readouterr().err
    gap = _meta(second)["gaps"][-1]
    assert gap["action"] == "abort"
    rows = _rows(second)
    if rows == 0:  # the usual case: the first run advanced it before the second's first step
        assert gap["start_time_s"] is None
    else:
        assert gap["start_time_s"] == read_log(second).t[-1]


@pytest.mark.parametrize("on_restart", ["continue", "restart-phase"])
def test_another_client_advancing_is_a_marked_break(serve, tmp_path, local, on_restart):
    srv = serve(lockstep=True)
    out = tmp_path / "shared.csv"

    def other() -> None:
        _wait(lambda: _rows(out) >= 1500, "row 1500")
        _advance_from_another_client(srv.port, 3600)

    threading.Thread(target=other, daemon=True).start()
    assert _run(srv.port, out, "--on-restart", on_restart) == 0
    log = read_log(out)  # time_s strictly increasing (checked by read_log)
    epoch = log.columns["rig_epoch"]
    n0 = int(np.sum(epoch == 0))
    assert set(epoch) == {0.0, 1.0} and np.all(epoch[:n0] == 0)
    # before the break: the undisturbed run; across it the log time jumps by what the
    # plant lived through without this client (3600 s of the other client, 1 s of this
    # client's step whose reads were discarded)
    assert_logs_equal(_prefix(read_log(local), n0), _prefix(read_log(out), n0))
    (gap,) = log.meta["gaps"]
    assert gap["action"] == on_restart and gap["rig_epoch"] == 1
    assert gap["start_time_s"] == log.t[n0 - 1] and gap["end_time_s"] == log.t[n0]
    assert log.t[n0] - log.t[n0 - 1] == 3602.0
    notes = " ".join(log.meta["notes"])
    if on_restart == "restart-phase":
        assert "restarted at time_s" in notes
        phase = log.text["phase"][n0]
        mark = {"start_up": "t0_s", "test": "t1_s", "cooling_1": "t2_s", "cooling_2": "t3_s"}
        if phase in mark:  # a restart moves no mark: a phase's start mark is where the
            # phase before it ended (cooling_1's restart moved t2, the test's end: a probe)
            assert log.meta[mark[phase]] < log.t[n0]
            assert gap["phase_restarted"] == phase
    else:  # the note names the break as it was, not "a new plant" (a stranger's probe)
        assert "rig_epoch 1" in notes and "another client advanced the server" in notes
        assert "a new plant" not in notes


def test_a_run_of_many_breaks_says_ten_and_counts_the_rest(serve, tmp_path, capsys):
    """A stranger's probe: two clients stepping one lockstep server with --on-restart
    continue made 1018 breaks, a console line each, and a balance warning of kilobytes
    listing them. Ten are said as they come, then one line; the analyses list three."""
    srv = serve(lockstep=True)
    out = tmp_path / "busy.csv"

    def other() -> None:
        for n in range(12):
            _wait(lambda n=n: _rows(out) >= 1000 + 200 * n, f"row {1000 + 200 * n}")
            _advance_from_another_client(srv.port, 60)

    threading.Thread(target=other, daemon=True).start()
    assert _run(srv.port, out, "--on-restart", "continue") == 0
    err = capsys.readouterr().err
    assert err.count("break after") == 10 and "more than 10 breaks" in err, err
    assert len(_meta(out)["gaps"]) == 12
    from hil_client.analysis.logio import one_plant

    warning = next(n for n in one_plant(read_log(out)).notes if "plants" in n)
    assert "and 9 more" in warning and len(warning) < 600, warning
    # a plant without a whole test: said as such, not as "the run was cut short (its
    # meta file records no mark)" while it records all five
    balance = ["balance", str(out), "--boiler", BOILER, "--out", str(tmp_path / "b.json")]
    assert main(balance) == 2  # the longest plant holds no whole test (which one is the
    err = capsys.readouterr().err  # longest depends on the machine's load)
    assert "the rows of the log's longest plant (rig_epoch " in err and "cut short" not in err


def _realtime_client(port: int, out: Path, *extra: str) -> subprocess.Popen:
    return _start_client(port, out, "--reconnect-timeout", "30", *extra)


def test_realtime_restart_aborts_cleanly_by_default(servers, tmp_path):
    port = free_port()
    first = servers(port, "--speed", "200")
    out = tmp_path / "rt.csv"
    client = _realtime_client(port, out)
    kill_row = random.Random(21).randint(10, 60)  # a seeded random point
    try:
        _wait(lambda: _rows(out) >= kill_row, f"{kill_row} rows")
        first.kill()
        servers(port, "--speed", "200")
        _, err = client.communicate(timeout=60)
    finally:
        if client.poll() is None:
            client.kill()
    assert client.returncode == 1
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "the server restarted (a new plant)" in err and "--on-restart abort" in err
    log = read_log(out)
    assert set(log.columns["rig_epoch"]) == {0.0}
    gap = log.meta["gaps"][-1]
    assert gap["action"] == "abort" and gap["start_time_s"] == log.t[-1]
    assert gap["end_time_s"] is None


def _epoch_id(port: int) -> str:
    """The server's ``epoch_id`` as its fault journal writes it (8 hex digits)."""
    dev, point = load_map().point("epoch_id")
    c = Connection("127.0.0.1", port, 5.0)
    try:
        c.send(
            [
                (
                    dev.unit_id,
                    read_pdu(4 if point.table == "input" else 3, point.address, point.width),
                )
            ]
        )
        return f"{int(decode(point, registers_of(c.receive()))):08x}"
    finally:
        c.close()


def test_realtime_restart_with_continue_is_a_marked_break(servers, tmp_path):
    """... and the meta names the server start of its rows, as their fault journals do:
    ``server_epoch_id`` (the first server's) and the gap's (the server's after it). A
    stranger's probe: the fault report matched each journal with the rows of either plant,
    the meta saying no more than ``rig_epoch`` (a count, not which server)."""
    port = free_port()
    first = servers(port, "--speed", "200")
    first_epoch = _epoch_id(port)
    out = tmp_path / "rt.csv"
    client = _realtime_client(port, out, "--on-restart", "continue")
    kill_row = random.Random(22).randint(10, 60)  # a seeded random point
    try:
        _wait(lambda: _rows(out) >= kill_row, f"{kill_row} rows")
        first.kill()
        servers(port, "--speed", "200")
        second_epoch = _epoch_id(port)
        _wait(lambda: out.read_text().count(",1\n") >= 10, "10 rows of rig_epoch 1")
        # the meta file is written as the run goes: the gap is there before the run ends
        client.send_signal(signal.SIGKILL)
        client.wait(timeout=30)
    finally:
        if client.poll() is None:
            client.kill()
    text = out.read_text()
    out.write_text(text[: text.rfind("\n") + 1])  # a row cut by SIGKILL is not the test's
    log = read_log(out)  # time_s strictly increasing across the break
    epoch = log.columns["rig_epoch"]
    n0 = int(np.sum(epoch == 0))
    assert set(epoch) == {0.0, 1.0} and np.all(epoch[:n0] == 0)
    (gap,) = log.meta["gaps"]
    assert gap["action"] == "continue" and gap["rig_epoch"] == 1
    assert gap["reason"] == "the server restarted (a new plant)"
    assert gap["start_time_s"] == log.t[n0 - 1] and gap["end_time_s"] == log.t[n0]
    # the jump is at least the wall-clock outage at x200 (rounded in the meta to 1 ms)
    assert log.t[n0] - log.t[n0 - 1] >= (gap["outage_wall_s"] - 0.001) * 200
    assert log.meta["complete"] is False
    assert first_epoch != second_epoch  # (random 32 bits per start)
    assert log.meta["server_epoch_id"] == first_epoch
    assert gap["server_epoch_id"] == second_epoch


def test_meta_file_is_replaced_atomically(tmp_path):
    from hil_client.lablog import meta_path, write_meta

    out = tmp_path / "x.csv"
    write_meta(out, {"gaps": [1]})
    write_meta(out, {"gaps": [1, 2]})
    assert json.loads(meta_path(out).read_text()) == {"gaps": [1, 2]}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.meta.json"]  # no temporary left
    assert os.path.exists(meta_path(out))
    # a re-probe: a symlinked meta file was replaced by a plain file, its target left as was
    target = tmp_path / "other.json"
    target.write_text("{}")
    linked = tmp_path / "y.csv"
    meta_path(linked).symlink_to(target)
    write_meta(linked, {"gaps": []})
    assert meta_path(linked).is_symlink() and json.loads(target.read_text()) == {"gaps": []}


def test_servers_publish_a_new_epoch_per_start_and_their_set_up(serve):
    a, b = serve(seed=3), serve(seed=3)
    c = serve(seed=3, profile="lab")
    d = serve(seed=4, boiler="windhager_6kw")
    va, vb, vc, vd = (s.values() for s in (a, b, c, d))
    assert va["epoch_id"] != vb["epoch_id"]  # random 32-bit: equal once in 4e9 starts
    for key in ("boiler_id", "profile_id", "seed"):
        assert va[key] == vb[key]
    assert vc["profile_id"] != va["profile_id"] and vc["boiler_id"] == va["boiler_id"]
    assert vd["boiler_id"] != va["boiler_id"] and vd["seed"] == 4.0


def test_a_run_stopped_by_an_outage_names_the_unit_that_was_silent(servers, tmp_path, capsys):
    """A re-probe: a unit silent for minutes before the server went away (an outage longer
    than --reconnect-timeout) had its readings empty in most rows, and the stopped run said
    nothing of it, though a finished or interrupted one did."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: no_reply, unit: 2, at_s: 0}\n")
    port = free_port()
    server = servers(port, "--lockstep", "--faults", str(faults))
    out = tmp_path / "stopped.csv"

    def killer() -> None:
        _wait(lambda: _rows(out) >= 300, "row 300")
        server.kill()

    thread = threading.Thread(target=killer, daemon=True)
    thread.start()
    code = _run(port, out, "--reconnect-timeout", "1")
    thread.join(timeout=90)
    err = capsys.readouterr().err
    assert code == 1, err
    lines = err.splitlines()
    told = [line for line in lines if "unit 2 never answered a read of this run" in line]
    assert len(told) == 1 and told[0].startswith("hil-client: warning: "), err
    assert lines[-1].startswith("hil-client: error: ") and "not back within 1 s" in lines[-1]
    notes = _meta(out)["notes"]
    assert any("unit 2 never answered a read of this run" in n for n in notes), notes
