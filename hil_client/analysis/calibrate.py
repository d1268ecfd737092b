"""Calibration of the Type 869 parameters from lab logs (Section 3.1 of Carlon et al. 2015).

From a stationary-test log and/or a load-cycle log plus the boiler's documentation values:

- stationary intervals: the ``stationary_*`` sequences (or, without a ``sequence`` column
  or with a lab's own step names, :func:`~hil_client.analysis.logio.stationary_steps`,
  flow plateaus of at least 20 min in the test phase), without their first 10 min, and only
  where the burner fired throughout and the boiler water held within 3 K between its 2.5th
  and 97.5th percentiles (a slow approach at the start is cut off; the 13 % step, below
  the modulation range, cycles and is left out); without any, the values below that need
  them keep their documentation values and are flagged;
- dTnom and dThx,wat (Eq. 8): linear regression of (T_fg - T_w,in) against
  (1 - m_w/m_w,nom) over the stationary intervals: the intercept is dTnom, the slope
  dThx,wat (Fig. 4). With a single load level only dTnom is fitted (dThx,wat kept);
- facA,lam and facB,lam (Eq. 9): lambda from the measured O2 against the dry fuel flow of
  each interval, the flow from a linear fit of the balance over the interval (Fig. 5);
- UAamb,OFF (Eq. 11-13): ln(T_boiler - T_room) is linear in time during the second cooling
  (no flow, no firing): UAamb,OFF = -C x slope, C = Ctherm + Volwat rho_w cp_w (digest);
- UAamb,ON (Eq. 14-16): (UAamb,OFF - UAamb,ON) (T_boiler - T_room) = Q_air, the heat the
  draught air carries off the idle boiler; Q_air from the flue-gas velocity measured in
  stand-by (rho_air cp_air v A (T_boiler - T_room)), the duct being DN100;
- Pel,MAX, Pel,MIN: electric power against firing power (fuel flow times LHV) over the
  stationary intervals, evaluated at Pmax and Pmin; Pel,OFF: mean power in stand-by;
  Wel: the electric energy above Pel,MAX during the start-up time after t0;
- Pstart: the dry fuel flow from the balance over the start-up at Pstart (from t0 until
  the boiler water first reaches the set temperature, at most the start-up time), times LHV.

Each fitted value carries a standard uncertainty: the regression's standard error combined
with the propagated accuracy of the bench's instruments (:data:`BENCH_ACCURACY`; a fixed
instrument error within a tolerance band +-a has standard uncertainty a/sqrt(3)). The files
report it expanded with a coverage factor of 2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from hil_client.analysis.logio import (
    LabLog,
    LogError,
    fill_gaps,
    flow_plateaus,
    record_steps,
    stationary_steps,
)
from hil_client.analysis.phases import Phases
from rig_emulator.model import constants as k
from rig_emulator.model.fuel import stoichiometry
from rig_emulator.model.params import (
    LAMBDA_MAX,
    ORDERED_PAIRS,
    BoilerParams,
    ParameterError,
    params_from_mapping,
)

#: The lab's instruments (Carlon et al. 2015, Section 2.2; typical classes where silent):
#: (absolute, relative) half-width of the tolerance band.
BENCH_ACCURACY = {
    "flue_gas_temp_C": (0.30, 0.005),  # Pt100 class B
    "water_temp_C": (0.15, 0.002),  # Pt100 class A
    "flue_gas_O2_pct": (0.2, 0.0),  # paramagnetic analyser
    "water_flow_kg_h": (0.0, 0.005),  # inductive meter
    "balance_mass_kg": (0.02, 0.0),  # 0.02 kg precision
    "flue_gas_velocity_m_s": (0.15, 0.0),  # vortex meter
    "electric_power_W": (0.5, 0.01),  # power meter
    "room_temp_C": (0.3, 0.0),
}
COVERAGE = 2.0
DUCT_AREA_M2 = math.pi * 0.10**2 / 4  # DN100 chimney of the bench
R_AIR = 287.05  # [J/(kg K)]
CP_AIR = 1.006  # [kJ/(kg K)]
SKIP_S = 600.0  # transient at the start of a stationary interval
MIN_INTERVAL_S = 1200.0  # shortest stationary interval kept (after the skip)
#: The second cooling's decay is read from 30 min after t3 on, over this long at least [s]
#: and from this many readings at least.
COOLING_READ_S = 600.0
COOLING_MIN_ROWS = 30
TRIM_S = 300.0  # a slow approach is cut off in steps of this long
#: Shortest start-up Pstart is read over [s]: at Pstart the auger feeds some 0.1 kg in two
#: minutes, five steps of the balance (0.02 kg, Section 2.2); a time, not a count of rows,
#: so a log sampled every 10 s reads it as one sampled every second does.
PSTART_MIN_S = 120.0


def _u(name: str, value: float) -> float:
    """Standard uncertainty of a fixed instrument error at ``value`` (uniform in the band)."""
    a, r = BENCH_ACCURACY[name]
    return (a + r * abs(value)) / math.sqrt(3.0)


@dataclass(frozen=True, slots=True)
class Fitted:
    """A calibrated value with its standard uncertainty and how it was found."""

    value: float
    u: float  # standard uncertainty
    method: str
    n: int = 0  # data points behind it

    @property
    def expanded(self) -> float:
        return COVERAGE * self.u


@dataclass(frozen=True, slots=True)
class Interval:
    """A stationary interval of a log: rows [i0, i1), mean flow, and its label."""

    log: LabLog
    i0: int
    i1: int
    label: str

    def mean(self, name: str) -> float:
        return float(np.nanmean(self.log[name][self.i0 : self.i1]))


def _mean_read(log: LabLog, column: str, mask: np.ndarray) -> float | None:
    """The mean of ``column`` over the rows ``mask`` where it was read (None: the log has
    no such column, or not one reading there: a dropout, a unit silent throughout)."""
    if not log.has(column):
        return None
    values = log[column][mask]
    values = values[~np.isnan(values)]
    return float(np.mean(values)) if len(values) else None


def _linfit(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    """(intercept, slope, se_intercept, se_slope) of an ordinary least-squares line, fitted
    about the mean of ``x`` (at Unix times, 1.8e9 s, the raw fit lost the slope: UA_off came
    out -0.0004 W/K and no fuel flow was found; a re-probe)."""
    n = len(x)
    x0 = float(np.mean(x)) if n else 0.0
    A = np.column_stack([np.ones(n), x - x0])
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    slope = float(coef[1])
    intercept = float(coef[0]) - slope * x0
    if n <= 2:
        return intercept, slope, 0.0, 0.0
    resid = y - A @ coef
    s2 = float(resid @ resid) / (n - 2)
    cov = s2 * np.linalg.inv(A.T @ A)  # (centred: intercept and slope uncorrelated)
    return intercept, slope, math.sqrt(cov[0, 0] + x0 * x0 * cov[1, 1]), math.sqrt(cov[1, 1])


#: How closely the boiler water must hold over a stationary interval [K] ...
HOLD_K = 3.0


def _spread_K(tb: np.ndarray) -> float:
    """... read between its 2.5th and 97.5th percentiles: a staged controller's swing and
    the sensor's noise and quantisation are part of a steady state, a slow approach is
    not."""
    ok = tb[np.isfinite(tb)]
    return float(np.percentile(ok, 97.5) - np.percentile(ok, 2.5)) if len(ok) else math.inf


def stationary_intervals(log: LabLog, phases: Phases) -> list[Interval]:
    """Stationary intervals of the test phase (see the module docstring)."""
    t = log.t
    test = phases.mask("test", t)
    segments: list[tuple[int, int, str]] = []
    marked = stationary_steps(log, test)
    if marked is not None:
        seq = np.array([s.strip() for s in log.text["sequence"]])
        for name in dict.fromkeys(seq[test & marked]):
            idx = np.flatnonzero(test & (seq == name))
            segments.append((int(idx[0]), int(idx[-1]) + 1, name))
    else:  # no sequence column, or a lab's own step names: the flow's plateaus
        segments += [(i0, i1, f"plateau_{lv:.0f}kg_h") for i0, i1, lv in flow_plateaus(log, test)]
    out = []

    def span(i0: int, i1: int) -> float:  # covered time [s], whatever the sampling period
        return float(t[i1 - 1] - t[i0]) if i1 - 1 > i0 else 0.0

    for i0, i1, name in segments:
        i0 = int(np.searchsorted(t, t[i0] + SKIP_S))
        if i1 - i0 < 2 or span(i0, i1) < TRIM_S:
            continue
        if log.has("boiler_on") and np.nanmin(log["boiler_on"][i0:i1]) < 0.5:
            continue  # the burner stopped: below the modulation range
        # the water must hold within 3 K: drop a slow approach at the start, if any
        tb = log["boiler_water_temp_C"][i0:i1]
        while span(i0, i1) >= MIN_INTERVAL_S and _spread_K(tb) > HOLD_K:
            i0 = int(np.searchsorted(t, t[i0] + TRIM_S))
            tb = log["boiler_water_temp_C"][i0:i1]
        if span(i0, i1) < MIN_INTERVAL_S or _spread_K(tb) > HOLD_K:
            continue
        out.append(Interval(log, i0, i1, name))
    return out


#: The largest share of a stationary interval's time the balance may have no readings
#: over (a dropout, a stuck stretch) before its fuel flow is not read: what rests on
#: readings that are not there over more than half of it is no reading (as the balance's
#: :data:`~hil_client.analysis.balance.UNREAD_MAX`)
BALANCE_UNREAD_MAX = 0.5


def _unread_rows(log: LabLog, i0: int, i1: int) -> np.ndarray:
    """Per row of ``i0``..``i1`` (exclusive), whether the balance's reading there is none
    (:meth:`LabLog.balance_readings`: a dropout, a stuck stretch)."""
    rows = np.zeros(i1 - i0, dtype=bool)
    if not len(rows):
        return rows
    for u in log.balance_readings()[1]:
        rows[max(u.start, i0) - i0 : max(min(u.end, i1) - i0, 0)] = True
    return rows


def _gap_min(log: LabLog, i0: int, i1: int) -> float:
    """The gaps in the record (:func:`record_steps`) between rows ``i0`` and ``i1 - 1``
    [min]."""
    dt, gap = record_steps(log.t)
    return float(dt[i0 + 1 : i1][gap[i0 + 1 : i1]].sum()) / 60.0


def _fuel_rate_dry(iv: Interval, params: BoilerParams) -> tuple[float, float]:
    """(dry fuel flow [kg/h], its standard uncertainty) from a linear fit of the balance,
    refills taken out (one refill in a 6-h test read as fuel going back: no fuel flow, and
    four parameters left at their documentation values); one slope over the stretches
    between the record's gaps, each with its own intercept (across a clock stepped
    forward the balance lost nothing in an hour: the fuel flow, and Pel from it, were
    read 15 % low; a stranger's probe); NaN where the balance has no readings over more
    than :data:`BALANCE_UNREAD_MAX` of the interval (stuck an hour into a 6-h test, it
    gave Pel,MAX 73 W for 50)."""
    t = iv.log.t[iv.i0 : iv.i1]
    m = iv.log.balance_without_refills()[iv.i0 : iv.i1]
    dt, gap = record_steps(iv.log.t)
    rec = np.where(gap, 0.0, dt)[iv.i0 : iv.i1]
    rec[0] = 0.0
    unread = _unread_rows(iv.log, iv.i0, iv.i1)
    if rec.sum() <= 0.0 or rec[unread].sum() > BALANCE_UNREAD_MAX * rec.sum():
        return math.nan, math.nan
    seg = np.cumsum(gap[iv.i0 : iv.i1] & (np.arange(len(t)) > 0))
    ok = ~np.isnan(m)
    tc, mc = t[ok].copy(), m[ok].copy()
    for s_ in np.unique(seg[ok]):  # each stretch about its own mean
        in_s = seg[ok] == s_
        tc[in_s] -= tc[in_s].mean()
        mc[in_s] -= mc[in_s].mean()
    n_seg = len(np.unique(seg[ok]))
    sxx = float(tc @ tc)
    if ok.sum() < 2 or sxx <= 0.0:
        return math.nan, math.nan
    slope = float(tc @ mc) / sxx
    dof = int(ok.sum()) - n_seg - 1
    resid = mc - slope * tc
    se = math.sqrt(float(resid @ resid) / dof / sxx) if dof > 0 else 0.0
    per_kg_dry = params.fuel.balance_loss_per_kg_dry
    duration = float(rec.sum())  # the time recorded
    # the resolution of the two end readings bounds the mass difference: 0.02 kg each
    u_res = math.sqrt(2) * _u("balance_mass_kg", 0.0) / duration
    rate = -slope * 3600.0 / per_kg_dry
    return rate, math.hypot(se, u_res) * 3600.0 / per_kg_dry


def _lambda_rows(
    log: LabLog, i0: int, i1: int, params: BoilerParams, o2_shift: float = 0.0
) -> np.ndarray:
    """Excess-air ratio of each row from the dry O2 reading (shifted by ``o2_shift``)."""
    st = stoichiometry(params.fuel)
    o2 = log["flue_gas_O2_pct"][i0:i1]
    return st.lambda_from_o2(np.clip(o2[~np.isnan(o2)] + o2_shift, 0.0, 19.5))


@dataclass
class Calibration:
    """The calibrated parameter set, each fitted value, the data of Figs. 4 and 5, and the
    fitted values that were implausible (kept at their documentation value; ``flags``:
    key -> why)."""

    params: BoilerParams
    fitted: dict[str, Fitted]
    fig4: dict[str, np.ndarray]
    fig5: dict[str, np.ndarray]
    flags: dict[str, str] = field(default_factory=dict)
    #: what the user should know of what was fitted (a gap in the record within it), one
    #: line each
    warnings: list[str] = field(default_factory=list)
    #: fitted values kept though far from the documentation (key -> why): a log of another
    #: boiler size (:func:`_far_from_documentation`)
    far: dict[str, str] = field(default_factory=dict)


#: A fitted value that tells the boiler's size, over its documentation value [-], beyond
#: which the log is likely of another boiler (warned, the fit kept): the start-up's fuel
#: power is Pstart by design, and the fuel's energy per kg differs from the nominal by at
#: most 30 % (the gap benchmark's fuel_energy_bias), the bench's instruments by a few %;
#: dTnom is the flue gas over the water at nominal flow, which a boiler of half the size
#: reaches at half the doc's (the 6-kW boiler's 42 K against the 12-kW one's 97 K). The
#: stationary intervals' highest firing power is set against 1.5 Pmax only (a load cycle
#: may hold part loads alone).
SIZE_RATIO_RANGE = (0.6, 1.5)


def _far_from_documentation(
    fitted: dict[str, Fitted], fuel_kg_h: np.ndarray, doc: BoilerParams
) -> dict[str, str]:
    """Fitted values (and the stationary firing power) far from the documentation of
    ``doc``, key -> why: one log of a 6-kW boiler calibrated as the 12-kW one fitted dTnom
    43 K (documented 97) and Pstart 7.1 kW (13.2) with no word (a stranger's probe)."""
    low, high = SIZE_RATIO_RANGE
    far = {}
    for key, what in (("p_start_kW", "the start-up's fuel power"), ("dt_nom_K", "dTnom")):
        f = fitted.get(key)
        documented = getattr(doc, key)
        if f is None or not math.isfinite(f.value) or documented <= 0:
            continue
        ratio = f.value / documented
        if not low <= ratio <= high:
            far[key] = (
                f"{what} fitted {f.value:.4g}, {ratio:.0%} of the documentation's {documented:.4g}"
            )
    if len(fuel_kg_h):
        top = float(np.max(fuel_kg_h)) * doc.fuel.lhv_dry_kJ_kg / 3600.0
        if top > high * doc.p_max_kW:
            far["p_max_kW"] = (
                f"the stationary intervals fire at up to {top:.3g} kW, {top / doc.p_max_kW:.0%}"
                f" of the documentation's Pmax {doc.p_max_kW:g} kW"
            )
    return far


def _lambda_ok(params: BoilerParams) -> bool:
    """Eq. 9 gives 1 < lambda <= :data:`LAMBDA_MAX` over the whole firing range (the
    start-up's Pstart too, as the parameter files' check asks)."""
    lhv = params.fuel.lhv_dry_kJ_kg
    return all(
        1.0 < params.fac_a_lambda + params.fac_b_lambda_h_kg * p * 3600.0 / lhv <= LAMBDA_MAX
        for _, p in params.firing_points()
    )


#: What each fitted value must satisfy to be physical (the checks of the parameter files,
#: CONTRACT section 2): a value that fails keeps its documentation value and is flagged.
PLAUSIBLE = {
    "ua_amb_off_W_K": ("positive", lambda v, p: v > 0),
    "ua_amb_on_W_K": ("positive", lambda v, p: v > 0),
    "dt_nom_K": ("positive", lambda v, p: v > 0),
    "p_start_kW": ("positive and at most 1.5 Pmax", lambda v, p: 0 < v <= 1.5 * p.p_max_kW),
    "w_el_Wh": ("not negative", lambda v, p: v >= 0),
    "p_el_min_W": ("not negative", lambda v, p: v >= 0),
    "p_el_max_W": ("not negative", lambda v, p: v >= 0),
    "p_el_off_W": ("not negative", lambda v, p: v >= 0),
}


def _plausible(doc: BoilerParams, fitted: dict[str, Fitted]) -> tuple[BoilerParams, dict[str, str]]:
    """The calibrated set with every implausible fitted value replaced by its documentation
    value, and why each was replaced."""
    flags: dict[str, str] = {}
    values = {}
    for key, f in fitted.items():
        rule = PLAUSIBLE.get(key)
        if not math.isfinite(f.value):
            flags[key] = f"fitted value {f.value} is not a number"
        elif rule is not None and not rule[1](f.value, doc):
            flags[key] = f"fitted {f.value:.4g}, where it must be {rule[0]} ({f.method})"
        else:
            values[key] = f.value
    params = replace(doc, **values, dt_hx_fg_K=0.0)
    if not _lambda_ok(params):
        for key in ("fac_a_lambda", "fac_b_lambda_h_kg"):
            if key in values:
                flags[key] = (
                    f"fitted {values[key]:.4g} gives lambda outside 1..{LAMBDA_MAX:g} in the "
                    "modulation range (Eq. 9; an analyser reading air?)"
                )
        params = replace(
            params, fac_a_lambda=doc.fac_a_lambda, fac_b_lambda_h_kg=doc.fac_b_lambda_h_kg
        )
    for low, high, why in ORDERED_PAIRS:  # a pair out of order: the lower one's fit goes
        if getattr(params, low) <= getattr(params, high):  # back to its documentation
            continue  # value, clamped at the higher one's where that is above it still
        above = f"above {high} {getattr(params, high):.4g}, where {why}"
        if low in values:  # its fit out of order
            flags[low] = f"fitted {low} {values[low]:.4g} {above}"
        else:  # its documentation value (its fit, if any, already refused: said first)
            said = f"the documentation value {getattr(doc, low):.4g} {above}"
            flags[low] = f"{flags[low]}; {said}" if low in flags else f"{low}: {said}"
        params = replace(params, **{low: min(getattr(doc, low), getattr(params, high))})
    return _as_a_file_may_be(doc, params, values, flags), flags


def _as_a_file_may_be(
    doc: BoilerParams, params: BoilerParams, values: dict[str, float], flags: dict[str, str]
) -> BoilerParams:
    """``params`` as a parameter file may hold them (:func:`params_from_mapping`'s physics:
    a flue gas hotter than its flame, a boiler that cannot heat its water): the fits the
    check names go back to their documentation values, flagged with its reason, the
    others kept (the set written was refused whole, exit 2, where one fit was wrong)."""
    for _ in range(len(values) + 1):
        try:
            params_from_mapping(params.to_mapping(), "the calibrated set")
            return params
        except ParameterError as exc:
            refused = str(exc).removeprefix("the calibrated set: ")
        fitted = [key for key in values if getattr(params, key) != getattr(doc, key)]
        named = [key for key in fitted if f"'{key}'" in refused] or fitted
        if not named:
            break
        for key in named:
            flags[key] = f"fitted {values[key]:.4g}: the set it gives is refused ({refused})"
        params = replace(params, **{key: getattr(doc, key) for key in named})
    return params


#: What only the stationary intervals can give (Eq. 8, Eq. 9, electric power).
STATIONARY_KEYS = (
    "dt_nom_K",
    "dt_hx_wat_K",
    "fac_a_lambda",
    "fac_b_lambda_h_kg",
    "p_el_max_W",
    "p_el_min_W",
)


def _fit_stationary(
    intervals: list[Interval], doc: BoilerParams, fitted: dict[str, Fitted]
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Eq. 8 (Fig. 4), Eq. 9 (Fig. 5) and the electric power over the stationary intervals,
    into ``fitted``; returns the data of Figs. 4 and 5."""
    m_nom = doc.nominal_flow_kg_h
    # --- Eq. 8: dTnom, dThx,wat (Fig. 4)
    x = np.array([1.0 - iv.mean("water_flow_kg_h") / m_nom for iv in intervals])
    y = np.array([iv.mean("flue_gas_temp_C") - iv.mean("water_in_temp_C") for iv in intervals])
    t_fg = np.mean([iv.mean("flue_gas_temp_C") for iv in intervals])
    t_in = np.mean([iv.mean("water_in_temp_C") for iv in intervals])
    u_instr = math.hypot(_u("flue_gas_temp_C", t_fg), _u("water_temp_C", t_in))
    if np.ptp(x) > 0.1:
        a, b, se_a, se_b = _linfit(x, y)
        # fixed relative errors of the flow meter and the flue-gas sensor tilt the line:
        # refit with each shifted by its standard uncertainty
        u_flow = _u("water_flow_kg_h", 1.0)
        a_f, b_f, _, _ = _linfit(1.0 - (1.0 - x) * (1.0 + u_flow), y)
        t_fg_rows = np.array([iv.mean("flue_gas_temp_C") for iv in intervals])
        rel_fg = BENCH_ACCURACY["flue_gas_temp_C"][1] / math.sqrt(3.0)
        _, b_t, _, _ = _linfit(x, y + t_fg_rows * rel_fg)
        u_b = math.sqrt(se_b**2 + (b_f - b) ** 2 + (b_t - b) ** 2)
        u_a = math.sqrt(se_a**2 + u_instr**2 + (a_f - a) ** 2)
        fitted["dt_hx_wat_K"] = Fitted(
            b,
            u_b,
            "slope of (T_fg - T_in) vs (1 - m/m_nom), stationary intervals (Fig. 4)",
            len(x),
        )
        fitted["dt_nom_K"] = Fitted(
            a, u_a, "intercept of the same regression (nominal flow)", len(x)
        )
    else:
        b = doc.dt_hx_wat_K
        dtn = float(np.mean(y - b * x))
        se = float(np.std(y - b * x, ddof=1) / math.sqrt(len(y))) if len(y) > 1 else 0.0
        fitted["dt_nom_K"] = Fitted(
            dtn,
            math.hypot(se, u_instr),
            "mean (T_fg - T_in) at nominal load, dThx,wat kept",
            len(x),
        )
    # --- Eq. 9: facA, facB (Fig. 5), only where the balance shows fuel fed (a stuck or
    # empty balance gives no fuel flow: nothing to regress lambda or Pel on)
    rates = [_fuel_rate_dry(iv, doc) for iv in intervals]
    fed = [r[0] > COVERAGE * r[1] for r in rates]  # NaN compares False
    if not any(fed):
        return {"x": x, "y": y}, {"fuel": np.array([]), "lambda": np.array([])}
    intervals = [iv for iv, f in zip(intervals, fed, strict=True) if f]
    fuel = np.array([r for r, f in zip(rates, fed, strict=True) if f])
    lam = np.array([float(np.mean(_lambda_rows(iv.log, iv.i0, iv.i1, doc))) for iv in intervals])
    # a fixed O2 error (+-0.2 vol-%) moves lambda most where the air excess is high: refit
    # with O2 shifted by its standard uncertainty to propagate it
    o2_shift = _u("flue_gas_O2_pct", 0.0)
    lam_shifted = np.array(
        [float(np.mean(_lambda_rows(iv.log, iv.i0, iv.i1, doc, o2_shift))) for iv in intervals]
    )
    if np.ptp(fuel[:, 0]) > 0.2 * np.mean(fuel[:, 0]):
        a, b, se_a, se_b = _linfit(fuel[:, 0], lam)
        a_o2, b_o2, _, _ = _linfit(fuel[:, 0], lam_shifted)
        # the fuel flows' own uncertainty, through the slope and onto the intercept
        u_b_fuel = abs(b) * float(np.mean(fuel[:, 1] / fuel[:, 0]))
        u_b = math.sqrt(se_b**2 + u_b_fuel**2 + (b_o2 - b) ** 2)
        u_a = math.sqrt(se_a**2 + (u_b_fuel * float(np.mean(fuel[:, 0]))) ** 2 + (a_o2 - a) ** 2)
        fitted["fac_b_lambda_h_kg"] = Fitted(
            b, u_b, "slope of lambda (from O2) vs dry fuel flow (Fig. 5)", len(lam)
        )
        fitted["fac_a_lambda"] = Fitted(a, u_a, "intercept of the same regression", len(lam))
    else:
        b = doc.fac_b_lambda_h_kg
        per_interval = lam - b * fuel[:, 0]
        a = float(np.mean(per_interval))
        a_o2 = float(np.mean(lam_shifted - b * fuel[:, 0]))
        # the same terms as the regression's: the intervals' scatter, the fuel flows' own
        # uncertainty through facB (it was the O2 shift alone: a stranger's probe found the
        # stated uncertainty a third of the fuel flow's share)
        n = len(per_interval)
        se_a = float(np.std(per_interval, ddof=1)) / math.sqrt(n) if n > 1 else 0.0
        u_a_fuel = abs(b) * float(np.mean(fuel[:, 1]))
        u_a = math.sqrt(se_a**2 + u_a_fuel**2 + (a_o2 - a) ** 2)
        fitted["fac_a_lambda"] = Fitted(a, u_a, "lambda - facB m_fuel at one load, facB kept", n)
    # --- electric power against firing power
    firing = fuel[:, 0] * doc.fuel.lhv_dry_kJ_kg / 3600.0
    pel = (
        np.array([iv.mean("electric_power_W") for iv in intervals])
        if all(iv.log.has("electric_power_W") for iv in intervals)
        else None
    )
    if pel is not None:
        u_pel = _u("electric_power_W", float(np.mean(pel)))
        if np.ptp(firing) > 0.2 * doc.p_max_kW:
            a, b, se_a, se_b = _linfit(firing, pel)
            for key, p in (("p_el_max_W", doc.p_max_kW), ("p_el_min_W", doc.p_min_kW)):
                se = math.hypot(se_a, se_b * p)
                fitted[key] = Fitted(
                    a + b * p,
                    math.hypot(se, u_pel),
                    "electric vs firing power, stationary intervals, at " + key[5:8],
                    len(pel),
                )
        elif float(np.mean(firing)) >= doc.p_max_kW:
            # at full load (the balance's firing reads at or above Pmax): Pel,MAX itself
            fitted["p_el_max_W"] = Fitted(
                float(np.mean(pel)), u_pel, "mean at nominal load", len(pel)
            )
        else:
            # one part load (a load cycle's steady steps span 5-7 kW of a 13-kW boiler; a
            # stationary test at 87 %): the documented line moved through the mean, its
            # slope kept (as facB is above); the mean alone was read as Pel,MAX, 30 W
            # against 50, and a 15 % band around Pmax left 46 W at 87 % (re-probes)
            slope = (doc.p_el_max_W - doc.p_el_min_W) / (doc.p_max_kW - doc.p_min_kW)
            at = max(float(np.mean(firing)), doc.p_min_kW)
            for key, p in (("p_el_max_W", doc.p_max_kW), ("p_el_min_W", doc.p_min_kW)):
                fitted[key] = Fitted(
                    float(np.mean(pel)) + slope * (p - at),
                    u_pel,
                    f"mean at {at:.1f} kW along the documented slope, at " + key[5:8],
                    len(pel),
                )
    return {"x": x, "y": y}, {"fuel": fuel[:, 0], "lambda": lam}


def calibrate(logs: list[tuple[LabLog, Phases]], doc: BoilerParams) -> Calibration:
    """Calibrate from logs (each with its phases) starting from documentation values."""
    fitted: dict[str, Fitted] = {}
    intervals = [iv for log, ph in logs for iv in stationary_intervals(log, ph)]
    warnings: list[str] = []  # what is fitted across a gap in the record (a probe: none)
    for iv in intervals:
        if (gap_min := _gap_min(iv.log, iv.i0, iv.i1)) > 0.0:
            warnings.append(
                f"{iv.log.path}: the stationary interval {iv.label} (time_s "
                f"{iv.log.t[iv.i0]:g}..{iv.log.t[iv.i1 - 1]:g}) spans gaps of {gap_min:.0f} min "
                "in the record: its fuel flow is read over the time recorded, each side of "
                "a gap on its own"
            )
    if intervals:
        fig4, fig5 = _fit_stationary(intervals, doc, fitted)
    else:
        fig4, fig5 = (
            {"x": np.array([]), "y": np.array([])},
            {"fuel": np.array([]), "lambda": np.array([])},
        )
    # --- second cooling: UAamb,OFF (Eq. 13) and UAamb,ON (Eq. 14-16)
    cap = doc.capacity_kJ_K
    ua_off_values, ua_on_values, pel_off, starts = [], [], [], []
    for log, ph in logs:
        t = log.t
        mask = ph.mask("cooling_2", t) & (t > ph.t3 + 1800.0)
        # (10 min of it, in time: 600 rows were 100 min of a 10-s log)
        if mask.sum() >= COOLING_MIN_ROWS and np.ptp(t[mask]) >= COOLING_READ_S:
            tb, tr = log["boiler_water_temp_C"][mask], log["room_temp_C"][mask]
            ok = ~(np.isnan(tb) | np.isnan(tr))
            tt = t[mask][ok]
            dT = tb[ok] - tr[ok]
            _, slope, _, se = _linfit(tt, np.log(dT))
            ua = -slope * cap * 1000.0
            # a fixed error of the boiler or room sensor shifts dT: propagate by perturbation
            u_t = math.hypot(_u("water_temp_C", float(np.nanmean(tb))), _u("room_temp_C", 0.0))
            _, slope_p, _, _ = _linfit(tt, np.log(dT + u_t))
            u_ua = math.hypot(se * cap * 1000.0, (slope - slope_p) * cap * 1000.0)
            ua_off_values.append((ua, u_ua, int(ok.sum())))
            v = _mean_read(log, "flue_gas_velocity_m_s", mask)
            if v is not None:
                t_air = float(np.nanmean(tb)) + k.T_NORMAL_K
                # standard air where the barometer read nothing there (a column of error
                # codes: its nanmean was NaN, and so was UA_on: a re-probe)
                p_hpa = _mean_read(log, "ambient_pressure_hPa", mask)
                p_pa = p_hpa * 100.0 if p_hpa is not None else 101325.0
                rho = p_pa / (R_AIR * t_air)
                per_K = rho * CP_AIR * 1000.0 * DUCT_AREA_M2  # W/K per m/s
                ua_on_values.append((v * per_K, _u("flue_gas_velocity_m_s", v) * per_K))
            p_el = _mean_read(log, "electric_power_W", mask)
            if p_el is not None:
                pel_off.append(p_el)
        # start-up: Wel and Pstart from the first start, if the log holds it from the row
        # before t0 to the end of the start-up time
        i0 = int(np.searchsorted(t, ph.t0, side="right"))
        i_end = int(np.searchsorted(t, ph.t0 + doc.startup_duration_s, side="right"))
        if i0 >= 1 and t[-1] >= ph.t0 + doc.startup_duration_s:
            if (gap_min := _gap_min(log, i0 - 1, i_end)) > 0.0:  # read as if continuous
                warnings.append(
                    f"{log.path}: the start-up (time_s {t[i0 - 1]:g}..{t[i_end - 1]:g}) spans "
                    f"gaps of {gap_min:.0f} min in the record: W_el and Pstart read across them"
                )
            starts.append((log, i0, i_end))
    if ua_off_values:
        vals = np.array(ua_off_values)
        ua_off = float(np.mean(vals[:, 0]))
        fitted["ua_amb_off_W_K"] = Fitted(
            ua_off,
            float(np.max(vals[:, 1])),
            "exponential fit of the second cooling (Eq. 13)",
            int(vals[:, 2].sum()),
        )
        if ua_on_values:
            q_air = np.array(ua_on_values)
            diff = float(np.mean(q_air[:, 0]))
            fitted["ua_amb_on_W_K"] = Fitted(
                ua_off - diff,
                math.hypot(fitted["ua_amb_off_W_K"].u, float(np.max(q_air[:, 1]))),
                "UA_off - draught-air heat per K in stand-by (Eq. 14-16)",
                len(q_air),
            )
    if pel_off:
        fitted["p_el_off_W"] = Fitted(
            float(np.mean(pel_off)),
            _u("electric_power_W", float(np.mean(pel_off))),
            "mean power in stand-by (second cooling)",
            len(pel_off),
        )
    p_el_max = fitted["p_el_max_W"].value if "p_el_max_W" in fitted else doc.p_el_max_W
    w_el, p_start = [], []
    short_start_up = False  # why no start-up gave Pstart: too short, or no fuel fed
    for log, i0, i_end in starts:
        t = log.t
        if log.has("electric_power_W"):
            pel_rows = fill_gaps(log["electric_power_W"], t)[i0:i_end]
            dts = np.diff(t[i0 - 1 : i_end])
            w_el.append(float(np.sum((pel_rows - p_el_max) * dts)) / 3600.0)
        tb = log["boiler_water_temp_C"]
        reach = np.flatnonzero(tb[i0:i_end] >= doc.set_temp_C - 0.5)
        i_stop = i0 + int(reach[0]) if len(reach) else i_end
        mass = fill_gaps(log.balance_without_refills(), t)
        per_kg_dry = doc.fuel.balance_loss_per_kg_dry
        dm = (mass[i0 - 1] - mass[i_stop - 1]) / per_kg_dry
        duration = t[i_stop - 1] - t[i0 - 1]
        short_start_up |= duration < PSTART_MIN_S
        # (no Pstart from a start-up where the balance's readings are none: stuck, a dropout)
        if _unread_rows(log, i0 - 1, i_stop).any():
            dm = math.nan
        if duration >= PSTART_MIN_S and dm > 0:  # NaN (no balance) compares False
            p_start.append(
                (
                    dm / duration * doc.fuel.lhv_dry_kJ_kg,
                    math.sqrt(2)
                    * _u("balance_mass_kg", 0.0)
                    / per_kg_dry
                    / duration
                    * doc.fuel.lhv_dry_kJ_kg,
                )
            )
    if w_el:
        fitted["w_el_Wh"] = Fitted(
            float(np.mean(w_el)),
            math.hypot(
                _u("electric_power_W", 500.0) * doc.startup_duration_s / 3600.0,
                float(np.std(w_el)) if len(w_el) > 1 else 0.0,
            ),
            "electric energy above Pel,MAX during the start-up time",
            len(w_el),
        )
    if p_start:
        vals = np.array(p_start)
        fitted["p_start_kW"] = Fitted(
            float(np.mean(vals[:, 0])),
            float(np.max(vals[:, 1])),
            "dry fuel flow over the start-up at Pstart x LHV",
            len(vals),
        )
    names = ", ".join(str(log.path) for log, _ in logs)
    if not fitted:
        raise LogError(
            f"{names}: nothing to calibrate: no stationary interval, no second cooling "
            f"longer than {(1800 + COOLING_READ_S) / 60:.0f} min, no start-up recorded whole "
            "(too short a log?)"
        )
    params, flags = _plausible(doc, fitted)
    if not intervals:
        for key in STATIONARY_KEYS:
            flags[key] = (
                "no stationary interval (a step of the test phase with steady firing of at "
                f"least {(SKIP_S + MIN_INTERVAL_S) / 60:.0f} min: its first "
                f"{SKIP_S / 60:.0f} min are its transient, the {MIN_INTERVAL_S / 60:.0f} after "
                "are read)"
            )
    elif not len(fig5["fuel"]):
        for key in ("fac_a_lambda", "fac_b_lambda_h_kg", "p_el_max_W", "p_el_min_W"):
            flags[key] = (
                "no fuel flow from the balance over the stationary intervals (a stuck or "
                "empty balance?)"
            )
    if not starts:
        for key in ("w_el_Wh", "p_start_kW"):
            flags[key] = (
                "no start-up recorded whole (from the row before t0 to t0 + the start-up "
                f"time, {doc.startup_duration_s / 60:.0f} min)"
            )
    elif not p_start and "p_start_kW" not in flags:
        flags["p_start_kW"] = (
            f"the water reached the set temperature within {PSTART_MIN_S:.0f} s of the start"
            " (too short to read the fuel fed over it)"
            if short_start_up
            else "no fuel fed over the start-up by the balance (a stuck or empty balance?)"
        )
    far = _far_from_documentation(fitted, fig5["fuel"], doc)
    if far:
        warnings.append(
            f"{names}: far from the documentation of '{doc.name}' (--boiler): "
            f"{'; '.join(far.values())}: a log of another boiler size? (the fits are kept)"
        )
    return Calibration(params, fitted, fig4, fig5, flags, warnings, far)
