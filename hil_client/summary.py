"""Running per-phase totals of a lab log while it is acquired (for the run summary).

A missing reading (an empty field: NaN; an infinite one alike) is skipped, as ``hil-client
balance`` does, never summed: one missing forward temperature made a phase's heat to water
``nan kWh`` (a stranger's probe); the table says how many rows a phase's heat left out.
A balance reading below 0 kg is the pellet store run empty only when the next reading stays
at or below 0; one glitch between plausible readings (0xFFFFFFFF of an int32 x0.001, -0.001
kg, between 180-kg readings) is no reading (it was "the pellet store ran empty", and the
rise back to 180 kg a refill).
"""

from __future__ import annotations

import math
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
    #: rows of the phase, and those of them without the flow, return or forward reading
    #: (their heat to water left out of the sum)
    rows: int = 0
    heat_missing: int = 0
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
    #: the first time the balance read below 0 kg and stayed at or below 0 (the pellet
    #: store empty), None: never
    empty_at_s: float | None = None
    #: when a reading below 0 kg came that the next reading has yet to confirm, None: none
    _below_at_s: float | None = None

    def __call__(self, row: Row) -> None:
        t: float = row[_T]  # type: ignore[assignment]
        dt = t - self._t_prev
        self._t_prev = t
        self.intervals_s.append(dt)
        reading = self._balance(t, row[_MASS])  # type: ignore[arg-type]
        if reading == reading:  # a reading (NaN: none this row)
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
        total.rows += 1
        q_water = heat_to_water_kW(row[_FLOW], row[_T_IN], row[_T_OUT])  # type: ignore[arg-type]
        if math.isfinite(q_water):
            total.heat_to_water_kWh += q_water * dt / 3600.0
        else:
            total.heat_missing += 1
        total.mass_end_kg = mass
        total.mass_readings += reading == reading
        t_boiler: float = row[_T_BOILER]  # type: ignore[assignment]
        if math.isfinite(t_boiler):  # (the last reading of the phase)
            total.t_boiler_end_C = t_boiler
        total.epochs.add(int(row[_EPOCH]))  # type: ignore[call-overload]
        self._mass_prev = mass

    def _balance(self, t: float, reading: float) -> float:
        """The balance's reading of the row at ``t`` as the totals take it: NaN for none
        (an infinite one; one below 0 kg until the next reading stays at or below 0, which
        makes :attr:`empty_at_s` the time of the first; a glitch if it does not)."""
        if not math.isfinite(reading):
            return math.nan
        below_at, self._below_at_s = self._below_at_s, None
        if reading > 0.0 or self.empty_at_s is not None:
            return reading
        if below_at is not None:  # the second reading at or below 0 in a row: empty
            self.empty_at_s = below_at
            return reading
        if reading < 0.0:  # to be confirmed by the next reading
            self._below_at_s = t
            return math.nan
        return reading

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
            heat = p.heat_to_water_kWh if p.heat_missing < p.rows else math.nan
            lines.append(
                f"{name:<10} {h:>3d}:{rem // 60:02d}:{rem % 60:02d} "
                f"{_cell(heat, 10, 'kWh')} {_cell(p.fuel_kg, 12, 'kg')} "
                f"{_cell(p.t_boiler_end_C, 11, 'C')}"
            )
        for name, p in self.phases.items():  # (the sum is short of what they held)
            if p.heat_missing:
                lines.append(
                    f"note: {name}: heat to water leaves out {p.heat_missing} of its {p.rows} "
                    "rows (no flow, return or forward reading)"
                )
        for name, p in self.phases.items():  # (summed across the break without a word)
            if len(p.epochs) > 1:
                lines.append(
                    f"note: {name} spans a break of the record (rig_epoch "
                    f"{min(p.epochs)}..{max(p.epochs)}): its totals join two plants; "
                    "hil-client balance reads one"
                )
        return "\n".join(lines)


def _cell(value: float, width: int, unit: str) -> str:
    """``value`` with two decimals and its unit, or "-" where it is unknown (NaN, or not
    finite): the table never prints nan or inf."""
    if not math.isfinite(value):
        return f"{'-':>{width}} {' ' * len(unit)}"
    return f"{value:>{width}.2f} {unit}"
