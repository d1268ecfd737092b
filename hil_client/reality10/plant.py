"""The reality10 plant: a pellet boiler after Carlon et al. (2015), TRNSYS Type 869, on the
Wieselburg bench, stepped at a fixed 2 s internal step.

Type 869's balance is kept (fuel power on HHV basis, excess air linear in the dry fuel flow,
flue-gas sensible / latent / CO / ash losses, losses to the room with UA on/off, igniter
energy into the chamber), but the boiler is a real one: a fuel bed fed by a pulsing auger, a
metal node between the flame and the water, its own controller and start/stop sequence, a
load-dependent exchanger and a bench with its own return conditioning and sensors (see
background.py). One listed effect (or none) may be switched on. An internal energy ledger and
the true fuel/hopper masses are returned for checks. Only numpy and the standard library.
"""

from __future__ import annotations

import bisect
import math

import numpy as np

DT = 2.0  # internal step [s]
CP_W = 4.19  # kJ/(kg K), also the bench's load definition
RHO_W = 978.0  # kg/m3 at ~70 C
DH_VAP = 2442.0  # kJ/kg
DH_CO = 10100.0  # kJ/kg
HHV_C = 32800.0  # kJ/kg, char
CP_VAP = 1.88

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("layered_wall", "lumped_core_mass"),
    "outlet_sensor_pipe": ("plug_flow_pipe", "mixed_well_volume"),
    "ignition_delay": ("dead_time_pile_up", "slow_ignition_front"),
    "flue_gas_lag": ("refractory_first_order", "exchanger_second_order_flow"),
    "fuel_energy_bias": ("wet_fuel_moisture", "unburnt_carbon_in_ash"),
}


def effect_params(effect: str | None, form: str | None, s: float) -> dict[str, float]:
    """Physical parameters of one effect form at strength ``s`` (linear weak -> strong)."""

    def lin(a: float, b: float) -> float:
        return a + (b - a) * s

    if effect is None:
        return {}
    table = {
        "layered_wall": {"tau_diff_s": lin(90.0, 700.0)},
        "lumped_core_mass": {
            "core_share": lin(0.15, 0.5),
            "rad_fraction": lin(0.1, 0.3),
            "tau_core_s": lin(200.0, 900.0),
        },
        "plug_flow_pipe": {
            "volume_L": lin(0.15, 1.5),
            "tau_loss_s": lin(4000.0, 600.0),
            "stagnant_coupling": lin(0.98, 0.6),  # stagnant pipe: share of boiler excess
        },
        "mixed_well_volume": {
            "volume_L": lin(0.15, 2.0),
            "ua_W_K": lin(0.03, 1.2),  # to the room
            "g_boiler_W_K": 1.0,  # conduction along the pipe wall from the boiler
        },
        "dead_time_pile_up": {"dead_time_s": lin(30.0, 360.0)},
        "slow_ignition_front": {"ramp_s": lin(60.0, 600.0), "burnout_tau_s": lin(30.0, 480.0)},
        "refractory_first_order": {"tau_s": lin(60.0, 900.0)},
        "exchanger_second_order_flow": {"tau_s": lin(60.0, 900.0)},
        "wet_fuel_moisture": {"moisture_add": lin(0.015, 0.12)},
        "unburnt_carbon_in_ash": {"energy_fraction": lin(0.02, 0.13)},
    }
    return dict(table[str(form)])


def _hms(text: str) -> float:
    h, m, sec = (float(x) for x in str(text).split(":"))
    return 3600 * h + 60 * m + sec


def build_schedule(proto: dict) -> list[tuple[str, float, float, float]]:
    """Test sequences as (name, start load %, end load %, duration s)."""
    out = []
    for seq in proto["test_sequence"]["sequences"]:
        load = seq["load_pct"]
        a, b = (float(load[0]), float(load[1])) if isinstance(load, list) else (float(load),) * 2
        out.append((str(seq["name"]), a, b, _hms(seq["duration"])))
    return out


