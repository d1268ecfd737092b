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
from collections.abc import Callable, Sequence


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
    """A request that got no reply (``reason``: ``no reply``, ``timeout``, or ``too late``:
    it came, after the timeout, and is not used)."""

    def __init__(self, unit: int, function: int, reason: str) -> None:
        super().__init__(f"unit {unit}: function {function}: {reason}")
        self.unit = unit
        self.function = function
        self.reason = reason


Reply = bytes | ModbusExceptionResponse | NoReply

_HEADER = struct.Struct(">HHHB")
#: Modbus function codes that read (coils, discrete inputs, holding, input registers) and
#: that write (single and multiple coils and registers, read/write multiple)
READ_FUNCTIONS = frozenset({1, 2, 3, 4})
WRITE_FUNCTIONS = frozenset({5, 6, 15, 16, 23})


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
            got_tid, body = self._frame()
            if got_tid == tid:
                break  # a late reply to an earlier, timed-out request is skipped
        if body[0] == function | 0x80:
            raise ModbusExceptionResponse(unit, function, body[1])
        return body

    def receive_all(
        self,
        count: int,
        own: range = range(0),
        patience_s: float = 0.0,
        still_coming: Callable[[int, int], bool] | None = None,
    ) -> tuple[list[Reply], list[float]]:
        """The outcome of each of the ``count`` oldest outstanding requests, in order, and
        the wall time [s, monotonic] each outcome was known. After a timeout the connection
        may still carry late replies: close it (or let the transaction IDs skip them).

        With ``patience_s``, the caller's own requests (the indices ``own``) are waited for,
        up to ``patience_s`` in all: an in-order server answers each only after those sent
        before it, so one slow unit ahead holds them back. A reading's reply before them
        that comes more than the timeout after the last byte before it is ``too late`` all
        the same (its unit's fields stay empty; a write's late reply says it was carried
        out, and stands); the connection stays usable, and the caller's own requests are
        carried out once, on it, and their outcome known. ``still_coming(unit, function)``,
        asked at each silence of the timeout, says whether the request at the head of the
        line is only slow (True) or the connection has died on the way (False: give up now,
        as without patience)."""
        out: list[Reply] = []
        times: list[float] = []
        deadline = time.monotonic() + patience_s
        overdue: set[int] = set()  # transaction IDs whose reply came too late to count
        while len(out) < count:
            try:
                got_tid, body = self._frame()
            except ReplyTimeout:
                now = time.monotonic()
                tid, unit, function = self._expect[0]
                waiting_own = bool(own) and len(out) <= own[-1]
                if (
                    waiting_own
                    and now < deadline
                    and (still_coming is None or still_coming(unit, function))
                ):
                    if len(out) not in own:
                        overdue.add(tid)
                    continue
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
            if got_tid in overdue and function not in WRITE_FUNCTIONS:
                out.append(NoReply(unit, function, "too late"))
            elif body[0] == function | 0x80:
                out.append(ModbusExceptionResponse(unit, function, body[1]))
            else:
                out.append(body)
            times.append(now)
        return out, times

    def _frame(self) -> tuple[int, bytes]:
        """(transaction ID, PDU) of the next reply; a timeout loses nothing already read."""
        header = self._peek(7)
        got_tid, _, length, _ = _HEADER.unpack(header)
        frame = self._peek(6 + length)
        self._buffer = self._buffer[6 + length :]
        return got_tid, frame[7:]

    def _peek(self, n: int) -> bytes:
        """The first ``n`` bytes of what arrived, waiting for them; nothing is consumed."""
        while len(self._buffer) < n:
            try:
                chunk = self.sock.recv(65536)
            except TimeoutError:
                raise ReplyTimeout("no reply within the timeout") from None
            except OSError as exc:
                raise ConnectionLost(f"receive failed ({exc})") from None
            if not chunk:
                raise ConnectionLost("connection closed by the server")
            self._buffer += chunk
        return self._buffer[:n]

    def close(self, abort: bool = False) -> None:
        """Close; ``abort``: with a reset, so the server drops what it has not carried out
        yet (a request queued behind a slow one) rather than answering into the void."""
        with contextlib.suppress(OSError):
            if abort:
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
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
