"""``ignition_delay``: the fuel the balance lost before the flue gas showed combustion, at
each start, and where the flue gas counts the flame's fuel, the fuel fed but not yet burnt
five minutes into the start.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hil_client.analysis.candidates.base import (
    AIR_O2_MARGIN_PCT,
    BALANCE_STEP_KG,
    O2_AIR_PCT,
    Z_MIN,
    Assessment,
)
from hil_client.analysis.firing import ONSET_LOOKBACK_S
from hil_client.analysis.logio import fill_gaps
from hil_client.analysis.replay import Case

#: The pre-feed an effect must exceed [s of feed]: the onset of combustion is seen in the
#: flue gas (+3 K) some 10-20 s after the bed lights; twice that is the floor.
PRE_FEED_MIN_S = 40.0


#: The balance before a start is read until this long before the onset [s] ...
PRE_WINDOW_END_S = 720.0


#: ... over at least this long and at most this long [s]: a log that begins a few minutes
#: before its first start still reads it (fewer readings only widen the mass's standard
#: error, which the evidence carries).
PRE_WINDOW_MIN_S = 60.0


PRE_WINDOW_MAX_S = 480.0


#: The mass at the onset is read from the readings this long before it [s].
ONSET_FIT_S = 90.0


#: The fuel still waiting in the bed is read again this long after the onset [s], as the
#: mean over a window this wide around it [s]: a pellet bed burns what it is fed within
#: tens of seconds (its burning time), so what is left five minutes in, beyond that, is
#: fuel the bed has not lit yet (a bed that lights at once but burns slowly at first).
HOLDUP_AT_S = 300.0


HOLDUP_WINDOW_S = 120.0


#: The flame's fuel is read from the flue gas (O2 consumed times the dry gas flow) only
#: where air is left over: below this dry O2 [vol-%], part of the fuel leaves unburnt (CO,
#: tar, soot) and the O2 no longer counts it.
FUEL_READABLE_O2_PCT = 3.0


#: Relative uncertainty of the flue gas's fuel scale, which the whole log's fed fuel sets:
#: the bed's content at the record's ends, the gas's moisture varying with the load
#: (Eq. 4-7: 1-2 % of the dry flow) and the analyser's zero (0.1 vol-% of O2 in 5-15).
U_BURNT_SCALE_REL = 0.03


#: The gas analyser's sample line delays O2 by 15-45 s on the bench, more on a long heated
#: line; the log cannot tell by how much (the fan's steps and the O2 correlate by less than
#: 0.1 on most logs), only at least how much (:func:`_analyser_delay_min_s`: from the
#: flue-gas probe's onset to the O2's fall), and that falls short of the line's delay by
#: as much as the probe's onset trails the flame: this much at most [s] (the first hot
#: gas warms the exchanger before the probe behind it rises 3 K; on the first independent
#: plant the onset trailed the O2's departure by 10-40 s). The flame's fuel is read as if
#: the delay were the longest the log allows, the least shown plus this: the O2 is advanced
#: by it, which counts fuel as burnt early and leaves the least in the bed the log allows.
ONSET_TRAIL_MAX_S = 45.0


def _start_feed_rate_kg_h(case: Case) -> float:
    """The balance's loss rate at the documented start-up power Pstart [kg/h]."""
    fuel = case.params.fuel
    return case.params.p_start_kW / fuel.lhv_dry_kJ_kg * fuel.balance_loss_per_kg_dry * 3600.0


