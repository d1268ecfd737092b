"""How long this client process was held up: stopped (SIGSTOP, a debugger), swapped out or
starved of CPU, whatever it was doing at the time.

A thread of its own wakes every :data:`PERIOD_S`; every wake-up later than that by more
than :data:`LATE_S` is time the whole process stood still. Unlike the wall time between two
requests less the time spent waiting on the wire, it does not depend on where the process
was stopped: one stopped while blocked on a socket finds the server's reply there once it
goes on, and that wait looked like the server's (a client SIGSTOPped 8 s, whose connection
a server's ``--idle-timeout 3`` closed meanwhile, was recorded as "connection closed by the
server" alone: a stranger's probe).
"""

from __future__ import annotations

import os
import threading
import time

#: how often the heartbeat wakes [s]
PERIOD_S = 0.05
#: a wake-up this much later than asked is a hold-up [s] (a busy machine's scheduling is
#: late by milliseconds)
LATE_S = 0.05


class _Heartbeat:
    """The thread that measures the hold-ups of this process (see the module docstring)."""

    def __init__(self) -> None:
        self.pid = os.getpid()  # (a forked child has no such thread: it starts its own)
        # (held up so far [s], the last wake-up [monotonic s]): one tuple, so that a reader
        # never sees one updated without the other
        self._state = (0.0, time.monotonic())
        threading.Thread(target=self._beat, name="hold-up heartbeat", daemon=True).start()

    def _beat(self) -> None:
        while True:
            time.sleep(PERIOD_S)
            held, last = self._state
            now = time.monotonic()
            late = now - last - PERIOD_S
            self._state = (held + late if late > LATE_S else held, now)

    def held_s(self) -> float:
        """Held up so far [s], the hold-up still under way included: the process goes on
        after one with every thread at once, and the heartbeat may not have woken yet."""
        held, last = self._state
        pending = time.monotonic() - last - PERIOD_S
        return held + pending if pending > LATE_S else held


_heartbeat: _Heartbeat | None = None
_lock = threading.Lock()


def held_up_s() -> float:
    """How long this process has been held up since its first call [s] (monotonic: the
    difference of two calls is the hold-up between them)."""
    global _heartbeat
    with _lock:
        if _heartbeat is None or _heartbeat.pid != os.getpid():
            _heartbeat = _Heartbeat()
        return _heartbeat.held_s()
