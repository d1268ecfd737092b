"""A random real boiler and bench around the documentation values (:func:`draw_background`).

Everything a real boiler and lab do that Type 869 does not list: the controller's own
program and tuning, start-up, stratification and sensor height, an exchanger whose exit
temperature follows the gas flow (load) rather than the water flow, a fan with its own
lambda curve, the bench's return conditioning, instrument offsets, drifts, noise and
quantisation. Each value is drawn uniformly from a documented range (the comments give the
ranges' sources or reasons); the ranges are set so that the gap between this plant without
an effect and the Type 869 model calibrated on it spans the paper's Table 4 in the test
phase (measured by bench/reality2_gap.py).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _pm(rng: np.random.Generator, half: float) -> float:
    return float(rng.uniform(-half, half))


def draw_background(rng: np.random.Generator, boiler: Mapping) -> dict:
    """One real boiler and bench, as a flat dict of named values (units in the names)."""
    scale = float(boiler["p_nom_kW"]) / 12.0
    weights = np.array([0.15, 0.2, 0.25, 0.4]) * rng.uniform(0.7, 1.3, 4)
    weights /= weights.sum()
    bw_height = _u(rng, 0.3, 1.6)  # boiler sensor below the top node, in nodes
    return {
        # --- the room (digest section 5: 18-30 C, 969-1004 hPa)
        "room_base_C": _u(rng, 19.0, 27.0),
        "room_amp_K": _u(rng, 0.2, 1.2),
        "room_phase_s": _u(rng, 0.0, 86400.0),
        "room_ou_sig_K": _u(rng, 0.05, 0.25),
        "room_ou_tau_s": _u(rng, 1800.0, 5400.0),
        "pressure_hPa": _u(rng, 970.0, 1003.0),
        "rh_pct": _u(rng, 30.0, 60.0),
        "t_init_C": _u(rng, 28.0, 42.0),
        # --- controller (own program; set, shut-off and restart near the paper's 70/85/55 C)
        "set_offset_K": _pm(rng, 0.5),
        "ctrl_sensor_offset_K": _pm(rng, 0.4),
        "shutoff_offset_K": _u(rng, -1.0, 1.0),
        "restart_offset_K": _u(rng, -1.0, 0.5),
        "stop_hyst_K": _u(rng, 14.0, 17.0),
        "min_burn_s": _u(rng, 900.0, 1800.0),
        "min_off_s": _u(rng, 180.0, 600.0),
        "prop_band_K": _u(rng, 4.0, 10.0),
        "ti_s": _u(rng, 240.0, 720.0),
        "n_stages": float(rng.integers(4, 13)),
        "ramp_s": _u(rng, 120.0, 360.0),
        "start_hold_s": _u(rng, 600.0, 1100.0),
        "ramp_handover_K": _u(rng, 1.0, 4.0),
        "burnout_s": _u(rng, 240.0, 600.0),
        "prepurge_s": _u(rng, 30.0, 90.0),
        "ign_program_s": _u(rng, 90.0, 240.0),
        # the charge lands on a grate the igniter's hot air has preheated since the
        # pre-purge and lights within seconds: fuel fed a minute or more before the bed
        # burns is the listed ignition_delay (CONTRACT section 4), which a plant without an
        # effect must not carry (its forms add 120-600 s, effects.py)
        "ign_delay_bg_s": _u(rng, 5.0, 15.0),
        "charge_ar_kg": _u(rng, 0.06, 0.14) * scale,
        "igniter_W": _u(rng, 350.0, 500.0),
        "igniter_energy_factor": _u(rng, 0.85, 1.15),
        "auger_period_s": _u(rng, 10.0, 25.0),
        "auger_duty_max": _u(rng, 0.6, 0.85),
        "auger_bias": _pm(rng, 0.02),
        "auger_W": _u(rng, 8.0, 20.0),
        "pel_off_factor": _u(rng, 0.85, 1.15),
        "pel_factor": _u(rng, 0.9, 1.1),
        "p_max_headroom": _u(rng, 0.15, 0.25),  # firing reserve above the documented Pmax
        "p_min_factor": _u(rng, 0.98, 1.02),
        "p_start_factor": _u(rng, 0.9, 1.0),
        "tau_bed_s": _u(rng, 25.0, 70.0),
        "feed_sig": _u(rng, 0.1, 0.3),  # pellet mass per auger period varies
        "smoulder_stop": _u(rng, 1.5, 3.0),
        # --- fan and combustion
        "lam_a_factor": 1.0 + _pm(rng, 0.06),
        "lam_b_factor": 1.0 + _pm(rng, 0.1),
        "lam_curv_h2_kg2": _pm(rng, 0.15) / scale**2,
        "tau_fan_s": _u(rng, 5.0, 20.0),
        "co_pmax_ppm": _u(rng, 40.0, 150.0),
        "co_pmin_ppm": _u(rng, 100.0, 400.0),
        "co_start_ppm": _u(rng, 800.0, 2500.0),
        "hhv_factor": 1.0 + _pm(rng, 0.01),
        "moisture_delta": _pm(rng, 0.005),
        # --- body and exchanger
        "steel_factor": _u(rng, 0.85, 1.2),
        "tau_steel_water_s": _u(rng, 20.0, 60.0),
        "heat_weights": [float(w) for w in weights],
        "g_mix_stable_kW_K": _u(rng, 0.3, 1.0) * scale,
        "g_mix_unstable_kW_K": _u(rng, 1.0, 3.0) * scale,
        "bw_height_nodes": bw_height,
        "ua_jacket_factor": _u(rng, 0.9, 1.15),
        "draught_factor": _u(rng, 0.7, 1.3),
        "draught_eff": _u(rng, 0.8, 0.98),
        "dt_fg_factor": 1.0 + _pm(rng, 0.05),
        "dt_x_exp": _u(rng, 0.05, 0.35),
        "pipe_bg_volume_L": _u(rng, 0.05, 0.2),
        "pipe_bg_ua_W_K": _u(rng, 0.05, 0.2),
        "pipe_bg_g_back_W_K": _u(rng, 3.0, 8.0),
        # --- bench
        "tau_flow_s": _u(rng, 5.0, 20.0),
        "flow_ripple": _u(rng, 0.001, 0.005),
        "loop_volume_L": _u(rng, 15.0, 40.0),
        "loop_ua_W_K": _u(rng, 3.0, 10.0),
        "t_cold_C": _u(rng, 10.0, 16.0),
        "valve_max": _u(rng, 0.3, 0.45),
        "valve_stroke_s": _u(rng, 60.0, 180.0),
        "valve_deadband": _u(rng, 0.005, 0.02),  # stiction of the mixing valve
        "tau_return_s": _u(rng, 5.0, 20.0),
        "bench_kp_per_K": _u(rng, 0.08, 0.25),
        "bench_ti_s": _u(rng, 60.0, 200.0),
        "heater_factor": _u(rng, 1.0, 1.5),
        # --- instruments
        "flow_bias": _pm(rng, 0.005),
        "flow_noise_rel": _u(rng, 0.002, 0.005),
        "off_tin_K": _pm(rng, 0.15),
        "off_tout_K": _pm(rng, 0.15),
        "drift_tin_K_h": _pm(rng, 0.01),
        "drift_tout_K_h": _pm(rng, 0.01),
        "noise_tw_K": _u(rng, 0.01, 0.03),
        "off_tbw_K": _pm(rng, 2.0),  # sensor in a well of the body, poor contact
        "drift_tbw_K_h": _pm(rng, 0.02),
        "noise_tbw_K": _u(rng, 0.02, 0.06),
        "q_tbw_K": float(rng.choice([0.01, 0.1])),
        "off_tfg_K": _pm(rng, 0.3),
        "rel_tfg": _pm(rng, 0.005),
        "off_o2_pct": _pm(rng, 0.1),
        "drift_o2_pct_h": _pm(rng, 0.01),
        "rel_co2": _pm(rng, 0.01),
        "an_delay_s": _u(rng, 10.0, 40.0),
        "an_tau_s": _u(rng, 5.0, 15.0),
        "tau_tw_s": _u(rng, 3.0, 8.0),
        "tau_bw_s": _u(rng, 10.0, 30.0),
        "tau_fg_s": _u(rng, 10.0, 30.0),
        "bal_m0_kg": _u(rng, 200.0, 350.0),
        "bal_res_kg": float(rng.choice([0.01, 0.02])),
        "bal_noise_kg": _u(rng, 0.003, 0.01),
        "bal_vib_kg": _u(rng, 0.01, 0.05),
        "bal_drift_kg_h": _pm(rng, 0.005),
        "off_room_K": _pm(rng, 0.2),
        "draught_sig_Pa": _u(rng, 0.3, 1.0),
        "dropout_prob": _u(rng, 1e-4, 1e-3),
        "analyser_gap": bool(rng.random() < 0.5),
    }
