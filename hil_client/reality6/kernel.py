"""Per-second kernel of the reality-6 plant: burner controller, bed, boiler body, bench.

Physics (Carlon et al. 2015, Type 869), written as explicit 1-s balances:

* Eq. 1: Q_fuel + Q_el,ign = Q_ash + Q_fg,lat + Q_fg,sens + Q_fg,chem + Q_hx (Q_bc,amb = 0).
* Eq. 2: Q_hx = Q_w,out + Q_amb + Q_Mtherm, with Q_Mtherm the change of the heat stored in the
  water node, the optional metal node (body_heat_diffusion forms) and the flue-side store.
* Eq. 3-6 and 9: see combustion.py.  Eq. 7: Q_w,out = m_w * cp_w * (T_w,out - T_w,in).
* Eq. 8 is replaced by this boiler's own exchanger: T_fg,ss = T_water + dT_fg * q^n * (1 + f t),
  a load exponent n (the exchanger's NTU rises as the gas flow falls) and slow fouling f.
* Eq. 10: Q_amb = UA * (T_boiler - T_room), UA_on while a flame burns, UA_off otherwise, plus a
  fan-driven purge term while the fan runs without a flame (Eq. 14-16: Q_air).

What differs from Type 869 (the plant's own "real boiler" features, drawn per case):
* a burner state machine: pre-purge, ignition (an ignition charge fed by the auger, an electric
  igniter, light-off after a cold or hot-bed delay, top-up feeds while waiting), stabilisation at
  part fire, a start mode at P_start, PI modulation in 5-12 fixed stages (with hysteresis)
  and a slew limit on the controller's own
  (stratified, offset) body sensor, minimum burn and minimum off timers, burn-out and post-purge;
* pulse-pause auger feeding into a burning bed (first-order burn-off, capped by the air supply);
  the auger's fill degree wanders (AR(1): pellet bridging, fines), so the heat output
  fluctuates around what the controller asks for;
* a bench circuit (its own water volume and losses) whose return conditioning is a PI cooler of
  limited capacity (about the imposed load) with an actuator lag, and a preheater.

Assumptions: time step 1 s, explicit Euler for every store so that each 1-s step closes the
energy balance exactly (the tests check it); temperatures in C, powers in kW, masses in kg.
"""

from __future__ import annotations

import math

import numpy as np

try:  # numba is optional: without it the kernel runs as plain Python (slow)
    from numba import njit
except ImportError:  # pragma: no cover

    def njit(*args, **kwargs):
        if args and callable(args[0]):
            return args[0]
        return lambda f: f


