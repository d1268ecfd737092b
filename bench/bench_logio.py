"""``make bench``: reading a long lab log for analysis, printed (never asserted).

A log of about 300,000 rows (3.5 days at 1 s; the clean 12 kW load cycle written by
``hil-client run`` and repeated with its time shifted) is read by
:func:`hil_client.analysis.logio.read_log` in a fresh process: wall time, and the peak
resident memory it added over the file's size. Rows held as lists of text took 14 times
the file (a 76 MB log 1.05 GB; the 1 GB the reader accepts would have needed 14 GB);
parsed into columns a chunk at a time, about 3 times.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

from stopping import bench_main, require_exit_zero

from hil_client.cli import main as hil_client_main

ROWS = 300_000
# the peak of this process's own memory (VmHWM; ru_maxrss keeps the forking parent's)
MEASURE = """
import sys, time
from hil_client.analysis.logio import read_log
def peak():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) * 1024
before = peak()
start = time.perf_counter()
log = read_log(sys.argv[1])
wall = time.perf_counter() - start
print(len(log), wall, peak() - before)
"""


def _long_log(folder: Path) -> Path:
    one = folder / "one.csv"
    code = hil_client_main(
        ["run", "load_cycle", "--boiler", "windhager_12kw", "--out", str(one), "--quiet"]
    )
    require_exit_zero("hil-client run load_cycle", code)
    header, *rows = one.read_text().splitlines()
    at = header.split(",").index("time_s")
    span = float(rows[-1].split(",")[at]) + 1.0
    out = folder / "long.csv"
    with out.open("w") as fh:
        fh.write(header + "\n")
        written, k = 0, 0
        while written < ROWS:
            for row in rows[: ROWS - written]:
                fields = row.split(",")
                fields[at] = f"{float(fields[at]) + k * span:.3f}"
                fh.write(",".join(fields) + "\n")
            written += min(len(rows), ROWS - written)
            k += 1
    return out


def main() -> int:
    if not Path("/proc/self/status").exists():
        print("read_log memory: skipped (no /proc/self/status on this system)")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        log = _long_log(Path(tmp))
        size = log.stat().st_size
        measured = subprocess.run(
            [sys.executable, "-c", MEASURE, str(log)],
            capture_output=True,
            text=True,
            timeout=600,
        )
        require_exit_zero("the read_log measurement", measured.returncode)
        out = measured.stdout.split()
        rows, wall, added = int(out[0]), float(out[1]), float(out[2])
    print(
        f"read_log, {rows:,} rows, {size / 1e6:.0f} MB: {wall:.1f} s "
        f"({rows / wall:,.0f} rows/s), peak memory added {added / 1e6:.0f} MB = "
        f"{added / size:.1f} x the file (was about 14 x)"
    )
    return 0


if __name__ == "__main__":
    bench_main(main)
