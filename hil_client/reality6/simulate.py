"""simulate_log / write_log_csv: one lab test of one boiler on the bench, as a lab log.

The flow of one call: protocol.py reads the test schedule; `kernel_parameters` turns the
boiler YAML (Table 3 of Carlon et al. 2015), the drawn background (background.py) and the
effect (effects.py) into the kernel's parameter vector; kernel.py runs the plant and the bench
second by second until t4 = t2 + 8 h; instruments.py turns the true signals into readings;
rows are then taken every `sample_s` seconds (with `jitter`, at irregular times and with a few
rows dropped).

Assumptions: the capacity of the body is Ctherm + Volwat * rho_w * cp_w (digest section 1);
firing powers in the YAML are net (LHV, as received) powers; the auger is calibrated on the
documented fuel; the load of the first sequence applies during the start-up.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from . import kernel as K
from .combustion import CP_WATER_KJ_KG_K, stoichiometry
from .effects import effect_settings, resolve
from .instruments import measure
from .protocol import TESTS, load_schedule

COLUMNS = (
    "time_s",
    "phase",
    "sequence",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "balance_mass_kg",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "water_flow_setpoint_kg_h",
    "boiler_on",
)
NOMINAL_EFFICIENCY_HHV = 0.85  # only to place "nominal firing" on the exchanger's load law


def body_capacity_kJ_K(boiler: dict) -> float:
    return float(boiler["c_therm_kJ_K"]) + float(boiler["vol_water_m3"]) * 1000.0 * (
        CP_WATER_KJ_KG_K
    )


def kernel_parameters(boiler: dict, schedule, bg: dict, eff: dict) -> tuple[np.ndarray, dict]:
    """The kernel's parameter vector, and a dict of derived figures (for meta and tests)."""
    fuel = boiler["fuel"]
    st_nom = stoichiometry(fuel)
    w_true = float(fuel["moisture"])
    w_true = w_true * eff.get("moisture_factor", 1.0) + eff.get("moisture_add", 0.0)
    hhv_true = float(fuel["hhv_dry_kJ_kg"]) * eff.get("hhv_factor", 1.0)
    st = stoichiometry(fuel, hhv_dry_kJ_kg=hhv_true, moisture_ar=w_true)
    p_nom, p_max = float(boiler["p_nom_kW"]), float(boiler["p_max_kW"])
    p_min, p_start = float(boiler["p_min_kW"]), float(boiler["p_start_kW"])
    kg_per_kj = bg["auger_calibration_factor"] / st_nom.lhv_ar_kJ_kg
    c_total = body_capacity_kJ_K(boiler)
    flow_nom = p_nom * 3600.0 / (CP_WATER_KJ_KG_K * schedule.flow_spread_K)
    # the exchanger's flue-gas law, placed so that the nominal stationary point gives about
    # T_in + dTnom (Eq. 8 at m_w = m_w,nom) times the plant's own factor
    q_fuel_max = p_max * kg_per_kj * (1.0 - w_true) * hhv_true
    q_rel_nominal = min(1.0, p_nom / NOMINAL_EFFICIENCY_HHV / q_fuel_max)
    dt_fg = (float(boiler["dt_nom_K"]) - schedule.flow_spread_K) * bg["flue_dt_factor"]
    dt_fg /= q_rel_nominal ** bg["flue_load_exponent"]
    m_dry_min = p_min * kg_per_kj * (1.0 - w_true)  # kg/s
    lam_min = float(boiler["fac_a_lambda"]) + float(boiler["fac_b_lambda_h_kg"]) * (
        m_dry_min * 3600.0
    )
    air_fan_min = 0.8 * max(lam_min, 1.3) * st.air_min_m3_kg * m_dry_min
    m_dry_max = p_max * kg_per_kj * (1.0 - w_true)
    lam_max = max(
        1.15,
        float(boiler["fac_a_lambda"]) + float(boiler["fac_b_lambda_h_kg"]) * m_dry_max * 3600.0,
    )
    gas_nom = m_dry_max * (
        st.dry_gas_mass_const_kg_kg + lam_max * st.dry_gas_mass_per_lambda_kg_kg + st.vapour_kg_kg
    )

    v = {
        K.I_P_NOM: p_nom,
        K.I_P_MAX: p_max,
        K.I_P_MIN: p_min,
        K.I_P_START: p_start,
        K.I_HHV_TRUE: hhv_true,
        K.I_W_TRUE: w_true,
        K.I_SIFT_FRAC: eff.get("sift_frac", 0.0),
        K.I_KG_PER_KJ_CMD: kg_per_kj,
        K.I_MFG0: st.dry_gas_mass_const_kg_kg,
        K.I_MFG1: st.dry_gas_mass_per_lambda_kg_kg,
        K.I_VD0: st.dry_gas_volume_const_m3_kg,
        K.I_AIR_MIN: st.air_min_m3_kg,
        K.I_V_CO2: st.v_co2_m3_kg,
        K.I_VAPOUR: st.vapour_kg_kg,
        K.I_CARBON: st.carbon,
        K.I_FAC_A: float(boiler["fac_a_lambda"]),
        K.I_FAC_B: float(boiler["fac_b_lambda_h_kg"]),
        K.I_LAMBDA_FAC: bg["lambda_factor"],
        K.I_LAMBDA_NOISE: bg["lambda_hunting"],
        K.I_AIR_FAN_MIN: air_fan_min,
        K.I_AIR_NATURAL: 0.3 * air_fan_min,
        K.I_CO_BASE: bg["co_base_ppm"],
        K.I_CO_LOW: bg["co_low_load_factor"],
        K.I_CO_PYRO: 400.0,
        K.I_DT_FG: dt_fg,
        K.I_FG_EXP: bg["flue_load_exponent"],
        K.I_FOUL_PER_H: bg["fouling_per_h"],
        K.I_TAU_FG_BG: bg["flue_store_tau_s"],
        K.I_C_FG_BG: bg["flue_store_kJ_K"],
        K.I_FG_MODE: eff.get("fg_mode", 0.0),
        K.I_FG_TAU_EFF: eff.get("fg_tau_eff_s", 0.0),
        K.I_FG_C_EFF: eff.get("fg_c_eff", 0.0),
        K.I_C_TOTAL: c_total,
        K.I_UA_ON: float(boiler["ua_amb_on_W_K"]) * bg["ua_on_factor"] / 1000.0,
        K.I_UA_OFF: float(boiler["ua_amb_off_W_K"]) * bg["ua_off_factor"] / 1000.0,
        K.I_UA_PURGE: bg["ua_purge_W_K"] / 1000.0,
        K.I_BODY_MODE: eff.get("body_mode", 0.0),
        K.I_C_METAL: eff.get("c_metal", 0.0),
        K.I_UA_METAL: eff.get("ua_metal", 0.0),
        K.I_PLATE_FRAC: eff.get("plate_frac", 0.0),
        K.I_UA_PLATE_ROOM: eff.get("ua_plate_room", 0.0),
        K.I_TAU_BED: bg["bed_tau_s"] + eff.get("bed_extra_tau_s", 0.0),
        K.I_BURN_CAP: 1.5 * p_max * kg_per_kj,
        K.I_M_IGN: bg["ignition_charge_kg"],
        K.I_AUGER_RATE: p_max * kg_per_kj * bg["auger_capacity_factor"],
        K.I_AUGER_CYCLE: bg["auger_cycle_s"],
        K.I_T_PREPURGE: bg["prepurge_s"],
        K.I_T_LIGHT_COLD: bg["light_cold_s"],
        K.I_T_LIGHT_HOT: bg["light_hot_s"],
        K.I_T_HOT_WINDOW: bg["hot_window_s"],
        K.I_LIGHT_EXTRA_COLD: eff.get("light_extra_cold_s", 0.0),
        K.I_LIGHT_EXTRA_HOT: eff.get("light_extra_hot_s", 0.0),
        K.I_TOPUP_PERIOD: bg["topup_period_s"],
        K.I_TOPUP_MASS: bg["topup_fraction"] * bg["ignition_charge_kg"],
        K.I_T_STAB: bg["stabilise_s"],
        K.I_STAB_FRAC: bg["stabilise_fraction"],
        K.I_T_START_FULL: bg["start_full_s"],
        K.I_T_IGN_POST: bg["igniter_post_s"],
        K.I_P_IGN_W: bg["igniter_W"],
        K.I_IGN_HEAT_FRAC: 0.8,
        K.I_T_POSTPURGE: bg["postpurge_s"],
        K.I_BED_OUT: 0.001 * p_max / 13.2,
        K.I_FLUCT_SIGMA: bg["auger_fill_sigma"],
        K.I_FLUCT_TAU: bg["auger_fill_tau_s"],
        K.I_T_SET: 70.0 + bg["ctrl_setpoint_error_K"] + bg["ctrl_sensor_offset_K"],
        K.I_CTRL_OFFSET: bg["ctrl_sensor_offset_K"],
        K.I_CTRL_STRAT: bg["ctrl_stratification_K"],
        K.I_KP: bg["ctrl_kp_per_K"] * p_max,
        K.I_TI: bg["ctrl_ti_s"],
        K.I_SLEW: bg["ctrl_slew_per_s"] * p_max,
        K.I_T_OFF: 85.0 + bg["shutoff_offset_K"],
        K.I_T_ON: 55.0 + bg["restart_offset_K"],
        K.I_T_MIN_BURN: bg["min_burn_s"],
        K.I_T_MIN_OFF: bg["min_off_s"],
        K.I_T_SAFETY: 89.0 + bg["shutoff_offset_K"],
        K.I_FLOW_NOM: flow_nom,
        K.I_TAU_FLOW: bg["flow_tau_s"],
        K.I_C_CIRC: bg["circuit_volume_l"] * CP_WATER_KJ_KG_K + 20.0,
        K.I_UA_CIRC: bg["circuit_ua_W_K"] / 1000.0,
        K.I_BENCH_KP: bg["bench_kp_kW_K"] * p_nom / 12.0,
        K.I_BENCH_TI: bg["bench_ti_s"],
        K.I_BENCH_TAU_ACT: bg["bench_actuator_tau_s"],
        K.I_CAP_MARGIN: bg["bench_capacity_margin"],
        K.I_HEAT_MAX: bg["preheater_kW"],
        K.I_PRE_T: schedule.preheat_temp_C,
        K.I_PRE_TOL: schedule.preheat_tol_K,
        K.I_PRE_HOLD: schedule.preheat_hold_s,
        K.I_PRE_LOAD: schedule.preheat_load,
        K.I_PRE_MAX: schedule.preheat_max_s,
        K.I_RET_SET: schedule.return_setpoint_C,
        K.I_SU_WINDOW: schedule.startup_window_s,
        K.I_SU_RISE: schedule.startup_max_rise_K_min,
        K.I_SU_MIN: schedule.startup_min_s,
        K.I_SU_MAX: schedule.startup_max_s,
        K.I_C1_LOAD: schedule.cooling1_load,
        K.I_C1_RET: schedule.cooling1_return_C,
        K.I_C1_UNTIL: schedule.cooling1_until_forward_C,
        K.I_C1_MAX: schedule.cooling1_max_s,
        K.I_C1_MARGIN: bg["cooling1_margin"],
        K.I_C2_UNTIL: schedule.cooling2_until_after_t2_s,
        K.I_T_INIT: bg["initial_temp_C"],
        K.I_OUT_OFFSET: bg["t_out_offset_K"],
        K.I_IN_OFFSET: bg["t_in_offset_K"],
        K.I_P_EL_MIN: float(boiler["p_el_min_W"]),
        K.I_P_EL_MAX: float(boiler["p_el_max_W"]),
        K.I_P_EL_OFF: float(boiler["p_el_off_W"]),
        K.I_AUGER_W: bg["auger_motor_W"],
        K.I_Q_FUEL_NOM: q_fuel_max,
        K.I_GAS_NOM: gas_nom,
        K.I_FG_OFF_FRAC: bg["flue_idle_fraction"],
        K.I_N_STAGES: float(round(bg["modulation_stages"])),
    }
    par = np.full(K.N_PAR, np.nan)
    for i, x in v.items():
        par[i] = float(x)
    if np.isnan(par).any():  # pragma: no cover (guards the index table)
        raise RuntimeError(f"kernel parameters unset: {np.flatnonzero(np.isnan(par))}")
    info = {
        "p_nom_kW": p_nom,
        "flow_nom_kg_h": flow_nom,
        "c_total_kJ_K": c_total,
        "hhv_true_dry_kJ_kg": hhv_true,
        "moisture_true": w_true,
        "hhv_nominal_dry_kJ_kg": float(fuel["hhv_dry_kJ_kg"]),
        "moisture_nominal": float(fuel["moisture"]),
        "kg_per_kJ_cmd": kg_per_kj,
        "dt_fg_K": dt_fg,
        "q_fuel_max_kW": q_fuel_max,
    }
    return par, info


