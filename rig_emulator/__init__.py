"""Hardware-in-the-loop emulator of a pellet-boiler test bench (Carlon et al. 2015).

Layers, imports pointing one way only:
``rig_emulator.model`` (pure physics) <- ``rig_emulator.bench`` (water loop, balance, room)
<- clock and Modbus adapter.
"""

import hashlib
import os
import tempfile
from pathlib import Path

__version__ = "0.1.0"


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
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    for cache in (
        base / "rig-emulator" / "numba" / key,
        # a service account without a home (HOME=/nonexistent): numba found no cache
        # directory, and every command, --help too, ended in a traceback (a stranger's probe)
        Path(tempfile.gettempdir()) / f"rig-emulator-{os.getuid()}" / "numba" / key,
    ):
        try:
            cache.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(cache, os.W_OK):
            os.environ["NUMBA_CACHE_DIR"] = str(cache)
            return


_set_numba_cache_dir()
