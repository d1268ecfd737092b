"""A random real boiler and bench around the documented parameters (one per case).

What Type 869 does not have, and every real boiler and lab has in its own way, drawn from
ranges a lab would consider plausible (uniform unless stated):

- the boiler's own controller: PI on its own boiler-water sensor, proportional band 4-10
  K, integral time 300-900 s, anti-windup; power levels quantised in steps of 6-15 % of
  Pmax with hysteresis (the limit cycle real modulating burners show); set point 70 C
  with a set-point error of 0.3-1.2 K either way (the boiler's own NTC/KTY sensor in its
  well against the lab's Pt100 at the outlet, and the display's 1 K steps; the paper's
  stationary Q fluctuated around the mean with r = 0.01-0.29 against the model, a
  0.3-0.37 kW RMSD); its own sensor reads the water within 0.1 K (1 sigma, clipped at
  0.2 K); cut-out at 84.7-85.3 C after a minimum burn time of 10-25 min (92 C safety),
  restart below 54.8-55.2 C after a minimum off time of 5-15 min (the documented 85 / 55
  C; the paper reports that the Type 869 model with exactly these values "predicts
  correctly the boiler's starts and stops" in the load cycle, so the real thresholds sat
  close to them; at 13 % load both are reached on slow exponential approaches, where
  every 0.1 K of threshold shifts a stop or restart by minutes);
- its own start-up: pre-purge 60-180 s, ignition stage 60-150 s feeding 30-50 % of Pstart,
  igniter on for 600-1200 s (drawing the documented Wel), fuel ramp 120-400 s to Pstart,
  Pstart held for 5-15 min or until 1-4 K below the set point; post-run of the fan
  180-480 s after a stop; fuel in auger pulses every 8-20 s; the bed lights 5-15 s after
  the first feed and burns with a time constant of 15-35 s;
- exchanger efficiency varying with load: NTU ~ W^-n (n = 0.15-0.4, convective) times
  (Q_rel / Q_rel,nom)^m (radiative, m placed per case, :func:`simulate._fire_ntu_exponent`)
  so that the nominal flue-gas temperature lies within +-3 K (1 sigma) of the documented
  dTnom and the one at Pmin within +-3 K (1 sigma, clipped at 6 K) of the documented
  part-load line dThx,wat (Fig. 4: the thermo-controlled boilers' flue gas leaves at nearly
  the same temperature at every load; a bare convective exchanger made the part load tens
  of kelvin colder and far more efficient than documented);
- losses: envelope 0.8-1.2 x UAamb,ON, stand-by draught 0.8-1.2 x (UAamb,OFF -
  UAamb,ON), combustion-chamber loss 0-0.8 % of the fuel's heat; metal and water
  capacities within 15 % / 10 % of the documentation; excess air 5 % / 10 % off facA /
  facB; electric powers within 10 %; HHV within 0.5 % (1 sigma) of the analysis;
- bench: flow loop lag 5-20 s; return conditioning with a cooling capacity 1.1-1.6 x Pmax
  and a heater of 0.8-1.5 x Pnom (preheat only), two lags (20-90 s, 10-40 s), an offset
  of -0.6..+0.2 K and a valve ripple of 0.02-0.3 K (period 1-5 min); room 19-27 C with a
  slow daily swing and trend; start temperature 28-42 C;
- instruments: Pt100 responses 3-12 s (water) and 10-30 s (flue gas), offsets within the
  class A / B tolerances, drifts of 0.03 K/h (1 sigma), noise and quantisation (0.01 K,
  0.1 K flue gas, 0.02 kg balance, 0.01 vol-% O2), the gas analyser's sample line (15-45 s),
  the boiler-water sensor's position in the stratified body (reads 5-15 % of the
  water's heating span above or below the mixed temperature), rare dropouts (NaN).
"""

from __future__ import annotations

import math

