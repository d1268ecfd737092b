"""Files written whole or not at all: a temporary file beside the target, put in its place
once written (a rename, which needs no space). A disk that fills up, or any other failure,
leaves the previous file as it was and no temporary file (map-doc left 8 kB of a new
reference in place of the old one, validate a 0-byte figure: a stranger's probe with an
8-kB tmpfs)."""

from __future__ import annotations

import contextlib
import errno
import os
import stat
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix: a figure's format follows it) to write;
    it replaces ``path`` (the file a link names, not the link) when the block ends, and is
    removed if the block fails (an OSError about it then names ``path``); the old file's mode
    and owner are kept. Written as it is instead: see :func:`_in_place`, and a directory
    that allows no new file."""
    if _in_place(path):
        if path.is_fifo():  # (a FIFO nobody reads: the writer's open waited for good, the
            reader = open_without_waiting(path)  # files beside an --out: a re-probe)
            try:  # (held open: the writer's own open finds its reader still there)
                yield path
            finally:
                os.close(reader)
            return
        yield path
        return
    real = Path(os.path.realpath(path))  # through links: the file they name is replaced
    # (a short name: one of 245 bytes grew past the file system's 255 with the suffixes)
    tmp = real.with_name(f".{real.stem[:64]}.{os.getpid()}.tmp{real.suffix[:16]}")
    try:
        tmp.touch()
    except OSError:  # a directory it may not create files in (a re-probe: the writable
        yield path  # file of a read-only directory could no longer be written)
        return
    try:
        if real.exists():  # the old file's mode, and owner where allowed (a private file
            st = real.stat()  # became world-readable: a re-probe)
            os.chmod(tmp, stat.S_IMODE(st.st_mode))
            with contextlib.suppress(OSError):
                os.chown(tmp, st.st_uid, st.st_gid)
        yield tmp
        os.replace(tmp, real)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename == str(tmp):
            exc.filename = str(path)
        raise


def _in_place(path: Path) -> bool:
    """Whether ``path`` is written as it is, not replaced: a device or a pipe, anything under
    /dev or /proc (/dev/stdout redirected to a file replaced that file, and a file was put
    in place of the link: re-probes), and a file of several hard links (the others kept
    the old text)."""
    if not path.exists():
        return False
    if not path.is_file() or str(path.absolute()).startswith(("/dev/", "/proc/")):
        return True
    return path.stat().st_nlink > 1


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`replacing`; a stream under /dev or
    /proc is appended to (``/dev/stdout`` opened for writing truncated the file the shell
    appended standard output to: a re-probe)."""
    if path.exists() and str(path.absolute()).startswith(("/dev/", "/proc/")):
        with path.open("a", encoding="utf-8") as stream:
            stream.write(text)
        return
    with replacing(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def open_without_waiting(path: Path, flags: int = os.O_WRONLY, *, blocking: bool = True) -> int:
    """A descriptor of ``path`` opened for writing (``flags``) that never waits for a FIFO's
    reader: a FIFO no process reads is an ``OSError`` ENXIO at once (a plain open waits for
    one, taken up again after every signal whose handler raises nothing, as the server's
    stop signals' do: ``serve --fault-log FIFO`` hung deaf to them, a stranger's probe).
    Once open it blocks as any other, unless ``blocking`` is False: a writer that must never
    wait (the server's fault journal, written from its event loop) then gets
    ``BlockingIOError`` from a pipe its reader stopped emptying."""
    try:
        fd = os.open(path, flags | os.O_NONBLOCK, 0o666)
    except OSError as exc:
        if exc.errno == errno.ENXIO:  # (its own words, "No such device or address", named
            raise OSError(errno.ENXIO, "no process reads the FIFO", str(path)) from None
        raise  # nothing a user could act on: a re-probe)
    os.set_blocking(fd, blocking)
    return fd
