"""A lean blocking Modbus TCP client that pipelines: one connection, many requests in flight.

Modbus TCP lets a client send several requests before the first reply comes back (the
transaction ID pairs them); a server answers them in order. The rig sends all requests of
one acquisition step (setpoint writes, the lockstep advance, one read per instrument) in one
segment and then collects the replies, so a step costs one round trip, not one per request.

Errors: :class:`ModbusExceptionResponse` for an exception reply (with its code),
:class:`ConnectionLost` for a closed, reset or timed-out connection.

:meth:`Connection.receive_all` survives a faulty unit: it returns, per request, the reply,
the exception, or a :class:`NoReply` (the unit never answered: a later request's reply came
first, which an in-order server only does when it dropped this one; or the timeout passed).
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from collections import deque
from collections.abc import Sequence


class ConnectionLost(ConnectionError):
    """The connection to a unit failed (refused, reset, closed or timed out)."""


class ModbusExceptionResponse(RuntimeError):
    """The server answered with a Modbus exception."""

    def __init__(self, unit: int, function: int, code: int) -> None:
        super().__init__(f"unit {unit}: function {function} refused with exception {code:02X}")
        self.unit = unit
        self.function = function
        self.code = code


class ReplyTimeout(ConnectionLost):
    """No reply within the connection's timeout."""


class NoReply(Exception):
    """A request that got no reply (``reason``: ``no reply`` or ``timeout``)."""

    def __init__(self, unit: int, function: int, reason: str) -> None:
        super().__init__(f"unit {unit}: function {function}: {reason}")
        self.unit = unit
        self.function = function
        self.reason = reason


Reply = bytes | ModbusExceptionResponse | NoReply

_HEADER = struct.Struct(">HHHB")


class Connection:
    """A TCP connection to a Modbus server; requests to any unit ID, pipelined."""

    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self._tid = 0
        self._expect: deque[tuple[int, int, int]] = deque()  # (tid, unit, function)
        self._buffer = b""
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {host}:{port}: {exc.strerror or exc}"
            ) from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def send(self, requests: Sequence[tuple[int, bytes]]) -> None:
        """Send ``(unit, pdu)`` requests in one segment; :meth:`receive` returns their
        replies in the same order."""
        frames = []
        for unit, pdu in requests:
            self._tid = (self._tid + 1) & 0xFFFF
            self._expect.append((self._tid, unit, pdu[0]))
            frames.append(_HEADER.pack(self._tid, 0, len(pdu) + 1, unit) + pdu)
        try:
            self.sock.sendall(b"".join(frames))
        except OSError as exc:
            raise ConnectionLost(f"send failed ({exc})") from None

    def receive(self) -> bytes:
        """The reply PDU (function code first) of the oldest outstanding request."""
        tid, unit, function = self._expect.popleft()
        while True:
            header = self._recv(7)
            got_tid, _, length, _ = _HEADER.unpack(header)
            body = self._recv(length - 1)
            if got_tid == tid:
                break  # a late reply to an earlier, timed-out request is skipped
        if body[0] == function | 0x80:
            raise ModbusExceptionResponse(unit, function, body[1])
        return body

    def receive_all(self, count: int) -> tuple[list[Reply], list[float]]:
        """The outcome of each of the ``count`` oldest outstanding requests, in order, and
        the wall time [s, monotonic] each outcome was known. After a timeout the connection
        may still carry late replies: close it (or let the transaction IDs skip them)."""
        out: list[Reply] = []
        times: list[float] = []
        while len(out) < count:
            try:
                header = self._recv(7)
                got_tid, _, length, _ = _HEADER.unpack(header)
                body = self._recv(length - 1)
            except ReplyTimeout:
                now = time.monotonic()
                while len(out) < count:
                    _, unit, function = self._expect.popleft()
                    out.append(NoReply(unit, function, "timeout"))
                    times.append(now)
                break
            wanted = [e[0] for e in list(self._expect)[: count - len(out)]]
            if got_tid not in wanted:
                continue  # a late reply to an earlier request given up on
            now = time.monotonic()
            while self._expect[0][0] != got_tid:  # answered out of turn: those were dropped
                _, unit, function = self._expect.popleft()
                out.append(NoReply(unit, function, "no reply"))
                times.append(now)
            _, unit, function = self._expect.popleft()
            if body[0] == function | 0x80:
                out.append(ModbusExceptionResponse(unit, function, body[1]))
            else:
                out.append(body)
            times.append(now)
        return out, times

    def _recv(self, n: int) -> bytes:
        """``n`` bytes; reads whatever has arrived (several replies in one call, usually)."""
        buffer = self._buffer
        while len(buffer) < n:
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                self._buffer = b""  # a partial frame is lost: the caller reconnects
                raise ReplyTimeout("no reply within the timeout") from None
            except OSError as exc:
                raise ConnectionLost(f"receive failed ({exc})") from None
            if not chunk:
                raise ConnectionLost("connection closed by the server")
            buffer += chunk
        self._buffer = buffer[n:]
        return buffer[:n]

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def read_pdu(function: int, address: int, count: int) -> bytes:
    """Request of a read function (1 coils, 2 discrete, 3 holding, 4 input)."""
    return struct.pack(">BHH", function, address, count)


def write_registers_pdu(address: int, words: Sequence[int]) -> bytes:
    """FC16 request."""
    n = len(words)
    return struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *words)


def write_coils_pdu(address: int, bits: Sequence[bool]) -> bytes:
    """FC15 request."""
    data = bytearray((len(bits) + 7) // 8)
    for i, bit in enumerate(bits):
        if bit:
            data[i // 8] |= 1 << (i % 8)
    return struct.pack(">BHHB", 15, address, len(bits), len(data)) + bytes(data)


def registers_of(reply: bytes) -> list[int]:
    """Registers of an FC3/FC4 reply."""
    n = reply[1] // 2
    return list(struct.unpack(f">{n}H", reply[2 : 2 + 2 * n]))


def bits_of(reply: bytes, count: int) -> list[bool]:
    """Bits of an FC1/FC2 reply."""
    data = reply[2 : 2 + reply[1]]
    return [bool(data[i // 8] >> (i % 8) & 1) for i in range(count)]
