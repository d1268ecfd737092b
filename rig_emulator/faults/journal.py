"""The fault journal: one JSON line per fault start and end (CONTRACT section 5).

Each line: ``event`` (``start`` | ``end``), ``id`` (the same for a fault's start and end),
``t_sim_s`` (simulated time of the event), ``t_wall`` (Unix time), ``kind``, ``unit`` or
``signal``, ``source`` (``file``, ``profile``, ``random``, ``python``, ``modbus``, ``dashboard``),
``parameter`` (the kind's own: ``delay_ms``, ``code``, ``rate_per_h`` or ``value``) and
``served``: what the server answered (``delay_ms``, ``reply: none``, ``exception_code``,
``connections_closed``) or the reading it published next to the instrument's own reading
without the fault and the plant's true value (``reading``, ``instrument``, ``truth``; a
dropout's reading is null; a start line adds ``asked`` where the fault asked for a reading
below what the instrument can show, its ``reading_min``, and the floor was served: on the
register's steps, as ``reading``). End
lines add ``requests`` (communication: how many requests got the fault's effect, each
counted by the faults whose effect it got, never by one another fault of the unit
overrode, nor by an exception-04 fault for a request the spec's checks refused first; a
request delay faults held, by the one whose delay it waited out: a delay that ended while
a shorter one still held the request passes it on; an RTU broadcast, which gets no reply,
by no delay fault and by another fault once, whatever the units it reaches; an RTU read
answered ahead whose frame went on, by none) and ``reason`` (``for_s elapsed``,
``cleared``, ``reset``, ``once``).
A server's journal adds ``epoch_id`` to every line: the ``epoch_id`` it publishes (8 hex
digits), which tells its plant from a restarted server's (a stranger's probe: a server
killed and restarted under a run, the report matched the second journal with the rows
and events of the first plant by time alone).
"""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import math
import os
import re
import stat
import time
from collections import deque
from pathlib import Path
from typing import Any

from rig_emulator.atomic import open_without_waiting

log = logging.getLogger("rig_emulator.serve")

#: Lines held back for a FIFO whose reader is behind, at most [bytes]: 30 bursts of the
#: largest tick (400 lines of 300 bytes at x1000); beyond, lines are lost, not the server
BACKLOG_BYTES = 4_000_000
#: How long :meth:`FaultJournal.close` waits for a FIFO's reader to take the rest [s]
CLOSE_WAIT_S = 2.0


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


