"""The dashboard's HTTP connections are bounded: idle ones cannot take the process's file
descriptors, and a process out of them sheds an idle one; each against a real
``rig-emulator serve --http`` under a low RLIMIT_NOFILE (:mod:`tests.rig_emulator.fd_limits`)."""

from __future__ import annotations

import contextlib
import re
import socket
import struct
import time
from pathlib import Path

from hil_client.wait_for_port import free_port
from rig_emulator.certs import make_lab_certificates
from tests.rig_emulator.fd_limits import (
    NOFILE,
    close_all,
    http_get,
    idle_connections,
    kernels_loaded,
    modbus_read,
    serving_limited,
    take_descriptors,
)

#: log lines a test's whole run may write: the start's (the Modbus limit's line, the
#: dashboard's, "serving"), the dashboard's shedding at most once a minute and its count at
#: the stop, the Modbus client's connect and disconnect, "stopping". The flood this
#: replaced: 2958 tracebacks
MAX_LOG_LINES = 12


def _answered(response: bytes) -> bool:
    """Whether ``response`` is the state, whole (a JSON object after the head)."""
    head, _, body = response.partition(b"\r\n\r\n")
    return head.startswith(b"HTTP/1.1 200") and body.startswith(b"{") and body.endswith(b"}")


def test_idle_http_connections_cannot_take_the_descriptors_modbus_and_http_need(tmp_path):
    """A stranger's probe: 1100 idle TCP connections to the dashboard's port under
    ``ulimit -n 1024``, the default options otherwise: every descriptor taken (the HTTP port
    had no connection limit), 2958 "Too many open files" tracebacks. Now the dashboard holds
    its share of the descriptors at most, a new connection closing the one that has waited
    longest for its request: a new HTTP client and a Modbus client are both answered."""
    http = free_port()
    with serving_limited(tmp_path / "serve.log", "--http", str(http), http=http) as served:
        idle = idle_connections(http, 3 * NOFILE)
        try:
            state = http_get(http, "/api/state")
            reply = modbus_read(served.port)
        finally:
            close_all(idle)
    lines = served.lines()
    assert len(idle) == 3 * NOFILE, lines[-5:]
    assert _answered(state), (state[:200], lines[-5:])
    assert reply[6:9] == b"\x64\x04\x08", (reply, lines[-5:])
    assert not any("Traceback" in line or "Too many open files" in line for line in lines)
    shed = [line for line in lines if "HTTP connections open (its limit)" in line]
    assert len(shed) == 1 and "closed the one waiting longest for its request" in shed[0]
    assert len(lines) <= MAX_LOG_LINES, lines


def test_descriptors_taken_by_others_shed_an_idle_http_connection_for_a_new_one(tmp_path):
    """The process out of descriptors below the dashboard's own limit (files, Modbus
    connections took them): an accept that finds no descriptor closes the HTTP connection
    that has waited longest for its request, and the new client is answered; one line."""
    http = free_port()
    with serving_limited(
        tmp_path / "serve.log", "--http", str(http), http=http, take_all_but=3
    ) as served:
        assert _answered(http_get(http, "/api/state"))  # (the page's state built once)
        assert take_descriptors(served) > 0
        idle = idle_connections(http, NOFILE)
        try:
            state = http_get(http, "/api/state")
        finally:
            close_all(idle)
    lines = served.lines()
    assert _answered(state), (state[:200], lines[-5:])
    assert not any("Traceback" in line or "Too many open files" in line for line in lines)
    said = [line for line in lines if "no file descriptor left for a new HTTP connection" in line]
    assert len(said) == 1 and "closed the one waiting longest for its request" in said[0]
    assert len(lines) <= MAX_LOG_LINES, lines


def test_two_hundred_slowloris_requests_are_all_answered(served):
    """Kept from a stranger's probe: 200 connections each trickling its request in a few
    bytes at a time were all answered (the limit is above them: it sheds only beyond)."""
    _, http = served("--lockstep")
    request = b"GET /api/state HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n"
    slow = [socket.create_connection(("127.0.0.1", http), timeout=20) for _ in range(200)]
    try:
        for start in range(0, len(request), 8):  # 6 rounds, 0.2 s apart: 1 s a request
            for sock in slow:
                sock.sendall(request[start : start + 8])
            time.sleep(0.2)
        answers = []
        for sock in slow:
            answer = b""
            while chunk := sock.recv(65536):
                answer += chunk
            answers.append(answer)
    finally:
        close_all(slow)
    assert all(_answered(a) for a in answers), sum(not _answered(a) for a in answers)


def _tls_options(certs: Path) -> list[str]:
    """``serve``'s TLS options with the certificates of ``rig-emulator certs`` in ``certs``."""
    make_lab_certificates(certs)
    files = (("cert", "server.pem"), ("key", "server.key"), ("ca", "ca.pem"))
    return [f"--tls-{kind}={certs / name}" for kind, name in files]


def _dashboard_share(lines: list[str]) -> int:
    """The dashboard's connections the start's line makes room for."""
    said = [line for line in lines if "does not fit" in line]
    assert len(said) == 1, lines[:5]
    found = re.search(r"with room for the dashboard's (\d+) connections", said[0])
    assert found, said[0]
    return int(found.group(1))


