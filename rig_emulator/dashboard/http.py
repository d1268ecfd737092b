"""The dashboard's HTTP side: a small HTTP/1.1 server on the server's event loop.

Routes (GET, or HEAD for the head alone, unless said; another method gets 405 with
``Allow``):

- ``/``: the page (``static/index.html``: plain HTML, CSS and canvas drawing, no library,
  nothing fetched from the internet);
- ``/api/state[?window=S]``: the state as JSON (readings by unit, clock, faults, trends of
  the last S simulated seconds);
- ``/api/stream``: the same pushed as server-sent events every :data:`PUSH_PERIOD_S` of
  wall time (each event: readings, clock, faults and the trend samples taken since the
  last event, ``trend_point``);
- POST ``/api/control`` with ``{"signal": NAME, "value": X}``: only with
  ``--http-control``, for the signals the state's ``controls`` lists (every plant command
  the map has a writable point for, and the speed); the write takes the Modbus write path
  of :meth:`~rig_emulator.modbus.server.BenchServer.write_signal` (the same checks, the
  same exception codes, the guard of the clock commands: a real-time server without
  ``--allow-control`` refuses the speed, 403), so the page can do nothing a Modbus client
  could not;
- POST ``/api/faults`` with ``{"inject": {FAULT}}`` (an entry as in ``FAULTS.yaml``,
  validated the same way), ``{"clear": true}``, or both (clear, then inject; a bad fault
  changes nothing): only with ``--http-control``, through
  :meth:`~rig_emulator.modbus.server.BenchServer.inject` (journaled with source
  ``dashboard``) and ``clear_faults``, refused where the Modbus fault block is (403).

Every request is bounded (4 kB of request target, else 414; 8 kB of headers, 4 kB of body,
10 s to arrive); a malformed one gets 400 and the connection closes. The work per push is
one snapshot shared by all streams; a stream that cannot keep up skips samples instead of
queueing them (the page fetches the history again now and then).

Connections are bounded too: at most :data:`~rig_emulator.modbus.connections.DASHBOARD_CONNECTIONS`
open (fewer where the process's open-file limit holds fewer: the share the Modbus server's
start gave it, the one its line names), a new one beyond closes the one that has waited
longest for its request (none waits: the new one is closed), and so does a process out of
file descriptors; each logged, a line a minute at most, with a count of the connections
closed (a shortage with none to close, once) (a stranger's probe: 1100 idle connections
under ``ulimit -n 1024`` took every descriptor, and asyncio logged a traceback per failed
accept, 2958 of them).
"""

from __future__ import annotations

import asyncio
import contextlib
import ipaddress
import itertools
import json
import logging
import math
import re
import socket
import time
from dataclasses import dataclass
from importlib import resources
from urllib.parse import parse_qs, urlsplit

import numpy as np

from rig_emulator.dashboard.state import (
    CLOCK_MODES,
    Trend,
    served,
    trend_points,
    trend_values,
    units,
)
from rig_emulator.faults import FaultError
from rig_emulator.modbus.connections import (
    DASHBOARD_CONNECTIONS,
    EventLog,
    Listener,
    descriptor_shares,
    listen,
)
from rig_emulator.modbus.fault_control import FAULT_COMMANDS
from rig_emulator.modbus.server import BenchServer, carried_range
from rig_emulator.registers import Point, precision

log = logging.getLogger("rig_emulator.dashboard")

PUSH_PERIOD_S = 0.5
MAX_TARGET_BYTES = 4096
MAX_HEADER_BYTES = 8192
MAX_BODY_BYTES = 4096
REQUEST_TIMEOUT_S = 10.0
MAX_STREAMS = 64
#: At most one log line per this long about streams closed for new ones [s] (a client
#: opening streams in a loop wrote a line per stream)
EVICTION_LOG_S = 60.0
INITIAL_WINDOW_S = 12 * 3600.0  # the trend sent with the page
#: Signals the controls may write beside the plant's commands (those: every one the map
#: has a writable point for, setpoints and switches)
CLOCK_CONTROLS = ("speed_factor",)
#: A real-time tick's sample joins the trend only this long after its last point [simulated
#: s]: at high speed every tick adds one (x1000: one per 100 s), at low speed the pushes do
TICK_SAMPLE_MIN_S = 1.0
STREAM_HEAD = (
    b"HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\n"
    b"Cache-Control: no-cache\r\nConnection: close\r\n\r\n"
)
#: What each path takes (HEAD: the head of the GET)
ROUTES = {
    "/": ("GET", "HEAD"),
    "/api/state": ("GET", "HEAD"),
    "/api/stream": ("GET", "HEAD"),
    "/api/control": ("POST",),
    "/api/faults": ("POST",),
}


