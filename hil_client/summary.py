"""Running per-phase totals of a lab log while it is acquired (for the run summary)."""

from __future__ import annotations

import statistics
from dataclasses import dataclass, field

from hil_client.analysis.logio import REFILL_STEP_KG
from hil_client.protocol.runner import LOG_COLUMNS, Row
from rig_emulator.model.water_heat import heat_to_water_kW

_I = {name: i for i, name in enumerate(LOG_COLUMNS)}
_T, _PHASE, _MASS, _FLOW = _I["time_s"], _I["phase"], _I["balance_mass_kg"], _I["water_flow_kg_h"]
_T_IN, _T_OUT, _T_BOILER = _I["water_in_temp_C"], _I["water_out_temp_C"], _I["boiler_water_temp_C"]
_EPOCH = _I["rig_epoch"]


@dataclass(slots=True)
class PhaseTotal:
    """Totals of one phase: duration [s], heat to water (Eq. 7) [kWh], balance loss [kg]."""

    duration_s: float = 0.0
    heat_to_water_kWh: float = 0.0
    mass_start_kg: float = float("nan")
    mass_end_kg: float = float("nan")
    t_boiler_end_C: float = float("nan")
    #: rows of the phase with a balance reading
    mass_readings: int = 0
    #: the plants (``rig_epoch``) its rows came from: more than one, a break within it
    epochs: set[int] = field(default_factory=set)

    @property
    def fuel_kg(self) -> float:
        """Fuel as received less ash, from the balance, refills taken out [kg]; NaN when the
        balance read nothing in the phase (a dropout: unknown, not 0)."""
        if not self.mass_readings:
            return float("nan")
        return self.mass_start_kg - self.mass_end_kg


@dataclass(slots=True)
class RunSummary:
    """Accumulates :class:`PhaseTotal` row by row (a sink for the runner)."""

    phases: dict[str, PhaseTotal] = field(default_factory=dict)
    #: simulated time between consecutive rows [s]
    intervals_s: list[float] = field(default_factory=list)
    _t_prev: float = 0.0
    _mass_prev: float | None = None
    #: refills so far (rises of the balance between two readings), taken out of the mass
    _refilled_kg: float = 0.0
    _reading_prev: float | None = None
    #: the first time the balance read below 0 kg (the pellet store empty), None: never
    empty_at_s: float | None = None

    def __call__(self, row: Row) -> None:
        t: float = row[_T]  # type: ignore[assignment]
        dt = t - self._t_prev
        self._t_prev = t
        self.intervals_s.append(dt)
        reading: float = row[_MASS]  # type: ignore[assignment]
        if reading == reading:  # a reading (NaN: none this row)
            if reading < 0.0 and self.empty_at_s is None:
                self.empty_at_s = t
            if self._reading_prev is not None and reading - self._reading_prev > REFILL_STEP_KG:
                self._refilled_kg += reading - self._reading_prev
            self._reading_prev = reading
            mass = reading - self._refilled_kg
        else:  # the last reading stands for it (a dropout on a phase's last row)
            mass = self._mass_prev if self._mass_prev is not None else reading
        phase: str = row[_PHASE]  # type: ignore[assignment]
        total = self.phases.get(phase)
        if total is None:
            total = self.phases[phase] = PhaseTotal()
            total.mass_start_kg = self._mass_prev if self._mass_prev is not None else mass
        total.duration_s += dt
        q_water = heat_to_water_kW(row[_FLOW], row[_T_IN], row[_T_OUT])  # type: ignore[arg-type]
        total.heat_to_water_kWh += q_water * dt / 3600.0
        total.mass_end_kg = mass
        total.mass_readings += reading == reading
        total.t_boiler_end_C = row[_T_BOILER]  # type: ignore[assignment]
        total.epochs.add(int(row[_EPOCH]))  # type: ignore[call-overload]
        self._mass_prev = mass

    @property
    def median_interval_s(self) -> float | None:
        """The rows' median spacing in simulated time [s] (None before two rows)."""
        return statistics.median(self.intervals_s[1:]) if len(self.intervals_s) > 1 else None

    def table(self) -> str:
        """The totals as a text table, one line per phase."""
        lines = [
            f"{'phase':<10} {'duration':>9} {'heat to water':>14} {'fuel (balance)':>15} "
            f"{'T boiler end':>13}"
        ]
        for name, p in self.phases.items():
            h, rem = divmod(round(p.duration_s), 3600)
            fuel = f"{p.fuel_kg:>12.2f} kg" if p.fuel_kg == p.fuel_kg else f"{'-':>12}   "
            lines.append(
                f"{name:<10} {h:>3d}:{rem // 60:02d}:{rem % 60:02d} "
                f"{p.heat_to_water_kWh:>10.2f} kWh {fuel} {p.t_boiler_end_C:>11.2f} C"
            )
        for name, p in self.phases.items():  # (summed across the break without a word)
            if len(p.epochs) > 1:
                lines.append(
                    f"note: {name} spans a break of the record (rig_epoch "
                    f"{min(p.epochs)}..{max(p.epochs)}): its totals join two plants; "
                    "hil-client balance reads one"
                )
        return "\n".join(lines)
