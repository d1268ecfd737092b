"""The emulator's Modbus TCP server: connections, framing, gates and in-order answers.

pymodbus keeps the datastore (``SimCore`` over one ``SimDevice`` per instrument); the rest
is here, written from the Modbus specs rather than from pymodbus's server:

- :mod:`rig_emulator.modbus.framing` cuts the byte stream into MBAP frames, however TCP
  segments it; a frame with a wrong protocol identifier is discarded; a header that shows
  the stream out of step (a length below 2 or over 254, three wrong frames in a row)
  closes the connection once the requests before it are answered, each with a log line;
- :meth:`BenchModbusServer.execute` is transport-neutral (TCP, TLS and RTU use it): the
  gates first (:class:`GateDecision`: delay, drop or force an exception; 04 comes at the
  operation, after the request's checks), then the unit check (0B), then
  :func:`rig_emulator.modbus.conformance.process`; a fault's delay ends
  early when the fault does (:func:`rig_emulator.faults.engine.holding`);
- answers go out in the order the requests came, per connection. A request that never
  waits is answered at once, without a task (the answers of one turn leave in one write);
  one that waits (a gate's delay, a long lockstep advance) holds the later requests of
  its connection behind it while other connections are served;
- a connection stops being read while its answers are not taken (the transport's buffer
  is full) or while more than :data:`MAX_QUEUED_BYTES` of its requests wait: TCP flow
  control, nothing dropped; a connection answers at most :data:`MAX_ANSWERS_PER_TURN`
  requests per turn of the event loop; connections idle for ``idle_timeout_s`` are closed,
  and at most ``max_connections`` are open (a new one closes the oldest unused, as the
  guide says), fewer where the process's open-file limit holds fewer
  (:func:`rig_emulator.modbus.connections.descriptor_shares`); a process out of
  descriptors closes the oldest unused too (:class:`~rig_emulator.modbus.connections.Listener`);
  each logged, a line per kind at most every :data:`_LIMIT_LOG_INTERVAL_S`, with a count;
- a client's connect and disconnect are logged, the first :data:`CONNECTION_LOG_BURST` of
  each a :data:`CONNECTION_LOG_INTERVAL_S`, then one line with the count (at the latest
  when the server stops, the disconnections of its stop among them).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl
import time
import types
from collections import deque
from collections.abc import Callable, Coroutine, Generator, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from pymodbus.simulator import SimDevice
from pymodbus.simulator.simcore import SimCore

from rig_emulator.faults.engine import DelayHold, holding, refused_by_checks
from rig_emulator.modbus.conformance import (
    ENCAPSULATED_INTERFACE,
    GATEWAY_TARGET_FAILED,
    SERVER_DEVICE_FAILURE,
    DeviceIdentity,
    DocumentedBits,
    WriteCheck,
    exception_pdu,
    process,
    process_failing,
)
from rig_emulator.modbus.connections import (
    DescriptorShares,
    EventLog,
    Listener,
    descriptor_shares,
    listen,
)
from rig_emulator.modbus.framing import (
    MAX_DISCARDED_IN_ROW,
    MbapFrame,
    frame_bytes,
    frame_ready,
    split_frames,
)

log = logging.getLogger("rig_emulator.serve")
_PENDING: set[asyncio.Task] = set()  # strong references to requests that had to wait

MAX_QUEUED_BYTES = 65536  # requests of one connection waiting behind a slow one [bytes]
#: requests of one connection answered in one turn of the event loop; the rest wait for the
#: next turn, so a client pipelining thousands does not hold up the others (~1-2 ms)
MAX_ANSWERS_PER_TURN = 64
DEFAULT_IDLE_TIMEOUT_S = 300.0
DEFAULT_MAX_CONNECTIONS = 100
_LIMIT_LOG_INTERVAL_S = 10.0  # what the connection limit did: one line per interval at most
#: a TLS handshake's bound where connections have no idle timeout (asyncio's own) [s]
HANDSHAKE_TIMEOUT_S = 60.0
#: how long a closed TLS connection waits for the peer's close_notify before its socket is
#: freed (asyncio's own: 30 s, a file descriptor a silent peer holds that long) [s]
TLS_SHUTDOWN_TIMEOUT_S = 2.0
HANDSHAKE_LOG_BURST = 20  # failed TLS handshakes logged a minute, the rest counted
#: client connects (and as many disconnects, TLS identities) logged an interval, the rest
#: counted: a client reconnecting for every read at 10/s wrote 140 MB of them a day
CONNECTION_LOG_BURST = 20
CONNECTION_LOG_INTERVAL_S = 60.0
#: descriptors a server may open after its connection limit is fitted, besides a second TCP
#: listener and the dashboard's (as many as its own listener has): a serial line's seven (a
#: pty's two ends, the pipes that stop and wake its reader, the watch on its masters'
#: closes) and the fault journal
LATER_DESCRIPTORS = 8


@dataclass(frozen=True)
class RequestInfo:
    """One decoded request, before it touches any datastore."""

    unit_id: int
    function_code: int
    peer: str  # "host:port" or "pty"
    role: str | None  # TLS role of the connection; None on plain TCP / RTU
    #: FC 43's MEI type (14: read device identification), None for other functions or a
    #: PDU too short to hold one: what a request does depends on it (the role gate)
    mei_type: int | None = None

    @classmethod
    def of(cls, unit_id: int, pdu: bytes, peer: str, role: str | None) -> RequestInfo:
        """The info of request ``pdu`` (not empty) to ``unit_id``."""
        mei_type = pdu[1] if pdu[0] == ENCAPSULATED_INTERFACE and len(pdu) > 1 else None
        return cls(unit_id, pdu[0], peer, role, mei_type)


@dataclass(frozen=True)
class GateDecision:
    """What a gate decides for one request."""

    delay_s: float = 0.0  # answer this much later (later requests of the connection wait)
    drop: bool = False  # send no reply at all
    #: answer FC|0x80 with this code and change nothing: at once, or for 04 (SERVER DEVICE
    #: FAILURE) at the operation, after the request's checks (:meth:`_carry_out`)
    exception_code: int | None = None


Gate = Callable[[RequestInfo], "GateDecision | None"]


@types.coroutine
def _resume(coro: Coroutine[Any, Any, Any], future: Any) -> Generator[Any, None, Any]:
    """Hand the futures ``coro`` waits on to the task running this; return its result."""
    while True:
        try:
            yield future
        except BaseException as exc:  # cancelled while waiting: pass it on
            try:
                future = coro.throw(exc)
            except StopIteration as stop:
                return stop.value
            continue
        try:
            future = coro.send(None)
        except StopIteration as stop:
            return stop.value


async def _hold(delay_s: float, holds: list[DelayHold]) -> None:
    """Wait out a gate's delay of ``delay_s``; with ``holds`` (the delay faults that asked
    it), no longer than they last: a fault that ends (cleared, its ``for_s`` elapsed, a
    reset) lets the request go at once if no other delay still holds it (a stranger's
    probe: a cleared 20 s delay still held the read it had taken for 19 s more)."""
    if not holds:
        await asyncio.sleep(delay_s)
        return
    loop = asyncio.get_running_loop()
    taken = loop.time()
    woken: asyncio.Future[None] | None = None

    def wake() -> None:
        if woken is not None and not woken.done():
            woken.set_result(None)

    def wake_threadsafe() -> None:  # a fault may end in another thread
        loop.call_soon_threadsafe(wake)

    for hold in holds:
        hold.on_change = wake_threadsafe
    try:
        while True:
            left_s = taken + min(delay_s, max(h.delay_s for h in holds)) - loop.time()
            if left_s <= 0:
                return
            woken = loop.create_future()
            timer = loop.call_later(left_s, wake)
            try:
                await woken
            finally:
                timer.cancel()
    finally:
        for hold in holds:
            hold.close()


def _ordinary_close(exc: BaseException) -> bool:
    """Whether ``exc``, ending a connection, is only a client that spoke after the server had
    closed the connection (its idle timeout, the connection limit): OpenSSL reports the bytes
    that came after the server's close_notify as an error, which the log showed as
    "disconnected ([SSL: APPLICATION_DATA_AFTER_CLOSE_NOTIFY] ...)" (a stranger's probe)."""
    return isinstance(exc, ssl.SSLError) and exc.reason == "APPLICATION_DATA_AFTER_CLOSE_NOTIFY"


class RequestHandler(asyncio.Protocol):
    """One client connection (see the module docstring)."""

    def __init__(self, server: BenchModbusServer, tls: ssl.SSLContext | None = None) -> None:
        self.server = server
        #: Modbus/TCP Security: the handshake this connection makes before any request
        self._tls = tls
        self._securing = False  # the handshake is under way: requests wait for its end
        self.transport: Any = None
        self.peer = "?"
        self.role: str | None = None  # set by a TLS transport when the connection is made
        self._buffer = bytearray()
        self._queue: deque[MbapFrame] = deque()
        self._queued_bytes = 0
        self._busy = False  # a request of this connection is waiting
        self._task: asyncio.Task | None = None  # the task finishing it
        self._closed = False
        self._close_after: str | None = None  # close once the queued requests are answered
        self._eof = False  # the client half-closed: close once its requests are answered
        self._registered = False
        self._write_paused = False
        self._read_paused = False
        #: when it last sent a whole request or was answered: bytes that make no request (a
        #: frame trickled in for ever, a header and nothing more) do not count, so such a
        #: connection neither stays open past the idle timeout nor outranks a real client
        #: when the connection limit needs a place
        self._last_activity = time.monotonic()
        self._idle_timer: asyncio.TimerHandle | None = None
        self._discarded = 0  # frames discarded for a wrong MBAP header
        self._discarded_in_row = 0  # the last of them, with no valid frame after them
        self._yielding = False  # a slice of requests was answered; the rest come next turn
        #: it sent a whole request: its connection and disconnection are logged at INFO (a
        #: port probe, a health check that connects and closes, only at DEBUG)
        self._spoke = False

    # ------------------------------------------------------------------ connection
    def connection_made(self, transport: Any) -> None:
        self.transport = transport
        peer = transport.get_extra_info("peername")
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        server = self.server
        if len(server.handlers) >= server.max_connections and not server.make_room(self.peer):
            self._closed = True
            transport.close()
            return
        server.handlers.add(self)
        self._registered = True
        self._arm_idle_timer(server.idle_timeout_s)
        if self._tls is not None:
            # the place is taken now, while the handshake runs (bounded by the idle timeout)
            self._securing = True
            transport.pause_reading()  # its bytes are the handshake's: start_tls reads them
            task = asyncio.get_running_loop().create_task(self._secure(transport, self._tls))
            _PENDING.add(task)
            task.add_done_callback(_PENDING.discard)
            return
        self._greet()

    def _greet(self) -> None:
        for hook in self.server.connection_hooks:
            hook(self)
        log.debug("client %s connected (%d open)", self.peer, len(self.server.handlers))

    async def _secure(self, transport: Any, context: ssl.SSLContext) -> None:
        """The TLS handshake; then the connection hooks (the role) and the requests that
        came with the handshake's end. A failed handshake is logged (rate-limited), with
        the reason, and frees the place."""
        timeout_s = self.server.idle_timeout_s or HANDSHAKE_TIMEOUT_S
        try:
            secure = await asyncio.get_running_loop().start_tls(
                transport,
                self,
                context,
                server_side=True,
                ssl_handshake_timeout=timeout_s,
                ssl_shutdown_timeout=TLS_SHUTDOWN_TIMEOUT_S,
            )
        except asyncio.CancelledError:
            transport.abort()
            raise
        except (OSError, ValueError, RuntimeError, TimeoutError) as exc:  # ssl.SSLError too
            if not self._closed:  # else closed for a reason already logged
                self.server.handshake_failed(self.peer, exc)
            transport.abort()
            self._forget()
            return
        if self._closed or secure is None:  # closed meanwhile (the limit, the idle timer)
            if secure is not None:
                secure.abort()
            transport.abort()
            self._forget()
            return
        self.transport = secure
        self._securing = False
        self._greet()
        if self._buffer or self._eof:  # (the requests, or a close, that came with its end)
            self._drain()

    def _forget(self) -> None:
        """Closed: cancel the idle timer and free the place."""
        self._closed = True
        if self._idle_timer is not None:
            self._idle_timer.cancel()
        if self._registered:
            self._registered = False
            self.server.handlers.discard(self)

    def connection_lost(self, exc: Exception | None) -> None:
        registered = self._registered
        self._forget()
        if not registered:
            return
        self._log_disconnected(f" ({exc})" if exc and not _ordinary_close(exc) else "")

    def _log_disconnected(self, reason: str) -> None:
        """Log the disconnection (rate-limited with a count; a client that never sent a
        request at debug level)."""
        say = self.server.log_disconnected if self._spoke else log.debug
        say("client %s disconnected%s (%d open)", self.peer, reason, len(self.server.handlers))

    def eof_received(self) -> bool:
        """The client sent all it will send: answer what it asked, then close. Over TLS
        the transport closes itself whatever this returns (a close_notify closes both
        ways), and asyncio warns when it is True: TLS is the handler's own knowledge, not
        the transport's, which during the handshake's end is still the plain one (the
        close_notify read with the client's Finished, as ``echo | openssl s_client`` sends
        it, came before the TLS transport was handed over: asyncio's warning in 13 of 15
        runs, a stranger's probe). A handshake under way closes at its end."""
        self._eof = True
        if not self._securing and not self.waiting and not self._closed:
            self.transport.close()
        # plain TCP: kept open for the answers still to come
        return self._tls is None and not self._closed

    def close(self, reason: str, kind: str) -> None:
        """Close the connection with a log line naming ``reason``: for each ``kind`` of
        reason at most one a :data:`_LIMIT_LOG_INTERVAL_S`, with a count (120 silent
        connections timing out together wrote 98 lines in 2 s; a stranger's probe)."""
        if self._closed or self.transport is None:
            return
        self._closed = True
        self.server.log_close(kind, self.peer, reason)
        self.transport.close()

    def close_quietly(self, *, at_once: bool = False) -> None:
        """Close the connection and free its place (the caller logs why); ``at_once``: its
        descriptor too, without waiting for what it still has to send or a TLS close (the
        process needs that descriptor for a new connection)."""
        if self._registered:
            self._registered = False
            self.server.handlers.discard(self)
        self._closed = True
        if self.transport is not None:
            if at_once:
                self.transport.abort()
            else:
                self.transport.close()

    def _arm_idle_timer(self, delay_s: float) -> None:
        if self.server.idle_timeout_s > 0 and hasattr(self.transport, "get_extra_info"):
            loop = asyncio.get_running_loop()
            self._idle_timer = loop.call_later(delay_s, self._check_idle)

    def _check_idle(self) -> None:
        timeout_s = self.server.idle_timeout_s
        idle_s = time.monotonic() - self._last_activity
        if self._busy or idle_s < timeout_s:
            self._arm_idle_timer(max(timeout_s - idle_s, 0.01) if not self._busy else timeout_s)
            return
        what = "a request left incomplete" if self._buffer else "idle"
        self.close(f"{what} for {idle_s:.0f} s (--idle-timeout {timeout_s:g})", "idle")

    # ------------------------------------------------------------------ flow control
    def pause_writing(self) -> None:
        self._write_paused = True
        self._update_reading()

    def resume_writing(self) -> None:
        self._write_paused = False
        self._update_reading()

    def _update_reading(self) -> None:
        waiting_bytes = self._queued_bytes + len(self._buffer)
        want_pause = self._write_paused or waiting_bytes > MAX_QUEUED_BYTES or self._yielding
        if self._closed or want_pause == self._read_paused:
            return
        self._read_paused = want_pause
        if want_pause:
            self.transport.pause_reading()
        else:
            self.transport.resume_reading()

    # ------------------------------------------------------------------ requests
    def data_received(self, data: bytes) -> None:
        if self._closed or self._close_after is not None:
            return
        self._buffer += data
        if not self._securing:  # else the handshake's end drains it, once the role is known
            self._drain()

    def _parse(self) -> int:
        """Take up to :data:`MAX_ANSWERS_PER_TURN` frames from the buffer into the queue
        (a stream of thousands is cut into turns, never parsed in one go); returns how
        many were discarded for their header."""
        frames, discarded, error, self._discarded_in_row = split_frames(
            self._buffer, MAX_ANSWERS_PER_TURN, self._discarded_in_row
        )
        for why in discarded:
            self._log_discard(why)
        if error is not None:  # answer the frames before the bad header, then close
            self._buffer.clear()
            self._close_after = (
                f"bad MBAP header ({error}); the stream cannot be resynchronised: the"
                " requests before it were answered, the bytes from it on are dropped"
            )
        for frame in frames:
            self._queue.append(frame)
            self._queued_bytes += len(frame.pdu) + 7
        if frames:
            self._last_activity = time.monotonic()
            if not self._spoke:
                self._spoke = True
                self.server.log_connected(
                    "client %s connected (%d open)", self.peer, len(self.server.handlers)
                )
        return len(discarded)

    def _log_discard(self, why: str) -> None:
        """One warning for the first frame of a connection discarded for its header, the
        rest counted at debug level (a stream of them must not flood the log). It says only
        what is known when it is logged: whether the frames after it are answered depends
        on them (:data:`MAX_DISCARDED_IN_ROW` in a row close the connection, in a line of
        its own)."""
        self._discarded += 1
        level = logging.WARNING if self._discarded == 1 else logging.DEBUG
        log.log(
            level,
            "discarded a frame of %s without an answer: bad MBAP header (%s); the connection"
            " goes on, closed at %d such frames in a row (%d discarded on this connection)",
            self.peer,
            why,
            MAX_DISCARDED_IN_ROW,
            self._discarded,
        )

    @property
    def spoke(self) -> bool:
        """Whether it ever sent a request (its handshake aside)."""
        return self._spoke

    @property
    def unused_since(self) -> float | None:
        """When it last sent or was answered (``time.monotonic()``), if no request of it
        waits and it is open; else None."""
        return None if self._closed or self.waiting else self._last_activity

    @property
    def waiting(self) -> bool:
        """Whether requests of this connection are still to be answered."""
        return self._busy or bool(self._queue) or frame_ready(self._buffer)

    def cancel(self) -> None:
        """Abandon the request in progress and the queued ones (the server stops)."""
        self._closed = True
        self._queue.clear()
        if self._task is not None:
            self._task.cancel()

    def stop(self) -> None:
        """The server stops: abandon the requests, close the connection and log its
        disconnection now, before the server says its counts (from ``connection_lost``
        it came after them, uncounted, or never: the loop ends first)."""
        registered = self._registered
        self.cancel()
        self.close_quietly()
        if registered:
            self._log_disconnected(" (the server stops)")

    def datagram_received(self, data: bytes, _addr: tuple | None = None) -> None:
        """The same as :meth:`data_received` (kept for the benchmarks' in-process driver)."""
        self.data_received(data)

    def _drain(self) -> None:
        """Answer the queued requests in order until one has to wait (then it goes on in a
        task, and this resumes when it is done)."""
        self._yielding = False
        out: list[bytes] = []
        answered = 0
        while not self._busy and not self._closed:
            if answered >= MAX_ANSWERS_PER_TURN:  # bounded work: let other connections in
                self._yielding = True
                asyncio.get_running_loop().call_soon(self._drain)
                break
            if not self._queue:
                if not frame_ready(self._buffer):
                    break
                answered += self._parse()  # a discarded frame is work too
                continue
            answered += 1
            frame = self._queue.popleft()
            self._queued_bytes -= len(frame.pdu) + 7
            coro = self._answer(frame)
            try:
                future = coro.send(None)
            except StopIteration as stop:
                if stop.value is not None:
                    out.append(stop.value)
                continue
            self._busy = True
            self._task = asyncio.get_running_loop().create_task(self._finish(coro, future))
            _PENDING.add(self._task)
            self._task.add_done_callback(_PENDING.discard)
        self._send(out)
        if not self.waiting and not self._yielding:
            if self._close_after is not None:
                self.close(self._close_after, "framing")
                return
            if self._eof and not self._closed:
                self._closed = True
                self.transport.close()
                return
        self._update_reading()

    async def _finish(self, coro: Coroutine[Any, Any, bytes | None], future: Any) -> None:
        try:
            reply = await _resume(coro, future)
        finally:
            self._busy = False
            self._task = None
        if reply is not None:
            self._send([reply])
        self._drain()

    def _send(self, replies: list[bytes]) -> None:
        if replies and not self._closed and self.transport is not None:
            self._last_activity = time.monotonic()
            self.transport.write(b"".join(replies))

    async def _answer(self, frame: MbapFrame) -> bytes | None:
        info = RequestInfo.of(frame.unit_id, frame.pdu, self.peer, self.role)
        try:
            response = await self.server.execute(info, frame.pdu)
        except Exception:  # a gate failed: the spec's 04, and the connection goes on
            log.exception("request %s of %s failed", frame.pdu[:8].hex(), self.peer)
            response = exception_pdu(info.function_code, SERVER_DEVICE_FAILURE)
        if response is None:
            return None
        return frame_bytes(frame.transaction_id, frame.unit_id, response)


class BenchModbusServer:
    """A Modbus TCP server over pymodbus ``SimDevice`` datastores (see the module docstring).

    Args:
        devices: one ``SimDevice`` per unit; device id 0 is the catch-all of unknown units.
        address: (host, port) to listen on (port 0: any free one).
        identity: what read device identification (43/14) answers; None: exception 01.
        idle_timeout_s: close connections that sent no whole request for this long (0: never).
        max_connections: connections open at once; a new one beyond closes the oldest
            unused one (none unused: the new one is closed).
        ssl: an ``ssl.SSLContext`` for Modbus/TCP Security, or None.
        dashboard_connections: the HTTP connections of a dashboard serving beside it, whose
            descriptors the connection limit leaves (0: no dashboard, none left for it).
        bits: per unit, the bit addresses it has per read function (1: coils, 2: discrete
            inputs); a read of others gets 02 (:class:`DocumentedBits`).
        own_units: the emulator's own units, never reached by a broadcast.
    """

    def __init__(
        self,
        devices: list[SimDevice],
        address: tuple[str, int] = ("127.0.0.1", 5020),
        *,
        identity: DeviceIdentity | None = None,
        idle_timeout_s: float = DEFAULT_IDLE_TIMEOUT_S,
        max_connections: int = DEFAULT_MAX_CONNECTIONS,
        ssl: Any = None,
        bits: Mapping[int, Mapping[int, frozenset[int]]] | None = None,
        own_units: frozenset[int] = frozenset((100, 101)),
        dashboard_connections: int = 0,
    ) -> None:
        self.context = SimCore(devices)
        #: the emulator's own units (simulation control, truth), which a broadcast leaves
        #: alone (:func:`rig_emulator.registers.emulator_units`)
        self.own_units = own_units
        #: what requests read and write: the datastore, its bit tables as documented
        self.requests_store = DocumentedBits(self.context, bits or {})
        self.units = frozenset(d.id for d in devices if d.id != 0)
        self.address = address
        self.identity = identity
        self.idle_timeout_s = idle_timeout_s
        self.max_connections = max_connections
        self.ssl = ssl
        self.dashboard_connections = dashboard_connections
        #: the process's descriptors shared out once this listens: the Modbus connection
        #: limit and the dashboard's both come from it (:meth:`fit_descriptors`)
        self.shares: DescriptorShares | None = None
        #: consulted in order for every decoded request; the first non-None decision wins
        self.gates: list[Gate] = []
        #: the datastore's write rules, asked without writing for a unit whose operation
        #: fails (a gate's 04); None: a write's addresses alone are checked
        self.write_check: WriteCheck | None = None
        #: called with each new connection (a TLS transport sets ``handler.role`` here)
        self.connection_hooks: list[Callable[[RequestHandler], None]] = []
        self.handlers: set[RequestHandler] = set()
        self.transport: Listener | None = None
        #: per limit (--max-connections, the open-file limit): its line a
        #: :data:`_LIMIT_LOG_INTERVAL_S` at most, and what it did so far
        self._limit_logs: dict[str, EventLog] = {}
        self._limit_events: dict[str, int] = {}
        #: per kind of close: (when last logged, closes since then not logged)
        self._closes: dict[str, tuple[float, int]] = {}
        #: connection events, each kind logged the first few times an interval, then counted
        self.log_connected = EventLog(
            "client connections", CONNECTION_LOG_BURST, CONNECTION_LOG_INTERVAL_S
        )
        self.log_disconnected = EventLog(
            "client disconnections", CONNECTION_LOG_BURST, CONNECTION_LOG_INTERVAL_S
        )
        self.log_identity = EventLog(
            "TLS client identities", CONNECTION_LOG_BURST, CONNECTION_LOG_INTERVAL_S
        )
        self._log_handshake = EventLog(
            "failed TLS handshakes", HANDSHAKE_LOG_BURST, 60.0, logging.WARNING
        )
        #: out of descriptors with no connection to close: once per shortage, not per try
        self._log_descriptor_wait = EventLog(
            "shortages of file descriptors with no connection unused",
            1,
            _LIMIT_LOG_INTERVAL_S,
            logging.WARNING,
        )

    @property
    def connections(self) -> int:
        """Connections open now."""
        return len(self.handlers)

    def callback_new_connection(self) -> RequestHandler:
        return RequestHandler(self, self.ssl)

    async def serve_forever(self, *, background: bool = True) -> None:
        """Listen (raises ``RuntimeError`` when it cannot), the connection limit fitted to
        the process's descriptors as it does (:meth:`fit_descriptors`: no connection is
        accepted before); with ``background=False`` also wait until :meth:`shutdown`."""
        host, port = self.address
        try:
            self.transport = await self.listen(host, port, self.ssl)
        except OSError as exc:
            raise RuntimeError(f"cannot listen on {host}:{port}: {exc}") from exc
        self.fit_descriptors(len(self.transport.sockets))
        if not background:
            await self.transport.serve_forever()

    def fit_descriptors(self, listener_sockets: int = 1) -> None:
        """Make ``max_connections`` fit the process's open-file limit (RLIMIT_NOFILE): the
        soft limit is raised as far as the hard one allows where the connections need it,
        and a limit that still does not fit, beside the server's own descriptors (those
        open, its listener's ``listener_sockets`` among them, and those it opens later: as
        many for a second TCP listener and for the dashboard's, :data:`LATER_DESCRIPTORS`),
        the dashboard's connections (only where there is one) and the files, is lowered to
        what does, in one line (a stranger's probe: --max-connections 2000 under ``ulimit
        -n 1024`` ran out of descriptors at about 1020 connections, so the limit's relief,
        the oldest unused connection closed, never came). Lowered, not refused: the same
        command serves on any machine, as many clients as that one can hold. The shares
        are kept (:attr:`shares`): the dashboard's limit is the one this line names."""
        dashboards = 1 if self.dashboard_connections else 0
        later = listener_sockets * (1 + dashboards) + LATER_DESCRIPTORS
        shares = self.shares = descriptor_shares(
            self.max_connections, self.dashboard_connections, later
        )
        if shares.limit - shares.own < shares.files + shares.dashboard + 1:
            # nothing would be served (a re-probe: under ``ulimit -n 16`` with a pty and the
            # dashboard the line said "serving at most 1 connections" and served none)
            least = shares.own + shares.files + shares.dashboard + 1
            raise OSError(
                f"the open-file limit (RLIMIT_NOFILE) {shares.limit} leaves no descriptor for a"
                f" connection: the server's own listeners and files take {shares.own}; raise it"
                f" to {least} at least (ulimit -n {least})"
            )
        if shares.modbus < self.max_connections:
            log.warning(
                "--max-connections %d does not fit the process's %s (%s): serving at most "
                "%d connections",
                self.max_connections,
                shares.said,
                shares.room,
                shares.modbus,
            )
            self.max_connections = shares.modbus
        elif shares.limit != shares.was:
            log.info("%s, for --max-connections %d", shares.said, self.max_connections)

    async def listen(self, host: str, port: int, ssl_context: Any = None) -> Listener:
        """A listener for this server's connections on ``host:port``, TLS with
        ``ssl_context``. A TLS connection counts from its first byte, not from the end of
        its handshake (which the idle timeout bounds as any silence, else
        :data:`HANDSHAKE_TIMEOUT_S`): a client that opens the port and stalls its handshake
        holds one place of ``max_connections``, and not for long; a failed handshake is
        logged with its reason. Out of descriptors, it closes the oldest unused connection
        (:meth:`make_room_for_descriptor`)."""
        return await listen(
            host,
            port,
            lambda: RequestHandler(self, ssl_context),
            lambda: self.max_connections - len(self.handlers),
            self.make_room_for_descriptor,
        )

    def handshake_failed(self, peer: str, exc: BaseException) -> None:
        """Log a failed TLS handshake (a wrong certificate, an old TLS version, plain bytes
        on the TLS port, a stall): one line each, at most :data:`HANDSHAKE_LOG_BURST` a
        minute, the rest counted."""
        reason = getattr(exc, "reason", None) or str(exc) or type(exc).__name__
        verify = getattr(exc, "verify_message", None)  # why a certificate was refused
        if verify:
            reason = f"{reason}: the client's certificate: {verify}"
        if verify == "unhandled critical extension":
            reason += (
                " (a Modbus role extension marked critical is one: Python's ssl cannot accept it,"
                " issue it non-critical; see the README)"
            )
        self._log_handshake("client %s: TLS handshake failed (%s); connection closed", peer, reason)

    async def shutdown(self) -> None:
        """Stop listening and close every connection, then say the connection events of
        each kind not logged, the disconnections of this stop among them (said before
        the connections were closed, the stop's went uncounted: 30 clients, 10 of their
        disconnections never said; a re-probe)."""
        if self.transport is not None:
            self.transport.close()
        for handler in list(self.handlers):
            handler.stop()
        self.handlers.clear()
        logs = (
            self.log_connected,
            self.log_disconnected,
            self.log_identity,
            self._log_handshake,
            self._log_descriptor_wait,
        )
        for events in (*logs, *self._limit_logs.values()):
            events.flush()
        for kind in list(self._closes):
            self._log_closes_left(kind)

    def close_all_connections(self, reason: str) -> int:
        """Close every open connection (logged as :meth:`log_close` does); how many."""
        handlers = list(self.handlers)
        for handler in handlers:
            handler.close(reason, "disconnect")
        return len(handlers)

    def make_room(self, peer: str) -> bool:
        """At the connection limit, close the oldest unused connection for the new one from
        ``peer``: "If the number of client and server connections is greater than the
        number of authorized connections the oldest unused connection is closed" (the
        guide's 4.2.1.2). Unused: no request waiting. A connection that never sent a request
        was never used and goes before any that was, the one open longest first (a port
        scan, a client that connected and left without a word and whose end the server
        has not read yet, a leaking tool: a burst of them closed a client polling every
        second, whose last answer was older than their connects); among the used ones, the
        one that sent or was answered longest ago. With every connection busy the new one
        is refused. Either is logged, at most once per interval, with a count."""
        oldest = self._oldest_unused()
        if oldest is None:
            self._log_limit(f"refused the connection of {peer}")
            return False
        self._log_limit(f"closed the oldest unused connection ({oldest.peer}) for {peer}")
        oldest.close_quietly()
        return True

    def make_room_for_descriptor(self, first: bool = True) -> bool:
        """The process has no file descriptor left for a new connection (files, other
        listeners' connections took them): close the oldest unused connection, as at the
        connection limit (:meth:`make_room`), at once, so the next one is served; False
        when every connection has a request waiting (the new ones wait in the backlog).
        Logged as the limit is, a line per interval at most, with a count of the
        connections closed; a shortage with none to close is said on its ``first`` try
        only (the retries counted as connections closed, none was: a re-probe)."""
        cause = "the process's open-file limit"
        oldest = self._oldest_unused()
        if oldest is None:
            if first:
                self._log_descriptor_wait(
                    "no file descriptor left for a new connection (%s) and none unused: new "
                    "connections wait in the backlog until one is freed; %d connections open",
                    cause,
                    len(self.handlers),
                )
            return False
        self._log_limit(
            f"no file descriptor left for a new connection: closed the oldest unused"
            f" connection ({oldest.peer})",
            cause,
        )
        oldest.close_quietly(at_once=True)
        return True

    def _oldest_unused(self) -> RequestHandler | None:
        """The connection the limit closes first (:meth:`make_room`), or None."""
        unused = [h for h in self.handlers if h.unused_since is not None]
        return min(unused, key=lambda h: (h.spoke, h.unused_since or 0.0), default=None)

    def log_close(self, kind: str, peer: str, reason: str) -> None:
        """Log a connection closed for ``reason``: at most one line of each ``kind`` a
        :data:`_LIMIT_LOG_INTERVAL_S`, saying how many of that kind it did not log."""
        now = time.monotonic()
        logged_s, unlogged = self._closes.get(kind, (-_LIMIT_LOG_INTERVAL_S, 0))
        if now - logged_s < _LIMIT_LOG_INTERVAL_S:
            self._closes[kind] = (logged_s, unlogged + 1)
            if not unlogged:  # the count is said when the interval ends, burst or not
                with contextlib.suppress(RuntimeError):  # (no loop: said with the next)
                    asyncio.get_running_loop().call_later(
                        logged_s + _LIMIT_LOG_INTERVAL_S - now, self._log_closes_left, kind
                    )
            return
        more = f" ({unlogged} more closed so since the last such line)" if unlogged else ""
        log.warning("closing the connection of %s: %s%s", peer, reason, more)
        self._closes[kind] = (now, 0)

    def _log_closes_left(self, kind: str) -> None:
        """The closes of ``kind`` an interval did not log, in one line (a burst's count was
        said only when another close of its kind came, maybe never; a re-probe)."""
        logged_s, unlogged = self._closes.get(kind, (0.0, 0))
        if unlogged:
            log.warning(
                "%d more connection(s) closed (%s) in the %g s after the last such line",
                unlogged,
                kind,
                _LIMIT_LOG_INTERVAL_S,
            )
            self._closes[kind] = (logged_s, 0)

    def _log_limit(self, what: str, cause: str = "--max-connections") -> None:
        """Log what a limit (``cause``) did: one line per interval, with a count (and the
        count of those the interval did not log as it ends)."""
        events = self._limit_events[cause] = self._limit_events.get(cause, 0) + 1
        if cause not in self._limit_logs:
            self._limit_logs[cause] = EventLog(
                f"connections closed or refused for {cause}",
                1,
                _LIMIT_LOG_INTERVAL_S,
                logging.WARNING,
            )
        self._limit_logs[cause](
            "%s: %d connections open (%s); %d so far", what, len(self.handlers), cause, events
        )

    # ------------------------------------------------------------------ requests
    def decide(self, info: RequestInfo, gates: Iterable[Gate] | None = None) -> GateDecision:
        """The first non-None decision of the gates, or the default (answer normally)."""
        for gate in self.gates if gates is None else gates:
            decision = gate(info)
            if decision is not None:
                return decision
        return _PASS

    async def execute(self, info: RequestInfo, pdu: bytes) -> bytes | None:
        """The response PDU to ``pdu`` (None: no reply): the gates, then the unit check
        (0B for a unit the bench does not have, whatever the function), then the request
        itself, checked per the spec (:mod:`rig_emulator.modbus.conformance`). A gate's
        delay passes before the request is carried out; a fault's, no longer than the fault
        lasts (:func:`_hold`)."""
        if not self.gates:
            return await self._carry_out(_PASS, info, pdu)
        with holding() as holds:
            decision = self.decide(info)
        if decision.delay_s > 0:
            await _hold(decision.delay_s, holds)
        return await self._carry_out(decision, info, pdu)

    async def answer(self, info: RequestInfo, pdu: bytes) -> tuple[float, bytes | None]:
        """(a gate's delay [s], the response PDU) to ``pdu``, carried out at once: for a line
        that keeps its own time (RTU), where the delay comes on top of the reply's."""
        decision = self.decide(info) if self.gates else _PASS
        return decision.delay_s, await self._carry_out(decision, info, pdu)

    async def _carry_out(
        self, decision: GateDecision, info: RequestInfo, pdu: bytes
    ) -> bytes | None:
        """The response PDU to ``pdu`` under a gate's ``decision`` (its delay waited out).

        A gate's exception code answers before any check (a busy device, 05 or 06; a
        gateway that cannot reach its target, 0A or 0B; a role's 01: whatever the request),
        except 04 SERVER DEVICE FAILURE, which comes at the operation
        (:func:`process_failing`): an illegal request to a failing unit still gets its
        01/03/02, a legal one 04, and nothing is written."""
        if decision.drop:
            return None
        failing = decision.exception_code == SERVER_DEVICE_FAILURE
        if decision.exception_code is not None and not failing:
            return exception_pdu(info.function_code, decision.exception_code)
        if info.unit_id not in self.units:
            return exception_pdu(info.function_code, GATEWAY_TARGET_FAILED)
        try:
            if failing:
                response = await process_failing(
                    self.requests_store, info.unit_id, pdu, self.identity, self.write_check
                )
                if response[1] != SERVER_DEVICE_FAILURE:  # the fault's count: not its request
                    refused_by_checks()
                return response
            return await process(self.requests_store, info.unit_id, pdu, self.identity)
        except Exception:  # a datastore fault: the spec's 04, and the server goes on
            log.exception("request %s of %s failed", pdu[:8].hex(), info.peer)
            return exception_pdu(info.function_code, SERVER_DEVICE_FAILURE)

    # ------------------------------------------------------------------ datastore
    async def async_setValues(
        self, device_id: int, func_code: int, address: int, values: list
    ) -> None:
        """Set values in the datastore (the emulator's publishing); refusal is a bug."""
        if await self.context.async_setValues(device_id, func_code, address, values):
            raise TypeError(f"the datastore refused {func_code}@{address} of unit {device_id}")

    async def async_getValues(
        self, device_id: int, func_code: int, address: int, count: int = 1
    ) -> list:
        """Values of the datastore (or the exception code it answers)."""
        return await self.context.async_getValues(device_id, func_code, address, count)


_PASS = GateDecision()