def test_at_a_tiny_open_file_limit_every_listener_leaves_the_dashboard_its_share(tmp_path):
    """A re-probe: under ``ulimit -n 24`` with TLS, ``--tcp-port``, ``--serial pty``,
    ``--http`` and ``--fault-log``, 9 Modbus clients and one live stream took every
    descriptor: a GET /api/state waited 20 s unanswered though the dashboard held 1 of its
    4 connections (the shares were made with 7 descriptors open, before the listeners,
    the pty and the journal), and each retry of its accept was counted as "HTTP
    connections closed for a file descriptor" (25), none was. Now the server's own
    descriptors are counted first: the Modbus clients beyond its share close the oldest
    unused one, and the dashboard's client is answered."""
    http, tcp = free_port(), free_port()
    options = [
        *_tls_options(tmp_path / "certs"),
        *("--tcp-port", str(tcp), "--serial", "pty", "--http", str(http)),
        *("--fault-log", str(tmp_path / "journal.jsonl")),
    ]
    with serving_limited(tmp_path / "serve.log", *options, http=http, nofile=24) as served:
        clients = [socket.create_connection(("127.0.0.1", tcp), timeout=5) for _ in range(9)]
        stream = socket.create_connection(("127.0.0.1", http), timeout=5)
        try:
            for sock in clients:
                with contextlib.suppress(OSError):  # (one the limit closed: reset)
                    sock.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 100, 4, 0, 4))
                    sock.recv(64)
            stream.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            assert stream.recv(64).startswith(b"HTTP/1.1 200"), served.lines()[-5:]
            started = time.monotonic()
            state = http_get(http, "/api/state")
            waited_s = time.monotonic() - started
        finally:
            close_all([*clients, stream])
    lines = served.lines()
    assert _answered(state), (state[:200], waited_s, lines[-5:])
    assert _dashboard_share(lines) >= 2  # the stream and the GET
    assert not any("descriptor not logged" in line for line in lines), lines
    assert not any("Traceback" in line for line in lines), lines


def _every_listener_limited(tmp_path: Path, http: int):
    """``serve`` under the open-file limit with TLS, a second TCP port, a pty and the
    dashboard on ``http``: the dashboard's share as small as the limits make it."""
    options = (*_tls_options(tmp_path / "certs"), "--tcp-port", "0", "--serial", "pty")
    return serving_limited(tmp_path / "serve.log", *options, "--http", str(http), http=http)


def test_the_dashboards_limit_is_the_share_the_start_line_names(tmp_path):
    """A re-probe: the start's line said "with room for the dashboard's 6 connections"
    while the dashboard logged "4 HTTP connections open (its limit)": it made its share
    again, with the descriptors open once the other listeners were. Now one computation
    gives both: connections beyond the share the line names close the oldest idle one."""
    http = free_port()
    with _every_listener_limited(tmp_path, http) as served:
        share = _dashboard_share(served.lines())
        idle = idle_connections(http, share + 1)
        try:
            time.sleep(0.5)  # (the last one accepted, the oldest closed for it)
        finally:
            close_all(idle)
    lines = served.lines()
    at_limit = [line for line in lines if "HTTP connections open (its limit)" in line]
    assert len(at_limit) == 1 and f"dashboard: {share} HTTP connections open" in at_limit[0], (
        share,
        at_limit,
    )


def test_out_of_descriptors_with_no_idle_http_connection_is_one_line_not_a_count(tmp_path):
    """A re-probe: the process out of descriptors with no HTTP connection waiting for its
    request (a live stream): "none waits for its request", then each retry of the accept
    (0.01 s doubling to 1 s apart) counted as an HTTP connection "closed for a file
    descriptor", said at the stop; none was closed. Now one line for the shortage, and
    only connections closed are counted."""
    http = free_port()
    with serving_limited(
        tmp_path / "serve.log", "--http", str(http), http=http, take_all_but=0
    ) as served:
        kernels_loaded(served.port)  # (before the descriptors go: they load files)
        stream = socket.create_connection(("127.0.0.1", http), timeout=5)
        waiting = [stream]
        try:
            stream.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            assert stream.recv(64).startswith(b"HTTP/1.1 200")
            assert take_descriptors(served) > 0
            waiting.append(socket.create_connection(("127.0.0.1", http), timeout=5))
            time.sleep(4.0)  # about 10 retries
        finally:
            close_all(waiting)
    lines = served.lines()
    said = [line for line in lines if "no file descriptor left for a new HTTP connection" in line]
    assert len(said) == 1 and "none waits for its request" in said[0], lines
    assert not any("descriptor not logged" in line for line in lines), lines
    assert not any("shortages" in line for line in lines), lines  # one shortage, logged


def test_live_streams_filling_the_dashboards_share_give_way_to_a_request(tmp_path):
    """A stranger's probe: with the dashboard's share of connections at 4 (a tight
    open-file limit), four live streams (four tabs, or an idle neighbour) held the page
    hostage: a stream never waits for a request, so none could be closed for a GET, and
    every request was reset. The oldest stream gives way to a new request, as it does to
    a new stream at the streams' limit."""
    http = free_port()
    with _every_listener_limited(tmp_path, http) as served:
        share = _dashboard_share(served.lines())
        streams = []
        try:
            for _ in range(share):
                stream = socket.create_connection(("127.0.0.1", http), timeout=5)
                streams.append(stream)
                stream.sendall(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
                assert stream.recv(64).startswith(b"HTTP/1.1 200")
            state = http_get(http, "/api/state")
        finally:
            close_all(streams)
    lines = served.lines()
    assert _answered(state), (state[:200], lines[-5:])
    assert any("the oldest stream closed for a new connection" in line for line in lines), lines
