"""The reality9 plant: a pellet boiler on the Wieselburg bench, stepped at DT seconds.

Physics after Carlon et al. (2015): fuel power on the HHV basis (Eq. 3), combustion with
an excess-air law (Eq. 9), flue-gas sensible, latent and CO losses (Eq. 4-6), ash loss,
a heat exchanger, the thermal capacity of body and water, losses to the room with UA
on/off (Eq. 10) and the electric igniter. Everything here is written from the paper; the
controller, start-up, exchanger law and bench are this plant's own (see background.py).

`run_plant` returns the true and sensor signals at every internal step plus an energy
and mass ledger; `simulate_log` (in __init__) samples it into a lab log.
"""

from __future__ import annotations

import bisect
import math
from pathlib import Path

import numpy as np
import yaml

DT = 2.0  # internal step, s
CP_W = 4.19  # kJ/(kg K)
RHO_W = 990.0  # kg/m3
CP_FG = 1.06  # dry flue gas, kJ/(kg K)
CP_VAP = 1.90  # water vapour, kJ/(kg K)
DH_VAP = 2442.0  # kJ/kg
DH_CO = 10100.0  # kJ/kg
RHO_AIR_N = 1.293  # kg/m3 at 0 C, 1013 hPa
RHO_CO_N = 1.25

PHASES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
OFF, PURGE, IGNITE, RAMP, RUN, BURNOUT = range(6)


def load_protocol(test: str) -> dict:
    if test not in ("stationary", "load_cycle"):
        raise ValueError(f"unknown test {test!r}")
    path = Path(__file__).parents[1] / "protocol" / "definitions" / f"{test}.yaml"
    return yaml.safe_load(path.read_text())


def _hms(text) -> float:
    if isinstance(text, (int, float)):
        return float(text)
    h, m, s = (float(x) for x in str(text).split(":"))
    return 3600.0 * h + 60.0 * m + s