class FaultJournal:
    """Appends fault events to a JSONL file, one flushed line each.

    A journal path that cannot be opened for writing at all (a directory the server's user
    may not write, a read-only file system) is refused by ``serve`` before any port opens
    (:func:`check_writable`). One that opens but cannot be written later (a full disk,
    ``/dev/full``, which opens as any device, a file system gone read-only) costs its
    lines, not the faults or the simulation: one warning says so and how many lines were
    lost, and the server serves on. Before, the error reached the
    lockstep advance that started the fault, which answered exception 04 although it had
    advanced (the client's next step went two), with a traceback in the log and a false
    "cannot serve" at the stop (a stranger's probe). :attr:`lines_lost` keeps the count
    after :meth:`close`: ``serve`` exits 1 on it (it exited 0, silent in CI: a probe).

    ``epoch_id``: the server's per-start identifier (:attr:`BenchServer.epoch_id`), written
    on every line as 8 hex digits; None: no such field (a journal of no server)."""

    def __init__(self, path: str | Path, begin: bool = True, epoch_id: int | None = None) -> None:
        self.path = Path(path)
        self.epoch_id = epoch_id
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd: int | None = None
        self._backlog: deque[bytes] = deque()  # lines a FIFO's pipe did not take yet
        self._backlog_bytes = 0
        self._behind_said = False
        self._begun = False
        self._failed = False  # the file could not be written: its lines are lost
        self.lost = 0  # lines that could not be written (and not warned of yet)
        self.lines_lost = 0  # all the lines lost, kept after close
        if begin:
            self.begin()

    def begin(self) -> None:
        """Start the file, unless begun: a server begins it once it serves on every port
        asked for, so a start that fails (a busy Modbus, HTTP or serial port) leaves an
        earlier journal as it was (it was emptied: strangers' probes); a first line begins
        it too. An earlier journal there is set aside, not replaced (:func:`set_aside`): a
        server restarted with the same ``--fault-log`` under a run emptied the first
        server's, the faults of the plant the run's first rows came from (one journal is
        one server's: the fault report compares each with its own plant's rows).

        A FIFO is opened without waiting for its reader (:func:`open_without_waiting`):
        one no process reads costs the lines, not the server (the open waited in the
        event loop, which no stop signal reached: a stranger's probe). Its writes never
        wait either: what a full pipe does not take is held back (at most
        :data:`BACKLOG_BYTES`) and written as the reader takes it, at the next line or
        :meth:`drain` (a burst of a tick at x1000 is twice a pipe's 64 kB: a re-probe lost
        it, and every line after, when a full pipe was a failed write)."""
        if self._begun:
            return
        self._begun = True
        try:
            kept = set_aside(self.path)
            if kept is not None:
                log.warning(
                    "fault journal %s: the earlier journal there kept as %s", self.path, kept
                )
            flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC
            if names_a_descriptor(self.path):  # (a stream, e.g. `>> out.txt`: added to)
                flags = os.O_WRONLY | os.O_APPEND
            self._fd = open_without_waiting(self.path, flags, blocking=False)
        except OSError as exc:
            self._failed = True
            why = "no process reads the FIFO" if exc.errno == errno.ENXIO else exc.strerror
            log.warning("fault journal %s: cannot write (%s)", self.path, why or exc)

    def write(self, event: dict[str, Any]) -> None:
        if self.epoch_id is not None:
            event = {**event, "epoch_id": f"{self.epoch_id:08x}"}
        line = json.dumps(_json_safe(event), allow_nan=False) + "\n"
        self.begin()
        if self._fd is None:
            if self._failed:  # dropped after a failed write (after close: nothing to count)
                self.lost += 1
                self.lines_lost += 1
            return
        data = line.encode("utf-8")
        if self._backlog_bytes + len(data) > BACKLOG_BYTES:
            self.lost += 1  # (the reader this far behind: this line, not the server)
            self.lines_lost += 1
            if not self._behind_said:
                self._behind_said = True
                log.warning(
                    "fault journal %s: its reader is %d kB behind: lines lost until it "
                    "catches up; the faults act as scheduled",
                    self.path,
                    BACKLOG_BYTES // 1000,
                )
        else:
            self._backlog.append(data)
            self._backlog_bytes += len(data)
        self.drain()

    def drain(self) -> None:
        """Write what is held back, as far as the file takes it without waiting (all of it,
        but for a FIFO whose reader is behind); a failed write costs the journal's lines
        from then on, said once."""
        while self._fd is not None and self._backlog:
            try:
                written = os.write(self._fd, self._backlog[0])
            except BlockingIOError:
                return
            except OSError as exc:
                self.lost += len(self._backlog)
                self.lines_lost += len(self._backlog)
                self._failed = True
                log.warning(
                    "fault journal %s: cannot write (%s): its lines are lost from now on; the "
                    "faults act as scheduled",
                    self.path,
                    exc.strerror or exc,
                )
                self._drop()
                return
            self._backlog_bytes -= written
            if written < len(self._backlog[0]):  # (a line's rest goes first, next time)
                self._backlog[0] = self._backlog[0][written:]
                return
            self._backlog.popleft()

    def _drop(self) -> None:
        """Stop writing: what is held back is lost (counted by the caller)."""
        fd, self._fd = self._fd, None
        self._backlog.clear()
        self._backlog_bytes = 0
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)

    def close(self) -> None:
        """Write what is held back, waiting up to :data:`CLOSE_WAIT_S` for a FIFO's reader
        (a reader that stopped reading cannot hold the server's stop), then close."""
        deadline = time.monotonic() + CLOSE_WAIT_S
        while self._fd is not None and self._backlog and time.monotonic() < deadline:
            self.drain()
            if self._backlog:
                time.sleep(0.01)
        if self._backlog:
            self.lost += len(self._backlog)
            self.lines_lost += len(self._backlog)
            log.warning(
                "fault journal %s: its reader took no more within %g s of the stop",
                self.path,
                CLOSE_WAIT_S,
            )
        self._drop()
        if self.lost:
            log.warning("fault journal %s: %d line(s) lost", self.path, self.lost)
            self.lost = 0