import numpy as np


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """A random real-boiler background for ``boiler`` (CONTRACT section 2 mapping).

    Returns plain floats by name (JSON-serialisable); :func:`simulate_log` combines them
    with the boiler's documented values."""
    u = rng.uniform
    p_max = float(boiler["p_max_kW"])
    p_min = float(boiler["p_min_kW"])

    def sign() -> float:
        return 1.0 if rng.random() < 0.5 else -1.0

    s_bw = sign()  # the boiler-water sensor sits high (+) or low (-) in the stratified body
    beta = u(0.02, 0.06) * s_bw
    return {
        # boiler around its documentation
        "p_max_factor": float(1.0 + 0.02 * rng.standard_normal()),
        "p_min_factor": u(0.97, 1.03),
        "p_start_factor": u(0.90, 1.00),
        "c_metal_factor": u(0.85, 1.15),
        "c_water_factor": u(0.90, 1.10),
        "ua_shell_factor": u(0.8, 1.2),
        "draught_factor": u(0.8, 1.2),
        "bc_share": u(0.0, 0.008),
        "lam_a_factor": u(0.95, 1.05),
        "lam_b_factor": u(0.90, 1.10),
        "pel_min_factor": u(0.9, 1.1),
        "pel_max_factor": u(0.9, 1.1),
        "pel_off_factor": u(0.9, 1.1),
        "p_ign_factor": u(0.9, 1.1),
        "hhv_factor": float(1.0 + 0.005 * rng.standard_normal()),
        "fg_dev_K": float(3.0 * rng.standard_normal()),
        "ntu_exp": u(0.15, 0.4),
        "sink_kappa": u(0.6, 0.9),
        "tau_mw": u(8.0, 25.0),
        "co_at_max": u(30.0, 100.0),
        "co_at_min": u(100.0, 400.0),
        "co_start_ppm": u(500.0, 2500.0),
        "co_stop_ppm": u(200.0, 1000.0),
        "co_tau_s": u(120.0, 400.0),
        # controller
        "t_set": 70.0 + u(0.3, 1.2) * sign(),
        "kp_kW_K": (p_max - p_min) / u(4.0, 10.0),
        "ti_s": u(300.0, 900.0),
        "p_step_kW": u(0.06, 0.15) * p_max,
        "t_shut": u(84.7, 85.3),
        "t_restart": u(54.8, 55.2),
        "t_safety": 92.0,
        "min_burn_s": u(600.0, 1500.0),
        "min_off_s": u(300.0, 900.0),
        "t_purge_s": u(60.0, 180.0),
        "t_ign_stage_s": u(60.0, 150.0),
        "t_igniter_s": u(600.0, 1200.0),
        "ign_share": u(0.3, 0.5),
        "t_ramp_s": u(120.0, 400.0),
        "t_hold_s": u(300.0, 900.0),
        "hold_exit_K": u(1.0, 4.0),
        "t_post_s": u(180.0, 480.0),
        "aug_period_s": u(8.0, 20.0),
        "aug_max_share": u(1.3, 2.0),
        "ctrl_tau_s": u(10.0, 40.0),
        "ctrl_offset_K": float(np.clip(0.1 * rng.standard_normal(), -0.2, 0.2)),
        "light_delay_s": u(5.0, 15.0),
        "bed_tau_s": u(15.0, 35.0),
        # bench
        "flow_tau_s": u(5.0, 20.0),
        "ret_tau_s": u(20.0, 90.0),
        "ret_tau2_s": u(10.0, 40.0),
        "q_cool_factor": u(1.1, 1.6),
        "q_heat_factor": u(0.8, 1.5),
        "ret_offset_K": u(-0.6, 0.2),
        "ret_ripple_K": u(0.02, 0.3),
        "ret_ripple_period_s": u(60.0, 300.0),
        "ret_stag_tau_s": u(1500.0, 3000.0),
        "room0": u(19.0, 27.0),
        "room_amp": u(0.3, 1.5),
        "room_period_s": u(43200.0, 86400.0),
        "room_phase": u(0.0, 2.0 * math.pi),
        "room_trend_K_h": u(-0.1, 0.1),
        "p0_hPa": u(970.0, 1003.0),
        "p_amp": u(0.5, 3.0),
        "rh0": u(30.0, 60.0),
        "rh_amp": u(2.0, 8.0),
        "t_init": u(28.0, 42.0),
        "hopper_kg": u(15.0, 40.0),
        "tare_kg": u(180.0, 320.0),
        # instruments
        "tau_water_s": u(3.0, 12.0),
        "tau_flue_s": u(10.0, 30.0),
        "off_in": float(np.clip(0.08 * rng.standard_normal(), -0.15, 0.15)),
        "off_out": float(np.clip(0.08 * rng.standard_normal(), -0.15, 0.15)),
        "off_bw": u(0.8, 1.8) * s_bw,
        "strat_beta": beta,
        "drift_in": float(0.03 * rng.standard_normal()),
        "drift_out": float(0.03 * rng.standard_normal()),
        "drift_bw": float(0.03 * rng.standard_normal()),
        "noise_water_K": u(0.005, 0.03),
        "noise_flue_K": u(0.1, 0.4),
        "off_fg": float(np.clip(0.5 * rng.standard_normal(), -1.0, 1.0)),
        "o2_delay_s": u(15.0, 45.0),
        "o2_off": float(np.clip(0.1 * rng.standard_normal(), -0.2, 0.2)),
        "o2_noise": u(0.02, 0.06),
        "co2_gain": float(0.01 * rng.standard_normal()),
        "flow_gain": float(np.clip(0.003 * rng.standard_normal(), -0.005, 0.005)),
        "flow_noise": u(0.001, 0.004),
        "room_off": float(np.clip(0.2 * rng.standard_normal(), -0.3, 0.3)),
        "draught_off": float(0.5 * rng.standard_normal()),
        "dropout_p": u(0.0, 3e-4),
        # drawn last so that the draws above keep their values for a seed
        "fg_part_load_dev_K": float(np.clip(3.0 * rng.standard_normal(), -6.0, 6.0)),
    }
