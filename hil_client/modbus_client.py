"""A lean blocking Modbus TCP client that pipelines: one connection, many requests in flight.

Modbus TCP lets a client send several requests before the first reply comes back; the
transaction ID pairs each reply with its request, whatever the order the replies come in (the
Messaging on TCP/IP Implementation Guide V1.0b lets a server work on several transactions of
a connection at once: a gateway to several serial lines answers as its lines do; the client
took every server to answer in order, and gave up at once on every request ahead of a reply
that came out of turn: a stranger's probe through a proxy that answers each burst in reverse
could not even start a run). The rig sends all requests of one acquisition step (setpoint
writes, the lockstep advance, one read per instrument) in one segment and then collects the
replies, so a step costs one round trip, not one per request.

A server may take fewer transactions at once than are sent (the TCP guide, 4.2.1.1, leaves
the number a server handles at once to the device). :attr:`Connection.window` is how many
requests are in flight at most (None: no limit, the rest wait and go as replies come): a
server that answers a pipelined request with exception 06 (server busy) while it answers
the earlier ones has it set to the number that were in flight, and the request is sent
again once nothing sent before it waits (once, alone; 06 again then is the unit's own busy,
its exception given and the window as it was). One such 06 narrows the window only for a
while: after :data:`REOPEN_AFTER` clean replies it opens again, and it is kept only when the
server refuses what is sent behind that many once more (the evidence of a limit: twice, a
wider window not answered in between). A 06 that went away when asked again says nothing
of a limit by itself (a stranger's probe: a 0.5-s busy fault at a run's start, the coil
writes behind the setpoint's answered once asked again after it, kept the window at 1 for
the whole run: ten times the segments, a lockstep run twice as long). A server that answered
a request sent alone but none sent behind another, the timeout passing, drops pipelined
requests: the window becomes 1 and those requests go again, one at a time (a stranger's
bench device that took 4 transactions at a time stopped the run before the first row,
"refused with exception 06"; one that read one request per segment, "cannot reach ...: no
reply within the timeout"). A server that pipelines keeps the window open: nothing is held back.

Replies that name no request sent (a server that answers every request with transaction
ID 0) are counted, and a timeout then names them ("replies came with transaction id 0, not
the requests' ...", not "no reply within the timeout": the server did answer).

Errors: :class:`ModbusExceptionResponse` for an exception reply (with its code),
:class:`ConnectionLost` for a closed, reset or timed-out connection, :class:`BadReply` (one)
for a reply that does not answer its request.

:meth:`Connection.receive_all` survives a faulty unit: it returns, per request, the reply,
the exception, or a :class:`NoReply` (the timeout passed with no reply; or what came does not
answer the request; or, only on a connection that has shown its server answers in order, a
later request's reply came first, which such a server does only when it dropped this one:
``no reply`` at once, where waiting would cost the timeout every step).

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
import itertools
import socket
import struct
import time
from collections import Counter, deque
from collections.abc import Callable, Collection, Sequence
from typing import NamedTuple


class ConnectionLost(ConnectionError):
    """The connection to a unit failed (refused, reset, closed or timed out);
    ``by_server``: the server closed (or reset) it, rather than a send, a connect or a
    timeout of this client failing."""

    def __init__(self, message: str, by_server: bool = False) -> None:
        super().__init__(message)
        self.by_server = by_server


class ModbusExceptionResponse(RuntimeError):
    """The server answered with a Modbus exception."""

    def __init__(self, unit: int, function: int, code: int) -> None:
        super().__init__(f"unit {unit}: function {function} refused with exception {code:02X}")
        self.unit = unit
        self.function = function
        self.code = code


class ReplyTimeout(ConnectionLost):
    """No reply within the connection's timeout."""


class UnpairedReplies(ReplyTimeout):
    """No reply within the timeout, though frames came that name no request sent: the
    server was reached, and its replies cannot be paired with their requests."""


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


class _Sent(NamedTuple):
    """A request sent and not collected yet: its place in the connection's order of sending
    (transaction IDs wrap, this does not), its unit and PDU."""

    seq: int
    unit: int
    pdu: bytes


class _Came(NamedTuple):
    """A frame that named a request: the unit and PDU it carries, why it does not answer
    the request (None if it does), and whether it ended a silence of the timeout."""

    unit: int
    body: bytes
    problem: str | None
    late: bool


