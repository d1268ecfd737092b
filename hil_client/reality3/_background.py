"""The random "real boiler and bench" around the documentation values.

Everything here is a plain float (relative factors where a documented value exists), so a
background is JSON-serialisable and reusable for both boilers.
"""

from __future__ import annotations

import numpy as np


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _n(rng: np.random.Generator, sd: float, lim: float) -> float:
    return float(np.clip(rng.normal(0.0, sd), -lim, lim))


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """Draw the real plant, controller, bench and instruments around ``boiler``'s documentation.

    The draws make the plant differ from the one-node Type 869 (paper Eq. 1-10) the way a
    real boiler does: a steel node apart from the water (Eq. 2 lumps them), an exchanger whose
    flue-gas temperature follows convective heat transfer instead of Eq. 8, a burner fed in
    auger pulses with varying pellet density, a PI controller with its own sensor offset and
    start/stop rules, natural draught through the idle boiler (Eq. 14-16 made explicit), a
    stratification bias at the body sensor and a bench with finite return conditioning.
    """
    sign = 1.0 if rng.uniform() < 0.5 else -1.0
    bg = {
        # thermal body
        "k_capacity": _u(rng, 0.92, 1.12),
        "steel_share": _u(rng, 0.33, 0.45),
        "tau_steel_water_s": _u(rng, 20.0, 60.0),
        "k_ua_env": _u(rng, 0.75, 1.30),
        "k_draught": _u(rng, 0.70, 1.40),
        "chamber_loss_share": _u(rng, 0.004, 0.015),
        "unburnt_carbon_bg": _u(rng, 0.001, 0.004),
        # exchanger / flue gas
        "k_dt_nom": _u(rng, 0.93, 1.07),
        "n_ua": _u(rng, 0.85, 1.15),
        # fuel feed and air
        "k_auger": float(np.clip(rng.normal(1.015, 0.02), 0.985, 1.07)),
        "k_lambda": _u(rng, 0.94, 1.06),
        "lambda_noise_sd": _u(rng, 0.015, 0.040),
        "lambda_noise_tau_s": _u(rng, 60.0, 300.0),
        "density_noise_sd": _u(rng, 0.04, 0.10),
        "density_noise_tau_s": _u(rng, 30.0, 300.0),
        "co_base_ppm": _u(rng, 25.0, 70.0),
        # controller
        "ctrl_offset_K": _n(rng, 0.4, 0.9),
        "t_off_C": _u(rng, 84.0, 86.5),
        "t_restart_true_C": _u(rng, 55.0, 56.0),
        "t_off_max_s": _u(rng, 5400.0, 7200.0),
        "kp_rel": _u(rng, 0.5, 1.5),
        "ti_s": _u(rng, 180.0, 600.0),
        "tau_ctrl_s": _u(rng, 10.0, 30.0),
        "t_min_burn_s": _u(rng, 600.0, 1200.0),
        "t_min_off_s": _u(rng, 180.0, 600.0),
        # start-up and shutdown
        "t_prepurge_s": _u(rng, 20.0, 60.0),
        "t_catch_s": _u(rng, 40.0, 110.0),
        "t_detect_s": _u(rng, 10.0, 30.0),
        "p_igniter_W": _u(rng, 250.0, 420.0),
        "k_ignition_energy": _u(rng, 0.7, 1.2),
        "charge_kg_12kw": _u(rng, 0.03, 0.06),
        "t_ramp_s": _u(rng, 60.0, 200.0),
        "t_hold_max_s": _u(rng, 600.0, 1080.0),
        "dt_hold_exit_K": _u(rng, 1.5, 4.0),
        "t_post_s": _u(rng, 300.0, 900.0),
        "tau_bed_s": _u(rng, 40.0, 90.0),
        "t_auger_s": _u(rng, 12.0, 40.0),
        "k_auger_max": _u(rng, 1.3, 1.8),
        "v_ign_frac": _u(rng, 0.20, 0.35),
        "v_purge_frac": _u(rng, 0.80, 1.10),
        "v_post_frac": _u(rng, 0.50, 0.90),
        "tau_fan_s": _u(rng, 4.0, 12.0),
        # electricity
        "k_pel_off": _u(rng, 0.85, 1.15),
        "p_el_ctrl_W": _u(rng, 3.0, 7.0),
        "p_auger_on_W": _u(rng, 30.0, 55.0),
        "k_pel_max": _u(rng, 0.90, 1.10),
        # bench
        "bench_volume_l": _u(rng, 20.0, 45.0),
        "bench_ua_W_K": _u(rng, 3.0, 8.0),
        "k_cool_capacity": _u(rng, 1.5, 2.5),
        "t_cold_C": _u(rng, 10.0, 16.0),
        "kp_bench": _u(rng, 0.08, 0.20),
        "ti_bench_s": _u(rng, 60.0, 200.0),
        "tau_valve_s": _u(rng, 8.0, 25.0),
        "valve_dead_band": _u(rng, 0.003, 0.015),
        "cold_side_sd": _u(rng, 0.03, 0.08),
        "cold_side_tau_s": _u(rng, 30.0, 120.0),
        "tau_flow_s": _u(rng, 4.0, 15.0),
        "flow_ripple_sd": _u(rng, 0.003, 0.010),
        "flow_ripple_tau_s": _u(rng, 10.0, 60.0),
        "t_floor_cooling_1_C": _u(rng, 48.0, 52.0),
        # room
        "t_room_C": _u(rng, 18.0, 28.0),
        "room_day_amp_K": _u(rng, 0.5, 2.0),
        "room_day_phase": _u(rng, 0.0, 2.0 * np.pi),
        "room_noise_sd_K": _u(rng, 0.1, 0.4),
        "pressure_hPa": _u(rng, 969.0, 1004.0),
        "pressure_sd_hPa": _u(rng, 0.3, 1.5),
        "rh_pct": _u(rng, 30.0, 65.0),
        "rh_sd_pct": _u(rng, 1.0, 5.0),
        "t_init_C": _u(rng, 43.5, 46.5),
        "t_init_bench_dK": _n(rng, 1.0, 2.0),
        # instruments
        "off_tin_K": _n(rng, 0.12, 0.3),
        "off_tout_K": _n(rng, 0.12, 0.3),
        "off_tbw_K": _n(rng, 0.12, 0.3),
        "drift_tin_K_10h": _n(rng, 0.03, 0.08),
        "drift_tout_K_10h": _n(rng, 0.03, 0.08),
        "drift_tbw_K_10h": _n(rng, 0.03, 0.08),
        "tau_tin_s": _u(rng, 3.0, 8.0),
        "tau_tout_s": _u(rng, 3.0, 8.0),
        "tau_tbw_s": _u(rng, 15.0, 45.0),
        "strat_beta": sign * _u(rng, 0.03, 0.12),
        "off_tfg_class_B": _u(rng, -1.0, 1.0),
        "tau_tfg_s": _u(rng, 15.0, 40.0),
        "o2_delay_s": _u(rng, 30.0, 90.0),
        "tau_o2_s": _u(rng, 8.0, 20.0),
        "off_o2_pct": _n(rng, 0.08, 0.2),
        "span_o2": _u(rng, 0.985, 1.015),
        "drift_o2_pct_10h": _n(rng, 0.05, 0.15),
        "tau_co2_s": _u(rng, 10.0, 25.0),
        "off_co2_pct": _n(rng, 0.05, 0.15),
        "span_co2": _u(rng, 0.98, 1.02),
        "tau_co_s": _u(rng, 15.0, 30.0),
        "velocity_nom_m_s": _u(rng, 2.3, 3.0),
        "balance_kg": _u(rng, 18.0, 30.0),
        "balance_step_kg": 0.01 if rng.uniform() < 0.5 else 0.02,
        "balance_noise_kg": _u(rng, 0.002, 0.008),
        "flow_gain": _n(rng, 0.003, 0.008),
        "off_room_K": _n(rng, 0.2, 0.5),
        "off_pressure_hPa": _n(rng, 0.5, 1.5),
        "off_rh_pct": _n(rng, 2.0, 5.0),
    }
    bg["boiler"] = str(boiler.get("name", "unnamed"))
    return bg
