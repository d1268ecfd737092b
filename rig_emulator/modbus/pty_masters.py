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

#: inotify's events: a file opened, closed after writing, closed after reading only, and
#: the event queue overflowed (inotify(7))
IN_OPEN, IN_CLOSE_WRITE, IN_CLOSE_NOWRITE, IN_Q_OVERFLOW = 0x20, 0x08, 0x10, 0x4000
_EVENT = struct.Struct("iIII")  # wd, mask, cookie, len (then len bytes of name)


class PtyMasters:
    """The processes' opens of a pty's client side, other than the server's own (made
    before the watch began); :meth:`watch` gives None where inotify is not to be had.

    Attributes:
        openers: open descriptions of the client side now (a master, or a prober).
    """

    def __init__(self, path: str, fd: int) -> None:
        self.path = path
        self._fd = fd
        self.openers = 0

    @classmethod
    def watch(cls, path: str) -> PtyMasters | None:
        """A watch on ``path``'s opens and closes, or None where the system has none (not
        Linux) or refuses one (no inotify watches left)."""
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
        return cls(path, fd)

    def fileno(self) -> int:
        return self._fd

    def update(self) -> tuple[bool, bool]:
        """Take the events that came: (a master came to a pty nobody had open, the last
        one left), each seen event by event (a master leaving and the next coming read
        together are both). After a queue that overflowed, the events are not all there:
        the count is made again from the processes' descriptors once the queue is read
        empty (the events read after the overflow are in that count already; applied on
        top of it, they left a count too high, or a live master unanswered: a re-probe),
        and only nobody left is told."""
        came = left = overflowed = False
        while True:
            try:
                data = os.read(self._fd, 4096)
            except OSError:  # (empty: BlockingIOError; closed: the line stopped)
                break
            offset = 0
            while offset + _EVENT.size <= len(data):
                _, mask, _, size = _EVENT.unpack_from(data, offset)
                offset += _EVENT.size + size
                if mask & IN_Q_OVERFLOW:
                    overflowed = True
                elif mask & IN_OPEN:
                    came |= self.openers == 0
                    self.openers += 1
                elif mask & (IN_CLOSE_WRITE | IN_CLOSE_NOWRITE):
                    left |= self.openers == 1
                    self.openers = max(self.openers - 1, 0)
        if overflowed:
            self.openers = count_openers(self.path)
            return False, self.openers == 0
        return came, left

    def close(self) -> None:
        with contextlib.suppress(OSError):
            os.close(self._fd)


def count_openers(path: str) -> int:
    """The descriptors other processes hold on ``path``'s device, from /proc (those of
    another user's processes are not seen: a master is the user's own program)."""
    try:
        device = os.stat(path).st_rdev
    except OSError:
        return 0
    own = str(os.getpid())
    count = 0
    with contextlib.suppress(OSError):
        for pid in os.listdir("/proc"):
            if not pid.isdigit() or pid == own:
                continue
            with contextlib.suppress(OSError):
                for fd in os.listdir(f"/proc/{pid}/fd"):
                    with contextlib.suppress(OSError):
                        status = os.stat(f"/proc/{pid}/fd/{fd}")
                        count += stat.S_ISCHR(status.st_mode) and status.st_rdev == device
    return count
