"""What the dashboard shows: every instrument's reading by unit, the clock, and trends.

The state is built from the server's published values (the same numbers a Modbus client
reads) and the register map (which unit holds which signal), so the page never shows a
value the wire does not. The trends keep the signals of Fig. 7 of Carlon et al. (2015) and
the balance, one sample per simulated second at most, for :data:`TREND_WINDOW_S`.
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from collections.abc import Mapping

from rig_emulator.model import constants as k
from rig_emulator.registers import RegisterMap

#: Signals drawn as trends: temperatures, heat to water, O2, balance (CONTRACT section 8).
TREND_SIGNALS = (
    "water_out_temp_C",
    "water_in_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "heat_to_water_kW",
    "flue_gas_O2_pct",
    "balance_mass_kg",
)
TREND_WINDOW_S = 12 * 3600.0
TREND_MAX_POINTS = 4000
CLOCK_MODES = {0: "real time", 1: "lockstep"}


def _finite(x: float) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


class Trend:
    """A bounded history of the trend signals against simulated time."""

    def __init__(self, window_s: float = TREND_WINDOW_S, max_points: int = TREND_MAX_POINTS):
        self.window_s = window_s
        self.step_s = window_s / max_points
        self.rows: deque[tuple[float, ...]] = deque(maxlen=max_points)

    def add(self, time_s: float, values: Mapping[str, float]) -> None:
        if self.rows and time_s < self.rows[-1][0]:
            self.rows.clear()  # the plant was reset: a new history
        if self.rows and time_s - self.rows[-1][0] < self.step_s:
            return
        self.rows.append((time_s, *(values.get(s, math.nan) for s in TREND_SIGNALS)))

    def as_dict(self, window_s: float | None = None) -> dict:
        rows = list(self.rows)
        if window_s is not None and rows:
            rows = [r for r in rows if r[0] >= rows[-1][0] - window_s]
        return {
            "time_s": [r[0] for r in rows],
            **{s: [_finite(r[i + 1]) for r in rows] for i, s in enumerate(TREND_SIGNALS)},
        }


def with_derived(values: Mapping[str, float]) -> dict[str, float]:
    """The published values plus the heat to water (Eq. 7) from flow and temperatures."""
    out = dict(values)
    with contextlib.suppress(KeyError):
        out["heat_to_water_kW"] = (
            values["water_flow_kg_h"]
            * k.CP_WATER
            * (values["water_out_temp_C"] - values["water_in_temp_C"])
            / 3600.0
        )
    return out


def units(register_map: RegisterMap, values: Mapping[str, float]) -> list[dict]:
    """Every unit with its readings (signal, value, unit of measure, access)."""
    out = []
    for dev in register_map.devices:
        readings = [
            {
                "name": p.name,
                "signal": p.signal,
                "value": _finite(values.get(p.signal, math.nan)),
                "unit": p.unit,
                "access": p.access,
            }
            for p in dev.points
        ]
        out.append(
            {
                "unit_id": dev.unit_id,
                "name": dev.name,
                "instrument": dev.instrument,
                "readings": readings,
            }
        )
    return out
