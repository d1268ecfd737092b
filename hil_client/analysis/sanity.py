"""What in a lab log looks like a wrong unit or a broken sensor rather than a boiler: one
warning line each, naming the file, the column and the figure, for every analysis.

Real logs come with their units mixed up and their sensors stuck, and an analysis run on
them ends in confident, absurd figures (a direct efficiency of 1.3 % from a flow logged
in l/min; a fuel 237 % richer than nominal behind a forward sensor stuck at 60 C). The
readings stay as they are, since a warning cannot know the right unit; what it says is
where to look. What no boiler's bench can read (temperatures in kelvin, oxygen as a
fraction, heat to the water under 20 % or over 150 % of the fuel's energy) is refused
instead (:func:`refuse_wrong_units`):

- a time that advances minutes per row (milliseconds?);
- a water or room temperature whose median is that of water or air in kelvin, a flue
  gas that never reads below 250 C;
- oxygen above air's, or read as a fraction rather than vol-%;
- a temperature or the oxygen that never moves in a log where the boiler burns fuel;
- a flow that is negative through most of the log;
- heat to the water that is not 35-110 % of the energy of the fuel the balance lost
  while the boiler fired (a boiler's direct efficiency, Eq. 7 against the balance and the
  nominal calorific value; the water's stored heat counted);
- a balance that gains mass, or loses more than a bed's burn-out, while the burner is
  off, or ends the firing heavier than it began it (refills taken out first).
"""

from __future__ import annotations

import numpy as np

from hil_client.analysis.firing import observe_firing
from hil_client.analysis.logio import LabLog, LogError, fill_gaps, noisy_balance
from rig_emulator.model.params import BoilerParams
from rig_emulator.model.water_heat import heat_to_water_kW

#: Water inside, into and out of the boiler, and the room, as a lab reads them [C]; a
#: median above these is water or air in kelvin (273.15 K is 0 C).
WATER_MEDIAN_MAX_C = 150.0


ROOM_MEDIAN_MAX_C = 60.0


KELVIN_OFFSET = 273.15


#: A pellet boiler's flue gas leaves at 80-250 C while it fires and cools to the room's
#: when it does not; one whose lowest twentieth is above this [C] is in kelvin.
FLUE_GAS_LOW_MAX_C = 250.0


#: Air's oxygen [vol-%, dry] and how far above it an analyser's zero and span may read.
O2_AIR_PCT = 20.95


O2_ABOVE_AIR_PCT = 0.5


#: A boiler's direct efficiency, heat to water over the fuel's energy at the nominal
#: calorific value [-]: the paper's boilers reach 85 % at nominal load, a cold start or a
#: long stand-by far less; below or above this band the flow, the temperatures or the
#: balance are in another unit (a flow in l/min reads 1/60 of the heat).
DIRECT_EFFICIENCY_RANGE = (0.35, 1.10)


#: The least fuel [kg] the efficiency is read over: fifty steps of the balance, some
#: twenty minutes at a 12-kW boiler's full load (a start-up alone stores much of its heat
#: in metal the one capacity does not hold).
CLOSURE_FUEL_MIN_KG = 1.0


#: A balance that gains more than this [kg] over a stretch of at least
#: :data:`QUIET_STRETCH_MIN_S` with the burner off drifts: the fuel only leaves.
QUIET_GAIN_MAX_KG = 0.1


QUIET_STRETCH_MIN_S = 1800.0


#: ... or loses more than this [kg] over such a stretch, from :data:`BURN_OUT_S` after the
#: burner stopped (the bed burns out meanwhile, and leaves as gas: a tenth of a kilogram).
QUIET_LOSS_MAX_KG = 0.3


BURN_OUT_S = 900.0


#: A log whose median step is longer than this [s] is in other units than seconds: a lab
#: logs every 1-10 s (CONTRACT section 4), a coarse export every minute.
TIME_STEP_MAX_S = 120.0


#: A column that never moves over at least this many readings is stuck [-].
STUCK_MIN_READINGS = 100


_WATER = ("water_in_temp_C", "water_out_temp_C", "boiler_water_temp_C")
_MUST_MOVE = ("water_out_temp_C", "boiler_water_temp_C", "flue_gas_temp_C", "flue_gas_O2_pct")


def _readings(log: LabLog, name: str) -> np.ndarray:
    if name not in log.columns:
        return np.array([])
    x = log[name]
    return x[np.isfinite(x)]


