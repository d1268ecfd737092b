"""Who has the emulator's pty open: the masters on its client side, counted from inotify's
open and close events of the client side's path (Linux; inotify(7)).

A reply on a serial line reaches the master listening then, or nobody: a master that
timed out or was killed before reading it never gets it, and neither does the next. On a
pty the reply waits in the client side's queue instead, and the next master to open the
pty (mbpoll: libmodbus does not flush on opening) took it for its own answer and printed
a register's old value with exit 0 (a stranger's probe). Knowing whether anybody has the
pty open, the line can do what a wire does: write no reply when nobody is there, drop what
is queued when the last master leaves, and start each new master on an empty queue. A
process that opens the pty while a master has it (``stty -F``, a prober) changes nothing
for that master: a queue emptied on every close lost a live master's reply (a re-probe).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import stat
import struct
from dataclasses import dataclass

#: inotify's events: a file opened, closed after writing, closed after reading only, and
#: the event queue overflowed (inotify(7))
IN_OPEN, IN_CLOSE_WRITE, IN_CLOSE_NOWRITE, IN_Q_OVERFLOW = 0x20, 0x08, 0x10, 0x4000
_EVENT = struct.Struct("iIII")  # wd, mask, cookie, len (then len bytes of name)


#: How many times the processes are counted again while events keep coming as they are
#: (a storm of opens and closes ends the batch with the last count; the next batch goes on)
RECOUNTS = 3


@dataclass
class _Batch:
    """A batch of the watch's events, as :meth:`PtyMasters.update` takes them."""

    running: int  # the openers, counted on from the last count by the events
    opened: bool = False
    closed: bool = False
    overflowed: bool = False
    #: a master opened the pty after the batch's closes had left nobody
    swapped: bool = False
    more: bool = False  # the last read of the queue found events


class PtyMasters:
    """The processes' opens of a pty's client side, other than the server's own
    descriptors; :meth:`watch` gives None where inotify is not to be had.

    inotify's events say *when* somebody opened or closed the pty, not how many have it
    open: two identical events queued back to back are merged into one (inotify(7)), so a
    master opening the pty twice (a reader and a writer) was counted once, and its first
    close left it unanswered (a re-probe: 5 of 8 runs), and two closes merged left a count
    with nobody there. So each batch of events is followed by a count from /proc, the
    truth wherever every process's descriptors can be read (a batch of opens alone
    needs none: somebody is there); the events in between tell only that one master left
    and the next came within the batch.

    Attributes:
        openers: descriptors of the client side held now (a master, or a prober).
        arrivals: how many times a master came to a pty nobody had open (or as the last
            one left): a reply to a request made before the last arrival is the departed
            master's.
    """

    def __init__(self, path: str, fd: int, own: frozenset[int] = frozenset()) -> None:
        self.path = path
        self._fd = fd
        self._own = own
        self.openers = 0
        self.arrivals = 0

    @classmethod
    def watch(cls, path: str, own: frozenset[int] = frozenset()) -> PtyMasters | None:
        """A watch on ``path``'s opens and closes (``own``: this process's descriptors of
        it, which are no master), or None where the system has none (not Linux) or refuses
        one (no inotify watches left)."""
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            fd = libc.inotify_init1(os.O_NONBLOCK | os.O_CLOEXEC)
        except (OSError, AttributeError):
            return None
        if fd < 0:
            return None
        events = IN_OPEN | IN_CLOSE_WRITE | IN_CLOSE_NOWRITE
        if libc.inotify_add_watch(fd, os.fsencode(path), events) < 0:
            os.close(fd)
            return None
        masters = cls(path, fd, own)
        masters.openers = count_openers(path, own)[0]
        return masters

    def fileno(self) -> int:
        return self._fd

    def update(self) -> tuple[bool, bool]:
        """Take the events that came: (a master came to a pty nobody had open, the last
        one left). A master leaving and the next coming within the batch are both. After
        the batch the count is the processes' (:func:`count_openers`); where some
        processes' descriptors cannot be read (another user's: ``sudo mbpoll``), not less
        than the events say. A master that opens the pty while the processes are counted
        is in the count but its event comes after the batch: the events are read again
        after each count, and counted again while more came (a newcomer counted before its
        event was read was never told as come, and read the departed master's reply as
        its own: a re-probe, 17 of 20 runs opening 13-15 ms after the request at 19,200
        baud). After a queue that overflowed, the events are not all there and only the
        processes' count is taken (the events read after the overflow are in it already;
        applied on top of it, they left a count too high, or a live master unanswered: a
        re-probe), and only nobody left is told."""
        before = self.openers
        batch = self._take(_Batch(before))
        if batch.closed and not batch.overflowed:  # (opens alone need no count: somebody
            for _ in range(RECOUNTS):  # is there, as counted)
                seen, whole = count_openers(self.path, self._own)
                if not self._take(batch).more:
                    break
            batch.running = seen if whole else max(seen, batch.running)
        if batch.overflowed:
            self.openers = count_openers(self.path, self._own)[0]
            return False, self.openers == 0
        came = (before == 0 and batch.opened) or batch.swapped
        self.openers, self.arrivals = batch.running, self.arrivals + came
        return came, batch.closed and batch.running == 0

    def _take(self, batch: _Batch) -> _Batch:
        """``batch`` with the events queued now applied (:attr:`_Batch.more`: whether any
        were)."""
        batch.more = False
        while True:
            try:
                data = os.read(self._fd, 4096)
            except OSError:  # (empty: BlockingIOError; closed: the line stopped)
                return batch
            offset = 0
            while offset + _EVENT.size <= len(data):
                _, mask, _, size = _EVENT.unpack_from(data, offset)
                offset += _EVENT.size + size
                batch.more = True
                if mask & IN_Q_OVERFLOW:
                    batch.overflowed = True
                elif mask & IN_OPEN:
                    batch.swapped |= batch.closed and batch.running == 0
                    batch.opened = True
                    batch.running += 1
                elif mask & (IN_CLOSE_WRITE | IN_CLOSE_NOWRITE):
                    batch.closed = True
                    batch.running = max(batch.running - 1, 0)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self._fd)


def count_openers(path: str, own: frozenset[int] = frozenset()) -> tuple[int, bool]:
    """(the descriptors processes hold on ``path``'s device, from /proc, less this
    process's ``own``; whether every process's descriptors could be read: another user's
    cannot be, unless this one is root)."""
    try:
        device = os.stat(path).st_rdev
    except OSError:
        return 0, True
    me = str(os.getpid())
    count, whole = 0, True
    try:
        pids = [pid for pid in os.listdir("/proc") if pid.isdigit()]
    except OSError:
        return 0, False
    for pid in pids:
        try:
            fds = os.listdir(f"/proc/{pid}/fd")
        except PermissionError:
            whole = False
            continue
        except OSError:  # (the process is gone)
            continue
        for fd in fds:
            if pid == me and int(fd) in own:
                continue
            with contextlib.suppress(OSError):
                status = os.stat(f"/proc/{pid}/fd/{fd}")
                count += stat.S_ISCHR(status.st_mode) and status.st_rdev == device
    return count, whole
