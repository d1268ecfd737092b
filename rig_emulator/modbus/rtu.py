"""Modbus RTU on a serial line (a device, or a pseudo-terminal the emulator creates).

The same units and map as TCP: every request goes through
:meth:`~rig_emulator.modbus.handler.BenchModbusServer.execute` (gates included) with
``peer`` the line's path and no role. The line behaves as a real one would
(:mod:`rig_emulator.modbus.rtu_wire`):

- a frame ends with 3.5 characters of silence; bytes that come before that belong to it;
- a frame with a bad CRC, a unit no instrument on the line has, and a broadcast (unit 0)
  get no reply; a broadcast write is carried out by every instrument unit of the map (not
  by the emulator's own units, the simulation control and the truth: a master's broadcast
  of a setpoint must not reset or advance the simulation);
- a pause longer than 1.5 characters inside a frame is not detected: the bytes' arrival is
  seen by a thread that may wait for the interpreter several milliseconds, longer than the
  1.5 to 3.5 characters that would tell a broken frame at common speeds, and a frame
  discarded for a pause the client never made is worse than a stutter let through;
- a pty (``pty``, or a path that is one, e.g. a socat pair) has no line speed, so the
  emulator keeps the time the wire would take (on a device the UART takes the reply's time
  itself and the emulator only keeps the rest): a frame
  occupies the line for its characters at the baud rate from its first byte, it is taken
  as ended only after the silence that follows, the reply is handed over when its last
  character would have arrived, and the next request starts on the line no earlier than a
  silence after that. A transaction thus takes at least request + silence + reply +
  silence, as on a line;
- bytes cannot come faster than the baud rate on a line, but a pty takes them as fast as a
  writer gives them: 64 KiB written at once held the line for its 38 s of wire time at
  19,200 baud, and 20 MB for 50 hours at 1,200 (a stranger's probe). The line owes at most
  :data:`OWED_CHARACTERS` characters of line time ahead of the present (more than a frame
  is long, so only noise reaches the bound); bytes beyond it are discarded with a log line
  (at most one a minute; the bytes discarded after it are counted and said when its minute
  ends, or at the stop: a 64 KiB burst's log said its first 3838 bytes, and the rest only
  with another burst, a stranger's probe). A burst that stops leaves the line silent and
  answering again at most that many characters and a t3.5 later (0.15 s at 19,200 baud,
  2.4 s at 1,200);
- a unit under a ``delay`` fault answers that much after its reply would have come, unless
  the master speaks again first (it timed out): then the unit keeps its reply, which would
  collide with the master's request on a line, and the new request is answered. A delay
  fault that ends meanwhile (cleared, its ``for_s`` elapsed, a reset) lets the reply go
  at once, as on TCP (:class:`~rig_emulator.faults.engine.DelayHold`);
- a line can go away: a socat peer that ends hangs up its pty, an unplugged USB-RS485
  adapter's device reports EIO. The line then read end-of-file for ever, and the thread
  read it in a loop (half a core, no log line, RTU dead while TCP answered: a stranger's
  probe). It says so in one line, closes the line and opens its path again, backing off
  (:data:`REOPEN_FIRST_S` to :data:`REOPEN_MAX_S`), until a line is there again (a new pty
  or device at that path), saying so in one line. The emulator's own pty (``pty``) never
  goes away: the server holds both its sides.

The line is served by one thread with blocking I/O and ``select`` timeouts (microseconds,
where the event loop's timers are good to about a millisecond); the requests run in the
server's event loop. A read whose frame is complete (CRC valid) is started at once, while
its silence passes, and its answer dropped if more bytes follow (the faults take back the
request they counted: :meth:`~rig_emulator.faults.engine.Tally.withdraw`); writes run only
once their frame has ended.
"""

from __future__ import annotations

import array
import asyncio
import contextlib
import errno
import fcntl
import logging
import os
import select
import stat
import termios
import threading
import time
import tty
from concurrent.futures import Future
from typing import Any

from rig_emulator.faults.engine import DelayHold, Tally, holding, tallying
from rig_emulator.modbus.handler import BenchModbusServer, RequestInfo
from rig_emulator.modbus.pty_masters import PtyMasters
from rig_emulator.modbus.rtu_wire import (
    BROADCAST_UNIT,
    PARITIES,
    character_s,
    frame,
    silence_s,
    unframe,
)

