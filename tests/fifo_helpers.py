"""A reader of a FIFO for the tests of outputs that may be one (a journal followed through a
named pipe, a report): the process reading it, in a thread."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path


class FifoReader:
    """A thread reading a FIFO from its first writer's open until the end of the stream
    (every writer closed), the lines kept as they come."""

    def __init__(self, fifo: Path) -> None:
        self.fifo = fifo
        self.lines: list[str] = []
        # a read end open from now on, so a writer's open finds a reader before the
        # thread's own open (which waits for a writer) is under way
        self._early = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)
        self.thread = threading.Thread(target=self._read, daemon=True)
        self.thread.start()

    def _read(self) -> None:
        with self.fifo.open(encoding="utf-8") as stream:  # (waits for a writer)
            os.close(self._early)
            for line in stream:
                self.lines.append(line)

    def wait_for(self, count: int, timeout_s: float) -> bool:
        """True once ``count`` lines came, False after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while len(self.lines) < count and time.monotonic() < deadline:
            time.sleep(0.05)
        return len(self.lines) >= count

    def ended(self, timeout_s: float) -> bool:
        """Whether the stream ended (the thread done) within ``timeout_s``; if not, a writer
        opened and closed here releases the thread."""
        self.thread.join(timeout_s)
        if not self.thread.is_alive():
            return True
        with_reader_waiting = os.open(self.fifo, os.O_WRONLY | os.O_NONBLOCK)
        os.close(with_reader_waiting)
        self.thread.join(10.0)
        return False
