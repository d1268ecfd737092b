"""The per-second loop of the reality7 plant (numba).

Physics, per 0.5 s sub-step (paper Section 2.1):

* fuel bed: the auger adds as-received pellets in pulses; the lit bed burns with a time
  constant and a fluctuation, limited by the air the fan gives; Q_rel = m_dry * HHV (Eq. 3);
* gas side: Q_ash, Q_fg,lat, Q_fg,chem leave first (Eq. 4-6); what remains heats the gas to an
  adiabatic temperature; the exchanger is a counter-flow NTU law, NTU ~ W^-n, reduced by
  fouling (own law, instead of the delta-T approach of Eq. 8); Q_fg,sens follows from the exit
  temperature (Eq. 4) and Q_hx is the rest (Eq. 1);
* body: a steel node around the fire and the jacket water node (Eq. 2, 7, 10); the cladding
  loses UA_env (T_w - T_room) always, the idle draught air through the hot body is what makes
  UAamb,OFF larger than UAamb,ON (paper Eq. 14-16): it runs through the same exchanger law;
* exit pipe (4 water segments, backward Euler, to the forward sensor), the bench loop with
  its cooler/heater and PI valve, and the return pipe;
* instruments: first-order lags; the gas analyser has a transport delay.

Energy bookkeeping: every flux that crosses the boiler+pipe boundary is summed into E_in; the
stored energy U is the sum of C*T over all nodes. U - U0 - E_in = 0 up to rounding.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from .fuel import DH_CO, DH_VAP, RHO_CO, RHO_CO2, RHO_H2O, RHO_N2, RHO_O2, RHO_SO2

CP_W = 4.19  # kJ/(kg K), water at 45-85 C (assumption)
CP_G = 1.05  # kJ/(kg K), dry flue gas 20-300 C (assumption)
CP_V = 1.90  # kJ/(kg K), water vapour
CP_AIR = 1.005

_FIELDS_TEXT = (
    "c_w c_s ua_sw ua_env v_idle ua_nc m_pipe ua_pipe t_set t_off t_on ctrl_off ctrl_tau "
    "kp ti slew min_off p_min p_max p_start lhv_ctrl w_ctrl lam_a lam_b trim_tau prepurge "
    "ign_kw ign_ref ign_rise charge tau_bed spread ramp start_hold postpurge air_purge "
    "air_ign air_post aug_max bulk_ratio aug_period ign_timeout pel_min pel_max pel_off "
    "hhv fc fh fo fn fs fash fw fan_sigma fan_tau burn_sigma burn_tau co_base md_ref "
    "ntu_ref w_ref ntu_exp fouling0 fouling_per_kg clean_eff cool_max heat_max bench_kp "
    "bench_ti valve_tau c_loop dist flow_tau m_rp ua_loop ua_rp tau_t_in tau_t_out "
    "tau_t_boiler tau_t_fg tau_ch o2_delay o2_tau duct_area p_amb flow_nom pre_t pre_tol "
    "pre_hold pre_load pre_max init_dev su_ret su_window su_rise su_min su_max su_load "
    "test_ret c1_load c1_ret c1_until c1_max c2_after eff form s cap_door door_share "
    "door_tau cap_ring ring_share ring_k pocket_tau pocket_beta cap_valve ua_valve_w "
    "ua_valve_r m_extra ign_fan_factor spread_extra burnout_factor cap_ins ntu_ins k_ins "
    "cap_pl ntu_pl ua_pl_s pause_period pause_s"
)
KP_FIELDS = _FIELDS_TEXT.split()

KParams = namedtuple("KParams", KP_FIELDS)

# output columns of the kernel (per second)
(
    O_PHASE, O_SEQ, O_FLOW, O_FLOW_SP, O_TIN, O_TOUT, O_TB, O_TFG, O_O2, O_CO2, O_CO, O_VEL,
    O_HOPPER, O_PEL, O_ON, O_U, O_EIN, O_FED, O_BURNT, O_ASH, O_BED, O_TW, O_TS, O_TFGT,
    O_QREL, O_QW, O_FEED, O_STATE, O_LAM, O_TROOM, O_PCMD, O_QFG, O_GROSS, O_TOUT_TRUE,
    O_TIN_TRUE, O_FLOW_TRUE, O_MD,
) = range(37)  # fmt: skip
NCOL = 37

# controller states
S_OFF, S_PURGE, S_IGNITE, S_STAB, S_MOD, S_BURNOUT, S_WAIT = range(7)
# effect codes (quirks.EFFECT_CODES)
E_BODY, E_PIPE, E_IGN, E_FLUE, E_FUEL = 1, 2, 3, 4, 5
NSEG = 4
RING = 4096


@njit(cache=True)
def _lag(x: float, target: float, h: float, tau: float) -> float:
    """Exact first-order lag step."""
    if tau <= 0.0:
        return target
    return target + (x - target) * math.exp(-h / tau)


@njit(cache=True)
def _lam_set(kp, md_cmd: float) -> float:
    """The controller's excess-air curve, paper Eq. 9 (with this boiler's own coefficients)."""
    lam = kp.lam_a + kp.lam_b * md_cmd
    return min(max(lam, 1.25), 6.0)


@njit(cache=True)
def run_kernel(kp, seq_dur, seq_l0, seq_l1, noise, t_room_arr, out):
    """Simulate preheat, start-up, test sequence and both coolings; fill ``out`` per second.

    Returns (rows used, t0, t1, t2, t3, t4) in seconds (= row indices).
    """
    n_max = out.shape[0]
    nsub = 2
    h = 0.5
    eff = int(kp.eff) if kp.s > 0.0 else 0  # strength 0: exactly the plant without it
    form = int(kp.form)
    s = kp.s
    # fuel actually fed (the effect fuel_energy_bias is already in these numbers)
    w_d = kp.fw / (1.0 - kp.fw)
    air_min = (1.866 * kp.fc + 5.56 * kp.fh + 0.7 * kp.fs - 0.7 * kp.fo) / 0.21
    vh2o_per_kg = 11.1 * kp.fh + 1.244 * w_d
    # effect switches
    door = eff == E_BODY and form == 0
    ring = eff == E_BODY and form == 1
    pocket = eff == E_PIPE and form == 0
    valve = eff == E_PIPE and form == 1
    fan_ign = eff == E_IGN and form == 0
    smoulder = eff == E_IGN and form == 1
    insert = eff == E_FLUE and form == 0
    plate = eff == E_FLUE and form == 1
    c_d = kp.cap_door * s if door else 0.0
    c_r = kp.cap_ring * s if ring else 0.0
    c_ins = kp.cap_ins * s if insert else 0.0
    c_pl = kp.cap_pl * s if plate else 0.0
    c_v = kp.cap_valve * s if valve else 0.0
    m_seg = (kp.m_pipe + (kp.m_extra * s if (pocket or valve) else 0.0)) / NSEG
    ua_seg = kp.ua_pipe / NSEG
    # --- states ---------------------------------------------------------------------------
    t_room = t_room_arr[0]
    t0v = kp.pre_t + kp.init_dev
    tw = t0v
    ts = t0v
    td = t0v
    tr = t0v
    tins = t0v
    tpl = t0v
    tv = t0v
    tp = np.full(NSEG, t0v)
    f_ax = np.zeros(NSEG)
    trp = kp.pre_t
    tloop = kp.pre_t
    m_flow = kp.flow_nom * kp.pre_load / 100.0  # kg/h
    s_tin = trp
    s_tout = t0v
    s_tb = t0v
    s_ctrl = t0v
    s_tfg = t0v
    s_ch = t0v
    s_flow = m_flow
    s_o2 = 20.95
    s_co2 = 0.04
    s_co = 0.0
    ring_o2 = np.full(RING, 20.95)
    ring_co2 = np.full(RING, 0.04)
    ring_co = np.zeros(RING)
    ring_fg = np.zeros(RING)
    # fuel
    hopper = 0.0  # fed so far is tracked as negative hopper change
    fed = 0.0
    burnt = 0.0
    ash = 0.0
    bed = 0.0
    lit = False
    lf = 0.0
    t_el = t_room
    t_surf = t_room
    prog = 0.0
    fouling = kp.fouling0
    # controller
    st = S_OFF
    st_t = 0.0
    p_cmd = 0.0
    integ = 0.0
    charge_left = 0.0
    ign_t = 0.0
    igniter = False
    ig_after = 0.0
    stop_time = -1e9
    top_ups = 0
    t_ch_ref = 0.0
    trim = 0.0
    xi_burn = 0.0
    xi_fan = 0.0
    xi_dist = 0.0
    q_bench = 0.0
    b_int = 0.0
    request = False
    # schedule
    phase = 0
    hold = 0
    t0 = -1
    t1 = -1
    t2 = -1
    t3 = -1
    t4 = -1
    tfg_at_t0 = 0.0
    n_seq = seq_dur.shape[0]
    total_test = 0
    for i in range(n_seq):
        total_test += seq_dur[i]
    e_in = 0.0
    gross = 0.0
    u0 = 0.0
    lam = 99.0
    md = 0.0
    q_rel = 0.0
    t_fg = t0v
    q_fg = 0.0
    v_air = 0.0
    feed_ar = 0.0
    n_used = n_max
    flow_sp = 0.0
    ret_sp = kp.pre_t
    uvw = 0.0
    o2 = 20.95
    co2 = 0.04
    co = 0.0
    v_dry = 0.0
    v_h2o = 0.0
    a_fan = math.exp(-1.0 / kp.fan_tau)
    a_burn = math.exp(-1.0 / kp.burn_tau)
    a_dist = math.exp(-1.0 / 60.0)
    for k in range(n_max):
        t_room = t_room_arr[k]
        # ===== schedule (paper Section 2.3, Fig. 3; protocol YAML) =========================
        seq_i = -1
        if phase == 0:
            flow_sp = kp.flow_nom * kp.pre_load / 100.0
            ret_sp = kp.pre_t
            if abs(s_tout - kp.pre_t) <= kp.pre_tol and abs(s_tin - kp.pre_t) <= kp.pre_tol:
                hold += 1
            else:
                hold = 0
            if hold >= kp.pre_hold or k >= kp.pre_max:
                phase = 1
                t0 = k
                request = True
                tfg_at_t0 = s_tfg
        if phase == 1:
            flow_sp = kp.flow_nom * kp.su_load / 100.0
            ret_sp = kp.su_ret
            el = k - t0
            w = int(kp.su_window)
            if el >= kp.su_min and el >= w:
                rise = (s_tfg - ring_fg[(k - w) % RING]) / (w / 60.0)
                # the flame must have lifted the flue gas first (operator's reading of t1)
                if rise < kp.su_rise and s_tfg - tfg_at_t0 > 20.0:
                    phase = 2
                    t1 = k
            if phase == 1 and el >= kp.su_max:
                phase = 2
                t1 = k
        if phase == 2:
            el = k - t1
            if el >= total_test:
                phase = 3
                t2 = k
                request = False
            else:
                acc = 0
                load = 0.0
                for i in range(n_seq):
                    if el < acc + seq_dur[i]:
                        seq_i = i
                        frac = (el - acc) / seq_dur[i]
                        load = seq_l0[i] + (seq_l1[i] - seq_l0[i]) * frac
                        break
                    acc += seq_dur[i]
                flow_sp = kp.flow_nom * load / 100.0
                ret_sp = kp.test_ret
        if phase == 3:
            flow_sp = kp.flow_nom * kp.c1_load / 100.0
            ret_sp = kp.c1_ret
            if s_tout <= kp.c1_until or k - t2 >= kp.c1_max:
                phase = 4
                t3 = k
        if phase == 4:
            flow_sp = 0.0
            ret_sp = kp.c1_ret
            if k - t2 >= kp.c2_after:
                t4 = k
        ring_fg[k % RING] = s_tfg
        # ===== burner controller (own design, once a second) ================================
        t_c = s_ctrl + kp.ctrl_off
        if not request and st in (S_PURGE, S_IGNITE, S_STAB, S_MOD):
            st = S_BURNOUT
            st_t = 0.0
            fouling *= 1.0 - kp.clean_eff
        if not request and st == S_WAIT:
            st = S_OFF
        if request and st == S_OFF:
            st = S_PURGE
            st_t = 0.0
        if st == S_WAIT and t_c < kp.t_on and k - stop_time >= kp.min_off:
            st = S_PURGE
            st_t = 0.0
        if st == S_PURGE and st_t >= kp.prepurge:
            st = S_IGNITE
            st_t = 0.0
            charge_left = kp.charge
            ign_t = 0.0
            top_ups = 0
            igniter = True
            t_ch_ref = s_ch
        if st == S_IGNITE:
            if s_ch - t_ch_ref > 60.0:
                st = S_STAB
                st_t = 0.0
                ig_after = 45.0
                p_cmd = 0.5 * kp.p_start
            elif ign_t >= kp.ign_timeout and top_ups < 3:
                charge_left += 0.5 * kp.charge  # safety re-feed, igniter stays on
                top_ups += 1
                ign_t = 0.0
        if st in (S_STAB, S_MOD) and t_c > kp.t_off:
            st = S_BURNOUT
            st_t = 0.0
            fouling *= 1.0 - kp.clean_eff
        if st == S_STAB:
            p_cmd = kp.p_start * (0.5 + 0.5 * st_t / kp.ramp) if st_t < kp.ramp else kp.p_start
            if st_t >= kp.start_hold:
                st = S_MOD
                st_t = 0.0
                integ = p_cmd - kp.kp * (kp.t_set - t_c)
        if st == S_MOD:
            e = kp.t_set - t_c
            p_try = kp.kp * e + integ
            if (
                kp.p_min < p_try < kp.p_max
                or (p_try >= kp.p_max and e < 0)
                or (p_try <= kp.p_min and e > 0)
            ):
                integ += kp.kp / kp.ti * e
            p_want = min(max(kp.kp * e + integ, kp.p_min), kp.p_max)
            dp = min(max(p_want - p_cmd, -kp.slew), kp.slew)
            p_cmd += dp
        if st == S_BURNOUT and st_t >= kp.postpurge and bed < 1e-4:
            stop_time = k
            st = S_WAIT if request else S_OFF
            st_t = 0.0
        if st not in (S_STAB, S_MOD):
            p_cmd = 0.0
        if ig_after > 0.0:
            ig_after -= 1.0
            if ig_after <= 0.0:
                igniter = False
        if st not in (S_IGNITE, S_STAB):
            igniter = False
        # fuel command and fan
        md_cmd = p_cmd * 3600.0 / kp.lhv_ctrl  # kg/h dry, what the controller believes
        xi_fan = a_fan * xi_fan + math.sqrt(1.0 - a_fan * a_fan) * noise[k, 1]
        if st == S_STAB or st == S_MOD:
            lam_sp = _lam_set(kp, md_cmd)
            v_air = lam_sp * air_min * md_cmd * (1.0 + kp.fan_sigma * xi_fan + trim)
            v_air = max(v_air, kp.air_ign if st == S_MOD else kp.air_purge)
            if md > 0.0 and lam < 50.0:
                trim += (lam_sp - lam) / lam_sp / kp.trim_tau  # O2 trim
                trim = min(max(trim, -0.15), 0.15)
        elif st == S_PURGE:
            v_air = kp.air_purge
        elif st == S_IGNITE:
            v_air = kp.air_ign * (1.0 + (kp.ign_fan_factor - 1.0) * s if fan_ign else 1.0)
        elif st == S_BURNOUT:
            v_air = kp.air_post
        else:
            v_air = kp.v_idle
        # auger: pulses of the full auger rate; the controller meters turns for nominal density
        feed_ar = 0.0
        if st == S_IGNITE and charge_left > 0.0:
            feed_ar = kp.aug_max * kp.bulk_ratio
            charge_left -= kp.aug_max / 3600.0
        elif st == S_STAB or (st == S_MOD and st_t % kp.pause_period >= kp.pause_s):
            # in modulation the feed pauses now and then while the grate is shaken clean
            duty = md_cmd / (1.0 - kp.w_ctrl) / kp.aug_max
            ph = (k % int(kp.aug_period)) / kp.aug_period
            on = min(max(duty - ph, 0.0) * kp.aug_period, 1.0)
            feed_ar = on * kp.aug_max * kp.bulk_ratio
        # electricity (paper Section 2.1: linear in load between Pel,MIN and Pel,MAX, Pel,OFF in
        # stand-by; the igniter on top, the spiral cleaner after each stop)
        if st == S_OFF or st == S_WAIT:
            p_el = kp.pel_off
        elif st == S_PURGE or st == S_IGNITE:
            p_el = kp.pel_min
        elif st == S_BURNOUT:
            p_el = 0.8 * kp.pel_min + (40.0 if st_t < 60.0 else 0.0)
        else:
            frac = min(max((p_cmd / kp.p_max - 0.3) / 0.7, 0.0), 1.0)
            p_el = kp.pel_min + (kp.pel_max - kp.pel_min) * frac
        if igniter:
            p_el += kp.ign_kw * 1000.0
        # ===== plant sub-steps ==============================================================
        xi_burn = a_burn * xi_burn + math.sqrt(1.0 - a_burn * a_burn) * noise[k, 0]
        xi_dist = a_dist * xi_dist + math.sqrt(1.0 - a_dist * a_dist) * noise[k, 2]
        fsp = flow_sp
        for sub in range(nsub):
            if k == 0 and sub == 0:
                u0 = (
                    kp.c_w * tw + kp.c_s * ts + c_d * td + c_r * tr + c_ins * tins + c_pl * tpl
                    + c_v * tv + m_seg * CP_W * (tp[0] + tp[1] + tp[2] + tp[3])
                )  # fmt: skip
            m_flow = _lag(m_flow, fsp, h, kp.flow_tau)
            if fsp <= 0.0 and m_flow < 0.5:
                m_flow = 0.0
            mdot = m_flow / 3600.0  # kg/s
            # --- bed ---
            bed += feed_ar / 3600.0 * h
            fed += feed_ar / 3600.0 * h
            if not lit and bed > 0.2 * kp.charge:
                t_target = t_room + (kp.ign_rise if igniter else 0.0) / (
                    1.0 + (kp.ign_fan_factor - 1.0) * s if fan_ign else 1.0
                )
                t_el = _lag(t_el, t_target, h, 45.0)
                t_surf = _lag(t_surf, t_el, h, 60.0)
                prog += h / 30.0 * math.exp(min((t_surf - kp.ign_ref) / 35.0, 20.0))
                if prog >= 1.0:
                    lit = True
                    lf = 0.02
            elif not lit:
                t_el = _lag(t_el, t_room + (kp.ign_rise if igniter else 0.0), h, 45.0)
            tau_b = kp.tau_bed
            if lit:
                sp = kp.spread + (kp.spread_extra * s if smoulder else 0.0)
                lf += h * lf * (1.0 - lf) / sp
                lf = min(lf, 1.0)
                if smoulder and st in (S_BURNOUT, S_WAIT, S_OFF):
                    tau_b = kp.tau_bed * (1.0 + kp.burnout_factor * s)
                burn_ar = lf * bed / tau_b * max(1.0 + kp.burn_sigma * xi_burn, 0.0) * 3600.0
            else:
                burn_ar = 0.0
            md = burn_ar * (1.0 - kp.fw)  # kg/h dry
            md_air = v_air / (air_min * 1.02)  # air-limited burning
            if md > md_air:
                md = md_air
                burn_ar = md / (1.0 - kp.fw)
            if burn_ar / 3600.0 * h > bed:
                burn_ar = bed / h * 3600.0
                md = burn_ar * (1.0 - kp.fw)
            dm = burn_ar / 3600.0 * h
            bed -= dm
            ash += dm * (1.0 - kp.fw) * kp.fash
            burnt += dm * (1.0 - (1.0 - kp.fw) * kp.fash)
            if lit and bed < 1e-6 and st in (S_BURNOUT, S_WAIT, S_OFF, S_PURGE):
                ash += bed  # the last crumbs drop into the ash box
                bed = 0.0
                lit = False
                lf = 0.0
                prog = 0.0
                t_el = t_room
                t_surf = t_room
            # --- gas (paper Eq. 3-6) ---
            v_co2 = 1.866 * kp.fc * md
            v_so2 = 0.7 * kp.fs * md
            v_n2 = 0.79 * v_air + 0.8 * kp.fn * md
            v_o2 = max(0.21 * v_air - 0.21 * air_min * md, 0.0)
            v_dry = v_co2 + v_so2 + v_n2 + v_o2
            v_h2o = vh2o_per_kg * md
            m_dry = RHO_CO2 * v_co2 + RHO_SO2 * v_so2 + RHO_N2 * v_n2 + RHO_O2 * v_o2
            m_vap = RHO_H2O * v_h2o
            wcp = (m_dry * CP_G + m_vap * CP_V) / 3600.0  # kW/K
            lam = v_air / (air_min * md) if md > 1e-9 else 99.0
            o2 = 100.0 * v_o2 / v_dry if v_dry > 0 else 20.95
            co2 = 100.0 * v_co2 / v_dry if v_dry > 0 else 0.04
            if md > 1e-9:
                load = md / kp.md_ref
                co = kp.co_base * (1.0 + 2.5 * (1.0 - min(load, 1.0)) ** 2)
                co += 2500.0 * (1.0 - lf)
                if st == S_BURNOUT:
                    co += 1200.0
                if lam < 1.15:
                    co += 30000.0 * (1.15 - lam)
                co = min(co, 20000.0)
            else:
                co = 0.0
            q_rel = md * kp.hhv / 3600.0
            q_lat = m_vap * DH_VAP / 3600.0
            q_chem = co * 1e-6 * v_dry * RHO_CO * DH_CO / 3600.0
            q_ash = 0.0002 * q_rel
            q_avail = q_rel - q_lat - q_chem - q_ash
            q_ring_in = ring_in = 0.0
            if ring and lit:
                q_ring_in = kp.ring_share * s * q_avail * lf
                ring_in = q_ring_in
            q_gas = q_avail - q_ring_in
            q_ins = 0.0
            q_pl = 0.0
            if wcp > 1e-9:
                t_ad = t_room + q_gas / wcp
                tg = t_ad
                ratio = max(wcp / kp.w_ref, 1e-3)
                if insert:
                    ntu_i = kp.ntu_ins * s * ratio ** (-kp.ntu_exp)
                    tg1 = tins + (tg - tins) * math.exp(-ntu_i)
                    q_ins = wcp * (tg - tg1)
                    tg = tg1
                ntu = kp.ntu_ref * ratio ** (-kp.ntu_exp) * (1.0 - fouling)
                tg2 = ts + (tg - ts) * math.exp(-ntu)
                t_chamber = ts + (tg - ts) * math.exp(-0.2 * ntu)
                q_hx = wcp * (tg - tg2)
                tg = tg2
                if plate:
                    ntu_p = kp.ntu_pl * s * ratio ** (-kp.ntu_exp)
                    tg3 = tpl + (tg - tpl) * math.exp(-ntu_p)
                    q_pl = wcp * (tg - tg3)
                    tg = tg3
                t_fg = tg
                q_fgs = wcp * (t_fg - t_room)
            else:
                q_hx = 0.0
                t_fg = ts
                t_chamber = ts
                q_fgs = 0.0
            fouling += kp.fouling_per_kg * md / 3600.0 * h
            q_fg = q_fgs + q_lat + q_chem
            # --- body (Eq. 2, 7, 10) ---
            q_ign = kp.ign_kw if igniter else 0.0
            q_door_in = kp.door_share * s * max(q_hx, 0.0) if door else 0.0
            q_dw = c_d / kp.door_tau * (td - tw) if door else 0.0
            q_dr = 0.0003 * s * (td - t_room) if door else 0.0
            q_rs = kp.ring_k * s * ((tr + 273.15) ** 4 - (ts + 273.15) ** 4) if ring else 0.0
            q_ins_s = kp.k_ins * s * ((tins + 273.15) ** 4 - (ts + 273.15) ** 4) if insert else 0.0
            q_pl_s = kp.ua_pl_s * s * (tpl - ts) if plate else 0.0
            q_sw = kp.ua_sw * (ts - tw)
            q_env = kp.ua_env * (tw - t_room)
            # --- exit pipe, backward Euler from the boiler to the forward sensor ---
            t_src = tw
            q_nc = 0.0
            q_pipe_loss = 0.0
            q_vw = 0.0
            cseg = m_seg * CP_W
            # axial conduction along the pipe (explicit, old temperatures: cancels exactly)
            for j in range(NSEG - 1):
                f_ax[j] = kp.ua_nc * (tp[j] - tp[j + 1])
            for j in range(NSEG):
                num = cseg * tp[j] + mdot * CP_W * h * t_src + ua_seg * h * t_room
                if j < NSEG - 1:
                    num -= f_ax[j] * h
                if j > 0:
                    num += f_ax[j - 1] * h
                den = cseg + mdot * CP_W * h + ua_seg * h
                if j == 0:
                    num += kp.ua_nc * h * tw
                    den += kp.ua_nc * h
                if valve and j == 1:
                    uvw = kp.ua_valve_w * s * (0.15 + (m_flow / kp.flow_nom) ** 0.8)
                    num += uvw * h * tv
                    den += uvw * h
                tp[j] = num / den
                q_pipe_loss += ua_seg * (tp[j] - t_room)
                if j == 0:
                    q_nc = kp.ua_nc * (tw - tp[0])
                if valve and j == 1:
                    q_vw = uvw * (tv - tp[1])
                t_src = tp[j]
            q_vr = kp.ua_valve_r * s * (tv - t_room) if valve else 0.0
            # boundary fluxes (kW), then explicit node updates with the same numbers
            q_w_in = mdot * CP_W * trp
            q_w_out = mdot * CP_W * tp[NSEG - 1]
            flux = (
                q_rel + q_ign - q_ash - q_lat - q_chem - q_fgs + q_w_in - q_w_out - q_env
                - q_dr - q_pipe_loss - q_vr
            )  # fmt: skip
            e_in += flux * h
            gross += (
                abs(q_rel) + q_ign + abs(q_fg) + abs(q_w_in) + abs(q_w_out) + abs(q_env)
                + abs(q_pipe_loss)
            ) * h  # fmt: skip
            tw_new = tw + h / kp.c_w * (q_sw + q_dw + mdot * CP_W * (trp - tw) - q_env - q_nc)
            ts_new = ts + h / kp.c_s * (q_hx - q_door_in + q_rs + q_ins_s + q_pl_s + q_ign - q_sw)
            if door:
                td += h / c_d * (q_door_in - q_dw - q_dr)
            if ring:
                tr += h / c_r * (ring_in - q_rs)
            if insert:
                tins += h / c_ins * (q_ins - q_ins_s)
            if plate:
                tpl += h / c_pl * (q_pl - q_pl_s)
            if valve:
                tv += h / c_v * (-q_vw - q_vr)
            tw = tw_new
            ts = ts_new
            # --- bench: loop, cooler/heater on a PI valve, return pipe ---
            q_cmd = 0.0
            if mdot > 0.0:
                cap = kp.heat_max if phase == 0 else 0.0
                e_b = ret_sp - s_tin
                b_int += kp.bench_kp / kp.bench_ti * e_b * h
                b_int = min(max(b_int, -kp.cool_max), cap)  # anti-windup
                q_cmd = min(max(kp.bench_kp * e_b + b_int, -kp.cool_max), cap)
            q_bench = _lag(q_bench, q_cmd, h, kp.valve_tau)
            q_loop = q_bench + kp.dist * xi_dist * (1.0 if mdot > 0.0 else 0.0)
            tloop += (
                h
                / kp.c_loop
                * (mdot * CP_W * (tp[NSEG - 1] - tloop) + q_loop - kp.ua_loop * (tloop - t_room))
            )
            c_rp = kp.m_rp * CP_W
            trp = (c_rp * trp + mdot * CP_W * h * tloop + kp.ua_rp * h * t_room) / (
                c_rp + mdot * CP_W * h + kp.ua_rp * h
            )
            # --- instruments (lags) ---
            s_tin = _lag(s_tin, trp, h, kp.tau_t_in)
            if pocket:
                ff = 0.08 + (m_flow / kp.flow_nom) ** 0.8
                beta = kp.pocket_beta * s / (1.0 + 12.0 * (ff - 0.08))
                tgt = tp[NSEG - 1] - beta * (tp[NSEG - 1] - t_room)
                s_tout = _lag(s_tout, tgt, h, kp.tau_t_out + kp.pocket_tau * s / ff)
            else:
                s_tout = _lag(s_tout, tp[NSEG - 1], h, kp.tau_t_out)
            s_tb = _lag(s_tb, tw, h, kp.tau_t_boiler)
            s_ctrl = _lag(s_ctrl, tw, h, kp.ctrl_tau)
            s_tfg = _lag(s_tfg, t_fg, h, kp.tau_t_fg)
            s_ch = _lag(s_ch, t_chamber, h, kp.tau_ch)
            s_flow = _lag(s_flow, m_flow, h, 2.0)
        # gas analyser: transport delay then a lag
        ring_o2[k % RING] = o2
        ring_co2[k % RING] = co2
        ring_co[k % RING] = co
        dly = int(kp.o2_delay)
        j = (k - dly) % RING if k >= dly else 0
        s_o2 = _lag(s_o2, ring_o2[j], 1.0, kp.o2_tau)
        s_co2 = _lag(s_co2, ring_co2[j], 1.0, kp.o2_tau)
        s_co = _lag(s_co, ring_co[j], 1.0, kp.o2_tau)
        st_t += 1.0
        ign_t += 1.0
        # ===== record (state at the end of second k) ========================================
        u = (
            kp.c_w * tw + kp.c_s * ts + c_d * td + c_r * tr + c_ins * tins + c_pl * tpl
            + c_v * tv + m_seg * CP_W * (tp[0] + tp[1] + tp[2] + tp[3])
        )  # fmt: skip
        v_act = (v_dry + v_h2o) / 3600.0 * (t_fg + 273.15) / 273.15 * 1013.25 / kp.p_amb
        out[k, O_PHASE] = phase
        out[k, O_SEQ] = seq_i
        out[k, O_FLOW] = s_flow
        out[k, O_FLOW_SP] = flow_sp
        out[k, O_TIN] = s_tin
        out[k, O_TOUT] = s_tout
        out[k, O_TB] = s_tb
        out[k, O_TFG] = s_tfg
        out[k, O_O2] = s_o2
        out[k, O_CO2] = s_co2
        out[k, O_CO] = s_co
        out[k, O_VEL] = v_act / kp.duct_area
        out[k, O_HOPPER] = hopper - fed
        out[k, O_PEL] = p_el
        out[k, O_ON] = 1.0 if st in (S_PURGE, S_IGNITE, S_STAB, S_MOD) else 0.0
        out[k, O_U] = u - u0
        out[k, O_EIN] = e_in
        out[k, O_FED] = fed
        out[k, O_BURNT] = burnt
        out[k, O_ASH] = ash
        out[k, O_BED] = bed
        out[k, O_TW] = tw
        out[k, O_TS] = ts
        out[k, O_TFGT] = t_fg
        out[k, O_QREL] = q_rel
        out[k, O_QW] = mdot * CP_W * (tp[NSEG - 1] - trp)
        out[k, O_FEED] = feed_ar
        out[k, O_STATE] = st
        out[k, O_LAM] = lam
        out[k, O_TROOM] = t_room
        out[k, O_PCMD] = p_cmd
        out[k, O_QFG] = q_fg
        out[k, O_GROSS] = gross
        out[k, O_TOUT_TRUE] = tp[NSEG - 1]
        out[k, O_TIN_TRUE] = trp
        out[k, O_FLOW_TRUE] = m_flow
        out[k, O_MD] = md
        if t4 >= 0:
            n_used = k + 1
            break
    return n_used, t0, t1, t2, t3, t4
