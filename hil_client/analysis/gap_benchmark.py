"""Blind benchmark of the gap diagnosis (``hil-client gap-benchmark``).

Each case: one effect of CONTRACT section 4 (or ``none``) at a strength drawn uniformly from
its documented range (:func:`rig_emulator.bench.effects.strength_ranges`), a random boiler
(one of the two shipped sets with its lab-calibrated values moved by up to +-10 to 30 %), the
lab's instrument errors with a random seed. The emulator runs the stationary test (the
calibration log) and the load cycle (the validation log); the truth goes to ``sealed/``,
which the diagnosis never reads; the logs lose their meta files (the profile path is in
them), so the diagnosis sees CSVs only. Cases are balanced over the six answers and run on
``workers`` processes.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from hil_client.analysis.augment import EFFECTS
from rig_emulator.bench.effects import strength_ranges
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.instruments.profile import PROFILE_DIR
from rig_emulator.model.params import ParameterError, params_from_mapping

ANSWERS = ("none", *EFFECTS)
#: Lab-calibrated values of a random boiler: relative half-range of the uniform draw.
PARAMETER_SPREAD = {
    "dt_nom_K": 0.10,
    "dt_hx_wat_K": 0.30,
    "fac_a_lambda": 0.08,
    "fac_b_lambda_h_kg": 0.15,
    "ua_amb_off_W_K": 0.15,
    "ua_amb_on_W_K": 0.15,
    "w_el_Wh": 0.10,
}


def _random_boiler(base: str, rng: np.random.Generator) -> dict:
    """A shipped boiler with its lab-calibrated values moved; drawn again until the set is
    valid and burns with lambda >= 1.2 at Pmax."""
    shipped = yaml.safe_load((BOILER_DIR / f"{base}.yaml").read_text())
    while True:
        params = dict(shipped)
        for key, spread in PARAMETER_SPREAD.items():
            params[key] = round(float(params[key]) * (1 + rng.uniform(-spread, spread)), 4)
        try:
            p = params_from_mapping(params)
        except ParameterError:
            continue
        fuel_max = p.p_max_kW * 3600.0 / p.fuel.lhv_dry_kJ_kg
        if p.fac_a_lambda + p.fac_b_lambda_h_kg * fuel_max >= 1.2:
            return params


def make_cases(n: int, seed: int) -> list[dict]:
    """The cases' truth: answer, strength, boiler parameters, instrument seed."""
    rng = np.random.default_rng(seed)
    answers = [ANSWERS[i % len(ANSWERS)] for i in range(n)]
    answers = [answers[i] for i in rng.permutation(n)]
    ranges = strength_ranges()
    cases = []
    for i, answer in enumerate(answers):
        base = str(rng.choice(["windhager_6kw", "windhager_12kw"]))
        params = _random_boiler(base, rng)
        params["name"] = f"case_{i:02d}_boiler"
        strength = float(rng.uniform(*ranges[answer])) if answer != "none" else 0.0
        cases.append(
            {
                "case": i,
                "effect": answer,
                "strength": round(strength, 3),
                "base_boiler": base,
                "params": params,
                "instrument_seed": int(rng.integers(1, 1_000_000)),
            }
        )
    return cases


def _run_case(job: tuple[dict, str]) -> dict:
    """Worker: emulate both tests, then diagnose blind; returns the diagnosis summary."""
    from hil_client.cli import main as client

    truth, out = job
    out_dir = Path(out)
    case_dir = out_dir / "cases" / f"case_{truth['case']:02d}"
    sealed = out_dir / "sealed"
    case_dir.mkdir(parents=True, exist_ok=True)
    boiler = case_dir / "boiler.yaml"
    boiler.write_text(yaml.safe_dump(truth["params"], sort_keys=False))
    profile = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    profile["name"] = f"p{truth['case']:02d}"
    profile["effects"] = (
        {truth["effect"]: {"strength": truth["strength"]}} if truth["effect"] != "none" else {}
    )
    profile_file = sealed / f"p{truth['case']:02d}.yaml"
    profile_file.write_text(yaml.safe_dump(profile, sort_keys=False))
    started = time.monotonic()
    logs = {}
    for name, test in (("calibration", "stationary"), ("validation", "load_cycle")):
        log = case_dir / f"{name}.csv"
        code = client(
            [
                "run",
                test,
                "--boiler",
                str(boiler),
                "--profile",
                str(profile_file),
                "--seed",
                str(truth["instrument_seed"]),
                "--out",
                str(log),
                "--quiet",
            ]
        )
        if code != 0:
            raise RuntimeError(f"case {truth['case']}: hil-client run {test} failed")
        log.with_name(log.stem + ".meta.json").unlink()  # the meta names the profile
        logs[name] = log
    emulated = time.monotonic() - started
    started = time.monotonic()
    diag_dir = case_dir / "diagnosis"
    code = client(
        [
            "diagnose",
            "--calibration",
            str(logs["calibration"]),
            "--validation",
            str(logs["validation"]),
            "--boiler",
            str(boiler),
            "--out",
            str(diag_dir),
        ]
    )
    diagnosed = time.monotonic() - started
    result = json.loads((diag_dir / "diagnosis.json").read_text()) if code == 0 else {}
    shrink = result.get("shrinkage") or {}
    return {
        "case": truth["case"],
        "found": result.get("effect", "error"),
        "confidence": result.get("confidence"),
        "shrink_pct": shrink.get("shrink_pct"),
        "gap_signal": shrink.get("signal"),
        "gap_phase": shrink.get("phase"),
        "emulation_s": round(emulated, 2),
        "diagnosis_s": round(diagnosed, 2),
    }