def _pre_feed(case: Case) -> list[tuple[float, float, float]]:
    """(fuel lost before the onset of combustion [kg], its standard error [kg], the feed
    rate it is counted in [kg/h]) per start that follows at least 15 min without burning.

    The mass before is the mean reading from 20 min (or the last stop, or the record's
    start, whichever is later; at least 3 min of readings) to 12 min before the onset (a
    pre-feed of up to 12 min fits in between); the mass at the onset is the line through
    the readings of the :data:`ONSET_FIT_S` before it, read at the onset. Only readings
    before the onset count: what the auger feeds once the bed burns (an ignition charge
    landing on the flame, a fuel ramp) is the start-up's own, not fuel waiting for the bed
    to light. Each mass has the standard error of its fit and that of the balance's 0.02-kg
    steps (uniform rounding, 0.02 / sqrt(12)), which averaging the readings of a mass that
    hardly moves does not reduce: they all round the same way; only starts at different
    masses average it out. The rate is the documented start-up power's (Pstart at the
    nominal calorific value), so the evidence reads as seconds of feed whatever the
    plant's own start-up does after the onset. A charge the burner's start-up program feeds
    before the flame by design (:attr:`Case.ignition_charge_kg`, from its manual) is taken
    off the pre-feed: only fuel beyond it waits for a bed that is late to light.

    Where the flue gas counts the flame's fuel, the fuel still in the bed
    :data:`HOLDUP_AT_S` after the onset (:func:`_holdup`) is read as well, and the start
    gives the larger of the two: a bed that lights at once but burns slowly at first
    shows no pre-feed, only fuel that keeps waiting once it burns."""
    t = case.t
    mass = case.balance
    rounding = BALANCE_STEP_KG / math.sqrt(12.0)
    rate_kg_h = _start_feed_rate_kg_h(case)
    out = []
    stops = case.firing.stops
    for i in case.firing.starts:
        ts = t[i]
        before = stops[stops < i]
        quiet_since = t[before[-1]] if len(before) else t[0]
        quiet_s = min(ts - quiet_since, ts - t[0], PRE_WINDOW_END_S + PRE_WINDOW_MAX_S)
        if quiet_s < PRE_WINDOW_END_S + PRE_WINDOW_MIN_S:
            continue
        pre = (t >= ts - quiet_s) & (t <= ts - PRE_WINDOW_END_S) & ~np.isnan(mass)
        near = (t >= ts - ONSET_FIT_S) & (t <= ts) & ~np.isnan(mass)
        if pre.sum() < 5 or near.sum() < 4:
            continue
        m0 = float(np.mean(mass[pre]))
        u0 = math.hypot(float(np.std(mass[pre])) / math.sqrt(pre.sum()), rounding)
        x = t[near] - ts
        slope, intercept = np.polyfit(x, mass[near], 1)
        resid = mass[near] - (intercept + slope * x)
        s_res = float(np.std(resid, ddof=2)) if len(x) > 2 else 0.0
        sxx = float(np.sum((x - x.mean()) ** 2))
        u1 = s_res * math.sqrt(1.0 / len(x) + x.mean() ** 2 / sxx) if sxx > 0 else s_res
        u1 = math.hypot(u1, rounding)
        lost = m0 - float(intercept) - case.ignition_charge_kg
        pre_feed = (lost, math.hypot(u0, u1), rate_kg_h)
        held = _holdup(case, i, pre, m0, u0)
        out.append(held if held is not None and held[0] > pre_feed[0] else pre_feed)
    return out


def _analyser_delay_min_s(case: Case) -> float:
    """Least delay of the analyser's sample line the log shows [s]: the median, over the
    starts, of the time from the flue gas's onset (its probe answers within seconds) to the
    first O2 reading below air's (less :data:`AIR_O2_MARGIN_PCT`); the flame was lit
    before the onset, and the O2 takes a while to fall that far, so the true delay is
    longer (on the first independent plant, 0-30 s against true 15-45 s). The search
    reaches as far as the onset may lie before the O2's crossing (:data:`ONSET_LOOKBACK_S`),
    so the delay of a line slower than that is still seen."""
    t = case.t
    o2 = fill_gaps(case.log["flue_gas_O2_pct"], t)
    seen = []
    for i in case.firing.starts:
        fallen = np.flatnonzero(
            (t >= t[i]) & (t <= t[i] + ONSET_LOOKBACK_S) & (o2 < O2_AIR_PCT - AIR_O2_MARGIN_PCT)
        )
        if len(fallen):
            seen.append(t[fallen[0]] - t[i])
    return float(np.median(seen)) if seen else 0.0


