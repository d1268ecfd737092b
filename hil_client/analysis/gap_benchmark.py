"""Blind benchmark of the gap diagnosis (``hil-client gap-benchmark``).

Two "realities" write the lab logs the diagnosis sees:

- ``independent`` (default): pellet-boiler plants written from the paper without the
  emulator's model or bench (:data:`INDEPENDENT_PLANTS`; the cases alternate between
  them), each with its own controller, start-up, exchanger, return conditioning and sensor
  drifts drawn at random per case, and every listed effect in functional forms the
  diagnosis's candidates do not share;
- ``emulator``: the emulator's own plant with the ``lab`` profile (the effect at a strength
  from its documented range).

Cases are balanced: a sixth (at least one) carry no listed effect (``none``; only the
background gap), the rest cycle through the five effects and, for the independent plant,
through each effect's forms; strengths are spread evenly from barely detectable to strong;
both boilers and both log pairs alternate (the stationary test as calibration with the load
cycle held out, and the reverse). The truth goes to ``sealed/``, which the diagnosis never
reads; logs have no meta files and no phase columns.

Scoring: a case counts as right when the answer is the truth and, for an effect, its
held-out shrinkage is positive ("not confirmed" otherwise). ``scores.json`` adds the
confusion matrix, false alarms on ``none``, the median held-out shrinkage of the right
answers, the reliability table of the confidence, and why each miss missed
(:func:`miss_reason`: outranked, or short of held-out evidence, of a mark beyond its floor,
or of both).
"""

from __future__ import annotations

import csv
import importlib
import itertools
import multiprocessing as mp
import statistics
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import yaml

from hil_client.analysis.augment import EFFECTS
from hil_client.analysis.diagnose import diagnose
from hil_client.analysis.diagnosis_files import write_diagnosis
from hil_client.analysis.figures import benchmark_figure
from hil_client.analysis.logio import read_log
from hil_client.analysis.phases import find_phases
from hil_client.jsonio import strict_json
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.model.params import params_from_mapping

ANSWERS = ("none", *EFFECTS)
REALITIES = ("independent", "emulator")
BOILERS = ("windhager_6kw", "windhager_12kw")
PAIRS = (("stationary", "load_cycle"), ("load_cycle", "stationary"))  # (calibration, held out)
#: Confidence bins of the reliability table.
CONFIDENCE_BINS = (0.0, 0.5, 0.8, 0.95, 1.0000001)
#: Logged columns a real lab's CSV lacks: the diagnosis must not need them.
DROPPED_COLUMNS = ("phase", "sequence")


#: The independently written plants (each a package with the API of
#: :mod:`hil_client.reality`); the cases alternate between those present.
INDEPENDENT_PLANTS = ("hil_client.reality", "hil_client.reality2")
#: Independently written plants kept out of the default rotation: a check of how the
#: diagnosis does on plants it was not written beside (``--plant reality3`` to ``reality10``).
#: One rule was made after looking at the third to fifth (``diagnose.YIELDING``); measure a
#: new rule on a plant nobody has looked at: a rule changed to score on these makes them
#: development plants.
HELD_OUT_PLANTS = (
    "hil_client.reality3",
    "hil_client.reality4",
    "hil_client.reality5",
    "hil_client.reality6",
    "hil_client.reality7",
    "hil_client.reality8",
    "hil_client.reality9",
    "hil_client.reality10",
)


def plants_by_name() -> dict[str, str]:
    """Every independently written plant, development and held out, by its short name
    (``reality3``) -> its module."""
    return {p.rsplit(".", 1)[-1]: p for p in INDEPENDENT_PLANTS + HELD_OUT_PLANTS}


def independent_plants(names: Sequence[str] | None = None) -> list[str]:
    """The independent plants that are installed (of ``names``, default all of
    :data:`INDEPENDENT_PLANTS`)."""
    found = []
    for name in names or INDEPENDENT_PLANTS:
        try:
            importlib.import_module(name)
        except ImportError:
            continue
        found.append(name)
    return found