def _temperatures(log: LabLog, kelvin: bool | None = None) -> list[str]:
    """Water and room medians above what a lab reads; ``kelvin`` True: only those that are
    kelvin's (refused), False: only the others (warned), None: all."""
    out = []
    for name, limit in [
        *((n, WATER_MEDIAN_MAX_C) for n in _WATER),
        ("room_temp_C", ROOM_MEDIAN_MAX_C),
    ]:
        x = _readings(log, name)
        if not len(x):
            continue
        median = float(np.median(x))
        if median > limit:
            like = -30.0 < median - KELVIN_OFFSET < limit
            if kelvin is None or kelvin == like:
                said = ": kelvin? convert to C" if like else ""
                out.append(f"column '{name}' reads a median of {median:.1f} C{said}")
    return out


def _flue_gas(log: LabLog, kelvin: bool | None = None) -> list[str]:
    x = _readings(log, "flue_gas_temp_C")
    if len(x) >= STUCK_MIN_READINGS and float(np.percentile(x, 5)) > FLUE_GAS_LOW_MAX_C:
        low = float(np.percentile(x, 5))
        like = low - KELVIN_OFFSET < FLUE_GAS_LOW_MAX_C
        if kelvin is None or kelvin == like:
            said = ": kelvin? convert to C" if like else ""
            return [f"column 'flue_gas_temp_C' never reads below {low:.0f} C{said}"]
    return []


def _oxygen(log: LabLog) -> list[str]:
    x = _readings(log, "flue_gas_O2_pct")
    if not len(x):  # (validate and diagnose said nothing of it: a stranger's probe)
        return (
            [
                "column 'flue_gas_O2_pct' has no readings: lambda, the flue-gas loss and the "
                "burner's firing seen by the analyser are unknown"
            ]
            if "flue_gas_O2_pct" in log.columns
            else []
        )
    top = float(np.max(x))
    above = float(np.mean(x > O2_AIR_PCT + O2_ABOVE_AIR_PCT))
    if above > 0.01:
        return [
            f"column 'flue_gas_O2_pct' reads above air's {O2_AIR_PCT} vol-% in {above:.0%} of"
            f" its readings (up to {top:.2f}): an offset, or another unit?"
        ]
    return _o2_fraction(log)


#: The least top reading [vol-%] of an oxygen column read as a fraction (refused): air is
#: 0.21 of it, a firing boiler's flue gas 0.05-0.15; a column that stays below it (a dead
#: analyser's zero, a constant 0) is data, not a fraction.
O2_FRACTION_TOP_MIN = 0.05


def _o2_fraction(log: LabLog) -> list[str]:
    """Oxygen read as a fraction of one (every reading at most 1, moving): the firing seen
    by the analyser (O2 under 16 vol-%) was all the log, lambda 1.0, and every analysis
    gave its results (a stranger's probe)."""
    x = _readings(log, "flue_gas_O2_pct")
    if len(x) < STUCK_MIN_READINGS:
        return []
    top = float(np.max(x))
    if O2_FRACTION_TOP_MIN <= top <= 1.0 and float(np.ptp(x)) > 0.0:
        return [
            f"column 'flue_gas_O2_pct' reads at most {top:.3g}: a fraction, not vol-%"
            f" (air is {O2_AIR_PCT}); multiply by 100"
        ]
    return []


def _fuel_lost_kg(log: LabLog) -> float:
    if "balance_mass_kg" not in log.columns:
        return float("nan")
    mass = log.balance_without_refills()
    x = mass[np.isfinite(mass)]
    return float(x[0] - x[-1]) if len(x) >= 2 else float("nan")


def _stuck(log: LabLog) -> list[str]:
    if not _fuel_lost_kg(log) > CLOSURE_FUEL_MIN_KG:
        return []  # a boiler that burns nothing may hold its temperatures
    out = []
    for name in _MUST_MOVE:
        x = _readings(log, name)
        if len(x) >= STUCK_MIN_READINGS and float(np.ptp(x)) == 0.0:
            out.append(
                f"column '{name}' reads {x[0]:g} throughout while the boiler burns fuel:"
                " a stuck sensor?"
            )
    return out


