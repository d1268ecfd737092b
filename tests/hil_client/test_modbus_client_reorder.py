"""Replies that come out of order are each their own request's, by the transaction ID (the
Modbus Messaging on TCP/IP Implementation Guide V1.0b lets a server work on several
transactions of a connection at once; a gateway to several serial lines answers as its lines
do). A stranger's probe: through a proxy that answers each burst of pipelined requests in
reverse, ``hil-client run`` stopped before its first row (``cannot reach ...: no reply within
the timeout``): the client took a reply out of turn for a sign that every request ahead of it
had been dropped, and their replies, coming next, for late ones. Over real sockets: an
asyncio proxy of a few lines in front of a real ``rig-emulator serve --lockstep`` process."""

from __future__ import annotations

import asyncio
import contextlib
import json
import struct
import threading
import time
from pathlib import Path

import pytest

from hil_client.cli import main
from hil_client.modbus_client import (
    Connection,
    ModbusExceptionResponse,
    NoReply,
    read_pdu,
)
from tests.hil_client.rigs.test_transports_runs import TINY

HEADER = struct.Struct(">HHHB")
REPLY_TIMEOUT_S = 5.0  # loopback answers in milliseconds: room for a busy machine


class ReorderingProxy:
    """A Modbus/TCP proxy on a free port of 127.0.0.1 that holds the replies of a burst until
    every request forwarded so far is answered, then sends them on in one write, in reverse
    order from the ``reverse_from``-th burst of a connection on (:attr:`released`: the
    transaction IDs of each burst as sent on)."""

    def __init__(self, target_port: int, reverse_from: int = 0) -> None:
        self.target_port = target_port
        self.reverse_from = reverse_from
        self.released: list[list[int]] = []
        self._tasks: set[asyncio.Task] = set()
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True)
        self._thread.start()
        start = asyncio.start_server(self._relay, "127.0.0.1", 0)
        self._server = asyncio.run_coroutine_threadsafe(start, self._loop).result(10)
        self.port = self._server.sockets[0].getsockname()[1]

    @property
    def reversed_bursts(self) -> int:
        """How many bursts of two replies or more went out in reverse order."""
        return sum(1 for b in self.released if len(b) > 1 and b == sorted(b, reverse=True))

    async def _relay(self, client_in: asyncio.StreamReader, client_out: asyncio.StreamWriter):
        self._tasks.add(asyncio.current_task())  # type: ignore[arg-type]
        server_in, server_out = await asyncio.open_connection("127.0.0.1", self.target_port)
        unanswered = [0]  # requests forwarded whose reply has not come from the server yet

        async def up() -> None:
            with contextlib.suppress(OSError, asyncio.IncompleteReadError):
                while True:
                    frame = await _frame(client_in)
                    unanswered[0] += 1
                    server_out.write(frame)
                    await server_out.drain()
            server_out.close()

        async def down() -> None:
            held: list[bytes] = []
            bursts = 0
            with contextlib.suppress(OSError, asyncio.IncompleteReadError):
                while True:
                    held.append(await _frame(server_in))
                    unanswered[0] -= 1
                    if unanswered[0] == 0:
                        if bursts >= self.reverse_from:
                            held.reverse()
                        bursts += 1
                        self.released.append([HEADER.unpack(f[:7])[0] for f in held])
                        client_out.write(b"".join(held))
                        await client_out.drain()
                        held = []
            client_out.close()

        with contextlib.suppress(asyncio.CancelledError):
            await asyncio.gather(up(), down())
        for writer in (client_out, server_out):
            writer.close()

    def close(self) -> None:
        async def stop() -> None:
            self._server.close()
            for task in self._tasks:
                task.cancel()

        asyncio.run_coroutine_threadsafe(stop(), self._loop).result(10)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(10)


async def _frame(reader: asyncio.StreamReader) -> bytes:
    """One whole Modbus/TCP frame (the MBAP length delimits it)."""
    header = await reader.readexactly(7)
    return header + await reader.readexactly(HEADER.unpack(header)[2] - 1)


@pytest.fixture
def reordering(serve_process):
    """A lockstep server of the 12-kW boiler with a :class:`ReorderingProxy` in front of it."""
    server = serve_process("--boiler", "windhager_12kw", "--lockstep")
    proxy = ReorderingProxy(server.port)
    yield server, proxy
    proxy.close()


