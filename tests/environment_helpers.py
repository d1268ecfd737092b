"""What the tests of the commands' environment share: a name no stream encoding carries
whole, a command launched as its own process with a chosen stream encoding, and a
directory mounted read-only."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import pytest

#: a directory name with a byte that is no UTF-8 (as Python hands it over: surrogateescape)
#: and a character ASCII lacks
ODD_NAME = "caf\u00e9-" + os.fsdecode(b"bad\xff")

#: what each standard stream encoding makes of ODD_NAME: the raw byte back where the
#: encoding carries a lone byte, else its backslash escape; 'é' escaped where it cannot go
ODD_NAME_WRITTEN = {
    "utf-8:strict": "caf\u00e9".encode() + b"-bad\xff",
    "ascii:strict": b"caf\\xe9-bad\xff",
    "latin-1:strict": b"caf\xe9-bad\xff",
    "utf-16-le:strict": "caf\u00e9-bad\\xff".encode("utf-16-le"),
}


def launched(
    package: str,
    *argv: str,
    timeout_s: float,
    cwd: Path | None = None,
    encoding: str | None = None,
    preexec_fn: Callable[[], None] | None = None,
    prefix: Sequence[str] = (),
) -> subprocess.CompletedProcess[bytes]:
    """``package``'s command (``rig_emulator`` or ``hil_client``) with ``argv`` as its own
    process, through its launcher (``encoding``: its PYTHONIOENCODING; ``prefix``: a
    command it runs under, e.g. :func:`read_only_mount`'s)."""
    env = dict(os.environ)
    if encoding is not None:
        env["PYTHONIOENCODING"] = encoding
    code = f"from {package}.launch import main; import sys; sys.exit(main())"
    return subprocess.run(
        [*prefix, sys.executable, "-c", code, *argv],
        cwd=cwd, env=env, preexec_fn=preexec_fn, capture_output=True, timeout=timeout_s,
    )  # fmt: skip


def close_stdout() -> None:
    """A ``preexec_fn``: the command starts without a standard output (``>&-``)."""
    os.close(1)


def read_only_mount(directory: Path, timeout_s: float = 60) -> list[str]:
    """The command prefix that runs a command with ``directory`` mounted read-only in a
    mount namespace of its own (nothing outside sees it); skips where that is not allowed
    (no root, no unshare)."""
    prefix = [
        "unshare", "-m", "sh", "-c",
        'mount --bind "$1" "$1" && mount -o remount,bind,ro "$1" && shift && exec "$@"',
        "sh", str(directory),
    ]  # fmt: skip
    if shutil.which("unshare") is None:
        pytest.skip("no unshare here to mount a directory read-only")
    probe = subprocess.run([*prefix, "true"], capture_output=True, timeout=timeout_s)
    if probe.returncode != 0:
        pytest.skip(f"cannot mount a directory read-only here: {probe.stderr.decode().strip()}")
    return prefix
