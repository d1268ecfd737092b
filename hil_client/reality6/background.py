"""The plant's own, unlisted differences from Type 869, drawn per case (`draw_background`).

Every value is a Python float; the draw order is fixed, so one generator state gives one
background.  The ranges are what a real manufacturer's boiler and a real bench show; together
they give a background gap of the size of Table 4 of Carlon et al. (2015) (test phase: water
temperature RMSD 1-3 K, heat-to-water RMSD 0.3-0.7 kW; tests/hil_client/reality6 checks it).

Groups (names carry their units):
* room and weather: room temperature level and daily swing, pressure, humidity;
* burner and combustion: excess-air calibration (Eq. 9 times a factor, O2-trim hunting), the
  exchanger's own flue-gas law (level, load exponent, fouling growth; replaces Eq. 8), a small
  flue-side store, CO level, bed burn-off time, auger pulse cycle and wandering fill degree;
* start-up sequence: pre-purge, ignition charge (kg), cold and hot-bed light-off times,
  top-up feeds, stabilisation stage, start mode at P_start, igniter power, post-purge;
* controller: body-sensor offset and stratification, forward set-point error, PI gains, slew,
  shut-off / restart offsets to 85 / 55 C, minimum burn and off times;
* stand-by: UA_on / UA_off factors (Eq. 10), purge-fan cooling;
* bench: flow-loop lag, circuit volume and losses, return-cooler PI, lag and capacity margin,
  preheater power;
* instruments: offsets, lags, noise, analyser delay, drift and calibration gaps, balance.
"""

from __future__ import annotations

import numpy as np

__all__ = ["draw_background"]


