"""Energy balance from the instruments, as the lab computes it (Eq. 3-7, EN 14785).

Per phase:
- fuel power on a cumulative basis (the balance does not resolve single seconds). The boiler
  stands on the balance with its ash box (:mod:`rig_emulator.bench.bench`), so the balance
  loses the fuel as received less its ash, which stays in the box:
  balance loss = mass at start - mass at end, refills taken out (``balance_loss_kg``);
  m_dry = balance loss / (as-received per kg dry - ash per kg dry) (``fuel_dry_kg``);
  fuel as received = m_dry x as-received per kg dry = m_dry / (1 - moisture)
  (``fuel_as_received_kg``, the balance loss plus the ash m_dry x ash);
  Q_fuel = m_dry HHV / duration (Eq. 3);
- excess air from the dry O2 reading (exact inverse of the stoichiometry, ~21/(21-O2));
- flue-gas losses per kg of dry fuel from flue-gas temperature, composition and CO
  (Eq. 4-6), averaged over the rows where the burner fires (O2 below 19 vol-%), times the
  phase's fuel; ash loss 0.02 % of Q_fuel (EN 14785);
- heat to water from flow and temperatures (Eq. 7), integrated row by row;
- direct efficiency Q_water / Q_fuel, indirect efficiency 1 - (flue-gas + ash losses) /
  Q_fuel (the loss to the room is not measured, so the indirect figure is an upper bound).

Missing readings (empty fields) are interpolated in time; a refill of the balance (a rise
over 0.5 kg between readings) is no fuel leaving and is taken out. What the log cannot give is
unknown (NaN; null in the JSON, "-" in the table), never 0 or 100 %, and each phase's
``warnings`` say why: a column without any reading (no balance: fuel, Q_fuel, flue-gas loss
and efficiencies; no O2: lambda, flue-gas loss and indirect efficiency, the firing rows being
unknown; no flow or water temperature: Q_water and direct efficiency), or a stuck balance
(one reading throughout at least 10 min of firing by the O2, in the log or the phase: the
fuel is not read).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from hil_client.analysis.logio import (
    FIRING_O2_PCT,
    STUCK_FIRING_S,
    LabLog,
    Unread,
    balance_step_kg,
    fill_gaps,
    heat_needs_a_fall,
    noisy_balance,
    record_steps,
)
from hil_client.analysis.phases import NAMES, Phases
from rig_emulator.model import constants as k
from rig_emulator.model.fuel import stoichiometry
from rig_emulator.model.params import BoilerParams
from rig_emulator.model.water_heat import heat_to_water_kW

#: Fuel gone from the balance beyond its resolution (two 0.02-kg steps) [kg]
FUEL_SEEN_KG = 0.05
#: The least fuel [kg] an efficiency is read over: ten steps of the balance, so that the
#: reading's resolution (0.02 kg at each end) is within 3 % of it; a cooling phase that
#: loses one step gave an indirect efficiency of 99.98 % and a direct one of -0.04 %
EFFICIENCY_FUEL_MIN_KG = 0.2


@dataclass(slots=True)
class PhaseBalance:
    """Energy balance of one phase (energies [kWh], mean powers [kW], fractions [-])."""

    phase: str
    duration_s: float
    #: the fuel burnt, as received (with its moisture and ash) [kg]
    fuel_as_received_kg: float
    #: what the balance lost, refills taken out: the fuel as received less its ash [kg]
    balance_loss_kg: float
    fuel_dry_kg: float
    q_fuel_kW: float
    q_water_kW: float
    q_flue_gas_kW: float
    q_fg_sensible_kW: float
    q_fg_latent_kW: float
    q_fg_chemical_kW: float
    lambda_mean: float
    eta_direct: float
    eta_indirect: float
    #: why a figure of this phase is unknown (NaN), one line each
    warnings: list[str] = field(default_factory=list)


def flue_gas_loss_per_kg(
    params: BoilerParams,
    o2_pct: np.ndarray,
    t_fg: np.ndarray,
    t_room: np.ndarray,
    co_ppm: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(lambda, sensible, latent, chemical loss [kJ per kg dry fuel]) per row (Eq. 4-6)."""
    st = stoichiometry(params.fuel)
    o2 = np.clip(o2_pct, 0.0, FIRING_O2_PCT)
    lam = st.lambda_from_o2(o2)
    b0, b1 = st.dry_heat_capacity_coeffs()
    sens = (b0 + b1 * lam + st.m_h2o_kg * k.CP_VAPOUR) * (t_fg - t_room)
    latent = np.full_like(lam, st.m_h2o_kg * k.DH_VAP_WATER)
    chem = co_ppm * 1e-6 * st.dry_volume_m3(lam) * k.RHO_N_CO * k.DH_COMB_CO
    return lam, sens, latent, chem


