"""Background gap of the independent plant (``hil_client.reality``) against the project's
model, printed beside the paper's Table 4 band (never asserted).

For each of N random backgrounds (alternating the 6 kW and 12 kW boilers; sampling 1, 2, 5
or 10 s, 30 % with jitter, as the gap benchmark draws them) the plant writes a stationary
and a load-cycle log *without* a listed effect. The project's calibration
(:func:`hil_client.analysis.calibrate.calibrate`, what ``hil-client calibrate`` runs) is
fitted on the stationary log, and the project's validation (:func:`compare`, what
``hil-client validate`` runs) replays the calibrated Type 869 model on both logs. Printed per
case and as a distribution: RMSD of the boiler-water temperature [K] and of the heat to
water [kW] in the test phase (t1..t2), the figures of Table 4 (test sequence: T 1.36-2.63 K,
Q 0.30-0.67 kW over the four runs; the issue's band T 1-3 K, Q 0.3-0.7 kW).

Usage: ``python bench/reality_gap.py [N] [SEED]`` (default 20 backgrounds, seed 2015).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.logio import read_log
from hil_client.analysis.metrics import rmsd
from hil_client.analysis.phases import find_phases
from hil_client.analysis.validate import compare
from hil_client.reality import draw_background, simulate_log, write_log_csv
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.model.params import params_from_mapping

BOILERS = ("windhager_6kw", "windhager_12kw")
BAND_T_K = (1.0, 3.0)  # issue 10 / CONTRACT section 4: test phase, Table 4
BAND_Q_KW = (0.3, 0.7)


def test_phase_gap(log_path: Path, params) -> tuple[float, float]:
    """(T RMSD [K], Q RMSD [kW]) of the calibrated model on the test phase of one log."""
    log = read_log(log_path)
    phases = find_phases(log)
    comp = compare(log, phases, params)
    mask = comp.segments["test"]
    return (
        rmsd(comp.model["boiler_water_temp_C"][mask], comp.lab["boiler_water_temp_C"][mask]),
        rmsd(comp.model["heat_to_water_kW"][mask], comp.lab["heat_to_water_kW"][mask]),
    )


def one_case(i: int, seed: int, work: Path) -> dict:
    rng = np.random.default_rng([seed, i])
    name = BOILERS[i % 2]
    boiler = yaml.safe_load((BOILER_DIR / f"{name}.yaml").read_text())
    background = draw_background(rng, boiler)
    sample_s = float(rng.choice([1.0, 2.0, 5.0, 10.0]))
    jitter = bool(rng.random() < 0.3)
    paths = {}
    for test in ("stationary", "load_cycle"):
        cols, _ = simulate_log(
            boiler,
            test,
            background=background,
            effect=None,
            form=None,
            strength=0.0,
            seed=seed + i,
            sample_s=sample_s,
            jitter=jitter,
        )
        paths[test] = work / f"case{i:02d}_{test}.csv"
        write_log_csv(cols, paths[test])
    doc = params_from_mapping(boiler)
    stat = read_log(paths["stationary"])
    cal = calibrate([(stat, find_phases(stat))], doc)
    row = {"case": i, "boiler": name, "sample_s": sample_s, "jitter": jitter}
    for test in ("stationary", "load_cycle"):
        t_gap, q_gap = test_phase_gap(paths[test], cal.params)
        row[f"{test}_T_K"], row[f"{test}_Q_kW"] = t_gap, q_gap
    return row


def _inside(x: float, band: tuple[float, float]) -> str:
    return "in " if band[0] <= x <= band[1] else ("low" if x < band[0] else "HIGH")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args else 20
    seed = int(args[1]) if len(args) > 1 else 2015
    rows = []
    started = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(n):
            r = one_case(i, seed, Path(tmp))
            rows.append(r)
            print(
                f"case {i:2d} {r['boiler']:<15} {r['sample_s']:4.0f} s"
                f"{' jitter' if r['jitter'] else '       '} | stationary T "
                f"{r['stationary_T_K']:5.2f} K ({_inside(r['stationary_T_K'], BAND_T_K)}) Q "
                f"{r['stationary_Q_kW']:5.2f} kW ({_inside(r['stationary_Q_kW'], BAND_Q_KW)}) | "
                f"load cycle T {r['load_cycle_T_K']:5.2f} K "
                f"({_inside(r['load_cycle_T_K'], BAND_T_K)}) Q {r['load_cycle_Q_kW']:5.2f} kW "
                f"({_inside(r['load_cycle_Q_kW'], BAND_Q_KW)})",
                flush=True,
            )
    print(f"\nbackground gap, test phase, {n} backgrounds ({time.monotonic() - started:.0f} s)")
    print(
        "Table 4 (paper): T RMSD 1.36 / 2.63 / 1.45 / 2.21 K, Q RMSD 0.37 / 0.67 / 0.30 / 0.31 kW"
    )
    print(f"band: T {BAND_T_K[0]}-{BAND_T_K[1]} K, Q {BAND_Q_KW[0]}-{BAND_Q_KW[1]} kW")
    for key, band, unit in (
        ("stationary_T_K", BAND_T_K, "K"),
        ("load_cycle_T_K", BAND_T_K, "K"),
        ("stationary_Q_kW", BAND_Q_KW, "kW"),
        ("load_cycle_Q_kW", BAND_Q_KW, "kW"),
    ):
        x = np.array([r[key] for r in rows])
        q10, q50, q90 = np.percentile(x, [10, 50, 90])
        inside = int(np.sum((x >= band[0]) & (x <= band[1])))
        print(
            f"  {key:<16} min {x.min():5.2f}  p10 {q10:5.2f}  median {q50:5.2f}  p90 {q90:5.2f}"
            f"  max {x.max():5.2f} {unit}; in band {inside}/{n}, below "
            f"{int(np.sum(x < band[0]))}, above {int(np.sum(x > band[1]))}"
        )
    both = [statistics.mean([r["stationary_T_K"], r["load_cycle_T_K"]]) for r in rows]
    print(f"  mean of both logs' T RMSD: median {statistics.median(both):.2f} K")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
