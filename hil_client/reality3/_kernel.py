"""The plant, its controller, the bench and the test scheduler in one numba loop.

One call simulates a whole record at a fixed internal step (1 s). The energy bookkeeping
follows the paper's Eq. 1-2 with the flows of every node evaluated at the start of each
sub-step (explicit Euler), so the stored heat changes by exactly the sum of the recorded
flows: fuel heat + igniter = ash + CO + latent + chamber loss + flue-gas sensible +
casing loss + pipe loss + heat to water + storage change (to rounding).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hil_client.reality3._combustion import (
    CP_AIR,
    CP_FG,
    CP_VAP,
    DH_CO,
    DH_VAP,
    HHV_CARBON,
    RHO_AIR_N,
    RHO_H2O_N,
    air_min,
    co_ppm_model,
    flue_gas,
)
from hil_client.reality3._params import (
    A_DUCT,
    A_SP,
    AIRMIN_DOC,
    C1_LOAD,
    C1_MAX,
    C1_UNTIL,
    C2_AFTER,
    C_B,
    C_D,
    C_H,
    C_M,
    C_P,
    C_R,
    C_S,
    C_SP,
    C_W,
    CO_BASE,
    CP_W,
    CTRL_OFFSET,
    DT,
    DT_HOLD_EXIT,
    DT_REF,
    DT_RESTART,
    E_STAG,
    EPS_A,
    EPS_MIN,
    F_BC,
    FAC_A,
    FAC_B,
    FC,
    FC_BG,
    FC_EXP,
    FC_NOM,
    FH,
    FN,
    FO,
    FORCE_M,
    FORCE_P,
    FORCE_TIN,
    FORCE_TROOM,
    FS,
    G_AX,
    G_BR,
    G_C,
    G_DB,
    G_MW,
    G_SW,
    H_WELL_0,
    H_WELL_NOM,
    HHV,
    IGN_FAIL,
    K_AUGER,
    K_LAMBDA,
    K_MIX_FLOW,
    K_NAT,
    K_RAD,
    KP,
    KP_B,
    LAMBDA_MIN,
    LHV_AR_DOC,
    M_CHARGE,
    M_CHARGE2,
    M_CRIT,
    M_NOM,
    MOIST,
    N_DELAY,
    N_REC,
    N_SUB,
    N_UA,
    OFF_TIN,
    OFF_TOUT,
    P_AUGER_ON,
    P_EL_BASE,
    P_EL_CTRL,
    P_FAN_NOM,
    P_IGN,
    P_MAX,
    P_MIN,
    P_NOM,
    P_START,
    PH_COOLING_1,
    PH_COOLING_2,
    PH_PREHEAT,
    PH_START_UP,
    PH_TEST,
    PIPE_MODE,
    PREHEAT_HOLD,
    PREHEAT_LOAD,
    PREHEAT_MAX,
    PREHEAT_MIN,
    PREHEAT_TOL,
    Q_CMAX,
    Q_HMAX,
    R_AUGER_MAX,
    R_BED,
    R_BURNT,
    R_CO2_S,
    R_CO_S,
    R_DRY_NOM,
    R_ESTORE,
    R_FED,
    R_FIRE,
    R_IGN,
    R_LAMBDA,
    R_M,
    R_MSP,
    R_O2_S,
    R_O2_TRUE,
    R_ON,
    R_PEL,
    R_PHASE,
    R_QASH,
    R_QBC,
    R_QCHEM,
    R_QENV,
    R_QFG,
    R_QIGN,
    R_QLAT,
    R_QPIPE,
    R_QREL,
    R_QW,
    R_SEQ,
    R_STATE,
    R_TBW_S,
    R_TCTRL,
    R_TD,
    R_TEXIT,
    R_TFG,
    R_TFG_S,
    R_TH,
    R_TIN,
    R_TIN_S,
    R_TM,
    R_TOP,
    R_TOUT_S,
    R_TROOM,
    R_TW,
    R_VCUM,
    R_VEL,
    R_WG,
    SIGMA_D,
    ST_BURNOUT,
    ST_HOLD,
    ST_IGNITE,
    ST_MODULATE,
    ST_OFF,
    ST_PREPURGE,
    ST_RAMP,
    ST_RETRY_PURGE,
    STRAT_BETA,
    SU_MAX,
    SU_MIN,
    SU_RISE,
    SU_WINDOW,
    T_AUGER,
    T_CATCH,
    T_COLD,
    T_DET,
    T_FAIL,
    T_FLOOR_C1,
    T_HOLD_MIN,
    T_IGN_MAX,
    T_IGN_ON,
    T_INIT,
    T_INIT_BENCH,
    T_MIN_BURN,
    T_MIN_OFF,
    T_OFF,
    T_OFF_MAX,
    T_POST,
    T_PREHEAT,
    T_PREPURGE,
    T_PURGE_RETRY,
    T_RAMP,
    T_RET_SP,
    T_SET,
    TAU_BED,
    TAU_CO,
    TAU_CO2,
    TAU_CTRL,
    TAU_FAN,
    TAU_FG0,
    TAU_FLOW,
    TAU_LOSS,
    TAU_O2,
    TAU_TBW,
    TAU_TIN,
    TAU_TOUT,
    TAU_VALVE,
    TI,
    TI_B,
    UA_B,
    UA_ENV,
    UA_NOM,
    UA_P,
    UA_RG,
    V_IGN_FRAC,
    V_PIPE,
    V_POST_FRAC,
    V_PURGE_FRAC,
    V_REF,
    VALVE_DB,
    W_REF,
    X_COLD,
    X_DENS,
    X_FLOW,
    X_LAM,
    X_PRESS,
    X_TROOM,
    X_XAIR,
)

_K0 = 273.15


@njit(cache=True)
def _lag(a: float, y: float, x: float) -> float:
    return y + (x - y) * a


@njit(cache=True)
def _overlap(a0: float, a1: float, b0: float, b1: float) -> float:
    return max(0.0, min(a1, b1) - max(a0, b0))


# equal-probability classes of the laminar residence-time distribution in volume units,
# F(theta) = 1 - 1 / (4 theta^2) for theta >= 1/2 (Poiseuille flow, no diffusion)
_N_LAM = 8
_THETA = np.array([0.5 / math.sqrt(1.0 - (i + 0.5) / _N_LAM) for i in range(_N_LAM)])


@njit(cache=True)
def _laminar_pipe(
    rec: np.ndarray,
    k: int,
    vcum: float,
    t: float,
    dt: float,
    v_pipe: float,
    tau_loss: float,
    t_eq: float,
    t_now: float,
) -> float:
    """Water temperature at the end of a laminar exit pipe (flow-weighted over streamlines).

    Each streamline's parcel left the boiler when the cumulative volume was ``theta`` pipe
    volumes ago; it has relaxed towards ``t_eq`` for its age with time constant ``tau_loss``.
    """
    acc = 0.0
    for i in range(_N_LAM):
        target = vcum - _THETA[i] * v_pipe
        lo = 0
        hi = k
        if rec[0, R_VCUM] > target:
            j = 0
        else:
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if rec[mid, R_VCUM] <= target:
                    lo = mid
                else:
                    hi = mid
            j = lo
        if j >= k:
            temp = t_now
            age = 0.0
        else:
            temp = rec[j, R_TEXIT]
            age = t - j * dt
        acc += t_eq + (temp - t_eq) * math.exp(-age / tau_loss)
    return acc / _N_LAM


@njit(cache=True)
def run_kernel(
    p: np.ndarray,
    seq_dur: np.ndarray,
    seq_l0: np.ndarray,
    seq_l1: np.ndarray,
    exo: np.ndarray,
    rec: np.ndarray,
) -> tuple[int, float, float, float, float, float, int]:
    """Simulate until t4 (or the end of ``rec``); return (n, t0, t1, t2, t3, t4, starts)."""
    dt = p[DT]
    nsub = int(p[N_SUB])
    h = dt / nsub
    nmax = rec.shape[0]
    forced = p[FORCE_P] > 0.0
    pipe_mode = int(p[PIPE_MODE])
    cpw = p[CP_W] / 3600.0  # kJ/(K) per kg/h -> kW/K
    wd = p[MOIST] / (1.0 - p[MOIST])
    test_total = 0.0
    for i in range(seq_dur.shape[0]):
        test_total += seq_dur[i]
    # ---- plant state
    tm = p[T_INIT]
    tw = tm
    th = tm
    td = tm
    tsp = tm
    tr = tm
    tp = tm
    tb = p[T_INIT_BENCH]
    if forced:
        tb = p[FORCE_TIN]
    vcum = 0.0
    bed = 0.0
    fed = 0.0
    burnt = 0.0
    lit = False
    t_lit = 1e9
    # ---- sensors
    tin_s = tb
    tout_s = tw
    tbw_s = tw
    tfg_s = tw
    tctrl = tw
    twell = tw
    o2_f = 20.95
    co2_f = 0.04
    co_f = 0.0
    nd = max(int(p[N_DELAY]), 0)
    buf_o2 = np.full(nd + 1, 20.95)
    buf_co2 = np.full(nd + 1, 0.04)
    buf_co = np.zeros(nd + 1)
    # ---- bench
    m = p[M_NOM] * p[PREHEAT_LOAD] / 100.0
    if forced:
        m = p[FORCE_M]
    u_valve = 0.0
    u_target = 0.0
    i_bench = 0.0
    # ---- controller
    state = ST_OFF
    t_state = 0.0
    p_cmd = 0.0
    integ = 0.0
    attempt = 0
    charge_fed = 0.0
    charge_target = 0.0
    t_attempt = 0.0
    v_fan = 0.0
    starts = 0
    start_pending = False
    burning_time = 0.0
    if forced:
        state = ST_MODULATE
        lit = True
        t_lit = 1e6
        p_cmd = p[FORCE_P]
        v_fan = 0.0
    # ---- scheduler
    phase = PH_TEST if forced else PH_PREHEAT
    seq = 0
    t0 = -1.0
    t1 = -1.0
    t2 = -1.0
    t3 = -1.0
    t4 = -1.0
    hold_ok = 0.0
    enabled = forced
    a_tin = 1.0 - math.exp(-dt / p[TAU_TIN])
    a_tout = 1.0 - math.exp(-dt / p[TAU_TOUT])
    a_tbw = 1.0 - math.exp(-dt / p[TAU_TBW])
    a_ctrl = 1.0 - math.exp(-dt / p[TAU_CTRL])
    a_o2 = 1.0 - math.exp(-dt / p[TAU_O2])
    a_co2 = 1.0 - math.exp(-dt / p[TAU_CO2])
    a_co = 1.0 - math.exp(-dt / p[TAU_CO])
    a_fan = 1.0 - math.exp(-dt / p[TAU_FAN])
    a_flow = 1.0 - math.exp(-dt / p[TAU_FLOW])
    a_valve = 1.0 - math.exp(-dt / p[TAU_VALVE])
    win = int(p[SU_WINDOW] / dt)
    n = nmax
    for k in range(nmax):
        t = k * dt
        troom = p[FORCE_TROOM] if forced else exo[k, X_TROOM]
        x_air = exo[k, X_XAIR]
        press = exo[k, X_PRESS]
        dens = exo[k, X_DENS]
        lamf = exo[k, X_LAM]
        ripple = exo[k, X_FLOW]
        if k > 0:
            tout_read = rec[k - 1, R_TOUT_S] + p[OFF_TOUT]
            tin_read = rec[k - 1, R_TIN_S] + p[OFF_TIN]
        else:
            tout_read = tout_s + p[OFF_TOUT]
            tin_read = tin_s + p[OFF_TIN]
        # ================= scheduler (Section 2.3, Fig. 3)
        heater_ok = False
        ret_sp = p[T_RET_SP]
        msp = 0.0
        last = False
        if forced:
            msp = p[FORCE_M]
        elif phase == PH_PREHEAT:
            msp = p[M_NOM] * p[PREHEAT_LOAD] / 100.0
            # hold the mean of supply and return at the preheat temperature
            ret_sp = p[T_PREHEAT] + 0.5 * (tin_read - tout_read)
            heater_ok = True
            if (
                abs(tout_read - p[T_PREHEAT]) < p[PREHEAT_TOL]
                and abs(tin_read - p[T_PREHEAT]) < p[PREHEAT_TOL]
            ):
                hold_ok += dt
            else:
                hold_ok = 0.0
            if (hold_ok >= p[PREHEAT_HOLD] and t >= p[PREHEAT_MIN]) or t >= p[PREHEAT_MAX]:
                phase = PH_START_UP
                t0 = t
                enabled = True
                start_pending = True
        if not forced and phase == PH_START_UP:
            msp = p[M_NOM] * seq_l0[0] / 100.0
            if t0 < t:
                done = False
                if t - t0 >= p[SU_MIN] and burning_time >= p[SU_WINDOW] and k > win:
                    rise = rec[k - 1, R_TFG_S] - rec[k - 1 - win, R_TFG_S]
                    if rise < p[SU_RISE] * p[SU_WINDOW] / 60.0:
                        done = True
                if t - t0 >= p[SU_MAX]:
                    done = True
                if done:
                    phase = PH_TEST
                    t1 = t
        if not forced and phase == PH_TEST:
            tt = t - t1
            if tt >= test_total:
                phase = PH_COOLING_1
                t2 = t
                enabled = False
            else:
                acc = 0.0
                seq = seq_dur.shape[0] - 1
                for i in range(seq_dur.shape[0]):
                    if tt < acc + seq_dur[i]:
                        seq = i
                        break
                    acc += seq_dur[i]
                frac = (tt - acc) / max(seq_dur[seq], 1.0)
                load = seq_l0[seq] + (seq_l1[seq] - seq_l0[seq]) * frac
                msp = p[M_NOM] * load / 100.0
        if not forced and phase == PH_COOLING_1:
            msp = p[M_NOM] * p[C1_LOAD] / 100.0
            q_target = p[C1_LOAD] / 100.0 * p[P_NOM]
            ret_sp = tout_read - q_target / (max(m, 1.0) * cpw)
            ret_sp = min(max(ret_sp, p[T_FLOOR_C1]), p[T_RET_SP])
            if (tout_read <= p[C1_UNTIL] and t - t2 >= 10.0 * dt) or t - t2 >= p[C1_MAX]:
                phase = PH_COOLING_2
                t3 = t
        if not forced and phase == PH_COOLING_2:
            msp = 0.0
            if t - t2 >= p[C2_AFTER]:
                t4 = t
                last = True
        # ================= bench: flow and return conditioning
        if msp > 0.0:
            m = _lag(a_flow, m, msp * (1.0 + ripple))
        else:
            m = _lag(a_flow, m, 0.0)
            if m < 0.5:
                m = 0.0
        if forced:
            m = p[FORCE_M]
        q_c = 0.0
        q_h = 0.0
        if not forced:
            if m > 0.0:
                e_b = tin_read - ret_sp
                umin = -1.0 if heater_ok else 0.0
                u_cmd = p[KP_B] * (e_b + i_bench / p[TI_B])
                if u_cmd > 1.0:
                    u_cmd = 1.0
                    if e_b < 0.0:
                        i_bench += e_b * dt
                elif u_cmd < umin:
                    u_cmd = umin
                    if e_b > 0.0:
                        i_bench += e_b * dt
                else:
                    i_bench += e_b * dt
            else:
                u_cmd = 0.0
            if abs(u_cmd - u_target) > p[VALVE_DB]:
                u_target = u_cmd
            u_valve = _lag(a_valve, u_valve, u_target)
            cap = (tb - p[T_COLD]) / (p[T_RET_SP] - p[T_COLD])
            cap = min(max(cap, 0.0), 2.0) * (1.0 + exo[k, X_COLD])
            q_c = max(u_valve, 0.0) * p[Q_CMAX] * cap
            q_h = max(-u_valve, 0.0) * p[Q_HMAX]
        # ================= boiler controller (own design)
        tctrl_read = tctrl + p[CTRL_OFFSET]
        feed_rate = 0.0  # continuous feed [kg/h as received]
        auger_pulsed = False
        igniter = False
        v_sp = 0.0
        burnout = False
        if not forced:
            t_state += dt
            t_attempt += dt
            if lit:
                t_lit += dt
            if not enabled and (
                state == ST_PREPURGE
                or state == ST_IGNITE
                or state == ST_RETRY_PURGE
                or state == ST_RAMP
                or state == ST_HOLD
                or state == ST_MODULATE
            ):
                state = ST_BURNOUT
                t_state = 0.0
            if state == ST_OFF:
                if enabled and (
                    start_pending
                    or (t_state >= p[T_MIN_OFF] and tctrl_read <= p[T_SET] - p[DT_RESTART])
                    or (t_state >= p[T_OFF_MAX] and tctrl_read <= p[T_SET] - 10.0)
                ):
                    start_pending = False
                    state = ST_PREPURGE
                    t_state = 0.0
                    starts += 1
            elif state == ST_PREPURGE:
                if t_state >= p[T_PREPURGE]:
                    state = ST_IGNITE
                    t_state = 0.0
                    t_attempt = 0.0
                    attempt = 1
                    charge_fed = 0.0
                    charge_target = p[M_CHARGE]
            elif state == ST_RETRY_PURGE:
                if t_state >= p[T_PURGE_RETRY]:
                    state = ST_IGNITE
                    t_state = 0.0
                    t_attempt = 0.0
                    attempt += 1
                    charge_fed = 0.0
                    charge_target = p[M_CHARGE2]
            elif state == ST_IGNITE:
                if lit and t_lit >= p[T_DET]:
                    state = ST_RAMP
                    t_state = 0.0
                else:
                    limit = p[T_IGN_MAX]
                    if p[IGN_FAIL] > 0.0 and attempt == 1:
                        limit = p[T_FAIL]
                    if t_state >= limit and not lit:
                        state = ST_RETRY_PURGE
                        t_state = 0.0
            elif state == ST_RAMP:
                if t_state >= p[T_RAMP]:
                    state = ST_HOLD
                    t_state = 0.0
            elif state == ST_HOLD:
                if (tctrl_read >= p[T_SET] - p[DT_HOLD_EXIT] and t_state >= 60.0) or t_lit >= p[
                    T_HOLD_MIN
                ]:
                    state = ST_MODULATE
                    t_state = 0.0
                    integ = p[P_START] - p[KP] * (p[T_SET] - tctrl_read)
            elif state == ST_BURNOUT and t_state >= p[T_POST] and bed < 1e-5:
                state = ST_OFF
                t_state = 0.0
            if (state == ST_RAMP or state == ST_HOLD or state == ST_MODULATE) and (
                tctrl_read >= p[T_OFF] and (t_lit >= p[T_MIN_BURN] or tctrl_read >= p[T_OFF] + 3.0)
            ):
                state = ST_BURNOUT
                t_state = 0.0
            # actions
            if state == ST_PREPURGE or state == ST_RETRY_PURGE:
                v_sp = p[V_PURGE_FRAC] * p[V_REF]
            elif state == ST_IGNITE:
                igniter = True
                v_sp = p[V_IGN_FRAC] * p[V_REF]
                feed_rate = p[R_IGN] if charge_fed < charge_target else p[R_TOP]
            elif state == ST_RAMP or state == ST_HOLD or state == ST_MODULATE:
                if state == ST_RAMP:
                    p_cmd = p[P_MIN] + (p[P_START] - p[P_MIN]) * min(t_state / p[T_RAMP], 1.0)
                elif state == ST_HOLD:
                    p_cmd = p[P_START]
                else:
                    e = p[T_SET] - tctrl_read
                    u = p[KP] * e + integ
                    if u > p[P_MAX]:
                        u = p[P_MAX]
                        if e < 0.0:
                            integ += p[KP] / p[TI] * e * dt
                    elif u < p[P_MIN]:
                        u = p[P_MIN]
                        if e > 0.0:
                            integ += p[KP] / p[TI] * e * dt
                    else:
                        integ += p[KP] / p[TI] * e * dt
                    p_cmd = u
                auger_pulsed = True
                igniter = t_attempt < p[T_IGN_ON]
            elif state == ST_BURNOUT:
                v_sp = p[V_POST_FRAC] * p[V_REF]
                burnout = True
            if state == ST_OFF or state == ST_BURNOUT:
                p_cmd = 0.0
            if state == ST_RAMP or state == ST_HOLD or state == ST_MODULATE:
                burning_time += dt
            else:
                burning_time = 0.0
        # feed this step [kg as received]
        r_cmd = p_cmd * 3600.0 / p[LHV_AR_DOC]  # what the controller believes it feeds
        auger_frac = 0.0
        if forced:
            fed_step = r_cmd * p[K_AUGER] * dt / 3600.0
            auger_frac = 1.0
        elif auger_pulsed:
            d = min(r_cmd * p[K_AUGER] / p[R_AUGER_MAX], 1.0)
            period = p[T_AUGER]
            ph0 = t - period * math.floor(t / period)
            on = _overlap(ph0, ph0 + dt, 0.0, d * period) + _overlap(
                ph0, ph0 + dt, period, period + d * period
            )
            auger_frac = on / dt
            fed_step = p[R_AUGER_MAX] * dens * on / 3600.0
        else:
            fed_step = feed_rate * dens * dt / 3600.0
            if feed_rate > 0.0:
                auger_frac = feed_rate / p[R_AUGER_MAX]
            charge_fed += fed_step
        if auger_pulsed or forced:
            m_dry_b = r_cmd * (1.0 - p[MOIST])
            lam_t = max(p[LAMBDA_MIN], p[FAC_A] + p[FAC_B] * m_dry_b) * p[K_LAMBDA]
            if not forced:
                lam_t *= lamf
            v_sp = lam_t * p[AIRMIN_DOC] * m_dry_b
        fed += fed_step
        bed += fed_step
        # fan and natural draught
        v_fan = v_sp if forced else _lag(a_fan, v_fan, v_sp)
        v_nat = p[K_NAT] * math.sqrt(max(tm - troom, 0.0))
        v_air = max(v_fan, v_nat)
        # ================= bed
        fc = p[FC_BG]
        if not lit and state == ST_IGNITE:
            can = t_state >= p[T_CATCH] and bed >= p[M_CRIT]
            if p[IGN_FAIL] > 0.0 and attempt == 1:
                can = False
            if can:
                lit = True
                t_lit = 0.0
        burn_step = 0.0
        if lit:
            amin_e = air_min(p[FC], p[FH], p[FO], p[FS], p[FC_BG])
            r_air_max = v_air / (amin_e * 1.05) / (1.0 - p[MOIST])
            r_ar = min(bed / p[TAU_BED] * 3600.0, r_air_max)
            if forced:
                r_ar = fed_step * 3600.0 / dt
            burn_step = min(r_ar * dt / 3600.0, bed)
            bed -= burn_step
            burnt += burn_step
            if bed < 1e-6 and (state == ST_BURNOUT or state == ST_OFF):
                lit = False
                t_lit = 1e9
        r_dry = burn_step * 3600.0 / dt * (1.0 - p[MOIST])
        if r_dry > 0.0 and p[FC_NOM] > 0.0:
            fc += p[FC_NOM] * (r_dry / p[R_DRY_NOM]) ** p[FC_EXP]
        fc = min(fc, 0.5)
        # ================= combustion (Eq. 3-6, 9)
        amin_a = air_min(p[FC], p[FH], p[FO], p[FS], fc)
        lam = v_air / (amin_a * r_dry) if r_dry > 1e-9 else np.nan
        co_t = 0.0
        if r_dry > 1e-9:
            co_t = co_ppm_model(lam, p[CO_BASE], t_lit, burnout)
        v_dry, o2, co2, m_fg, mvf, mva, m_co, ppm = flue_gas(
            r_dry, v_air, x_air, p[FC], p[FH], p[FO], p[FN], p[FS], wd, fc, co_t
        )
        w_g = max((m_fg * CP_FG + (mvf + mva) * CP_VAP) / 3600.0, 1e-8)
        w_air = v_air * RHO_AIR_N * (CP_AIR + x_air * CP_VAP) / 3600.0
        q_rel = r_dry * p[HHV] / 3600.0
        q_ash = r_dry * p[FC] * fc * HHV_CARBON / 3600.0
        q_chem = m_co * DH_CO / 3600.0
        q_lat = mvf * DH_VAP / 3600.0
        q_bc = p[F_BC] * q_rel
        q_ign = p[P_IGN] if igniter else 0.0
        q_av0 = q_rel - q_ash - q_chem - q_lat - q_bc + q_ign
        ua = p[UA_NOM] * (w_g / p[W_REF]) ** p[N_UA]
        eps = 1.0 - math.exp(-min(ua / w_g, 50.0))
        eps_g = 0.0
        if p[C_R] > 0.0:
            eps_g = 1.0 - math.exp(-min(p[UA_RG] * (w_g / p[W_REF]) ** p[N_UA] / w_g, 50.0))
        a_sp = p[A_SP] if p[C_SP] > 0.0 else 0.0
        a_d = p[SIGMA_D] if p[C_D] > 0.0 else 0.0
        # ================= thermal sub-steps
        s_fg = 0.0
        s_env = 0.0
        s_pipe = 0.0
        s_w = 0.0
        tfg = tm
        texit = tw
        for _j in range(nsub):
            tin = tb
            q_ra = 0.0
            if p[C_R] > 0.0:
                q_ra = w_air * p[EPS_A] * (tr - troom)
            q_av = q_av0 + q_ra
            q_rad = 0.0
            if p[C_H] > 0.0 and lit and r_dry > 1e-9:
                tfl = troom + q_av / w_g
                q_rad = p[K_RAD] * ((tfl + _K0) ** 4 - (th + _K0) ** 4)
                q_rad = min(max(q_rad, 0.0), 0.6 * max(q_av, 0.0))
            q_gas = q_av - q_rad
            tad = troom + q_gas / w_g
            q_gm = eps * w_g * (1.0 - a_sp - a_d) * (tad - tm)
            q_gsp = eps * w_g * a_sp * (tad - tsp)
            q_gd = eps * w_g * a_d * (tad - td)
            tfg1 = tad - (q_gm + q_gsp + q_gd) / w_g
            q_gr = 0.0
            if p[C_R] > 0.0:
                q_gr = w_g * eps_g * (tfg1 - tr)
            tfg = tfg1 - q_gr / w_g
            q_fg = w_g * (tfg - troom)
            q_spm = p[G_SW] * (tsp - tm)
            q_mw = p[G_MW] * (tm - tw)
            q_hw = p[G_C] * (th - tw)
            q_env = p[UA_ENV] * (tw - troom)
            q_mix = 0.0  # jacket pocket -> main water (buoyant plume, forced mixing)
            if p[C_D] > 0.0:
                d_pm = td - tw
                g_pm = p[G_DB] * (1.0 + p[K_MIX_FLOW] * m / p[M_NOM])
                g_pm *= p[EPS_MIN] + (max(d_pm, 0.0) / p[DT_REF]) ** (1.0 / 3.0)
                q_mix = g_pm * d_pm
            m_b = m
            adv_p = 0.0
            q_pipe = 0.0
            q_ax = 0.0
            if pipe_mode == 1:
                q_ax = p[G_AX] * (tp - tw)
            if pipe_mode == 1:
                adv_p = m * cpw * (tw - tp)
                q_pipe = p[UA_P] * (tp - troom)
                texit = tp
            else:
                texit = tw
            adv_w = m_b * cpw * (tin - tw)
            q_w = m * cpw * (texit - tin)
            # derivatives
            d_tm = (q_gm + q_spm - q_mw) / p[C_M]
            d_tw = (q_mw + q_hw + adv_w - q_env + q_mix + q_ax) / p[C_W]
            if p[C_H] > 0.0:
                th += h * (q_rad - q_hw) / p[C_H]
            if p[C_D] > 0.0:
                td += h * (q_gd - q_mix) / p[C_D]
            if p[C_SP] > 0.0:
                tsp += h * (q_gsp - q_spm) / p[C_SP]
            if p[C_R] > 0.0:
                tr += h * (q_gr - q_ra) / p[C_R]
            if pipe_mode == 1:
                tp += h * (adv_p - q_pipe - q_ax) / p[C_P]
            if not forced:
                d_tb = (m * cpw * (texit - tb) - q_c + q_h - p[UA_B] * (tb - troom)) / p[C_B]
                tb += h * d_tb
            tm += h * d_tm
            tw += h * d_tw
            s_fg += q_fg
            s_env += q_env
            s_pipe += q_pipe
            s_w += q_w
        # exit temperature after the step (for sensors)
        texit = tp if pipe_mode == 1 else tw
        e_store = p[C_M] * tm + p[C_W] * tw
        if p[C_H] > 0.0:
            e_store += p[C_H] * th
        if p[C_D] > 0.0:
            e_store += p[C_D] * td
        if p[C_SP] > 0.0:
            e_store += p[C_SP] * tsp
        if p[C_R] > 0.0:
            e_store += p[C_R] * tr
        if pipe_mode == 1:
            e_store += p[C_P] * tp
        # ================= sensors (no offsets or noise here)
        tin_s = _lag(a_tin, tin_s, tb)
        if pipe_mode == 1:
            hwell = p[H_WELL_0] + p[H_WELL_NOM] * (m / p[M_NOM]) ** 0.8
            g = hwell + p[G_BR]
            target = (hwell * tp + p[G_BR] * troom) / g
            twell = _lag(1.0 - math.exp(-dt * g / p[C_S]), twell, target)
            tout_s = twell
        elif pipe_mode == 2:
            vcum += m * dt / 3600.0
            rec[k, R_VCUM] = vcum
            rec[k, R_TEXIT] = texit
            t_eq = troom + (1.0 - p[E_STAG]) * (texit - troom)
            tpipe = _laminar_pipe(rec, k, vcum, t, dt, p[V_PIPE], p[TAU_LOSS], t_eq, texit)
            tout_s = _lag(a_tout, tout_s, tpipe)
        else:
            tout_s = _lag(a_tout, tout_s, texit)
        teff = tw
        tbw_t = teff + p[STRAT_BETA] * min(m / p[M_NOM], 1.5) * (teff - tb)
        tbw_s = _lag(a_tbw, tbw_s, tbw_t)
        tctrl = _lag(a_ctrl, tctrl, tw)
        tau_fg = p[TAU_FG0] * math.sqrt(p[W_REF] / max(w_g, 0.05 * p[W_REF]))
        tau_fg = min(tau_fg, 600.0)
        tfg_s = _lag(1.0 - math.exp(-dt / tau_fg), tfg_s, tfg)
        slot = k % (nd + 1)
        buf_o2[slot] = o2
        buf_co2[slot] = co2
        buf_co[slot] = ppm
        old = (k - nd) % (nd + 1) if k >= nd else -1
        if old >= 0:
            o2_f = _lag(a_o2, o2_f, buf_o2[old])
            co2_f = _lag(a_co2, co2_f, buf_co2[old])
            co_f = _lag(a_co, co_f, buf_co[old])
        v_wet = v_dry + (mvf + mva) / RHO_H2O_N
        vel = v_wet / 3600.0 * (tfg + _K0) / _K0 * 1013.25 / press / p[A_DUCT]
        pel = p[P_EL_BASE] + p[P_FAN_NOM] * (v_fan / p[V_REF]) ** 2.5
        if state != ST_OFF:
            pel += p[P_EL_CTRL]
        pel += p[P_AUGER_ON] * min(auger_frac, 1.0) + 1000.0 * q_ign
        # ================= record
        rec[k, R_TIN_S] = tin_s
        rec[k, R_TOUT_S] = tout_s
        rec[k, R_TBW_S] = tbw_s
        rec[k, R_TFG_S] = tfg_s
        rec[k, R_O2_S] = o2_f
        rec[k, R_CO2_S] = co2_f
        rec[k, R_CO_S] = co_f
        rec[k, R_VEL] = vel
        rec[k, R_FED] = fed
        rec[k, R_PEL] = pel
        rec[k, R_M] = m
        rec[k, R_MSP] = msp
        on_flag = (
            state == ST_PREPURGE
            or state == ST_IGNITE
            or state == ST_RETRY_PURGE
            or state == ST_RAMP
            or state == ST_HOLD
            or state == ST_MODULATE
        )
        rec[k, R_ON] = 1.0 if on_flag else 0.0
        rec[k, R_PHASE] = phase
        rec[k, R_SEQ] = seq if phase == PH_TEST else -1
        rec[k, R_TROOM] = troom
        rec[k, R_TW] = tw
        rec[k, R_TEXIT] = texit
        rec[k, R_TIN] = tb
        rec[k, R_TFG] = tfg
        rec[k, R_QREL] = q_rel
        rec[k, R_QIGN] = q_ign
        rec[k, R_QASH] = q_ash
        rec[k, R_QCHEM] = q_chem
        rec[k, R_QLAT] = q_lat
        rec[k, R_QBC] = q_bc
        rec[k, R_QFG] = s_fg / nsub
        rec[k, R_QENV] = s_env / nsub
        rec[k, R_QPIPE] = s_pipe / nsub
        rec[k, R_QW] = s_w / nsub
        rec[k, R_ESTORE] = e_store
        rec[k, R_BED] = bed
        rec[k, R_BURNT] = burnt
        rec[k, R_STATE] = state
        rec[k, R_LAMBDA] = lam
        rec[k, R_O2_TRUE] = o2
        rec[k, R_TM] = tm
        rec[k, R_TD] = td
        rec[k, R_TH] = th
        rec[k, R_TCTRL] = tctrl_read
        rec[k, R_FIRE] = p_cmd
        rec[k, R_WG] = w_g
        rec[k, R_VCUM] = vcum
        if last:
            n = k + 1
            break
    if t4 < 0.0:
        t4 = (n - 1) * dt
    return n, t0, t1, t2, t3, t4, starts


def new_record(nmax: int) -> np.ndarray:
    """A record array for ``nmax`` steps."""
    return np.zeros((nmax, N_REC))


__all__ = ["new_record", "run_kernel"]
