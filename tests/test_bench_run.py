"""``bench/run_bench.py``'s memory line says what it measures (the real script, run)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_the_memory_figure_names_its_parts():
    """A stranger's probe: "peak resident memory: 304 MiB (rows of one whole test kept in
    memory)", where the rows were about 50 MiB of it (158 MiB after the imports, 222 after
    one run, 273 with the rows kept). The line now gives the resident memory at each of
    those points beside the peak."""
    done = subprocess.run(
        [sys.executable, "bench/run_bench.py"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,  # (about 15 s here)
    )
    assert done.returncode == 0, done.stderr
    line = next(x for x in done.stdout.splitlines() if x.startswith("peak resident memory"))
    parts = re.fullmatch(
        r"peak resident memory of this process: (\d+) MiB; resident after its imports "
        r"\(numpy, numba, the packages\) (\d+) MiB, after the first run \(rows dropped\) "
        r"(\d+) MiB, with the (\d+) rows of one whole test kept in memory (\d+) MiB",
        line,
    )
    assert parts, line
    peak, imports, first, rows, kept = map(int, parts.groups())
    assert rows > 50_000, line
    # resident at each point, never above the peak (the rows need not add to what the
    # first run left resident: where it compiled the kernels, memory it freed holds them)
    assert 0 < imports <= first <= peak and imports < kept <= peak, line