def _analyser_delay_max_s(case: Case) -> float:
    """The longest delay of the sample line the log allows [s] (:data:`ONSET_TRAIL_MAX_S`)."""
    return _analyser_delay_min_s(case) + ONSET_TRAIL_MAX_S


def _burnt_kg(case: Case) -> tuple[np.ndarray, np.ndarray] | None:
    """(fuel the flame burnt since the record's start as the balance counts it [kg], the
    dry O2 per row, aligned) from the flue gas: the O2 consumed times the dry gas flow
    (velocity at the duct's temperature, normalised), shifted back by the analyser's
    delay at its longest (:func:`_analyser_delay_max_s`), and scaled so that the whole log
    burns what the balance lost. None without a usable velocity or with too little fed to
    scale by."""
    log, t = case.log, case.t
    if not log.has("flue_gas_velocity_m_s"):
        return None
    velocity = fill_gaps(log["flue_gas_velocity_m_s"], t)
    o2 = fill_gaps(log["flue_gas_O2_pct"], t)
    if np.isnan(velocity).any() or np.isnan(o2).any():
        return None
    o2 = np.interp(t + _analyser_delay_max_s(case), t, o2)
    idle = ~case.firing.burning & (o2 > O2_AIR_PCT - AIR_O2_MARGIN_PCT)
    if idle.sum() < 10:
        return None
    deficit = np.clip(float(np.median(o2[idle])) - o2, 0.0, None)
    gas = fill_gaps(case.lab["flue_gas_temp_C"], t)
    flow = deficit * velocity * 273.15 / (gas + 273.15)
    burnt = np.concatenate(([0.0], np.cumsum(0.5 * (flow[1:] + flow[:-1]) * np.diff(t))))
    mass = case.balance[~np.isnan(case.balance)]
    fed = float(mass[0] - mass[-1]) if len(mass) else 0.0
    if fed < 10.0 * BALANCE_STEP_KG or not burnt[-1] > 0.0:
        return None
    return burnt * fed / burnt[-1], o2


def _holdup(
    case: Case, start: int, pre: np.ndarray, m0: float, u0: float
) -> tuple[float, float, float] | None:
    """(fuel fed but not yet burnt :data:`HOLDUP_AT_S` after the onset of the start at row
    ``start`` [kg], its standard error [kg], the start-up feed rate [kg/h]), counted from the
    quiet balance before the start (rows ``pre``, mean mass ``m0`` +- ``u0``); None where
    the flue gas does not count the flame's fuel (no velocity; air-starved rows)."""
    read = case.memo(("burnt_kg",), lambda: _burnt_kg(case))
    if read is None:
        return None
    burnt, o2 = read
    t, mass = case.t, case.balance
    ts = t[start]
    flame = (t >= ts) & (t <= ts + HOLDUP_AT_S + HOLDUP_WINDOW_S / 2.0)
    if float(np.min(o2[flame])) < FUEL_READABLE_O2_PCT:
        return None
    window = (np.abs(t - ts - HOLDUP_AT_S) <= HOLDUP_WINDOW_S / 2.0) & ~np.isnan(mass)
    later = case.firing.stops[case.firing.stops > start]
    if window.sum() < 5 or (len(later) and later[0] <= np.flatnonzero(window)[-1]):
        return None
    rounding = BALANCE_STEP_KG / math.sqrt(12.0)
    x = t[window] - ts - HOLDUP_AT_S
    slope, intercept = np.polyfit(x, mass[window], 1)
    s_res = float(np.std(mass[window] - (intercept + slope * x), ddof=2))
    u1 = math.hypot(s_res / math.sqrt(window.sum()), rounding)
    burnt_since = float(np.interp(ts + HOLDUP_AT_S, t, burnt) - np.mean(burnt[pre]))
    u_burnt = U_BURNT_SCALE_REL * burnt_since
    held = m0 - float(intercept) - burnt_since
    return held, math.sqrt(u0**2 + u1**2 + u_burnt**2), _start_feed_rate_kg_h(case)


