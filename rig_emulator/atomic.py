"""Files written whole or not at all: a temporary file beside the target, put in its place
once written (a rename, which needs no space). A disk that fills up, or any other failure,
leaves the previous file as it was and no temporary file (map-doc left 8 kB of a new
reference in place of the old one, validate a 0-byte figure: a stranger's probe with an
8-kB tmpfs)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def replacing(path: Path) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix: a figure's format follows it) to write;
    it replaces ``path`` (the file a link names, not the link) when the block ends, and is
    removed if the block fails (an OSError about it then names ``path``). A ``path`` that is
    a device or a pipe is written as it is."""
    if path.exists() and not path.is_file():  # a device or a pipe (/dev/stdout): written
        yield path  # to as it is (a file was put in its place: a re-probe)
        return
    real = Path(os.path.realpath(path))  # through links: the file they name is replaced
    tmp = real.with_name(f".{real.stem}.{os.getpid()}.tmp{real.suffix}")
    try:
        yield tmp
        os.replace(tmp, real)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename == str(tmp):
            exc.filename = str(path)
        raise


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`replacing`."""
    with replacing(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
