"""One run at a time per log: ``hil-client run`` holds an exclusive lock on a hidden file
beside its ``--out`` (``.NAME.csv.lock``) while it writes, so a second run given the same
log is refused before it moves anything. Without it the second run set the first one's
live log aside as ``.previous`` and deleted it at its own first row, while the first went
on writing into the deleted file (a probe: two CI jobs given one ``--out``).

The lock is the kernel's (``flock``): it goes with the process however the process ends
(kill -9 included), so a stale file never blocks a later run; the file is removed when the
run ends."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path


class RunBusy(Exception):
    """Another live process holds the lock of this log."""


def lock_path(log_path: Path) -> Path:
    """The lock file of ``log_path``, beside the file it resolves to (a link and its
    target are one log)."""
    real = Path(os.path.realpath(log_path))
    return real.with_name(f".{real.name}.lock")


@contextlib.contextmanager
def run_lock(log_path: Path) -> Iterator[None]:
    """Hold the lock of ``log_path`` for the ``with`` block; :class:`RunBusy` naming the
    holder's pid if another process holds it. Where no lock file can be made (a directory
    without write permission), the run goes on without one: its log cannot be written
    there either, and the run says so itself."""
    path = lock_path(log_path)
    fd = _locked(path)
    if fd is None:
        yield
        return
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _locked(path: Path) -> int | None:
    """A descriptor of ``path`` holding its lock, None where the file cannot be made."""
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.read(fd, 32).decode("ascii", "replace").strip()
            os.close(fd)
            raise RunBusy(f"pid {holder}" if holder.isdigit() else "another process") from None
        try:  # the file a finished run removed after this one opened it: open it again
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)
