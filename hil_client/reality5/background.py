"""Per-case background of plant 5 and the strength mapping of its effect forms.

The background is everything in which this boiler and bench differ from Type 869 without being
a listed effect. Every value is drawn uniformly (``U(a, b)``) or normally (``N(0, s)``) per case;
the ranges are the documentation, written next to each key. Powers scale with the boiler.

Effect forms (``strength`` s in [0, 1], linear in s unless noted):

body_heat_diffusion
  burner_flange_path   a share f = 0.08 + 0.27 s of the heat given up by the gases goes first into
                       the heavy burner pot flange / ash pan (capacity (0.15 + 0.6 s) * Ctherm) that
                       conducts to the water with time constant 300 + 1500 s.
  flow_dependent_film  the water-side film between body and water is convective: UA = UA_0 (1 - w
                       + w (0.5 (m_w / m_w,nom)^0.8 + 0.5 (|dT| / 20 K)^(1/3))) (Dittus-Boelter plus
                       natural convection), w = 0.15 + 0.85 s, C_s / UA_0 = tau_sw + 150 s: the
                       body runs hot and lags at low flow.
outlet_sensor_pipe
  thermosiphon_exchange bare exit pipe: loss UA = 0.08 + 2.9 s W/K; once circulation stops a
                       buoyant counter-flow G = 4 W/K * sqrt(dT / 10 K) feeds it from the boiler,
                       so the sensor settles where G(dT) dT = UA (T_pipe - T_room).
  stem_conduction      short immersion: fin error e = 1 / cosh(mL), mL = mL_nom * sqrt((m/m_nom)^0.8
                       + 0.06), mL_nom = 18^(1 - s) * 4.5^s; the tip reads T - e * 0.5 (T - T_room)
                       and its lag grows as h falls (3 s at nominal flow).
ignition_delay
  ash_crust_grate      after each start a clinker crust starves the fresh charge of air: the bed's
                       burning constant is k (phi + (1 - phi)(1 - exp(-t / tau))),
                       phi = 0.5 - 0.45 s, tau = 180 + 1620 s since the pre-purge.
  char_shrinking_core  a share f = 0.12 + 0.23 s of the fuel forms char that burns by the
                       shrinking-core law dM/dt = -M^(2/3) M_ref^(1/3) / tau, tau = 120 + 1200 s
                       (finite burn-out 3 tau (M/M_ref)^(1/3) after a stop).
flue_gas_lag
  flue_collector_mass  a heavy flue collector (C = (1 + 11 s) kJ/K * Pnom/12) after the exchanger:
                       T_out = T_box + (T_ex - T_box) exp(-NTU), NTU = (0.1 + 1.7 s) (m_fg /
                       m_fg,nom)^-0.4; the box loses 0.1 W/K to the room.
  bimetal_bypass       a thermostatic flap opens a bypass of the last pass as a bimetal (time
                       constant 300 + 900 s) warms: T_ex = T_base + dTx (1 + g f_b),
                       g = 0.04 + 0.66 s, f_b up to 0.6 between the minimum- and full-load dTx.
fuel_energy_bias
  torrefied_blend      a share 0.04 + 0.56 s of torrefied pellets (HHV 23.0 MJ/kg dry, C 56 %,
                       O 37.6 %, 3 % moisture): +0.6 .. +8.8 % per kg dry, +0.7 .. +10.8 % as fed.
  calcite_additive     CaCO3 additive, 0.6 % + 7.4 % s of the dry mass: inert dilution plus the
                       endothermic calcination (1.78 MJ/kg) that adds CO2: -0.65 .. -8.7 % per kg.
"""

from __future__ import annotations

import math

import numpy as np

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("burner_flange_path", "flow_dependent_film"),
    "outlet_sensor_pipe": ("thermosiphon_exchange", "stem_conduction"),
    "ignition_delay": ("ash_crust_grate", "char_shrinking_core"),
    "flue_gas_lag": ("flue_collector_mass", "bimetal_bypass"),
    "fuel_energy_bias": ("torrefied_blend", "calcite_additive"),
}
EFFECT_CODES = {name: i + 1 for i, name in enumerate(EFFECT_FORMS)}