@dataclass
class _Connection:
    """An HTTP connection being served."""

    writer: asyncio.StreamWriter
    since_s: float  # when it came (monotonic) [s]
    reading: bool = True  # its request has not all come yet


class BadRequest(Exception):
    """A request the dashboard refuses with 400."""


class CrossSite(Exception):
    """A control request that may come from another web site (refused with 403)."""


class TooLong(Exception):
    """A request target longer than :data:`MAX_TARGET_BYTES` (refused with 414)."""


class SlowRequest(Exception):
    """A request not all come within :data:`REQUEST_TIMEOUT_S` (refused with 408)."""


def _check_same_site(headers: dict[str, str]) -> None:
    """Controls come from the page itself, never from another site the lab's browser has
    open: the body must be declared JSON (a form, or a ``no-cors`` fetch of another site,
    can only send text/plain, form or multipart bodies without asking the server first, and
    the dashboard answers no preflight), an ``Origin`` must be this server's own, and the
    ``Host`` must be an address, ``localhost`` or this machine's name (a site whose name
    was made to point here, DNS rebinding, shows its own name)."""
    kind = headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":
        raise CrossSite(f"Content-Type {kind or 'none'}: controls are sent as application/json")
    host = headers.get("host", "")
    origin = headers.get("origin")
    # the page's own origin is http://host (RFC 6454 4: scheme, host and port); a page of
    # https://host is another origin, as is one whose Origin is "null" (a sandbox, a file)
    if origin is not None and origin.lower() != f"http://{host}".lower():
        raise CrossSite(f"Origin {origin} is not this dashboard (http://{host})")
    name = urlsplit(f"//{host}").hostname or ""
    if not _own_name(name):
        raise CrossSite(f"Host {host or 'none'} is not an address or a name of this machine")


