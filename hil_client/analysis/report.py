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
    lines += ["", "## Figures", ""]
    lines += [f"![{p.stem}]({p.name})" for p in figures]
    return "\n".join(lines) + "\n"
