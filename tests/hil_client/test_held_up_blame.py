"""Whose a lost connection was, against real processes: a real ``rig-emulator serve`` with
an idle timeout and a real ``hil-client run`` stopped with SIGSTOP and let go on with
SIGCONT. A server's idle timeout closes a client held up that long; the gap says the client
was held up, and a connection the server closed of its own keeps the server's cause."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil_client.rigs.modbus import HELD_UP_S
from hil_client.wait_for_port import free_port, wait_for_port
from tests.hil_client.timed_protocol import timed_protocol

BOILER = "windhager_12kw"
SPEED = 100.0  # rows 10 s apart (the server's 10-Hz tick), the first cooling 6 s of wall
# phases ended by time-outs; the first cooling (600 s, 60 rows) is where things happen
RT = timed_protocol("rt", [("stationary_100", 100, 60)], cooling_1_s=600, cooling_2_after_t2_s=700)
RUN_TIMEOUT_S = 120.0  # the whole run: about 9 s of wall at x100, and the pause


def _serve(tmp_path: Path, *args: str) -> tuple[subprocess.Popen, int, Path]:
    """``rig-emulator serve`` at x100 in its own process on a free port; its log's path."""
    port = free_port()
    log = tmp_path / "serve.log"
    with open(log, "w") as fh:
        proc = subprocess.Popen(
            [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", BOILER,
             "--port", str(port), "--speed", f"{SPEED:g}", *args],
            stdout=fh, stderr=subprocess.STDOUT,
        )  # fmt: skip
    if not wait_for_port("127.0.0.1", port, 60.0):
        proc.kill()
        raise AssertionError(f"no server on port {port}")
    return proc, port, log


