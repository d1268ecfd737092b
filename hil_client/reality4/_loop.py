"""Time loop of the reality4 plant (1 s explicit steps, numba)."""

from __future__ import annotations

import numpy as np
from numba import njit

CP_W = 4.186  # kJ/(kg K)

# order of the parameter tuple handed to ``run`` (keep in step with the unpack below)
PNAMES = [
    "p_nom",
    "p_max",
    "p_min",
    "p_start",
    "hhv",
    "lhv_bel",
    "w",
    "ash_ar",
    "air_min",
    "v_co2",
    "v_h2o",
    "v_n2",
    "v_so2",
    "lam_a",
    "lam_b",
    "c_w",
    "c_s",
    "ua_sw",
    "ua_on",
    "ua_off",
    "c_ci",
    "ua_ci",
    "ci_frac",
    "c_fg",
    "n_fg",
    "dthx",
    "eff_off",
    "tau_fg_bg",
    "fg_mode",
    "fg_a",
    "fg_tau",
    "tau_burn",
    "burn_sig",
    "burn_tau",
    "pulse_kg",
    "auger_over",
    "t_light",
    "retort_tau",
    "retort_g0",
    "burnout_fac",
    "ign_kg",
    "ign_feed_s",
    "p_ign",
    "ign_on_s",
    "ign_heat",
    "prepurge_s",
    "ramp_s",
    "hold_s",
    "post_s",
    "t_set",
    "kp",
    "ti",
    "q_step",
    "t_stop",
    "t_restart",
    "co0",
    "co_frac",
    "pipe_mode",
    "pipe_ua",
    "pipe_c",
    "clamp_beta",
    "clamp_tau",
    "riser_kg",
    "riser_g",
    "tau_flow",
    "flow_gain",
    "tau_valve",
    "valve_sig",
    "tau_stag",
    "room0",
    "room_amp",
    "room_ph",
    "p_amb0",
    "rh0",
    "m_bal0",
    "area",
    "tau_s_in",
    "tau_s_out",
    "tau_s_bw",
    "tau_s_fg",
    "o2_delay",
    "tau_o2",
    "n_pre",
    "test_total",
    "t_w0",
    "p_el_min",
    "p_el_max",
    "p_el_off",
]

N_OUT = 27


