"""Effect vocabulary and the random per-case background of the reality9 plant.

The background is what makes this boiler differ from Type 869 even without a listed
effect: its own PI controller (anti-windup, minimum burn time, own restart rule), its own
start-up (pre-purge, ignition charge, fuel ramp), an exchanger whose NTU depends on the gas
flow, a bench return conditioning with a capacity limit, a lag and valve hunting, lumpy
auger feeding, and sensor offsets, lags and slow drifts.
"""

from __future__ import annotations

import math

import numpy as np

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("fire_side_steel_skin", "three_shell_conduction_chain"),
    "outlet_sensor_pipe": ("lossy_exit_cells", "aging_parcel_transit"),
    "ignition_delay": ("slow_kindling_front", "gradual_pyrolysis_onset"),
    "flue_gas_lag": ("hearth_stone_buffer", "baffle_cascade_pair"),
    "fuel_energy_bias": ("damp_delivery_lot", "cold_wall_char_residue"),
}

SENSORS = ("ctrl", "bw", "out", "in", "fg")
# (offset half-range K, lag range s, drift rate half-range K/h, drift amplitude max K)
_SENSOR_SPEC = {
    "ctrl": (0.6, (15.0, 40.0), 0.05, 0.4),
    "bw": (2.0, (10.0, 30.0), 0.06, 0.5),  # pocket in stratified water
    "out": (0.2, (4.0, 12.0), 0.03, 0.25),
    "in": (0.2, (4.0, 10.0), 0.03, 0.25),
    "fg": (1.0, (20.0, 60.0), 0.10, 0.8),
}


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """One case's random background: a flat dict of plain floats."""
    p_nom = float(boiler["p_nom_kW"])
    u = rng.uniform
    bg: dict = {
        # boiler body and fuel
        "cap_factor": u(0.95, 1.05),
        "ua_on_factor": u(0.8, 1.25),
        "ua_off_factor": u(0.85, 1.15),
        "hhv_factor": u(0.99, 1.01),
        "moisture_dev": u(-0.008, 0.008),
        # exchanger: flue-gas temperature at nominal and NTU ~ (gas flow)^-exp
        "dt_fg_factor": u(0.93, 1.07),
        "ntu_exp": u(0.15, 0.5),
        # bed and auger
        "tau_bed_s": u(60.0, 150.0),
        "lump_sigma": u(0.05, 0.15),
        "auger_period_s": u(10.0, 25.0),
        "auger_gain": u(0.98, 1.06),
        "fan_factor": u(0.95, 1.06),
        "co_base_ppm": u(40.0, 160.0),
        # controller
        "t_set_C": u(69.2, 70.8),
        "t_off_C": u(83.0, 87.0),
        "t_restart_C": u(52.0, 58.0),
        "t_min_burn_s": u(900.0, 2400.0),
        "t_min_off_s": u(300.0, 900.0),
        "kp_kW_K": u(0.6, 1.6) * p_nom / 12.0,
        "ti_s": u(250.0, 800.0),
        # start-up and stop sequence
        "t_purge_s": u(60.0, 180.0),
        "t_ign_s": u(150.0, 400.0),
        "t_detect_s": u(30.0, 90.0),
        "charge_kg": u(0.008, 0.015) * p_nom,
        "t_charge_s": u(40.0, 90.0),
        "t_ramp_s": u(300.0, 900.0),
        "t_post_s": u(180.0, 420.0),
        # bench: return conditioning and flow
        "rc_tau_s": u(40.0, 120.0),
        "rc_cool_cap": u(1.1, 1.5),
        "rc_heat_cap": u(0.6, 1.0),
        "rc_osc_amp_K": u(0.03, 0.25),
        "rc_osc_period_s": u(120.0, 400.0),
        "flow_tau_s": u(8.0, 25.0),
        "flow_gain": u(0.985, 1.015),
        "t_boiler0_C": u(20.0, 35.0),
        # room
        "room_base_C": u(19.0, 26.0),
        "room_amp_K": u(0.2, 1.2),
        "room_period_h": u(6.0, 20.0),
        "room_phase": u(0.0, 2.0 * math.pi),
        "pressure_hPa": u(972.0, 1000.0),
        "rh_pct": u(30.0, 60.0),
        # instruments
        "gas_delay_s": u(20.0, 45.0),
        "gas_tau_s": u(8.0, 20.0),
        "o2_offset": u(-0.2, 0.2),
        "co2_gain": u(0.99, 1.01),
        "v_nom_m_s": u(1.4, 2.4),
        "v_bias_m_s": u(-0.1, 0.1),
        "balance_m0_kg": u(250.0, 350.0),
        "p_drop": u(0.0, 0.002),
        "el_gain": u(0.95, 1.05),
    }
    for name in SENSORS:
        off, (lo, hi), rate, amp = _SENSOR_SPEC[name]
        bg[f"{name}_offset_K"] = u(-off, off)
        bg[f"{name}_tau_s"] = u(lo, hi)
        bg[f"{name}_drift_K_h"] = u(-rate, rate)
        bg[f"{name}_drift_amp_K"] = u(0.0, amp)
        bg[f"{name}_drift_period_h"] = u(2.0, 8.0)
        bg[f"{name}_drift_phase"] = u(0.0, 2.0 * math.pi)
    return {k: float(v) for k, v in bg.items()}