#: The log columns the balance reads (besides CO, where the log has it).
READ = (
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "balance_mass_kg",
    "room_temp_C",
)


#: A balance that gains more than this [kg] over a phase the burner fired in, or over a
#: validated segment, reads no fuel there: the fuel only leaves (its sign reversed, or a
#: refill the refill detection did not take out). The fuel is unknown, not 0 kg, nor the
#: negative mass ``validate`` gave (a stranger's probe).
GAIN_UNREAD_KG = 0.1


#: The largest share of a phase's firing rows the flue-gas temperature may miss before its
#: loss is unknown (what is interpolated over more than half the firing is no reading).
UNREAD_MAX = 0.5


def energy_balance(log: LabLog, params: BoilerParams, phases: Phases) -> list[PhaseBalance]:
    """Per-phase energy balance of a lab log (see the module docstring)."""
    t = log.t
    mass = log.balance_without_refills()  # a refill is no fuel leaving
    readings, not_read = log.balance_readings()  # (a dropout, a stuck stretch: none)
    raw = {name: log[name] for name in READ} | {"balance_mass_kg": mass}
    get = {name: fill_gaps(values, t) for name, values in raw.items()}
    co = (
        np.nan_to_num(fill_gaps(log["flue_gas_CO_ppm"], t))
        if log.has("flue_gas_CO_ppm")
        else np.zeros(len(t))
    )
    dt, gap = record_steps(t)
    # what a row stands for: its step from the row before, none across a gap in the record
    # (a clock stepped forward, or rows missing): heat and fuel are both read over the time
    # recorded only (heat read across a clock's hour at 12 kW, with the balance losing
    # nothing over it, made 99.7 % of 85.4 %: a stranger's probe)
    rec = np.where(gap, 0.0, dt)
    fuel_window = fuel_rate_from_balance(log, params)
    q_water = heat_to_water_kW(
        get["water_flow_kg_h"], get["water_in_temp_C"], get["water_out_temp_C"]
    )
    lam, sens, lat, chem = flue_gas_loss_per_kg(
        params, get["flue_gas_O2_pct"], get["flue_gas_temp_C"], get["room_temp_C"], co
    )
    firing = get["flue_gas_O2_pct"] < FIRING_O2_PCT
    per_kg_dry = params.fuel.balance_loss_per_kg_dry
    hhv = params.fuel.hhv_dry_kJ_kg
    empty = {name: bool(np.isnan(v).all()) for name, v in get.items()}
    no_water = [n for n in ("water_flow_kg_h", "water_in_temp_C", "water_out_temp_C") if empty[n]]
    no_fg = [n for n in ("flue_gas_temp_C", "room_temp_C") if empty[n]]
    raw_mass = log["balance_mass_kg"]
    read_all = raw_mass[~np.isnan(raw_mass)]
    fired_all = float(rec[firing].sum())
    step_kg = balance_step_kg(raw_mass)
    # (the heat to the water must need the balance to move: a 0.5-kg balance held its
    # reading through a cooling's 10 min of firing, and was called stuck: a re-probe)
    heat_all = _heat_kJ(q_water, rec, firing)
    stuck_all = bool(
        fired_all >= STUCK_FIRING_S
        and len(read_all)
        and np.ptp(read_all) == 0
        and heat_needs_a_fall(heat_all, step_kg)
    )
    noisy = noisy_balance(raw_mass)  # (said in each phase whose fuel rests on it)
    out = []
    for name in NAMES:
        mask = phases.mask(name, t)
        if not mask.any():
            continue
        warn: list[str] = []
        idx = np.flatnonzero(mask)
        duration = float(rec[idx].sum())  # the time recorded
        gap_s = float(dt[idx[gap[idx]]].sum())
        after = idx[-1] + 1  # a gap from the phase's last row on: its end lies in the gap
        if after < len(t) and gap[after]:  # (the test was shortened without a word: a re-probe)
            gap_s += float(dt[after])
        if gap_s > 0:  # (an 11-day hole was averaged over without a word: a stranger's probe)
            warn.append(
                f"the record has gaps of {gap_s / 60:.0f} min in all in this phase: its "
                f"figures cover the {duration / 60:.0f} min recorded, heat and fuel alike, "
                "the gaps left out"
            )
        if name == phases.cut_in:
            warn.append(
                f"the run was cut short in this phase: its figures cover the "
                f"{duration / 60:.0f} min recorded, not the whole phase"
            )
        first = max(idx[0] - 1, 0)
        # the balance's falls over the phase's steps, none over a gap's (see ``rec``)
        falls = -np.diff(get["balance_mass_kg"][first : idx[-1] + 1])
        balance_loss = float(falls[~gap[first + 1 : idx[-1] + 1]].sum())
        burn = idx[firing[idx]]
        fired_s = float(rec[burn].sum())
        read = raw_mass[first : idx[-1] + 1]
        read = read[~np.isnan(read)]
        if empty["balance_mass_kg"]:
            warn.append(
                "column 'balance_mass_kg' has no readings: fuel, Q_fuel, flue-gas loss and "
                "efficiencies unknown"
            )
        elif stuck_all or (
            fired_s >= STUCK_FIRING_S
            and (not len(read) or np.ptp(read) == 0)
            and heat_needs_a_fall(_heat_kJ(q_water, rec, burn), step_kg)
        ):
            balance_loss = math.nan
            what = f"reads {read[0]:g} kg" if len(read) else "has no reading"
            where = "the log's" if stuck_all else "the phase's"
            minutes = (fired_all if stuck_all else fired_s) / 60
            warn.append(
                f"the balance {what} throughout {where} {minutes:.0f} min of firing (stuck?): "
                "fuel, Q_fuel, flue-gas loss and efficiencies unknown"
            )
        else:
            balance_loss = _read_across(not_read, readings, first, idx[-1], balance_loss, warn)
            if noisy is not None and math.isfinite(balance_loss):
                warn.append(noisy)
            if fired_s > 0 and balance_loss < -GAIN_UNREAD_KG:
                warn.append(
                    f"the balance gains {-balance_loss:.2f} kg over the phase while the "
                    "burner fires, which burns fuel (its sign reversed, or a refill not taken "
                    "out?): fuel, Q_fuel, flue-gas loss and efficiencies unknown"
                )
                balance_loss = math.nan
        fuel_dry = max(balance_loss, 0.0) / per_kg_dry if math.isfinite(balance_loss) else math.nan
        # (the balance's loss was given as the fuel as received, short of the ash left in
        # the box: read as such, it made a moisture error that does not exist, a stranger's
        # probe)
        fuel_as_received = fuel_dry * params.fuel.as_received_per_kg_dry
        q_fuel = fuel_dry * hhv / duration
        q_w = float((q_water[idx] * rec[idx]).sum() / duration)
        if no_water:
            warn.append(
                f"column '{no_water[0]}' has no readings: Q_water and direct efficiency unknown"
            )
        o2_known = not np.isnan(get["flue_gas_O2_pct"][idx]).all()
        lam_mean = float(lam[burn].mean()) if len(burn) else math.nan
        if not o2_known:
            s_ = l_ = c_ = math.nan
            warn.append(
                "column 'flue_gas_O2_pct' has no readings: the firing rows, lambda, flue-gas "
                "loss and indirect efficiency unknown"
            )
        elif not len(burn) and fuel_dry * per_kg_dry > FUEL_SEEN_KG:
            s_ = l_ = c_ = math.nan  # fuel left the balance, yet the analyser read air
            warn.append(
                f"the analyser reads air (O2 >= {FIRING_O2_PCT:g} %) throughout while the "
                f"balance lost {fuel_dry * per_kg_dry:.2f} kg: lambda, flue-gas loss and "
                "indirect efficiency unknown"
            )
        elif not len(burn):
            s_ = l_ = c_ = 0.0  # no combustion, no flue-gas loss
        elif (unread := float(np.isnan(raw["flue_gas_temp_C"][burn]).mean())) > UNREAD_MAX:
            s_ = l_ = c_ = math.nan  # (a stranger's probe: a flue gas pinned at its register's
            warn.append(  # limit, logged empty, read as 91.9 % across the gap, no word)
                f"column 'flue_gas_temp_C' has no reading in {unread:.0%} of the phase's "
                "firing rows: flue-gas loss and indirect efficiency unknown"
            )
        else:  # per kg of dry fuel, weighted by where the fuel went, times the phase's flow
            rate = fuel_dry / duration  # kg/s
            # (the plain mean over firing rows weighted a low load's high-lambda rows as much
            # as full load's: +3 % in a load cycle's test, a stranger's review)
            w = fuel_window[burn] * rec[burn]
            w = w if w.sum() > 0.0 else rec[burn]  # (a balance that moved too little)
            s_, l_, c_ = (float(np.average(a[burn], weights=w)) * rate for a in (sens, lat, chem))
            if no_fg:
                warn.append(f"column '{no_fg[0]}' has no readings: flue-gas loss unknown")
        q_fg = s_ + l_ + c_
        readable = q_fuel > 0 and fuel_dry * per_kg_dry >= EFFICIENCY_FUEL_MIN_KG
        eta_d = q_w / q_fuel if readable else math.nan
        eta_i = 1.0 - (q_fg + k.ASH_LOSS_FRACTION * q_fuel) / q_fuel if readable else math.nan
        out.append(
            PhaseBalance(
                name,
                duration,
                fuel_as_received,
                balance_loss,
                fuel_dry,
                q_fuel,
                q_w,
                q_fg,
                s_,
                l_,
                c_,
                lam_mean,
                eta_d,
                eta_i,
                warn,
            )
        )
    return out


