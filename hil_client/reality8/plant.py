"""Parameter vector of the plant: boiler YAML (documentation values) + background quirks.

The boiler YAML gives what the documentation says; the real plant's exchanger is a physical
NTU exchanger calibrated (here) so that at full firing and 70/55 C its flue gas leaves about
dt_nom * dt_fg_factor above the return, i.e. near what the lab calibration of Type 869 finds.
"""

from __future__ import annotations

import math

import numpy as np

from .fuel import DH_VAP_KJ_KG, stoichiometry
from .kernel import CP_AIR, CP_FG, CP_VAP, CP_W, N_PARAMS, PARAM_NAMES
from .protocol import COOLING_1, COOLING_2_AFTER_T2_S, FLOW_SPREAD_K, PREHEAT, START_UP

DESIGN_ROOM_C = 22.0  # room temperature at which the exchanger is sized (assumption)


def nominal_gas(boiler: dict, bg: dict, hhv_true: float, w_ar: float) -> dict[str, float]:
    """Flue-gas capacity flow and adiabatic temperature at full firing (p_max).

    W_g = (m_dry,gas cp_fg + m_vap cp_vap) / 3600 [kW/K];  T_ad = T_room + Q_gas / W_g with
    Q_gas = Q_fuel - Q_ash - Q_lat (complete combustion, HHV basis, Eq. 1/4/6 of the paper).
    """
    fuel = boiler["fuel"]
    st = stoichiometry(fuel)
    h = float(fuel["h"])
    dry_h = float(boiler["p_max_kW"]) / st["lhv_ar"] * (1.0 - w_ar) * 3600.0
    lam = (
        float(boiler["fac_a_lambda"]) * bg["lam_a_factor"]
        + float(boiler["fac_b_lambda_h_kg"]) * bg["lam_b_factor"] * dry_h
    )
    m_air = st["air_min_mass"] * dry_h * lam
    m_vap = (9.0 * h + w_ar / (1.0 - w_ar)) * dry_h
    m_dry_gas = m_air + (1.0 - float(fuel["ash"]) - 9.0 * h) * dry_h
    w_g = (m_dry_gas * CP_FG + m_vap * CP_VAP) / 3600.0
    q_fuel = dry_h / 3600.0 * hhv_true
    q_gas = q_fuel * (1.0 - 0.0002) - m_vap * DH_VAP_KJ_KG / 3600.0
    return {"w_g": w_g, "t_ad": DESIGN_ROOM_C + q_gas / w_g, "m_air": m_air, "q_gas": q_gas}


