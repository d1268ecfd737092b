"""Replies that do not answer their request are never decoded (a stranger's probe: a reply
whose transaction ID named the next request was logged as that request's, the bench PLC's
14 registers as the flue-gas probe's 3; well-framed but malformed replies ended the run with a
traceback). Over real sockets: a Modbus/TCP server of a few lines that answers right except
for one chosen malformation, and a run through a relay that spoils one reply."""

from __future__ import annotations

import contextlib
import json
import math
import socket
import struct
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from hil_client.modbus_client import (
    Connection,
    ConnectionLost,
    ModbusExceptionResponse,
    NoReply,
    read_pdu,
    write_registers_pdu,
)
from rig_emulator.registers import load_map
from tests.hil_client.rigs.test_transports_runs import TINY
from tests.hil_client.test_modbus_rig import _tolerance

HEADER = struct.Struct(">HHHB")
REPLY_TIMEOUT_S = 3.0

#: (tid, unit, request PDU, reply frame) -> the frame sent instead
Spoil = Callable[[int, int, bytes, bytes], bytes]


def answer(unit: int, pdu: bytes) -> bytes:
    """The right reply PDU: input and holding register ``a`` of unit ``u`` hold 1000 u + a;
    an address from 100 on is none (exception 02); writes are echoed."""
    function = pdu[0]
    if function in (3, 4):
        address, n = struct.unpack(">HH", pdu[1:5])
        if address >= 100:
            return bytes([function | 0x80, 2])
        words = [1000 * unit + address + i for i in range(n)]
        return struct.pack(f">BB{n}H", function, 2 * n, *words)
    if function in (1, 2):
        n = struct.unpack(">H", pdu[3:5])[0]
        return bytes([function, (n + 7) // 8]) + bytes([0x55] * ((n + 7) // 8))
    if function in (5, 6):
        return pdu
    if function in (15, 16):
        return pdu[:5]
    return bytes([function | 0x80, 1])


def reply_frame(tid: int, unit: int, pdu: bytes) -> bytes:
    return HEADER.pack(tid, 0, len(pdu) + 1, unit) + pdu


class RawServer:
    """A Modbus/TCP server on a free port of 127.0.0.1: every request answered in order with
    :func:`answer`, the first reply to unit 1 passed through ``spoil`` first."""

    def __init__(self, spoil: Spoil) -> None:
        self.spoil = spoil
        self.spoiled = 0
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.conns: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                conn, _ = self.listener.accept()
            except OSError:
                return
            self.conns.append(conn)
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        buffer = b""
        with contextlib.suppress(OSError):
            while chunk := conn.recv(65536):
                buffer += chunk
                while len(buffer) >= 7:
                    tid, _, length, unit = HEADER.unpack(buffer[:7])
                    if len(buffer) < 6 + length:
                        break
                    pdu, buffer = buffer[7 : 6 + length], buffer[6 + length :]
                    out = reply_frame(tid, unit, answer(unit, pdu))
                    if unit == 1 and not self.spoiled:
                        self.spoiled += 1
                        out = self.spoil(tid, unit, pdu, out)
                    conn.sendall(out)

    def close(self) -> None:
        self.listener.close()
        for conn in self.conns:
            with contextlib.suppress(OSError):
                conn.close()


def _with_body(tid: int, unit: int, body: bytes, protocol: int = 0) -> bytes:
    return HEADER.pack(tid, protocol, len(body) + 1, unit) + body


#: one malformation each, of the reply to unit 1's read of 14 input registers
SPOILS: dict[str, Spoil] = {
    # the transaction ID of the next request (unit 2's read of 3 registers)
    "tid": lambda tid, unit, pdu, f: HEADER.pack(tid + 1, *HEADER.unpack(f[:7])[1:]) + f[7:],
    "unit": lambda tid, unit, pdu, f: f[:6] + bytes([9]) + f[7:],
    "function": lambda tid, unit, pdu, f: f[:7] + bytes([3]) + f[8:],
    # two registers fewer, byte count and MBAP length consistent
    "short": lambda tid, unit, pdu, f: _with_body(tid, unit, bytes([4, f[8] - 4]) + f[9:-4]),
    # byte count 28, 24 data bytes (the MBAP length counts what is sent)
    "byte count lies": lambda tid, unit, pdu, f: _with_body(tid, unit, f[7:-4]),
    "long": lambda tid, unit, pdu, f: _with_body(tid, unit, bytes([4, f[8] + 4]) + f[9:] + b"1234"),
    "odd": lambda tid, unit, pdu, f: _with_body(tid, unit, bytes([4, f[8] + 1]) + f[9:] + b"\0"),
    # MBAP length 1: the unit ID and no function code
    "empty pdu": lambda tid, unit, pdu, f: _with_body(tid, unit, b""),
    "exception without code": lambda tid, unit, pdu, f: _with_body(tid, unit, b"\x84"),
    "protocol id": lambda tid, unit, pdu, f: _with_body(tid, unit, f[7:], protocol=7),
}
#: frames no server sends: nothing after them can be read (their replies count as none)
STREAM_LOST = {"protocol id"}

REQUESTS = [(1, read_pdu(4, 0, 14)), (2, read_pdu(4, 0, 3)), (3, read_pdu(4, 500, 2))]


@pytest.fixture
def serve_raw():
    """``serve_raw(mode)``: a :class:`RawServer` with the malformation ``mode``."""
    servers: list[RawServer] = []

    def start(mode: str) -> RawServer:
        servers.append(RawServer(SPOILS[mode]))
        return servers[-1]

    yield start
    for srv in servers:
        srv.close()


def _connect(srv: RawServer) -> Connection:
    return Connection("127.0.0.1", srv.port, REPLY_TIMEOUT_S)


@pytest.mark.parametrize("mode", list(SPOILS))
def test_a_reply_that_does_not_answer_its_request_is_never_decoded(serve_raw, mode):
    srv = serve_raw(mode)
    conn = _connect(srv)
    conn.send(REQUESTS)
    replies, _ = conn.receive_all(len(REQUESTS))
    conn.close()
    assert srv.spoiled == 1
    first, second, third = replies
    # unit 1's fields are left empty, a "timeout" (the rig resets the connection): where its
    # reply came under another's transaction ID, no reply ever named it, and a fresh
    # connection cannot tell that from a slow reply (a server may answer out of order)
    assert isinstance(first, NoReply) and first.unit == 1, first
    assert first.reason == "timeout", first
    if mode in STREAM_LOST:
        assert all(isinstance(r, NoReply) and r.reason == "timeout" for r in replies), replies
        return
    # the rest read as ever: unit 2's own registers (never unit 1's in their place; "tid":
    # the relabelled reply passed over, unit 2's own, which came next, used), and a right
    # exception still an exception
    assert second == answer(2, REQUESTS[1][1]), second
    assert isinstance(third, ModbusExceptionResponse) and third.code == 2, third


RECEIVE_ONE = [m for m in SPOILS if m != "tid"]  # (tid: no reply comes: a timeout, as ever)


@pytest.mark.parametrize("mode", RECEIVE_ONE)
def test_receive_one_by_one_refuses_a_reply_that_does_not_answer(serve_raw, mode):
    conn = _connect(serve_raw(mode))
    conn.send(REQUESTS[:1])
    started = time.monotonic()
    with pytest.raises(ConnectionLost, match=r"reply not used|Modbus/TCP"):
        conn.receive()
    # refused as it came, not after waiting out the timeout (loopback answers in
    # milliseconds; half the reply timeout is room for a busy machine)
    assert time.monotonic() - started < REPLY_TIMEOUT_S / 2
    conn.close()


@pytest.mark.parametrize("mode", ["short", "unit", "protocol id"])
def test_the_callers_own_request_answered_wrong_is_a_lost_connection(serve_raw, mode):
    # the rig's own requests (the advance, the simulation control) are never given up on as
    # a unit's failure: it reconnects and settles what the server holds
    conn = _connect(serve_raw(mode))
    conn.send(REQUESTS)
    with pytest.raises(ConnectionLost, match=r"reply not used|Modbus/TCP"):
        conn.receive_all(len(REQUESTS), own=range(0, 1))
    conn.close()


def test_a_length_no_frame_has_is_known_at_once():
    """An MBAP length of 65535 (no frame is longer than 254) waited for 65541 bytes until
    the timeout; it is now a lost stream at once, the replies behind it none."""
    spoil: Spoil = lambda tid, unit, pdu, f: HEADER.pack(tid, 0, 0xFFFF, unit) + f[7:]  # noqa: E731
    srv = RawServer(spoil)
    conn = _connect(srv)
    conn.send(REQUESTS)
    started = time.monotonic()
    replies, _ = conn.receive_all(len(REQUESTS))
    elapsed = time.monotonic() - started
    conn.close()
    srv.close()
    assert all(isinstance(r, NoReply) and r.reason == "timeout" for r in replies), replies
    assert elapsed < REPLY_TIMEOUT_S / 2  # (as above: loopback, room for a busy machine)


WRITES = {
    # FC16 acknowledged for another quantity, FC6 echoed with another value, FC1 byte count
    "fc16 quantity": (write_registers_pdu(10, [1, 2]), lambda p: p[:3] + b"\x00\x03"),
    "fc6 value": (bytes([6, 0, 10, 0, 7]), lambda p: p[:3] + b"\x00\x08"),
    "fc1 byte count": (read_pdu(1, 0, 9), lambda p: b"\x01\x01\x55"),
}


@pytest.mark.parametrize("case", list(WRITES))
def test_a_write_or_bit_reply_of_another_size_is_refused(case):
    pdu, wrong = WRITES[case]
    spoil: Spoil = lambda tid, unit, req, f: reply_frame(tid, unit, wrong(req))  # noqa: E731
    srv = RawServer(spoil)
    conn = _connect(srv)
    conn.send([(1, pdu), (2, pdu)])
    replies, _ = conn.receive_all(2)
    conn.close()
    srv.close()
    assert isinstance(replies[0], NoReply) and replies[0].reason == "timeout", replies
    assert replies[1] == answer(2, pdu)  # the same request, answered right, is used


# ---------------------------------------------------------------------------- end to end
class SpoilingRelay:
    """A relay between the client and a real emulator that spoils the ``nth`` reply to
    the bench PLC's read of its input registers (unit 1, function 4, address 0), as the
    outside tester's proxy did."""

    def __init__(self, target_port: int, mode: str, nth: int) -> None:
        self.target_port = target_port
        self.mode = mode
        self.nth = nth
        self.seen = 0
        self.spoiled = 0
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self.socks: list[socket.socket] = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            server = socket.create_connection(("127.0.0.1", self.target_port))
            self.socks += [client, server]
            pending: dict[int, bytes] = {}
            threading.Thread(target=self._up, args=(client, server, pending), daemon=True).start()
            threading.Thread(target=self._down, args=(server, client, pending), daemon=True).start()

    @staticmethod
    def _frames(src: socket.socket):
        buffer = b""
        while chunk := src.recv(65536):
            buffer += chunk
            while len(buffer) >= 7:
                length = HEADER.unpack(buffer[:7])[2]
                if len(buffer) < 6 + length:
                    break
                frame, buffer = buffer[: 6 + length], buffer[6 + length :]
                yield frame

    def _up(self, src: socket.socket, dst: socket.socket, pending: dict[int, bytes]) -> None:
        with contextlib.suppress(OSError):
            for frame in self._frames(src):
                pending[HEADER.unpack(frame[:7])[0]] = frame[7:]
                dst.sendall(frame)
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)

    def _down(self, src: socket.socket, dst: socket.socket, pending: dict[int, bytes]) -> None:
        with contextlib.suppress(OSError):
            for frame in self._frames(src):
                tid, _, _, unit = HEADER.unpack(frame[:7])
                request = pending.pop(tid, b"")
                if unit == 1 and request[:3] == b"\x04\x00\x00":
                    self.seen += 1
                    if self.seen == self.nth:
                        self.spoiled += 1
                        frame = SPOILS[self.mode](tid, unit, request, frame)
                dst.sendall(frame)
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        self.listener.close()
        for s in self.socks:
            with contextlib.suppress(OSError):
                s.close()


def _run(protocol: Path, *args: str) -> int:
    return main(["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", *args])


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("protocol") / "tiny.yaml"
    path.write_text(TINY)
    return path


@pytest.fixture(scope="module")
def tiny_local(tiny, tmp_path_factory):
    out = tmp_path_factory.mktemp("local") / "local.csv"
    assert _run(tiny, "--rig", "local", "--out", str(out)) == 0
    return read_log(out)


BENCH = [p.signal for p in next(d for d in load_map().devices if d.unit_id == 1).table("input")]


@pytest.mark.parametrize("mode", ["tid", "short", "exception without code", "protocol id"])
def test_a_run_leaves_the_spoiled_units_fields_empty_and_goes_on(
    serve, tiny, tiny_local, tmp_path, capsys, mode
):
    srv = serve(lockstep=True)
    relay = SpoilingRelay(srv.port, mode, nth=30)
    out = tmp_path / "log.csv"
    rig = f"modbus://127.0.0.1:{relay.port}"
    code = _run(tiny, "--rig", rig, "--out", str(out), "--reply-timeout", "2")
    relay.close()
    err = capsys.readouterr().err
    assert code == 0 and "Traceback" not in err, err
    assert relay.spoiled == 1
    log = read_log(out)
    assert log.meta["complete"] is True and len(log) == len(tiny_local)
    bench = [name for name in BENCH if name in log.columns]
    assert "water_flow_kg_h" in bench and "flue_gas_temp_C" not in bench
    empty = np.flatnonzero(np.isnan(log.columns["water_flow_kg_h"]))
    assert len(empty) == 1, empty  # the spoiled row alone
    row = int(empty[0])
    # up to that row the run is the local run's: the bench PLC's fields empty in it, every
    # other unit's (the flue-gas probe's, whose request came next, among them) its own
    for name, values in log.columns.items():
        local = tiny_local.columns[name][: row + 1]
        mine = values[: row + 1].copy()
        if name in bench:
            assert math.isnan(mine[row]), name
            mine, local = mine[:row], local[:row]
        same = np.isnan(local) == np.isnan(mine)
        assert same.all(), name
        both = ~np.isnan(local)
        assert np.all(np.abs(mine[both] - local[both]) <= _tolerance(name, local[both])), name
    events = [json.loads(line) for line in out.with_suffix(".modbus_events.jsonl").open()]
    at_row = [e for e in events if e["time_s"] == log.columns["time_s"][row]]
    assert any(e["unit"] == 1 and e["event"] in ("timeout", "no_reply") for e in at_row), at_row