#: one step's worth of reads, of several units, functions and sizes, and a read the bench
#: refuses (exception 02: no such register): no two replies alike
BURST = [
    (1, read_pdu(4, 0, 14)),  # the bench PLC's inputs
    (4, read_pdu(4, 0, 3)),  # the flue-gas probe
    (2, read_pdu(4, 0, 2)),  # the analyser's O2
    (1, read_pdu(4, 500, 2)),  # no such register
    (5, read_pdu(4, 0, 2)),  # the balance
    (100, read_pdu(4, 0, 10)),  # the simulation control
    (7, read_pdu(1, 0, 1)),  # the boiler controller's coil
]


def _one_by_one(
    port: int, requests: list[tuple[int, bytes]] = BURST
) -> list[bytes | ModbusExceptionResponse]:
    """The reply to each of ``requests``, asked directly, one at a time (a lockstep server
    not advanced answers a read alike each time)."""
    conn = Connection("127.0.0.1", port, REPLY_TIMEOUT_S)
    replies: list[bytes | ModbusExceptionResponse] = []
    for request in requests:
        conn.send([request])
        try:
            replies.append(conn.receive())
        except ModbusExceptionResponse as exc:
            replies.append(exc)
    conn.close()
    return replies


def _same(got, expected) -> bool:
    if isinstance(expected, ModbusExceptionResponse):
        return isinstance(got, ModbusExceptionResponse) and (got.unit, got.code) == (
            expected.unit,
            expected.code,
        )
    return got == expected


def test_a_burst_answered_in_reverse_gives_each_request_its_own_reply(reordering):
    """The stranger's proxy at the Connection: every request of the burst but the last was
    given up on as dropped (``no reply``), its reply, coming next, passed over as late."""
    server, proxy = reordering
    expected = _one_by_one(server.port)
    conn = Connection("127.0.0.1", proxy.port, REPLY_TIMEOUT_S)
    conn.send(BURST)
    replies, _ = conn.receive_all(len(BURST))
    # the proxy did answer in reverse: the burst's last request first
    assert proxy.released == [sorted(proxy.released[0], reverse=True)], proxy.released
    assert len(proxy.released[0]) == len(BURST)
    for i, (got, right) in enumerate(zip(replies, expected, strict=True)):
        assert _same(got, right), (i, got, right)
    assert conn.reorders and not conn.in_order  # learned: never taken to answer in order
    # and one by one: each receive() its own request's, the others' kept meanwhile
    conn.send(BURST)
    for i, right in enumerate(expected):
        try:
            got: object = conn.receive()
        except ModbusExceptionResponse as exc:
            got = exc
        assert _same(got, right), (i, got, right)
    conn.close()
    assert proxy.reversed_bursts == 2, proxy.released


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("protocol") / "tiny.yaml"
    path.write_text(TINY)
    return path