#: replies in turn (each for the first request sent after the last one answered, while a
#: later one waited too) before a connection counts as one to a server that answers in order
#: (:attr:`Connection.in_order`): a server that took its waiting requests in any order would
#: answer that one of two or more with a chance of one half at most, so ten in turn leave it
#: less than 0.1 % (2^-10). Requests a server drops (a faulty unit) stay waiting before the
#: last one answered and do not stop the count (the first unit of every step silent cost the
#: timeout at every step when only replies to the oldest request waiting counted: a
#: re-probe); the first step of ``hil-client run`` on a connection (13 requests pipelined)
#: gives them
IN_ORDER_EVIDENCE = 10
#: the most stray transaction IDs a timeout's message names
STRAYS_NAMED = 3
#: clean replies (no 06) after a window narrowed by one busy answer before it opens again
#: (:attr:`Connection.window`): about two steps of ``hil-client run`` (13 to 20 requests
#: each), so a busy moment of the server costs a few steps one at a time, never the run
REOPEN_AFTER = 40
#: narrowings by a pipelined 06 answered once sent alone, a wider window not answered in
#: between, before the window is kept for good: "more than once" (a passing busy fault
#: seldom falls twice on the very steps that try the wider window)
BUSY_EVIDENCE = 2


class Connection:
    """A TCP connection to a Modbus server; requests to any unit ID, pipelined, each reply
    paired with its request by the transaction ID, whatever the order the replies come in."""

    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self._tid = 0
        self._seq = 0
        # the requests sent and not collected yet (transaction IDs in the order sent), those
        # of them nothing usable came for yet, and the others' outcomes (with the wall time)
        self._order: deque[int] = deque()
        self._sent: dict[int, _Sent] = {}
        self._waiting: dict[int, _Sent] = {}
        self._outcome: dict[int, tuple[_Came | NoReply, float]] = {}
        self._spoilt: dict[int, str] = {}  # why a frame naming a waiting request was passed over
        self._given_up: dict[int, _Sent] = {}  # settled without their reply (it may come yet)
        self._answered_seq = -1  # the last request sent that a reply came for
        self._in_turn = 0  # replies in turn (IN_ORDER_EVIDENCE)
        #: the server answered a request after one sent later (never assumed in order again)
        self.reorders = False
        self._buffer = b""
        self._corrupt = ""  # why what the server sends is no longer read (a bad frame)
        #: the most requests in flight at once (None: no limit); see the module docstring
        self.window: int | None = None
        self._window_shown: int | None = None  # the window kept (a limit shown, or none)
        self._narrowings = 0  # narrowings by a 06 answered alone, none answered wider since
        self._narrowed_to: int | None = None  # the window of the last narrowing (trying)
        self._counted = False  # the last narrowing counted among them already
        self._clean = 0  # replies with no 06 since the last narrowing
        self._unsent: deque[int] = deque()  # waiting requests not sent yet, in order sent
        self._in_flight: set[int] = set()  # sent and waiting
        self._ahead: dict[int, int] = {}  # how many were in flight when each went out
        self._busy_retried: set[int] = set()  # sent again after a pipelined 06
        self._busy_alone: set[int] = set()  # units that answered 06 to a request alone
        self._pipelined_answered = False  # a request sent behind another was answered
        self._alone_answered = False  # a request sent with none in flight was answered
        #: transaction IDs of frames that named no request sent, since the last reply paired
        self._strays: Counter[int] = Counter()
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {host}:{port}: {exc.strerror or exc}"
            ) from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    @property
    def in_order(self) -> bool:
        """Whether this connection has shown that its server answers in order: replies came
        in turn (:data:`IN_ORDER_EVIDENCE`), and never one after a later request's. Only then
        does a reply out of turn tell that the requests before it were dropped; it is never
        assumed (the TCP guide lets a server work on several requests of a connection at
        once, and a gateway to several lines answers as its lines do)."""
        return not self.reorders and self._in_turn >= IN_ORDER_EVIDENCE

    def learn_from(self, earlier: object) -> None:
        """Take over what an earlier connection to the same server showed of the order it
        answers in (a connection opened again after a timeout would otherwise start with no
        evidence, and a unit that drops every request would cost the timeout every step)."""
        if isinstance(earlier, Connection):
            self.reorders = self.reorders or earlier.reorders
            self._in_turn = max(self._in_turn, earlier._in_turn)
            self.window = self._window_shown = earlier._window_shown
            self._narrowings = earlier._narrowings
            self._narrowed_to = earlier._narrowed_to  # (tried again here: the window kept)
            self._busy_alone |= earlier._busy_alone
            self._pipelined_answered |= earlier._pipelined_answered
            self._alone_answered |= earlier._alone_answered

    def send(self, requests: Sequence[tuple[int, bytes]]) -> None:
        """Send ``(unit, pdu)`` requests in one segment (those beyond the :attr:`window`
        as replies come); :meth:`receive` and :meth:`receive_all` give their outcomes in
        the same order."""
        if self._corrupt:
            raise BadReply(self._corrupt)
        for unit, pdu in requests:
            self._tid = (self._tid + 1) & 0xFFFF
            self._given_up.pop(self._tid, None)  # (an ID used again: no late reply of that one)
            self._spoilt.pop(self._tid, None)
            self._order.append(self._tid)
            self._sent[self._tid] = self._waiting[self._tid] = _Sent(self._seq, unit, pdu)
            self._unsent.append(self._tid)
            self._seq += 1
        self._transmit()

    def _transmit(self) -> None:
        """Send the waiting requests the :attr:`window` has room for, in one segment; a
        request sent again after a 06 goes only alone (nothing in flight)."""
        frames = []
        while self._unsent and (self.window is None or len(self._in_flight) < self.window):
            tid = self._unsent[0]
            if tid in self._busy_retried and self._in_flight:
                break
            self._unsent.popleft()
            sent = self._sent[tid]
            self._ahead[tid] = len(self._in_flight)
            self._in_flight.add(tid)
            frames.append(_HEADER.pack(tid, 0, len(sent.pdu) + 1, sent.unit) + sent.pdu)
        if not frames:
            return
        try:
            self.sock.sendall(b"".join(frames))
        except OSError as exc:
            raise ConnectionLost(f"send failed ({exc})") from None

    def _send_again(self, tid: int) -> None:
        """Put the waiting request ``tid`` back among those to send, in its order."""
        self._in_flight.discard(tid)
        seq = self._sent[tid].seq
        place = next((i for i, t in enumerate(self._unsent) if self._sent[t].seq > seq), None)
        self._unsent.insert(len(self._unsent) if place is None else place, tid)

    def _fall_back(self) -> bool:
        """At a timeout, whether the server drops pipelined requests (it answered a request
        sent alone, never one sent behind another, and every request silent now went behind
        another): then the :attr:`window` becomes 1 and those requests go again, one at a
        time (True). Once per server: a server seen answering pipelined requests never."""
        silent = self._in_flight
        if (
            self.window == 1
            or not silent
            or self._pipelined_answered
            or not self._alone_answered
            or any(self._ahead[tid] == 0 for tid in silent)
        ):
            return False
        self.window = self._window_shown = 1
        self._narrowed_to = None
        for tid in list(silent):
            self._send_again(tid)
        self._transmit()
        return True

    def _strays_named(self, tids: Collection[int]) -> str:
        """What a timeout of the requests ``tids`` says of the frames that came naming no
        request sent ("" if none came: no reply at all)."""
        if not self._strays:
            return ""
        named = sorted(self._strays)
        ids = ", ".join(str(t) for t in named[:STRAYS_NAMED])
        more = f" and {len(named) - STRAYS_NAMED} more" if len(named) > STRAYS_NAMED else ""
        ours = sorted(tids)
        span = f"{ours[0]}" if len(ours) == 1 else f"{ours[0]} to {ours[-1]}"
        if len(ours) > 1 and ours[-1] - ours[0] != len(ours) - 1:
            span = ", ".join(str(t) for t in ours)
        return (
            f"replies came with transaction id{'s' if len(named) > 1 else ''} {ids}{more}, "
            f"not the requests' {span} ({self._strays.total()} replies that name no request "
            "sent: a server that does not send back its request's transaction ID, whose "
            "replies cannot be paired with their requests)"
        )

    def receive(self) -> bytes:
        """The reply PDU (function code first) of the oldest outstanding request, waited for
        up to the timeout (the replies that come for the others meanwhile kept for them);
        :class:`BadReply` if what came does not answer it."""
        tid = self._order[0]
        while tid not in self._outcome:
            try:
                self._take(*self._frame(), late=False)
            except ReplyTimeout as exc:
                if self._fall_back():
                    continue
                strays = self._strays_named([tid])
                self._give_up(tid, "timeout")
                self._collect(tid)
                if strays:
                    raise UnpairedReplies(strays) from None
                raise exc from None
        try:
            reply, _ = self._reply(tid, own=True)
        finally:
            self._collect(tid)
        if isinstance(reply, ModbusExceptionResponse):
            raise reply
        if isinstance(reply, NoReply):  # (given up on by a receive_all that did not return)
            raise ReplyTimeout(str(reply))
        return reply

    def receive_all(
        self,
        count: int,
        own: range = range(0),
        patience_s: float = 0.0,
        still_coming: Callable[[int, int], bool] | None = None,
    ) -> tuple[list[Reply], list[float]]:
        """The outcome of each of the ``count`` oldest outstanding requests, in order, and
        the wall time [s, monotonic] each outcome was known. Each reply is its request's by
        the transaction ID, in whatever order they come; a request is given up on at the
        timeout (a silence that long) or, on a connection that has shown its server answers
        in order (:attr:`in_order`), when a later request's reply came first and nothing
        more is at hand (the server dropped it: ``no reply``). After a timeout the
        connection may still carry late replies: close it (or let the transaction IDs skip
        them).

        With ``patience_s``, the caller's own requests (the indices ``own``) are waited for,
        up to ``patience_s`` in all (an in-order server answers each only after those sent
        before it, so one slow unit ahead holds them back; they are never given up on as
        dropped). A reading's reply that comes more than the timeout after the last byte
        before it is ``too late`` all the same (its unit's fields stay empty; a write's late
        reply says it was carried out, and stands); the connection stays usable, and the
        caller's own requests are carried out once, on it, and their outcome known.
        ``still_coming(unit, function)``, asked at each silence of the timeout, says whether
        the oldest request waited for is only slow (True) or the connection has died on the
        way (False: give up after one more silence, as without patience).

        A reply that does not answer its request (:func:`reply_problem`) is a ``timeout``
        :class:`NoReply`; one that names a request while an older one waits may be that
        one's reply under a wrong ID: it is passed over, and the request it names waited for
        on (no right reply in time: a ``timeout`` saying what was wrong). After a frame no
        Modbus server sends nothing more is read: every request left is one.
        :class:`BadReply` instead where that befalls one of ``own``: the caller's own
        requests are not given up on."""
        tids = list(itertools.islice(self._order, count))
        mine = {tids[i] for i in own if i < len(tids)}
        place = {tid: i for i, tid in enumerate(tids)}
        out: list[Reply | None] = [None] * len(tids)
        times = [0.0] * len(tids)
        deadline = time.monotonic() + patience_s
        last_look: int | None = None  # the oldest waited for, answered on a second connection
        late = False  # a silence of the timeout passed: the next frame ends it
        settled = [tid for tid in tids if tid in self._outcome]  # (came before this call)
        while True:
            for tid in settled:
                if tid in place:
                    out[place[tid]], times[place[tid]] = self._reply(tid, tid in mine)
            left = [tid for tid, reply in zip(tids, out, strict=True) if reply is None]
            if not left:
                break
            try:
                frame = self._frame()
            except ReplyTimeout:
                if self._fall_back():
                    settled = []
                    continue
                head = self._sent[left[0]]
                if mine.intersection(left) and time.monotonic() < deadline and last_look != left[0]:
                    if still_coming is not None and not still_coming(head.unit, head.pdu[0]):
                        # answered there: the unit is not slow now, but may have been till a
                        # moment ago (a delay fault that ended meanwhile lets its held replies
                        # go): one more timeout here for a reply on its way, before this
                        # connection counts as dead (it was dropped at once: a stray
                        # reconnection and a gap)
                        last_look = left[0]
                    late = True
                    settled = []
                    continue
                self._abandon(left, mine, out, times, place, self._strays_named(left))
                break
            except BadReply as exc:  # no frame a server sends: the rest cannot be read
                if mine.intersection(left):
                    raise
                self._abandon(left, mine, out, times, place, str(exc))
                break
            settled = self._take(*frame, late=late)
            settled += self._dropped(set(left) - mine)
            late = False
        for tid in tids:
            self._collect(tid)
        return out, times  # type: ignore[return-value]

    def _take(self, tid: int, got_unit: int, body: bytes, late: bool) -> list[int]:
        """File a frame that came (transaction ID, unit, PDU; ``late``: after a silence of the
        timeout) under its request; the transaction IDs that got an outcome by it. A reply to
        a request given up on is passed over; so is a frame that does not answer the request
        it names while an older one waits (it may be that one's, under a wrong ID)."""
        sent = self._waiting.get(tid) if tid in self._in_flight else None
        if sent is None:
            gone = self._given_up.get(tid)
            if gone is None:
                self._strays[tid] += 1  # (a request not sent, or no longer known)
            elif (
                gone.seq < self._answered_seq
                and tid not in self._busy_retried
                and reply_problem(gone.unit, gone.pdu, got_unit, body) is None
            ):
                self.reorders = True  # it came after a later request's: it was not dropped
            return []
        problem = reply_problem(sent.unit, sent.pdu, got_unit, body)
        oldest = next(iter(self._waiting))
        if problem is not None and tid != oldest:
            self._spoilt[tid] = problem
            return []
        if problem is None and self._busy(tid, sent, body):
            self._transmit()
            return []
        retried = tid in self._busy_retried
        self._in_flight.discard(tid)
        ahead = self._ahead.pop(tid, 0)
        if problem is None:
            self._strays.clear()
            if ahead:
                self._pipelined_answered = True
            else:
                self._alone_answered = True
            if not (body[0] & 0x80 and body[1:] == b"\x06"):  # (a unit's own busy: no news)
                self._widen(ahead)
        # in turn: the first request sent after the last one answered, another after it
        after = [s.seq for s in self._waiting.values() if s.seq > self._answered_seq]
        in_turn = len(after) >= 2 and sent.seq == after[0]
        del self._waiting[tid]
        now = time.monotonic()
        self._outcome[tid] = (_Came(got_unit, body, problem, late), now)
        self._transmit()
        if problem is not None:
            return [tid]
        if retried:  # (sent again, alone: its reply comes after later requests' by design)
            self._busy_retried.discard(tid)
        elif sent.seq < self._answered_seq:
            self.reorders = True
        elif in_turn:
            self._in_turn += 1
        self._answered_seq = max(self._answered_seq, sent.seq)
        return [tid]

    def _busy(self, tid: int, sent: _Sent, body: bytes) -> bool:
        """Whether ``body``, the reply to the request ``tid``, is a server busy (exception
        06) to be sent again: the request went behind others (the :attr:`window` becomes
        the number in flight then) and was not sent again yet, and its unit has not shown
        a busy of its own. A request sent again that gets 06 once more (alone) shows the
        unit's own busy: its exception is given, and the window is as it was."""
        busy = body == bytes([sent.pdu[0] | 0x80, 6])
        if tid in self._busy_retried:
            if busy:
                self._busy_alone.add(sent.unit)
                self.window = self._window_shown
                self._narrowed_to = None
            elif self._narrowed_to is not None and not self._counted:
                self._counted = True  # (once per narrowing: a step's several 06 are one)
                self._narrowings += 1
                if self._narrowings >= BUSY_EVIDENCE:  # a limit: fewer in flight served
                    self._window_shown = self.window
                    self._narrowed_to = None
            return False
        if not busy:
            self._busy_alone.discard(sent.unit)
            return False
        ahead = self._ahead.get(tid, 0)
        if not ahead or sent.unit in self._busy_alone:
            return False
        before = self.window
        self.window = ahead if before is None else min(before, ahead)
        if self.window != self._window_shown:
            if self._narrowed_to is None or before != self._narrowed_to:
                self._counted = False  # (a narrowing of its own, not one more 06 of it)
            self._narrowed_to = self.window
        self._clean = 0
        self._busy_retried.add(tid)
        self._send_again(tid)
        return True

    def _widen(self, ahead: int) -> None:
        """After a clean reply (sent behind ``ahead`` others): a window narrowed by one
        busy answer opens again (to the one kept) after :data:`REOPEN_AFTER` of them, and a
        reply to a request sent behind as many as it was narrowed to shows that the server
        takes that many: the narrowing is no evidence of a limit any more."""
        if self._narrowed_to is None:
            return
        if self.window != self._narrowed_to and ahead >= self._narrowed_to:
            self._narrowings = 0
            self._narrowed_to = None
            return
        self._clean += 1
        if self._clean >= REOPEN_AFTER and self.window == self._narrowed_to:
            self.window = self._window_shown  # (the caller sends what it lets through)
            self._counted = False

    def _dropped(self, droppable: Collection[int]) -> list[int]:
        """On a connection :attr:`in_order`, with no whole frame left to read, the requests
        of ``droppable`` still waiting that were sent before the last one answered: such a
        server dropped them, and they are given up on (``no reply``). Not before the frames
        at hand are read: replies that came together are taken together, whatever their
        order (a server that showed no reordering yet may be one)."""
        if not self.in_order or self._frame_at_hand():
            return []
        now = time.monotonic()
        dropped = []
        for tid, request in list(self._waiting.items()):
            if request.seq > self._answered_seq:
                break
            if tid in droppable and tid in self._in_flight and tid not in self._busy_retried:
                self._outcome[tid] = (self._give_up(tid, "no reply"), now)
                dropped.append(tid)
        if dropped:
            self._transmit()
        return dropped

    def _reply(self, tid: int, own: bool) -> tuple[Reply, float]:
        """The outcome of a request that has one, and when it was known: its reply, the
        exception it carries, or a :class:`NoReply` (a reply that does not answer it: a
        ``timeout``, :class:`BadReply` if ``own``; a reading's ``too late``)."""
        sent = self._sent[tid]
        came, at = self._outcome.pop(tid)
        function = sent.pdu[0]
        if isinstance(came, NoReply):
            return came, at
        if came.problem is not None:
            if own:
                raise BadReply(
                    f"unit {sent.unit}: function {function}: reply not used: {came.problem}"
                )
            return NoReply(sent.unit, function, "timeout", f"reply not used: {came.problem}"), at
        if came.late and not own and function not in WRITE_FUNCTIONS:
            return NoReply(sent.unit, function, "too late"), at
        if came.body[0] == function | 0x80:
            return ModbusExceptionResponse(sent.unit, function, came.body[1]), at
        return came.body, at

    def _abandon(
        self,
        tids: list[int],
        mine: set[int],
        out: list[Reply | None],
        times: list[float],
        place: dict[int, int],
        detail: str,
    ) -> None:
        """Give up on the requests ``tids`` (the timeout passed, or the stream cannot be read:
        ``detail``), each a ``timeout`` :class:`NoReply` saying why a frame naming it was not
        used; :class:`BadReply` where that is one of the caller's own (``mine``)."""
        now = time.monotonic()
        for tid in tids:
            problem = self._spoilt.get(tid)
            if problem is not None and tid in mine:
                sent = self._sent[tid]
                raise BadReply(
                    f"unit {sent.unit}: function {sent.pdu[0]}: reply not used: {problem}"
                )
            why = detail or (f"reply not used: {problem}" if problem is not None else "")
            out[place[tid]] = self._give_up(tid, "timeout", why)
            times[place[tid]] = now

    def _give_up(self, tid: int, reason: str, detail: str = "") -> NoReply:
        """Stop waiting for the request ``tid`` (a reply that still comes is passed over)."""
        sent = self._waiting.pop(tid)
        self._given_up[tid] = sent
        self._in_flight.discard(tid)
        self._ahead.pop(tid, None)
        self._busy_retried.discard(tid)
        if tid in self._unsent:
            self._unsent.remove(tid)
        return NoReply(sent.unit, sent.pdu[0], reason, detail)

    def _collect(self, tid: int) -> None:
        """Forget the oldest outstanding request, ``tid``, once its outcome is given."""
        assert self._order[0] == tid
        self._order.popleft()
        del self._sent[tid]
        self._spoilt.pop(tid, None)
        self._busy_retried.discard(tid)

    def _frame_at_hand(self) -> bool:
        """Whether a whole frame (or a header no frame has) is read and not taken yet."""
        if len(self._buffer) < 7:
            return False
        length = _HEADER.unpack(self._buffer[:7])[2]
        return len(self._buffer) >= 6 + length or not 1 <= length <= MAX_MBAP_LENGTH

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
                reset = isinstance(exc, ConnectionResetError)
                raise ConnectionLost(f"receive failed ({exc})", by_server=reset) from None
            if not chunk:
                raise ConnectionLost("connection closed by the server", by_server=True)
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