def score(cases: list[dict], results: list[dict]) -> dict:
    """Accuracy, confusion matrix, false alarms on none, median shrinkage per effect."""
    truth = {c["case"]: c["effect"] for c in cases}
    confusion = {t: dict.fromkeys((*ANSWERS, "error"), 0) for t in ANSWERS}
    for r in results:
        confusion[truth[r["case"]]][r["found"]] += 1
    correct = sum(truth[r["case"]] == r["found"] for r in results)
    none_cases = [r for r in results if truth[r["case"]] == "none"]
    shrink = {}
    for effect in EFFECTS:
        values = [
            r["shrink_pct"]
            for r in results
            if truth[r["case"]] == effect and r["found"] == effect and r["shrink_pct"] is not None
        ]
        shrink[effect] = statistics.median(values) if values else None
    return {
        "cases": len(results),
        "accuracy": correct / len(results) if results else 0.0,
        "false_alarms_on_none": sum(r["found"] != "none" for r in none_cases),
        "none_cases": len(none_cases),
        "median_validation_shrink_pct": shrink,
        "confusion": confusion,
        "median_diagnosis_s": statistics.median(r["diagnosis_s"] for r in results),
        "median_case_s": statistics.median(r["emulation_s"] + r["diagnosis_s"] for r in results),
    }


def run_benchmark(n: int, seed: int, out: Path, workers: int) -> dict:
    """Generate, emulate, diagnose and score ``n`` cases; prints and writes scores.json."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "sealed").mkdir(exist_ok=True)
    cases = make_cases(n, seed)
    (out / "sealed" / "truth.json").write_text(json.dumps(cases, indent=2) + "\n")
    started = time.monotonic()
    results = []
    jobs = [(c, str(out)) for c in cases]
    ctx = mp.get_context("spawn")
    with ctx.Pool(min(workers, n)) as pool:
        for r in pool.imap_unordered(_run_case, jobs):
            results.append(r)
            truth = cases[r["case"]]["effect"]
            mark = "ok " if truth == r["found"] else "MISS"
            print(
                f"[{len(results):2d}/{n}] case {r['case']:02d} {mark} truth {truth:<20} "
                f"found {r['found']:<20} shrink {r['shrink_pct'] or 0:5.0f} %  "
                f"({r['emulation_s'] + r['diagnosis_s']:.0f} s)",
                flush=True,
            )
    wall = time.monotonic() - started
    results.sort(key=lambda r: r["case"])
    scores = score(cases, results) | {
        "wall_s": round(wall, 1),
        "workers": workers,
        "seed": seed,
        "results": results,
    }
    (out / "scores.json").write_text(json.dumps(scores, indent=2) + "\n")
    print(
        f"\naccuracy {scores['accuracy']:.0%} on {n} cases; false alarms on none: "
        f"{scores['false_alarms_on_none']} of {scores['none_cases']}"
    )
    print("median validation shrinkage where the gap lies (correctly named cases):")
    for effect, value in scores["median_validation_shrink_pct"].items():
        print(f"  {effect:<20} {'-' if value is None else f'{value:.0f} %'}")
    print("confusion (rows: truth, columns: found):")
    print("  " + " " * 20 + " ".join(f"{a[:8]:>8}" for a in ANSWERS))
    for t in ANSWERS:
        print(f"  {t:<20}" + " ".join(f"{scores['confusion'][t][a]:>8}" for a in ANSWERS))
    print(
        f"time: median {scores['median_case_s']:.0f} s per case (diagnosis "
        f"{scores['median_diagnosis_s']:.0f} s), {wall:.0f} s for {n} cases on {workers} "
        f"processes; written {out / 'scores.json'}"
    )
    sys.stdout.flush()
    return scores
