"""Random per-case background of the reality10 test bench: everything in which a real
Windhager-type pellet boiler on the Wieselburg bench differs from TRNSYS Type 869 apart from
the five listed effects.

The elements: the boiler's own modulating PI controller (band, reset time, slew limit,
anti-windup, own sensor offset/lag, safety shut-off and restart thresholds, minimum off time),
its own start-up (pre-purge, ignition charge, timer-driven fuel ramp, hold at Pstart) and stop
(bed burn-out, post-ventilation), auger pulsing and combustion-rate fluctuation, a
load-dependent exchanger (flue-gas approach temperature), a perturbed excess-air law, a
split body (metal node linked to the water by a fast conductance), the bench's return
conditioning (capacity limits, lag, small oscillation) and flow loop, sensor offsets / lags /
drifts, the gas analyser (sample-line delay, lag, offsets), the balance and the room.
All values are plain floats in one flat dict.
"""

from __future__ import annotations

import math

import numpy as np


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """Draw one case's background (flat dict of plain floats) for ``boiler``."""

    def u(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    def pm(width: float) -> float:
        return float(rng.uniform(-width, width))

    p_nom = float(boiler["p_nom_kW"])
    bg: dict[str, float] = {
        # --- controller -------------------------------------------------------------------
        "ctrl_setpoint_C": 70.0 + pm(0.6),
        "ctrl_sensor_offset_K": pm(0.8),
        "ctrl_sensor_tau_s": u(15.0, 45.0),
        "ctrl_band_K": u(3.0, 8.0),  # proportional band over Pmin..Pmax
        "ctrl_reset_s": u(200.0, 600.0),
        "ctrl_slew_frac_min": u(0.06, 0.20),  # of Pmax per minute
        "ctrl_shutoff_C": 85.0 + u(-1.0, 1.5),
        "ctrl_restart_C": u(56.0, 58.5),
        "ctrl_min_off_s": u(300.0, 900.0),
        "ctrl_handover_K": u(2.0, 5.0),
        # --- start-up / stop sequence --------------------------------------------------------
        "start_purge_s": u(30.0, 90.0),
        "start_charge_s": u(40.0, 90.0),
        "start_charge_frac": u(0.6, 1.0),  # auger rate during the charge, of Pstart
        "start_ignite_wait_s": u(90.0, 180.0),  # charge start -> fuel ramp (timer)
        "start_ramp_s": u(120.0, 360.0),
        "start_ramp0_frac": u(0.25, 0.45),
        "start_total_s": u(720.0, 1080.0),  # hold at Pstart until this (or hand-over)
        "ignite_bg_s": u(35.0, 80.0),  # bed catches fire this long after the charge
        "igniter_W": u(280.0, 450.0),
        "igniter_energy_frac": u(0.9, 1.1),  # of w_el_Wh
        "post_vent_s": u(300.0, 900.0),
        "fan_purge_frac": u(0.6, 1.2),  # purge air, of the air flow at Pmin
        # --- combustion ------------------------------------------------------------------
        "bed_tau_s": u(20.0, 60.0),
        "auger_period_s": u(10.0, 24.0),
        "auger_factor": 1.0 + pm(0.03),
        "burn_fluct_sigma": u(0.06, 0.12),
        "burn_fluct_tau_s": u(90.0, 400.0),
        "lambda_gain": 1.0 + pm(0.05),
        "lambda_curv": pm(0.15),  # extra relative excess air at low load
        "co_base_ppm": u(40.0, 150.0),
        "fuel_moisture_dev": pm(0.005),
        # --- exchanger -------------------------------------------------------------------
        "hx_dt_scale": 1.0 + pm(0.04),
        "hx_load_exponent": u(0.05, 0.20),  # flue-gas approach ~ load**n
        "fg_tau_bg_s": u(15.0, 45.0),
        # --- body ------------------------------------------------------------------------
        "body_metal_scale": u(0.9, 1.15),
        "body_water_scale": u(0.95, 1.08),
        "body_metal_tau_s": u(12.0, 35.0),
        "ua_on_scale": u(0.85, 1.2),
        "ua_off_scale": u(0.85, 1.2),
        "boiler_init_C": u(30.0, 42.0),
        # --- bench -----------------------------------------------------------------------
        "ret_tau_s": u(30.0, 120.0),
        "ret_cool_max_kW": p_nom * u(1.2, 1.6),
        "ret_heat_max_kW": p_nom * u(0.6, 1.0) + 2.0,
        "ret_osc_K": u(0.05, 0.3),
        "ret_osc_period_s": u(300.0, 900.0),
        "ret_osc_phase": u(0.0, 2 * math.pi),
        "ret_pipe_tau_s": u(2500.0, 6000.0),  # stagnant return pipe to room
        "flow_tau_s": u(5.0, 20.0),
        "flow_bias": pm(0.01),
        "flow_noise_frac": u(0.002, 0.006),
        # --- sensors ---------------------------------------------------------------------
        "t_in_offset_K": pm(0.3),
        "t_in_tau_s": u(5.0, 20.0),
        "t_in_drift_K_h": pm(0.03),
        "t_out_offset_K": pm(0.3),
        "t_out_tau_s": u(5.0, 20.0),
        "t_out_drift_K_h": pm(0.03),
        "t_boiler_offset_K": pm(1.5),
        "t_boiler_tau_s": u(20.0, 60.0),
        "t_boiler_drift_K_h": pm(0.05),
        "t_noise_K": u(0.02, 0.06),
        "t_fg_offset_K": pm(0.8),
        "t_fg_tau_s": u(10.0, 40.0),
        "t_fg_noise_K": u(0.1, 0.4),
        "o2_delay_s": u(15.0, 45.0),
        "o2_tau_s": u(5.0, 15.0),
        "o2_offset": pm(0.2),
        "co2_gain": 1.0 + pm(0.01),
        "co_gain": 1.0 + pm(0.08),
        "v_fg_nom_m_s": u(1.8, 2.6),
        "draught_Pa": -12.0 + pm(0.5),
        "balance_res_kg": float(rng.choice([0.01, 0.02])),
        "balance_noise_kg": u(0.002, 0.008),
        "hopper_kg": u(18.0, 35.0),
        "el_scale": 1.0 + pm(0.06),
        # --- room ------------------------------------------------------------------------
        "room_base_C": u(19.0, 27.0),
        "room_amp_K": u(0.3, 1.5),
        "room_period_s": u(6 * 3600.0, 24 * 3600.0),
        "room_phase": u(0.0, 2 * math.pi),
        "room_sensor_offset_K": pm(0.2),
        "pressure_hPa": u(969.0, 1004.0),
        "pressure_drift_hPa_h": pm(0.3),
        "humidity_pct": u(30.0, 60.0),
        "humidity_drift_pct_h": pm(0.8),
    }
    return bg