log = logging.getLogger("rig_emulator.serve")

WRITE_FUNCTIONS = frozenset({5, 6, 15, 16, 22, 23})
READ_AHEAD_FUNCTIONS = frozenset({1, 2, 3, 4})
MAX_FRAME_BYTES = 256  # the longest RTU frame (section 2.5.1.1); longer runs are noise
#: the line time the line may owe ahead of the present [characters]: one more than the
#: longest frame, so a frame is never cut, while a burst faster than the baud rate cannot
#: hold the line for its whole wire time
OWED_CHARACTERS = MAX_FRAME_BYTES + 1
DISCARD_LOG_INTERVAL_S = 60.0  # bytes discarded for coming too fast: a log line at most
#: a line that went away is looked for at its path again this long after [s], the wait
#: doubling on each try that finds none, up to REOPEN_MAX_S: an adapter plugged back in
#: is served within two seconds, and a path that stays empty costs a try every two
REOPEN_FIRST_S = 0.1
REOPEN_MAX_S = 2.0
#: A reply still unread this long after it came is nobody's, dropped from a pty's client
#: side [s]: a master waiting for it reads it within milliseconds (a client on a loaded
#: CI machine was held up 0.12 s at most, measured); one held up longer loses it, as it
#: would on a line it did not listen to
UNREAD_REPLY_S = 1.0
#: the last master left the pty: its queue is emptied then and this much later, when a
#: reply the server wrote as it left has reached it [s]
NOBODY_RECHECK_S = 0.05
EXECUTE_TIMEOUT_S = 30.0
_BAUD_CONSTANTS = {
    int(name[1:]): getattr(termios, name)
    for name in dir(termios)
    if name.startswith("B") and name[1:].isdigit()
}
_BAUD_OF = {constant: baud for baud, constant in _BAUD_CONSTANTS.items()}


class SerialConfigError(ValueError):
    """A serial line that cannot be opened or configured (the message names it)."""


def check_line_options(baud: int, parity: str) -> None:
    """SerialConfigError unless ``baud`` is a speed termios knows and ``parity`` E, N or O."""
    if parity not in PARITIES:
        raise SerialConfigError(f"--parity: '{parity}' is not one of {', '.join(PARITIES)}")
    if baud not in _BAUD_CONSTANTS:
        known = ", ".join(str(b) for b in sorted(_BAUD_CONSTANTS) if b >= 1200)
        raise SerialConfigError(f"--baud: {baud} is not a serial line speed ({known})")


def open_line(
    path: str, baud: int, parity: str, *, warn: bool = True
) -> tuple[int, int | None, str, bool]:
    """(fd the server uses, fd to keep open or None, path clients use, whether the line took
    ``baud`` and ``parity``) of ``path`` or, for ``pty``, of a new pseudo-terminal; raw
    mode, 8 data bits, ``baud``, ``parity``. ``warn``: log a line that refused them (a
    line opened again says so in its own line)."""
    check_line_options(baud, parity)
    if path == "pty":
        server_fd, client_fd = os.openpty()
        # the server keeps the client side open too, so reads never fail with EIO while
        # no client has it open; clients configure it as they like
        applied = _configure(client_fd, baud, parity)
        tty.setraw(server_fd)
        return server_fd, client_fd, os.ttyname(client_fd), applied
    if is_pty_multiplexer(path):  # before opening: that would make a pty of its own
        raise SerialConfigError(f"--serial {path}: {PTY_MULTIPLEXER}; use --serial pty")
    try:
        # non-blocking: a device without carrier (no CLOCAL yet) would hold the open, and
        # a line opened again must not keep the serving thread from its stop
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        raise SerialConfigError(f"--serial {path}: {exc.strerror}") from None
    try:
        configured = _configure(fd, baud, parity)
    except termios.error:
        os.close(fd)
        raise SerialConfigError(
            f"--serial {path}: is not a terminal (a serial line or pty)"
        ) from None
    os.set_blocking(fd, True)
    if not configured and warn:
        log.warning("RTU %s: the line refused %d baud, parity %s; served raw", path, baud, parity)
    return fd, None, path, configured