def _ignition_z(units: Sequence[tuple[float, float, float]]) -> float:
    """The mean pre-feed of the starts in standard errors (0 without a start)."""
    if not units:
        return 0.0
    se = math.sqrt(sum(u[1] ** 2 for u in units)) / len(units)
    return float(np.mean([u[0] for u in units])) / se


def _ignition_evidence(units: Sequence[tuple[float, float, float]]) -> bool:
    return bool(units) and _ignition_z(units) >= Z_MIN


def _decide_ignition(units: Sequence[tuple[float, float, float]]) -> tuple[bool, float, str]:
    if not units:
        return False, 0.0, "no start after a quiet balance"
    mean = float(np.mean([u[0] for u in units]))
    z = _ignition_z(units)
    delay = _delay_s(units)
    if delay < PRE_FEED_MIN_S:
        return False, z, f"pre-feed {mean:.3f} kg, {delay:.0f} s < {PRE_FEED_MIN_S:g} s of feed"
    if z < Z_MIN:
        return False, z, f"evidence {z:.1f} < {Z_MIN:g} standard errors"
    return True, z, "named"


def _delay_s(units: Sequence[tuple[float, float]]) -> float:
    pre = np.array([u[0] for u in units])
    rate = np.array([u[2] for u in units])
    return float(max(pre.mean(), 0.0) / max(rate.mean(), 1e-6) * 3600.0) if len(pre) else 0.0


def _ignition_rmsd(units, delay_s: float) -> tuple[float, float]:
    if not units:
        return math.nan, math.nan
    pre = np.array([u[0] for u in units])
    rate = np.array([u[2] for u in units])
    after = pre - delay_s * rate / 3600.0
    return float(np.sqrt(np.mean(pre**2))), float(np.sqrt(np.mean(after**2)))


def _params(case: Case, delay_s: float) -> dict[str, float]:
    """The candidate's parameters: the delay, and the documented charge it lies beyond
    where one was given."""
    if case.ignition_charge_kg > 0.0:
        return {"delay_s": delay_s, "charge_kg": case.ignition_charge_kg}
    return {"delay_s": delay_s}


class IgnitionCandidate:
    effect = "ignition_delay"
    signal = "fuel_cum_kg"
    locus = "start_up"

    def assess(self, case: Case) -> Assessment:
        units = _pre_feed(case)
        delay = _delay_s(units)
        # held out: each start predicted with the delay of the others
        res0, res1 = [], []
        for j, (pre, _, rate) in enumerate(units):
            rest = units[:j] + units[j + 1 :]
            if rest:
                res0.append(pre)
                res1.append(pre - _delay_s(rest) * rate / 3600.0)
        before = float(np.sqrt(np.mean(np.square(res0)))) if res0 else math.nan
        after = float(np.sqrt(np.mean(np.square(res1)))) if res1 else math.nan
        return Assessment(
            self.effect,
            self.signal,
            self.locus,
            _params(case, delay),
            units,
            _decide_ignition,
            before,
            after,
            delay / PRE_FEED_MIN_S,
            len(units),
            _ignition_evidence,
        )

    def held_out(self, case: Case, theta: dict[str, float]) -> tuple[float, float]:
        return _ignition_rmsd(_pre_feed(case), theta.get("delay_s", 0.0))

    def prediction(self, case: Case, theta: dict[str, float]) -> dict[str, np.ndarray]:
        """The balance loses the documented charge and the pre-feed beyond it at every
        start, on top of the model's fuel."""
        fuel = case.base_prediction()["fuel_cum_kg"].copy()
        per_start = theta.get("charge_kg", 0.0)
        per_start += theta["delay_s"] * _start_feed_rate_kg_h(case) / 3600.0
        for i in case.firing.starts:
            fuel[i:] += per_start
        return {"fuel_cum_kg": fuel}
