"""Writing a lab log as CSV (CONTRACT section 3): header row, ``time_s`` first, one row per
acquisition, an empty field for a missing value (NaN), text columns as they are."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

#: Decimals per column (finer than each instrument resolves); others get 4.
DECIMALS = {
    "time_s": 3,
    "water_in_temp_C": 2,
    "water_out_temp_C": 2,
    "boiler_water_temp_C": 2,
    "flue_gas_temp_C": 1,
    "flue_gas_CO_ppm": 0,
    "balance_mass_kg": 2,
    "room_temp_C": 1,
    "boiler_on": 0,
}


def _texts(name: str, values: np.ndarray) -> list[str]:
    if values.dtype.kind in "OUS":
        return ["" if v is None else str(v) for v in values]
    x = np.asarray(values, dtype=float)
    fmt = f"%.{DECIMALS.get(name, 4)}f"
    text = np.char.mod(fmt, x).astype(object)
    text[~np.isfinite(x)] = ""
    return text.tolist()


def write_log_csv(columns: dict[str, np.ndarray], path) -> None:
    """Write ``columns`` (equal lengths, ``time_s`` among them) to ``path``."""
    if "time_s" not in columns:
        raise ValueError("write_log_csv: no time_s column")
    names = ["time_s", *[k for k in columns if k != "time_s"]]
    n = len(columns["time_s"])
    for k in names:
        if len(columns[k]) != n:
            raise ValueError(f"write_log_csv: column {k} has {len(columns[k])} rows, not {n}")
    texts = [_texts(k, np.asarray(columns[k])) for k in names]
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(names)
        w.writerows(zip(*texts, strict=True))
