"""The Modbus server and the process's file descriptors: a connection limit above what the
open-file limit holds, and a process whose descriptors run out, each against a real
``rig-emulator serve`` started under a low RLIMIT_NOFILE (:mod:`tests.rig_emulator.fd_limits`)."""

from __future__ import annotations

import time

from tests.rig_emulator.fd_limits import (
    NOFILE,
    close_all,
    idle_connections,
    kernels_loaded,
    modbus_read,
    serving_limited,
    take_descriptors,
)

#: log lines a test's whole run may write: the start's (the limit's line, "serving", the
#: dashboard's), per kind of close at most one each 10 s (the test runs within 10 s, a slow
#: machine 20: two), the fresh client's connect and disconnect, "stopping", the counts
#: said at the stop. The flood this replaced: thousands of lines a second
MAX_LOG_LINES = 16


def _describes_the_rig(reply: bytes) -> bool:
    """Whether ``reply`` answers the fresh client's read: transaction 7, unit 100, FC4 with
    8 bytes (the simulated time, a float64)."""
    return reply[:2] == b"\x00\x07" and reply[6:9] == b"\x64\x04\x08" and len(reply) == 17


def test_max_connections_above_the_open_file_limit_is_lowered_and_a_new_client_served(
    tmp_path,
):
    """A stranger's probe: under ``ulimit -n 1024``, ``serve --max-connections 2000`` and
    1100 idle connections: about 1020 accepted, the rest left in the backlog, a fresh
    client never answered, none of the idle ones closed (the limit's relief never came),
    and asyncio's "socket.accept() out of system resource" traceback at a growing rate
    (1.28 M lines and 22 s of CPU in 45 s). Now the limit is lowered to what the
    descriptors hold, in one line at start, and the oldest unused connection makes room."""
    with serving_limited(tmp_path / "serve.log", "--max-connections", "1000") as served:
        kernels_loaded(served.port)
        idle = idle_connections(served.port, 3 * NOFILE)
        try:
            started = time.monotonic()
            reply = modbus_read(served.port)
            waited_s = time.monotonic() - started
        finally:
            close_all(idle)
    lines = served.lines()
    assert _describes_the_rig(reply), (reply, waited_s, lines[-5:])
    assert len(idle) == 3 * NOFILE  # all accepted, or waiting in the backlog for a place
    assert not any("Traceback" in line or "out of system resource" in line for line in lines)
    said = [line for line in lines if "--max-connections 1000 does not fit" in line]
    assert len(said) == 1 and f"RLIMIT_NOFILE) {NOFILE}" in said[0], lines[:3]
    assert "serving at most" in said[0]
    assert len(lines) <= MAX_LOG_LINES, lines  # and so no CPU spent on a flood


def test_descriptors_taken_by_others_close_the_oldest_unused_connection_for_a_new_one(
    tmp_path,
):
    """The same exhaustion when other things hold the descriptors (files, the dashboard's
    connections): the process's open-file limit reached below the connection limit. An
    accept that finds no descriptor closes the oldest unused connection, as the
    connection limit does, and a new client is served; one line says so, with a count."""
    with serving_limited(tmp_path / "serve.log", take_all_but=3) as served:
        kernels_loaded(served.port)  # (before the descriptors go: they load files)
        assert take_descriptors(served) > 0
        idle = idle_connections(served.port, NOFILE)
        try:
            reply = modbus_read(served.port)
            again = modbus_read(served.port)  # and the next: it goes on
        finally:
            close_all(idle)
    lines = served.lines()
    assert _describes_the_rig(reply) and _describes_the_rig(again), lines[-5:]
    assert not any("Traceback" in line or "out of system resource" in line for line in lines)
    said = [line for line in lines if "no file descriptor left for a new connection" in line]
    assert 1 <= len(said) <= 2 and "closed the oldest unused connection" in said[0], lines
    assert "so far" in said[0]  # the count
    assert len(lines) <= MAX_LOG_LINES, lines