#: Readings of the flow below this share of its largest magnitude are a standstill's, the
#: meter's zero (-0.3 kg/h over two hours of second cooling made the whole log's median
#: negative, and a good log was refused: a re-probe); the flow's sign is read from the rest.
FLOW_STANDSTILL_SHARE = 0.05


def _flow(log: LabLog) -> list[str]:
    x = _readings(log, "water_flow_kg_h")
    if not len(x):
        return []
    moving = x[np.abs(x) > FLOW_STANDSTILL_SHARE * float(np.max(np.abs(x)))]
    if len(moving) and float(np.median(moving)) < 0.0:
        return [
            f"column 'water_flow_kg_h' reads a median of {float(np.median(moving)):.1f} kg/h"
            " while the water moves: negative (the meter's direction, or its sign?)"
        ]
    return []


def refuse_reversed_flow(log: LabLog) -> None:
    """Refuse a log whose water flow reads negative most of the time (:func:`_flow`): the
    model fed a flow that runs backwards through the boiler diverged, and ``validate``
    wrote a Table 4 of 1e42 K with exit 0 (a stranger's probe); the energy balance read a
    negative heat to water. A few negative readings (a meter's zero in a standstill) are
    data."""
    found = _flow(log)
    if found:
        raise LogError(f"{log.path}: {found[0]}; correct the column's sign and analyse again")


def refuse_wrong_units(log: LabLog, params: BoilerParams | None = None) -> None:
    """Refuse a log in one line where a column is in a unit no boiler's bench reads: water,
    room or flue-gas temperatures in kelvin, oxygen as a fraction, heat to the water
    outside :data:`DIRECT_EFFICIENCY_REFUSED` of the fuel's energy (with ``params``). Each
    gave ten warnings and then confident results with exit 0 (a stranger's probes); what
    only looks odd stays a warning (:func:`suspicious`)."""
    found = [*_temperatures(log, kelvin=True), *_flue_gas(log, kelvin=True), *_o2_fraction(log)]
    if not found and params is not None:
        found = _closure_refused(log, params, observe_firing(log).burning)
        # a time in minutes reads the heat 1/60 too: the fuel's rate says so (the flow
        # was blamed: a re-probe)
        found = (_fuel_rate(log, params) or found) if found else found
    if found:
        raise LogError(f"{log.path}: {found[0]}")


#: The most the balance may lose over the record, over what the boiler burns at full power
#: for as long (its start-up's Pstart is at most 1.5 Pmax; the balance's steps add little)
FUEL_RATE_MAX_FACTOR = 2.0


def _fuel_rate(log: LabLog, params: BoilerParams) -> list[str]:
    """The balance losing more over the record than the boiler could burn firing at full
    power throughout: a time in minutes read as seconds gave 847 kW of a 12-kW boiler
    with no word (a re-probe)."""
    fuel_kg = _fuel_lost_kg(log)
    span_h = float(log.t[-1] - log.t[0]) / 3600.0 if len(log) > 1 else 0.0
    if not (fuel_kg > CLOSURE_FUEL_MIN_KG and span_h > 0):
        return []
    fuel = params.fuel
    full_kg_h = params.p_max_kW / fuel.hhv_dry_kJ_kg * 3600.0 * fuel.balance_loss_per_kg_dry
    rate = fuel_kg / span_h
    if rate <= FUEL_RATE_MAX_FACTOR * full_kg_h:
        return []
    return [
        f"the balance loses {fuel_kg:.3g} kg in {span_h * 3600:.4g} s, {rate:.3g} kg/h, "
        f"{rate / full_kg_h:.0f} times what the boiler burns at full power ({full_kg_h:.2f} "
        "kg/h): is time_s in seconds (not minutes), and the balance in kg?"
    ]


#: Heat to the water over the fuel's energy [-] beyond which no boiler can be, refused
#: rather than warned (:data:`DIRECT_EFFICIENCY_RANGE` is warned): over more than
#: :data:`CLOSURE_FUEL_MIN_KG` of fuel (18 MJ at least), the most a boiler's metal can
#: store beyond the water counted (some 300 kg of steel warmed 50 K, 7 MJ) and its worst
#: flue-gas and stand-by losses (30 %) leave over 20 % of the fuel's energy to the water;
#: and no boiler gives the water more than the fuel's energy at its higher calorific value
#: (108 % of the lower one for wood) and what the metal gives back (some 40 % of 18 MJ), so
#: never 150 %. Beyond them the flow is in another unit (l/min reads 1/60 of the heat,
#: m3/h 1/1000, g/s 3.6 times), or the temperatures or the balance are.
DIRECT_EFFICIENCY_REFUSED = (0.20, 1.50)


