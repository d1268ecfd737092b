"""The dashboard's HTTP connections are bounded: idle ones cannot take the process's file
descriptors, and a process out of them sheds an idle one; each against a real
``rig-emulator serve --http`` under a low RLIMIT_NOFILE (:mod:`tests.rig_emulator.fd_limits`)."""

from __future__ import annotations

import socket
import time

from hil_client.wait_for_port import free_port
from tests.rig_emulator.fd_limits import (
    NOFILE,
    close_all,
    http_get,
    idle_connections,
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