@njit(cache=True)
def run(p, seq_end, seq_l0, seq_l1, z, n_max):
    (
        p_nom,
        p_max,
        p_min,
        p_start,
        hhv,
        lhv_bel,
        w,
        ash_ar,
        air_min,
        v_co2,
        v_h2o,
        v_n2,
        v_so2,
        lam_a,
        lam_b,
        c_w,
        c_s,
        ua_sw,
        ua_on,
        ua_off,
        c_ci,
        ua_ci,
        ci_frac,
        c_fg,
        n_fg,
        dthx,
        eff_off,
        tau_fg_bg,
        fg_mode,
        fg_a,
        fg_tau,
        tau_burn,
        burn_sig,
        burn_tau,
        pulse_kg,
        auger_over,
        t_light,
        retort_tau,
        retort_g0,
        burnout_fac,
        ign_kg,
        ign_feed_s,
        p_ign,
        ign_on_s,
        ign_heat,
        prepurge_s,
        ramp_s,
        hold_s,
        post_s,
        t_set,
        kp,
        ti,
        q_step,
        t_stop,
        t_restart,
        co0,
        co_frac,
        pipe_mode,
        pipe_ua,
        pipe_c,
        clamp_beta,
        clamp_tau,
        riser_kg,
        riser_g,
        tau_flow,
        flow_gain,
        tau_valve,
        valve_sig,
        tau_stag,
        room0,
        room_amp,
        room_ph,
        p_amb0,
        rh0,
        m_bal0,
        area,
        tau_s_in,
        tau_s_out,
        tau_s_bw,
        tau_s_fg,
        o2_delay,
        tau_o2,
        n_pre,
        test_total,
        t_w0,
        p_el_min,
        p_el_max,
        p_el_off,
    ) = p
    out = np.full((N_OUT, n_max), np.nan)
    en = np.zeros(12)  # energy/mass accounting
    marks = np.full(5, -1.0)
    m_nom = p_nom / (CP_W * 15.0)
    # states
    t_w = t_w0
    t_s = t_w0
    t_ci = t_w0
    t_in = t_w0
    t_pipe = t_w0
    t_clamp = t_w0
    t_riser = t_w0
    x_fg = -(1 - eff_off) * (t_w0 - room0)
    x_fast = x_fg
    x_wall = x_fg
    flow = 0.0
    m_bed = 0.0
    lit = False
    burn_ou = 0.0
    valve_ou = 0.0
    room_ou = 0.0
    pr_ou = 0.0
    rh_ou = 0.0
    acc = 0.0
    fed = 0.0
    burnt = 0.0
    mode = 0
    t_mode = 0.0
    t_ign_start = -1e9
    t_lit = -1e9
    integ = 0.0
    p_cmd = 0.0
    enable = False
    phase = 0
    seq = -1
    retort = 1.0
    s_in = t_w0
    s_out = t_w0
    s_bw = t_w0
    s_fg = t_w0
    s_o2 = 20.9
    s_co2 = 0.04
    t0 = -1
    t1 = -1
    t2 = -1
    t3 = -1
    n = n_max
    e_store0 = c_w * t_w + c_s * t_s + c_ci * t_ci
    first_start = True
    for i in range(n_max):
        tt = float(i)
        # ---------------- phase / schedule
        load = 1.0
        ret_sp = 55.0
        if phase == 0:
            ret_sp = 45.0
            if i >= n_pre:
                phase = 1
                t0 = i
                enable = True
        # t1: flue-gas rise below 0.5 K/min over 5 min, well after the flame appeared
        rise_ok = i - t0 >= 300 and s_fg - out[18, max(i - 300, 0)] < 2.5
        if phase == 1 and mode >= 3 and tt - t_lit > 600.0 and rise_ok:
            phase = 2
            t1 = i
        if phase == 2:
            k = tt - t1
            if k >= test_total:
                phase = 3
                t2 = i
                enable = False
            else:
                seq = 0
                while seq < len(seq_end) - 1 and k >= seq_end[seq]:
                    seq += 1
                s0 = 0.0 if seq == 0 else seq_end[seq - 1]
                fr = (k - s0) / (seq_end[seq] - s0)
                load = seq_l0[seq] + (seq_l1[seq] - seq_l0[seq]) * fr
        if phase == 3:
            load = 0.2
            seq = -1
            if (i - t2 > 60 and s_out <= 55.0) or i - t2 >= 10800:
                phase = 4
                t3 = i
        if phase == 4:
            load = 0.0
            if i - t2 >= 28800:
                n = i
                break
        # ---------------- room and ambient
        room_ou += -room_ou / 1800.0 + 0.006 * z[3, i]
        t_room = room0 + room_amp * np.sin(2 * np.pi * (tt / 86400.0 + room_ph)) + room_ou
        pr_ou += -pr_ou / 7200.0 + 0.01 * z[16, i]
        rh_ou += -rh_ou / 3600.0 + 0.05 * z[17, i]
        # ---------------- bench: flow and return
        fsp = load * m_nom
        if fsp <= 0.0:
            flow = 0.0
        else:
            flow += (fsp * flow_gain - flow) / tau_flow
        valve_ou += -valve_ou / 240.0 + valve_sig * 0.09 * z[2, i]
        tgt = ret_sp if phase == 0 else min(ret_sp, t_w - 0.4)
        if flow > 0.0:
            t_in += (tgt + valve_ou - t_in) / tau_valve
        else:
            t_in += (t_room - t_in) / tau_stag
        # ---------------- burner controller
        t_ctrl = t_w
        t_mode += 1.0
        if mode == 0:
            p_cmd = 0.0
            if enable and (first_start or t_ctrl < t_restart):
                first_start = False
                mode = 1
                t_mode = 0.0
        elif mode == 1:
            if t_mode >= prepurge_s:
                mode = 2
                t_mode = 0.0
                t_ign_start = tt
        elif mode == 2:
            if lit and tt - t_lit >= 30.0:
                mode = 3
                t_mode = 0.0
            elif t_mode > 1800.0:
                mode = 5
                t_mode = 0.0
        elif mode == 3:
            p_cmd = p_min + (p_start - p_min) * min(1.0, t_mode / ramp_s)
            if t_mode >= ramp_s + hold_s or t_ctrl > t_set - 1.0:
                mode = 4
                t_mode = 0.0
                integ = p_cmd - kp * (t_set - t_ctrl)
        elif mode == 4:
            e = t_set - t_ctrl
            integ += kp * e / ti
            integ = min(max(integ, p_min - kp * e), p_max - kp * e)
            p_raw = min(max(kp * e + integ, p_min), p_max)
            p_cmd = round(p_raw / q_step) * q_step
            p_cmd = min(max(p_cmd, p_min), p_max)
        elif mode == 5:
            p_cmd = 0.0
            if t_mode >= post_s:
                mode = 0
                t_mode = 0.0
        if (mode in (3, 4) and t_ctrl > t_stop) or (mode in (2, 3, 4) and not enable):
            mode = 5
            t_mode = 0.0
            p_cmd = 0.0
        # ---------------- auger and bed
        m_cmd = 0.0  # believed kg/s as received
        if mode == 2 and t_mode <= ign_feed_s:
            m_cmd = ign_kg / ign_feed_s
        elif mode in (3, 4):
            m_cmd = p_cmd / lhv_bel
        acc += m_cmd
        if acc >= pulse_kg:
            dm = pulse_kg * (1.0 + auger_over) * (1.0 + 0.04 * z[14, i])
            acc -= pulse_kg
            m_bed += dm
            fed += dm
        if not lit and m_bed > 0.0 and mode == 2 and tt - t_ign_start >= t_light:
            lit = True
            t_lit = tt
            retort = retort_g0 if retort_tau > 0 else 1.0
        if retort_tau > 0:
            retort += (1.0 - retort) / retort_tau if lit else 0.0
        burn_ou += -burn_ou / burn_tau + burn_sig * np.sqrt(2.0 / burn_tau) * z[0, i]
        burn = 0.0
        if lit:
            tb = tau_burn if mode in (3, 4) else tau_burn * burnout_fac
            burn = m_bed / tb * retort * max(0.3, 1.0 + burn_ou)
            burn = min(burn, m_bed)
            m_bed -= burn
            burnt += burn
            if m_bed < 1e-4 and mode not in (2, 3, 4):
                burnt += m_bed
                burn += m_bed
                m_bed = 0.0
                lit = False
        b_dry = burn * (1.0 - w)
        qb = b_dry * hhv
        # ---------------- air and flue gas
        m_dry_h = m_cmd * (1.0 - w) * 3600.0
        va = 0.0
        if mode in (3, 4):
            lam = min(max(lam_a + lam_b * m_dry_h, 1.4), 6.0)
            va = lam * air_min * m_cmd * (1.0 - w)
        if mode in (1, 2, 5) or (mode in (3, 4) and va < 0.0):
            va = 2.2 * air_min * p_min / lhv_bel * (1.0 - w)
        if mode == 0:
            va = 0.03 * air_min * p_nom / lhv_bel
        va = max(va, 1.05 * air_min * b_dry)
        v_o2 = 0.21 * va - 0.21 * air_min * b_dry
        v_c = v_co2 * b_dry + 0.0004 * va
        v_n = 0.79 * va + v_n2 * b_dry
        v_dry = v_o2 + v_c + v_n + v_so2 * b_dry
        v_wat = v_h2o * b_dry + 0.012 * va
        m_dry = 1.429 * v_o2 + 1.977 * v_c + 1.251 * v_n
        m_vap = 0.804 * v_wat
        fp = qb / p_nom
        x_ss = -(1.0 - eff_off) * (t_w - t_room) * np.exp(-fp / 0.05)
        if fp > 0.02:
            x_ss += c_fg * fp**n_fg + dthx * (1.0 - flow / m_nom)
        if fg_mode == 1.0:  # soot-fouled exchanger: part of the excess via a slow wall
            x_fast += (x_ss - x_fast) / tau_fg_bg
            x_wall += (x_ss - x_wall) / fg_tau
            x_fg = (1.0 - fg_a) * x_fast + fg_a * x_wall
        elif fg_mode == 2.0:  # ceramic afterburner: lag grows as the gas flow falls
            m_ref = 1.05 * air_min * 2.5 * p_nom / lhv_bel
            tau_c = fg_tau * min(4.0, (m_ref / max(va, 0.05 * m_ref)) ** 0.8)
            x_fg += (x_ss - x_fg) / tau_c
        else:
            x_fg += (x_ss - x_fg) / tau_fg_bg
        t_fg = t_w + x_fg
        # combustion CO (dry ppm) and losses
        co = 0.0
        if b_dry > 0.0:
            co = co0 * (1.0 + 2.0 * max(0.0, 0.5 - fp) / 0.5)
            if mode not in (3, 4):
                co += 1500.0
            co += 6000.0 * (1.0 - retort)
            co *= max(0.2, 1.0 + 0.5 * burn_ou)
            co += co_frac * qb / (10100.0 * 1.25 * max(v_dry, 1e-9)) * 1e6
        q_chem = co * 1e-6 * v_dry * 1.25 * 10100.0
        q_sens = (m_dry * 1.05 + m_vap * 1.9) * (t_fg - t_room)
        q_lat = 0.804 * v_h2o * b_dry * 2442.0
        q_ash = 0.0002 * qb
        ign_on = (mode == 2) or (tt - t_ign_start < ign_on_s and mode in (2, 3))
        q_ign = p_ign * ign_heat if ign_on else 0.0
        q_hx = qb + q_ign - q_sens - q_lat - q_chem - q_ash
        # ---------------- thermal body
        burning = mode in (2, 3, 4) or lit
        ua = ua_on if burning else ua_off
        q_sw = ua_sw * (t_s - t_w)
        q_ciw = ua_ci * (t_ci - t_w)
        q_loss = ua * (t_w - t_room)
        q_water = flow * CP_W * (t_w - t_in)
        t_s += ((1.0 - ci_frac) * q_hx - q_sw) / c_s
        t_ci += (ci_frac * q_hx - q_ciw) / c_ci
        t_w += (q_sw + q_ciw - q_loss - q_water) / c_w
        en[0] += qb
        en[1] += q_ign
        en[2] += q_water
        en[3] += q_loss
        en[4] += q_sens + q_lat + q_chem + q_ash
        # ---------------- forward pipe
        if pipe_mode == 1.0:  # clamp-on sensor on an uninsulated pipe
            q_in = flow * CP_W * (t_w - t_pipe) + 0.0015 * (t_w - t_pipe)  # + natural conv.
            t_pipe += (q_in - pipe_ua * (t_pipe - t_room)) / pipe_c
            if flow > 1e-6:
                beta = min(0.2, clamp_beta * (m_nom / flow) ** 0.8)
                tauc = clamp_tau * min(6.0, (m_nom / flow) ** 0.5)
            else:
                beta = min(0.2, 2.0 * clamp_beta)
                tauc = 6.0 * clamp_tau
            t_clamp += (t_pipe - beta * (t_pipe - t_room) - t_clamp) / tauc
            t_fwd = t_clamp
        elif pipe_mode == 2.0:  # long riser: transport delay, thermosiphon at zero flow
            if flow > 1e-6:
                d = int(min(1800.0, riser_kg / flow))
                j = max(0, i - d)
                src = out[0, j] if j < i else t_w
                att = np.exp(-pipe_ua / (flow * CP_W))
                t_riser += (t_room + (src - t_room) * att - t_riser) / 3.0
            else:
                c_r = riser_kg * CP_W + 1.5
                t_riser += (riser_g * (t_w - t_riser) - pipe_ua * (t_riser - t_room)) / c_r
            t_fwd = t_riser
        else:
            t_fwd = t_w - 0.02 * (t_w - t_room) * (1.0 if flow < 1e-6 else 0.1)
        # ---------------- sensors (states, no noise here)
        s_in += (t_in - s_in) / tau_s_in
        s_out += (t_fwd - s_out) / tau_s_out
        s_bw += (t_w - s_bw) / tau_s_bw
        s_fg += (t_fg - s_fg) / tau_s_fg
        o2_true = 100.0 * v_o2 / v_dry
        co2_true = 100.0 * v_c / v_dry
        out[5, i] = o2_true
        out[6, i] = co2_true
        jd = int(max(0, i - o2_delay))
        s_o2 += (out[5, jd] - s_o2) / tau_o2
        s_co2 += (out[6, jd] - s_co2) / tau_o2
        # ---------------- store
        out[0, i] = t_w
        out[1, i] = t_in
        out[2, i] = t_fwd
        out[3, i] = flow
        out[4, i] = t_fg
        out[7, i] = co
        v_wet = (v_dry + v_wat) * (t_fg + 273.15) / 273.15 * 1013.25 / (p_amb0 + pr_ou)
        out[8, i] = v_wet / area
        out[9, i] = m_bal0 - fed * (1.0 - ash_ar)
        out[10, i] = t_room
        pel = p_el_off
        if mode in (3, 4):
            pel = p_el_min + (p_el_max - p_el_min) * max(0.0, (p_cmd / p_nom - 0.3) / 0.7)
        elif mode in (1, 2, 5):
            pel = p_el_min
        if ign_on:
            pel += p_ign * 1000.0
        out[11, i] = pel
        out[12, i] = fsp
        out[13, i] = 1.0 if mode in (2, 3, 4) else 0.0
        out[14, i] = phase
        out[15, i] = seq
        out[16, i] = qb
        out[17, i] = q_water
        out[18, i] = s_fg
        out[19, i] = s_out
        out[20, i] = s_bw
        out[21, i] = s_in
        out[22, i] = s_o2
        out[23, i] = s_co2
        out[24, i] = t_s
        out[25, i] = p_amb0 + pr_ou
        out[26, i] = rh0 + rh_ou
    marks[0] = t0
    marks[1] = t1
    marks[2] = t2
    marks[3] = t3
    marks[4] = n
    en[5] = c_w * t_w + c_s * t_s + c_ci * t_ci - e_store0
    en[6] = fed
    en[7] = burnt
    en[8] = m_bed
    return out[:, :n], en, marks