def _efficiency(log: LabLog, params: BoilerParams, burning: np.ndarray) -> tuple[float, float]:
    """(heat to water over the fuel's energy [-], the fuel [kg]) from the first firing row
    to the last (the preheat's bench-heated water and a stand-by's losses are no part of
    it: a clean run of a short part-load test read 19 % over the whole log), the water's
    stored heat counted; NaN where it cannot be read or the fuel is not over
    :data:`CLOSURE_FUEL_MIN_KG`."""
    nan = (float("nan"), float("nan"))
    if "balance_mass_kg" not in log.columns:
        return nan
    t = log.t
    firing = np.flatnonzero(burning)
    if len(firing) < 2:
        return nan
    span = slice(int(firing[0]), int(firing[-1]) + 1)
    mass = log.balance_without_refills()[span]
    rows = np.flatnonzero(np.isfinite(mass))
    if len(rows) < 2:
        return nan
    # the heat over the readings' own span: a balance whose readings stop (stuck to the
    # end, their readings none) was set against the heat of the whole firing (486 %, a
    # stranger's probe)
    span = slice(span.start + int(rows[0]), span.start + int(rows[-1]) + 1)
    fuel_kg = float(mass[rows[0]] - mass[rows[-1]])
    if not fuel_kg > CLOSURE_FUEL_MIN_KG:
        return nan
    ts = t[span]
    q = heat_to_water_kW(
        np.clip(fill_gaps(log["water_flow_kg_h"], t)[span], 0.0, None),
        fill_gaps(log["water_in_temp_C"], t)[span],
        fill_gaps(log["water_out_temp_C"], t)[span],
    )
    water = fill_gaps(log["boiler_water_temp_C"], t)[span]
    ok = np.isfinite(q)
    both = ok[1:] & ok[:-1]
    if both.sum() < 2 or not np.isfinite(water[[0, -1]]).all():
        return nan
    heat_kJ = float(np.sum((0.5 * (q[1:] + q[:-1]) * np.diff(ts))[both]))
    heat_kJ += params.c_therm_kJ_K * float(water[-1] - water[0])
    fuel = params.fuel
    energy_kJ = fuel_kg / fuel.balance_loss_per_kg_dry * fuel.lhv_dry_kJ_kg
    return heat_kJ / energy_kJ, fuel_kg


def _closure_line(
    eta: float, fuel_kg: float, band: tuple[float, float], what: str, flow: str = "kg/h"
) -> str:
    low, high = band
    return (
        f"the heat to the water is {eta:.0%} of the energy of the {fuel_kg:.2f} kg of fuel"
        f" the balance lost while the boiler fired ({low:.0%}-{high:.0%} {what}): is"
        f" the flow in {flow}, are the forward and return temperatures right, and is the"
        " balance in kg?"
    )


def _closure(log: LabLog, params: BoilerParams, burning: np.ndarray) -> list[str]:
    """Heat to water over the fuel's energy outside :data:`DIRECT_EFFICIENCY_RANGE`
    (:func:`_efficiency`)."""
    eta, fuel_kg = _efficiency(log, params, burning)
    low, high = DIRECT_EFFICIENCY_RANGE
    if not np.isfinite(eta) or low <= eta <= high:
        return []
    return [_closure_line(eta, fuel_kg, DIRECT_EFFICIENCY_RANGE, "for a boiler")]