def _check_boiler(boiler) -> None:
    if not isinstance(boiler, dict) or "p_nom_kW" not in boiler or "fuel" not in boiler:
        raise ValueError("boiler must be the parsed YAML of one boiler parameter file")


def run_plant(
    boiler: dict,
    test: str,
    *,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
) -> tuple[dict[str, np.ndarray], dict]:
    """Run the plant and bench; returns the true per-second signals and the run's figures."""
    _check_boiler(boiler)
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    effect, form = resolve(effect, form, strength)
    schedule = load_schedule(test)
    eff = effect_settings(effect, form, strength, body_capacity_kJ_K(boiler))
    par, info = kernel_parameters(boiler, schedule, background, eff)
    rng = np.random.default_rng(seed)
    n_max = int(
        schedule.preheat_max_s
        + schedule.startup_max_s
        + schedule.test_duration_s
        + schedule.cooling2_until_after_t2_s
        + 2
    )
    t = np.arange(n_max, dtype=np.float64)
    room = background["room_temp_mean_C"] + background["room_swing_K"] * np.sin(
        2.0 * math.pi * t / 86_400.0 + background["room_phase_rad"]
    )
    normals = rng.standard_normal((n_max, 2))
    out, times = K.run_kernel(
        par,
        schedule.seq_start_s,
        schedule.seq_duration_s,
        schedule.seq_load_from,
        schedule.seq_load_to,
        room,
        normals,
    )
    n = out.shape[0]
    truth = {name: out[:, i].copy() for i, name in enumerate(K.OUT_NAMES)}
    truth["room_C"] = room[:n].copy()
    info.update(
        effect=effect,
        form=form,
        eff=eff,
        schedule=schedule,
        times=[float(x) for x in times],
        rng=rng,
        par=par,
    )
    return truth, info