def run_plant(
    boiler: dict,
    proto: dict,
    bg: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
) -> dict:
    """Simulate one test on the internal grid; return traces (lists) and meta."""
    ep = effect_params(effect, form, strength)
    rng = np.random.default_rng(seed)
    fuel = boiler["fuel"]
    hhv = float(fuel["hhv_dry_kJ_kg"])
    c_f, h_f, o_f, n_f, s_f = (float(fuel[k]) for k in ("c", "h", "o", "n", "s"))
    w_nom = float(fuel["moisture"])
    w = w_nom + bg["fuel_moisture_dev"] + ep.get("moisture_add", 0.0)
    wd = w / (1 - w)  # water per kg dry
    char = ep.get("energy_fraction", 0.0) * hhv / HHV_C  # kg char per kg dry
    lhv_ar_nom = (hhv - DH_VAP * 8.94 * h_f) * (1 - w_nom) - DH_VAP * w_nom
    air_min = (1.866 * c_f + 5.56 * h_f + 0.7 * s_f - 0.7 * o_f) / 0.21  # m3N/kg dry
    o2_dem = 1.866 * (c_f - char) + 5.56 * h_f + 0.7 * s_f - 0.7 * o_f  # m3N O2 / kg dry
    v_co2 = 1.866 * (c_f - char)
    h2o_kg = 8.94 * h_f + wd  # kg water vapour / kg dry

    p_nom, p_max, p_min = (float(boiler[k]) for k in ("p_nom_kW", "p_max_kW", "p_min_kW"))
    p_start = float(boiler["p_start_kW"])
    fa, fb = float(boiler["fac_a_lambda"]), float(boiler["fac_b_lambda_h_kg"])
    spread = float(proto.get("flow_spread_K", 15))
    m_nom = p_nom * 3600.0 / (CP_W * spread)  # kg/h

    def lam_law(md_kg_h: float) -> float:
        lam = (fa + fb * md_kg_h) * bg["lambda_gain"]
        lam *= 1.0 + bg["lambda_curv"] * max(0.0, 1.0 - md_kg_h / md_max) ** 2
        return max(lam, 1.25)

    md_max = p_max / lhv_ar_nom * (1 - w_nom) * 3600.0  # kg/h dry at Pmax
    md_min = p_min / lhv_ar_nom * (1 - w_nom) * 3600.0
    va_min = lam_law(md_min) * air_min * md_min / 3600.0  # m3N/s
    va_purge = bg["fan_purge_frac"] * va_min
    q_ref = p_max * hhv * (1 - w_nom) / lhv_ar_nom * (p_nom / p_max)  # kW HHV, ~nominal
    lam_n = lam_law(md_max * p_nom / p_max)
    mfg_nom = (lam_n * air_min * 1.293 + 1.0 - h2o_kg) * md_max * p_nom / p_max / 3600.0
    vfg_nom = (lam_n * air_min + 1.244 * h2o_kg) * md_max * p_nom / p_max / 3600.0
    a_flue = vfg_nom * (273.15 + 150.0) / 273.15 / bg["v_fg_nom_m_s"]

    # body
    c_metal = float(boiler["c_therm_kJ_K"]) * bg["body_metal_scale"]
    c_water = float(boiler["vol_water_m3"]) * RHO_W * CP_W * bg["body_water_scale"]
    ua_on = float(boiler["ua_amb_on_W_K"]) * bg["ua_on_scale"] / 1000.0
    ua_off = float(boiler["ua_amb_off_W_K"]) * bg["ua_off_scale"] / 1000.0
    if form == "layered_wall":
        nl = 3
        caps = [c_metal / nl] * nl
        g_l = nl * c_metal / ep["tau_diff_s"]
        gs = [g_l] * nl  # layer i -> i+1, last -> water
        rad = 1.0
    elif form == "lumped_core_mass":
        caps = [c_metal * (1 - ep["core_share"]), c_metal * ep["core_share"]]
        gs = [c_metal / bg["body_metal_tau_s"], caps[1] / ep["tau_core_s"]]
        rad = ep["rad_fraction"]
    else:
        caps = [c_metal]
        gs = [c_metal / bg["body_metal_tau_s"]]
        rad = 0.0
    n_sub = max(1, math.ceil(DT / (0.4 * min(c / g for c, g in zip(caps, gs, strict=True)))))
    h_sub = DT / n_sub

    t_init = bg["boiler_init_C"]
    tm = [t_init] * len(caps)
    tw = t_init
    t_ret = t_init
    flow = 0.0
    e_store0 = sum(c * t for c, t in zip(caps, tm, strict=True)) + c_water * tw

    # schedule / protocol
    pre, su, c1, c2 = proto["preheat"], proto["start_up"], proto["cooling_1"], proto["cooling_2"]
    seqs = build_schedule(proto)
    test_dur = sum(x[3] for x in seqs)
    n_max = (
        int(
            (
                pre["max_duration_s"]
                + su["max_duration_s"]
                + test_dur
                + c1["max_duration_s"]
                + c2["until_after_t2_s"]
            )
            / DT
        )
        + 10
    )
    noise = rng.standard_normal(n_max).tolist()
    win_n = max(1, round(su["t1_window_s"] / DT))

    # effect-specific state
    pipe_v = ep.get("volume_L", 0.0) / 1000.0
    hist_v: list[float] = []
    hist_t: list[float] = []
    hist_tw: list[float] = []
    cum_v = 0.0
    t_pipe = t_init
    fg_lags = [t_init, t_init, t_init]
    tau_fg_eff = ep.get("tau_s", 0.0)

    # controller and bed
    state = 0  # 0 off, 1 purge, 2 ignite, 3 ramp, 4 hold, 5 modulate, 6 burn-out
    t_state = 0.0
    t_off = 1e9
    t_since_start = 0.0
    p_cmd = 0.0
    integ = 0.0
    ign_on_s = 0.0
    ign_need_s = float(boiler["w_el_Wh"]) * bg["igniter_energy_frac"] * 3.6 / bg["igniter_W"] * 1000
    m_bed = 0.0
    ignited = False
    ign_timer = 0.0
    since_ign = 0.0
    burning_out = False
    z = 0.0
    n_starts = 0
    ign_delay = bg["ignite_bg_s"] + ep.get("dead_time_s", 0.0)

    # sensors
    s_ctrl = s_in = s_out = s_boil = t_init
    s_fg = t_init
    s_o2, s_co2, s_co = 20.95, 0.04, 0.0

    # ledger [kJ]
    led = dict.fromkeys(
        ("fuel", "igniter", "water", "amb", "fg_sens", "fg_lat", "fg_co", "ash_char"), 0.0
    )
    fed = 0.0
    keys = (
        "t",
        "flow",
        "flow_sp",
        "t_in",
        "t_out",
        "t_boil",
        "t_fg",
        "o2",
        "co2",
        "co",
        "vel",
        "hopper",
        "room",
        "pel",
        "on",
        "phase",
        "seq",
        "q_water",
        "q_fuel",
        "tw_true",
        "tout_true",
        "tfg_true",
        "fed",
        "tin_true",
    )
    tr: dict[str, list] = {k: [] for k in keys}

    phase = "preheat"
    seq_name = "preheat"
    t = 0.0
    t_phase = 0.0
    marks: dict[str, float] = {}
    hold = 0.0
    tfg_t0 = 0.0
    fg_buf: list[float] = []
    a = lambda tau: 1.0 - math.exp(-DT / tau)  # noqa: E731
    a_flow, a_ret, a_ctrl = a(bg["flow_tau_s"]), a(bg["ret_tau_s"]), a(bg["ctrl_sensor_tau_s"])
    a_in, a_out, a_boil = a(bg["t_in_tau_s"]), a(bg["t_out_tau_s"]), a(bg["t_boiler_tau_s"])
    a_fgs, a_fgb, a_o2 = a(bg["t_fg_tau_s"]), a(bg["fg_tau_bg_s"]), a(bg["o2_tau_s"])
    a_rp = a(bg["ret_pipe_tau_s"])
    a_z = DT / bg["burn_fluct_tau_s"]
    z_sd = bg["burn_fluct_sigma"] * math.sqrt(2 * a_z)
    kp = (p_max - p_min) / bg["ctrl_band_K"]
    k = 0
    while True:
        k += 1
        t_h = t / 3600.0
        room = bg["room_base_C"] + bg["room_amp_K"] * math.sin(
            2 * math.pi * t / bg["room_period_s"] + bg["room_phase"]
        )
        # ---- bench schedule ---------------------------------------------------------------
        if phase == "preheat":
            load, ret_sp, enabled = float(pre["load_pct"]), float(pre["temperature_C"]), False
        elif phase == "start_up":
            load, ret_sp, enabled = seqs[0][1], float(su["return_setpoint_C"]), True
        elif phase == "test":
            tt = t_phase
            for name, la, lb, dur in seqs:
                if tt < dur or name == seqs[-1][0]:
                    load = la + (lb - la) * min(1.0, tt / dur)
                    seq_name = name
                    break
                tt -= dur
            ret_sp, enabled = float(proto["test_sequence"]["return_setpoint_C"]), True
        elif phase == "cooling_1":
            load, ret_sp, enabled = float(c1["load_pct"]), float(c1["return_setpoint_C"]), False
        else:
            load, ret_sp, enabled = 0.0, float(c1["return_setpoint_C"]), False
        flow_sp = m_nom * load / 100.0
        flow += (flow_sp * (1 + bg["flow_bias"]) - flow) * (a_flow if flow_sp > 0 else a(4.0))
        ms = flow / 3600.0  # kg/s
        # ---- return conditioning ----------------------------------------------------------
        if ms > 1e-3:
            osc = bg["ret_osc_K"] * math.sin(
                2 * math.pi * t / bg["ret_osc_period_s"] + bg["ret_osc_phase"]
            )
            lo = t_pipe - bg["ret_cool_max_kW"] / (ms * CP_W)
            hi = t_pipe + bg["ret_heat_max_kW"] / (ms * CP_W)
            tgt = ret_sp + osc - bg["t_in_offset_K"] - bg["t_in_drift_K_h"] * t_h  # on its sensor
            t_ret += (min(max(tgt, lo), hi) - t_ret) * a_ret
        else:
            t_ret += (room - t_ret) * a_rp
        # ---- controller -------------------------------------------------------------------
        t_state += DT
        t_off += DT
        fan = 0.0
        ign = False
        if not enabled and 1 <= state <= 5:
            state, t_state = 6, 0.0
        if state == 0:
            p_cmd = 0.0
            if enabled and s_ctrl < bg["ctrl_restart_C"] and t_off >= bg["ctrl_min_off_s"]:
                state, t_state, t_since_start, ign_on_s = 1, 0.0, 0.0, 0.0
                n_starts += 1
        if 1 <= state <= 5:
            t_since_start += DT
            ign = ign_on_s < ign_need_s and state >= 2
        if state == 1:
            fan = va_purge
            if t_state >= bg["start_purge_s"]:
                state, t_state = 2, 0.0
        if state == 2:
            fan = 0.5 * va_purge
            p_cmd = p_start * bg["start_charge_frac"] if t_state < bg["start_charge_s"] else 0.0
            if t_state >= bg["start_ignite_wait_s"]:
                state, t_state = 3, 0.0
        if state == 3:
            f0 = bg["start_ramp0_frac"]
            p_cmd = p_start * (f0 + (1 - f0) * min(1.0, t_state / bg["start_ramp_s"]))
            if t_state >= bg["start_ramp_s"]:
                state, t_state = 4, 0.0
        err = bg["ctrl_setpoint_C"] - s_ctrl
        if state == 4:
            p_cmd = p_start
            if t_since_start >= bg["start_total_s"] or err <= bg["ctrl_handover_K"]:
                state, t_state = 5, 0.0
                integ = min(p_cmd, p_max) - kp * err
        if state == 5:
            u_raw = kp * err + integ
            u_sat = min(max(u_raw, p_min), p_max)
            if not ((u_raw > p_max and err > 0) or (u_raw < p_min and err < 0)):
                integ += kp * err * DT / bg["ctrl_reset_s"]
            slew = bg["ctrl_slew_frac_min"] * p_max * DT / 60.0
            p_cmd += min(max(u_sat - p_cmd, -slew), slew)
            if s_ctrl >= bg["ctrl_shutoff_C"]:
                state, t_state = 6, 0.0
        if state == 6:
            p_cmd = 0.0
            fan = va_purge
            if t_state >= bg["post_vent_s"] and m_bed < 2e-3:
                state, t_state, t_off = 0, 0.0, 0.0
        on = 1.0 if 1 <= state <= 5 else 0.0
        if ign:
            ign_on_s += DT
        # ---- auger and bed ----------------------------------------------------------------
        cap = 1.25 * p_max
        duty = min(1.0, p_cmd / cap)
        ph = (t % bg["auger_period_s"]) / bg["auger_period_s"]
        feed = (cap / lhv_ar_nom * bg["auger_factor"]) if ph < duty else 0.0  # kg/s ar
        if p_cmd > 0 and state >= 3:
            md_cmd = p_cmd / lhv_ar_nom * (1 - w_nom) * 3600.0
            fan = max(lam_law(md_cmd) * air_min * md_cmd / 3600.0, va_min)
        m_bed += feed * DT
        fed += feed * DT
        led["fuel"] += feed * (1 - w) * hhv * DT
        z += -z * a_z + z_sd * noise[k]
        if not ignited and m_bed > 1e-4 and (ign or state == 3 or state == 4 or state == 5):
            ign_timer += DT
            if ign_timer >= ign_delay:
                ignited, since_ign, burning_out = True, 0.0, False
        if ignited:
            since_ign += DT
            tau_b = bg["bed_tau_s"]
            if state >= 6 or state == 0:
                burning_out = True
            if form == "slow_ignition_front":
                ramp = min(1.0, since_ign / ep["ramp_s"])
                if burning_out:
                    tau_b += ep["burnout_tau_s"]
            else:
                ramp = 1.0
            r = m_bed * ramp * (1 + z) / tau_b
            r = min(r, fan / (1.05 * air_min) / (1 - w)) if fan > 0 else 0.0
            r = min(max(r, 0.0), m_bed / DT)
            if m_bed < 1e-4 and (state == 0 or state == 6):
                ignited, ign_timer = False, 0.0
        else:
            r = 0.0
        m_bed -= r * DT
        b = r * (1 - w)  # kg/s dry burnt
        # ---- gas --------------------------------------------------------------------------
        vo2 = max(0.21 * fan - o2_dem * b, 0.0)
        vn2 = 0.79 * fan + 0.8 * n_f * b
        vc = v_co2 * b
        vdry = vo2 + vn2 + vc
        if vdry > 1e-9:
            o2 = 100 * vo2 / vdry
            co2 = 100 * vc / vdry
            lam_act = fan / (air_min * b) if b > 0 else 99.0
            co = bg["co_base_ppm"] * (1 + 3 * max(0.0, 1 - b * 3600 / md_max) ** 2)
            if lam_act > 6 and b > 0:
                co += 1500.0
            if lam_act < 1.15:
                co += 6000.0
        else:
            o2, co2, co = 20.95, 0.04, 0.0
        co *= float(b > 0)
        q_rel = b * hhv
        # the gas leaves the exchanger between the return and the water in the boiler
        t_ref = tw + 0.5 * (t_ret - tw) * min(1.0, ms / 0.005)
        p_rel = q_rel / q_ref
        dtn = (
            float(boiler["dt_nom_K"]) * bg["hx_dt_scale"]
            - 0.5 * spread
            + float(boiler["dt_hx_wat_K"]) * (1 - flow / m_nom)
        )
        tfg_eq = t_ref + dtn * (min(p_rel, 1.5) ** bg["hx_load_exponent"] if p_rel > 1e-3 else 0)
        fg_lags[0] += (tfg_eq - fg_lags[0]) * a_fgb
        if form == "refractory_first_order":
            fg_lags[1] += (fg_lags[0] - fg_lags[1]) * a(tau_fg_eff)
            tfg = fg_lags[1]
        elif form == "exchanger_second_order_flow":
            mfg = (fan * 1.293 + b) / mfg_nom
            tau2 = 0.5 * tau_fg_eff * min(max(mfg, 1e-6) ** -0.5, 3.0)
            fg_lags[1] += (fg_lags[0] - fg_lags[1]) * a(tau2)
            fg_lags[2] += (fg_lags[1] - fg_lags[2]) * a(tau2)
            tfg = fg_lags[2]
        else:
            tfg = fg_lags[0]
        m_dry = vo2 * 1.429 + vn2 * 1.251 + vc * 1.977
        m_h2o = h2o_kg * b
        q_sens = (m_dry * (1.0 + 1e-4 * tfg) + m_h2o * CP_VAP) * (tfg - room)
        q_lat = m_h2o * DH_VAP
        q_co = co * 1e-6 * vdry * 1.25 * DH_CO
        q_ash = 0.0002 * q_rel + b * char * HHV_C
        q_ign = bg["igniter_W"] / 1000.0 if ign else 0.0
        q_hx = q_rel + q_ign - q_sens - q_lat - q_co - q_ash
        # ---- body and water ---------------------------------------------------------------
        ua = ua_on if ignited else ua_off
        q_w_tot = q_amb_tot = 0.0
        for _ in range(n_sub):
            q_w = ms * CP_W * (tw - t_ret)
            q_amb = ua * (tw - room)
            if len(caps) == 1:
                f0 = gs[0] * (tm[0] - tw)
                tm[0] += (q_hx - f0) * h_sub / caps[0]
                into_w = f0
            elif form == "layered_wall":
                f = [gs[i] * (tm[i] - (tm[i + 1] if i + 1 < len(tm) else tw)) for i in range(3)]
                tm[0] += (q_hx - f[0]) * h_sub / caps[0]
                tm[1] += (f[0] - f[1]) * h_sub / caps[1]
                tm[2] += (f[1] - f[2]) * h_sub / caps[2]
                into_w = f[2]
            else:
                f0 = gs[0] * (tm[0] - tw)
                f1 = gs[1] * (tm[1] - tw)
                tm[0] += ((1 - rad) * q_hx - f0) * h_sub / caps[0]
                tm[1] += (rad * q_hx - f1) * h_sub / caps[1]
                into_w = f0 + f1
            tw += (into_w - q_w - q_amb) * h_sub / c_water
            q_w_tot += q_w
            q_amb_tot += q_amb
        q_w_mean = q_w_tot / n_sub
        led["water"] += q_w_tot * h_sub
        led["amb"] += q_amb_tot * h_sub
        led["igniter"] += q_ign * DT
        led["fg_sens"] += q_sens * DT
        led["fg_lat"] += q_lat * DT
        led["fg_co"] += q_co * DT
        led["ash_char"] += q_ash * DT
        # ---- exit pipe --------------------------------------------------------------------
        if form == "plug_flow_pipe":
            cum_v += ms / RHO_W * DT
            hist_v.append(cum_v)
            hist_t.append(t)
            hist_tw.append(tw)
            j = bisect.bisect_left(hist_v, cum_v - pipe_v)
            if j >= len(hist_v):
                j = len(hist_v) - 1
            t_src, age = (hist_tw[j], t - hist_t[j]) if cum_v >= pipe_v else (t_init, t)
            t_eqs = room + ep["stagnant_coupling"] * (tw - room)
            t_pipe = t_eqs + (t_src - t_eqs) * math.exp(-age / ep["tau_loss_s"])
        elif form == "mixed_well_volume":
            mc = ms * CP_W + ep["g_boiler_W_K"] / 1000.0
            ua_p = ep["ua_W_K"] / 1000.0
            eq = (mc * tw + ua_p * room) / (mc + ua_p)
            t_pipe = eq + (t_pipe - eq) * math.exp(-(mc + ua_p) * DT / (pipe_v * RHO_W * CP_W))
        else:
            t_pipe = tw
        # ---- sensors ----------------------------------------------------------------------
        s_ctrl += (tw + bg["ctrl_sensor_offset_K"] - s_ctrl) * a_ctrl
        s_in += (t_ret - s_in) * a_in
        s_out += (t_pipe - s_out) * a_out
        s_boil += (tw - s_boil) * a_boil
        s_fg += (tfg - s_fg) * a_fgs
        s_o2 += (o2 - s_o2) * a_o2
        s_co2 += (co2 - s_co2) * a_o2
        s_co += (co - s_co) * a_o2
        m_in = s_in + bg["t_in_offset_K"] + bg["t_in_drift_K_h"] * t_h
        m_out = s_out + bg["t_out_offset_K"] + bg["t_out_drift_K_h"] * t_h
        m_fg = s_fg + bg["t_fg_offset_K"]
        vel = (vdry + 1.244 * m_h2o / 1.0) * (tfg + 273.15) / 273.15 / a_flue
        vel *= 1013.25 / bg["pressure_hPa"]
        pel = float(boiler["p_el_off_W"]) * bg["el_scale"]
        if 1 <= state <= 6:
            frac = min(max((p_cmd - p_min) / (p_max - p_min), 0.0), 1.0)
            pel = float(boiler["p_el_min_W"]) + frac * (
                float(boiler["p_el_max_W"]) - float(boiler["p_el_min_W"])
            )
            if p_cmd == 0.0:
                pel *= 0.8
            pel *= bg["el_scale"]
            pel += 8.0 * (feed > 0) + (bg["igniter_W"] if ign else 0.0)
        # ---- record -----------------------------------------------------------------------
        for key, val in (
            ("t", t),
            ("flow", flow),
            ("flow_sp", flow_sp),
            ("t_in", m_in),
            ("t_out", m_out),
            ("t_boil", s_boil + bg["t_boiler_offset_K"] + bg["t_boiler_drift_K_h"] * t_h),
            ("t_fg", m_fg),
            ("o2", s_o2),
            ("co2", s_co2),
            ("co", s_co),
            ("vel", vel),
            ("hopper", bg["hopper_kg"] - fed),
            ("room", room),
            ("pel", pel),
            ("on", on),
            ("phase", phase),
            ("seq", seq_name),
            ("q_water", q_w_mean),
            ("q_fuel", q_rel),
            ("tw_true", tw),
            ("tout_true", t_pipe),
            ("tfg_true", tfg),
            ("fed", fed),
            ("tin_true", t_ret),
        ):
            tr[key].append(val)
        fg_buf.append(m_fg)
        # ---- phase transitions (on what the bench measures) -------------------------------
        t += DT
        t_phase += DT
        nxt = None
        if phase == "preheat":
            tol, tgt = float(pre["tolerance_K"]), float(pre["temperature_C"])
            hold = hold + DT if abs(m_out - tgt) <= tol and abs(m_in - tgt) <= tol else 0.0
            if hold >= float(pre["hold_s"]) or t_phase >= float(pre["max_duration_s"]):
                nxt, marks["t0_s"], tfg_t0 = "start_up", t, m_fg
        elif phase == "start_up":
            rise = (
                (m_fg - fg_buf[-win_n - 1]) / (su["t1_window_s"] / 60.0)
                if len(fg_buf) > win_n
                else 1e9
            )
            if (
                t_phase >= su["min_duration_s"]
                and rise < su["t1_max_rise_K_min"]
                and m_fg - tfg_t0 > 20.0
            ) or t_phase >= su["max_duration_s"]:
                nxt, marks["t1_s"] = "test", t
        elif phase == "test":
            if t_phase >= test_dur:
                nxt, marks["t2_s"] = "cooling_1", t
        elif phase == "cooling_1":
            if m_out <= float(c1["until_forward_C"]) or t_phase >= float(c1["max_duration_s"]):
                nxt, marks["t3_s"] = "cooling_2", t
        elif t - marks["t2_s"] >= float(c2["until_after_t2_s"]):
            marks["t4_s"] = t
            break
        if nxt is not None:
            phase, t_phase, seq_name = nxt, 0.0, nxt
        if k >= n_max - 2:
            raise RuntimeError("reality10: protocol did not finish")
    e_store = sum(c * x for c, x in zip(caps, tm, strict=True)) + c_water * tw - e_store0
    e_bed = m_bed * (1 - w) * hhv
    ledger = dict(led, storage=e_store, bed=e_bed)
    meta = {
        "marks": marks,
        "ledger_kJ": ledger,
        "fuel_fed_kg": fed,
        "hopper_start_kg": bg["hopper_kg"],
        "n_starts": n_starts,
        "effect_params": ep,
        "fuel_moisture": w,
        "lhv_ar_nominal_kJ_kg": lhv_ar_nom,
        "nominal_flow_kg_h": m_nom,
        "internal_step_s": DT,
    }
    return {"traces": tr, "meta": meta, "noise_rng": rng}
