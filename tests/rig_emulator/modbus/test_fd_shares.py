"""How the Modbus server shares the process's file descriptors out, and what its log says
when they run short, each against a real ``rig-emulator serve`` under a low RLIMIT_NOFILE
(:mod:`tests.rig_emulator.fd_limits`): a re-probe of the descriptor fit of f80501b."""

from __future__ import annotations

import functools
import socket
import subprocess
import sys
import time

from hil_client.wait_for_port import free_port
from tests.rig_emulator.fd_limits import (
    REPO,
    close_all,
    http_get,
    kernels_loaded,
    limit_descriptors,
    modbus_read,
    serving_limited,
    take_descriptors,
)
from tests.rig_emulator.modbus.raw import Replies, connect, frame, read_pdu

READ_TIME = frame(1, 100, read_pdu(4, 0, 4))  # unit 100's simulated time: answered at once
READ_PLC = frame(2, 1, read_pdu(4, 0, 1))  # unit 1's first input register


def _answered(sock: socket.socket) -> bool:
    """Whether ``sock``, a client that read once already, is answered a read again (not
    closed meanwhile by the connection limit)."""
    try:
        sock.sendall(READ_TIME)
        return Replies(sock).next()[2][:1] == b"\x04"
    except (OSError, AssertionError):
        return False


def _clients_still_answered(port: int, count: int) -> int:
    """How many of ``count`` clients, each of which read once (used, so counted in the
    limit), are answered a read again once all are connected."""
    clients: list[socket.socket] = []
    try:
        for _ in range(count):
            clients.append(connect(port))
            clients[-1].sendall(READ_TIME)
            Replies(clients[-1]).next()
        time.sleep(0.5)  # (a connection the limit closed is closed by now)
        return sum(_answered(sock) for sock in clients)
    finally:
        close_all(clients)


def test_without_http_no_descriptors_are_kept_for_a_dashboard(tmp_path):
    """A re-probe: under an open-file limit of 128 (soft and hard), ``serve`` without
    ``--http`` and the default 100 connections served 61 of 100 clients at once, "with
    room for the dashboard's 29 connections", a dashboard not running (the build before
    served all 100; under 1024 with --max-connections 900: 731 against 900). Now a
    server without a dashboard keeps no descriptor for one: 100 clients fit in 128
    descriptors, and nothing is lowered."""
    with serving_limited(tmp_path / "serve.log", nofile=128) as served:
        kernels_loaded(served.port)
        answered = _clients_still_answered(served.port, 100)
    lines = served.lines()
    assert answered == 100, [line for line in lines if "connection" in line][-5:]
    assert not any("does not fit" in line or "dashboard" in line for line in lines), lines[:3]


def test_out_of_descriptors_with_none_unused_is_one_line_not_a_count_of_retries(tmp_path):
    """A re-probe: a process out of descriptors whose every Modbus connection had a request
    waiting logged "no file descriptor left for a new connection, none unused" and then
    counted each retry of the accept (0.01 s doubling to 1 s apart) as a connection
    "closed or refused for the process's open-file limit", said at the stop, though none
    was closed or refused (the new ones wait in the backlog). Now such a shortage is one
    line, and only connections closed are counted."""
    faults = tmp_path / "faults.yaml"  # unit 1 answers a minute late: its client waits
    faults.write_text("faults:\n  - {kind: delay, unit: 1, delay_ms: 60000, at_s: 0}\n")
    with serving_limited(tmp_path / "serve.log", "--faults", str(faults), take_all_but=0) as served:
        kernels_loaded(served.port)
        busy = connect(served.port)
        waiting: list[socket.socket] = [busy]
        try:
            busy.sendall(READ_PLC)  # its request waits: the connection is not unused
            time.sleep(0.3)
            assert take_descriptors(served) > 0
            waiting.append(connect(served.port))  # accepted by the kernel, then EMFILE
            time.sleep(4.0)  # about 10 retries: 0.01 s doubling up to 1 s apart
        finally:
            close_all(waiting)
    lines = served.lines()
    said = [line for line in lines if "no file descriptor left for a new connection" in line]
    assert len(said) == 1 and "none unused" in said[0], lines
    assert not any("open-file limit not logged" in line for line in lines), lines
    assert not any("shortages" in line for line in lines), lines  # one shortage, logged
    assert not any("Traceback" in line for line in lines), lines


def test_a_dashboard_beside_keeps_a_few_descriptors_not_a_quarter(tmp_path):
    """A re-probe: under a hard open-file limit of 1024, ``--max-connections 1000 --http``
    served 725 of the 1000 clients the build before the descriptor fit served, "with room
    for the dashboard's 252 connections": a quarter of the descriptors kept for a
    dashboard nobody used. Where not everything fits, the dashboard keeps a few (a
    browser's), and a shortage later is met by closing the oldest unused connection. Here
    under 128: the default 100 clients and a dashboard all fit, as before."""
    http = free_port()
    with serving_limited(tmp_path / "serve.log", "--http", str(http), http=http,
                         nofile=128) as served:  # fmt: skip
        kernels_loaded(served.port)
        answered = _clients_still_answered(served.port, 100)
        page = http_get(http, "/api/state")
    lines = served.lines()
    assert answered == 100, [line for line in lines if "connection" in line][-5:]
    assert not any("does not fit" in line for line in lines), lines[:3]
    assert page.startswith(b"HTTP/1.1 200"), page[:100]


def test_a_limit_that_leaves_no_connection_is_refused_in_one_line(tmp_path):
    """A re-probe: under ``ulimit -n 16`` with a pty and the dashboard, the start's line
    said "serving at most 1 connections", and neither a Modbus client nor the dashboard
    was ever answered (the server's own descriptors took the whole limit). Now such a
    limit is refused at the start, naming the limit to raise it to; one that leaves room
    serves."""
    serve = [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw"]
    serve += ["--lockstep", "--port", "0", "--serial", "pty", "--http", "0"]
    done = subprocess.run(
        serve,
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=functools.partial(limit_descriptors, 16),
        cwd=REPO,
    )
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr
    assert "leaves no descriptor for a connection" in lines[-1], lines
    assert "Traceback" not in done.stderr, done.stderr
    least = int(lines[-1].rsplit("ulimit -n ", 1)[1].rstrip(")"))
    http = free_port()
    options = ("--serial", "pty", "--http", str(http))
    with serving_limited(tmp_path / "serve.log", *options, http=http, nofile=least) as served:
        assert modbus_read(served.port)[7:8] == b"\x04"  # (FC 4 answered)
        assert http_get(http, "/api/state").startswith(b"HTTP/1.1 200")