# ---- parameter vector indices -------------------------------------------------------------
I_P_NOM = 0  # kW nominal output
I_P_MAX = 1  # kW net firing
I_P_MIN = 2
I_P_START = 3
I_HHV_TRUE = 4  # kJ/kg dry, the real lot
I_W_TRUE = 5  # moisture as received, the real lot
I_SIFT_FRAC = 6  # fed fuel falling unburnt through the grate
I_KG_PER_KJ_CMD = 7  # kg as-received per kJ of commanded net firing (auger calibration)
I_MFG0 = 8
I_MFG1 = 9
I_VD0 = 10
I_AIR_MIN = 11
I_V_CO2 = 12
I_VAPOUR = 13
I_CARBON = 14
I_FAC_A = 15
I_FAC_B = 16
I_LAMBDA_FAC = 17
I_LAMBDA_NOISE = 18
I_AIR_FAN_MIN = 19  # m3/s purge / minimum fan air
I_AIR_NATURAL = 20  # m3/s natural draught air, fan off
I_CO_BASE = 21
I_CO_LOW = 22
I_CO_PYRO = 23
I_DT_FG = 24  # K above the water node at nominal firing
I_FG_EXP = 25
I_FOUL_PER_H = 26
I_TAU_FG_BG = 27
I_C_FG_BG = 28
I_FG_MODE = 29  # 0 none, 1 constant extra lag, 2 gas-flow dependent extra lag
I_FG_TAU_EFF = 30
I_FG_C_EFF = 31
I_C_TOTAL = 32  # kJ/K structure + water
I_UA_ON = 33  # kW/K
I_UA_OFF = 34
I_UA_PURGE = 35
I_BODY_MODE = 36  # 0 one node, 1 series metal node, 2 parallel dry plate
I_C_METAL = 37
I_UA_METAL = 38
I_PLATE_FRAC = 39
I_UA_PLATE_ROOM = 40
I_TAU_BED = 41
I_BURN_CAP = 42  # kg/s as received, air-limited
I_M_IGN = 43
I_AUGER_RATE = 44  # kg/s as received while the auger runs
I_AUGER_CYCLE = 45
I_T_PREPURGE = 46
I_T_LIGHT_COLD = 47
I_T_LIGHT_HOT = 48
I_T_HOT_WINDOW = 49
I_LIGHT_EXTRA_COLD = 50
I_LIGHT_EXTRA_HOT = 51
I_TOPUP_PERIOD = 52
I_TOPUP_MASS = 53
I_T_STAB = 54
I_STAB_FRAC = 55
I_T_START_FULL = 56
I_T_IGN_POST = 57
I_P_IGN_W = 58
I_IGN_HEAT_FRAC = 59
I_T_POSTPURGE = 60
I_BED_OUT = 61
I_FLUCT_SIGMA = 62
I_FLUCT_TAU = 63
I_T_SET = 64
I_CTRL_OFFSET = 65
I_CTRL_STRAT = 66
I_KP = 67  # kW/K
I_TI = 68
I_SLEW = 69  # kW/s
I_T_OFF = 70
I_T_ON = 71
I_T_MIN_BURN = 72
I_T_MIN_OFF = 73
I_T_SAFETY = 74
I_FLOW_NOM = 75  # kg/h at 100 % load
I_TAU_FLOW = 76
I_C_CIRC = 77
I_UA_CIRC = 78
I_BENCH_KP = 79  # kW/K
I_BENCH_TI = 80
I_BENCH_TAU_ACT = 81
I_CAP_MARGIN = 82
I_HEAT_MAX = 83
I_PRE_T = 84
I_PRE_TOL = 85
I_PRE_HOLD = 86
I_PRE_LOAD = 87
I_PRE_MAX = 88
I_RET_SET = 89
I_SU_WINDOW = 90
I_SU_RISE = 91  # K/min
I_SU_MIN = 92
I_SU_MAX = 93
I_C1_LOAD = 94
I_C1_RET = 95
I_C1_UNTIL = 96
I_C1_MAX = 97
I_C1_MARGIN = 98
I_C2_UNTIL = 99
I_T_INIT = 100
I_OUT_OFFSET = 101  # bench's own forward-sensor offset (operator decisions)
I_IN_OFFSET = 102
I_P_EL_MIN = 103
I_P_EL_MAX = 104
I_P_EL_OFF = 105
I_AUGER_W = 106
I_Q_FUEL_NOM = 107  # kW HHV basis at nominal firing
I_GAS_NOM = 108  # kg/s wet gas at nominal firing
I_FG_OFF_FRAC = 109  # idle flue-side temperature: T_w - frac * (T_w - T_room)
I_N_STAGES = 110  # modulation stages between P_min and P_max (0: continuous)
N_PAR = 111