def _closure_refused(log: LabLog, params: BoilerParams, burning: np.ndarray) -> list[str]:
    """Heat to water over the fuel's energy outside :data:`DIRECT_EFFICIENCY_REFUSED`,
    where the flow and the water temperatures move (a flow that reads zero or one value
    throughout is data: CONTRACT section 4)."""
    for name in ("water_flow_kg_h", "water_in_temp_C", "water_out_temp_C"):
        x = _readings(log, name)
        if len(x) < 2 or float(np.ptp(x)) == 0.0:
            return []
    eta, fuel_kg = _efficiency(log, params, burning)
    low, high = DIRECT_EFFICIENCY_REFUSED
    if not np.isfinite(eta) or low <= eta <= high:
        return []
    line = _closure_line(
        eta, fuel_kg, DIRECT_EFFICIENCY_REFUSED, "for any boiler", "kg/h (not l/min)"
    )
    # the column at fault, where the readings tell (the flow was named for temperatures
    # swapped or in Fahrenheit: a stranger's probe)
    forward = float(np.median(_readings(log, "water_out_temp_C")))
    if forward > WATER_BOILS_C:  # (before the sign: the two in Fahrenheit beside a boiler
        return [  # water in C read negative, and "swapped?": a re-probe)
            f"column 'water_out_temp_C': {line} (it reads a median of {forward:.4g}, above "
            "boiling: Fahrenheit? convert to C)"
        ]
    if eta < 0.0:
        return [
            f"columns 'water_in_temp_C' and 'water_out_temp_C': {line} (the return reads "
            "warmer than the forward while the boiler fires: swapped?)"
        ]
    return [f"column 'water_flow_kg_h': {line}"]


#: A boiler's forward water above this [C] in the median boils at the bench's pressure.
WATER_BOILS_C = 100.0


def _firing_gain(log: LabLog, burning: np.ndarray) -> list[str]:
    """A balance that ends the firing heavier than it began it (refills taken out): the
    boiler burns fuel, so the column is read with its sign reversed, mirrored, or refilled
    in a way the refill detection did not take out (a stranger's probe: fuel 0.00 kg and
    -0.23 kg in the results, with no word)."""
    if "balance_mass_kg" not in log.columns:
        return []
    firing = np.flatnonzero(burning)
    if len(firing) < 2:
        return []
    span = slice(int(firing[0]), int(firing[-1]) + 1)
    mass = log.balance_without_refills()[span]
    read = np.flatnonzero(np.isfinite(mass))
    if len(read) < 2:
        return []
    gain = float(mass[read[-1]] - mass[read[0]])
    if not gain > QUIET_GAIN_MAX_KG:
        return []
    t = log.t[span]
    return [
        f"column 'balance_mass_kg' gains {gain:.2f} kg from time_s = {t[read[0]]:g} to "
        f"{t[read[-1]]:g} while the boiler fires, which burns fuel: is its sign reversed, or "
        "a refill not taken out?"
    ]


