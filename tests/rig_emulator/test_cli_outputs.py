"""Output files that are no regular file: a FIFO, read or not, and a socket.

A stranger's probe: ``serve --fault-log FIFO`` with no process reading the FIFO listened on
its port, then hung in the open of the FIFO, deaf to SIGINT and SIGTERM (only SIGKILL ended
it, the port held till then). A FIFO a process reads is a fine journal (``tail`` through a
named pipe); one nobody reads, or a socket, is one line and exit 2 before any port opens.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys

import pytest

from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.faults import read_journal
from rig_emulator.registers import encode, load_map
from tests.fifo_helpers import FifoReader
from tests.modbus_helpers import client

#: bound of a server's start-up or stop on a loaded machine (rig_emulator_serve waits 60 s)
START_S = 60.0


def _serve(port: int, *options: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw",
         "--port", str(port), *options],
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _exit_of(proc: subprocess.Popen) -> tuple[int | None, str]:
    """The exit code within START_S (None: still running, then killed) and standard error."""
    try:
        code: int | None = proc.wait(timeout=START_S)
    except subprocess.TimeoutExpired:
        code = None
        proc.kill()
        proc.wait(timeout=30)
    return code, proc.stderr.read() if proc.stderr else ""


def test_a_fault_log_fifo_nobody_reads_is_refused_before_any_port(tmp_path):
    """A stranger's probe: the server logged "serving ... on 127.0.0.1:PORT", then blocked
    opening the FIFO; SIGINT and SIGTERM did nothing, only SIGKILL ended it."""
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    port = free_port()
    proc = _serve(port, "--lockstep", "--fault-log", str(fifo))
    code, err = _exit_of(proc)
    assert code == 2, err
    assert err.count("\n") == 1, err
    assert f"--fault-log: no process reads the FIFO '{fifo}'" in err, err
    assert "serving" not in err  # refused before the port was opened


@pytest.mark.parametrize("stop", [signal.SIGINT, signal.SIGTERM])
def test_a_fault_log_fifo_read_streams_the_journal_and_the_server_stops(tmp_path, stop):
    """A FIFO a process reads stays a journal (the fix refuses only an unread one): its
    lines arrive while the server serves, the stop signal stops it cleanly (exit 0) and
    the reader sees the end of the stream."""
    fifo = tmp_path / "journal.fifo"
    os.mkfifo(fifo)
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 5, code: 6, at_s: 1, for_s: 2}\n")
    reader = FifoReader(fifo)
    port = free_port()
    proc = _serve(port, "--lockstep", "--faults", str(faults), "--fault-log", str(fifo))
    try:
        assert wait_for_port("127.0.0.1", port, START_S, alive=lambda: proc.poll() is None)
        advance = next(p for p in load_map().device("sim_control").points
                       if p.name == "lockstep_advance")  # fmt: skip
        c = client(port, timeout_s=START_S)
        for _ in range(4):  # 4 s: the fault starts at 1 s and ends at 3 s
            assert not c.write_registers(
                advance.address, encode(advance, 1), device_id=100
            ).isError()
        c.close()
        assert reader.wait_for(2, START_S), reader.lines  # streamed before the stop
        proc.send_signal(stop)
    finally:
        code, err = _exit_of(proc)
    assert code == 0, err
    assert "stopping at simulated time 4.0 s" in err and "Traceback" not in err, err
    assert reader.ended(START_S)  # every write end closed at the exit
    journal = tmp_path / "copy.jsonl"
    journal.write_text("".join(reader.lines))
    assert [(e["event"], e["t_sim_s"]) for e in read_journal(journal)] == [
        ("start", 1.0),
        ("end", 3.0),
    ]


def test_a_fault_log_that_is_a_socket_is_refused(tmp_path):
    """A socket took the journal's open for ENXIO: the server served on, the journal lost
    (a warning in its log); it is no file to write, refused in one line."""
    path = tmp_path / "j.sock"
    with socket.socket(socket.AF_UNIX) as listening:
        listening.bind(str(path))
        proc = _serve(free_port(), "--fault-log", str(path))
        code, err = _exit_of(proc)
    assert code == 2, err
    assert err.count("\n") == 1 and f"--fault-log: '{path}' is a socket" in err, err