# ---- output columns -----------------------------------------------------------------------
OUT_NAMES = (
    "phase_code",
    "seq_index",
    "load",
    "flow_set_kg_h",
    "flow_kg_h",
    "t_in_C",
    "t_water_C",
    "t_metal_C",
    "t_fg_C",
    "q_fuel_kW",
    "q_el_in_kW",
    "q_ash_kW",
    "q_lat_kW",
    "q_sens_kW",
    "q_chem_kW",
    "q_water_kW",
    "q_amb_kW",
    "q_in_water_kW",
    "q_bench_kW",
    "e_store_kJ",
    "feed_kg",
    "burn_kg",
    "sift_kg",
    "bed_kg",
    "excess_air",
    "co_ppm",
    "o2_pct",
    "co2_pct",
    "gas_m3_s",
    "state",
    "boiler_on",
    "auger_on",
    "igniter_on",
    "fan_on",
    "lit",
    "p_target_kW",
    "p_el_W",
    "t_ctrl_C",
)
(
    O_PHASE,
    O_SEQ,
    O_LOAD,
    O_FLOW_SET,
    O_FLOW,
    O_T_IN,
    O_T_W,
    O_T_M,
    O_T_FG,
    O_Q_FUEL,
    O_Q_EL,
    O_Q_ASH,
    O_Q_LAT,
    O_Q_SENS,
    O_Q_CHEM,
    O_Q_W,
    O_Q_AMB,
    O_Q_IN_W,
    O_Q_BENCH,
    O_E_STORE,
    O_FEED,
    O_BURN,
    O_SIFT,
    O_BED,
    O_LAMBDA,
    O_CO,
    O_O2,
    O_CO2,
    O_GAS,
    O_STATE,
    O_BOILER_ON,
    O_AUGER,
    O_IGNITER,
    O_FAN,
    O_LIT,
    O_P_TARGET,
    O_P_EL,
    O_T_CTRL,
) = range(len(OUT_NAMES))
N_OUT = len(OUT_NAMES)

# burner states
S_OFF = 0
S_PREPURGE = 1
S_IGNITION = 2
S_STABILISE = 3
S_RUN = 4
S_BURNOUT = 5

# bench phases
PH_PREHEAT = 0
PH_STARTUP = 1
PH_TEST = 2
PH_COOL1 = 3
PH_COOL2 = 4
PHASE_NAMES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")

CP_W = 4.186
DH_VAP = 2442.0
DH_CO = 10100.0
CP_FG = 1.04
CP_VAP = 1.87
RHO_CO = 1.25


