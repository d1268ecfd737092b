"""Markdown reports of the analyses (tables people read, figures people look at)."""

from __future__ import annotations

import math
from pathlib import Path

_UNITS = {"boiler_water_temp_C": "K", "heat_to_water_kW": "kW", "flue_gas_loss_kW": "kW"}
_TITLES = {
    "boiler_water_temp_C": "Water temperature inside the boiler",
    "heat_to_water_kW": "Heat transfer rate to water",
    "flue_gas_loss_kW": "Flue-gas loss",
}


def _f(x, digits: int = 3) -> str:
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{digits}f}"


def validation_report(result: dict, figures: list[Path]) -> str:
    """Table 4 of the paper for this log, the fuel comparison, and the figures."""
    metrics = result["metrics"]
    segments = list(metrics)
    lines = [
        f"# Validation of {result['boiler']} against {result['log']}",
        "",
        "Phases (from the "
        + result["phases"]["source"]
        + "): "
        + ", ".join(
            f"{k[:2]} = {v / 3600:.3f} h" for k, v in result["phases"].items() if k != "source"
        ),
        "",
        "## Model against lab (cf. Table 4)",
        "",
        "| signal | metric | " + " | ".join(segments) + " |",
        "|---|---|" + "---:|" * len(segments),
    ]
    for signal, title in _TITLES.items():
        for metric, label in (
            ("max_dev", "max. deviation"),
            ("r", "correlation r"),
            ("rmsd", "RMSD"),
        ):
            unit = f" ({_UNITS[signal]})" if metric != "r" else ""
            values = [_f(metrics[s][signal][metric]) for s in segments]
            lines.append(f"| {title} | {label}{unit} | " + " | ".join(values) + " |")
    lines += [
        "",
        "The lab's flue-gas loss is the measured flue gas's loss per kilogram (Eq. 4-6) times "
        "the fuel flow the balance gives over a centred 15-min window (it resolves no single "
        "second): around starts, stops and steep load changes that window smears the fuel "
        "flow, so part of the flue-gas loss's deviation there is the method's own (about "
        "0.4 kW RMSD in the start-up of the emulator's clean load cycle validated against "
        "its own parameters).",
        "",
        "## Cumulative fuel (as received, less ash)",
        "",
        "| segment | model (kg) | balance (kg) | deviation (%) |",
        "|---|---:|---:|---:|",
    ]
    for name, f in result["fuel"].items():
        lines.append(
            f"| {name} | {_f(f['model_kg'])} | {_f(f['balance_kg'])} | "
            f"{_f(f['deviation_pct'], 1)} |"
        )
    left_out = (result["fuel"].get("total") or {}).get("gaps_left_out_s") or 0.0
    if left_out:
        lines += [
            "",
            f"The record has gaps ({left_out / 60:.0f} min in all): what the plant burnt in "
            "them is counted on neither side (the replay does not know their inputs).",
        ]
    lines += ["", "## Figures", ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    return "\n".join(lines) + "\n"


def diagnosis_report(result: dict, figures: list[Path], cal: str, val: str) -> str:
    """A readable account of the diagnosis."""
    lines = [
        "# Sim-to-real gap diagnosis",
        "",
        f"Calibration log (fitted on): `{cal}`; validation log (held out): `{val}`.",
        "",
        *(
            [
                f"Phases from the {result['phases']['calibration']} (calibration log) and "
                f"the {result['phases']['validation']} (validation log).",
                "",
            ]
            if result.get("phases")
            else []
        ),
        f"**Unmodelled effect: `{result['effect']}`** (confidence "
        f"{result['confidence']:.2f}: the share of bootstrap draws of the evidence that "
        f"give this answer). Rule: {result['rule']}.",
        "",
    ]
    if result.get("unexplained_gap"):
        top = result["where"][0] if result["where"] else None
        lines += [
            "**A gap remains that none of the listed effects explains out of sample**"
            + (
                f"; it is largest in {top['signal']} during {top['phase']} (RMSD "
                f"{_f(top['rmsd'])})."
                if top
                else "."
            ),
            "",
        ]
    shrink = result.get("shrinkage")
    if shrink:
        verdict = "confirmed" if shrink["confirmed"] else "**not confirmed**"
        pct = shrink["shrink_pct"]
        lines += [
            f"Where the effect acts: **{shrink['signal']}**, {shrink['phase']}. With the "
            f"effect added (parameters frozen from the calibration log) the RMSD there on "
            f"the validation log goes from {_f(shrink['validation_rmsd_before'])} to "
            f"{_f(shrink['validation_rmsd_after'])}"
            + (f": {pct:.0f} % smaller" if pct is not None else "")
            + f" ({verdict} on held-out data).",
            "",
        ]
    for caveat in result.get("caveats", []):
        lines += [f"*Caveat:* {caveat}", ""]
    warnings = result.get("log_warnings") or []
    if warnings:
        lines += ["**What in the logs looks like a wrong unit or a broken sensor** (read the "
                  "answer with these in mind):", ""]  # fmt: skip
        lines += [f"- {w}" for w in warnings]
        lines.append("")
    if result.get("calibration_warnings"):
        lines += ["**What the calibration warns of:**", ""]
        lines += [f"- {w}" for w in result["calibration_warnings"]]
        lines.append("")
    if result.get("ignition_charge_kg"):
        lines += [
            f"The burner's documented ignition charge, {result['ignition_charge_kg']:g} kg as "
            "received, is fed before the flame by design: only feed beyond it is read as an "
            "ignition delay.",
            "",
        ]
    flags = result.get("calibration_flags") or {}
    if flags:
        lines += ["Calibration values kept at their documentation value:", ""]
        lines += [f"- `{key}`: {why}" for key, why in flags.items()]
        lines.append("")
    lines += [
        "## Candidates (tested out of sample on the calibration log)",
        "",
        "| effect | parameters | evidence (SE) | evidence alone names it | mark over its floor "
        "| verdict | where it acts | cal. RMSD held out before / after | val. RMSD before / "
        "after |",
        "|---|---|---:|---|---:|---|---|---|---|",
    ]
    for c in result["candidates"]:
        params = ", ".join(
            f"{k} = {'-' if v is None else format(v, '.3g')}" for k, v in c["params"].items()
        )
        lines.append(
            f"| {c['effect']} | {params} | {_f(c['score'], 1)} | "
            f"{'yes' if c.get('evidence_named') else 'no'} | {_f(c.get('margin'))} | "
            f"{c['reason']} | "
            f"{c['signal']} / {c['phase']} | {_f(c['calibration_rmsd_before'])} / "
            f"{_f(c['calibration_rmsd_after'])} | {_f(c['validation_rmsd_before'])} / "
            f"{_f(c['validation_rmsd_after'])} |"
        )
    lines += [
        "",
        "## Where the model departs from the validation log (ranked)",
        "",
        "| phase | signal | RMSD | max dev | r | bias / var / cov share | lag (s) | "
        "resid. autocorr. 1 min |",
        "|---|---|---:|---:|---:|---|---:|---:|",
    ]
    for w in result["where"]:
        lines.append(
            f"| {w['phase']} | {w['signal']} | {_f(w['rmsd'])} | {_f(w['max_dev'])} | "
            f"{_f(w['r'])} | {_f(w['bias_share'], 2)} / {_f(w['variance_share'], 2)} / "
            f"{_f(w['covariance_share'], 2)} | {_f(w['lag_s'], 0)} | "
            f"{_f(w['residual_autocorrelation_60s'], 2)} |"
        )
    lines += ["", "## Figures", ""] + [f"![{p.stem}]({p.name})" for p in figures]
    return "\n".join(lines) + "\n"
