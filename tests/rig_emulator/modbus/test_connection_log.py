"""A client's connect and disconnect lines are rate-limited with a count, as every other
connection event is (a stranger's probe: 600,000 connect/read/close cycles in 16.6 min
wrote 1.2 M lines, 97.8 MB; a client reconnecting for every read at 10/s, ~140 MB a day)."""

from __future__ import annotations

import logging
import socket
import time

from rig_emulator.modbus import handler
from tests.rig_emulator.modbus.raw import Replies, frame, read_pdu
from tests.rig_emulator.transports.served import serving

READ = frame(1, 100, read_pdu(4, 0, 4))  # the simulated time


def _cycle(port: int) -> int:
    """Connect, read once, close, as a client reconnecting for every read; its port."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(READ)
        Replies(sock).next()
        return sock.getsockname()[1]


def test_connection_churn_logs_the_first_connections_then_a_count():
    """200 connect/read/close cycles: the first 20 connects and disconnects are logged as
    before, each naming its client (users and tests look for them); the other 180 of each
    are one line with the count, said at the latest when the server stops."""
    with serving() as served:
        ports = [_cycle(served.port) for _ in range(200)]
        time.sleep(0.3)  # the last disconnect read by the server
    err = served.stderr
    connected = [line for line in err if " connected (" in line]
    disconnected = [line for line in err if " disconnected (" in line]
    assert len(connected) == 20, err  # (CONNECTION_LOG_BURST)
    assert len(disconnected) == 20, err
    for port, line in zip(ports, connected, strict=False):  # the first 20, in order
        assert f"client 127.0.0.1:{port} connected" in line
    assert sum("180 more client connections not logged" in line for line in err) == 1, err
    assert sum("180 more client disconnections not logged" in line for line in err) == 1, err
    assert "Traceback" not in "\n".join(err)
    assert len(err) < 60, err  # against 400 and more: a line per connect and disconnect


def test_the_count_is_said_as_the_interval_ends_and_the_next_interval_logs_again(
    serve, caplog, monkeypatch
):
    """The events beyond an interval's first are said in one line as the interval ends
    (not only with the next event, which may never come); the next interval's first
    connections are logged again."""
    monkeypatch.setattr(handler, "CONNECTION_LOG_INTERVAL_S", 1.0)
    srv = serve()
    caplog.set_level(logging.INFO, logger="rig_emulator.serve")
    for _ in range(25):
        _cycle(srv.port)

    def said(text: str) -> int:
        return sum(text in r.getMessage() for r in caplog.records)

    assert said(" connected (") == 20
    time.sleep(1.5)  # the interval (1 s) ends: its count is said by itself
    assert said("5 more client connections not logged (the first 20 of each 1 s are)") == 1
    assert said("5 more client disconnections not logged") == 1
    port = _cycle(srv.port)
    time.sleep(0.2)
    assert said(f"client 127.0.0.1:{port} connected") == 1  # a new interval: logged again
    assert said(f"client 127.0.0.1:{port} disconnected") == 1


def test_the_disconnections_of_a_stop_are_logged_or_counted():
    """A re-probe: 30 clients that each sent one request, then SIGTERM: 20 connect lines,
    20 disconnect lines, "10 more client connections not logged", and nothing of the other
    10 disconnections (the counts were said before the stop closed the connections; the
    build before logged all 30). Now the stop's disconnections are logged or counted
    before the counts are said."""
    clients: list[socket.socket] = []
    try:
        with serving() as served:
            for _ in range(30):
                clients.append(socket.create_connection(("127.0.0.1", served.port), timeout=10))
                clients[-1].sendall(READ)
                Replies(clients[-1]).next()
            time.sleep(0.3)  # (every request answered: the clients stay connected)
    finally:
        for sock in clients:
            sock.close()
    err = served.stderr
    assert sum(" connected (" in line for line in err) == 20, err
    assert sum("10 more client connections not logged" in line for line in err) == 1, err
    disconnected = [line for line in err if " disconnected (" in line]
    assert len(disconnected) == 20, err
    assert sum("10 more client disconnections not logged" in line for line in err) == 1, err
    assert all("(the server stops)" in line for line in disconnected), disconnected[:2]