def draw_background(rng: np.random.Generator, boiler: dict) -> dict[str, float]:
    """Draw one case's background (the plant's normal differences from Type 869)."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError("rng must be a numpy.random.Generator")
    p_start = float(boiler["p_start_kW"])
    size = p_start / 13.2  # ignition charge and purge air scale with the burner size

    def u(lo: float, hi: float) -> float:
        return float(rng.uniform(lo, hi))

    bg: dict[str, float] = {}
    # room and weather
    bg["room_temp_mean_C"] = u(19.0, 27.0)
    bg["room_swing_K"] = u(0.3, 1.5)
    bg["room_phase_rad"] = u(0.0, 2.0 * np.pi)
    bg["pressure_hPa"] = u(972.0, 1002.0)
    bg["pressure_trend_hPa"] = u(-3.0, 3.0)
    bg["humidity_pct"] = u(30.0, 60.0)
    bg["initial_temp_C"] = u(28.0, 38.0)
    # combustion and exchanger
    bg["lambda_factor"] = u(0.94, 1.08)
    bg["lambda_hunting"] = u(0.01, 0.04)
    bg["flue_dt_factor"] = u(0.93, 1.07)
    bg["flue_load_exponent"] = u(0.35, 0.65)
    bg["fouling_per_h"] = u(0.002, 0.008)
    bg["flue_store_tau_s"] = u(20.0, 45.0)
    bg["flue_store_kJ_K"] = u(3.0, 6.0)
    bg["flue_idle_fraction"] = u(0.15, 0.35)
    bg["co_base_ppm"] = u(20.0, 120.0)
    bg["co_low_load_factor"] = u(3.0, 10.0)
    bg["bed_tau_s"] = u(45.0, 90.0)
    bg["auger_fill_sigma"] = u(0.05, 0.10)
    bg["auger_fill_tau_s"] = u(200.0, 600.0)
    bg["auger_cycle_s"] = u(12.0, 24.0)
    bg["auger_capacity_factor"] = u(1.3, 1.6)
    bg["auger_calibration_factor"] = u(1.02, 1.07)
    # start-up and shut-down sequence
    bg["prepurge_s"] = u(30.0, 90.0)
    bg["ignition_charge_kg"] = size * u(0.08, 0.14)
    bg["light_cold_s"] = u(90.0, 240.0)
    bg["light_hot_s"] = u(25.0, 60.0)
    bg["hot_window_s"] = u(1200.0, 2400.0)
    bg["topup_period_s"] = u(150.0, 240.0)
    bg["topup_fraction"] = u(0.2, 0.35)
    bg["stabilise_s"] = u(90.0, 240.0)
    bg["stabilise_fraction"] = u(0.45, 0.7)
    bg["start_full_s"] = u(600.0, 900.0)
    bg["igniter_W"] = u(280.0, 400.0)
    bg["igniter_post_s"] = u(90.0, 240.0)
    bg["postpurge_s"] = u(240.0, 600.0)
    # controller
    bg["ctrl_sensor_offset_K"] = u(-0.4, 0.4)
    bg["ctrl_setpoint_error_K"] = u(-0.4, 0.4)
    bg["ctrl_stratification_K"] = u(0.3, 1.2)
    bg["ctrl_kp_per_K"] = u(0.08, 0.2)  # fraction of P_max per K
    bg["ctrl_ti_s"] = u(250.0, 700.0)
    bg["modulation_stages"] = u(4.5, 12.49)  # rounded: 5-12 fixed modulation stages
    bg["ctrl_slew_per_s"] = u(0.002, 0.006)  # fraction of P_max per s
    bg["shutoff_offset_K"] = u(-0.7, 0.7)
    bg["restart_offset_K"] = u(0.6, 1.4)
    bg["min_burn_s"] = u(300.0, 900.0)
    bg["min_off_s"] = u(300.0, 900.0)
    # stand-by losses
    bg["ua_on_factor"] = u(0.8, 1.25)
    bg["ua_off_factor"] = u(0.85, 1.2)
    bg["ua_purge_W_K"] = u(1.0, 4.0)
    # bench
    bg["flow_tau_s"] = u(10.0, 30.0)
    bg["circuit_volume_l"] = u(40.0, 80.0)
    bg["circuit_ua_W_K"] = u(4.0, 12.0)
    bg["bench_kp_kW_K"] = u(0.6, 1.8)
    bg["bench_ti_s"] = u(150.0, 400.0)
    bg["bench_actuator_tau_s"] = u(20.0, 60.0)
    bg["bench_capacity_margin"] = u(1.15, 1.4)
    bg["cooling1_margin"] = u(0.95, 1.1)
    bg["preheater_kW"] = u(6.0, 10.0)
    # instruments
    bg["flow_gain_error"] = u(-0.006, 0.006)
    bg["flow_noise_frac"] = u(0.001, 0.004)
    bg["t_in_offset_K"] = u(-0.15, 0.15)
    bg["t_out_offset_K"] = u(-0.15, 0.15)
    bg["t_water_tau_s"] = u(4.0, 10.0)
    bg["boiler_sensor_offset_K"] = u(-0.4, 0.4)
    bg["boiler_stratification_K"] = u(0.8, 2.2)
    bg["boiler_sensor_tau_s"] = u(15.0, 40.0)
    bg["outlet_pipe_kg"] = u(0.1, 0.25)
    bg["flue_sensor_offset_K"] = u(-1.0, 1.0)
    bg["flue_sensor_tau_s"] = u(8.0, 20.0)
    bg["o2_offset_pct"] = u(-0.15, 0.15)
    bg["o2_drift_pct_h"] = u(-0.02, 0.02)
    bg["analyser_delay_s"] = u(15.0, 35.0)
    bg["analyser_tau_s"] = u(6.0, 15.0)
    bg["analyser_cal_period_s"] = u(9000.0, 14400.0)
    bg["analyser_cal_len_s"] = u(180.0, 300.0)
    bg["balance_tare_kg"] = u(30.0, 45.0)
    bg["fuel_initial_kg"] = u(24.0, 32.0)
    bg["balance_noise_kg"] = u(0.004, 0.012)
    bg["draught_Pa"] = u(-12.5, -11.5)
    bg["auger_motor_W"] = u(10.0, 20.0)
    return bg