def _own_name(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        pass
    own = {"localhost", socket.gethostname().lower(), socket.getfqdn().lower()}
    return name.lower() in own or name.lower().endswith(".localhost")


class Dashboard:
    """Serve the page and the state of ``server`` on ``host:port`` (port 0: any free), at
    most ``max_connections`` HTTP connections at once (fewer where the process's open-file
    limit holds fewer: see :meth:`start`)."""

    def __init__(
        self,
        server: BenchServer,
        host: str = "127.0.0.1",
        port: int = 8080,
        control=False,
        max_connections: int = DASHBOARD_CONNECTIONS,
    ) -> None:
        self.server = server
        self.host = host
        self.port = port
        self.control = control
        self.max_connections = max_connections
        self.trend = Trend()
        self._trend_points = trend_points(server.map)
        #: the controls: each writable signal's finest point (the one write_signal takes)
        self._controls = _control_points(server) if control else {}
        self._trend_sent = 0  # trend samples taken when the last event was pushed
        self._page = resources.files("rig_emulator.dashboard").joinpath("static/index.html")
        #: the live streams, oldest first: each one's queue of events and its connection
        self._streams: dict[asyncio.Queue, asyncio.StreamWriter] = {}
        self._srv: Listener | None = None
        self._task: asyncio.Task | None = None
        #: the last sample: the published values it was of, and the state (:meth:`_current`)
        self._cached: tuple[dict[str, float], dict] | None = None
        self._evicted = 0  # streams closed for new ones since the last line said so
        self._evicted_said = -math.inf  # when that line was logged (monotonic) [s]
        #: the connections being served: ended before the loop stops (cancelled by the
        #: loop's shutdown, one with a request half sent logged a CancelledError traceback
        #: from asyncio's own callback: a probe)
        self._handlers: dict[asyncio.Task, _Connection] = {}
        #: connections closed (or refused) at the limit, and for want of a descriptor
        self._at_limit = EventLog(
            "HTTP connections closed at the dashboard's limit",
            1,
            EVICTION_LOG_S,
            logging.WARNING,
            log,
        )
        self._out_of_descriptors = EventLog(
            "HTTP connections closed for a file descriptor", 1, EVICTION_LOG_S, logging.WARNING, log
        )
        #: out of descriptors with none to close: once per shortage, not per try
        self._descriptor_wait = EventLog(
            "shortages of file descriptors with no HTTP connection waiting for its request",
            1,
            EVICTION_LOG_S,
            logging.WARNING,
            log,
        )

    # ------------------------------------------------------------------ lifecycle
    async def start(self) -> None:
        """Listen, the connection limit fitted to the process's open-file limit first:
        at most its share of the descriptors, silently (the limit is the dashboard's own,
        not an option). The share is the one the Modbus server made at its start, for a
        server told of its dashboard (``BenchServer(dashboard=True)``, ``serve --http``):
        made again here, with the descriptors open then, it differed from the one the
        start's line named (6 there, 4 here: a re-probe); else the dashboard's part of the
        descriptors free now, beside the Modbus connections to come."""
        modbus = self.server.modbus_server
        shares = modbus.shares if modbus is not None else None
        if shares is None or not shares.dashboard:
            connections = modbus.max_connections if modbus is not None else 0
            shares = descriptor_shares(connections, self.max_connections)
        self.max_connections = min(self.max_connections, shares.dashboard)
        self._srv = await listen(
            self.host,
            self.port,
            lambda: asyncio.StreamReaderProtocol(asyncio.StreamReader(), self._handle),
            lambda: self.max_connections - len(self._handlers),
            self._make_room_for_descriptor,
        )
        self.port = self._srv.sockets[0].getsockname()[1]
        self._sample()
        self.server.on_advance_sample = self._sample_advance
        previous = self.server.on_tick
        self.server.on_tick = (
            self._sample_tick if previous is None else lambda: (previous(), self._sample_tick())
        )
        self._task = asyncio.create_task(self._push_loop(), name="dashboard push")

    async def stop(self) -> None:
        if self._evicted:  # (those after the last line were never counted: a re-probe)
            log.warning(
                "dashboard: %d more live stream(s) closed for new streams or requests since the "
                "last such line",
                self._evicted,
            )
            self._evicted = 0
        self._at_limit.flush()
        self._out_of_descriptors.flush()
        self._descriptor_wait.flush()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
        for queue, writer in list(self._streams.items()):
            writer.transport.abort()
            _end(queue)
        if self._srv is not None:
            self._srv.close()
        for connection in list(self._handlers.values()):
            connection.writer.transport.abort()
        if self._handlers:  # each ends on its aborted connection
            await asyncio.wait(list(self._handlers), timeout=2.0)
        if self._srv is not None:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._srv.wait_closed(), 2.0)

    # ------------------------------------------------------------------ state
    def _published(self) -> dict[str, float]:
        """What the server last published (before its first publish: its values)."""
        return self.server.published_values or self.server.values()

    def _sample_trend(self, values: dict[str, float]) -> None:
        """A trend point of what the server published (of the plant run it published: a
        look taken inside an advance is older than the trend's last and dropped)."""
        self.trend.add(
            values["sim_time_s"],
            trend_values(self._trend_points, values),
            run=self.server.published_resets,
        )

    def _sample_tick(self) -> None:
        """A real-time tick published: a trend point if the last is a simulated second old
        (or the plant was reset)."""
        if (
            self.server.published_resets != self.trend.run
            or self.server.emulator.sim_time_s - self.trend.last_time_s >= TICK_SAMPLE_MIN_S
        ):
            self._sample_trend(self._published())

    def _sample_advance(self, done: bool) -> None:
        """A trend point from a lockstep advance: once published (``done``), what the wire
        serves (a run of short advances is drawn step by step, not between two pushes);
        part way through it, the readings as their points would serve them, a signal
        under an instrument fault with none there (a fault acts at publication only: what
        it would serve inside is not known)."""
        if done:
            self._sample_trend(self._published())
            return
        if self.server.published_resets != self.trend.run:  # a reset came before: its start
            self._sample_trend(self._published())  # (published, not yet sampled) first
        faulted = [f["signal"] for f in self.server.active_faults() if "signal" in f]
        values = self.server.sample_values()
        time_s = self.server.emulator.sim_time_s
        self.trend.add(
            time_s,
            trend_values(self._trend_points, values, hidden=faulted),
            run=self.server.resets,
        )

    def _current(self) -> dict:
        """The state as published now: sampled again only where the server published
        since the last sample (sampled for every GET, the whole map each time, a flood of
        them cost three times the CPU: a re-probe)."""
        cached = self._cached
        if cached is not None and cached[0] is self._published():
            return cached[1]
        return self._sample()

    def _sample(self) -> dict:
        values = self._published()
        time_s = values["sim_time_s"]
        self._sample_trend(values)
        clock = self.server.clock
        recent = list(itertools.islice(reversed(self.server.lateness.samples), 600))
        lateness = {
            "last": self.server.lateness.last_s * 1000.0,
            "p99_recent": float(np.percentile(recent, 99)) * 1000.0 if recent else math.nan,
        }
        state = {
            "boiler": self.server.emulator.params.name,
            "time_s": time_s,
            # which plant the trend is of: a new epoch (a restarted server) or reset count
            # starts a new history, whatever the times (the page keeps it the same way)
            "run": self._trend_run(),
            "clock": {
                "mode": CLOCK_MODES.get(int(clock.mode), str(clock.mode)),
                "speed": clock.speed,
                "tick_lateness_ms": {k: _num(v) for k, v in lateness.items()},
                "lockstep_counter": self.server.lockstep_counter,
            },
            "faults": list(getattr(self.server, "active_faults", lambda: [])()),
            "control": self.control,
            "controls": [self._control_state(s, p, values) for s, p in self._controls.items()],
            "fault_controls": {"refused": self.server.control_refusal(FAULT_COMMANDS)},
            "units": units(self.server.map, values),
        }
        self._cached = (values, state)
        return state

    def _control_state(self, signal: str, point: Point, values: dict[str, float]) -> dict:
        """A control as the page offers it: its point, the lowest and highest value a write
        can set (what its registers carry within its range, as the point serves them: an
        int32 x0.05 +0.025 in 10..90 offers 10.025..89.975), the value it holds, and why the
        server would refuse it now (None: it would not)."""
        lo, hi = carried_range(point)
        return {
            "signal": signal,
            "name": point.name,
            "unit": point.unit,
            "switch": point.datatype == "bool" or (lo, hi) == (0.0, 1.0),
            "min": _as_served(point, lo),
            "max": _as_served(point, hi),
            "value": served(point, values.get(signal, math.nan)),
            "refused": self.server.control_refusal([signal]),
        }

    def state(self, window_s: float | None = None) -> dict:
        """The state as published now with the trend, tagged with the plant run the trend
        is of (the last push's state, up to a push old, showed the time and readings from
        before a lockstep advance beside a trend that ran to its end, and named the plant
        before a reset while the trend was the new one's: re-probes)."""
        return self._current() | {"trend": self.trend.as_dict(window_s)}

    def _trend_run(self) -> dict:
        return {"epoch_id": self.server.epoch_id, "resets": self.trend.run}

    async def _push_loop(self) -> None:
        while True:
            await asyncio.sleep(PUSH_PERIOD_S)
            state = self._sample()
            new = self.trend.since(self._trend_sent)
            self._trend_sent = self.trend.added
            if not self._streams:
                continue
            event = json.dumps(state | {"trend_point": new}, allow_nan=False)
            for queue in self._streams:
                if queue.full():
                    with contextlib.suppress(asyncio.QueueEmpty):
                        queue.get_nowait()  # a slow reader skips a sample
                queue.put_nowait(event)

    # ------------------------------------------------------------------ HTTP
    def _shed(self, keep: _Connection | None = None) -> str | None:
        """Close the connection that has waited longest for its request (a connection left
        idle, a slowloris), other than ``keep``; its peer, or None when none waits."""
        waiting = [c for c in self._handlers.values() if c.reading and c is not keep]
        oldest = min(waiting, key=lambda c: c.since_s, default=None)
        if oldest is None:
            return None
        oldest.reading = False
        oldest.writer.transport.abort()  # its descriptor now: its task ends on it
        return _peer(oldest.writer)

    def _make_room_for_descriptor(self, first: bool = True) -> bool:
        """The process has no file descriptor for a new connection: close the one that has
        waited longest for its request (False: none waits). Counted are the connections
        closed; a shortage with none to close is said on its ``first`` try only (its
        retries were counted as connections closed, 25 in 20 s, none was: a re-probe)."""
        shed = self._shed()
        if shed is not None:
            self._out_of_descriptors(
                "dashboard: no file descriptor left for a new HTTP connection (the process's "
                "open-file limit): closed the one waiting longest for its request (%s)",
                shed,
            )
        elif first:
            self._descriptor_wait(
                "dashboard: no file descriptor left for a new HTTP connection (the process's "
                "open-file limit) and none waits for its request: new connections wait "
                "until one is freed; %d of %d open",
                len(self._handlers),
                self.max_connections,
            )
        return shed is not None

    def _admit(self, connection: _Connection) -> bool:
        """Whether a new connection is served: beyond the limit it closes the one that has
        waited longest for its request, or, none waiting, is closed itself."""
        if len(self._handlers) <= self.max_connections:
            return True
        shed = self._shed(keep=connection)
        if shed is None:  # streams never wait for a request: four held the page hostage
            # under --max-connections' share of 4, every request reset (a stranger's probe)
            stream = self._close_oldest_stream(
                f"{len(self._handlers) - 1} HTTP connections open (its limit)"
            )
            if stream is not None:
                return True
        self._at_limit(
            "dashboard: %d HTTP connections open (its limit): %s",
            len(self._handlers) - 1,
            f"closed the one waiting longest for its request ({shed}) for a new one"
            if shed
            else f"none waits for its request: closed the new one ({_peer(connection.writer)})",
        )
        return shed is not None

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        connection = _Connection(writer, time.monotonic())
        if task is not None:
            self._handlers[task] = connection
        try:
            if not self._admit(connection):
                writer.transport.abort()
                return
            try:
                method, target, headers, body = await asyncio.wait_for(
                    _read_request(reader), REQUEST_TIMEOUT_S
                )
            except TimeoutError:
                raise SlowRequest(f"request incomplete after {REQUEST_TIMEOUT_S:g} s") from None
            connection.reading = False
            await self._route(method, target, headers, body, writer)
        except BadRequest as exc:
            await _respond(writer, 400, {"error": str(exc)})
        except TooLong as exc:
            await _respond(writer, 414, {"error": str(exc)})
        except SlowRequest as exc:  # RFC 9110 15.5.9: said, and the connection closed
            await _respond(writer, 408, {"error": str(exc)})
        except CrossSite as exc:
            log.warning("dashboard: refused a POST from another site (%s)", exc)
            await _respond(writer, 403, {"error": str(exc)})
        except (TimeoutError, ConnectionError, asyncio.IncompleteReadError):
            pass
        finally:
            self._handlers.pop(task, None)  # type: ignore[arg-type]
            with contextlib.suppress(ConnectionError, RuntimeError):
                writer.close()

    async def _route(
        self, method: str, target: str, headers: dict[str, str], body: bytes, writer
    ) -> None:
        path, query = _path_and_query(target)
        allowed = ROUTES.get(path)
        if allowed is None:
            await _respond(writer, 404, {"error": f"no such page: {path}"})
            return
        if method not in allowed:
            await _respond(
                writer,
                405,
                {"error": f"{method} not allowed on {path} (only {', '.join(allowed)})"},
                {"Allow": ", ".join(allowed)},
            )
            return
        if method == "POST":  # after the method: a POST to a GET page is 405, not 403
            _check_same_site(headers)
        head = method == "HEAD"
        if path == "/":
            # inside the page's script: no "<" at all ("</script>", "<!--<script>" in a map's
            # text would end or hide the script); JSON reads \u003c as "<"
            state = json.dumps(self.state(INITIAL_WINDOW_S), allow_nan=False)
            state = state.replace("<", "\\u003c")
            page = self._page.read_text(encoding="utf-8").replace("/*INITIAL_STATE*/null", state, 1)
            await _respond_raw(writer, 200, "text/html; charset=utf-8", page.encode(), head=head)
        elif path == "/api/state":
            window = parse_qs(query).get("window", [None])[0]
            try:
                window_s = float(window) if window is not None else None
            except ValueError:
                raise BadRequest(f"window: '{window}' is not a number") from None
            if window_s is not None and not (math.isfinite(window_s) and window_s >= 0):
                raise BadRequest("window must be a non-negative number of seconds")
            await _respond(writer, 200, self.state(window_s), head=head)
        elif path == "/api/stream":
            if head:  # the head a stream starts with, and no stream
                writer.write(STREAM_HEAD)
                with contextlib.suppress(ConnectionError):
                    await writer.drain()
            else:
                await self._stream(writer)
        elif path == "/api/control":
            await self._control(body, writer)
        else:
            await self._faults(body, writer)

    def _close_oldest_stream(self, why: str) -> str | None:
        """Close the oldest live stream (it may be a connection that stopped reading) for
        a new stream or request: its peer, or None when there is none."""
        if not self._streams:
            return None
        oldest = next(iter(self._streams))
        self._evicted += 1
        now = time.monotonic()
        if now - self._evicted_said >= EVICTION_LOG_S:
            log.warning(
                "dashboard: %s: the oldest stream closed for a new connection (%d so since "
                "the last such line; at most one a minute)",
                why,
                self._evicted,
            )
            self._evicted, self._evicted_said = 0, now
        writer = self._streams.pop(oldest)
        writer.transport.abort()
        _end(oldest)
        return _peer(writer)

    async def _stream(self, writer: asyncio.StreamWriter) -> None:
        if len(self._streams) >= MAX_STREAMS:
            # a new viewer is never locked out by streams nobody reads
            self._close_oldest_stream(f"{MAX_STREAMS} live streams")
        queue: asyncio.Queue = asyncio.Queue(maxsize=2)
        self._streams[queue] = writer
        try:
            writer.write(STREAM_HEAD)
            first = self._current() | {"trend_point": self.trend.as_dict(0.0)}
            writer.write(f"data: {json.dumps(first, allow_nan=False)}\n\n".encode())
            await writer.drain()
            while True:
                event = await queue.get()
                if event is None:  # closed for a newer stream, or the server stops
                    break
                writer.write(f"data: {event}\n\n".encode())
                await writer.drain()
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            self._streams.pop(queue, None)

    async def _control(self, body: bytes, writer: asyncio.StreamWriter) -> None:
        if not self.control:
            await _respond(writer, 403, {"error": "controls are off (serve --http-control)"})
            return
        request = _json_body(body)
        if not isinstance(request, dict):
            raise BadRequest('expected {"signal": NAME, "value": NUMBER}')
        signal, value = request.get("signal"), request.get("value")
        if not isinstance(signal, str) or signal not in self._controls:  # (a list: a
            # traceback, "unhashable type", and an empty reply: a stranger's probe)
            raise BadRequest(f"signal: expected one of {', '.join(self._controls)}")
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise BadRequest("value: expected a number")
        try:
            number = float(value)
        except OverflowError:
            raise BadRequest("value: too large a number") from None
        if not math.isfinite(number):  # NaN and Infinity: JSON has neither, Python takes both
            raise BadRequest("value: expected a finite number")
        # the clock guard refuses it (write_signal would too, with exception 01): 403, as
        # what the server does not allow, not what the request got wrong
        guard = self.server.control_refusal([signal])
        refused = await self.server.write_signal(signal, number)
        if refused is not None:
            log.info("dashboard control refused: %s = %r (%s)", signal, value, refused)
            await _respond(writer, 403 if guard else 400, {"error": f"{signal}: {refused}"})
            return
        # what the server holds, as /api/state serves it (501 through a point of 2-kg/h
        # steps is 500: the answer said 501; 65.12500000000001 for 65.125, and the speed
        # asked for, not the float32 the clock took: re-probes)
        applied = _as_served(self._controls[signal], self.server.published_values[signal])
        log.info("dashboard control: %s = %r (applied %r)", signal, value, applied)
        self._sample()
        await _respond(writer, 200, {"ok": True, "signal": signal, "value": applied})

    async def _faults(self, body: bytes, writer: asyncio.StreamWriter) -> None:
        if not self.control:
            await _respond(writer, 403, {"error": "controls are off (serve --http-control)"})
            return
        request = _json_body(body)
        usage = 'expected {"inject": {FAULT}}, {"clear": true} or both (clear, then inject)'
        if not isinstance(request, dict) or not request or set(request) - {"inject", "clear"}:
            raise BadRequest(usage)
        if "inject" in request and not isinstance(request["inject"], dict):
            raise BadRequest(usage)
        if "clear" in request and request["clear"] is not True:
            raise BadRequest(usage)
        refused = self.server.control_refusal(FAULT_COMMANDS)
        if refused is not None:  # as the Modbus fault block: exception 01
            await _respond(writer, 403, {"error": f"faults: refused: {refused}"})
            return
        entry = None
        if "inject" in request:
            try:  # checked before anything is cleared: a bad fault changes nothing
                entry = self.server.faults.parse(request["inject"])
            except FaultError as exc:
                await _respond(writer, 400, {"error": str(exc)})
                return
        if request.get("clear") is True:
            self.server.clear_faults()
            log.info("dashboard control: faults cleared")
        if entry is not None:
            self.server.inject(entry, source="dashboard")
            log.info("dashboard control: fault %s", request["inject"])
        self._sample()
        await _respond(writer, 200, {"ok": True, "faults": self.server.active_faults()})