@njit(cache=True)
def _clip(x, lo, hi):
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@njit(cache=True)
def run_kernel(par, seq_start, seq_dur, seq_a, seq_b, room_temp, normals):
    """Simulate until t4 (or the end of `room_temp`); returns (out[n, N_OUT], times[5])."""
    n_max = room_temp.shape[0]
    out = np.full((n_max, N_OUT), np.nan)
    times = np.full(5, -1.0)  # t0 .. t4 in s
    dt = 1.0
    n_seq = seq_start.shape[0]
    test_total = seq_start[n_seq - 1] + seq_dur[n_seq - 1]
    p_nom = par[I_P_NOM]
    p_max = par[I_P_MAX]
    p_min = par[I_P_MIN]
    flow_nom = par[I_FLOW_NOM]
    body_mode = int(par[I_BODY_MODE])
    fg_mode = int(par[I_FG_MODE])
    c_metal = par[I_C_METAL] if body_mode > 0 else 0.0
    c_water = par[I_C_TOTAL] - c_metal
    c_st = par[I_C_FG_BG] + (par[I_FG_C_EFF] if fg_mode > 0 else 0.0)
    w_true = par[I_W_TRUE]
    fl_a = math.exp(-dt / par[I_FLUCT_TAU])
    fl_b = par[I_FLUCT_SIGMA] * math.sqrt(1.0 - fl_a * fl_a)

    # states
    t_w = par[I_T_INIT]
    t_c = par[I_T_INIT]
    t_m = par[I_T_INIT]
    t_fg = par[I_T_INIT] - par[I_FG_OFF_FRAC] * (par[I_T_INIT] - room_temp[0])
    flow = flow_nom * par[I_PRE_LOAD]
    m_bed = 0.0
    lit = False
    xi = 0.0
    lam_dev = 0.0
    phase = PH_PREHEAT
    hold = 0.0
    bench_int = 0.0
    q_bench = 0.0
    state = S_OFF
    t_state = 0.0
    since_out = 1.0e9
    off_time = 1.0e9
    burn_time = 0.0
    ign_fed = 0.0
    light_needed = 0.0
    topup_clock = 0.0
    igniter_left = 0.0
    p_target = 0.0
    integ = 0.0
    start_mode = False
    stage_p = 0.0
    cyc_t = 0.0
    cyc_on = 0.0
    postpurge_left = -1.0
    first_light = -1.0
    q_in_w_prev = 0.0
    t0 = -1.0
    t1 = -1.0
    t2 = -1.0
    t3 = -1.0
    n = n_max
    for k in range(n_max):
        t = k * dt
        t_room = room_temp[k]
        # ---------------- bench protocol (operator decisions at the start of the step) ------
        t_out_dec = t_w + par[I_OUT_OFFSET]
        t_in_dec = t_c + par[I_IN_OFFSET]
        if phase == PH_PREHEAT:
            if (
                abs(t_out_dec - par[I_PRE_T]) <= par[I_PRE_TOL]
                and abs(t_in_dec - par[I_PRE_T]) <= par[I_PRE_TOL]
            ):
                hold += dt
            else:
                hold = 0.0
            if hold >= par[I_PRE_HOLD] or t >= par[I_PRE_MAX]:
                phase = PH_STARTUP
                t0 = t
                bench_int = 0.0
        elif phase == PH_STARTUP:
            w = int(par[I_SU_WINDOW])
            el = t - t0
            done = False
            if el >= par[I_SU_MIN] and first_light >= 0.0 and t - first_light >= w:
                rise = t_fg - out[k - w, O_T_FG]
                if rise < par[I_SU_RISE] * w / 60.0:
                    done = True
            if el >= par[I_SU_MAX]:
                done = True
            if done:
                phase = PH_TEST
                t1 = t
        elif phase == PH_TEST:
            if t - t1 >= test_total:
                phase = PH_COOL1
                t2 = t
        elif phase == PH_COOL1:
            if t_out_dec <= par[I_C1_UNTIL] or t - t2 >= par[I_C1_MAX]:
                phase = PH_COOL2
                t3 = t
        elif phase == PH_COOL2 and t - t2 >= par[I_C2_UNTIL]:
            n = k
            break

        seq_idx = -1
        load = 0.0
        if phase == PH_PREHEAT:
            load = par[I_PRE_LOAD]
            ret_set = par[I_PRE_T]
            cap_hi = 0.2 * p_nom
            cap_lo = -par[I_HEAT_MAX]
            enable = False
        elif phase == PH_STARTUP:
            load = seq_a[0]
            ret_set = par[I_RET_SET]
            cap_hi = load * p_nom * par[I_CAP_MARGIN]
            cap_lo = 0.0
            enable = True
        elif phase == PH_TEST:
            tt = t - t1
            seq_idx = n_seq - 1
            for i in range(n_seq):
                if tt < seq_start[i] + seq_dur[i]:
                    seq_idx = i
                    break
            frac = _clip((tt - seq_start[seq_idx]) / seq_dur[seq_idx], 0.0, 1.0)
            load = seq_a[seq_idx] + (seq_b[seq_idx] - seq_a[seq_idx]) * frac
            ret_set = par[I_RET_SET]
            cap_hi = load * p_nom * par[I_CAP_MARGIN]
            cap_lo = 0.0
            enable = True
        elif phase == PH_COOL1:
            load = par[I_C1_LOAD]
            ret_set = par[I_C1_RET]
            cap_hi = load * p_nom * par[I_C1_MARGIN]
            cap_lo = 0.0
            enable = False
        else:
            load = 0.0
            ret_set = par[I_C1_RET]
            cap_hi = 0.0
            cap_lo = 0.0
            enable = False
        flow_set = load * flow_nom

        # ---------------- pump / flow ---------------------------------------------------------
        if phase == PH_COOL2:
            flow += (0.0 - flow) * (1.0 - math.exp(-dt / 3.0))
            if flow < 0.5:
                flow = 0.0
        else:
            flow += (flow_set - flow) * (1.0 - math.exp(-dt / par[I_TAU_FLOW]))

        # ---------------- bench return conditioning (PI with lagged actuator) -----------------
        err_b = t_in_dec - ret_set
        kp_b = par[I_BENCH_KP]
        bench_int += kp_b / par[I_BENCH_TI] * err_b * dt
        bench_int = _clip(bench_int, cap_lo - kp_b * err_b, cap_hi - kp_b * err_b)
        cmd_b = _clip(kp_b * err_b + bench_int, cap_lo, cap_hi)
        q_bench += (cmd_b - q_bench) * (1.0 - math.exp(-dt / par[I_BENCH_TAU_ACT]))

        # ---------------- burner controller ---------------------------------------------------
        # the controller's body sensor: stratified while the flame burns
        strat = par[I_CTRL_STRAT] * (q_in_w_prev / p_nom - 1.0) if lit else 0.0
        t_ctrl = t_w + par[I_CTRL_OFFSET] + strat
        t_state += dt
        off_time += dt
        if not enable and (
            state == S_PREPURGE or state == S_IGNITION or state == S_STABILISE or state == S_RUN
        ):
            state = S_BURNOUT
            t_state = 0.0
            off_time = 0.0
            postpurge_left = -1.0
        if state == S_OFF:
            if enable and t_ctrl <= par[I_T_ON] and off_time >= par[I_T_MIN_OFF]:
                state = S_PREPURGE
                t_state = 0.0
        elif state == S_PREPURGE:
            if t_state >= par[I_T_PREPURGE]:
                state = S_IGNITION
                t_state = 0.0
                ign_fed = 0.0
                topup_clock = 0.0
                if since_out < par[I_T_HOT_WINDOW]:
                    light_needed = par[I_T_LIGHT_HOT] + par[I_LIGHT_EXTRA_HOT]
                else:
                    light_needed = par[I_T_LIGHT_COLD] + par[I_LIGHT_EXTRA_COLD]
                igniter_left = 1.0e9
        elif state == S_IGNITION:
            if t_state >= light_needed:
                lit = True
                if first_light < 0.0:
                    first_light = t
                burn_time = 0.0
                state = S_STABILISE
                t_state = 0.0
                igniter_left = par[I_T_IGN_POST]
                p_target = par[I_STAB_FRAC] * par[I_P_START]
                cyc_t = 1.0e9
        elif state == S_STABILISE:
            if t_state >= par[I_T_STAB]:
                state = S_RUN
                t_state = 0.0
                start_mode = True
        elif state == S_RUN:
            if start_mode:
                p_target = par[I_P_START]
                if burn_time >= par[I_T_START_FULL] or t_ctrl >= par[I_T_SET] - 1.0:
                    start_mode = False
                    integ = _clip(p_target, p_min, p_max)
                    stage_p = integ
            if not start_mode:
                err = par[I_T_SET] - t_ctrl
                kp = par[I_KP]
                integ += kp / par[I_TI] * err * dt
                integ = _clip(integ, p_min - kp * err, p_max - kp * err)
                u = _clip(kp * err + integ, p_min, p_max)
                if par[I_N_STAGES] > 0.0:  # staged modulation with hysteresis
                    step = (p_max - p_min) / par[I_N_STAGES]
                    if abs(u - stage_p) > 0.6 * step:
                        stage_p = p_min + round((u - p_min) / step) * step
                    u = stage_p
                p_target += _clip(u - p_target, -par[I_SLEW] * dt, par[I_SLEW] * dt)
            if (t_ctrl >= par[I_T_OFF] and burn_time >= par[I_T_MIN_BURN]) or t_ctrl >= par[
                I_T_SAFETY
            ]:
                state = S_BURNOUT
                t_state = 0.0
                off_time = 0.0
                postpurge_left = -1.0
        elif state == S_BURNOUT:
            if postpurge_left < 0.0 and not lit:
                postpurge_left = par[I_T_POSTPURGE]
            if postpurge_left >= 0.0:
                postpurge_left -= dt
                if postpurge_left <= 0.0:
                    state = S_OFF
                    t_state = 0.0
                    postpurge_left = -1.0
        igniter_on = state == S_IGNITION or (igniter_left > 0.0 and state != S_OFF)
        if state != S_IGNITION:
            igniter_left -= dt
        fan_on = state != S_OFF
        boiler_on = state == S_IGNITION or state == S_STABILISE or state == S_RUN

        # ---------------- auger -------------------------------------------------------------
        feed = 0.0
        if state == S_IGNITION:
            if ign_fed < par[I_M_IGN]:
                feed = min(par[I_AUGER_RATE] * dt, par[I_M_IGN] - ign_fed)
                ign_fed += feed
            else:
                topup_clock += dt
                if topup_clock >= par[I_TOPUP_PERIOD]:
                    topup_clock = 0.0
                    ign_fed -= par[I_TOPUP_MASS]  # feed another top-up charge
        elif state == S_STABILISE or state == S_RUN:
            if cyc_t >= par[I_AUGER_CYCLE]:
                cyc_t = 0.0
                rate = p_target * par[I_KG_PER_KJ_CMD]  # kg/s
                cyc_on = rate * par[I_AUGER_CYCLE] / par[I_AUGER_RATE]
            # the auger's fill degree wanders (pellet bridging in the hopper, fines)
            feed = par[I_AUGER_RATE] * max(0.3, 1.0 + xi) * _clip(cyc_on - cyc_t, 0.0, dt)
            cyc_t += dt
        auger_on = feed > 0.0
        xi = fl_a * xi + fl_b * normals[k, 0]
        lam_dev = 0.98 * lam_dev + par[I_LAMBDA_NOISE] * 0.199 * normals[k, 1]

        # ---------------- bed ----------------------------------------------------------------
        burn = 0.0
        if lit:
            burn = m_bed * (1.0 - math.exp(-dt / par[I_TAU_BED]))
            burn = min(burn, par[I_BURN_CAP] * dt)
        sift = feed * par[I_SIFT_FRAC]
        bed_start = m_bed
        m_bed = m_bed + feed - sift - burn
        if lit and m_bed < par[I_BED_OUT] and (state == S_BURNOUT or state == S_OFF):
            lit = False
            since_out = 0.0
        else:
            since_out += dt
        if lit:
            burn_time += dt

        # ---------------- combustion (Eq. 3-6, 9) --------------------------------------------
        m_dry = burn * (1.0 - w_true) / dt  # kg/s dry
        q_fuel = m_dry * par[I_HHV_TRUE]
        air_min = par[I_AIR_MIN]
        if burn > 0.0:
            lam9 = (par[I_FAC_A] + par[I_FAC_B] * m_dry * 3600.0) * par[I_LAMBDA_FAC]
            lam9 = max(1.15, lam9 * (1.0 + lam_dev))
            air = max(lam9 * air_min * m_dry, par[I_AIR_FAN_MIN])
            lam = air / (air_min * m_dry)
            m_fg = m_dry * par[I_MFG0] + air * 1.293
            v_dry = m_dry * par[I_VD0] + air
            m_vap = m_dry * par[I_VAPOUR]
            o2 = 100.0 * 0.21 * (air - air_min * m_dry) / v_dry
            co2 = 100.0 * m_dry * par[I_V_CO2] / v_dry
            q_fire_rel = q_fuel / par[I_Q_FUEL_NOM]
            co = (
                par[I_CO_BASE]
                * (1.0 + par[I_CO_LOW] * max(0.0, (0.45 - q_fire_rel) / 0.45) ** 2)
                * (1.0 + 4.0 * max(0.0, xi))
                + 60.0 * max(0.0, 1.2 - lam) / 0.05
            )
            m_co = co * 1.0e-6 * v_dry * RHO_CO
            m_co = min(m_co, 0.05 * m_dry * par[I_CARBON] * 28.0 / 12.0)
            co = m_co / (1.0e-6 * v_dry * RHO_CO)
            q_chem = m_co * DH_CO
            q_lat = m_vap * DH_VAP
            q_sens = (m_fg * CP_FG + m_vap * CP_VAP) * (t_fg - t_room)
            gas = m_fg + m_vap
        else:
            lam = np.nan
            air = par[I_AIR_FAN_MIN] if fan_on else par[I_AIR_NATURAL]
            v_dry = air
            o2 = 20.9
            co2 = 0.04
            co = par[I_CO_PYRO] if (state == S_IGNITION and m_bed > 0.0) else 0.0
            q_chem = 0.0
            q_lat = 0.0
            q_sens = 0.0
            q_fire_rel = 0.0
            gas = air * 1.293
        q_ash = 0.0002 * q_fuel
        q_el = par[I_P_IGN_W] * par[I_IGN_HEAT_FRAC] / 1000.0 if igniter_on else 0.0

        # ---------------- flue-side store (gas exit temperature) -----------------------------
        if burn > 0.0:
            foul = 1.0 + par[I_FOUL_PER_H] * t / 3600.0
            t_fg_ss = t_w + par[I_DT_FG] * max(q_fire_rel, 0.0) ** par[I_FG_EXP] * foul
        else:
            t_fg_ss = t_w - par[I_FG_OFF_FRAC] * (t_w - t_room)
        tau_fg = par[I_TAU_FG_BG]
        if fg_mode == 1:
            tau_fg += par[I_FG_TAU_EFF]
        elif fg_mode == 2:
            ratio = par[I_GAS_NOM] / max(gas, 1.0e-9)
            tau_fg += par[I_FG_TAU_EFF] * _clip(ratio**0.8, 1.0, 6.0)
        d_fg = (t_fg_ss - t_fg) * (1.0 - math.exp(-dt / tau_fg))
        q_store_fg = c_st * d_fg / dt
        q_hx = q_fuel + q_el - q_ash - q_lat - q_sens - q_chem - q_store_fg

        # ---------------- water side (Eq. 2, 7, 10) -------------------------------------------
        q_w = flow / 3600.0 * CP_W * (t_w - t_c)
        if lit:
            ua = par[I_UA_ON]
        elif fan_on:
            ua = par[I_UA_OFF] + par[I_UA_PURGE]
        else:
            ua = par[I_UA_OFF]
        q_amb = ua * (t_w - t_room)
        d_m = 0.0
        if body_mode == 1:
            q_mw = par[I_UA_METAL] * (t_m - t_w)
            q_in_w = q_mw
            d_m = dt / c_metal * (q_hx - q_mw)
        elif body_mode == 2:
            q_pw = par[I_UA_METAL] * (t_m - t_w)
            q_pr = par[I_UA_PLATE_ROOM] * (t_m - t_room)
            f = par[I_PLATE_FRAC]
            q_in_w = (1.0 - f) * q_hx + q_pw
            q_amb += q_pr
            d_m = dt / c_metal * (f * q_hx - q_pw - q_pr)
        else:
            q_in_w = q_hx
        e_store = c_water * t_w + c_metal * t_m + c_st * t_fg
        d_w = dt / c_water * (q_in_w - q_w - ua * (t_w - t_room))
        q_circ_loss = par[I_UA_CIRC] * (t_c - t_room)
        d_c = dt / par[I_C_CIRC] * (q_w - q_bench - q_circ_loss)

        # ---------------- electricity --------------------------------------------------------
        if not fan_on:
            p_el = par[I_P_EL_OFF]
        else:
            rel = p_target / p_nom if lit else 0.0
            p_el = par[I_P_EL_MIN] + (par[I_P_EL_MAX] - par[I_P_EL_MIN]) * _clip(
                (rel - 0.3) / 0.7, 0.0, 1.0
            )
        if igniter_on:
            p_el += par[I_P_IGN_W]
        if auger_on:
            p_el += par[I_AUGER_W]

        # ---------------- record (values at the start of the step, fluxes over it) -----------
        o = out[k]
        o[O_PHASE] = phase
        o[O_SEQ] = seq_idx
        o[O_LOAD] = load
        o[O_FLOW_SET] = flow_set
        o[O_FLOW] = flow
        o[O_T_IN] = t_c
        o[O_T_W] = t_w
        o[O_T_M] = t_m if body_mode > 0 else t_w
        o[O_T_FG] = t_fg
        o[O_Q_FUEL] = q_fuel
        o[O_Q_EL] = q_el
        o[O_Q_ASH] = q_ash
        o[O_Q_LAT] = q_lat
        o[O_Q_SENS] = q_sens
        o[O_Q_CHEM] = q_chem
        o[O_Q_W] = q_w
        o[O_Q_AMB] = q_amb
        o[O_Q_IN_W] = q_in_w
        o[O_Q_BENCH] = q_bench
        o[O_E_STORE] = e_store
        o[O_FEED] = feed
        o[O_BURN] = burn
        o[O_SIFT] = sift
        o[O_BED] = bed_start
        o[O_LAMBDA] = lam
        o[O_CO] = co
        o[O_O2] = o2
        o[O_CO2] = co2
        o[O_GAS] = v_dry + (m_dry * par[I_VAPOUR] / 0.804 if burn > 0.0 else 0.0)
        o[O_STATE] = state
        o[O_BOILER_ON] = 1.0 if boiler_on else 0.0
        o[O_AUGER] = 1.0 if auger_on else 0.0
        o[O_IGNITER] = 1.0 if igniter_on else 0.0
        o[O_FAN] = 1.0 if fan_on else 0.0
        o[O_LIT] = 1.0 if burn > 0.0 else 0.0
        o[O_P_TARGET] = p_target if boiler_on else 0.0
        o[O_P_EL] = p_el
        o[O_T_CTRL] = t_ctrl

        # ---------------- advance ------------------------------------------------------------
        t_w += d_w
        t_m += d_m
        t_fg += d_fg
        t_c += d_c
        q_in_w_prev = q_in_w
    times[0] = t0
    times[1] = t1
    times[2] = t2
    times[3] = t3
    times[4] = n * dt
    return out[:n], times


