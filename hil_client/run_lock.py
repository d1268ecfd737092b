"""One run at a time per log: ``hil-client run`` holds an exclusive lock on a hidden file
beside its ``--out`` (``.NAME.csv.lock``) while it writes, so a second run given the same
log is refused before it moves anything. Without it the second run set the first one's
live log aside as ``.previous`` and deleted it at its own first row, while the first went
on writing into the deleted file (a probe: two CI jobs given one ``--out``).

The lock is one per log *name*: ``NAME.csv`` and ``NAME.CSV`` (any case of ``.csv``) take
the same ``.NAME.csv.lock``, as they share ``NAME.meta.json`` and
``NAME.modbus_events.jsonl`` (a stranger's probe: a run writing ``s.CSV`` replaced the
meta file of a live run writing ``s.csv`` and truncated its events, and ``balance s.csv``
then read the other run's boiler and phase marks without a word). So the lock covers
every file a run writes.

The lock is the kernel's (``flock``): it goes with the process however the process ends
(kill -9 included), so a stale file never blocks a later run; the file is removed when the
run ends. It holds the holder's pid, what it does with the name (``writing`` a log, or
``keeping`` an earlier run's files there) and the ``--out`` it was given, for the refusal
to say."""

from __future__ import annotations

import contextlib
import fcntl
import os
from collections.abc import Iterator
from pathlib import Path

#: The suffix of a log; any case of it names the same meta and events files.
LOG_SUFFIX = ".csv"


class RunBusy(Exception):
    """Another live process holds the lock of this log: its ``pid`` (None if it did not
    say), what it does there (``role``: ``writing`` or ``keeping``) and the ``--out`` it
    was given (``out``), each None if unknown (a lock file of an older version)."""

    def __init__(self, pid: int | None, role: str | None = None, out: str | None = None):
        super().__init__(f"pid {pid}" if pid is not None else "another process")
        self.pid, self.role, self.out = pid, role, out


def lock_path(log_path: Path) -> Path:
    """The lock file of ``log_path``, beside the file it resolves to (a link and its
    target are one log), one for every case of ``.csv`` (they share the companions)."""
    real = Path(os.path.realpath(log_path))
    if real.suffix.lower() == LOG_SUFFIX:
        return real.with_name(f".{real.stem}{LOG_SUFFIX}.lock")
    return real.with_name(f".{real.name}.lock")


@contextlib.contextmanager
def run_lock(log_path: Path, role: str = "writing", out: Path | None = None) -> Iterator[None]:
    """Hold the lock of ``log_path`` for the ``with`` block; :class:`RunBusy` naming the
    holder if another process holds it. ``role`` and ``out`` (``log_path`` if None) are
    written in the lock for a refused run to say. Where no lock file can be made (a
    directory without write permission), the run goes on without one: its log cannot be
    written there either, and the run says so itself."""
    path = lock_path(log_path)
    fd = _locked(path)
    if fd is None:
        yield
        return
    try:
        given = os.fsencode(os.path.abspath(out if out is not None else log_path))
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n{role}\n".encode() + given + b"\n")
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _holder(fd: int) -> RunBusy:
    """What the lock file open at ``fd`` says of the process holding it: pid, role and
    ``--out`` lines (a path may hold a line break: the rest of the file is the path)."""
    text = os.read(fd, 65536)
    pid, _, rest = text.partition(b"\n")
    role, _, out = rest.partition(b"\n")
    return RunBusy(
        int(pid) if pid.strip().isdigit() else None,
        role.decode("ascii", "replace") or None,
        os.fsdecode(out[:-1] if out.endswith(b"\n") else out) or None,
    )


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
            busy = _holder(fd)
            os.close(fd)
            raise busy from None
        try:  # the file a finished run removed after this one opened it: open it again
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)
