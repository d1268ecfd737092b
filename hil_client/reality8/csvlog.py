"""Lab-log columns (CONTRACT section 3) and the CSV writer."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

COLUMNS: tuple[str, ...] = (
    "time_s", "phase", "sequence", "water_flow_kg_h", "water_in_temp_C", "water_out_temp_C",
    "boiler_water_temp_C", "flue_gas_temp_C", "flue_gas_O2_pct", "flue_gas_CO2_pct",
    "flue_gas_CO_ppm", "flue_gas_velocity_m_s", "chimney_draught_Pa", "balance_mass_kg",
    "room_temp_C", "ambient_pressure_hPa", "relative_humidity_pct", "electric_power_W",
    "water_flow_setpoint_kg_h", "boiler_on",
)  # fmt: skip


def _fmt(v: object) -> str:
    if v is None:
        return ""
    if isinstance(v, str):
        return v
    if isinstance(v, int | np.integer):
        return str(int(v))
    x = float(v)  # type: ignore[arg-type]
    if math.isnan(x):
        return ""
    return repr(round(x, 6))


def write_log_csv(columns: dict, path: str | Path) -> None:
    """Header row, one row per acquisition, missing value (None/NaN) as an empty field."""
    names = [c for c in COLUMNS if c in columns] + [c for c in columns if c not in COLUMNS]
    n = len(columns[names[0]])
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        cols = [columns[c] for c in names]
        for i in range(n):
            w.writerow([_fmt(col[i]) for col in cols])