#: why a line on ``/dev/ptmx`` is refused, by the server (``--serial``) and the client
#: (``hil-client --rig modbus-rtu:///dev/ptmx``) alike
PTY_MULTIPLEXER = (
    "the pseudo-terminal multiplexer opens a new pty whose other side no client can reach"
)


def is_pty_multiplexer(line: int | str) -> bool:
    """Whether ``line`` (a path, links followed, or an open fd) is Linux's ``/dev/ptmx`` (or
    ``/dev/pts/ptmx``, another node of it: device 5, 2): opening it makes a new pty master
    whose slave nobody unlocked, so a line served there answers no client (it was served
    without a word), and a client opening it waits for a reply nobody sends (it said "no
    reply within 5 s"; stranger's probes). False for a path that does not exist."""
    try:
        rdev = os.stat(line).st_rdev
    except OSError:
        return False
    return (os.major(rdev), os.minor(rdev)) == (5, 2)


def is_pty(fd: int) -> bool:
    """Whether ``fd`` is a pseudo-terminal's slave (Linux: Unix98 ptys, majors 136-143)."""
    try:
        return os.major(os.fstat(fd).st_rdev) in range(136, 144)
    except OSError:
        return False


def hung_up(fd: int) -> bool:
    """Whether the line on ``fd`` is hung up or in error (its reads end at once: a pty whose
    other side closed, a device unplugged)."""
    poller = select.poll()
    poller.register(fd, select.POLLIN)
    return any(events & (select.POLLHUP | select.POLLERR) for _, events in poller.poll(0))


def _configure(fd: int, baud: int, parity: str) -> bool:
    """Raw mode, 8 data bits, ``baud`` and ``parity``; False if the line did not take the
    speed and parity (a pty has no line, and Linux drops parity on one): raw mode only."""
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    cflag = attrs[2] & ~(termios.PARENB | termios.PARODD | termios.CSTOPB | termios.CSIZE)
    cflag |= termios.CS8 | termios.CREAD | termios.CLOCAL
    if parity != "N":
        cflag |= termios.PARENB | (termios.PARODD if parity == "O" else 0)
    else:
        cflag |= termios.CSTOPB  # no parity: two stop bits keep the 11-bit character
    attrs[2] = cflag
    attrs[4] = attrs[5] = _BAUD_CONSTANTS[baud]
    try:
        termios.tcsetattr(fd, termios.TCSANOW, attrs)
    except termios.error:
        return False
    # tcsetattr succeeds when any of the changes was made (POSIX): Linux keeps a pty's
    # speed and drops its parity bits without an error, so what it holds is read back
    held = termios.tcgetattr(fd)
    mask = termios.PARENB | termios.PARODD | termios.CSTOPB
    return (held[2] & mask) == (cflag & mask) and held[4] == attrs[4] and held[5] == attrs[5]


def _link_of(path: str) -> tuple[int, int] | None:
    """A symbolic link's identity (its inode and change time), None where ``path`` is no
    link (or nothing)."""
    try:
        status = os.lstat(path)
    except OSError:
        return None
    return (status.st_ino, status.st_ctime_ns) if stat.S_ISLNK(status.st_mode) else None


def _abandon(answer: Future) -> None:
    """A read answered ahead whose frame went on (more bytes came): it was no request, so
    once answered, the faults that counted it take their counts back and the delay faults
    that held it forget it (:meth:`RtuLine._answer`; three reads each followed by a byte
    whose frame had a bad CRC were journalled as three requests, none answered: a
    re-probe)."""

    def withdraw(done: Future) -> None:
        if not done.cancelled() and done.exception() is None:
            done.result()[3].withdraw()

    answer.add_done_callback(withdraw)


