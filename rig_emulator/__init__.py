"""Hardware-in-the-loop emulator of a pellet-boiler test bench (Carlon et al. 2015).

Layers, imports pointing one way only:
``rig_emulator.model`` (pure physics) <- ``rig_emulator.bench`` (water loop, balance, room)
<- clock and Modbus adapter.
"""

import hashlib
import os
import stat
import tempfile
from pathlib import Path

__version__ = "0.1.0"


def home_dir() -> Path | None:
    """The user's home directory, or None where none can be named (HOME unset and a user id
    without a passwd entry, as ``docker run --user 12345`` can give): Path.home() raises
    there, and every command, --help too, ended in a traceback at import (a re-probe)."""
    try:
        return Path.home()
    except RuntimeError:
        return None


def writable_dir(path: Path) -> bool:
    """Whether ``path`` is, or could be made, a directory this process can write into."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return path.is_dir() and os.access(path, os.W_OK)


def private_temp_dir(*parts: str) -> Path | None:
    """This user's own directory under the system's temporary directory
    (``rig-emulator-UID``, mode 0700) with ``parts`` below it, created as needed; None where
    there is none to be had.

    For the caches the commands need where the home directory cannot be written (a service
    account with HOME=/nonexistent; ``docker compose run --user`` with HOME=/). The
    temporary directory is everybody's: a directory of that name made by another user (or
    a symlink there) would let them plant caches this user's processes load, so only one
    this user owns is used, and nobody else may write into it.
    """
    uid = os.getuid()
    base = Path(tempfile.gettempdir()) / f"rig-emulator-{uid}"
    try:
        base.mkdir(mode=0o700, exist_ok=True)
        info = base.lstat()
        if not stat.S_ISDIR(info.st_mode) or info.st_uid != uid:
            return None
        if stat.S_IMODE(info.st_mode) != 0o700:  # an earlier release made it with the umask's
            base.chmod(0o700)
        path = base.joinpath(*parts)
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return None
    return path if os.access(path, os.W_OK) else None


def _set_numba_cache_dir() -> None:
    """Key numba's on-disk cache by the content of the compiled sources.

    numba invalidates a cached function when its own file changes but not when a function
    it calls from another file does (bench_step calls the boiler's step); a directory per
    source hash makes a stale kernel impossible. An explicit NUMBA_CACHE_DIR is respected.
    """
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    root = Path(__file__).parent
    digest = hashlib.sha256()
    for sub in ("model", "bench", "instruments"):
        for path in sorted((root / sub).rglob("*.py")):
            digest.update(path.relative_to(root).as_posix().encode())
            digest.update(path.read_bytes())
    key = digest.hexdigest()[:16]
    home = home_dir()
    base = os.environ.get("XDG_CACHE_HOME") or (str(home / ".cache") if home else "")
    cache = Path(base, "rig-emulator", "numba", key) if base else None
    if cache is None or not writable_dir(cache):
        # a service account without a home (HOME=/nonexistent): numba found no cache
        # directory, and every command, --help too, ended in a traceback (a stranger's probe)
        cache = private_temp_dir("numba", key)
    if cache:
        os.environ["NUMBA_CACHE_DIR"] = str(cache)


_set_numba_cache_dir()