def make_cases(n: int, seed: int, reality: str, plants: Sequence[str] | None = None) -> list[dict]:
    """The cases' truth (see the module docstring); ``plants``: the independent plants
    the cases alternate between (default: every one installed)."""
    rng = np.random.default_rng(seed)
    n_none = max(1, round(n / 6)) if n >= 6 else (1 if n > 1 else 0)
    answers = ["none"] * n_none + [EFFECTS[i % len(EFFECTS)] for i in range(n - n_none)]
    plants = independent_plants(plants) if reality == "independent" else ["emulator"]
    if not plants:
        raise RuntimeError("no independent plant is installed (hil_client.reality)")
    seen: dict[str, int] = {}
    cases = []
    for answer in answers:
        k = seen.get(answer, 0)
        seen[answer] = k + 1
        per_effect = answers.count(answer)
        strength = (k + 0.5) / per_effect if answer != "none" else 0.0  # evenly, weak to strong
        # the k-th case of an answer: plants alternate; every 2 (4) per plant cover both
        # boilers (and both log pairs), each form meeting each boiler and each pair
        plant = plants[k % len(plants)]
        j = k // len(plants)  # the plant's j-th case of this answer
        boiler_k, pair_k = j % 2, (j // 2) % 2
        forms = _forms(plant)[answer] if answer != "none" else (None,)
        # two forms alternate so that each meets both boilers and both pairs; from the
        # plant's fifth case on (j // 4) a third and fourth form take their turns
        cases.append(
            {
                "effect": answer,
                "plant": plant,
                "form": forms[((j + j // 2) % 2 + 2 * (j // 4)) % len(forms)],
                "strength": round(strength, 3),
                "boiler": BOILERS[boiler_k],
                "pair": list(PAIRS[pair_k]),
                "seed": int(rng.integers(1, 1_000_000)),
            }
        )
    order = rng.permutation(n)
    cases = [cases[j] for j in order]
    for i, c in enumerate(cases):
        c["case"] = i
    return cases


def _forms(plant: str) -> dict[str, tuple]:
    if plant == "emulator":
        return {effect: ("lab",) for effect in EFFECTS}
    forms = importlib.import_module(plant).EFFECT_FORMS
    return {effect: tuple(forms[effect]) for effect in EFFECTS}


def _write_csv_without(columns: dict[str, np.ndarray], path: Path, writer) -> None:
    kept = {k: v for k, v in columns.items() if k not in DROPPED_COLUMNS}
    writer(kept, path)


def _independent_logs(truth: dict, case_dir: Path) -> dict[str, Path]:
    plant = importlib.import_module(truth["plant"])
    draw_background, simulate_log = plant.draw_background, plant.simulate_log
    write_log_csv = plant.write_log_csv
    boiler = yaml.safe_load((BOILER_DIR / f"{truth['boiler']}.yaml").read_text())
    rng = np.random.default_rng(truth["seed"])
    background = draw_background(rng, boiler)
    sample_s = float(rng.choice([1.0, 2.0, 5.0, 10.0]))
    jitter = bool(rng.random() < 0.3)
    logs = {}
    for test in ("stationary", "load_cycle"):
        columns, _ = simulate_log(
            boiler,
            test,
            background=background,
            effect=None if truth["effect"] == "none" else truth["effect"],
            form=truth["form"],
            strength=truth["strength"],
            seed=truth["seed"],
            sample_s=sample_s,
            jitter=jitter,
        )
        path = case_dir / f"{test}.csv"
        _write_csv_without(columns, path, write_log_csv)
        logs[test] = path
    (case_dir / "boiler.yaml").write_text(yaml.safe_dump(boiler, sort_keys=False))
    return logs


def _emulator_logs(truth: dict, case_dir: Path) -> dict[str, Path]:
    from hil_client.lablog import LabLogWriter
    from hil_client.protocol.definition import load_protocol
    from hil_client.protocol.runner import run_protocol
    from hil_client.rigs.local import LocalRig
    from rig_emulator.bench.effects import strength_ranges
    from rig_emulator.instruments import load_profile
    from rig_emulator.instruments.profile import PROFILE_DIR

    boiler = yaml.safe_load((BOILER_DIR / f"{truth['boiler']}.yaml").read_text())
    params = params_from_mapping(boiler)
    profile = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    profile["name"] = f"p{truth['case']:02d}"
    if truth["effect"] != "none":
        lo, hi = strength_ranges()[truth["effect"]]
        profile["effects"] = {truth["effect"]: {"strength": lo + truth["strength"] * (hi - lo)}}
    else:
        profile["effects"] = {}
    sealed = case_dir.parent.parent / "sealed" / f"profile_{truth['case']:02d}.yaml"
    sealed.write_text(yaml.safe_dump(profile, sort_keys=False))
    logs = {}
    for test in ("stationary", "load_cycle"):
        protocol = load_protocol(test)
        rig = LocalRig(params, load_profile(str(sealed)), seed=truth["seed"])
        path = case_dir / f"{test}.csv"
        full = case_dir / f"{test}.full.csv"
        try:
            with LabLogWriter(full) as writer:
                run_protocol(protocol, params.p_nom_kW, rig, writer)
        finally:
            rig.close()
        _strip_columns(full, path)
        full.unlink()
        logs[test] = path
    (case_dir / "boiler.yaml").write_text(yaml.safe_dump(boiler, sort_keys=False))
    return logs


def _strip_columns(src: Path, dst: Path) -> None:
    with src.open(newline="") as fin, dst.open("w", newline="") as fout:
        reader = csv.reader(fin)
        header = next(reader)
        keep = [i for i, h in enumerate(header) if h not in DROPPED_COLUMNS]
        writer = csv.writer(fout)
        writer.writerow([header[i] for i in keep])
        for row in reader:
            writer.writerow([row[i] for i in keep])


def _run_case(job: tuple[dict, str]) -> dict:
    """Worker: write both logs of one plant, then diagnose blind."""
    truth, out = job
    case_dir = Path(out) / "cases" / f"case_{truth['case']:02d}"
    case_dir.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    make = _emulator_logs if truth["plant"] == "emulator" else _independent_logs
    logs = make(truth, case_dir)
    emulated = time.monotonic() - started
    started = time.monotonic()
    cal_name, val_name = truth["pair"]
    result: dict = {}
    error = None
    try:
        cal_log, val_log = read_log(logs[cal_name]), read_log(logs[val_name])
        doc = params_from_mapping(
            yaml.safe_load((case_dir / "boiler.yaml").read_text()), str(case_dir / "boiler.yaml")
        )
        full = diagnose(cal_log, find_phases(cal_log), val_log, find_phases(val_log), doc)
        result = write_diagnosis(
            full, case_dir / "diagnosis", str(logs[cal_name]), str(logs[val_name])
        )
    except ValueError as exc:  # LogError, ParameterError: the one-line error a user would see
        error = str(exc)
    diagnosed = time.monotonic() - started
    shrink = result.get("shrinkage") or {}
    true = next((c for c in result.get("candidates", []) if c["effect"] == truth["effect"]), None)
    return {
        "case": truth["case"],
        "found": result.get("effect", "error"),
        "error": error,
        "confidence": result.get("confidence"),
        "unexplained_gap": result.get("unexplained_gap"),
        "shrink_pct": shrink.get("shrink_pct"),
        "confirmed": shrink.get("confirmed"),
        "gap_signal": shrink.get("signal"),
        "gap_phase": shrink.get("phase"),
        # what the true effect's candidate passed: named, its evidence alone, its mark alone
        "true_candidate": None
        if true is None
        else {k: true[k] for k in ("named", "evidence_named", "mark_named", "reason")},
        "emulation_s": round(emulated, 2),
        "diagnosis_s": round(diagnosed, 2),
    }


def is_right(truth: str, result: dict) -> bool:
    """Right: the true answer, and for an effect a positive held-out shrinkage."""
    if result["found"] != truth:
        return False
    return truth == "none" or bool(result.get("confirmed"))


def miss_reason(truth: str, result: dict) -> str:
    """Why a case was not right, in the terms of the diagnosis's tests: for ``none`` the
    effect named instead; for an effect, whether its candidate was named but not
    confirmed, named but outranked, or what it fell short of (its held-out evidence, its
    physical mark against its floor, or both)."""
    found = result["found"]
    if is_right(truth, result):
        return "right"
    if found == "error":
        return "error"
    if truth == "none":
        return f"false alarm: {found}"
    if found == truth:
        return "named, not confirmed on held-out data"
    cand = result.get("true_candidate") or {}
    if cand.get("named"):
        return f"named, outranked by {found}"
    evidence, mark = cand.get("evidence_named"), cand.get("mark_named")
    if evidence and not mark:
        return "evidence enough, mark below its floor"
    if mark and not evidence:
        return "mark beyond its floor, evidence short"
    return "neither evidence nor mark"


def reliability(cases: list[dict], results: list[dict]) -> list[dict]:
    """Share of right answers per confidence bin."""
    truth = {c["case"]: c["effect"] for c in cases}
    rows = []
    for lo, hi in itertools.pairwise(CONFIDENCE_BINS):
        inside = [r for r in results if r["confidence"] is not None and lo <= r["confidence"] < hi]
        right = sum(is_right(truth[r["case"]], r) for r in inside)
        rows.append(
            {
                "confidence_from": lo,
                "confidence_to": min(hi, 1.0),
                "answers": len(inside),
                "right": right,
                "share_right": right / len(inside) if inside else None,
            }
        )
    return rows


def score(cases: list[dict], results: list[dict]) -> dict:
    """Accuracy, confusion, false alarms on none, shrinkage, reliability of the confidence."""
    truth = {c["case"]: c["effect"] for c in cases}
    confusion = {t: dict.fromkeys((*ANSWERS, "error"), 0) for t in ANSWERS}
    for r in results:
        confusion[truth[r["case"]]][r["found"]] += 1
    right = [r for r in results if is_right(truth[r["case"]], r)]
    named_right = [r for r in results if r["found"] == truth[r["case"]] != "none"]
    none_cases = [r for r in results if truth[r["case"]] == "none"]
    shrinks = [r["shrink_pct"] for r in named_right if r["shrink_pct"] is not None]
    per_effect = {}
    for effect in EFFECTS:
        values = [
            r["shrink_pct"]
            for r in named_right
            if truth[r["case"]] == effect and r["shrink_pct"] is not None
        ]
        per_effect[effect] = statistics.median(values) if values else None
    confident = [r for r in results if (r["confidence"] or 0.0) >= 0.8]
    misses: dict[str, dict[str, int]] = {}
    for r in results:
        why = miss_reason(truth[r["case"]], r)
        if why != "right":
            row = misses.setdefault(truth[r["case"]], {})
            row[why] = row.get(why, 0) + 1
    return {
        "cases": len(results),
        "accuracy": len(right) / len(results) if results else 0.0,
        "false_alarms_on_none": sum(r["found"] != "none" for r in none_cases),
        "none_cases": len(none_cases),
        "not_confirmed": sum(not r.get("confirmed") for r in named_right),
        "median_validation_shrink_pct": statistics.median(shrinks) if shrinks else None,
        "negative_shrinks_on_right_effect": sum(s <= 0 for s in shrinks),
        "median_validation_shrink_pct_by_effect": per_effect,
        "confident_answers": len(confident),
        "confident_share_right": (
            sum(is_right(truth[r["case"]], r) for r in confident) / len(confident)
            if confident
            else None
        ),
        "reliability": reliability(cases, results),
        # the mean squared gap between the confidence and being right (0: perfect; a
        # constant 0.5 scores 0.25): how far the confidence means what it says
        "brier_score": (
            statistics.fmean(
                (r["confidence"] - is_right(truth[r["case"]], r)) ** 2
                for r in results
                if r["confidence"] is not None
            )
            if any(r["confidence"] is not None for r in results)
            else None
        ),
        "confusion": confusion,
        "misses": misses,
        "errors": sum(r["found"] == "error" for r in results),
        "max_diagnosis_s": max(r["diagnosis_s"] for r in results) if results else None,
        "median_diagnosis_s": statistics.median(r["diagnosis_s"] for r in results),
    }


def run_benchmark(
    n: int, seed: int, out: Path, workers: int, reality: str, plants: Sequence[str] | None = None
) -> dict:
    """Generate, diagnose and score ``n`` cases; prints progress and writes scores.json."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "sealed").mkdir(exist_ok=True)
    cases = make_cases(n, seed, reality, plants)
    (out / "sealed" / "truth.json").write_text(strict_json(cases, indent=2) + "\n")
    started = time.monotonic()
    results = []
    jobs = [(c, str(out)) for c in cases]
    ctx = mp.get_context("spawn")
    with ctx.Pool(min(workers, n)) as pool:
        for r in pool.imap_unordered(_run_case, jobs):
            results.append(r)
            c = cases[r["case"]]
            mark = "ok  " if is_right(c["effect"], r) else "MISS"
            shrink = "-" if r["shrink_pct"] is None else f"{r['shrink_pct']:.0f} %"
            conf = "-" if r["confidence"] is None else f"{r['confidence']:.2f}"
            print(
                f"[{len(results):2d}/{n}] case {r['case']:02d} {mark} truth {c['effect']:<20} "
                f"({c['form'] or '-'}, {c['strength']:.2f}, {c['boiler'][-4:]}, cal "
                f"{c['pair'][0]}) found {r['found']:<20} conf {conf} shrink {shrink} "
                f"({r['emulation_s'] + r['diagnosis_s']:.0f} s)"
                + (f" error: {r['error']}" if r["error"] else ""),
                flush=True,
            )
    wall = time.monotonic() - started
    results.sort(key=lambda r: r["case"])
    scores = score(cases, results) | {
        "reality": reality,
        "wall_s": round(wall, 1),
        "workers": workers,
        "seed": seed,
        "results": results,
    }
    (out / "scores.json").write_text(strict_json(scores, indent=2) + "\n")
    figure = benchmark_figure(scores, out / "benchmark.png")
    (out / "report.md").write_text(_report(scores, cases, figure.name))
    _print_scores(scores, n, wall)
    return scores


def _miss_lines(misses: dict[str, dict[str, int]]) -> list[str]:
    """One line per true answer: why its misses missed, with counts."""
    return [
        f"{effect}: " + "; ".join(f"{why} {n}" for why, n in sorted(row.items()))
        for effect, row in misses.items()
    ]


def _report(scores: dict, cases: list[dict], figure: str) -> str:
    """The benchmark as a readable page: figures, reliability table, every case."""
    med = scores["median_validation_shrink_pct"]
    lines = [
        f"# Gap benchmark ({scores['reality']} reality, {scores['cases']} blind cases)",
        "",
        f"- accuracy **{scores['accuracy']:.0%}** (an effect counts only with a positive "
        "held-out shrinkage)",
        f"- false alarms on `none`: {scores['false_alarms_on_none']} of {scores['none_cases']}",
        f"- named right but not confirmed on held-out data: {scores['not_confirmed']}",
        f"- median held-out shrinkage of right answers: {'-' if med is None else f'{med:.0f} %'}",
        f"- answers with confidence >= 0.8: {scores['confident_answers']}, right: "
        + (
            "-"
            if scores["confident_share_right"] is None
            else f"{scores['confident_share_right']:.0%}"
        ),
        f"- diagnosis time: median {scores['median_diagnosis_s']:.1f} s, max "
        f"{scores['max_diagnosis_s']:.1f} s; the whole benchmark {scores['wall_s']:.0f} s on "
        f"{scores['workers']} processes",
        "",
        f"![confusion and reliability]({figure})",
        "",
        "## Reliability of the confidence",
        "",
        "Brier score (the mean squared gap between the confidence and being right; 0 is "
        "perfect, a constant 0.5 scores 0.25): "
        + ("-" if scores["brier_score"] is None else f"{scores['brier_score']:.3f}"),
        "",
        "| confidence | answers | right | share right |",
        "|---|---:|---:|---:|",
    ]
    for r in scores["reliability"]:
        share = "-" if r["share_right"] is None else f"{r['share_right']:.0%}"
        lines.append(
            f"| {r['confidence_from']:.2f}-{r['confidence_to']:.2f} | {r['answers']} | "
            f"{r['right']} | {share} |"
        )
    lines += ["", "## Why the misses missed", ""]
    lines += [f"- {line}" for line in _miss_lines(scores["misses"])] or ["none missed"]
    lines += [
        "",
        "## Cases",
        "",
        "| case | truth | form | strength | boiler | calibration | found | confidence | shrink "
        "| why missed |",
        "|---:|---|---|---:|---|---|---|---:|---:|---|",
    ]
    truth = {c["case"]: c for c in cases}
    for r in scores["results"]:
        c = truth[r["case"]]
        shrink = "-" if r["shrink_pct"] is None else f"{r['shrink_pct']:.0f} %"
        conf = "-" if r["confidence"] is None else f"{r['confidence']:.2f}"
        lines.append(
            f"| {r['case']} | {c['effect']} | {c['form'] or '-'} | {c['strength']:.2f} | "
            f"{c['boiler']} | {c['pair'][0]} | {r['found']} | {conf} | {shrink} | "
            f"{miss_reason(c['effect'], r).replace('right', '-')} |"
        )
    return "\n".join(lines) + "\n"


def _print_scores(scores: dict, n: int, wall: float) -> None:
    print(
        f"\n[{scores['reality']}] accuracy {scores['accuracy']:.0%} on {n} cases; false alarms "
        f"on none: {scores['false_alarms_on_none']} of {scores['none_cases']}; named right but "
        f"not confirmed on held-out data: {scores['not_confirmed']}"
    )
    med = scores["median_validation_shrink_pct"]
    print(f"median held-out shrinkage of right answers: {'-' if med is None else f'{med:.0f} %'}")
    brier = scores["brier_score"]
    print(
        "confidence reliability (bin: right / answers; Brier score "
        f"{'-' if brier is None else f'{brier:.3f}'}):"
    )
    for row in scores["reliability"]:
        share = "-" if row["share_right"] is None else f"{row['share_right']:.0%}"
        print(
            f"  [{row['confidence_from']:.2f}, {row['confidence_to']:.2f}): "
            f"{row['right']} / {row['answers']}  ({share})"
        )
    print("confusion (rows: truth, columns: found):")
    print("  " + " " * 20 + " ".join(f"{a[:8]:>8}" for a in (*ANSWERS, "error")))
    for t in ANSWERS:
        row = scores["confusion"][t]
        print(f"  {t:<20}" + " ".join(f"{row[a]:>8}" for a in (*ANSWERS, "error")))
    print("why the misses missed (truth: reason count):")
    for line in _miss_lines(scores["misses"]):
        print(f"  {line}")
    print(
        f"time: diagnosis median {scores['median_diagnosis_s']:.1f} s, max "
        f"{scores['max_diagnosis_s']:.1f} s; {wall:.0f} s for {n} cases; written "
        "scores.json"
    )
    sys.stdout.flush()