class RtuLine:
    """Serves the units of ``server`` on a serial line (see the module docstring).

    Args:
        server: the Modbus server whose ``execute`` answers the requests.
        path: a device path, or ``pty`` for a new pseudo-terminal (see :attr:`path`).
        baud: line speed [bit/s].
        parity: ``E``, ``N`` or ``O``.
    """

    def __init__(
        self, server: BenchModbusServer, path: str = "pty", baud: int = 19200, parity: str = "E"
    ) -> None:
        self.server = server
        self.baud = baud
        self._speeds_said: set[int] = set()  # other speeds masters set, said once each
        self.parity = parity
        self.character_s = character_s(baud)
        self.silence_s = silence_s(baud)
        self._fd: int | None
        self._fd, self._keep_fd, self.path, applied = open_line(path, baud, parity)
        #: who has the emulator's pty open (None: a device, or no inotify): no reply is
        #: written to nobody, and none queued is left to the next master
        self._masters = (
            PtyMasters.watch(self.path, frozenset({self._keep_fd}))
            if self._keep_fd is not None
            else None
        )
        #: nobody has the pty open: what a reply still on its way to the client side
        #: leaves there is dropped then too (:data:`NOBODY_RECHECK_S`)
        self._nobody_check_at: float | None = None
        #: keep the reply's on-wire time (a pty); a device's UART takes it itself
        self.paced = path == "pty" or is_pty(self._fd)
        #: the line's settings in words for the start-up log: a pty carries bytes, not
        #: characters, and Linux drops parity on one
        self.settings = f"{baud} baud, parity {parity}"
        if not applied:
            why = "a pty has no line" if self.paced else "see the warning above"
            self.settings += (
                f" in the timing only: the line did not take its settings ({why}), so no parity"
                " bit is checked"
            )
        self.crc_errors = 0
        self.transactions = 0
        #: bytes discarded because they came faster than the line carries them
        self.discarded = 0
        self._discards_unlogged = 0
        self._discard_logged_at = -float("inf")
        #: how long a line that goes away is waited for before its path is tried again:
        #: back to REOPEN_FIRST_S once the line carries bytes, so one that comes and goes
        #: without a byte is tried ever less often
        self._reopen_wait_s = REOPEN_FIRST_S
        self._unread_check_at: float | None = None  # when replies unread are dropped
        self._stop_r, self._stop_w = os.pipe()
        #: a byte here: a delay fault holding the reply waited for ended (:meth:`_wake`)
        self._wake_r, self._wake_w = os.pipe()
        os.set_blocking(self._wake_r, False)
        os.set_blocking(self._wake_w, False)
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    async def start(self) -> None:
        """Serve the line from a thread; the requests run in the running event loop."""
        self._loop = asyncio.get_running_loop()
        self._thread = threading.Thread(target=self._serve, name=f"rtu {self.path}", daemon=True)
        self._thread.start()

    async def stop(self) -> None:
        os.write(self._stop_w, b"x")
        if self._thread is not None:
            await asyncio.to_thread(self._thread.join, 5.0)
        self._log_discards_left()
        if self._masters is not None:
            self._masters.close()
        for fd in (self._fd, self._keep_fd, self._stop_r, self._stop_w, self._wake_r, self._wake_w):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)

    # ------------------------------------------------------------------ the line
    def _serve(self) -> None:
        buffer = bytearray()  # the frame so far (at most MAX_FRAME_BYTES + 1 kept)
        received = 0  # its characters on the line, kept or not
        frame_start = 0.0  # when the frame's first character went on the line
        line_free = 0.0  # the end of the silence after the last frame on the line
        deadline = 0.0  # when the silence after the bytes received so far is complete
        early: tuple[int, Future] | None = None  # a read answered ahead: (length, answer)
        frame_arrivals = 0  # the pty's arrivals as the frame began (see below)
        while True:
            timeout = max(deadline - time.monotonic(), 0.0) if received else None
            for check_at in (self._unread_check_at, self._nobody_check_at):
                if check_at is not None:  # replies nobody read: dropped then
                    check_in = max(check_at - time.monotonic(), 0.0)
                    timeout = check_in if timeout is None else min(timeout, check_in)
            if self._discards_unlogged:  # their count is said when the minute ends
                said_at = self._discard_logged_at + DISCARD_LOG_INTERVAL_S
                said_in = max(said_at - time.monotonic(), 0.0)
                timeout = said_in if timeout is None else min(timeout, said_in)
            # the pty's opens and closes are taken between frames (before a request, and
            # at its reply), not while one comes in: counting them reads /proc, and bytes
            # that came meanwhile from the next master were taken into the frame (a
            # re-probe)
            masters = self._masters if not received else None
            watched = [self._fd, self._stop_r] + ([masters] if masters is not None else [])
            ready, _, _ = select.select(watched, [], [], timeout)
            # the bytes ready now came by now: their time on the line is not the time the
            # pty's count took (a /proc count of some ms put a master's request that late,
            # and the next master's frame, sent within the line's silence after it as it
            # really was, was read as part of it: both unanswered, a re-probe)
            came_by = time.monotonic()
            if self._stop_r in ready:
                return
            if masters is not None and masters in ready:  # (before its request)
                self._masters_changed()
            now = time.monotonic()
            if now - self._discard_logged_at >= DISCARD_LOG_INTERVAL_S:
                self._log_discards_left()
            if self._unread_check_at is not None and now >= self._unread_check_at:
                self._unread_check_at = None
                self._drop_unread_replies()
            if self._nobody_check_at is not None and now >= self._nobody_check_at:
                self._nobody_check_at = None
                if self._masters is not None and not self._masters.openers:
                    self._drop_unread_replies()
            if self._fd in ready:
                try:
                    data = os.read(self._fd, 4096)
                    gone = "" if data else "hang-up"  # a terminal's end-of-file
                except OSError as exc:  # EIO: a device unplugged
                    data, gone = b"", f"{errno.errorcode.get(exc.errno, exc.errno)}: {exc.strerror}"
                if gone:
                    if early is not None:
                        _abandon(early[1])
                    buffer, received, early = bytearray(), 0, None
                    if not self._line_back(gone):
                        return
                    continue
                self._reopen_wait_s = REOPEN_FIRST_S
                if not received:
                    frame_start = max(came_by, line_free)
                    # the masters there as the frame began: one that comes while it is read
                    # (the last one leaving as it asked) is not its master (a re-probe: a
                    # newcomer 0-3 ms after the request read the reply)
                    frame_arrivals = self._masters.arrivals if self._masters is not None else 0
                carried = self._carried(
                    len(data), frame_start + received * self.character_s, max(came_by, line_free)
                )
                if carried < len(data):
                    self._discard(len(data) - carried, now)
                received += carried
                if len(buffer) <= MAX_FRAME_BYTES:  # beyond: noise until the next silence
                    buffer += data[: MAX_FRAME_BYTES + 1 - len(buffer)]
                wire_end = frame_start + received * self.character_s
                deadline = max(wire_end, came_by) + self.silence_s
                if early is not None:  # more bytes: that frame was not the request
                    _abandon(early[1])
                early = self._read_ahead(bytes(buffer)) if received <= MAX_FRAME_BYTES else None
                continue
            if received and now >= deadline:
                request, buffer, received = bytes(buffer), bytearray(), 0
                answer = early[1] if early is not None and early[0] == len(request) else None
                if early is not None and answer is None:
                    _abandon(early[1])
                early = None
                line_free = self._transaction(request, deadline, answer, frame_arrivals)

    def _line_back(self, why: str) -> bool:
        """The line went away (``why``): say so, close it and open its path again, the wait
        between tries growing (:attr:`_reopen_wait_s`), until a line that is not hung up is
        there (a new pty or device), and say so; False if the line is stopped meanwhile.
        The emulator's own pty is not opened again (its path would change): it is read
        again once it no longer reads as hung up."""
        self._log_discards_left()  # the noise the line carried before it went
        log.warning(
            "RTU %s: the line went away (%s); served again once a line is back at that path",
            self.path,
            why,
        )
        own = self._keep_fd is not None
        if not own and self._fd is not None:
            with contextlib.suppress(OSError):
                os.close(self._fd)
            self._fd = None
        # a link that named the line that went away names no line: a pty given the same
        # number later is another program's (a test's server, its socat pair gone, opened
        # the next test's pty under the old link and took its bytes); a line comes back as
        # a new link (socat started again) or a device at a plain path
        stale = _link_of(self.path)
        while not select.select([self._stop_r], [], [], self._reopen_wait_s)[0]:
            self._reopen_wait_s = min(2.0 * self._reopen_wait_s, REOPEN_MAX_S)
            if own:
                if self._fd is not None and not hung_up(self._fd):
                    log.info("RTU %s: the line is back, served again", self.path)
                    return True
                continue
            if stale is not None and _link_of(self.path) == stale:
                continue
            try:
                fd, _, _, applied = open_line(self.path, self.baud, self.parity, warn=False)
            except SerialConfigError:
                continue  # nothing there yet (or not a terminal): try again later
            if hung_up(fd):
                os.close(fd)
                continue
            self._fd = fd
            self.paced = is_pty(fd)
            refused = (
                ""
                if applied or self.paced
                else f"; it refused {self.baud} baud, parity {self.parity}: served raw"
            )
            log.info(
                "RTU %s: the line is back (%s), served again%s",
                self.path,
                os.path.realpath(self.path),
                refused,
            )
            return True
        return False

    def _carried(self, count: int, wire_end: float, present: float) -> int:
        """How many of ``count`` bytes, arriving when the line's characters so far end at
        ``wire_end``, the line carries without owing more than :data:`OWED_CHARACTERS` of
        line time beyond ``present`` (now, or the end of the silence after a reply)."""
        room = (present + OWED_CHARACTERS * self.character_s - wire_end) / self.character_s
        return max(0, min(count, int(room)))

    def _discard(self, count: int, now: float) -> None:
        """Count ``count`` bytes discarded for coming too fast; a log line at most every
        :data:`DISCARD_LOG_INTERVAL_S`, saying how many."""
        self.discarded += count
        self._discards_unlogged += count
        if now - self._discard_logged_at < DISCARD_LOG_INTERVAL_S:
            return
        log.warning(
            "RTU %s: bytes come faster than %d baud carries them; those beyond %d characters "
            "of line time (%.2f s) are discarded as noise (%d bytes since the last such line; "
            "one a minute at most)",
            self.path,
            self.baud,
            OWED_CHARACTERS,
            OWED_CHARACTERS * self.character_s,
            self._discards_unlogged,
        )
        self._discards_unlogged = 0
        self._discard_logged_at = now

    def _log_discards_left(self) -> None:
        """Say the bytes discarded since the last line that did, if any (when its minute
        ends, the line goes away, the line stops): the rest of a 64 KiB burst was said only
        in the line of the next burst, a minute later or never (a stranger's probe)."""
        if self._discards_unlogged:
            log.warning(
                "RTU %s: %d more bytes discarded as noise since the last such line",
                self.path,
                self._discards_unlogged,
            )
            self._discards_unlogged = 0

    def _read_ahead(self, request: bytes) -> tuple[int, Future] | None:
        """Start answering ``request`` before its silence has passed if it is already a whole
        read frame (CRC valid): reads change nothing, so an answer that more bytes turn out
        to belong to is simply dropped; the reply still waits for the line's time. Writes
        are carried out only once their frame has ended, as a device does."""
        decoded = unframe(request)
        if decoded is None or not decoded[1] or decoded[1][0] not in READ_AHEAD_FUNCTIONS:
            return None
        unit_id, pdu = decoded
        if unit_id not in self.server.units or self._loop is None:
            return None
        info = RequestInfo.of(unit_id, pdu, self.path, None)
        return len(request), asyncio.run_coroutine_threadsafe(self._answer(info, pdu), self._loop)

    async def _answer(
        self, info: RequestInfo, pdu: bytes
    ) -> tuple[float, bytes | None, list[DelayHold], Tally]:
        """The server's answer to ``pdu`` (a delay fault's delay, the reply), the holds of
        the delay faults that asked the delay (the line waits no longer than they last) and
        the faults that counted the request (taken back if it was none: :func:`_abandon`)."""
        with holding() as holds, tallying() as tally:
            delay_s, reply = await self.server.answer(info, pdu)
        for hold in holds:
            hold.on_change = self._wake
        return delay_s, reply, holds, tally

    def _wake(self) -> None:
        """A delay fault holding the awaited reply ended (from any thread): look again."""
        with contextlib.suppress(OSError):  # (full: a wake is pending; closed: stopped)
            os.write(self._wake_w, b"w")

    def _transaction(
        self, request: bytes, ended: float, answer: Future | None = None, arrivals: int = 0
    ) -> float:
        """Answer one frame that ended (silence included) at ``ended`` (``answer``: its reply,
        already under way; ``arrivals``: :attr:`PtyMasters.arrivals` as it began); when the
        line is free again."""
        if len(request) > MAX_FRAME_BYTES or self._at_another_speed():
            self.crc_errors += 1
            if answer is not None:
                _abandon(answer)
            return ended
        decoded = unframe(request)
        if decoded is None:
            self.crc_errors += 1
            log.debug("RTU %s: frame with a bad CRC ignored (%s)", self.path, request[:16].hex())
            return ended
        unit_id, pdu = decoded
        if not pdu:
            return ended
        if unit_id == BROADCAST_UNIT:
            if pdu[0] in WRITE_FUNCTIONS:
                self._run(self._broadcast(pdu))
            return ended
        if unit_id not in self.server.units:
            return ended  # nobody on the line has that address: silence, as on a line
        if answer is None:
            info = RequestInfo.of(unit_id, pdu, self.path, None)
            answer = asyncio.run_coroutine_threadsafe(self._answer(info, pdu), self._loop)
        delay_s, reply, holds, _ = self._result(answer) or (0.0, None, [], None)
        try:
            if reply is None:
                return ended
            if delay_s > 0:
                delay_s = self._held(ended, delay_s, holds)
                if delay_s is None:
                    # the master spoke again before the late reply (it timed out): the reply
                    # would collide with its request on a line, so the unit keeps it
                    log.debug(
                        "RTU %s: unit %d's late reply dropped, the master spoke", self.path, unit_id
                    )
                    return ended
            return self._reply(unit_id, reply, ended, delay_s, arrivals)
        finally:
            for hold in holds:
                hold.close()

    def _at_another_speed(self) -> bool:
        """Whether a master set the pty to another speed than the line's: the client side's
        settings are one for all its openers, so what a master set is read there (the line
        set its own at the start). On a line its frames would come garbled, so none is
        answered (a stranger's probe: hil-client at ?baud=9600, and mbpoll -b 9600, read a
        19,200-baud line for rows on end, where the bench would have answered nothing).
        Said once per speed. A Linux pty keeps no parity, so parity is not compared."""
        if self._keep_fd is None:
            return False
        try:
            speed = termios.tcgetattr(self._keep_fd)[4]
        except termios.error:
            return False
        if speed == _BAUD_CONSTANTS[self.baud]:
            return False
        if speed not in self._speeds_said:
            self._speeds_said.add(speed)
            baud = _BAUD_OF.get(speed, f"an unknown rate (termios {speed})")
            log.warning(
                "RTU %s: a master set the line to %s baud; it runs at %d baud, so its frames "
                "come garbled, as on a line, and get no reply (give the master %d baud, or "
                "serve --baud %s)",
                self.path,
                baud,
                self.baud,
                self.baud,
                baud,
            )
        return True

    def _held(self, ended: float, delay_s: float, holds: list[DelayHold]) -> float | None:
        """Wait out a delay fault's ``delay_s`` after the request ``ended``, no longer than
        its faults (``holds``) last: a stranger's probe cleared a 6-s delay a second into a
        request and its RTU reply still came after 6 s (TCP's came at the clear). The delay
        waited [s]; None if the line stopped or the master spoke meanwhile."""
        while True:
            waited_s = min(delay_s, max((h.delay_s for h in holds), default=delay_s))
            left = max(ended + waited_s - time.monotonic(), 0.0)
            ready = select.select([self._stop_r, self._fd, self._wake_r], [], [], left)[0]
            if self._stop_r in ready or self._fd in ready:
                return None
            if self._wake_r in ready:
                with contextlib.suppress(BlockingIOError):
                    os.read(self._wake_r, 64)
                continue
            if time.monotonic() >= ended + waited_s:
                return waited_s

    def _reply(
        self, unit_id: int, reply: bytes, ended: float, delay_s: float, arrivals: int = 0
    ) -> float:
        """Put ``reply`` on the line ``delay_s`` after the request ``ended``; when the line
        is free again. On a pty, not where nobody has it open, nor where a master came to it
        since the request (``arrivals``: :attr:`PtyMasters.arrivals` then): the master that
        asked left, and the reply, written into the newcomer's emptied queue, was read by it
        as its own (a re-probe: mbpoll printed the register's old value, exit 0, in 5 of 20
        runs)."""
        out = frame(unit_id, reply)
        wire_s = len(out) * self.character_s
        if self.paced:
            # the reply goes on the line after the request's silence (and a delay fault's
            # delay); the emulator's own work overlaps its on-wire time (a reply that took
            # longer is handed over when ready)
            reply_end = max(ended + delay_s + wire_s, time.monotonic())
            if not self._wait_until(reply_end):
                return reply_end  # the line is stopping: no reply
        else:  # a real line: its UART takes the reply's time itself
            if not self._wait_until(ended + delay_s):
                return ended
            reply_end = time.monotonic() + wire_s
        if self._masters is not None:
            self._masters_changed()
        if self._masters is not None and not self._masters.openers:
            # nobody has the pty open (the master timed out, was killed): on a line the
            # reply reaches nobody; on a pty it would wait for the next master
            log.debug(
                "RTU %s: unit %d's reply not written: nobody has the line", self.path, unit_id
            )
        elif self._masters is not None and self._masters.arrivals != arrivals:
            log.debug(
                "RTU %s: unit %d's reply not written: its master left, another came",
                self.path,
                unit_id,
            )
        else:
            try:
                os.write(self._fd, out)
            except OSError as exc:
                log.warning("RTU %s: reply not written (%s)", self.path, exc.strerror)
            if self._keep_fd is not None:  # (a pty: see :meth:`_drop_unread_replies`)
                self._unread_check_at = reply_end + UNREAD_REPLY_S
        self.transactions += 1
        return reply_end + self.silence_s

    def _masters_changed(self) -> None:
        """Take the pty's opens and closes (:class:`PtyMasters`): what is queued when a
        master comes to a pty nobody had open, or the last one leaves, is nobody's; a
        reply on its way to the client side as the last one left is dropped a moment
        later (:data:`NOBODY_RECHECK_S`: the queue read empty while it was)."""
        assert self._masters is not None
        came, left = self._masters.update()
        if came or left:
            self._drop_unread_replies()
        if left:
            self._nobody_check_at = time.monotonic() + NOBODY_RECHECK_S

    def _drop_unread_replies(self) -> None:
        """Empty the pty's client side of replies nobody read: a reply the master never
        read (it timed out, was killed) is gone from a real line, but on a pty it waited
        in the client side's queue, and the next master took it for its own answer (a
        stranger's probe: mbpoll read 700 where the register held 600, exit 0). Called
        when nobody has the pty open or a master comes to it (:meth:`_masters_changed`),
        and when a reply is still unread :data:`UNREAD_REPLY_S` after it came (a master
        waiting for it reads it within milliseconds; one that stays open after giving up
        left it)."""
        waiting = array.array("i", [0])
        with contextlib.suppress(OSError):
            fcntl.ioctl(self._keep_fd, termios.FIONREAD, waiting)
            if waiting[0]:
                termios.tcflush(self._keep_fd, termios.TCIFLUSH)
                log.debug("RTU %s: %d unread reply bytes dropped", self.path, waiting[0])

    def _wait_until(self, when: float) -> bool:
        """Wait until the monotonic clock reads ``when`` (to about 0.1 ms); False if the
        line is stopped meanwhile (a delay fault may hold a reply for minutes: the line's
        fd must not be written once :meth:`stop` has closed it)."""
        while True:
            left = max(when - time.monotonic(), 0.0)
            if select.select([self._stop_r], [], [], left)[0]:
                return False
            if time.monotonic() >= when:
                return True

    async def _broadcast(self, pdu: bytes) -> None:
        """Carry out a broadcast write on every instrument unit: one request, with no reply,
        so a delay fault does not count it and another fault counts it once (three
        broadcasts and a read were journalled as four requests of a delay on unit 1: a
        re-probe)."""
        with tallying(replies=False):
            for unit_id in sorted(self.server.units - self.server.own_units):
                await self.server.answer(RequestInfo.of(unit_id, pdu, self.path, None), pdu)

    def _run(self, coro) -> None:
        assert self._loop is not None
        self._result(asyncio.run_coroutine_threadsafe(coro, self._loop))

    def _result(self, future: Future) -> Any:
        try:
            return future.result(EXECUTE_TIMEOUT_S)
        except Exception as exc:  # the loop stopped, or the request failed: no reply
            future.cancel()
            log.warning("RTU %s: request not answered (%s)", self.path, exc or type(exc).__name__)
            return None