@njit(cache=True)
def first_order_lag(x, tau_s, dt):
    """Exact first-order response of a series x (step dt) with time constant(s) tau_s[k]."""
    y = np.empty_like(x)
    y[0] = x[0]
    for k in range(1, x.shape[0]):
        tau = tau_s[k]
        a = math.exp(-dt / tau) if tau > 0.0 else 0.0
        y[k] = x[k] + (y[k - 1] - x[k]) * a
    return y


@njit(cache=True)
def dead_leg_sensor(t_main, flow_rel, t_room, tau_flow_s, tau_loss_s, flow_exp, dt):
    """Sensor in a side pocket: fed by the main pipe with a flow-dependent coupling, cooled
    by the room: dT/dt = (T_main - T) * flow_rel^n / tau_flow - (T - T_room) / tau_loss."""
    y = np.empty_like(t_main)
    y[0] = t_main[0]
    for k in range(1, t_main.shape[0]):
        g_flow = max(flow_rel[k], 0.0) ** flow_exp / tau_flow_s
        g_loss = 1.0 / tau_loss_s
        g = g_flow + g_loss + 1.0e-12
        target = (g_flow * t_main[k] + g_loss * t_room[k]) / g
        y[k] = target + (y[k - 1] - target) * math.exp(-g * dt)
    return y
