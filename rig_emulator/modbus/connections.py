"""What the Modbus and the dashboard's HTTP servers share about connections: listening
sockets that accept for themselves, the share of the process's file descriptors each
server's connections may hold, and log lines of a kind rate-limited with a count.

asyncio's own listener (``loop.create_server``) meets a process out of file descriptors
(EMFILE) with a traceback through the loop's exception handler for each of the up to 100
accepts of its turn, each also scheduling a retry of its own a second on: the tracebacks
multiply for as long as the descriptors stay short, and nothing is closed to make room (a
stranger's probe: 1.28 M lines, 94 MB and 22 s of CPU in 45 s, new clients unanswered in
the backlog). A :class:`Listener` accepts for itself: out of descriptors, it stops accepting
(the kernel keeps the new connections in the backlog), asks its server to make room (the
oldest unused connection closed, as at the connection limit; the server logs it) and tries
again once that descriptor is free; with nothing to close, later and later, up to
:data:`RETRY_MAX_S` apart.

The descriptors rarely run out that way: at start a server's connection limit is fitted to
the process's open-file limit (:func:`descriptor_shares`), once, for the Modbus server and
its dashboard alike.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import math
import os
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field

log = logging.getLogger("rig_emulator.serve")

#: accept() errors that say the process or the system has no descriptor (or buffer) left:
#: they last until a descriptor is freed, unlike a client that left before its accept
OUT_OF_DESCRIPTORS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})
BACKLOG = 100  # connections the kernel holds for accept (asyncio's default), and accepted a turn
#: out of descriptors with a connection closed to make room: its descriptor is freed on the
#: event loop's next turn, the accept tries again this much later [s]
RETRY_MIN_S = 0.01
RETRY_MAX_S = 1.0  # nothing could be closed: the retries double up to this far apart [s]
#: descriptors kept aside from the connection limits for files opened now and then (numba's
#: cache as the kernels load, the dashboard's page, a certificate), where the connections
#: leave room for them: else a sixteenth of what is free (:func:`descriptor_shares`)
RESERVED_DESCRIPTORS = 32
FILES_SHARE = 16  # the files' share of the free descriptors at most, where few are: 1/16
DASHBOARD_SHARE = 4  # the dashboard's share of them at most, where few are: 1/4
#: where not everything wanted fits, the descriptors the files and the dashboard keep (a
#: browser's few connections), within their shares above
FILES_MIN = 4
DASHBOARD_MIN = 4
#: the dashboard's connections however few descriptors are free: an open page's event
#: stream and one request beside it (with one, every request closed the page's stream)
DASHBOARD_LEAST = 2
#: the dashboard's HTTP connections open at once (streams included), its own limit
DASHBOARD_CONNECTIONS = 256


# ---------------------------------------------------------------------- descriptors
def open_descriptors() -> int:
    """The file descriptors the process has open now (0 where the OS does not say)."""
    for folder in ("/proc/self/fd", "/dev/fd"):
        with contextlib.suppress(OSError):
            return len(os.listdir(folder))
    return 0


def open_file_limit(needed: int) -> tuple[int, int]:
    """(the process's soft open-file limit as it was, as it is now): raised toward
    ``needed`` descriptors, as far as the hard limit allows, when below it (common server
    practice; only as far as needed: a descriptor above 1023 is one ``select()`` cannot
    watch). Where there is no such limit (Windows), ``needed`` both times."""
    try:
        import resource
    except ImportError:
        return needed, needed
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= needed:
        return soft, soft
    target = needed if hard == resource.RLIM_INFINITY else min(needed, hard)
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    except (ValueError, OSError):  # (macOS: at most OPEN_MAX, whatever the hard limit)
        return soft, soft
    return soft, target


@dataclass(frozen=True)
class DescriptorShares:
    """How the process's descriptors are shared out (:func:`descriptor_shares`)."""

    was: int  # the soft open-file limit before
    limit: int  # the soft open-file limit now
    own: int  # descriptors the server holds itself: open then, and to be opened
    files: int  # descriptors kept aside for files
    modbus: int  # Modbus connections that fit
    dashboard: int  # dashboard HTTP connections that fit (0: no dashboard)

    @property
    def said(self) -> str:
        """The limit and the server's own descriptors, as a log line names them."""
        raised = f", raised from {self.was}" if self.limit != self.was else ""
        return (
            f"open-file limit (RLIMIT_NOFILE) {self.limit}{raised}, {self.own} for the"
            " server's own listeners and files"
        )

    @property
    def room(self) -> str:
        """What the descriptors are kept for besides Modbus connections, as a log line
        names it."""
        dashboard = f"the dashboard's {self.dashboard} connections and " if self.dashboard else ""
        return f"with room for {dashboard}{self.files} more files"


def descriptor_shares(
    modbus_wanted: int = 0, dashboard_wanted: int = 0, own_to_come: int = 0
) -> DescriptorShares:
    """The connections each server may hold without the process running out of descriptors.

    The server's own descriptors come first: those open now and ``own_to_come``, those it
    opens after this (listeners, a pty, the fault journal; counted before, not as they
    opened: shares made with the few open at the first listener overcommitted a small
    limit, and a client of a dashboard holding 1 of its 4 connections waited for a
    descriptor for ever, a re-probe). Of the rest, where everything wanted fits, each gets
    it and the files :data:`RESERVED_DESCRIPTORS`; else the files keep :data:`FILES_MIN`
    and the dashboard :data:`DASHBOARD_MIN` (within a sixteenth and a quarter of what is
    free; nothing without a dashboard: a share kept for a dashboard not running cost a
    server without ``--http`` 169 of its 900 clients, a re-probe; the dashboard at least
    :data:`DASHBOARD_LEAST`), Modbus the rest; at least one each wanted. The soft
    open-file limit is raised first where what is wanted needs it
    (:func:`open_file_limit`)."""
    own = open_descriptors() + own_to_come
    needed = own + RESERVED_DESCRIPTORS + dashboard_wanted + modbus_wanted
    was, limit = open_file_limit(needed)
    spare = max(limit - own, 0)
    # where not everything fits, the files and the dashboard keep a few each (at most a
    # sixteenth and a quarter of what is free), Modbus the rest: a quarter kept for a
    # dashboard nobody used cost 275 of 1000 clients a limit of 1024 held before, and
    # descriptors short at a connection are met by closing the oldest unused (a re-probe)
    files_floor = min(FILES_MIN, max(spare // FILES_SHARE, 1))
    files = min(RESERVED_DESCRIPTORS, max(spare - dashboard_wanted - modbus_wanted, files_floor))
    dashboard_floor = min(DASHBOARD_MIN, max(spare // DASHBOARD_SHARE, DASHBOARD_LEAST))
    dashboard = min(dashboard_wanted, max(spare - files - modbus_wanted, dashboard_floor))
    modbus = max(spare - files - dashboard, 1)
    return DescriptorShares(was, limit, own, files, modbus, dashboard)


# ---------------------------------------------------------------------- listening
class Listener:
    """Listening sockets that accept for themselves (see the module docstring); what
    ``asyncio.Server`` gives its users: :attr:`sockets`, :meth:`close`,
    :meth:`wait_closed`, :meth:`serve_forever`.

    Args:
        sockets: bound, listening, non-blocking sockets.
        protocol_factory: a new connection's protocol.
        places: the places free below the server's connection limit: connections accepted
            a turn at most (at least one: at its limit the server closes one for the next).
            A connection counts once its protocol has it, on the loop's next turn: a burst
            accepted whole (asyncio's 100 a turn) overran the limit's descriptors.
        make_room: called when the process has no descriptor for the next connection:
            closes a connection (True) or finds none to close (False). Its argument says
            whether this is the shortage's first try (False: the last try found none to
            close and no connection came since): tries are not connections (a re-probe:
            25 tries in 20 s were logged as 25 connections closed, none was).
    """

    def __init__(
        self,
        sockets: list[socket.socket],
        protocol_factory: Callable[[], asyncio.BaseProtocol],
        places: Callable[[], int],
        make_room: Callable[[bool], bool],
    ) -> None:
        self.sockets = sockets
        self._factory = protocol_factory
        self._places = places
        self._make_room = make_room
        self._loop = asyncio.get_running_loop()
        self._closed: asyncio.Future[None] = self._loop.create_future()
        self._retry: asyncio.TimerHandle | None = None
        self._retry_s = RETRY_MIN_S  # the next wait when nothing could be closed
        self._stalled = False  # out of descriptors, nothing closed, nothing accepted since
        self._connecting: set[asyncio.Task] = set()  # strong references
        self._accepting(True)

    def _accepting(self, on: bool) -> None:
        for sock in self.sockets:
            if on:
                self._loop.add_reader(sock.fileno(), self._accept, sock)
            else:
                self._loop.remove_reader(sock.fileno())

    def _accept(self, sock: socket.socket) -> None:
        """Accept the connections waiting on ``sock``, as many as there are places (at least
        one, at most :data:`BACKLOG`) this turn."""
        for _ in range(min(max(self._places(), 1), BACKLOG)):
            try:
                conn, _ = sock.accept()
            except (BlockingIOError, InterruptedError):
                return
            except OSError as exc:
                if exc.errno in OUT_OF_DESCRIPTORS:
                    self._out_of_descriptors()
                    return
                # a client gone before its accept (ECONNABORTED), a firewall's EPERM: that
                # connection alone
                log.debug("accept on %s failed: %s", sock.getsockname(), exc)
                continue
            conn.setblocking(False)
            self._retry_s, self._stalled = RETRY_MIN_S, False
            task = self._loop.create_task(self._connect(conn))
            self._connecting.add(task)
            task.add_done_callback(self._connecting.discard)

    async def _connect(self, conn: socket.socket) -> None:
        try:
            await self._loop.connect_accepted_socket(self._factory, conn)
        except (OSError, RuntimeError) as exc:  # that connection failed as it was set up
            log.debug("a new connection failed: %s", exc)
            conn.close()

    def _out_of_descriptors(self) -> None:
        """Stop accepting, ask for room, and try again once it is free (or later). With
        connections of this turn not yet handed to the server, first wait for them: the
        server chooses the one to close among those too."""
        self._accepting(False)
        if self._connecting or self._make_room(not self._stalled):
            delay_s, self._retry_s, self._stalled = RETRY_MIN_S, RETRY_MIN_S, False
        else:
            delay_s, self._retry_s = self._retry_s, min(2 * self._retry_s, RETRY_MAX_S)
            self._stalled = True
        self._retry = self._loop.call_later(delay_s, self._resume)

    def _resume(self) -> None:
        self._retry = None
        if not self._closed.done():
            self._accepting(True)

    def close(self) -> None:
        """Stop listening (the connections made stay open)."""
        if self._closed.done():
            return
        if self._retry is not None:
            self._retry.cancel()
        else:
            self._accepting(False)
        for sock in self.sockets:
            sock.close()
        self._closed.set_result(None)

    async def wait_closed(self) -> None:
        await asyncio.shield(self._closed)

    async def serve_forever(self) -> None:
        """Wait until :meth:`close`."""
        await self.wait_closed()


async def listen(
    host: str | None,
    port: int,
    protocol_factory: Callable[[], asyncio.BaseProtocol],
    places: Callable[[], int],
    make_room: Callable[[bool], bool],
) -> Listener:
    """A :class:`Listener` on every address ``host`` names (None or "": all), as
    ``loop.create_server`` binds them (SO_REUSEADDR; an IPv6 socket IPv6 only); an address
    that cannot be bound is the OSError asyncio raises ("error while attempting to bind on
    address ..."); ``places`` and ``make_room`` as :class:`Listener` takes them."""
    loop = asyncio.get_running_loop()
    infos = await loop.getaddrinfo(
        host or None,
        port,
        family=socket.AF_UNSPEC,
        type=socket.SOCK_STREAM,
        flags=socket.AI_PASSIVE,
    )
    sockets: list[socket.socket] = []
    try:
        for family, kind, proto, _, address in dict.fromkeys(infos):
            sock = socket.socket(family, kind, proto)
            sockets.append(sock)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            if family == socket.AF_INET6 and hasattr(socket, "IPPROTO_IPV6"):
                sock.setsockopt(socket.IPPROTO_IPV6, socket.IPV6_V6ONLY, 1)
            try:
                sock.bind(address)
            except OSError as err:
                raise OSError(
                    err.errno,
                    f"error while attempting to bind on address {address!r}: "
                    f"{(err.strerror or str(err)).lower()}",
                ) from None
            sock.listen(BACKLOG)
            sock.setblocking(False)
    except BaseException:
        for sock in sockets:
            sock.close()
        raise
    return Listener(sockets, protocol_factory, places, make_room)


# ---------------------------------------------------------------------- logging
@dataclass
class EventLog:
    """Log lines of one kind of event, at most ``burst`` an interval: the rest are counted
    and said in one line when the interval ends (a timer: a burst's count is said even if
    no event of the kind follows). A client reconnecting for every read at 10/s wrote a
    line per connect and disconnect, 140 MB a day (a stranger's probe).

    Args:
        what: the events as the count names them ("client connections").
        burst: lines logged an interval.
        interval_s: the interval [s].
        level: the lines' logging level.
        logger: where they go.
    """

    what: str
    burst: int
    interval_s: float
    level: int = logging.INFO
    logger: logging.Logger = log
    _since_s: float = field(default=-math.inf, init=False)
    _logged: int = field(default=0, init=False)
    _unlogged: int = field(default=0, init=False)

    def __call__(self, message: str, *args: object) -> None:
        """Log ``message % args``, or count it if the interval's lines are spent."""
        now = time.monotonic()
        if now - self._since_s >= self.interval_s:
            self.flush()
            self._since_s, self._logged = now, 0
        if self._logged < self.burst:
            self._logged += 1
            self.logger.log(self.level, message, *args)
            return
        if not self._unlogged:  # said when the interval ends (no loop: with the next line)
            with contextlib.suppress(RuntimeError):
                asyncio.get_running_loop().call_later(
                    self._since_s + self.interval_s - now, self.flush
                )
        self._unlogged += 1

    def flush(self) -> None:
        """Say the count of the events not logged, if any (the interval's end; a stop)."""
        if self._unlogged:
            logged = (
                f"one each {self.interval_s:g} s is"
                if self.burst == 1
                else f"the first {self.burst} of each {self.interval_s:g} s are"
            )
            self.logger.log(
                self.level, "%d more %s not logged (%s)", self._unlogged, self.what, logged
            )
            self._unlogged = 0