def _heat_kJ(q_water: np.ndarray, rec: np.ndarray, rows: np.ndarray) -> float:
    """The heat to the water over ``rows`` (a mask or indices) [kJ]; infinite where it is
    not known (no water column read: unknown heat is no heat of 0, a re-probe)."""
    q = q_water[rows]
    return float(np.nansum(q * rec[rows])) if np.isfinite(q).any() else math.inf


def _read_across(
    unread: list[Unread], readings: np.ndarray, first: int, last: int, loss: float, warn: list[str]
) -> float:
    """The balance's loss over rows ``first``..``last`` (``loss``, read across what is
    missing), or NaN where a stretch of readings that are none (``unread``: a dropout, a
    stuck stretch) reaches an end of them, with no reading of the phase's to read across
    to; one line in ``warn`` for each such stretch."""
    for u in unread:
        lo, hi = max(u.start, first), min(u.end, last + 1)
        if lo >= hi:
            continue
        both = (~np.isnan(readings[first:lo])).any() and (~np.isnan(readings[hi : last + 1])).any()
        if both:
            warn.append(f"the balance {u.why}: those readings are none, read across")
        else:
            loss = math.nan
            warn.append(
                f"the balance {u.why}: those readings are none, and this phase's fuel rests "
                "on them: fuel, Q_fuel, flue-gas loss and efficiencies unknown"
            )
    return loss


