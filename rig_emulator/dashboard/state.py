"""What the dashboard shows: every instrument's reading by unit, the clock, and trends.

The state is built from the values the server last published and the register map (which
unit holds which signal), each value as its registers carry it (:func:`served`: an int16
x0.1 serves 3.1, not the 3.0731 the plant had; a float32 its float32), so the page never
shows a value the wire does not. The trends keep the signals of Fig. 7 of Carlon et al.
(2015) and the balance, each as the first point of the map carrying it serves it (the heat
to water from the served flow and temperatures), over :data:`TREND_WINDOW_S` of simulated
time, in :class:`Trend`'s tiers: every sample of the recent past, older ones thinned, so
memory and ``/api/state`` stay bounded whatever the speed.
"""

from __future__ import annotations

import contextlib
import math
import struct
from collections import deque
from collections.abc import Iterable, Mapping
from decimal import Decimal

import numpy as np

from rig_emulator.model import constants as k
from rig_emulator.registers import Point, RegisterMap, decode, encode, invalid_value
from rig_emulator.registers.datatypes import DATATYPES

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
#: The derived trend signal, and the served signals it is computed from (Eq. 7).
HEAT_SOURCES = ("water_flow_kg_h", "water_out_temp_C", "water_in_temp_C")
TREND_WINDOW_S = 12 * 3600.0
#: The trend's tiers, newest first: (points kept, least simulated time between two). The
#: newest tier takes every sample (the dashboard samples twice a wall second, each real-time
#: tick at high speed, and inside a lockstep advance), so the recent past is at full
#: resolution at any speed; the next keep one point per 5 s for the last hour, one per 30 s
#: for 12 h. At most 2760 points in memory and in a ``/api/state``.
TREND_TIERS = ((600, 0.0), (720, 5.0), (1440, 30.0))
CLOCK_MODES = {0: "real time", 1: "lockstep"}


def _finite(x: float) -> float | None:
    return float(x) if isinstance(x, int | float) and math.isfinite(x) else None


def decimals(point: Point) -> int | None:
    """How many decimals a scaled integer point carries (x0.01: 2; x2: 0); None for a float
    or a bit, whose registers carry no fixed step."""
    datatype = DATATYPES[point.datatype]
    if datatype.is_float or datatype.is_bit:
        return None
    exponents = [
        Decimal(repr(float(x))).normalize().as_tuple().exponent for x in (point.scale, point.offset)
    ]
    return max(0, *(-e for e in exponents if isinstance(e, int)))


def served(point: Point, value: float) -> float | None:
    """``value`` as ``point``'s registers carry it (what a client decodes): a scaled
    integer rounded to its step and saturated at its type's range, a float32 to float32
    (its shortest decimal, 118.70835 not 118.70835113525391); None for no reading (NaN, an
    integer's invalid code)."""
    if not isinstance(value, int | float) or math.isnan(value):
        return None
    try:
        carried = decode(point, encode(point, value))
    except (OverflowError, struct.error):  # beyond a float type: served as infinity
        return None
    if not math.isfinite(carried) or carried == invalid_value(point):
        return None
    places = decimals(point)
    if places is not None:
        return round(carried, places)
    if DATATYPES[point.datatype].code == "f":  # the shortest decimal of the float32
        return float(str(np.float32(carried)))
    return carried


def units(register_map: RegisterMap, values: Mapping[str, float]) -> list[dict]:
    """Every unit with its readings (point name, signal, value as served, unit of measure,
    access, decimals the point carries)."""
    return [
        {
            "unit_id": dev.unit_id,
            "name": dev.name,
            "instrument": dev.instrument,
            "readings": [
                {
                    "name": p.name,
                    "signal": p.signal,
                    "value": served(p, values.get(p.signal, math.nan)),
                    "unit": p.unit,
                    "access": p.access,
                    "decimals": decimals(p),
                }
                for p in dev.points
            ],
        }
        for dev in register_map.devices
    ]