def _run(tmp_path: Path, port: int, *options: str) -> tuple[subprocess.Popen, Path]:
    """``hil-client run`` of :data:`RT` in its own process; the log's path."""
    protocol = tmp_path / "rt.yaml"
    protocol.write_text(RT)
    out = tmp_path / "rt.csv"
    proc = subprocess.Popen(
        [sys.executable, "-m", "hil_client.cli", "run", str(protocol), "--boiler", BOILER,
         "--rig", f"modbus://127.0.0.1:{port}", "--quiet", "--out", str(out), *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    return proc, out


def _wait_for_cooling_rows(out: Path, proc: subprocess.Popen, rows: int) -> None:
    """Until the log holds ``rows`` rows of the first cooling (the run well under way)."""
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline and proc.poll() is None:
        lines = out.read_text().splitlines()[1:] if out.exists() else []
        if sum(1 for line in lines if ",cooling_1," in line) >= rows:
            return
        time.sleep(0.01)
    raise AssertionError(f"no {rows} rows of the first cooling in {out}")


def _finish(proc: subprocess.Popen) -> tuple[int, str]:
    """The run's exit code and its stderr, killed after :data:`RUN_TIMEOUT_S`."""
    try:
        _, err = proc.communicate(timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        raise AssertionError(f"the run did not end within {RUN_TIMEOUT_S:g} s: {err}") from None
    return proc.returncode, err


def _meta(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + ".meta.json").read_text())


# (the server's idle timeout [s], the client stopped this long [s]): three times it, and a
# re-probe's sub-second timeout (serve takes fractions), the stop under a second
@pytest.mark.parametrize(("idle_timeout_s", "pause_s"), [(1.0, 3.0), (0.5, 0.9)])
def test_a_client_paused_past_the_idle_timeout_is_named_held_up(tmp_path, idle_timeout_s, pause_s):
    """A stranger's probe: ``hil-client run`` against ``serve --speed 500 --idle-timeout 3``,
    SIGSTOPped for 8 s and let go on: the server closed its connection as idle, and the run
    said "break after time_s = 11650 s, rows again from 15650 s: connection lost (connection
    closed by the server); reconnected", the meta's gap the same: nothing said the client
    was held up (without the idle close, the run's hole note named it). The gap's reason and
    the line on stderr say it was, and how long; ``client_held_up_s`` gives the figure."""
    server, port, server_log = _serve(tmp_path, "--idle-timeout", f"{idle_timeout_s:g}")
    try:
        client, out = _run(tmp_path, port)
        try:
            _wait_for_cooling_rows(out, client, 15)
            client.send_signal(signal.SIGSTOP)
            time.sleep(pause_s)
        finally:
            client.send_signal(signal.SIGCONT)
            code, err = _finish(client)
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=30)
    # the server closed it as idle (the stranger's precondition)
    said = f"(--idle-timeout {idle_timeout_s:g})"
    assert said in server_log.read_text(), server_log.read_text()
    assert code == 0, err
    (gap,) = _meta(out)["gaps"]
    assert gap["action"] == "reconnected" and gap["rig_epoch"] == 0, gap  # the same plant
    assert gap["reason"].startswith("connection lost ("), gap  # (as before: extended)
    assert "after this client was held up" in gap["reason"], gap
    # the heartbeat wakes every 50 ms (hil_client.rigs.holdups.PERIOD_S): the stop may
    # begin anywhere in one sleep, so up to one period of it is not counted; and the time
    # since the last row is the pause and a few milliseconds of steps
    assert pause_s - 0.1 <= gap["client_held_up_s"] <= gap["outage_wall_s"], gap
    held = float(re.search(r"held up ([\d.]+) s", gap["reason"])[1])
    assert abs(held - gap["client_held_up_s"]) < 0.1, gap  # (the reason's to 0.1 s)
    told = [line for line in err.splitlines() if line.startswith("hil-client: break")]
    assert len(told) == 1 and "after this client was held up" in told[0], err


def test_a_connection_the_server_closed_keeps_the_server_s_cause(tmp_path):
    """The other side of the probe above: a server that closes the connection of its own (a
    ``disconnect`` fault), the client not held up, is recorded as before, with the
    server's cause alone, and ``client_held_up_s`` under :data:`HELD_UP_S`."""
    faults = tmp_path / "faults.yaml"  # (JSON is YAML)
    faults.write_text(json.dumps({"faults": [{"kind": "disconnect", "at_s": 400}]}))
    server, port, _ = _serve(tmp_path, "--faults", str(faults))
    try:
        client, out = _run(tmp_path, port)
        code, err = _finish(client)
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=30)
    assert code == 0, err
    meta = _meta(out)
    if meta["server_time_offset_s"] >= 400.0:  # (a CI run beside other work: no gap)
        pytest.skip("the client connected after the disconnect (a loaded machine's start)")
    (gap,) = meta["gaps"]
    assert gap["action"] == "reconnected" and gap["rig_epoch"] == 0, gap
    assert gap["reason"].startswith("connection lost ("), gap
    assert "held up" not in gap["reason"] and gap["client_held_up_s"] < HELD_UP_S, gap


def test_a_client_held_up_while_the_server_stalled_keeps_its_own_timeout(tmp_path):
    """A re-probe: the server stopped 6 s, the client stopped 1.5 s inside that: the client's
    own reply timeout gave up, nothing closed the connection, and the reason said "after
    this client was held up 1.5 s ...: a server's idle timeout closes a client silent that
    long". A connection the server did not close keeps its reason; the hold-up is the
    figure ``client_held_up_s``."""
    server, port, _ = _serve(tmp_path)
    try:
        client, out = _run(tmp_path, port, "--reply-timeout", "2")
        try:
            _wait_for_cooling_rows(out, client, 15)
            server.send_signal(signal.SIGSTOP)
            time.sleep(0.5)
            client.send_signal(signal.SIGSTOP)
            time.sleep(1.5)
            client.send_signal(signal.SIGCONT)
            time.sleep(4.0)  # (past the client's reply timeout)
        finally:
            client.send_signal(signal.SIGCONT)
            server.send_signal(signal.SIGCONT)
            code, err = _finish(client)
    finally:
        server.send_signal(signal.SIGTERM)
        server.wait(timeout=30)
    assert code == 0, err
    gaps = _meta(out)["gaps"]
    assert gaps and all("held up" not in gap["reason"] for gap in gaps), gaps
    assert max(gap["client_held_up_s"] for gap in gaps) >= 1.4, gaps  # (the figure stays)