def _cell(value: float, spec: str, width: int, scale: float = 1.0, unit: str = "") -> str:
    """``value`` formatted, or "-" where it is unknown (NaN), right-aligned in ``width``."""
    text = f"{value * scale:{spec}}{unit}" if math.isfinite(value) else "-"
    return f"{text:>{width}}"


def table(rows: list[PhaseBalance]) -> str:
    """The balance as a text table."""
    head = (
        f"{'phase':<10} {'duration':>9} {'fuel kg':>8} {'Q_fuel':>8} {'Q_water':>8} "
        f"{'Q_fluegas':>9} {'lambda':>7} {'eta dir':>8} {'eta ind':>8}"
    )
    lines = [head, f"{'':<10} {'h':>9} {'(a.r.)':>8} {'kW':>8} {'kW':>8} {'kW':>9}"]
    for r in rows:
        lines.append(
            f"{r.phase:<10} {r.duration_s / 3600:>9.3f} {_cell(r.fuel_as_received_kg, '.2f', 8)} "
            f"{_cell(r.q_fuel_kW, '.3f', 8)} {_cell(r.q_water_kW, '.3f', 8)} "
            f"{_cell(r.q_flue_gas_kW, '.3f', 9)} {_cell(r.lambda_mean, '.2f', 7)} "
            f"{_cell(r.eta_direct, '.1f', 8, 100, '%')} {_cell(r.eta_indirect, '.1f', 8, 100, '%')}"
        )
    return "\n".join(lines)