def trend_points(register_map: RegisterMap) -> dict[str, Point]:
    """The point whose registers each trend signal (and the heat's sources) is drawn from:
    the first in the map that carries it (a signal no point carries is not drawn)."""
    wanted = set(TREND_SIGNALS) | set(HEAT_SOURCES)
    out: dict[str, Point] = {}
    for dev in register_map.devices:
        for p in dev.points:
            if p.signal in wanted:
                out.setdefault(p.signal, p)
    return out


def trend_values(
    points: Mapping[str, Point], values: Mapping[str, float], hidden: Iterable[str] = ()
) -> dict[str, float | None]:
    """The trend signals as served (None: not on the wire, no reading, or ``hidden``), and
    the heat to water (Eq. 7) from the served flow and temperatures."""
    skip = set(hidden)
    out: dict[str, float | None] = {
        s: None if s in skip else served(p, values.get(s, math.nan)) for s, p in points.items()
    }
    out["heat_to_water_kW"] = None
    with contextlib.suppress(KeyError, TypeError):
        out["heat_to_water_kW"] = round(
            out["water_flow_kg_h"]  # type: ignore[operator]
            * k.CP_WATER
            * (out["water_out_temp_C"] - out["water_in_temp_C"])  # type: ignore[operator]
            / 3600.0,
            4,  # 0.1 W: finer than any served temperature difference carries
        )
    return out


_Row = tuple[float, ...]


class Trend:
    """A bounded history of the trend signals against simulated time, in
    :data:`TREND_TIERS`: each sample goes to the newest tier and, if far enough after that
    tier's last point, to each older one; a history is read back newest tier first. One
    history per plant ``run`` (the server's reset count): a sample of another run starts a
    new history."""

    def __init__(self, tiers: tuple[tuple[int, float], ...] = TREND_TIERS) -> None:
        self.tiers = [(deque[_Row](maxlen=size), step_s) for size, step_s in tiers]
        self.added = 0  # samples taken so far (a stream sends those since its last event)
        self.run = 0  # the plant run the history is of

    @property
    def last_time_s(self) -> float:
        newest = self.tiers[0][0]
        return newest[-1][0] if newest else -math.inf

    def add(self, time_s: float, values: Mapping[str, float | None], run: int = 0) -> None:
        """Take a sample at simulated ``time_s`` of plant ``run``: of another run than the
        history's, a new history (the plant was reset); of the same run, one no later than
        the last is dropped (a look at what was published before an advance, taken while
        the advance runs, is older than the samples taken inside it: read as a reset, it
        wiped the history, a re-probe)."""
        if run != self.run:
            for rows, _ in self.tiers:
                rows.clear()
            self.run = run
        elif time_s <= self.last_time_s:
            return
        row = (time_s, *(_nan(values.get(s)) for s in TREND_SIGNALS))
        for rows, step_s in self.tiers:
            if not rows or time_s - rows[-1][0] >= step_s:
                rows.append(row)
        self.added += 1

    def _rows(self) -> list[_Row]:
        out: list[_Row] = []
        until = math.inf
        for rows, _ in self.tiers:  # newest tier first; each older one before its start
            older = [r for r in rows if r[0] < until]
            out[:0] = older
            if rows:
                until = min(until, rows[0][0])
        return out

    def as_dict(self, window_s: float | None = None) -> dict:
        """The history (``window_s``: its last so many simulated seconds) as lists."""
        rows = self._rows()
        if window_s is not None and rows:
            rows = [r for r in rows if r[0] >= rows[-1][0] - window_s]
        return _columns(rows)

    def since(self, added: int) -> dict:
        """The samples taken after the first ``added`` (as many as the newest tier holds)."""
        newest = self.tiers[0][0]
        count = min(self.added - added, len(newest))
        return _columns(list(newest)[len(newest) - count :] if count > 0 else [])


def _nan(x: float | None) -> float:
    return math.nan if x is None else float(x)


def _columns(rows: list[_Row]) -> dict:
    return {
        "time_s": [r[0] for r in rows],
        **{s: [_finite(r[i + 1]) for r in rows] for i, s in enumerate(TREND_SIGNALS)},
    }