def _control_points(server: BenchServer) -> dict[str, Point]:
    """The signals the controls write, each with the point :meth:`BenchServer.write_signal`
    takes (the finest writable one): every plant command with a writable point (setpoints,
    switches), then the speed."""
    wanted = [*server.emulator.commands, *CLOCK_CONTROLS]
    writable = [p for d in server.map.devices for p in d.points if p.writable]
    out = {}
    for signal in wanted:
        points = [p for p in writable if p.signal == signal]
        if points:
            out[signal] = min(points, key=lambda p: precision(p, 1.0))
    return out


def _as_served(point: Point, value: float) -> float:
    """``value`` as ``point`` serves it (:func:`served`; itself where it serves none)."""
    shown = served(point, value)
    return value if shown is None else shown


def _json_body(body: bytes):
    """The request's body as JSON; an empty one, or one that is not JSON, is refused."""
    if not body.strip():
        raise BadRequest("the body is not JSON: it is empty")
    try:
        return json.loads(body)
    except (ValueError, RecursionError):  # JSONDecodeError, UnicodeDecodeError too
        raise BadRequest("the body is not JSON") from None


def _path_and_query(target: str) -> tuple[str, str]:
    """The path and query of a request target as asked (``//api/state`` is that path, not
    a host ``api`` and the path ``/state``); an absolute URL's own (RFC 9112 3.2.2)."""
    if "://" in target.split("?", 1)[0]:
        url = urlsplit(target)
        return url.path or "/", url.query
    path, _, query = target.partition("#")[0].partition("?")
    return path, query