def fuel_constants(fuel: dict) -> dict:
    c, h, o, n, s = (float(fuel[k]) for k in ("c", "h", "o", "n", "s"))
    airmin_v = (1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21
    return {
        "airmin_v": airmin_v,
        "airmin_m": airmin_v * RHO_AIR_N,
        "v_co2": 1.866 * c,
        "v_rest": 0.7 * s + 0.8 * n,  # SO2 + fuel N2, m3/kg dry
        "h2o_comb": 9.0 * h,  # kg water per kg dry fuel
        "ash": float(fuel["ash"]),
    }


def gas(m_b: float, m_air: float, wd: float, fc: dict) -> tuple:
    """Flue gas of m_b kg/h dry fuel burnt in m_air kg/h air with wd kg water per kg dry.

    Returns (heat capacity flow kW/K, vapour kg/h, dry volume m3/h (norm), O2 %, CO2 %).
    """
    m_vap = m_b * (fc["h2o_comb"] + wd)
    m_dg = m_air + m_b * (1.0 - fc["ash"] - fc["h2o_comb"])
    cfg = (m_dg * CP_FG + m_vap * CP_VAP) / 3600.0
    v_air = m_air / RHO_AIR_N
    v_o2 = max(0.21 * v_air - 0.21 * fc["airmin_v"] * m_b, 0.0)
    v_dry = 0.79 * v_air + v_o2 + m_b * (fc["v_co2"] + fc["v_rest"])
    if v_dry <= 1e-12:
        return 0.0, 0.0, 0.0, 20.95, 0.0
    return cfg, m_vap, v_dry, 100.0 * v_o2 / v_dry, 100.0 * m_b * fc["v_co2"] / v_dry


def drift(bg: dict, name: str, t: float) -> float:
    return (
        bg[f"{name}_offset_K"]
        + bg[f"{name}_drift_K_h"] * t / 3600.0
        + bg[f"{name}_drift_amp_K"]
        * math.sin(
            2.0 * math.pi * t / (3600.0 * bg[f"{name}_drift_period_h"]) + bg[f"{name}_drift_phase"]
        )
    )


def room_temp(bg: dict, t) -> float:
    return bg["room_base_C"] + bg["room_amp_K"] * np.sin(
        2.0 * np.pi * t / (3600.0 * bg["room_period_h"]) + bg["room_phase"]
    )


def nominal_point(boiler: dict, bg: dict) -> dict:
    """Nominal firing point used to set up the exchanger and the fan."""
    fuel = boiler["fuel"]
    fc = fuel_constants(fuel)
    hhv = float(fuel["hhv_dry_kJ_kg"]) * bg["hhv_factor"]
    lhv_nom = float(fuel["hhv_dry_kJ_kg"]) - DH_VAP * fc["h2o_comb"]
    w = float(fuel["moisture"])
    wd = w / (1.0 - w)
    m_dry = float(boiler["p_nom_kW"]) * 3600.0 / (lhv_nom * 0.93)
    lam = max(boiler["fac_a_lambda"] + boiler["fac_b_lambda_h_kg"] * m_dry, 1.2)
    m_air = lam * fc["airmin_m"] * m_dry
    cfg, m_vap, v_dry, _, _ = gas(m_dry, m_air, wd, fc)
    q_in = m_dry * hhv / 3600.0 * 0.9998 - m_vap * DH_VAP / 3600.0
    t_room = bg["room_base_C"]
    t_ad = t_room + q_in / cfg
    t_fg = 55.0 + float(boiler["dt_nom_K"]) * bg["dt_fg_factor"]
    t_b = 70.0
    ntu = math.log((t_ad - t_b) / (t_fg - t_b))
    v_act = (v_dry + m_vap / 0.804) * (t_fg + 273.15) / 273.15
    return {
        "fc": fc,
        "hhv": hhv,
        "lhv_nom": lhv_nom,
        "m_dry": m_dry,
        "m_air": m_air,
        "cfg": cfg,
        "ntu": ntu,
        "area_m2": v_act / 3600.0 / bg["v_nom_m_s"],
    }


def run_plant(
    boiler: dict,
    test: str,
    bg: dict,
    effect: str | None,
    form: str | None,
    s: float,
    seed: int,
) -> dict:
    """Step the plant through a whole test; return per-step arrays and the phase times."""
    proto = load_protocol(test)
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 9])
    if effect is None or s == 0.0:
        effect, form, s = None, None, 0.0
    fx = form  # the active form name or None
    dt = DT
    p_nom = float(boiler["p_nom_kW"])
    p_max = float(boiler["p_max_kW"])
    p_min = float(boiler["p_min_kW"])
    p_start = float(boiler["p_start_kW"])
    fuel = boiler["fuel"]
    nom = nominal_point(boiler, bg)
    fc = nom["fc"]
    hhv, lhv_nom = nom["hhv"], nom["lhv_nom"]
    cfg_nom, ntu_nom = nom["cfg"], nom["ntu"]
    air_nom = nom["m_air"] * bg["fan_factor"]
    air_min = 0.3 * air_nom
    w_nom = float(fuel["moisture"])
    w_act = w_nom + bg["moisture_dev"]
    if fx == "damp_delivery_lot":
        w_act += 0.10 * s
    wd_act = w_act / (1.0 - w_act)
    fac_a, fac_b = float(boiler["fac_a_lambda"]), float(boiler["fac_b_lambda_h_kg"])

    c_therm = float(boiler["c_therm_kJ_K"]) * bg["cap_factor"]
    c_water = float(boiler["vol_water_m3"]) * RHO_W * CP_W
    c_b = c_therm + c_water
    ua_on = float(boiler["ua_amb_on_W_K"]) * bg["ua_on_factor"] / 1000.0
    ua_off = float(boiler["ua_amb_off_W_K"]) * bg["ua_off_factor"] / 1000.0

    # --- effect set-up ---------------------------------------------------------------
    # body: metal nodes between the gas and the water (capacity taken from the body node)
    c_m = [0.0, 0.0, 0.0]
    g_m = [1.0, 1.0, 1.0]
    if fx == "fire_side_steel_skin":
        c_m[0] = 0.7 * c_therm * s
        g_m[0] = p_nom / 60.0
    elif fx == "three_shell_conduction_chain":
        c_m = [0.35 * c_therm * s, 0.25 * c_therm * s, 0.2 * c_therm * s]
        g_m = [p_nom / 25.0, p_nom / 25.0, p_nom / 20.0]
    c_b -= sum(c_m)
    # flue-gas stores (refractory)
    c_r = [0.0, 0.0]
    if fx == "hearth_stone_buffer":
        eps_r = 0.5 * s
        c_r[0] = eps_r * cfg_nom * 700.0
    elif fx == "baffle_cascade_pair":
        ntu_r = [0.6 * s, 0.4 * s]
        tau_r = [400.0, 1500.0]
        c_r = [(1.0 - math.exp(-ntu_r[i])) * cfg_nom * tau_r[i] for i in range(2)]
    ua_rw = [c / 14400.0 for c in c_r]  # slow leak of each store to the water
    # outlet pipe
    c_cell = 3.0 * s / 3.0  # kJ/K per cell, 3 cells
    ua_cell = 0.0015 * s * s / 3.0  # kW/K per cell
    m_pipe = 0.8 * s  # kg of water in the pipe (parcel form)
    tau_pipe = 1500.0
    # ignition
    t_ign_extra = 900.0 * s if fx == "slow_kindling_front" else 0.0
    t_ign_needed = bg["t_ign_s"] + t_ign_extra
    tau_warm = 1200.0 * s if fx == "gradual_pyrolysis_onset" else 0.0

    # --- protocol ----------------------------------------------------------------------
    pre = proto["preheat"]
    su = proto["start_up"]
    seqs = proto["test_sequence"]["sequences"]
    seq_names = [str(q["name"]) for q in seqs]
    seq_dur = [_hms(q["duration"]) for q in seqs]
    seq_end = list(np.cumsum(seq_dur))
    seq_load = []
    for q in seqs:
        lp = q["load_pct"]
        seq_load.append((float(lp[0]), float(lp[1])) if isinstance(lp, list) else (lp, lp))
    c1 = proto["cooling_1"]
    t_c2 = float(proto["cooling_2"]["until_after_t2_s"])
    spread = float(proto["flow_spread_K"])
    flow_100 = p_nom * 3600.0 / (CP_W * spread)
    win_n = max(1, round(float(su["t1_window_s"]) / dt))

    # --- random inputs of the plant --------------------------------------------------
    n_pulse = int(200000 / bg["auger_period_s"]) + 2
    lumps = np.clip(1.0 + bg["lump_sigma"] * rng.standard_normal(n_pulse), 0.2, 2.5).tolist()

    # --- state -------------------------------------------------------------------------
    t = 0.0
    phase = 0
    seq = -1
    t_ph = [math.nan] * 5
    t_ph[0] = 0.0
    t_end = math.nan
    enabled = False
    start_pending = False
    hold = 0.0
    tb = bg["t_boiler0_C"]
    t_in = tb
    m_w = 0.0
    tm = [tb, tb, tb]
    tr = [tb, tb]
    cells = [tb, tb, tb]
    f_ctrl = f_bw = f_out = f_in = tb
    f_fg = room_temp(bg, 0.0) + 0.85 * (tb - room_temp(bg, 0.0))
    state = OFF
    t_state = 0.0
    t_cycle = 0.0
    t_ign_start = -1e9
    t_lit = -1e9
    lit = False
    lit_once_t = math.nan
    integ = p_min
    p_cmd = 0.0
    m_bed = 0.0
    fed_dry = fed_ar = burned = 0.0
    hist_tb: list[float] = []
    hist_mc: list[float] = []
    m_cum = 0.0
    fg_hist: list[float] = []

    names = [
        "t",
        "phase",
        "seq",
        "m_w",
        "m_set",
        "t_in_m",
        "t_out_m",
        "t_bw_m",
        "t_fg_m",
        "t_b",
        "t_in",
        "t_sw",
        "t_fg",
        "o2",
        "co2",
        "co",
        "vel",
        "state",
        "on",
        "p_el",
        "fed_ar",
        "fed_dry",
        "burned",
        "m_bed",
        "m_b",
        "p_cmd",
        "t_room",
        "e_in",
        "e_water",
        "e_flue",
        "e_ash",
        "e_room",
        "e_store",
    ]
    rec: dict[str, list] = {k: [] for k in names}

    a_ctrl = 1.0 - math.exp(-dt / bg["ctrl_tau_s"])
    a_bw = 1.0 - math.exp(-dt / bg["bw_tau_s"])
    a_out = 1.0 - math.exp(-dt / bg["out_tau_s"])
    a_in = 1.0 - math.exp(-dt / bg["in_tau_s"])
    a_fg = 1.0 - math.exp(-dt / bg["fg_tau_s"])
    a_flow = 1.0 - math.exp(-dt / bg["flow_tau_s"])
    a_rc = 1.0 - math.exp(-dt / bg["rc_tau_s"])
    a_stag = 1.0 - math.exp(-dt / 1800.0)
    ki = bg["kp_kW_K"] / bg["ti_s"]
    kp = bg["kp_kW_K"]
    t_set, t_off, t_rst = bg["t_set_C"], bg["t_off_C"], bg["t_restart_C"]
    p_ig = float(boiler["w_el_Wh"]) * 3.6 / (bg["t_ign_s"] + bg["t_detect_s"])  # kW

    max_steps = int((pre["max_duration_s"] + su["max_duration_s"] + seq_end[-1] + t_c2) / dt) + 10
    for _ in range(max_steps):
        t_room = room_temp(bg, t)
        t_out_m = f_out + drift(bg, "out", t)
        t_in_m = f_in + drift(bg, "in", t)
        t_fg_m = f_fg + drift(bg, "fg", t)
        t_ctrl = f_ctrl + drift(bg, "ctrl", t)
        fg_hist.append(t_fg_m)
        # ---- protocol -----------------------------------------------------------------
        if phase == 0:
            ret_set, load = float(pre["temperature_C"]), float(pre["load_pct"])
            tol = float(pre["tolerance_K"])
            ok = abs(t_out_m - ret_set) <= tol and abs(t_in_m - ret_set) <= tol
            hold = hold + dt if ok else 0.0
            if hold >= float(pre["hold_s"]) or t >= float(pre["max_duration_s"]):
                phase, t_ph[1], enabled, start_pending = 1, t, True, True
        elif phase == 1:
            ret_set, load = float(su["return_setpoint_C"]), seq_load[0][0]
            el = t - t_ph[1]
            rise_ok = False
            if lit_once_t == lit_once_t and t - lit_once_t >= float(su["t1_window_s"]):
                rise = (fg_hist[-1] - fg_hist[-1 - win_n]) / (win_n * dt / 60.0)
                rise_ok = rise < float(su["t1_max_rise_K_min"])
            if (el >= float(su["min_duration_s"]) and rise_ok) or el >= float(su["max_duration_s"]):
                phase, t_ph[2] = 2, t
        if phase == 2:
            el = t - t_ph[2]
            ret_set = float(proto["test_sequence"]["return_setpoint_C"])
            seq = bisect.bisect_right(seq_end, el)
            if seq >= len(seqs):
                phase, t_ph[3], enabled, seq = 3, t, False, -1
            else:
                a, b = seq_load[seq]
                frac = (el - (seq_end[seq] - seq_dur[seq])) / seq_dur[seq]
                load = a + (b - a) * frac
        if phase == 3:
            ret_set, load = float(c1["return_setpoint_C"]), float(c1["load_pct"])
            if t_out_m <= float(c1["until_forward_C"]) or t - t_ph[3] >= float(
                c1["max_duration_s"]
            ):
                phase, t_ph[4] = 4, t
        if phase == 4:
            load = 0.0
            if t - t_ph[3] >= t_c2:
                t_end = t
                break
        m_set = load / 100.0 * flow_100
        # ---- controller ---------------------------------------------------------------
        if not enabled and state in (PURGE, IGNITE, RAMP, RUN):
            state, t_state = BURNOUT, t
        restart = t_ctrl < t_rst and t - t_state >= bg["t_min_off_s"]
        if state == OFF and enabled and (start_pending or restart):
            state, t_state, t_cycle, start_pending = PURGE, t, t, False
        if state == PURGE and t - t_state >= bg["t_purge_s"]:
            state, t_state, t_ign_start = IGNITE, t, t
        if state == IGNITE and t - t_state >= bg["t_ign_s"] + bg["t_detect_s"]:
            state, t_state = RAMP, t
        if state == RAMP:
            p_cmd = p_min + (p_start - p_min) * min(1.0, (t - t_state) / bg["t_ramp_s"])
            if t - t_state >= bg["t_ramp_s"]:
                state, t_state, integ = RUN, t, p_cmd
        if state == RUN:
            e = t_set - t_ctrl
            p_raw = kp * e + integ
            if (p_raw < p_max or e < 0.0) and (p_raw > p_min or e > 0.0):
                integ = min(max(integ + ki * e * dt, p_min), p_max)
            p_cmd = min(max(kp * e + integ, p_min), p_max)
            if (t_ctrl > t_off and t - t_cycle >= bg["t_min_burn_s"]) or t_ctrl > t_off + 4.0:
                state, t_state = BURNOUT, t
        if state == BURNOUT and t - t_state >= bg["t_post_s"] and (m_bed < 1e-3 or not lit):
            state, t_state = OFF, t
        # ---- feed, air, igniter -------------------------------------------------------
        feed_ar = 0.0
        q_ig = 0.0
        m_dry_cmd = 0.0
        if state in (RAMP, RUN):
            m_dry_cmd = p_cmd * 3600.0 / lhv_nom
            lump = lumps[int(t / bg["auger_period_s"]) % n_pulse]
            feed_ar = m_dry_cmd / (1.0 - w_nom) * bg["auger_gain"] * lump
            lam = max(fac_a + fac_b * m_dry_cmd, 1.2)
            m_air = max(lam * fc["airmin_m"] * m_dry_cmd * bg["fan_factor"], air_min)
        elif state == PURGE:
            m_air = 0.6 * air_nom
        elif state == IGNITE:
            m_air = air_min
            q_ig = p_ig
            if t - t_state < bg["t_charge_s"]:
                feed_ar = bg["charge_kg"] / bg["t_charge_s"] * 3600.0
        elif state == BURNOUT:
            m_air = air_min
        else:
            m_air = 0.0
        on = 1 if state in (IGNITE, RAMP, RUN) else 0
        feed_dry = feed_ar * (1.0 - w_act)
        # ---- bed ----------------------------------------------------------------------
        burning_state = state in (IGNITE, RAMP, RUN)
        if not lit and m_bed > 0.0 and burning_state and t - t_ign_start >= t_ign_needed:
            lit, t_lit = True, t
            if lit_once_t != lit_once_t and phase == 1:
                lit_once_t = t
        dm = 0.0
        if lit:
            tau_b = bg["tau_bed_s"]
            rate = 1.0
            if tau_warm > 0.0:
                rate = 1.0 - math.exp(-(t - t_lit) / tau_warm)
                if state in (OFF, BURNOUT):
                    tau_b *= 1.0 + 4.0 * s
            dm = m_bed * (1.0 - math.exp(-dt * rate / tau_b))
            # a pile cannot burn faster than the air through the grate allows
            dm = min(dm, max(m_air, 0.05 * air_nom) / (1.05 * fc["airmin_m"]) * dt / 3600.0)
            if state in (OFF, BURNOUT) and m_bed < 2e-4:
                lit = False
        m_b = dm * 3600.0 / dt
        # ---- combustion and gas -------------------------------------------------------
        cfg, m_vap, v_dry, o2, co2 = gas(m_b, m_air, wd_act, fc)
        q_fuel = m_b * hhv / 3600.0
        f_ub = 0.0
        if fx == "cold_wall_char_residue":
            f_ub = s * (0.02 + 0.08 * min(max((75.0 - tb) / 30.0, 0.0), 1.0))
        q_ash = 0.0002 * q_fuel + f_ub * q_fuel
        q_lat = m_vap * DH_VAP / 3600.0
        co = 0.0
        if m_b > 1e-4:
            x = m_b / nom["m_dry"]
            lam_act = m_air / (fc["airmin_m"] * m_b)
            co = bg["co_base_ppm"] * (1.0 + 3.0 * max(0.0, 0.5 - x) ** 2)
            co = min(co + 250.0 * max(0.0, lam_act - 2.5), 5000.0)
        q_chem = co * 1e-6 * v_dry * RHO_CO_N * DH_CO / 3600.0
        q_gas = q_fuel - q_ash - q_lat - q_chem + q_ig
        q_r = [0.0, 0.0]
        q_rw = [ua_rw[i] * (tr[i] - tb) for i in range(2)]
        if cfg > 1e-9:
            t_ad = t_room + q_gas / cfg
            t_hot = t_ad
            if fx == "hearth_stone_buffer":
                g = eps_r * cfg
                tr_new = (c_r[0] * tr[0] + dt * (g * t_ad - q_rw[0])) / (c_r[0] + dt * g)
                q_r[0] = g * (t_ad - tr_new)
                t_hot = t_ad - q_r[0] / cfg
            elif fx == "baffle_cascade_pair":
                for i in range(2):
                    ntu_i = ntu_r[i] * max(cfg / cfg_nom, 0.05) ** -0.2
                    g = (1.0 - math.exp(-ntu_i)) * cfg
                    tr_new = (c_r[i] * tr[i] + dt * (g * t_hot - q_rw[i])) / (c_r[i] + dt * g)
                    q_r[i] = g * (t_hot - tr_new)
                    t_hot -= q_r[i] / cfg
            ntu = ntu_nom * max(cfg / cfg_nom, 0.05) ** (-bg["ntu_exp"])
            t_fg = tb + (t_hot - tb) * math.exp(-ntu)
            q_hx = cfg * (t_hot - t_fg)
            q_sens = cfg * (t_fg - t_room)
        else:
            t_fg = t_room + 0.85 * (tb - t_room)
            q_hx = 0.0
            q_sens = 0.0
        # ---- body ---------------------------------------------------------------------
        store = 0.0
        for i in range(2):
            if c_r[i] > 0.0:
                new = tr[i] + dt * (q_r[i] - q_rw[i]) / c_r[i]
                store += c_r[i] * (new - tr[i])
                tr[i] = new
        q_into_b = q_hx + q_rw[0] + q_rw[1]
        if fx == "fire_side_steel_skin":
            c0, g0 = c_m[0], g_m[0]
            tm_new = (c0 * tm[0] + dt * (q_into_b + g0 * tb)) / (c0 + dt * g0)
            q_mw = g0 * (tm_new - tb)
            new = tm[0] + dt * (q_into_b - q_mw) / c0
            store += c0 * (new - tm[0])
            tm[0] = new
            q_into_b = q_mw
        elif fx == "three_shell_conduction_chain":
            cc = [c_m[i] / dt for i in range(3)]
            g1, g2, g3 = g_m
            # tridiagonal backward-Euler solve (Thomas)
            a_d = [cc[0] + g1, cc[1] + g1 + g2, cc[2] + g2 + g3]
            rhs = [cc[0] * tm[0] + q_into_b, cc[1] * tm[1], cc[2] * tm[2] + g3 * tb]
            up = [-g1, -g2]
            lo = [-g1, -g2]
            cp_ = [up[0] / a_d[0], 0.0]
            dp = [rhs[0] / a_d[0], 0.0, 0.0]
            den = a_d[1] - lo[0] * cp_[0]
            cp_[1] = up[1] / den
            dp[1] = (rhs[1] - lo[0] * dp[0]) / den
            den = a_d[2] - lo[1] * cp_[1]
            dp[2] = (rhs[2] - lo[1] * dp[1]) / den
            x3 = dp[2]
            x2 = dp[1] - cp_[1] * x3
            x1 = dp[0] - cp_[0] * x2
            q01, q12, q23 = g1 * (x1 - x2), g2 * (x2 - x3), g3 * (x3 - tb)
            fl = [q_into_b - q01, q01 - q12, q12 - q23]
            for i in range(3):
                new = tm[i] + dt * fl[i] / c_m[i]
                store += c_m[i] * (new - tm[i])
                tm[i] = new
            q_into_b = q23
        q_w = m_w * CP_W * (tb - t_in) / 3600.0
        q_amb = (ua_on if on else ua_off) * (tb - t_room)
        tb_new = tb + dt * (q_into_b - q_w - q_amb) / c_b
        store += c_b * (tb_new - tb)
        # ---- ledger and record (values of this step) ----------------------------------
        rec["e_in"].append((q_fuel + q_ig) * dt)
        rec["e_water"].append(q_w * dt)
        rec["e_flue"].append((q_sens + q_lat + q_chem) * dt)
        rec["e_ash"].append(q_ash * dt)
        rec["e_room"].append(q_amb * dt)
        rec["e_store"].append(store)
        vel = 0.0
        if cfg > 1e-9:
            v_act = (v_dry + m_vap / 0.804) * (t_fg + 273.15) / 273.15 * 1013.0 / bg["pressure_hPa"]
            vel = v_act / 3600.0 / nom["area_m2"]
        if state == OFF:
            p_el = float(boiler["p_el_off_W"])
        elif state == PURGE:
            p_el = float(boiler["p_el_max_W"])
        elif state == IGNITE:
            p_el = float(boiler["p_el_min_W"]) + 1000.0 * q_ig
        elif state == BURNOUT:
            p_el = float(boiler["p_el_min_W"])
        else:
            xl = min(max((p_cmd / p_nom - 0.3) / 0.7, 0.0), 1.0)
            p_el = boiler["p_el_min_W"] + (boiler["p_el_max_W"] - boiler["p_el_min_W"]) * xl
        for k, v in (
            ("t", t), ("phase", phase), ("seq", seq), ("m_w", m_w), ("m_set", m_set),
            ("t_in_m", t_in_m), ("t_out_m", t_out_m), ("t_bw_m", f_bw + drift(bg, "bw", t)),
            ("t_fg_m", t_fg_m), ("t_b", tb), ("t_in", t_in), ("t_sw", cells[2]),
            ("t_fg", t_fg), ("o2", o2), ("co2", co2), ("co", co), ("vel", vel),
            ("state", state), ("on", on), ("p_el", p_el * bg["el_gain"]),
            ("fed_ar", fed_ar), ("fed_dry", fed_dry), ("burned", burned), ("m_bed", m_bed),
            ("m_b", m_b), ("p_cmd", p_cmd if state in (RAMP, RUN) else 0.0),
            ("t_room", t_room),
        ):  # fmt: skip
            rec[k].append(v)
        # ---- updates ------------------------------------------------------------------
        m_bed = m_bed - dm + feed_dry * dt / 3600.0
        burned += dm
        fed_dry += feed_dry * dt / 3600.0
        fed_ar += feed_ar * dt / 3600.0
        tb_old = tb
        tb = tb_new
        # bench return conditioning: capacity-limited, lagged, hunting valve
        if m_w > 1e-6:
            gw = m_w * CP_W / 3600.0
            osc = 0.0
            if phase > 0:
                osc = bg["rc_osc_amp_K"] * math.sin(2.0 * math.pi * t / bg["rc_osc_period_s"])
            p_cool, p_heat = bg["rc_cool_cap"] * p_nom, bg["rc_heat_cap"] * p_nom
            target = min(max(ret_set + osc, tb_old - p_cool / gw), tb_old + p_heat / gw)
            t_in += a_rc * (target - t_in)
        else:
            t_in += a_stag * (t_room + 0.4 * (tb_old - t_room) - t_in)
        # water at the forward sensor
        m_cum += m_w * dt / 3600.0
        if fx == "lossy_exit_cells":
            up_t = tb_old
            gflow = m_w * CP_W / 3600.0
            for i in range(3):
                cells[i] = (c_cell * cells[i] + dt * (gflow * up_t + ua_cell * t_room)) / (
                    c_cell + dt * (gflow + ua_cell)
                )
                up_t = cells[i]
            t_sw = cells[2]
        elif fx == "aging_parcel_transit":
            hist_tb.append(tb_old)
            hist_mc.append(m_cum)
            j = bisect.bisect_left(hist_mc, m_cum - m_pipe)
            j = min(j, len(hist_mc) - 1)
            age = (len(hist_mc) - 1 - j) * dt
            t_src = hist_tb[j]
            t_sw = t_room + (t_src - t_room) * math.exp(-s * age / tau_pipe)
            cells[2] = t_sw
        else:
            t_sw = tb_old
            cells[2] = t_sw
        m_w += a_flow * (m_set * bg["flow_gain"] - m_w)
        if m_set == 0.0 and m_w < 0.5:
            m_w = 0.0
        f_ctrl += a_ctrl * (tb - f_ctrl)
        f_bw += a_bw * (tb - f_bw)
        f_out += a_out * (t_sw - f_out)
        f_in += a_in * (t_in - f_in)
        f_fg += a_fg * (t_fg - f_fg)
        t += dt
    if t_end != t_end:
        t_end = t
    out = {k: np.asarray(v, dtype=float) for k, v in rec.items()}
    out["phase"] = out["phase"].astype(int)
    out["seq"] = out["seq"].astype(int)
    out["on"] = out["on"].astype(int)
    out["state"] = out["state"].astype(int)
    meta: dict = {}
    meta["t0_s"] = float(t_ph[1])
    meta["t1_s"] = float(t_ph[2])
    meta["t2_s"] = float(t_ph[3])
    meta["t3_s"] = float(t_ph[4])
    meta["t4_s"] = float(t_end)
    meta["seq_names"] = seq_names
    meta["dt_s"] = dt
    return {"steps": out, "meta": meta}