def warnings_by_reason(rows: list[PhaseBalance]) -> list[str]:
    """Each phase's warnings once per reason, with the phases it concerns."""
    reasons: dict[str, list[str]] = {}
    for r in rows:
        for w in r.warnings:
            reasons.setdefault(w, []).append(r.phase)
    return [f"{w} ({', '.join(phases)})" for w, phases in reasons.items()]


def as_json(rows: list[PhaseBalance], phases: Phases) -> dict:
    return {
        "phases": phases.as_dict() | {"source": phases.source},
        "balance": [asdict(r) for r in rows],
    }


#: The window over which the balance's readings give a fuel flow [s] (a linear fit: the
#: balance resolves no single second)
FUEL_WINDOW_S = 900.0


def fuel_rate_from_balance(log: LabLog, params: BoilerParams) -> np.ndarray:
    """Dry fuel flow [kg/h] per row from the balance, refills taken out: slope of a
    centred linear fit over :data:`FUEL_WINDOW_S`."""
    t = log.t - log.t[0]  # (running sums of t^2 at Unix times lost the slope: a re-probe)
    m = fill_gaps(log.balance_without_refills(), log.t)
    per_kg_dry = params.fuel.balance_loss_per_kg_dry
    # running sums give the least-squares slope over a centred window at every row
    cs, cm, ctt, ctm = (np.concatenate(([0.0], np.cumsum(a))) for a in (t, m, t * t, t * m))
    lo = np.searchsorted(t, t - FUEL_WINDOW_S / 2, side="left")
    hi = np.searchsorted(t, t + FUEL_WINDOW_S / 2, side="right")
    n = hi - lo
    st, sm = cs[hi] - cs[lo], cm[hi] - cm[lo]
    stt, stm = ctt[hi] - ctt[lo], ctm[hi] - ctm[lo]
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = (n * stm - st * sm) / (n * stt - st * st)
    return np.maximum(np.nan_to_num(-slope), 0.0) * 3600.0 / per_kg_dry