def _peer(writer: asyncio.StreamWriter) -> str:
    """A connection's peer as "host:port" ("?" where it has none)."""
    peer = writer.get_extra_info("peername")
    return f"{peer[0]}:{peer[1]}" if peer else "?"


def _end(queue: asyncio.Queue) -> None:
    """Tell a stream's task to end (its samples dropped: nobody will read them)."""
    while not queue.empty():
        queue.get_nowait()
    queue.put_nowait(None)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


#: A field name (RFC 9110 5.1 and 5.6.2: a token of tchars).
_TOKEN = re.compile(r"[!#$%&'*+\-.^_`|~0-9A-Za-z]+")


async def _read_request(reader: asyncio.StreamReader) -> tuple[str, str, dict[str, str], bytes]:
    first = await reader.readexactly(1)
    if first == TLS_HANDSHAKE:  # (it waited 10 s for a line end and said 408: a probe)
        raise BadRequest("a TLS handshake: this port serves plain HTTP (http://, not https://)")
    try:  # the request line first: a target too long (414) is told from long headers (400)
        line = first + await reader.readuntil(b"\n")
    except asyncio.LimitOverrunError:
        raise TooLong(f"request target longer than {MAX_TARGET_BYTES} bytes") from None
    try:
        method, target, version = _line(line).split(" ")
    except ValueError:
        raise BadRequest("malformed request line") from None
    if len(target) > MAX_TARGET_BYTES:
        raise TooLong(f"request target of {len(target)} bytes (at most {MAX_TARGET_BYTES})")
    lines: list[str] = []
    size = 0
    while True:
        try:
            field = await reader.readuntil(b"\n")
        except asyncio.LimitOverrunError:
            raise BadRequest("headers too long") from None
        size += len(field)
        if size > MAX_HEADER_BYTES:
            raise BadRequest("headers too long")
        if field in (b"\r\n", b"\n"):
            break
        lines.append(_line(field))
    if not version.startswith("HTTP/1."):
        raise BadRequest(f"unsupported protocol {version!r}")
    headers: dict[str, str] = {}
    lengths: set[str] = set()
    hosts: list[str] = []
    for line in lines:
        name, colon, value = line.partition(":")
        if line[:1] in (" ", "\t"):  # RFC 9112 5.2: obs-fold, a server rejects or unfolds
            raise BadRequest("a header line folded onto the one before (obs-fold)")
        if not colon or not _TOKEN.fullmatch(name):  # RFC 9112 5.1: a server MUST reject
            # whitespace between the name and the colon (a `Host : ...` was taken: a re-probe)
            raise BadRequest(f"malformed header line {line[:40]!r}")
        name, value = name.lower(), value.strip(" \t")
        headers[name] = value
        if name == "content-length":
            lengths.add(value)
        elif name == "host":
            hosts.append(value)
    headers["host"] = _host(version, target, hosts)
    if "transfer-encoding" in headers:  # a body of chunks: the length must be given
        raise BadRequest("Transfer-Encoding is not accepted; send the body with Content-Length")
    # RFC 9112 6.3: differing lengths are a framing error (it waited for the larger and
    # dropped the connection); RFC 9110 8.6: digits only (+30 and 3_0 were taken: probes)
    if len(lengths) > 1:
        raise BadRequest(f"Content-Length given twice, differing ({', '.join(sorted(lengths))})")
    text = headers.get("content-length", "0")
    if not (text.isascii() and text.isdigit()):
        raise BadRequest(f"Content-Length {text[:20]!r} is not a number of bytes")
    length = int(text)
    if not 0 <= length <= MAX_BODY_BYTES:
        raise BadRequest(f"body of {length} bytes (at most {MAX_BODY_BYTES})")
    body = await reader.readexactly(length) if length else b""
    return method, target, headers, body