def check_writable(path: str | Path) -> None:
    """Raise the ``OSError`` :meth:`FaultJournal.begin` would meet at ``path``, found
    without changing anything there, so ``serve`` refuses a journal it cannot open before
    it opens a port: one that could not be opened (a directory of another user, its
    server run as nobody) was a warning, and the server served a whole session without a
    journal (a stranger's probe).

    - Nothing there: the file is created and removed again (through a dangling link: the
      file it names).
    - A non-empty regular file: the journal sets it aside (:func:`set_aside`) and makes a
      new one beside it, so it must be readable and its directory writable; the file
      itself need not be (a read-only earlier journal was refused: a re-probe).
    - An empty regular file or a device is opened for writing, not truncated, and closed.
    - A pipe or a FIFO is left alone: the command line checks and holds a FIFO's reader
      (closing a write end here would end its stream), and ``/dev/stdout`` piped, or a
      shell's ``>(...)``, names a pipe its holder reads (refused as "no such file" through
      the pipe's /proc name: a re-probe); a socket is refused by the command line.
    """
    path = Path(path)
    try:
        status = os.stat(path)  # (through links: /dev/stdout names the pipe itself)
    except FileNotFoundError:
        target = os.path.realpath(path)
        fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NONBLOCK, 0o666)
        os.close(fd)
        os.unlink(target)
        return
    if stat.S_ISFIFO(status.st_mode) or stat.S_ISSOCK(status.st_mode):
        return
    if stat.S_ISREG(status.st_mode) and status.st_size > 0 and not names_a_descriptor(path):
        folder = path.absolute().parent
        if not os.access(path, os.R_OK):
            why = "the earlier journal there cannot be read to set it aside"
        elif not os.access(folder, os.W_OK | os.X_OK):
            why = f"the earlier journal there cannot be set aside in {folder}"
        else:
            return
        raise OSError(errno.EACCES, f"{os.strerror(errno.EACCES)}: {why}", str(path))
    os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK | os.O_NOCTTY))  # (EROFS named)


#: a link that names an open descriptor of a process (``/dev/stdout`` is one to
#: ``/proc/self/fd/1``)
_DESCRIPTOR_LINK = re.compile(r"^/(proc/[^/]+|dev)/fd/\d+$")


def names_a_descriptor(path: str | Path) -> bool:
    """Whether ``path`` reaches its file through a link to an open descriptor
    (``/dev/stdout``, ``/dev/fd/N``, ``/proc/self/fd/N``): a stream the process was given,
    which is written to as it is, never set aside and replaced (``--fault-log /dev/stdout``
    with standard output appended to a file renamed the link and wrote a new file in its
    place: a re-probe)."""
    current = os.path.abspath(path)
    for _ in range(40):  # (the kernel's own bound on links followed)
        if _DESCRIPTOR_LINK.match(current):
            return True
        if not os.path.islink(current):
            return False
        current = os.path.normpath(os.path.join(os.path.dirname(current), os.readlink(current)))
    return False


def set_aside(path: Path) -> Path | None:
    """Rename a non-empty regular file at ``path`` to ``STEM.EPOCH.jsonl`` (the epoch id of
    its first line, else ``previous``; ``.2``, ``.3`` ... where taken) and return the new
    path; None where there is nothing to keep (no file, an empty one, a device, a stream
    the process was given: :func:`names_a_descriptor`)."""
    if not path.is_file() or path.stat().st_size == 0 or names_a_descriptor(path):
        return None
    with path.open("rb") as file:
        first = file.readline(4096)
    try:
        epoch = json.loads(first).get("epoch_id")
    except (ValueError, AttributeError):
        epoch = None
    tag = epoch if isinstance(epoch, str) and epoch.isalnum() else "previous"
    kept = path.with_name(f"{path.stem}.{tag}{path.suffix}")
    number = 1
    while kept.exists():
        number += 1
        kept = path.with_name(f"{path.stem}.{tag}.{number}{path.suffix}")
    path.rename(kept)
    return kept


def read_journal(path: str | Path) -> list[dict[str, Any]]:
    """The events of a journal file, in order."""
    events = []
    text = Path(path).read_text(encoding="utf-8-sig")  # an editor's byte-order mark dropped
    for number, line in enumerate(text.splitlines(), 1):
        if line.strip():
            try:
                events.append(json.loads(line))
            except (json.JSONDecodeError, RecursionError):
                raise ValueError(f"{path}: line {number} is not JSON") from None
    return events