TORREFIED = {
    "hhv_dry_kJ_kg": 23000.0,
    "c": 0.560,
    "h": 0.057,
    "o": 0.376,
    "n": 0.003,
    "s": 0.0001,
    "ash": 0.004,
    "moisture": 0.03,
}
H_CALCINATION = 1780.0  # kJ per kg CaCO3 -> CaO + CO2
CO2_PER_CACO3 = 0.2226  # Nm3 CO2 per kg CaCO3 (0.44 kg / 1.977 kg/Nm3)


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """Draw one case's background (controller, start-up, exchanger, bench, instruments)."""

    def u(a, b):
        return float(rng.uniform(a, b))

    def n(s):
        return float(rng.normal(0.0, s))

    sc = boiler["p_nom_kW"] / 12.0
    return {
        # boiler body, exchanger, combustion
        "c_steel_kJ_K": boiler["c_therm_kJ_K"] * u(0.85, 1.2),
        "vol_water_m3": boiler["vol_water_m3"] * u(0.92, 1.08),
        "tau_sw_s": u(30, 90),  # steel -> water coupling C_s / UA_sw
        "ua_env_W_K": boiler["ua_amb_on_W_K"] * u(0.8, 1.25),  # cladding, always
        "ua_draught_W_K": (boiler["ua_amb_off_W_K"] - boiler["ua_amb_on_W_K"]) * u(0.8, 1.25),
        "eps_idle": u(0.85, 0.95),  # exchanger effectiveness on idle draught air
        "dT_fg_scale": u(0.92, 1.08),  # gas excess temperature at full load vs Table 3
        "dT_fg_low": u(0.7, 0.9),  # share of it left at zero load (exchanger gets better)
        "foul_amp": u(0.01, 0.05),  # fouling saw-tooth between spiral cleanings
        "clean_interval_s": u(3600, 10800),
        "k_auger": u(0.94, 1.07),  # auger delivery vs its calibration
        "lam_scale_hi": u(0.92, 1.08),
        "lam_scale_lo": u(0.92, 1.08),
        "purge_air_frac": u(0.5, 0.9),
        "ign_air_frac": u(0.15, 0.3),
        "tau_bed_s": u(45, 120),
        "burnout_slow": u(1.5, 3.0),  # natural-draught burn-out slower than with the fan
        "flicker": u(0.02, 0.06),  # bed irregularity (relative burn rate, OU)
        "flicker_tau_s": u(20, 90),
        "t_light_s": u(90, 240),  # normal lighting time of the igniter
        "p_ig_W": u(250, 420),
        "m_charge_kg": u(0.08, 0.16) * sc,
        "dT_cc_max_K": u(450, 700),
        "tau_cc_s": u(30, 90),
        "dT_flame_K": u(40, 90),
        "co_nom_ppm": u(30, 150),
        "ash_loss": u(0.0002, 0.003),
        "pipe_ua_loss_W_K": u(0.02, 0.06),
        "pipe_ua_cond_W_K": u(0.6, 1.2),
        "pipe_c_kJ_K": u(0.9, 1.4),
        # controller: stepped PI on its own flow sensor, quantised modulation
        "ctrl_offset_K": u(-0.6, 0.6),
        "tau_ctrl_s": u(8, 20),
        "ctrl_period_s": u(20, 60),
        "deadband_K": u(0.3, 1.0),
        "kp": u(0.04, 0.10),  # per K
        "ki": u(0.01, 0.04),  # per K and minute
        "mod_step": u(0.03, 0.08),
        "x_min_scale": u(0.95, 1.05),  # real Pmin vs documentation
        "t_stop_C": u(84, 87),
        "dT_restart_K": u(13.5, 15.5),  # restart below T_set - dT, or demand timer below -10 K
        "t_demand_s": u(1200, 2400),
        "dT_lowstop_K": u(12, 16),
        "t_lowstop_s": u(60, 300),
        "min_burn_s": u(600, 1500),
        "min_off_s": u(180, 600),
        "t_prepurge_s": u(30, 120),
        "t_dwell_s": u(30, 90),
        "t_ramp_s": u(120, 480),
        "t_hold_s": u(600, 1200),
        "dT_handover_K": u(2, 6),
        "t_postpurge_s": u(300, 900),
        "t_auger_s": u(8, 20),
        "duty_max": u(0.3, 0.5),
        # electricity
        "p_el_scale": u(0.9, 1.1),
        "p_auger_frac": u(0.4, 0.7),
        "p_clean_W": u(30, 80),
        "t_clean_run_s": u(20, 60),
        # bench
        "tau_flow_s": u(5, 20),
        "flow_ripple": u(0.003, 0.01),
        "q_heat_frac": u(0.5, 1.0),  # return heater capacity, fraction of Pnom
        "q_cool_load": u(1.0, 1.3),  # cooler capacity Pnom (a load + b): pre-set by the program
        "q_cool_base": u(0.03, 0.08),
        "q_cool_min": u(0.7, 0.9),  # ... and it never extracts less than this share of the load
        "loop_mass_kg": u(15, 40),
        "ua_loop_W_K": u(3, 8),
        "tau_cond_s": u(20, 60),
        "hunt_amp_K": u(0.05, 0.3),
        "hunt_period_s": u(120, 400),
        "tau_stagnant_s": u(1800, 5400),
        "t_init_offset_K": u(0, 10),
        "hopper_kg": u(25, 40),
        # room
        "t_room_C": u(18, 30),
        "room_amp_K": u(0.3, 1.5),
        "room_phase": u(0, 2 * math.pi),
        "p_amb_hPa": u(969, 1004),
        "p_amp_hPa": u(0.5, 2.0),
        "rh_pct": u(30, 65),
        # instruments
        "off_in_K": n(0.1),
        "off_out_K": n(0.1),
        "off_bw_K": n(0.3),
        "drift_in_K_h": u(-0.02, 0.02),
        "drift_out_K_h": u(-0.02, 0.02),
        "tau_in_s": u(2, 8),
        "tau_out_s": u(2, 8),
        "tau_bw_s": u(10, 30),
        "noise_wt_K": u(0.01, 0.04),
        "k_pos": u(0.04, 0.12),  # body sensor sits on the jacket's temperature profile
        "tau_prof_s": u(60, 300),
        "fg_err": u(-0.7, 0.7),  # fraction of the class-B tolerance
        "tau_fg_s": u(8, 25),
        "noise_fg_K": u(0.1, 0.3),
        "fg_turb_K": u(0.3, 1.5),
        "o2_delay_s": u(10, 40),
        "o2_tau_s": u(5, 15),
        "o2_off": u(-0.15, 0.15),
        "o2_span": u(0.99, 1.01),
        "noise_o2": u(0.03, 0.08),
        "co2_extra_delay_s": u(2, 5),
        "co2_off": u(-0.1, 0.1),
        "co2_span": u(0.99, 1.01),
        "co_off_ppm": u(-5, 5),
        "flue_d_m": u(0.07, 0.10),
        "v_off": u(-0.05, 0.05),
        "v_noise": u(0.03, 0.06),
        "v_cut": u(0.3, 0.6),  # vortex meter reads 0 below this
        "draught_Pa": u(-12.5, -11.5),
        "bal_off_kg": u(-0.05, 0.05),
        "bal_drift_kg_h": u(-0.005, 0.005),
        "bal_noise_kg": u(0.003, 0.008),
        "bal_vib_kg": u(0.005, 0.015),
        "room_off_K": u(-0.2, 0.2),
        "flow_off": u(-0.005, 0.005),
        "flow_noise": u(0.002, 0.006),
        "pel_noise_W": u(0.2, 0.6),
        "autozero_period_s": u(3 * 3600, 5 * 3600),  # analyser auto-zero: O2/CO2/CO missing
        "autozero_len_s": u(60, 150),
        "autozero_phase": u(0, 1),
    }


