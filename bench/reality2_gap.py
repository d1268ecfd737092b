"""Background gap of an independent plant (hil_client.reality2, or ``--plant NAME``: any of
``gap_benchmark.plants_by_name()``, e.g. the held-out reality3-5) against Type 869.

For N random backgrounds (both boilers alternating), this plant writes a stationary and a
load-cycle log with no listed effect. The project's model is calibrated on one log with the
project's own library (``hil_client.analysis.calibrate``, starting from the documentation
values) and validated on the other (``hil_client.analysis.validate``), in both directions
(stationary -> load cycle and load cycle -> stationary), as a diagnosis would. Printed: the
RMSD in the test phase (t1..t2) of the water temperature inside the boiler [K] and of the heat
to water [kW], per case and as a distribution, beside the band of the paper's Table 4 (test
sequence: T RMSD 1.36-2.63 K, Q RMSD 0.30-0.67 kW over its four runs; the brief's target band
1-3 K and 0.3-0.7 kW). Also the time to simulate one log. Figures are printed, never asserted.

    PYTHONPATH=. .venv/bin/python bench/reality2_gap.py [--cases 20] [--seed 7]
        [--phase-from signals] [--plant reality3|...|reality10]
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.gap_benchmark import plants_by_name
from hil_client.analysis.logio import read_log
from hil_client.analysis.phases import find_phases
from hil_client.analysis.validate import compare, validation_metrics
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.model.params import params_from_mapping

BOILERS = ("windhager_12kw", "windhager_6kw")
T_BAND_K = (1.0, 3.0)  # Table 4, test sequence, rounded out (brief)
Q_BAND_KW = (0.3, 0.7)


def one_case(k: int, seed: int, workdir: Path, prefer_signals: bool, plant) -> list[dict]:
    """Both directions of one background: the test-phase RMSDs of the validated log."""
    boiler_name = BOILERS[k % 2]
    boiler = yaml.safe_load((BOILER_DIR / f"{boiler_name}.yaml").read_text())
    rng = np.random.default_rng([seed, k])
    background = plant.draw_background(rng, boiler)
    logs, sim_s = {}, []
    for test in ("stationary", "load_cycle"):
        started = time.perf_counter()
        columns, _ = plant.simulate_log(
            boiler,
            test,
            background=background,
            effect=None,
            form=None,
            strength=0.0,
            seed=seed * 1000 + k,
            sample_s=1.0,
            jitter=False,
        )
        sim_s.append(time.perf_counter() - started)
        path = workdir / f"case{k:02d}_{test}.csv"
        plant.write_log_csv(columns, path)
        log = read_log(path)
        logs[test] = (log, find_phases(log, prefer_signals=prefer_signals))
    doc = params_from_mapping(boiler, boiler_name)
    rows = []
    for cal, val in (("stationary", "load_cycle"), ("load_cycle", "stationary")):
        params = calibrate([logs[cal]], doc).params
        log, phases = logs[val]
        metrics = validation_metrics(compare(log, phases, params), log, params)["metrics"]
        rows.append(
            {
                "case": k,
                "boiler": boiler_name,
                "calibration": cal,
                "validation": val,
                "t_rmsd_K": metrics["test"]["boiler_water_temp_C"]["rmsd"],
                "q_rmsd_kW": metrics["test"]["heat_to_water_kW"]["rmsd"],
                "t_rmsd_start_K": metrics["start_up"]["boiler_water_temp_C"]["rmsd"],
                "q_rmsd_start_kW": metrics["start_up"]["heat_to_water_kW"]["rmsd"],
                "sim_s": max(sim_s),
            }
        )
    return rows


def _quantiles(values: list[float]) -> str:
    q = np.quantile(values, [0.0, 0.1, 0.5, 0.9, 1.0])
    return " / ".join(f"{x:.2f}" for x in q)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", type=int, default=20)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument(
        "--phase-from",
        choices=("column", "signals"),
        default="column",
        help="phase bounds from the phase column or found from the signals",
    )
    plants = plants_by_name()
    parser.add_argument("--plant", choices=sorted(plants), default="reality2")
    args = parser.parse_args(argv)
    plant = importlib.import_module(plants[args.plant])
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.cases):
            for r in one_case(k, args.seed, Path(tmp), args.phase_from == "signals", plant):
                rows.append(r)
                print(
                    f"case {r['case']:2d} {r['boiler']:<15} cal {r['calibration']:<10} -> "
                    f"val {r['validation']:<10}  test: T RMSD {r['t_rmsd_K']:5.2f} K, "
                    f"Q RMSD {r['q_rmsd_kW']:5.2f} kW   start-up: T {r['t_rmsd_start_K']:5.2f} K,"
                    f" Q {r['q_rmsd_start_kW']:5.2f} kW",
                    flush=True,
                )
    t = [r["t_rmsd_K"] for r in rows]
    q = [r["q_rmsd_kW"] for r in rows]
    t_in = sum(T_BAND_K[0] <= x <= T_BAND_K[1] for x in t)
    q_in = sum(Q_BAND_KW[0] <= x <= Q_BAND_KW[1] for x in q)
    print(f"\n{len(rows)} validations ({args.cases} backgrounds x 2 directions)")
    print(f"T RMSD test phase [K]  min/p10/median/p90/max: {_quantiles(t)}   in 1-3 K: {t_in}")
    print(f"Q RMSD test phase [kW] min/p10/median/p90/max: {_quantiles(q)}   in 0.3-0.7: {q_in}")
    for val in ("stationary", "load_cycle"):
        tv = [r["t_rmsd_K"] for r in rows if r["validation"] == val]
        qv = [r["q_rmsd_kW"] for r in rows if r["validation"] == val]
        print(
            f"  validated on {val:<10}: median T {statistics.median(tv):.2f} K, "
            f"median Q {statistics.median(qv):.2f} kW"
        )
    sim = [r["sim_s"] for r in rows]
    print(f"one log simulated in: median {statistics.median(sim):.2f} s, max {max(sim):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
