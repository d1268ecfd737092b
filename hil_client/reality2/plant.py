"""One lab log of this plant (:func:`simulate_log`): parameters by name, packed for the
kernel, run, and the readings turned into the CONTRACT section 3 columns."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from hil_client.reality2 import layout as L
from hil_client.reality2.combustion import stoichiometry
from hil_client.reality2.effects import EFFECT_FORMS, effect_settings
from hil_client.reality2.kernel import run_plant
from hil_client.reality2.protocol import load_protocol, longest_record_s, schedule_array

PHASE_NAMES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
#: Log columns in file order (CONTRACT section 3), with the kernel channel of each.
COLUMNS: tuple[tuple[str, int], ...] = (
    ("water_flow_kg_h", L.R_FLOW),
    ("water_in_temp_C", L.R_TIN),
    ("water_out_temp_C", L.R_TOUT),
    ("boiler_water_temp_C", L.R_TBW),
    ("flue_gas_temp_C", L.R_TFG),
    ("flue_gas_O2_pct", L.R_O2),
    ("flue_gas_CO2_pct", L.R_CO2),
    ("flue_gas_CO_ppm", L.R_CO),
    ("flue_gas_velocity_m_s", L.R_VEL),
    ("chimney_draught_Pa", L.R_DRAUGHT),
    ("balance_mass_kg", L.R_MASS),
    ("room_temp_C", L.R_ROOM),
    ("ambient_pressure_hPa", L.R_PRESS),
    ("relative_humidity_pct", L.R_RH),
    ("electric_power_W", L.R_PEL),
    ("water_flow_setpoint_kg_h", L.R_FLOWSET),
    ("boiler_on", L.R_ON),
)
ANALYSER = ("flue_gas_O2_pct", "flue_gas_CO2_pct", "flue_gas_CO_ppm")
RHO_WATER = 975.0  # kg/m3 at about 75 C
DUCT_AREA_M2 = math.pi * 0.10**2 / 4.0  # DN100 flue of the bench (digest section 5)


def _lambda_doc(boiler: Mapping, fuel_dry_kg_h: float) -> float:
    return float(boiler["fac_a_lambda"]) + float(boiler["fac_b_lambda_h_kg"]) * fuel_dry_kg_h


def build_params(boiler: Mapping, protocol: Mapping, bg: Mapping, fx: Mapping) -> np.ndarray:
    """The packed parameter array of the kernel from named inputs."""
    v: dict[str, float] = {}
    fuel = boiler["fuel"]
    p_nom = float(boiler["p_nom_kW"])
    moisture = float(fx.get("moisture", float(fuel["moisture"]) + bg["moisture_delta"]))
    st = stoichiometry(fuel, moisture)
    st_doc = stoichiometry(fuel, float(fuel["moisture"]))
    lhv_doc = st_doc["lhv"]
    cp_w = L.CP_WATER
    flow_nom = p_nom * 3600.0 / (cp_w * protocol["spread_K"])
    # --- protocol
    for key in (
        "preheat_t",
        "preheat_tol",
        "preheat_hold_s",
        "preheat_load",
        "preheat_max_s",
        "return_set",
        "t1_window_s",
        "t1_max_rise",
        "t1_min_s",
        "t1_max_s",
        "cool1_load",
        "cool1_return",
        "cool1_until",
        "cool1_max_s",
        "cool2_after_t2_s",
    ):
        v[key] = protocol[key]
    v["flow_per_pct"] = flow_nom / 100.0
    v["flow_nom"] = flow_nom
    # --- room and start
    v["room_base"] = bg["room_base_C"]
    v["room_amp"] = bg["room_amp_K"]
    v["room_phase_s"] = bg["room_phase_s"]
    v["room_ou_sig"] = bg["room_ou_sig_K"]
    v["room_ou_tau"] = bg["room_ou_tau_s"]
    v["pressure"] = bg["pressure_hPa"]
    v["rh"] = bg["rh_pct"]
    v["t_init"] = bg["t_init_C"]
    # --- controller
    set_t = float(boiler.get("set_temp_C", 70.0))
    v["set_t"] = set_t + bg["set_offset_K"]
    v["ctrl_offset"] = bg["ctrl_sensor_offset_K"]
    v["shutoff_t"] = float(boiler.get("shutoff_temp_C", 85.0)) + bg["shutoff_offset_K"]
    v["restart_t"] = float(boiler.get("restart_temp_C", 55.0)) + bg["restart_offset_K"]
    v["stop_hyst_k"] = bg["stop_hyst_K"]
    v["min_burn_s"] = bg["min_burn_s"]
    v["min_off_s"] = bg["min_off_s"]
    p_max = float(boiler["p_max_kW"]) * (1.0 + bg["p_max_headroom"])
    p_min = float(boiler["p_min_kW"]) * bg["p_min_factor"]
    v["p_max"], v["p_min"] = p_max, p_min
    v["p_start"] = min(float(boiler["p_start_kW"]) * bg["p_start_factor"], p_max)
    v["kp"] = (p_max - p_min) / bg["prop_band_K"]
    v["ti_s"] = bg["ti_s"]
    v["n_stages"] = bg["n_stages"]
    v["ramp_s"] = bg["ramp_s"]
    v["start_hold_s"] = bg["start_hold_s"]
    v["ramp_handover_k"] = bg["ramp_handover_K"]
    v["burnout_s"] = bg["burnout_s"]
    v["prepurge_s"] = bg["prepurge_s"]
    v["ign_program_s"] = bg["ign_program_s"]
    v["ign_delay_bg_s"] = bg["ign_delay_bg_s"]
    v["charge_ar_kg"] = bg["charge_ar_kg"]
    v["igniter_w"] = bg["igniter_W"]
    v["igniter_s"] = min(
        float(boiler["w_el_Wh"]) * 3600.0 / bg["igniter_W"] * bg["igniter_energy_factor"], 1800.0
    )
    v["auger_period_s"] = bg["auger_period_s"]
    v["p_auger_cap"] = p_max / bg["auger_duty_max"]
    # the auger moves volume: as-received mass per second as documented fuel
    v["auger_ar_kg_s"] = (
        v["p_auger_cap"] / lhv_doc / (1.0 - float(fuel["moisture"])) * (1.0 + bg["auger_bias"])
    )
    v["auger_w"] = bg["auger_W"]
    v["tau_bed"] = bg["tau_bed_s"]
    v["feed_sig"] = bg["feed_sig"]
    v["smoulder_start"] = 1.0
    v["smoulder_stop"] = bg["smoulder_stop"]
    v["moisture"] = moisture
    v["fines_frac"] = float(fx.get("fines_frac", 0.0))
    v["hhv"] = float(fuel["hhv_dry_kJ_kg"]) * bg["hhv_factor"]
    v["lhv_doc"] = lhv_doc
    # --- fan, air, gas
    v["air_min"] = st["air_min"]
    v["vdry0"], v["vdry1"], v["vco2"] = st["vdry0"], st["vdry1"], st["vco2"]
    v["gas_a0"], v["gas_a1"] = st["gas_a0"], st["gas_a1"]
    v["vapour_per_kg"] = st["vapour"]
    v["lam_a"] = float(boiler["fac_a_lambda"]) * bg["lam_a_factor"]
    v["lam_b"] = float(boiler["fac_b_lambda_h_kg"]) * bg["lam_b_factor"]
    v["lam_curv"] = bg["lam_curv_h2_kg2"]
    x_max, x_min = p_max * 3600.0 / lhv_doc, p_min * 3600.0 / lhv_doc
    v["lam_xmid"] = 0.5 * (x_max + x_min)

    def air_at(x_h: float) -> float:
        lam = v["lam_a"] + v["lam_b"] * x_h + v["lam_curv"] * (x_h - v["lam_xmid"]) ** 2
        return max(lam, 1.15) * st["air_min"] * x_h / 3600.0

    v["air_purge"] = air_at(x_max)
    v["air_ignition"] = 0.3 * air_at(x_max)
    v["air_burnout"] = air_at(x_min)
    v["tau_fan"] = bg["tau_fan_s"]
    v["co_pmax"], v["co_pmin"] = bg["co_pmax_ppm"], bg["co_pmin_ppm"]
    v["co_start"] = bg["co_start_ppm"]
    # gas heat-capacity flow at nominal output (firing about Pnom / 0.92 on the net basis)
    x_nom = p_nom / 0.92 / lhv_doc  # kg/s dry
    lam_nom = _lambda_doc(boiler, x_nom * 3600.0)
    mcp_nom = x_nom * ((st["gas_a0"] + st["gas_a1"] * lam_nom) * 1.01 + st["vapour"] * 1.89)
    v["mcp_gas_nom"] = mcp_nom
    # exchanger exit: gas leaves dT_x above the top steel, dT_x growing with the gas flow;
    # at nominal load T_fg - T_in matches the documented dTnom (steel about 16 K above return)
    v["dt_x0"] = max(float(boiler["dt_nom_K"]) * bg["dt_fg_factor"] - 16.0, 5.0)
    v["dt_x_exp"] = bg["dt_x_exp"]
    # electricity: fan linear in air, fitted to Pel,MIN / Pel,MAX of the documentation
    v["pel_off"] = float(boiler["p_el_off_W"]) * bg["pel_off_factor"]
    f_min = v["air_burnout"] / v["air_purge"]
    duty_min = p_min / v["p_auger_cap"]
    hi = (
        float(boiler["p_el_max_W"]) * bg["pel_factor"]
        - v["pel_off"]
        - bg["auger_W"] * bg["auger_duty_max"]
    )
    lo = float(boiler["p_el_min_W"]) * bg["pel_factor"] - v["pel_off"] - bg["auger_W"] * duty_min
    w1 = max((hi - lo) / max(1.0 - f_min, 0.05), 0.0)
    v["fan_w1"] = w1
    v["fan_w0"] = hi - w1  # may be negative: the line is used between Pmin and Pmax
    # --- body
    c_water = float(boiler["vol_water_m3"]) * RHO_WATER * cp_w
    v["c_water_node"] = c_water / L.N_WATER
    c_steel = float(boiler["c_therm_kJ_K"]) * bg["steel_factor"]
    wall_c = float(fx.get("wall_c_kJ_K", 0.0))
    c_steel = max(c_steel - wall_c, 20.0)
    v["c_steel_node"] = c_steel / L.N_WATER
    v["ua_sw_node"] = v["c_steel_node"] / bg["tau_steel_water_s"]
    for j, w in enumerate(bg["heat_weights"]):
        v[f"heat_w{j}"] = w
    v["g_mix_stable"] = bg["g_mix_stable_kW_K"]
    v["g_mix_unstable"] = bg["g_mix_unstable_kW_K"]
    h = bg["bw_height_nodes"]
    v["bw_node"] = float(min(int(h), L.N_WATER - 2))
    v["bw_frac"] = h - v["bw_node"]
    ua_on = float(boiler["ua_amb_on_W_K"]) * bg["ua_jacket_factor"]
    v["ua_jacket_node"] = ua_on / 1000.0 / L.N_WATER
    d_ua = max(float(boiler["ua_amb_off_W_K"]) - float(boiler["ua_amb_on_W_K"]), 0.2)
    v["draught_eff"] = bg["draught_eff"]
    v["draught_air_kg_s"] = d_ua * bg["draught_factor"] / 1000.0 / (L.CP_AIR * bg["draught_eff"])
    v["body_form"] = float(fx.get("body_form", 0))
    v["c_ref"] = float(fx.get("c_ref_kJ_K", 0.0))
    v["ref_frac"] = float(fx.get("ref_frac", 0.0))
    v["ref_ea"] = 0.85 * 0.25  # emissivity x area of the firebox lining [m2]
    v["wall_delay_s"] = float(round(fx.get("wall_delay_s", 0.0)))
    v["wall_c_seg"] = max(wall_c, 1.0) / L.N_WALL
    v["wall_g"] = v["wall_c_seg"] * L.N_WALL / float(fx.get("wall_tau_s", 300.0))
    # --- exit pipe
    form = int(fx.get("pipe_form", 0))
    c_per_L = RHO_WATER / 1000.0 * cp_w
    if form == 1:
        v["pipe_cells"] = 6.0
        v["pipe_c_cell"] = (fx["pipe_volume_L"] * c_per_L + fx["pipe_metal_kJ_K"]) / 6.0
        v["pipe_ua_cell"] = fx["pipe_ua_W_K"] / 1000.0 / 6.0
        v["pipe_g_back"] = 0.4e-3
        v["pipe_c_wall"] = v["pipe_h_wall"] = v["pipe_ua_wall"] = v["sensor_wall_w"] = 0.0
    elif form == 2:
        v["pipe_cells"] = 40.0
        v["pipe_c_cell"] = fx["pipe_volume_L"] * c_per_L / 40.0
        v["pipe_ua_cell"] = 0.0
        v["pipe_g_back"] = 0.0
        v["pipe_c_wall"] = fx["pipe_metal_kJ_K"]
        v["pipe_h_wall"] = 0.06  # water to pipe wall at nominal flow [kW/K]
        v["pipe_ua_wall"] = fx["pipe_ua_W_K"] / 1000.0
        v["sensor_wall_w"] = 0.1  # the well reads the wall a little
    else:  # a short, insulated stub next to the body: one cell, kept warm by conduction
        v["pipe_cells"] = 1.0
        v["pipe_c_cell"] = bg["pipe_bg_volume_L"] * c_per_L
        v["pipe_ua_cell"] = bg["pipe_bg_ua_W_K"] / 1000.0
        v["pipe_g_back"] = bg["pipe_bg_g_back_W_K"] / 1000.0
        v["pipe_c_wall"] = v["pipe_h_wall"] = v["pipe_ua_wall"] = v["sensor_wall_w"] = 0.0
    # --- ignition
    v["ign_form"] = float(fx.get("ign_form", 0))
    v["ign_bed_eta"] = 0.5
    v["ign_bed_dt"] = 280.0  # pellets ignite at about 300 C
    v["ign_bed_cp"] = 1.5
    v["ign_bed_tau_loss"] = 1800.0
    extra = float(fx.get("extra_delay_s", 0.0))
    # bed heat content at the intended ignition time: eta P tau (1 - exp(-t / tau)); the
    # bed's capacity (grate plus the surface layer of 1.5 charges) is sized to need it then
    t_ign = bg["ign_delay_bg_s"] + extra
    e_at = 0.5 * bg["igniter_W"] / 1000.0 * 1800.0 * (1.0 - math.exp(-t_ign / 1800.0))
    layer = 1.5 * bg["charge_ar_kg"]
    v["ign_bed_c0"] = max(e_at / 280.0 - 1.5 * layer, 0.02)
    if v["ign_form"] == 1.0:  # the program keeps the igniter on until the flame holds
        v["igniter_s"] = max(v["igniter_s"], t_ign + 180.0)
    if "smoulder" in fx:
        v["smoulder_start"] = fx["smoulder"]
        v["smoulder_stop"] = bg["smoulder_stop"] * (1.0 + 0.5 * (fx["smoulder"] - 1.0))
    # --- flue-gas stores
    v["fg_form"] = float(fx.get("fg_form", 0))
    tau_fg = float(fx.get("fg_tau_s", 0.0))
    v["fg_ntu0"] = 1.5
    if v["fg_form"] == 1:
        v["fg_c"] = tau_fg * mcp_nom * (1.0 - math.exp(-3.0))
        v["fg_g_steel"] = 0.0
    elif v["fg_form"] == 2:
        v["fg_c"] = tau_fg * mcp_nom * (1.0 - math.exp(-1.5))
        v["fg_g_steel"] = 0.02 * mcp_nom
    else:
        v["fg_c"] = v["fg_g_steel"] = 0.0
    # --- bench
    v["tau_flow"] = bg["tau_flow_s"]
    v["flow_ripple"] = bg["flow_ripple"]
    v["c_loop"] = bg["loop_volume_L"] * c_per_L
    v["ua_loop"] = bg["loop_ua_W_K"] / 1000.0
    v["t_cold"] = bg["t_cold_C"]
    v["valve_max"] = bg["valve_max"]
    v["valve_stroke_s"] = bg["valve_stroke_s"]
    v["valve_deadband"] = bg["valve_deadband"]
    v["tau_return"] = bg["tau_return_s"]
    v["bench_kp"] = bg["bench_kp_per_K"]
    v["bench_ti_s"] = bg["bench_ti_s"]
    v["heater_kw"] = p_nom * bg["heater_factor"]
    # --- instruments
    for key in (
        "flow_bias",
        "flow_noise_rel",
        "drift_o2",
        "rel_co2",
        "rel_tfg",
        "noise_tbw",
        "q_tbw",
        "an_delay_s",
        "an_tau_s",
        "tau_tw",
        "tau_bw",
        "tau_fg",
        "bal_res",
        "bal_noise",
        "bal_vib",
        "bal_drift",
        "bal_m0",
        "draught_sig",
    ):
        src = {
            "drift_o2": "drift_o2_pct_h",
            "noise_tbw": "noise_tbw_K",
            "q_tbw": "q_tbw_K",
            "tau_tw": "tau_tw_s",
            "tau_bw": "tau_bw_s",
            "tau_fg": "tau_fg_s",
            "bal_res": "bal_res_kg",
            "bal_noise": "bal_noise_kg",
            "bal_vib": "bal_vib_kg",
            "bal_drift": "bal_drift_kg_h",
            "bal_m0": "bal_m0_kg",
            "draught_sig": "draught_sig_Pa",
        }.get(key, key)
        v[key] = bg[src]
    v["an_delay_s"] = min(v["an_delay_s"], 60.0)
    v["off_tin"], v["off_tout"] = bg["off_tin_K"], bg["off_tout_K"]
    v["drift_tin"], v["drift_tout"] = bg["drift_tin_K_h"], bg["drift_tout_K_h"]
    v["noise_tw"] = bg["noise_tw_K"]
    v["off_tbw"], v["drift_tbw"] = bg["off_tbw_K"], bg["drift_tbw_K_h"]
    v["off_tfg"], v["off_o2"] = bg["off_tfg_K"], bg["off_o2_pct"]
    v["off_room"] = bg["off_room_K"]
    v["duct_area"] = DUCT_AREA_M2
    p = np.full(len(L.PARAM_NAMES), np.nan)
    for k, name in enumerate(L.PARAM_NAMES):
        if name not in v:
            raise KeyError(f"kernel parameter {name!r} not set")
        p[k] = v[name]
    return p


def _acquisition(n: int, sample_s: float, jitter: bool, rng: np.random.Generator) -> np.ndarray:
    """1 at the seconds that end an acquisition (a logged row)."""
    acq = np.zeros(n, dtype=np.int64)
    if not jitter:
        step = max(round(sample_s), 1)
        acq[step - 1 :: step] = 1
        return acq
    t = 0
    while True:
        t += max(1, round(sample_s * rng.uniform(0.6, 1.4)))
        if rng.random() < 0.01:  # a missed acquisition or two
            t += int(sample_s * rng.integers(1, 4))
        if t > n:
            return acq
        acq[t - 1] = 1


def simulate_log(
    boiler: Mapping,
    test: str,
    *,
    background: Mapping,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
    sample_s: float = 1.0,
    jitter: bool = False,
) -> tuple[dict[str, np.ndarray], dict]:
    """One lab log of ``test`` (``stationary`` or ``load_cycle``) on this plant.

    Returns the CONTRACT section 3 columns (``phase`` and ``sequence`` as text arrays; NaN
    where a reading is missing) and a meta dict (t0_s..t4_s, the truth and the plant's
    energy balance per row under ``truth``).
    """
    if not 1.0 <= float(sample_s) <= 10.0:
        raise ValueError(f"sample_s must be in [1, 10] s, got {sample_s}")
    protocol = load_protocol(test)
    fx = effect_settings(effect, form, strength)
    params = build_params(boiler, protocol, background, fx)
    n_max = longest_record_s(protocol)
    rng = np.random.default_rng([int(seed), 0 if test == "stationary" else 1])
    noise = rng.standard_normal((n_max, len(L.NOISE_NAMES)))
    acq = _acquisition(n_max, float(sample_s), bool(jitter), rng)
    mean_delay = float(fx.get("extra_delay_s", 0.0))
    start_delays = (
        np.clip(rng.gamma(4.0, mean_delay / 4.0, 16), 30.0, 1500.0)
        if fx.get("ign_form") == 2
        else np.zeros(16)
    )
    out = np.empty((n_max, len(L.OUTPUT_NAMES)))
    marks = np.full(5, np.nan)
    n = run_plant(params, schedule_array(protocol), noise, acq, start_delays, out, marks)
    rows = np.flatnonzero(acq[:n] == 1)
    if len(rows) == 0 or rows[-1] != n - 1:
        rows = np.append(rows, n - 1)  # the record ends with t4
    data = out[rows]
    time_s = data[:, L.R_TIME].copy()
    if jitter:
        time_s += rng.uniform(-0.2, 0.2, len(time_s))
        time_s[0] = max(time_s[0], 0.5)
    seq_names = [s[0] for s in protocol["sequences"]]
    columns: dict[str, np.ndarray] = {
        "time_s": time_s,
        "phase": np.array([PHASE_NAMES[int(x)] for x in data[:, L.R_PHASE]], dtype=object),
        "sequence": np.array(
            [seq_names[int(x)] if x >= 0 else "" for x in data[:, L.R_SEQUENCE]], dtype=object
        ),
    }
    for name, ch in COLUMNS:
        columns[name] = data[:, ch].copy()
    _dropouts(columns, background, rng)
    meta = {
        "test": test,
        "boiler": boiler.get("name"),
        "plant": "hil_client.reality2",
        "effect": effect,
        "form": (form or EFFECT_FORMS[effect][0]) if effect else None,
        "strength": float(strength),
        "seed": int(seed),
        "sample_s": float(sample_s),
        "jitter": bool(jitter),
        "starts": int(out[n - 1, L.X_STARTS]),
    }
    for k, name in enumerate(("t0_s", "t1_s", "t2_s", "t3_s", "t4_s")):
        meta[name] = float(marks[k])
    meta["truth"] = {name: out[rows, k].copy() for k, name in enumerate(L.OUTPUT_NAMES)}
    meta["truth_per_second"] = {name: out[:n, k] for k, name in enumerate(L.OUTPUT_NAMES)}
    return columns, meta


def _dropouts(columns: dict[str, np.ndarray], bg: Mapping, rng: np.random.Generator) -> None:
    """Missing readings: single dropouts per channel, and maybe a zero-gas check of the
    analyser (a few minutes of NaN in its columns) during the test."""
    n = len(columns["time_s"])
    for name, _ in COLUMNS:
        if name in ("water_flow_setpoint_kg_h", "boiler_on"):
            continue
        lost = rng.random(n) < bg["dropout_prob"]
        columns[name][lost] = np.nan
    if bg.get("analyser_gap"):
        test_rows = np.flatnonzero(columns["phase"] == "test")
        if len(test_rows) > 10:
            t = columns["time_s"]
            start = t[test_rows[0]] + rng.uniform(0.2, 0.8) * (t[test_rows[-1]] - t[test_rows[0]])
            gap = (t >= start) & (t < start + rng.uniform(120.0, 300.0))
            for name in ANALYSER:
                columns[name][gap] = np.nan
