"""One case's background: the quirks by which this real boiler and bench differ from Type 869.

Every value is a plain float drawn from the generator in a fixed order (deterministic in rng).
Ranges are chosen so that a calibrated one-node model misses the test phase by about Table 4
of the paper (T RMSD 1-3 K, Q RMSD 0.3-0.7 kW); see the package docstring for the physics.
"""

from __future__ import annotations

import numpy as np


def draw_background(rng: np.random.Generator, boiler: dict) -> dict[str, float]:
    """Draw one case's background quirks (plain floats) for ``boiler`` (parsed YAML mapping)."""
    u = rng.uniform
    p_nom = float(boiler["p_nom_kW"])
    bg: dict[str, float] = {
        # room and air
        "room_C": u(18.0, 30.0),
        "room_drift_K": u(0.2, 1.0),
        "room_period_h": u(5.0, 14.0),
        "room_phase": u(0.0, 2 * np.pi),
        "pressure_hPa": u(969.0, 1004.0),
        "humidity_pct": u(30.0, 60.0),
        # body: real capacity, metal share, metal-water coupling, envelope, idle draught
        "cap_factor": u(0.92, 1.08),
        "tau_mw_s": u(40.0, 100.0),
        "ua_env_factor": u(0.8, 1.2),
        "draught_factor": u(0.8, 1.25),
        # exchanger: flue-gas temperature level and its load dependence
        "dt_fg_factor": u(0.9, 1.1),
        "ntu_exp": u(0.12, 0.3),
        # combustion air: own excess-air curve
        "lam_a_factor": u(0.95, 1.05),
        "lam_b_factor": u(0.9, 1.1),
        "co_base_ppm": u(20.0, 120.0),
        # fuel lot and feeding
        "hhv_bias": float(np.clip(rng.normal(0.0, 0.006), -0.012, 0.012)),
        "moisture_delta": u(-0.005, 0.005),
        "feed_cal": u(0.99, 1.06),
        "density_sd": u(0.02, 0.06),
        "density_tau_s": u(120.0, 600.0),
        "auger_period_s": u(8.0, 20.0),
        "tau_bed_s": u(40.0, 90.0),
        # normal start: pre-purge, preload, ignition, stabilisation at full fire
        "t_purge_s": u(30.0, 60.0),
        "t_preload_s": u(30.0, 60.0),
        "t_ign_extra_s": u(30.0, 90.0),
        "t_stab_s": u(600.0, 1000.0),
        "t_ign_after_s": u(180.0, 360.0),
        "p_ign_W": u(280.0, 400.0),
        "min_pause_s": u(300.0, 900.0),
        # own controller
        "set_offset_K": float(rng.choice([-1.0, 1.0])) * u(0.2, 0.8),
        "wb_strat_K": float(rng.choice([-1.0, 1.0])) * u(1.0, 2.5),
        "off_offset_K": u(-0.5, 0.5),
        "restart_offset_K": u(0.3, 0.8),  # above the 55 C return
        "ctrl_sensor_offset_K": u(-0.3, 0.2),
        "kp_kW_K": u(0.15, 0.35) * p_nom / 6.0,
        "ti_s": u(250.0, 600.0),
        "rate_pct_s": u(0.4, 1.2),
        "tau_ctrl_s": u(15.0, 40.0),
        "pel_factor": u(0.9, 1.1),
        # bench: return conditioning loop
        "c_loop_kJ_K": u(60.0, 120.0),
        "kb_p_kW_K": u(0.6, 1.5) * p_nom / 12.0,
        "kb_i_s": u(80.0, 200.0),
        "cool_cap_factor": u(1.3, 1.8),
        "heat_cap_kW": u(3.0, 6.0),
        "tau_valve_s": u(10.0, 40.0),
        "tau_flow_s": u(5.0, 15.0),
        # normal exit pipe (sensor pocket 30 cm down an insulated pipe)
        "pipe_ua_W_K": u(0.005, 0.02),
        "pipe_g_ax_W_K": u(0.02, 0.06),
        # sensors
        "tau_out_s": u(5.0, 20.0),
        "tau_wb_s": u(15.0, 40.0),
        "tau_fg_s": u(20.0, 45.0),
        "off_in_K": u(-0.15, 0.15),
        "off_out_K": u(-0.15, 0.15),
        "off_wb_K": u(-0.3, 0.3),
        "off_fg_K": u(-1.0, 1.0),
        "off_o2_pct": u(-0.2, 0.2),
        "drift_o2_pct": u(-0.2, 0.2),
        "flow_gain": u(0.99, 1.01),
        "o2_delay_s": u(15.0, 40.0),
        "o2_tau_s": u(8.0, 20.0),
        "duct_d_m": u(0.07, 0.09),
        # initial state before preheat
        "t_init_C": u(40.0, 44.0),
        "t_init_metal_dK": u(-1.5, 0.5),
        "hopper_kg": u(25.0, 40.0),
    }
    return {k: float(v) for k, v in bg.items()}