#: The first byte of a TLS record carrying a handshake (RFC 8446 5.1: ContentType 22)
TLS_HANDSHAKE = b"\x16"


def _line(raw: bytes) -> str:
    """A request or header line without its end: CRLF, or a bare LF, which RFC 9112 2.2
    lets a recipient take as one (typed into nc, it waited 10 s and said 408: a
    stranger's probe)."""
    return raw.decode("latin-1").removesuffix("\n").removesuffix("\r")


def _host(version: str, target: str, hosts: list[str]) -> str:
    """The host a request names (RFC 9112 3.2): an absolute target's authority, else its
    one ``Host`` field; an HTTP/1.1 request without one, one with two, or a host that is
    not an authority (spaces, a path, user information) is refused. HTTP/1.0 may omit it."""
    if len(hosts) > 1:
        raise BadRequest(f"Host given {len(hosts)} times ({', '.join(hosts)[:80]})")
    if "://" in target.split("?", 1)[0]:  # absolute form: its authority, not Host (3.2.2)
        try:
            host = urlsplit(target).netloc
        except ValueError:  # ("http://[::1/": a traceback and no reply, a re-probe)
            raise BadRequest(f"request target {target[:80]!r} is not a URL") from None
    elif hosts:
        host = hosts[0]
    elif version == "HTTP/1.0":
        return ""
    else:
        raise BadRequest(f"{version} request without a Host field")
    if not _HOST.fullmatch(host):
        raise BadRequest(f"Host {host[:80]!r} is not a host and port")
    try:
        urlsplit(f"//{host}").port  # noqa: B018 (in range: a ValueError if not)
    except ValueError:
        raise BadRequest(f"Host {host[:80]!r} is not a host and port") from None
    return host


