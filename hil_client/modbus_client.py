"""A lean blocking Modbus TCP client that pipelines: one connection, many requests in flight.

Modbus TCP lets a client send several requests before the first reply comes back (the
transaction ID pairs them); a server answers them in order. The rig sends all requests of
one acquisition step (setpoint writes, the lockstep advance, one read per instrument) in one
segment and then collects the replies, so a step costs one round trip, not one per request.

Errors: :class:`ModbusExceptionResponse` for an exception reply (with its code),
:class:`ConnectionLost` for a closed, reset or timed-out connection, :class:`BadReply` (one)
for a reply that does not answer its request.

:meth:`Connection.receive_all` survives a faulty unit: it returns, per request, the reply,
the exception, or a :class:`NoReply` (the unit never answered: a later request's reply came
first, which an in-order server only does when it dropped this one; or the timeout passed;
or what came does not answer the request).

A reply is used only if it answers its request (:func:`reply_problem`): the MBAP header's
protocol ID 0 and a length a frame can have, the transaction ID, unit and function of the
request (or the function's exception, with its code), and the size the request asks for (a
stranger's probe: a reply whose transaction ID named the next request was decoded as that
request's, the bench PLC's 14 registers logged as the flue-gas probe's 3; well-framed
replies with 2 registers fewer, a byte count their data did not fill, no function code, or
an exception without its code ended the run with a traceback).
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


class BadReply(ConnectionLost):
    """What came is no reply to the request: another unit's, function's or size's, or a
    frame no Modbus server sends. Never decoded; the transaction failed, and the connection
    is not to be trusted (reset it, as after a timeout)."""


class NoReply(Exception):
    """A request that got no reply (``reason``: ``no reply``, ``timeout``, or ``too late``:
    it came, after the timeout, and is not used). A reply that does not answer its request
    counts as none: ``timeout``, so the rig resets the connection and leaves the unit's
    fields empty; ``detail`` says what was wrong with it."""

    def __init__(self, unit: int, function: int, reason: str, detail: str = "") -> None:
        why = f" ({detail})" if detail else ""
        super().__init__(f"unit {unit}: function {function}: {reason}{why}")
        self.unit = unit
        self.function = function
        self.reason = reason
        self.detail = detail


Reply = bytes | ModbusExceptionResponse | NoReply

_HEADER = struct.Struct(">HHHB")
#: Modbus function codes that read (coils, discrete inputs, holding, input registers) and
#: that write (single and multiple coils and registers, read/write multiple)
READ_FUNCTIONS = frozenset({1, 2, 3, 4})
WRITE_FUNCTIONS = frozenset({5, 6, 15, 16, 23})
#: the most an MBAP length counts: the unit ID and a PDU of up to 253 bytes (Modbus
#: Messaging on TCP/IP Implementation Guide V1.0b, 3.1.3: an ADU of at most 260 bytes)
MAX_MBAP_LENGTH = 254


def reply_problem(unit: int, request: bytes, got_unit: int, reply: bytes) -> str | None:
    """Why ``reply``, a PDU from unit ``got_unit``, does not answer ``request``, a PDU sent
    to ``unit`` (None if it does): another unit, another function, an exception without
    its code, or another size than the request asks for (a read's byte count and data; a
    write's echo of address and quantity)."""
    function = request[0]
    if got_unit != unit:
        return f"unit {got_unit} answered"
    if not reply:
        return "no function code"
    if reply[0] == function | 0x80:
        return None if len(reply) == 2 else f"an exception of {len(reply) - 1} bytes, not 1"
    if reply[0] != function:
        return f"function {reply[0]} answered"
    if function in (1, 2, 3, 4, 23) and len(request) >= 5:
        quantity = int.from_bytes(request[3:5], "big")
        size = (quantity + 7) // 8 if function in (1, 2) else 2 * quantity
        if len(reply) < 2 or reply[1] != size or len(reply) != 2 + size:
            count = reply[1] if len(reply) >= 2 else "none"
            return (
                f"byte count {count} and {max(len(reply) - 2, 0)} data bytes for "
                f"{quantity} {'bits' if function in (1, 2) else 'registers'} ({size})"
            )
    elif function in (5, 6) and reply != request:
        return "not the echo of the request"
    elif function in (15, 16) and reply != request[:5]:
        return "not the request's address and quantity"
    return None


class Connection:
    """A TCP connection to a Modbus server; requests to any unit ID, pipelined."""

    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self._tid = 0
        self._expect: deque[tuple[int, int, bytes]] = deque()  # (tid, unit, request PDU)
        self._buffer = b""
        self._corrupt = ""  # why what the server sends is no longer read (a bad frame)
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
        if self._corrupt:
            raise BadReply(self._corrupt)
        frames = []
        for unit, pdu in requests:
            self._tid = (self._tid + 1) & 0xFFFF
            self._expect.append((self._tid, unit, pdu))
            frames.append(_HEADER.pack(self._tid, 0, len(pdu) + 1, unit) + pdu)
        try:
            self.sock.sendall(b"".join(frames))
        except OSError as exc:
            raise ConnectionLost(f"send failed ({exc})") from None

    def receive(self) -> bytes:
        """The reply PDU (function code first) of the oldest outstanding request;
        :class:`BadReply` if what came does not answer it."""
        tid, unit, pdu = self._expect.popleft()
        function = pdu[0]
        while True:
            got_tid, got_unit, body = self._frame()
            if got_tid == tid:
                break  # a late reply to an earlier, timed-out request is skipped
        problem = reply_problem(unit, pdu, got_unit, body)
        if problem is not None:
            raise BadReply(f"unit {unit}: function {function}: reply not used: {problem}")
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
        as without patience).

        A reply that does not answer its request (:func:`reply_problem`) is a ``timeout``
        :class:`NoReply` (one whose transaction ID names a later request is not taken as a
        sign that those before it were dropped: it is passed over); after a frame no Modbus
        server sends, nothing more is read: every request left is one. :class:`BadReply`
        instead where that befalls one of ``own``: the caller's own requests are not given
        up on."""
        out: list[Reply] = []
        times: list[float] = []
        deadline = time.monotonic() + patience_s
        overdue: set[int] = set()  # transaction IDs whose reply came too late to count
        last_look: int | None = None  # the head's tid, answered on a second connection
        while len(out) < count:
            try:
                got_tid, got_unit, body = self._frame()
            except ReplyTimeout:
                now = time.monotonic()
                tid, unit, pdu = self._expect[0]
                function = pdu[0]
                waiting_own = bool(own) and len(out) <= own[-1]
                if waiting_own and now < deadline and last_look != tid:
                    if still_coming is not None and not still_coming(unit, function):
                        # answered there: the unit is not slow now, but may have been till
                        # a moment ago (a delay fault that ended meanwhile lets its held
                        # replies go): one more timeout here for a reply on its way, before
                        # this connection counts as dead (it was dropped at once: a stray
                        # reconnection and a gap)
                        last_look = tid
                    if len(out) not in own:
                        overdue.add(tid)
                    continue
                while len(out) < count:
                    _, unit, pdu = self._expect.popleft()
                    out.append(NoReply(unit, pdu[0], "timeout"))
                    times.append(now)
                break
            except BadReply as exc:  # no frame a server sends: the rest cannot be read
                if own and own[-1] >= len(out):
                    raise
                now = time.monotonic()
                while len(out) < count:
                    _, unit, pdu = self._expect.popleft()
                    out.append(NoReply(unit, pdu[0], "timeout", str(exc)))
                    times.append(now)
                break
            wanted = list(self._expect)[: count - len(out)]
            match = next((e for e in wanted if e[0] == got_tid), None)
            if match is None:
                continue  # a late reply to an earlier request given up on
            problem = reply_problem(match[1], match[2], got_unit, body)
            if problem is not None and match is not wanted[0]:
                continue  # out of turn and no answer to its own request either: not used
            now = time.monotonic()
            while self._expect[0][0] != got_tid:  # answered out of turn: those were dropped
                _, unit, pdu = self._expect.popleft()
                out.append(NoReply(unit, pdu[0], "no reply"))
                times.append(now)
            _, unit, pdu = self._expect.popleft()
            function = pdu[0]
            if problem is not None:
                if len(out) in own:
                    raise BadReply(f"unit {unit}: function {function}: reply not used: {problem}")
                out.append(NoReply(unit, function, "timeout", f"reply not used: {problem}"))
            elif got_tid in overdue and function not in WRITE_FUNCTIONS:
                out.append(NoReply(unit, function, "too late"))
            elif body[0] == function | 0x80:
                out.append(ModbusExceptionResponse(unit, function, body[1]))
            else:
                out.append(body)
            times.append(now)
        return out, times

    def _frame(self) -> tuple[int, int, bytes]:
        """(transaction ID, unit, PDU) of the next reply; a timeout loses nothing already
        read. :class:`BadReply` for a header no Modbus/TCP server sends (protocol ID not 0,
        a length no frame has): where the next frame starts is unknown, and the connection
        reads no more."""
        if self._corrupt:
            raise BadReply(self._corrupt)
        header = self._peek(7)
        got_tid, protocol, length, got_unit = _HEADER.unpack(header)
        if protocol != 0 or not 1 <= length <= MAX_MBAP_LENGTH:
            self._corrupt = (
                f"a frame no Modbus/TCP server sends (protocol ID {protocol}, length {length}): "
                "the connection is not read further"
            )
            raise BadReply(self._corrupt)
        frame = self._peek(6 + length)
        self._buffer = self._buffer[6 + length :]
        return got_tid, got_unit, frame[7:]

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
