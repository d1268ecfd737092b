"""The plant's time-stepping kernel: boiler, burner controller, bench and test protocol.

One call simulates one whole test at a fixed internal step of 1 s. All physics is in kW,
kJ, kJ/K, kW/K, kg and seconds. The parameter vector ``p`` is indexed by the names in
``PARAM_NAMES`` (the index constants below are generated from it, in this file, so that
numba's on-disk cache is invalidated whenever the layout changes).

Energy bookkeeping (checked by the tests): the control volume is the boiler (metal nodes,
water, economiser and lining nodes) plus the exit pipe up to the forward sensor. Per step

    dt * (Q_fuel + P_ign) = dt * (Q_hidden + Q_ash + Q_fg,lat + Q_fg,chem + Q_fg,sens
                                  + Q_room + Q_water) + (E_stored,new - E_stored,old)

holds to rounding: non-advective fluxes are explicit (old temperatures), the water path is
implicit upwind, and each flux is booked with exactly the value used in the update.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PARAM_NAMES: tuple[str, ...] = (
    # boiler body and water
    "c_w", "c_m", "c_a", "c_b", "g_ab", "g_bm", "f_rad", "g_mw",
    "c_pl", "f_pl", "g_pw", "ua_env", "m_draught_ref", "ntu_nom", "w_g_nom", "ntu_exp",
    # flue path after the main exchanger
    "c_e", "g_ew", "eps_e", "c_l", "eps_l", "ua_l",
    # exit pipe and sensor pocket
    "n_pipe", "c_cell", "ua_cell", "g_ax", "strat", "c_bot", "ua_bot", "g_mix0", "k_mix",
    # fuel (true) and its stoichiometry
    "hhv_true", "w_ar", "ash", "h", "air_min_mass", "o2_need", "v_co2", "v_so2", "v_n2f",
    "lhv_ar_nom", "def_mode", "def_a",
    # burner
    "p_max", "p_min", "p_start", "feed_cal", "auger_period", "tau_bed", "tau_dry",
    "t_ign_need", "t_preload", "t_purge", "t_stab", "t_ign_after", "min_pause",
    "lam_a", "lam_b", "m_air_purge", "p_ign", "pel_min", "pel_max", "pel_off", "co_base",
    # boiler controller
    "t_set", "t_off", "t_restart", "kp", "ti", "rate", "tau_ctrl", "ctrl_offset",
    # bench
    "c_loop", "kb_p", "kb_i", "q_cool_cap", "q_heat_cap", "tau_valve", "tau_flow",
    "flow_nom", "c_inpipe", "ua_inpipe", "g_inpipe",
    # sensor lags
    "tau_out", "tau_wb", "tau_fg", "wb_strat", "p_nom",
    # protocol
    "pre_T", "pre_tol", "pre_hold", "pre_max", "pre_load", "ret_sp_pre", "ret_sp",
    "su_window", "su_rise", "su_min", "su_max", "su_fg_min_rise",
    "c1_load", "c1_until", "c1_max", "c2_after",
    # initial state
    "t_init_w", "t_init_m",
)  # fmt: skip
# index constants (checked against PARAM_NAMES by the tests)
P_C_W = 0
P_C_M = 1
P_C_A = 2
P_C_B = 3
P_G_AB = 4
P_G_BM = 5
P_F_RAD = 6
P_G_MW = 7
P_C_PL = 8
P_F_PL = 9
P_G_PW = 10
P_UA_ENV = 11
P_M_DRAUGHT_REF = 12
P_NTU_NOM = 13
P_W_G_NOM = 14
P_NTU_EXP = 15
P_C_E = 16
P_G_EW = 17
P_EPS_E = 18
P_C_L = 19
P_EPS_L = 20
P_UA_L = 21
P_N_PIPE = 22
P_C_CELL = 23
P_UA_CELL = 24
P_G_AX = 25
P_STRAT = 26
P_C_BOT = 27
P_UA_BOT = 28
P_G_MIX0 = 29
P_K_MIX = 30
P_HHV_TRUE = 31
P_W_AR = 32
P_ASH = 33
P_H = 34
P_AIR_MIN_MASS = 35
P_O2_NEED = 36
P_V_CO2 = 37
P_V_SO2 = 38
P_V_N2F = 39
P_LHV_AR_NOM = 40
P_DEF_MODE = 41
P_DEF_A = 42
P_P_MAX = 43
P_P_MIN = 44
P_P_START = 45
P_FEED_CAL = 46
P_AUGER_PERIOD = 47
P_TAU_BED = 48
P_TAU_DRY = 49
P_T_IGN_NEED = 50
P_T_PRELOAD = 51
P_T_PURGE = 52
P_T_STAB = 53
P_T_IGN_AFTER = 54
P_MIN_PAUSE = 55
P_LAM_A = 56
P_LAM_B = 57
P_M_AIR_PURGE = 58
P_P_IGN = 59
P_PEL_MIN = 60
P_PEL_MAX = 61
P_PEL_OFF = 62
P_CO_BASE = 63
P_T_SET = 64
P_T_OFF = 65
P_T_RESTART = 66
P_KP = 67
P_TI = 68
P_RATE = 69
P_TAU_CTRL = 70
P_CTRL_OFFSET = 71
P_C_LOOP = 72
P_KB_P = 73
P_KB_I = 74
P_Q_COOL_CAP = 75
P_Q_HEAT_CAP = 76
P_TAU_VALVE = 77
P_TAU_FLOW = 78
P_FLOW_NOM = 79
P_C_INPIPE = 80
P_UA_INPIPE = 81
P_G_INPIPE = 82
P_TAU_OUT = 83
P_TAU_WB = 84
P_TAU_FG = 85
P_WB_STRAT = 86
P_P_NOM = 87
P_PRE_T = 88
P_PRE_TOL = 89
P_PRE_HOLD = 90
P_PRE_MAX = 91
P_PRE_LOAD = 92
P_RET_SP_PRE = 93
P_RET_SP = 94
P_SU_WINDOW = 95
P_SU_RISE = 96
P_SU_MIN = 97
P_SU_MAX = 98
P_SU_FG_MIN_RISE = 99
P_C1_LOAD = 100
P_C1_UNTIL = 101
P_C1_MAX = 102
P_C2_AFTER = 103
P_T_INIT_W = 104
P_T_INIT_M = 105
N_PARAMS = len(PARAM_NAMES)

SIGNAL_NAMES: tuple[str, ...] = (
    "time", "phase", "seq", "flow_sp", "flow", "t_in", "t_out_node", "t_out_sens", "t_w",
    "t_w_sens", "t_fg", "t_fg_sens", "o2", "co2", "co_ppm", "gas_m3n_h", "hopper",
    "boiler_on", "p_el", "t_room", "q_fuel", "p_ign", "q_hidden", "q_ash", "q_lat",
    "q_chem", "q_sens", "q_room", "q_water", "e_stored", "m_fed", "m_burn", "m_hold",
    "m_bed", "state", "p_dem", "t_m", "lam",
)  # fmt: skip
S_TIME = 0
S_PHASE = 1
S_SEQ = 2
S_FLOW_SP = 3
S_FLOW = 4
S_T_IN = 5
S_T_OUT_NODE = 6
S_T_OUT_SENS = 7
S_T_W = 8
S_T_W_SENS = 9
S_T_FG = 10
S_T_FG_SENS = 11
S_O2 = 12
S_CO2 = 13
S_CO_PPM = 14
S_GAS_M3N_H = 15
S_HOPPER = 16
S_BOILER_ON = 17
S_P_EL = 18
S_T_ROOM = 19
S_Q_FUEL = 20
S_P_IGN = 21
S_Q_HIDDEN = 22
S_Q_ASH = 23
S_Q_LAT = 24
S_Q_CHEM = 25
S_Q_SENS = 26
S_Q_ROOM = 27
S_Q_WATER = 28
S_E_STORED = 29
S_M_FED = 30
S_M_BURN = 31
S_M_HOLD = 32
S_M_BED = 33
S_STATE = 34
S_P_DEM = 35
S_T_M = 36
S_LAM = 37
N_SIGNALS = len(SIGNAL_NAMES)

MAX_CELLS = 6
CP_W = 4.19  # kJ/(kg K), liquid water 40-90 C
CP_FG = 1.05  # kJ/(kg K), dry flue gas 100-200 C
CP_VAP = 1.90  # kJ/(kg K), water vapour
CP_AIR = 1.006  # kJ/(kg K)
DH_VAP = 2442.0  # kJ/kg at 25 C (HHV basis)
DH_CO = 10100.0  # kJ/kg CO
RHO_CO = 1.25  # kg/m3N
# controller states
ST_OFF, ST_PURGE, ST_IGNITION, ST_STABILISE, ST_MODULATE, ST_BURNOUT = 0, 1, 2, 3, 4, 5


@njit(cache=True)
def _first_order(y: float, u: float, tau: float, dt: float) -> float:
    """Exact zero-order-hold step of tau*dy/dt = u - y."""
    if tau <= 0.0:
        return u
    return u + (y - u) * math.exp(-dt / tau)


@njit(cache=True)
def run_kernel(
    p: np.ndarray,
    room: np.ndarray,
    density: np.ndarray,
    seq_start: np.ndarray,
    seq_dur: np.ndarray,
    seq_l0: np.ndarray,
    seq_l1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate one test; returns (signals[n, N_SIGNALS], events[t0, t1, t2, t3, t4]).

    ``room`` and ``density`` are per-second series (room temperature in C, relative bulk
    density of the pellets leaving the auger) at least as long as the longest possible test.
    The test sequence is given as start offsets from t1 (s), durations (s) and the load at
    the start and end of each step (% of nominal; equal for stationary steps).
    """
    dt = 1.0
    nmax = room.shape[0]
    out = np.full((nmax, N_SIGNALS), np.nan)
    events = np.full(5, np.nan)
    n_seq = seq_start.shape[0]
    test_len = seq_start[n_seq - 1] + seq_dur[n_seq - 1]

    # ---- state -------------------------------------------------------------------------
    tw = p[P_T_INIT_W]
    tm = p[P_T_INIT_M]
    ta = tm
    tb = tm
    tpl = tm
    te = tm
    tl = room[0] + 0.5 * (tm - room[0])
    n_cells = int(p[P_N_PIPE])
    tp = np.empty(MAX_CELLS)
    for i in range(MAX_CELLS):
        tp[i] = tw
    tbot = tw
    tip = tw  # return pipe at the boiler inlet (bench side)
    tloop = tw
    t_out_sens = tw
    t_w_sens = tw
    t_ctrl = tw
    t_fg_sens = tw
    flow = p[P_PRE_LOAD] / 100.0 * p[P_FLOW_NOM]
    q_bench = 0.0
    q_bench_i = 0.0
    hopper = 0.0  # relative: the simulate layer adds the initial fill
    m_hold = 0.0
    m_bed = 0.0
    ignited = False
    state = ST_OFF
    t_state = 0.0
    t_since_stop = 1.0e9
    ign_timer = 0.0
    flame_time = -1.0
    fg_at_ign = 0.0
    p_dem = 0.0
    pi_i = 0.0
    igniter = False
    m_air_prev = 0.0

    phase = 0
    t_phase = 0.0
    hold = 0.0
    t0 = -1.0
    t1 = -1.0
    t2 = -1.0
    t3 = -1.0
    fg_t0 = 0.0
    fg_hist = np.zeros(nmax)
    n_used = nmax

    c_cells = p[P_C_CELL]
    cap_bot = p[P_C_BOT]
    w_ar = p[P_W_AR]
    vap_per_dry = 9.0 * p[P_H] + w_ar / (1.0 - w_ar)
    dry_gas_per_dry = 1.0 - p[P_ASH] - 9.0 * p[P_H]
    m_aug = p[P_FEED_CAL] * p[P_P_MAX] / p[P_LHV_AR_NOM]  # kg/s as received, auger on

    for k in range(nmax):
        t = k * dt
        t_room = room[k]
        # ---- protocol ------------------------------------------------------------------
        seq = -1
        enable = False
        ret_sp = p[P_RET_SP]
        if phase == 0:
            ret_sp = p[P_RET_SP_PRE]
            load = p[P_PRE_LOAD]
            ok = (
                abs(t_out_sens - p[P_PRE_T]) < p[P_PRE_TOL] and abs(tip - p[P_PRE_T]) < p[P_PRE_TOL]
            )
            hold = hold + dt if ok else 0.0
            if hold >= p[P_PRE_HOLD] or t_phase >= p[P_PRE_MAX]:
                phase = 1
                t_phase = 0.0
                t0 = t
                fg_t0 = t_fg_sens
        elif phase == 1:
            load = seq_l0[0]
            enable = True
            el = t_phase
            if el >= p[P_SU_MIN] and k >= int(p[P_SU_WINDOW]):
                rise = t_fg_sens - fg_hist[k - int(p[P_SU_WINDOW])]
                rate_ok = rise < p[P_SU_RISE] * p[P_SU_WINDOW] / 60.0
                risen = t_fg_sens - fg_t0 > p[P_SU_FG_MIN_RISE]
                if (rate_ok and risen) or el >= p[P_SU_MAX]:
                    phase = 2
                    t_phase = 0.0
                    t1 = t
        if phase == 2:
            enable = True
            el = t_phase
            if el >= test_len:
                phase = 3
                t_phase = 0.0
                t2 = t
                enable = False
            else:
                seq = 0
                while seq < n_seq - 1 and el >= seq_start[seq + 1]:
                    seq += 1
                frac = (el - seq_start[seq]) / seq_dur[seq]
                load = seq_l0[seq] + (seq_l1[seq] - seq_l0[seq]) * frac
        if phase == 3:
            load = p[P_C1_LOAD]
            if (t_phase > 0.0 and t_out_sens <= p[P_C1_UNTIL]) or t_phase >= p[P_C1_MAX]:
                phase = 4
                t_phase = 0.0
                t3 = t
        if phase == 4:
            load = 0.0
            if t - t2 >= p[P_C2_AFTER]:
                n_used = k
                break
        flow_sp = load / 100.0 * p[P_FLOW_NOM]

        # ---- boiler controller (own sensor, own state machine) ---------------------------
        t_state += dt
        feed_frac = 0.0
        if state == ST_OFF:
            t_since_stop += dt
            p_dem = 0.0
            if enable and t_ctrl <= p[P_T_RESTART] and t_since_stop >= p[P_MIN_PAUSE]:
                state = ST_PURGE
                t_state = 0.0
        elif state == ST_PURGE:
            if t_state >= p[P_T_PURGE]:
                state = ST_IGNITION
                t_state = 0.0
                ign_timer = 0.0
                igniter = True
                fg_at_ign = t_fg_sens
                flame_time = -1.0
        elif state == ST_IGNITION:
            if t_state < p[P_T_PRELOAD]:
                p_dem = p[P_P_START]
                feed_frac = 1.0
            else:
                p_dem = 0.0
            if flame_time < 0.0 and ignited and t_fg_sens > fg_at_ign + 8.0:
                flame_time = t
            if flame_time >= 0.0 or t_state > 2400.0:
                state = ST_STABILISE
                t_state = 0.0
                if flame_time < 0.0:
                    flame_time = t
        elif state == ST_STABILISE:
            p_dem = p[P_P_START]
            feed_frac = 1.0
            if t - flame_time >= p[P_T_IGN_AFTER]:
                igniter = False
            if t_state >= p[P_T_STAB] or t_ctrl >= p[P_T_SET] + 2.0:
                state = ST_MODULATE
                t_state = 0.0
                pi_i = p_dem
        elif state == ST_MODULATE:
            if t - flame_time >= p[P_T_IGN_AFTER]:
                igniter = False
            e = p[P_T_SET] - t_ctrl
            raw = p[P_KP] * e + pi_i
            wind = (raw >= p[P_P_MAX] and e > 0.0) or (raw <= p[P_P_MIN] and e < 0.0)
            if not wind:
                pi_i += p[P_KP] / p[P_TI] * e * dt
            target = min(max(raw, p[P_P_MIN]), p[P_P_MAX])
            step = p[P_RATE] * dt
            p_dem = p_dem + min(max(target - p_dem, -step), step)
            feed_frac = p_dem / p[P_P_MAX]
        if (state == ST_STABILISE or state == ST_MODULATE) and (t_ctrl >= p[P_T_OFF] or not enable):
            state = ST_BURNOUT
            t_state = 0.0
            igniter = False
            p_dem = 0.0
        if state == ST_IGNITION and not enable:
            state = ST_BURNOUT
            t_state = 0.0
            igniter = False
            p_dem = 0.0
        if state == ST_BURNOUT:
            feed_frac = 0.0
            p_dem = 0.0
            if (not ignited and t_state > 60.0) or t_state > 1800.0:
                state = ST_OFF
                t_state = 0.0
                t_since_stop = 0.0
        if state == ST_PURGE and not enable:
            state = ST_OFF
            t_state = 0.0

        # ---- auger: pulsed feeding, volumetric, with bulk-density fluctuation ------------
        fed = 0.0
        if feed_frac > 0.0:
            per = p[P_AUGER_PERIOD]
            pos = t - per * math.floor(t / per)
            dur = feed_frac * per  # auger on during [0, dur) of each period
            on = min(max(dur - pos, 0.0), 1.0)  # overlap of [pos, pos+1) with [0, dur)
            on += max(min(pos + 1.0, per + dur) - max(pos, per), 0.0)  # ... and the next one
            fed = m_aug * density[k] * on * dt
        hopper -= fed
        if p[P_TAU_DRY] > 0.0:
            m_hold += fed
            x = m_hold * dt / p[P_TAU_DRY]
            m_hold -= x
            m_bed += x
        else:
            m_bed += fed

        # ---- fan / air ------------------------------------------------------------------
        dry_dem_h = p_dem / p[P_LHV_AR_NOM] * (1.0 - w_ar) * 3600.0
        if state == ST_PURGE:
            m_air = p[P_M_AIR_PURGE]
        elif state == ST_IGNITION:
            m_air = 0.5 * p[P_M_AIR_PURGE]
        elif state == ST_STABILISE or state == ST_MODULATE:
            lam_set = p[P_LAM_A] + p[P_LAM_B] * dry_dem_h
            m_air = max(p[P_AIR_MIN_MASS] * dry_dem_h * lam_set, 0.5 * p[P_M_AIR_PURGE])
        elif state == ST_BURNOUT:
            m_air = 0.7 * p[P_M_AIR_PURGE]
        else:
            dtd = max(tm - t_room, 0.0)
            m_air = p[P_M_DRAUGHT_REF] * math.sqrt(dtd / 40.0) + 0.2
        m_air = m_air_prev + (m_air - m_air_prev) * (1.0 - math.exp(-dt / 5.0))
        m_air_prev = m_air

        # ---- bed: ignition and burning ---------------------------------------------------
        if igniter:
            ign_timer += dt
        if not ignited and m_bed > 1.0e-4 and ign_timer >= p[P_T_IGN_NEED]:
            ignited = True
        burn = 0.0
        if ignited:
            burn = m_bed * dt / p[P_TAU_BED]
            # oxygen limit: at most what the air flow can burn at lambda 1.05
            burn_max = m_air / (p[P_AIR_MIN_MASS] * 1.05) / 3600.0 / (1.0 - w_ar) * dt
            burn = min(burn, burn_max)
            m_bed -= burn
            if m_bed < 2.0e-3 and fed == 0.0 and m_hold < 2.0e-3:
                ignited = False
        mb_dry = burn * (1.0 - w_ar) / dt  # kg/s dry
        mb_dry_h = mb_dry * 3600.0

        # ---- combustion and losses -------------------------------------------------------
        q_fuel = mb_dry * p[P_HHV_TRUE]
        p_rel = q_fuel / (p[P_P_MAX] * 1.07)  # burning power relative to full firing
        deficit = 0.0
        if p[P_DEF_MODE] == 1.0 and p_rel > 0.0:
            deficit = min(p[P_DEF_A] * p_rel**1.5, 0.3)
        elif p[P_DEF_MODE] == 2.0 and p_rel > 0.0:
            deficit = min(p[P_DEF_A] * (0.4 + 0.6 / max(p_rel, 0.05)), 0.35)
        q_hidden = deficit * q_fuel
        q_ash = 0.0002 * q_fuel
        m_vap_h = vap_per_dry * mb_dry_h
        q_lat = m_vap_h * DH_VAP / 3600.0
        va = m_air / 1.293
        v_o2 = max(0.21 * va - p[P_O2_NEED] * mb_dry_h, 0.0)
        v_dry = (p[P_V_CO2] + p[P_V_SO2] + p[P_V_N2F]) * mb_dry_h + 0.79 * va + v_o2
        lam = 99.0
        if mb_dry_h > 1.0e-6:
            lam = m_air / (p[P_AIR_MIN_MASS] * mb_dry_h)
        co_ppm = 0.0
        if mb_dry_h > 1.0e-6:
            co_ppm = p[P_CO_BASE] * (1.0 + 8.0 * math.exp(-(lam - 1.0) / 0.12))
            co_ppm *= 1.0 + 3.0 * max(0.0, 0.35 - p_rel) / 0.35
            if state == ST_BURNOUT or state == ST_IGNITION:
                co_ppm += 1500.0
        q_chem = co_ppm * 1.0e-6 * v_dry * RHO_CO * DH_CO / 3600.0
        p_ign = p[P_P_IGN] if igniter else 0.0
        m_dry_gas_h = m_air + dry_gas_per_dry * mb_dry_h
        w_g = (m_dry_gas_h * CP_FG + m_vap_h * CP_VAP) / 3600.0  # kW/K
        q_gas = q_fuel - q_hidden - q_ash - q_lat - q_chem + p_ign
        t_ad = t_room + q_gas / w_g
        chain = p[P_C_A] > 0.0
        ntu = p[P_NTU_NOM] * (w_g / p[P_W_G_NOM]) ** (-p[P_NTU_EXP])
        t_g1 = t_ad - (1.0 - math.exp(-ntu)) * (t_ad - tm)
        q_hx = w_g * (t_ad - t_g1)
        q_e = w_g * p[P_EPS_E] * (t_g1 - te)
        t_g2 = t_g1 - q_e / w_g
        q_l = w_g * p[P_EPS_L] * (t_g2 - tl)
        t_g3 = t_g2 - q_l / w_g
        q_sens = w_g * (t_g3 - t_room)

        # ---- explicit fluxes (kW) ----------------------------------------------------------
        s_a = 0.0
        s_b = 0.0
        q_rad = q_hx * p[P_F_RAD] if chain else 0.0
        q_pl = q_hx * p[P_F_PL]
        s_m = q_hx - q_rad - q_pl - p[P_G_MW] * (tm - tw)
        if chain:
            f_ab = p[P_G_AB] * (ta - tb)
            f_bm = p[P_G_BM] * (tb - tm)
            s_a = q_rad - f_ab
            s_b = f_ab - f_bm
            s_m += f_bm
        f_pw = p[P_G_PW] * (tpl - tw)
        s_pl = q_pl - f_pw
        f_ew = p[P_G_EW] * (te - tw)
        s_e = q_e - f_ew
        l_l = p[P_UA_L] * (tl - t_room)
        s_l = q_l - l_l
        l_env = p[P_UA_ENV] * (tw - t_room)
        f_ip = p[P_G_INPIPE] * (tw - tip)
        f_ax0 = p[P_G_AX] * (tw - tp[0])
        s_w = p[P_G_MW] * (tm - tw) + f_pw + f_ew - l_env - f_ip - f_ax0
        q_room = l_l + l_env + f_ip
        s_p = np.zeros(MAX_CELLS)
        for i in range(n_cells):
            loss = p[P_UA_CELL] * (tp[i] - t_room)
            q_room += loss
            s_p[i] -= loss
            if i == 0:
                s_p[i] += f_ax0
            if i + 1 < n_cells:
                fax = p[P_G_AX] * (tp[i] - tp[i + 1])
                s_p[i] -= fax
                s_p[i + 1] += fax
        s_bot = 0.0
        w_w = flow * CP_W / 3600.0  # kW/K
        if p[P_STRAT] > 0.0:
            g_mix = min(p[P_G_MIX0] + p[P_K_MIX] * w_w, 0.5 * cap_bot / dt)
            f_mix = g_mix * (tp[n_cells - 1] - tbot)
            l_bot = p[P_UA_BOT] * (tbot - t_room)
            s_p[n_cells - 1] -= f_mix
            s_bot = f_mix - l_bot
            q_room += l_bot

        # ---- update: explicit nodes, implicit upwind water path ---------------------------
        e_old = (
            p[P_C_W] * tw + p[P_C_M] * tm + p[P_C_A] * ta + p[P_C_B] * tb + p[P_C_PL] * tpl
            + p[P_C_E] * te + p[P_C_L] * tl + cap_bot * tbot
        )  # fmt: skip
        for i in range(n_cells):
            e_old += c_cells * tp[i]
        t_in = tip
        tm += dt * s_m / p[P_C_M]
        if chain:
            ta += dt * s_a / p[P_C_A]
            tb += dt * s_b / p[P_C_B]
        if p[P_C_PL] > 0.0:
            tpl += dt * s_pl / p[P_C_PL]
        if p[P_C_E] > 0.0:
            te += dt * s_e / p[P_C_E]
        if p[P_C_L] > 0.0:
            tl += dt * s_l / p[P_C_L]
        if cap_bot > 0.0:
            tbot += dt * s_bot / cap_bot
        tw = (p[P_C_W] * tw + dt * (s_w + w_w * t_in)) / (p[P_C_W] + dt * w_w)
        up = tw
        for i in range(n_cells):
            tp[i] = (c_cells * tp[i] + dt * (s_p[i] + w_w * up)) / (c_cells + dt * w_w)
            up = tp[i]
        t_exit = up
        q_water = w_w * (t_exit - t_in)
        e_new = (
            p[P_C_W] * tw + p[P_C_M] * tm + p[P_C_A] * ta + p[P_C_B] * tb + p[P_C_PL] * tpl
            + p[P_C_E] * te + p[P_C_L] * tl + cap_bot * tbot
        )  # fmt: skip
        for i in range(n_cells):
            e_new += c_cells * tp[i]

        # ---- bench: return conditioning loop (PI, capacity limit, valve lag) -------------
        err = tip - ret_sp
        raw_b = p[P_KB_P] * err + q_bench_i
        sat = (raw_b >= p[P_Q_COOL_CAP] and err > 0.0) or (raw_b <= -p[P_Q_HEAT_CAP] and err < 0.0)
        if not sat and flow > 1.0:
            q_bench_i += p[P_KB_P] / p[P_KB_I] * err * dt
        q_cmd = min(max(raw_b, -p[P_Q_HEAT_CAP]), p[P_Q_COOL_CAP])
        if flow <= 1.0:
            q_cmd = 0.0
        q_bench = _first_order(q_bench, q_cmd, p[P_TAU_VALVE], dt)
        tloop = (p[P_C_LOOP] * tloop + dt * (w_w * t_exit - q_bench)) / (p[P_C_LOOP] + dt * w_w)
        tip = (
            p[P_C_INPIPE] * tip + dt * (w_w * tloop + f_ip - p[P_UA_INPIPE] * (tip - t_room))
        ) / (p[P_C_INPIPE] + dt * w_w)
        flow = _first_order(flow, flow_sp, p[P_TAU_FLOW], dt)
        if flow_sp == 0.0 and flow < 0.5:
            flow = 0.0

        # ---- sensors with their lags --------------------------------------------------
        t_sensor_node = tbot if p[P_STRAT] > 0.0 else t_exit
        t_out_sens = _first_order(t_out_sens, t_sensor_node, p[P_TAU_OUT], dt)
        # body sensor in the upper jacket: reads above/below the mixed water in proportion
        # to the heat flux the metal gives the water (incomplete mixing of the jacket)
        t_wb_node = tw + p[P_WB_STRAT] * p[P_G_MW] * (tm - tw) / p[P_P_NOM]
        t_w_sens = _first_order(t_w_sens, t_wb_node, p[P_TAU_WB], dt)
        t_ctrl = _first_order(t_ctrl, tw + p[P_CTRL_OFFSET], p[P_TAU_CTRL], dt)
        t_fg_sens = _first_order(t_fg_sens, t_g3, p[P_TAU_FG], dt)
        fg_hist[k] = t_fg_sens

        firing = state == ST_PURGE or state == ST_IGNITION or state == ST_STABILISE
        firing = firing or state == ST_MODULATE
        if state == ST_OFF:
            p_el = p[P_PEL_OFF]
        elif state == ST_PURGE or state == ST_IGNITION or state == ST_BURNOUT:
            p_el = p[P_PEL_MIN]
        else:
            fr = (p_dem - p[P_P_MIN]) / (p[P_P_MAX] - p[P_P_MIN])
            p_el = p[P_PEL_MIN] + (p[P_PEL_MAX] - p[P_PEL_MIN]) * min(max(fr, 0.0), 1.0)
        p_el += p_ign * 1000.0

        o = out[k]
        o[S_TIME] = t
        o[S_PHASE] = phase
        o[S_SEQ] = seq
        o[S_FLOW_SP] = flow_sp
        o[S_FLOW] = flow
        o[S_T_IN] = tip
        o[S_T_OUT_NODE] = t_sensor_node
        o[S_T_OUT_SENS] = t_out_sens
        o[S_T_W] = tw
        o[S_T_W_SENS] = t_w_sens
        o[S_T_FG] = t_g3
        o[S_T_FG_SENS] = t_fg_sens
        o[S_O2] = 100.0 * v_o2 / v_dry
        o[S_CO2] = 100.0 * p[P_V_CO2] * mb_dry_h / v_dry
        o[S_CO_PPM] = co_ppm
        o[S_GAS_M3N_H] = m_dry_gas_h / 1.30 + m_vap_h / 0.804
        o[S_HOPPER] = hopper
        o[S_BOILER_ON] = 1.0 if firing else 0.0
        o[S_P_EL] = p_el
        o[S_T_ROOM] = t_room
        o[S_Q_FUEL] = q_fuel
        o[S_P_IGN] = p_ign
        o[S_Q_HIDDEN] = q_hidden
        o[S_Q_ASH] = q_ash
        o[S_Q_LAT] = q_lat
        o[S_Q_CHEM] = q_chem
        o[S_Q_SENS] = q_sens
        o[S_Q_ROOM] = q_room
        o[S_Q_WATER] = q_water
        o[S_E_STORED] = e_new - e_old
        o[S_M_FED] = fed
        o[S_M_BURN] = burn
        o[S_M_HOLD] = m_hold
        o[S_M_BED] = m_bed
        o[S_STATE] = state
        o[S_P_DEM] = p_dem
        o[S_T_M] = tm
        o[S_LAM] = lam
        t_phase += dt
    events[0] = t0
    events[1] = t1
    events[2] = t2
    events[3] = t3
    events[4] = n_used * dt
    return out[:n_used], events