def _quiet_gain(log: LabLog, burning: np.ndarray) -> list[str]:
    if "balance_mass_kg" not in log.columns:
        return []
    t = log.t
    mass = log.balance_without_refills()
    edges = np.flatnonzero(np.diff(np.r_[0, (~burning).astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        rows = np.arange(a, b)
        rows = rows[np.isfinite(mass[rows])]
        if len(rows) < 10 or t[rows[-1]] - t[rows[0]] < QUIET_STRETCH_MIN_S:
            continue
        # the bed burns out for some minutes after a stop: the balance loses that
        rows = rows[t[rows] >= t[a] + BURN_OUT_S]
        if len(rows) < 10 or t[rows[-1]] - t[rows[0]] < QUIET_STRETCH_MIN_S:
            continue
        slope = float(np.polyfit(t[rows], mass[rows], 1)[0])
        span_s = float(t[rows[-1]] - t[rows[0]])
        change = slope * span_s
        if change > QUIET_GAIN_MAX_KG or change < -QUIET_LOSS_MAX_KG:
            what = "gains" if change > 0 else "loses"
            return [
                f"column 'balance_mass_kg' {what} {abs(change):.2f} kg over"
                f" {span_s / 60:.0f} min from time_s = {t[rows[0]]:g} with the burner off"
                f" ({slope * 3600:+.2f} kg/h): a drifting balance?"
            ]
    return []


#: A log whose median step is longer than this [s] is refused by the analyses: a 6-h test
#: of 36 rows, a start-up of one or two, holds no phase to read (a log in milliseconds, the
#: usual cause, gave a calibrated file 1000 times off with a tiny uncertainty: a
#: stranger's probe).
TIME_STEP_REFUSE_S = 600.0


#: ... and one that spans longer than this [s]: a test bench's run lasts hours to days;
#: a 14-h run logged every 0.5 s in milliseconds spans 300 days in rows under 10 min apart
#: (it still calibrated to UA_off 0.006 W/K: a re-probe).
TIME_SPAN_REFUSE_S = 30 * 86400.0


#: The shortest median step between rows the analyses read [s]: a data logger at 100 Hz;
#: a time in hours (1-s rows: 2.8e-4) or Excel's serial days (1.2e-5) gave balances of
#: 51,532 kW with exit 0 (a stranger's probe); a 20-Hz export (0.05 s) is read.
TIME_STEP_MIN_S = 0.01


def check_time_step(log: LabLog) -> None:
    """:class:`LogError` if ``log``'s median step exceeds :data:`TIME_STEP_REFUSE_S` or it
    spans more than :data:`TIME_SPAN_REFUSE_S`."""
    t = log.t
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if step > TIME_STEP_REFUSE_S:
        raise LogError(
            f"{log.path}: column 'time_s' advances a median of {step:g} s per row: a time in "
            f"milliseconds? (a lab logs every 1-10 s; the analyses need a row at least every "
            f"{TIME_STEP_REFUSE_S / 60:g} min)"
        )
    if 0.0 < step < TIME_STEP_MIN_S:
        raise LogError(
            f"{log.path}: column 'time_s' advances a median of {step:.3g} s per row: a time in "
            f"hours, or Excel's days? (a lab logs every 1-10 s; the analyses read rows at "
            f"most {1 / TIME_STEP_MIN_S:g} a second)"
        )
    span = float(t[-1] - t[0]) if len(t) else 0.0
    jumps = np.diff(t)
    if span > TIME_SPAN_REFUSE_S and float(jumps.max()) > 0.5 * span:  # a few rows' time
        # (a last row of 1e300 was shown as 300 digits of days and called milliseconds: a
        # stranger's probe); the wild rows are the fewer, on either side of the jump (a
        # wild first row had the good second named: a re-probe)
        i = int(np.argmax(jumps)) + 1
        days = f"{jumps[i - 1] / 86400:.3g} days"
        if i <= len(t) - i:
            where = f"the row at {t[i - 1]:.6g} s lies {days} before the row after ({t[i]:.6g} s)"
        else:
            where = f"the row at {t[i]:.6g} s comes {days} after the row before ({t[i - 1]:.6g} s)"
        raise LogError(f"{log.path}: column 'time_s': {where}: a wrong time in that row?")
    if span > TIME_SPAN_REFUSE_S:
        raise LogError(
            f"{log.path}: column 'time_s' spans {span / 86400:.3g} days: a time in "
            f"milliseconds? (a test bench's run lasts hours to days; the analyses read at "
            f"most {TIME_SPAN_REFUSE_S / 86400:.0f})"
        )


#: The fewest rows the phases are found from by the signals: a record's phases (preheat,
#: start-up, test, two coolings) need some ten readings each (1, 2 or 20 rows said "cannot
#: find t0: the burner never fires": a stranger's probe). A meta file's marks need none.
MIN_ROWS = 50


def too_few_rows(log: LabLog) -> str | None:
    """The one line refusing ``log`` when it has fewer than :data:`MIN_ROWS` rows, else
    None."""
    if len(log) >= MIN_ROWS:
        return None
    return (
        f"{log.path}: only {len(log)} data row(s); finding the phases from the signals needs "
        f"at least {MIN_ROWS} (preheat, start-up, test and two coolings, some ten readings "
        "each)"
    )


def _time_step(log: LabLog) -> list[str]:
    t = log.t
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    if step > TIME_STEP_MAX_S:
        return [
            f"column 'time_s' advances a median of {step:g} s per row (a lab logs every"
            " 1-10 s): milliseconds?"
        ]
    return []


def _noisy_balance(log: LabLog) -> list[str]:
    line = noisy_balance(log["balance_mass_kg"]) if log.has("balance_mass_kg") else None
    return [line] if line else []


def suspicious(log: LabLog, params: BoilerParams | None = None) -> list[str]:
    """One line per thing in ``log`` that looks like a wrong unit or a broken sensor (see
    the module docstring), each naming the log's file (without ``params``, the energy
    closure is not checked)."""
    burning = observe_firing(log).burning
    found = [
        *_time_step(log),
        *_temperatures(log),
        *_flue_gas(log),
        *_oxygen(log),
        *_stuck(log),
        *_flow(log),
        *(_fuel_rate(log, params) if params is not None else []),
        *(_closure(log, params, burning) if params is not None else []),
        *_firing_gain(log, burning),
        *_quiet_gain(log, burning),
        *_noisy_balance(log),
    ]
    return [f"{log.path}: {line}" for line in found]