def simulate_log(
    boiler: dict,
    test: str,
    *,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
    sample_s: float = 1.0,
    jitter: bool = False,
) -> tuple[dict[str, np.ndarray], dict]:
    """Simulate one lab test of one boiler; returns (columns, meta). See the package doc."""
    try:
        sample_s = float(sample_s)
    except (TypeError, ValueError):
        raise ValueError(f"sample_s must be a positive number, got {sample_s!r}") from None
    if not sample_s > 0.0 or not math.isfinite(sample_s):
        raise ValueError(f"sample_s must be a positive number, got {sample_s!r}")
    truth, info = run_plant(
        boiler,
        test,
        background=background,
        effect=effect,
        form=form,
        strength=strength,
        seed=seed,
    )
    rng = info.pop("rng")
    schedule = info["schedule"]
    per_s = measure(truth, background, info["eff"], info, rng)
    n = truth["t_water_C"].shape[0]

    rows_t = np.arange(0.0, n - 1, sample_s)
    if jitter:
        rows_t = rows_t + np.clip(
            rng.normal(0.0, 0.08 * min(sample_s, 5.0), rows_t.size), -0.4, 0.4
        )
        stall = rng.random(rows_t.size) < 0.002  # the logger stalls now and then
        rows_t = rows_t + np.where(stall, rng.uniform(0.5, 1.5, rows_t.size) * sample_s, 0.0)
        keep = rng.random(rows_t.size) >= 0.005  # dropped rows
        keep[0] = True
        rows_t = np.maximum.accumulate(np.clip(rows_t[keep], 0.0, n - 1))
        rows_t = np.round(rows_t, 3)
        _, first = np.unique(rows_t, return_index=True)
        rows_t = rows_t[np.sort(first)]
    idx = np.clip(np.round(rows_t).astype(np.int64), 0, n - 1)

    phase_code = truth["phase_code"].astype(np.int64)
    seq_index = truth["seq_index"].astype(np.int64)
    phase_names = np.array(K.PHASE_NAMES, dtype=object)
    phase_col = phase_names[phase_code[idx]]
    seq_names = np.array(schedule.seq_names, dtype=object)
    seq_col = np.where(seq_index[idx] >= 0, seq_names[np.clip(seq_index[idx], 0, None)], phase_col)
    columns: dict[str, np.ndarray] = {
        "time_s": rows_t.astype(np.float64),
        "phase": phase_col.astype(object),
        "sequence": seq_col.astype(object),
    }
    for name in COLUMNS[3:]:
        columns[name] = per_s[name][idx]

    times = info["times"]
    meta = {
        "effect": info["effect"] or "none",
        "form": info["form"],
        "strength": float(strength) if info["effect"] else 0.0,
        "background": dict(background),
        "boiler": str(boiler.get("name", "")),
        "test": test,
        "seed": int(seed),
        "sample_s": sample_s,
        "jitter": bool(jitter),
        "t0_s": times[0],
        "t1_s": times[1],
        "t2_s": times[2],
        "t3_s": times[3],
        "t4_s": times[4],
        "effect_settings": dict(info["eff"]),
        "fuel_fed_kg": float(truth["feed_kg"].sum()),
        "fuel_burnt_kg": float(truth["burn_kg"].sum()),
        "fuel_unburnt_kg": float(truth["sift_kg"].sum()),
        "burner_starts": int(np.sum(np.diff(truth["boiler_on"]) > 0.5) + truth["boiler_on"][0]),
        "light_off_times_s": [float(x) for x in np.flatnonzero(np.diff(truth["lit"]) > 0.5) + 1.0],
        "hhv_true_dry_kJ_kg": info["hhv_true_dry_kJ_kg"],
        "moisture_true": info["moisture_true"],
    }
    return columns, meta


def _fmt(x) -> str:
    if isinstance(x, str):
        return x
    if x is None:
        return ""
    xf = float(x)
    if math.isnan(xf):
        return ""
    if float(xf).is_integer() and abs(xf) < 1e15:
        return str(int(xf))
    return repr(round(xf, 6))


def write_log_csv(columns: dict[str, np.ndarray], path) -> None:
    """Write the log as CSV: header row, `time_s` first, NaN as an empty field."""
    names = ["time_s"] + [c for c in columns if c != "time_s"]
    if "time_s" not in columns:
        raise ValueError("columns must contain 'time_s'")
    n = len(columns["time_s"])
    for c in names:
        if len(columns[c]) != n:
            raise ValueError(f"column {c!r} has {len(columns[c])} rows, expected {n}")
    path = Path(path)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(names)
        cols = [columns[c].tolist() for c in names]
        for row in zip(*cols, strict=True):
            writer.writerow([_fmt(x) for x in row])