def _run(tiny: Path, port: int, out: Path) -> int:
    rig = f"modbus://127.0.0.1:{port}"
    args = ["run", str(tiny), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    return main([*args, "--out", str(out)])


def test_a_run_through_a_server_that_answers_in_reverse_equals_a_direct_one(
    reordering, serve_process, tiny, tmp_path, capsys
):
    """The stranger's repro: ``hil-client run`` through the proxy stopped at once with
    ``cannot reach ...: no reply within the timeout``; direct, it ran."""
    _, proxy = reordering
    direct = serve_process("--boiler", "windhager_12kw", "--lockstep")
    through, alone = tmp_path / "through.csv", tmp_path / "direct.csv"
    assert _run(tiny, proxy.port, through) == 0, capsys.readouterr().err
    assert _run(tiny, direct.port, alone) == 0, capsys.readouterr().err
    # every step's burst (10 requests) came back reversed
    assert proxy.reversed_bursts >= 100, len(proxy.released)
    # lockstep runs of the same boiler and seed are deterministic: the same log, to the digit,
    # and none of its readings empty (no unit given up on)
    text = through.read_text()
    assert text == alone.read_text()
    header, *rows = text.splitlines()
    assert len(rows) > 100
    assert all(field != "" for row in rows for field in row.split(",")[3:]), header
    # nothing given up on, nothing late: no Modbus event at all
    assert through.with_suffix(".modbus_events.jsonl").read_text() == ""


def test_a_connection_shown_in_order_still_takes_a_reversed_burst_whole(serve_process):
    """Only a connection that has shown its server answers in order takes a reply out of
    turn for a sign that the requests ahead of it were dropped; replies that came together
    are all taken before that, so a server that reorders after ten replies in turn costs
    nothing either, and is known as one from then on."""
    server = serve_process("--boiler", "windhager_12kw", "--lockstep")
    expected = _one_by_one(server.port)
    proxy = ReorderingProxy(server.port, reverse_from=1)
    conn = Connection("127.0.0.1", proxy.port, REPLY_TIMEOUT_S)
    conn.send(BURST + BURST)  # 13 replies in turn, a younger request waiting: IN_ORDER_EVIDENCE
    first, _ = conn.receive_all(2 * len(BURST))
    assert conn.in_order
    conn.send(BURST)
    second, _ = conn.receive_all(len(BURST))
    conn.close()
    proxy.close()
    assert proxy.reversed_bursts == 1 and len(proxy.released) == 2, proxy.released
    for i, (got, right) in enumerate(zip(first + second, expected * 3, strict=True)):
        assert _same(got, right), (i, got, right)
    assert conn.reorders and not conn.in_order


def test_a_dropped_request_costs_the_timeout_unless_the_server_has_shown_it_answers_in_order(
    serve_process, tmp_path
):
    """The emulator answers in order: under a no_reply fault, a connection that has seen
    that knows at once, when the next unit's reply comes, that the silent unit's request was
    dropped; a fresh connection cannot know it and waits for the timeout (as a client of a
    server that may reorder must). Either way the other units' replies are their own."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: no_reply, unit: 2, at_s: 0}\n")
    server = serve_process("--boiler", "windhager_12kw", "--lockstep", "--faults", str(faults))
    silent = next(i for i, (unit, _) in enumerate(BURST) if unit == 2)
    fresh_timeout_s = 1.0  # short: this wait is the point, not the loopback's speed

    def burst(conn: Connection) -> tuple[list, float]:
        started = time.monotonic()
        conn.send(BURST)
        replies, _ = conn.receive_all(len(BURST))
        return replies, time.monotonic() - started

    fresh = Connection("127.0.0.1", server.port, fresh_timeout_s)
    cold, cold_s = burst(fresh)
    fresh.close()
    shown = Connection("127.0.0.1", server.port, REPLY_TIMEOUT_S)
    others = BURST[:silent] + BURST[silent + 1 :]
    shown.send(others + others)  # 11 replies in turn: IN_ORDER_EVIDENCE
    shown.receive_all(2 * len(others))
    assert shown.in_order
    warm, _ = burst(shown)
    shown.close()
    assert isinstance(cold[silent], NoReply) and cold[silent].reason == "timeout", cold
    assert cold_s >= fresh_timeout_s
    # known as the next reply came ("no reply"), not after the timeout
    assert isinstance(warm[silent], NoReply) and warm[silent].reason == "no reply", warm
    expected = _one_by_one(server.port, others)
    for replies in (cold, warm):
        answered = replies[:silent] + replies[silent + 1 :]
        for i, (got, right) in enumerate(zip(answered, expected, strict=True)):
            assert _same(got, right), (i, got, right)


@pytest.mark.parametrize("unit", [1, 2])
def test_a_run_keeps_what_its_connections_showed_of_the_order_across_reconnections(
    serve_process, tiny, tmp_path, capsys, unit
):
    """The rig opens a new connection after each timeout; one that started with no evidence
    of the server's order made a unit silent from the start (a no_reply fault) cost the reply
    timeout at every step (a lockstep run of 119 rows took 124 s instead of 6): what the
    connections before showed is kept (``Connection.learn_from``), so after the first
    timeout the silent unit's requests are known dropped as the next reply comes. Unit 1
    (the bench PLC, whose setpoint writes open every step) too: its requests, always the
    oldest waiting, kept the evidence from building when only replies to the oldest counted
    (a re-probe); and the first row too, shown the order before it (a re-probe)."""
    faults = tmp_path / "faults.yaml"
    faults.write_text(f"faults:\n  - {{kind: no_reply, unit: {unit}, at_s: 0}}\n")
    server = serve_process("--boiler", "windhager_12kw", "--lockstep", "--faults", str(faults))
    out = tmp_path / "run.csv"
    rig = f"modbus://127.0.0.1:{server.port}"
    args = ["run", str(tiny), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    assert main([*args, "--reply-timeout", "1", "--out", str(out)]) == 0, capsys.readouterr()
    events = [
        json.loads(line)
        for line in out.with_suffix(".modbus_events.jsonl").read_text().splitlines()
    ]
    mine = [e for e in events if e["unit"] == unit]
    assert len(mine) > 20, mine  # the fault holds the whole run: every row's requests to it
    # the connection is shown the server's order before the first step (reads of the
    # simulation control, which no fault silences): no request waits for the timeout, the
    # first row's neither (a re-probe: at x100 the first row's timeouts lost 100 simulated
    # seconds of rows each)
    assert {e["event"] for e in mine} == {"no_reply"}, [e for e in mine if e["event"] != "no_reply"]
