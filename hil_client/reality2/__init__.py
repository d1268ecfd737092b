"""A second, independently written pellet-boiler plant and bench: a "reality" for the gap
benchmark (``hil-client gap-benchmark --reality independent``, issue 10).

Written from the paper (Carlon et al. 2015) and its digest, without the emulator's model,
bench or instruments and without the analysis: a stratified body (4 water and 4 steel
nodes) with the boiler sensor at one height, a controller of its own (pre-purge, ignition,
fuel ramp, staged PI with anti-windup, minimum burn and off times, restart rule), auger
pulses into a burning bed, a fan with its own lambda curve, an exchanger whose exit
temperature follows the gas flow, a bench with a capacity-limited mixing valve and its own
lags, and instruments with offsets, drifts, noise and quantisation. Each listed effect
comes in two forms of its own (:data:`EFFECT_FORMS`).

API (used by :mod:`hil_client.analysis.gap_benchmark`):

- :data:`EFFECT_FORMS`: effect name -> its form names;
- :func:`draw_background` (rng, boiler dict) -> a random real boiler and bench;
- :func:`simulate_log` (boiler, test, background=, effect=, form=, strength=, seed=,
  sample_s=, jitter=) -> (columns, meta);
- :func:`write_log_csv` (columns, path).
"""

from __future__ import annotations

import csv
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from hil_client.reality2.background import draw_background
from hil_client.reality2.effects import EFFECT_FORMS
from hil_client.reality2.plant import simulate_log

__all__ = ["EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]


def _field(value: object) -> str:
    if isinstance(value, str):
        return value
    x = float(value)  # type: ignore[arg-type]
    if not np.isfinite(x):
        return ""
    return repr(round(x, 6))


def write_log_csv(columns: Mapping[str, np.ndarray], path: str | Path) -> None:
    """Write ``columns`` as a lab-log CSV: ``time_s`` first, an empty field for NaN."""
    names = ["time_s", *[k for k in columns if k != "time_s"]]
    n = len(columns["time_s"])
    with Path(path).open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(names)
        cols = [columns[k] for k in names]
        for i in range(n):
            writer.writerow([_field(c[i]) for c in cols])