#: a host and an optional port as RFC 3986 3.2.2-3.2.3 write them: an IP literal in
#: brackets, or an IPv4 address or a name of unreserved, sub-delimiter and %-encoded
#: characters ("[::1" and "[::1]x" were a traceback and a 200, a re-probe)
_HOST = re.compile(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9\-._~%!$&'()*+,;=]*)(:[0-9]*)?")


async def _respond(
    writer: asyncio.StreamWriter,
    status: int,
    content: dict,
    extra: dict[str, str] | None = None,
    head: bool = False,
) -> None:
    body = json.dumps(content, allow_nan=False).encode()
    await _respond_raw(writer, status, "application/json", body, extra, head)


REASONS = {
    200: "OK",
    400: "Bad Request",
    403: "Forbidden",
    404: "Not Found",
    405: "Method Not Allowed",
    408: "Request Timeout",
    414: "URI Too Long",
    503: "Service Unavailable",
}


async def _respond_raw(
    writer: asyncio.StreamWriter,
    status: int,
    kind: str,
    body: bytes,
    extra: dict[str, str] | None = None,
    head: bool = False,
) -> None:
    """Send a whole response (``head``: its head alone, with the body's length, as HEAD
    asks: RFC 9110 9.3.2); ``extra``: more header fields (a 405's ``Allow``)."""
    fields = "".join(f"{name}: {value}\r\n" for name, value in (extra or {}).items())
    text = (
        f"HTTP/1.1 {status} {REASONS[status]}\r\nContent-Type: {kind}\r\n"
        f"Content-Length: {len(body)}\r\n{fields}Cache-Control: no-cache\r\n"
        "Connection: close\r\n\r\n"
    )
    writer.write(text.encode() + (b"" if head else body))
    with contextlib.suppress(ConnectionError):
        await writer.drain()