def build_params(boiler: dict, bg: dict) -> dict[str, float]:
    """All kernel parameters (names of ``PARAM_NAMES``) for the background plant, no effect."""
    fuel = boiler["fuel"]
    st = stoichiometry(fuel)
    p_nom = float(boiler["p_nom_kW"])
    p_max = float(boiler["p_max_kW"])
    w_ar = float(fuel["moisture"]) + bg["moisture_delta"]
    hhv_true = float(fuel["hhv_dry_kJ_kg"]) * (1.0 + bg["hhv_bias"])
    c_w = float(boiler["vol_water_m3"]) * 1000.0 * CP_W * bg["cap_factor"]
    c_m = float(boiler["c_therm_kJ_K"]) * bg["cap_factor"]
    g_mw = c_m / bg["tau_mw_s"]
    gas = nominal_gas(boiler, bg, hhv_true, w_ar)
    # exchanger sized so that T_fg = 55 + dt_nom*f at full fire with the wall ~ 70 C + q/g_mw
    t_fg = 55.0 + float(boiler["dt_nom_K"]) * bg["dt_fg_factor"]
    q_hx = gas["w_g"] * (gas["t_ad"] - t_fg)
    t_wall = 70.0 + q_hx / g_mw
    eff = (gas["t_ad"] - t_fg) / (gas["t_ad"] - t_wall)
    ntu_nom = -math.log(1.0 - min(eff, 0.999))
    ua_diff = max(float(boiler["ua_amb_off_W_K"]) - float(boiler["ua_amb_on_W_K"]), 0.3)
    p = {
        "c_w": c_w, "c_m": c_m, "c_a": 0.0, "c_b": 0.0, "g_ab": 0.0, "g_bm": 0.0,
        "f_rad": 0.0, "g_mw": g_mw, "c_pl": 0.0, "f_pl": 0.0, "g_pw": 0.0,
        "ua_env": float(boiler["ua_amb_on_W_K"]) * bg["ua_env_factor"] / 1000.0,
        "m_draught_ref": ua_diff * bg["draught_factor"] / (CP_AIR * 1000.0) * 3600.0,
        "ntu_nom": ntu_nom, "w_g_nom": gas["w_g"], "ntu_exp": bg["ntu_exp"],
        "c_e": 0.0, "g_ew": 0.0, "eps_e": 0.0, "c_l": 0.0, "eps_l": 0.0, "ua_l": 0.0,
        "n_pipe": 1.0, "c_cell": 0.7, "ua_cell": bg["pipe_ua_W_K"] / 1000.0,
        "g_ax": bg["pipe_g_ax_W_K"] / 1000.0, "strat": 0.0, "c_bot": 0.0, "ua_bot": 0.0,
        "g_mix0": 0.0, "k_mix": 0.0,
        "hhv_true": hhv_true, "w_ar": w_ar, "ash": float(fuel["ash"]), "h": float(fuel["h"]),
        "air_min_mass": st["air_min_mass"], "o2_need": st["o2_need"], "v_co2": st["v_co2"],
        "v_so2": st["v_so2"], "v_n2f": st["v_n2f"], "lhv_ar_nom": st["lhv_ar"],
        "def_mode": 0.0, "def_a": 0.0,
        "p_max": p_max, "p_min": float(boiler["p_min_kW"]),
        "p_start": float(boiler["p_start_kW"]), "feed_cal": bg["feed_cal"],
        "auger_period": bg["auger_period_s"], "tau_bed": bg["tau_bed_s"], "tau_dry": 0.0,
        "t_ign_need": bg["t_preload_s"] + bg["t_ign_extra_s"], "t_preload": bg["t_preload_s"],
        "t_purge": bg["t_purge_s"], "t_stab": bg["t_stab_s"], "t_ign_after": bg["t_ign_after_s"],
        "min_pause": bg["min_pause_s"],
        "lam_a": float(boiler["fac_a_lambda"]) * bg["lam_a_factor"],
        "lam_b": float(boiler["fac_b_lambda_h_kg"]) * bg["lam_b_factor"],
        "m_air_purge": 0.6 * gas["m_air"], "p_ign": bg["p_ign_W"] / 1000.0,
        "pel_min": float(boiler["p_el_min_W"]) * bg["pel_factor"],
        "pel_max": float(boiler["p_el_max_W"]) * bg["pel_factor"],
        "pel_off": float(boiler["p_el_off_W"]), "co_base": bg["co_base_ppm"],
        "t_set": 70.0 + bg["set_offset_K"], "t_off": 85.0 + bg["off_offset_K"],
        "t_restart": 55.0 + bg["restart_offset_K"], "kp": bg["kp_kW_K"], "ti": bg["ti_s"],
        "rate": bg["rate_pct_s"] / 100.0 * p_max, "tau_ctrl": bg["tau_ctrl_s"],
        "ctrl_offset": bg["ctrl_sensor_offset_K"],
        "c_loop": bg["c_loop_kJ_K"], "kb_p": bg["kb_p_kW_K"], "kb_i": bg["kb_i_s"],
        "q_cool_cap": bg["cool_cap_factor"] * p_max, "q_heat_cap": bg["heat_cap_kW"],
        "tau_valve": bg["tau_valve_s"], "tau_flow": bg["tau_flow_s"],
        "flow_nom": p_nom * 3600.0 / (CP_W * FLOW_SPREAD_K),
        "c_inpipe": 0.5, "ua_inpipe": 1.0e-5, "g_inpipe": 3.0e-5,
        "tau_out": bg["tau_out_s"], "tau_wb": bg["tau_wb_s"], "tau_fg": bg["tau_fg_s"],
        "wb_strat": bg["wb_strat_K"], "p_nom": p_nom,
        "pre_T": PREHEAT["temperature_C"], "pre_tol": PREHEAT["tolerance_K"],
        "pre_hold": PREHEAT["hold_s"], "pre_max": PREHEAT["max_duration_s"],
        "pre_load": PREHEAT["load_pct"], "ret_sp_pre": PREHEAT["temperature_C"],
        "ret_sp": START_UP["return_setpoint_C"], "su_window": START_UP["t1_window_s"],
        "su_rise": START_UP["t1_max_rise_K_min"], "su_min": START_UP["min_duration_s"],
        "su_max": START_UP["max_duration_s"], "su_fg_min_rise": 15.0,
        "c1_load": COOLING_1["load_pct"], "c1_until": COOLING_1["until_forward_C"],
        "c1_max": COOLING_1["max_duration_s"], "c2_after": COOLING_2_AFTER_T2_S,
        "t_init_w": bg["t_init_C"], "t_init_m": bg["t_init_C"] + bg["t_init_metal_dK"],
    }  # fmt: skip
    return p


def to_array(params: dict[str, float]) -> np.ndarray:
    """Parameter dict -> vector in kernel order (every name required)."""
    missing = set(PARAM_NAMES) - set(params)
    if missing:
        raise KeyError(f"missing kernel parameters: {sorted(missing)}")
    arr = np.array([float(params[n]) for n in PARAM_NAMES])
    assert arr.shape == (N_PARAMS,)
    return arr
