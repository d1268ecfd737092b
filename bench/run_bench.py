"""``make bench``: speed and memory of the offline physics, printed (never asserted).

Figures:
- simulated seconds per wall second for the full load-cycle test (preheat, t0..t4, about
  16.5 h at 1 s steps) played by the protocol runner on the in-process rig, median of
  several runs, rows kept in memory (what calibration and diagnosis loops do);
- the same with the lab log written to a CSV file (what ``hil-client run`` does);
- the bare compiled bench step, for reference;
- peak resident memory of the process, and its resident memory after the imports, after
  a first run and with the rows of one whole test kept;
- the 13 % step of the clean 12 kW load cycle against the paper's Fig. 7 (Section 3.2.2):
  cut-outs, cool-back to the restart, the water at t2 and the first cooling.
"""

from __future__ import annotations

import resource
import statistics
import tempfile
import time
from pathlib import Path

from stopping import bench_main

from hil_client.lablog import LabLogWriter
from hil_client.protocol.definition import load_protocol
from hil_client.protocol.low_load import (
    PAPER_COOL_BACK_H,
    PAPER_FIRST_COOLING_MIN,
    PAPER_T_AT_T2_C,
    low_load_sequence,
)
from hil_client.protocol.runner import run_protocol
from hil_client.rigs.local import LocalRig
from rig_emulator.bench import Bench
from rig_emulator.boilers import load_boiler
from rig_emulator.instruments import load_profile

TARGET_X_REAL_TIME = 100_000  # issue 2: about 0.6 s for the whole test
RUNS = 7


def _offline_run(params, protocol, sink) -> float:
    rig = LocalRig(params, load_profile("clean"))
    start = time.perf_counter()
    result = run_protocol(protocol, params.p_nom_kW, rig, sink)
    wall = time.perf_counter() - start
    return result.duration_s / wall


def _fig7(params, protocol) -> None:
    rows: list = []
    result = run_protocol(
        protocol, params.p_nom_kW, LocalRig(params, load_profile("clean")), rows.append
    )
    seq = low_load_sequence(rows, result.times)
    print(
        f"Fig. 7, clean {params.name} load cycle, 13 % step: {len(seq.stops_s)} cut-outs "
        f"(paper 2), {len(seq.starts_s)} restart(s) (paper 1); back at 55 C "
        f"{seq.cool_back_h:.2f} h after the first stop (paper {PAPER_COOL_BACK_H} h)"
    )
    print(
        f"  water inside the boiler at t2: {seq.t_boiler_at_t2_C:.1f} C (paper "
        f"{PAPER_T_AT_T2_C:.0f} C); first cooling t2..t3: {seq.first_cooling_min:.1f} min "
        f"(paper about {PAPER_FIRST_COOLING_MIN:.0f} min); see docs/model.md"
    )


def _peak_mib() -> float:
    """The process's peak resident memory so far [MiB] (Linux gives ru_maxrss in KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _resident_mib() -> float:
    """The process's resident memory now [MiB] (VmRSS; the peak where /proc has none).
    Peaks cannot be told apart: a first run that compiles the kernels peaks above
    everything after it."""
    try:
        with open("/proc/self/status") as fh:
            return next(int(x.split()[1]) for x in fh if x.startswith("VmRSS:")) / 1024
    except (OSError, StopIteration):
        return _peak_mib()


def main() -> int:
    # the label said "rows of one whole test kept in memory" of the whole peak, of which
    # the rows were about a sixth (a stranger's probe): the parts are measured apart
    imports_mib = _resident_mib()
    params = load_boiler("windhager_12kw")
    protocol = load_protocol("load_cycle")
    t = time.perf_counter()
    _offline_run(params, protocol, lambda row: None)  # compile or load the numba cache
    print(f"warm-up (numba compile or cache load + first run): {time.perf_counter() - t:.2f} s")
    warm_mib = _resident_mib()

    rows: list = []
    speeds = [_offline_run(params, protocol, (rows.clear(), rows.append)[1]) for _ in range(RUNS)]
    rows_mib = _resident_mib()
    median = statistics.median(speeds)
    print(
        f"load cycle offline, rows in memory: median {median:,.0f} x real time over {RUNS} runs "
        f"(min {min(speeds):,.0f}, max {max(speeds):,.0f}); "
        f"{len(rows)} steps; target {TARGET_X_REAL_TIME:,}: "
        f"ratio {median / TARGET_X_REAL_TIME:.2f}"
    )
    print(f"  whole test: {len(rows) / median:.3f} s wall per {len(rows) / 3600:.2f} h simulated")

    with tempfile.TemporaryDirectory() as tmp:
        csv_speeds = []
        for _ in range(3):
            with LabLogWriter(Path(tmp) / "lc.csv") as writer:
                csv_speeds.append(_offline_run(params, protocol, writer))
    print(
        f"load cycle offline, CSV written and flushed per row: median "
        f"{statistics.median(csv_speeds):,.0f} x real time over 3 runs"
    )

    bench = Bench(params)
    bench.set_inputs(500.0, 55.0, True, True, False)
    n = 200_000
    step_times = []
    for _ in range(5):
        start = time.perf_counter()
        for _ in range(n):
            bench.step(1.0)
        step_times.append((time.perf_counter() - start) / n)
    print(
        "bare bench step (boiler + loop, compiled): "
        f"median {statistics.median(step_times) * 1e6:.2f} us"
    )
    peak_mib = _peak_mib()
    print(
        f"peak resident memory of this process: {peak_mib:.0f} MiB; resident after its imports"
        f" (numpy, numba, the packages) {imports_mib:.0f} MiB, after the first run (rows "
        f"dropped) {warm_mib:.0f} MiB, with the {len(rows)} rows of one whole test kept in "
        f"memory {rows_mib:.0f} MiB"
    )
    _fig7(params, protocol)
    return 0


if __name__ == "__main__":
    bench_main(main)