def effect_params(effect: str | None, form: str | None, s: float, boiler: dict, bg: dict):
    """Map (effect, form, strength) to (effect code, form code, [e1..e6], readable dict)."""
    e = [0.0] * 6
    if effect is None:
        return 0, 0, e, {}
    fi = EFFECT_FORMS[effect].index(form)
    sc = boiler["p_nom_kW"] / 12.0
    if effect == "body_heat_diffusion" and fi == 0:
        c_fl = (0.15 + 0.6 * s) * boiler["c_therm_kJ_K"]
        d = {"share": 0.08 + 0.27 * s, "c_kJ_K": c_fl, "tau_s": 300 + 1500 * s}
        e[:3] = [d["share"], c_fl, c_fl / d["tau_s"]]
    elif effect == "body_heat_diffusion":
        d = {"tau_film_s": bg["tau_sw_s"] + 150 * s, "film_weight": 0.15 + 0.85 * s}
        e[:2] = [bg["c_steel_kJ_K"] / d["tau_film_s"], d["film_weight"]]
    elif effect == "outlet_sensor_pipe" and fi == 0:
        d = {"ua_loss_W_K": 0.08 + 2.9 * s, "g_thermosiphon_W_K": 4.0}
        e[:2] = [d["ua_loss_W_K"] / 1000, 0.004]
    elif effect == "outlet_sensor_pipe":
        d = {"mL_nom": 18.0 ** (1 - s) * 4.5**s, "beta": 0.5, "h_ratio": 0.06, "tau_s": 3.0}
        e[:4] = [d["mL_nom"], 0.5, 0.06, 3.0]
    elif effect == "ignition_delay" and fi == 0:
        d = {"phi": 0.5 - 0.45 * s, "tau_s": 180 + 1620 * s}
        e[:2] = [d["phi"], d["tau_s"]]
    elif effect == "ignition_delay":
        d = {"char_share": 0.12 + 0.23 * s, "tau_s": 120 + 1200 * s}
        e[:2] = [d["char_share"], d["tau_s"]]
    elif effect == "flue_gas_lag" and fi == 0:
        d = {"ntu_nom": 0.1 + 1.7 * s, "c_kJ_K": (1 + 11 * s) * sc, "ua_loss_W_K": 0.1}
        e[:3] = [d["ntu_nom"], d["c_kJ_K"], 0.0001]
    elif effect == "flue_gas_lag":
        d = {"g": 0.04 + 0.66 * s, "tau_s": 300 + 900 * s, "f_max": 0.6}
        e[:3] = [d["g"], d["tau_s"], 0.6]
    elif fi == 0:
        d = {"torrefied_share": 0.04 + 0.56 * s}
    else:
        d = {"caco3_share": 0.006 + 0.074 * s}
    return EFFECT_CODES[effect], fi, e, d


def effective_fuel(fuel: dict, effect: str | None, form: str | None, s: float) -> dict:
    """Fuel as burnt (dry basis, moisture as received); ``co2_extra`` Nm3/kg from calcination."""
    f = {k: float(fuel[k]) for k in ("hhv_dry_kJ_kg", "c", "h", "o", "n", "s", "ash", "moisture")}
    f["residue"], f["co2_extra"] = f["ash"], 0.0
    if effect != "fuel_energy_bias":
        return f
    if form == "torrefied_blend":
        a = 0.04 + 0.56 * s
        for k, v in TORREFIED.items():
            f[k] = (1 - a) * f[k] + a * v
        f["residue"] = f["ash"]
    else:
        x = 0.006 + 0.074 * s
        for k in ("c", "h", "o", "n", "s", "ash"):
            f[k] *= 1 - x
        f["hhv_dry_kJ_kg"] = (1 - x) * f["hhv_dry_kJ_kg"] - x * H_CALCINATION
        f["residue"] = f["ash"] + 0.56 * x
        f["co2_extra"] = x * CO2_PER_CACO3
    return f
