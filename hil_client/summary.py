"""Running per-phase totals of a lab log while it is acquired (for the run summary)."""

from __future__ import annotations

from dataclasses import dataclass, field

from rig_emulator.model.constants import CP_WATER

from hil_client.protocol.runner import LOG_COLUMNS, Row

_I_T = LOG_COLUMNS.index("time_s")
_I_PHASE = LOG_COLUMNS.index("phase")
_I_FLOW = LOG_COLUMNS.index("water_flow_kg_h")
_I_TIN = LOG_COLUMNS.index("water_in_temp_C")
_I_TOUT = LOG_COLUMNS.index("water_out_temp_C")
_I_MASS = LOG_COLUMNS.index("balance_mass_kg")
_I_TBOIL = LOG_COLUMNS.index("boiler_water_temp_C")


@dataclass(slots=True)
class PhaseTotal:
    duration_s: float = 0.0
    heat_to_water_kWh: float = 0.0
    fuel_kg: float = 0.0  # balance loss (as received, less ash)
    t_boiler_end_C: float = float("nan")
    _mass_start: float | None = None


@dataclass(slots=True)
class RunSummary:
    """Per-phase duration, heat to water (Eq. 7) and balance loss, accumulated row by row."""

    phases: dict[str, PhaseTotal] = field(default_factory=dict)
    _t_prev: float = 0.0
    _mass_prev: float | None = None

    def __call__(self, row: Row) -> None:
        t = float(row[_I_T])  # type: ignore[arg-type]
        dt = t - self._t_prev
        self._t_prev = t
        total = self.phases.get(row[_I_PHASE])  # type: ignore[arg-type]
        if total is None:
            total = self.phases[row[_I_PHASE]] = PhaseTotal()  # type: ignore[index]
            total._mass_start = self._mass_prev if self._mass_prev is not None else row[_I_MASS]  # type: ignore[assignment]
        mass = float(row[_I_MASS])  # type: ignore[arg-type]
        total.duration_s += dt
        total.heat_to_water_kWh += (
            float(row[_I_FLOW]) * CP_WATER * (float(row[_I_TOUT]) - float(row[_I_TIN]))  # type: ignore[arg-type]
            / 3600.0 * dt / 3600.0
        )
        total.fuel_kg = (total._mass_start or mass) - mass
        total.t_boiler_end_C = float(row[_I_TBOIL])  # type: ignore[arg-type]
        self._mass_prev = mass

    def table(self) -> str:
        lines = [f"{'phase':<10} {'duration':>9} {'heat to water':>14} {'fuel (balance)':>15} "
                 f"{'T boiler end':>13}"]
        for name, p in self.phases.items():
            h, rem = divmod(int(round(p.duration_s)), 3600)
            lines.append(
                f"{name:<10} {h:>3d}:{rem // 60:02d}:{rem % 60:02d} {p.heat_to_water_kWh:>10.2f} kWh"
                f" {p.fuel_kg:>12.2f} kg {p.t_boiler_end_C:>11.2f} C"
            )
        return "\n".join(lines)
