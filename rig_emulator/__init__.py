"""Hardware-in-the-loop emulator of a pellet-boiler test bench (Carlon et al. 2015).

Layers, imports pointing one way only:
``rig_emulator.model`` (pure physics) <- ``rig_emulator.bench`` (water loop, balance, room)
<- clock and Modbus adapter.
"""

import hashlib
import os
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
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ["NUMBA_CACHE_DIR"] = str(base / "rig-emulator" / "numba" / digest.hexdigest()[:16])


_set_numba_cache_dir()
