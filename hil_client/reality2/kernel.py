# ruff: noqa: F405, SIM102, SIM114 (a state machine reads better branch by branch)
"""The plant, its controller, the bench and the test scheduler, stepped at 1 s (numba).

One compiled loop runs a whole test: the scheduler (preheat, start-up, test, first and second
cooling, as the protocol definitions describe them, its rules evaluated on the readings at the
acquisition instants), the bench (pump, return conditioning by a mixing valve and an electric
heater with limited capacity and their own lags, the loop water), the boiler controller (its
own program: pre-purge, ignition, fuel ramp, staged PI modulation with anti-windup, minimum
burn and off times, a restart rule), the combustion (auger pulses into a bed that burns with
a time constant, fan air with its own lag, lambda from air over burning fuel), the body
(4 stratified water nodes, 4 steel nodes, optional refractory or delayed wall), the exit pipe,
optional flue-gas stores, and the instruments (lags, offsets, drifts, noise, quantisation).

Every heat flow of a step is computed once and used for both sides of the exchange, the water
advection is implicit upwind: so the energy balance of the boiler (chamber, body, exit pipe)
closes each step to rounding; :data:`X_RESIDUAL` reports it.

Parameters arrive packed in one float array (names in :mod:`hil_client.reality2.layout`);
results leave as one row per second of named channels (``R_*`` readings, ``X_*`` truths).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hil_client.reality2.layout import *  # noqa: F403 (parameter and channel indices)
from hil_client.reality2.layout import (
    CP_AIR,
    CP_WATER,
    DH_VAP,
    N_PIPE_MAX,
    N_WALL,
    N_WATER,
    SIGMA,
    TRANSIT_MAX,
)

# controller modes
OFF, PREPURGE, IGNITION, RAMP, MODULATE, BURNOUT, WAIT = 0, 1, 2, 3, 4, 5, 6
# scheduler phases
PREHEAT, START_UP, TEST, COOLING_1, COOLING_2, DONE = 0, 1, 2, 3, 4, 5


@njit(cache=True, inline="always")
def _lag(state, target, dt, tau):
    if tau <= 0.0:
        return target
    return state + (target - state) * (1.0 - math.exp(-dt / tau))


@njit(cache=True, inline="always")
def _quant(x, q):
    if q <= 0.0:
        return x
    return q * math.floor(x / q + 0.5)


@njit(cache=True, inline="always")
def _load_at(sched, k, elapsed):
    dur = sched[k, 0]
    a = sched[k, 1]
    b = sched[k, 2]
    frac = min(max(elapsed / dur, 0.0), 1.0) if dur > 0 else 1.0
    return a + (b - a) * frac


@njit(cache=True)
def run_plant(p, sched, noise, acq, start_delays, out, marks):
    """Run one test; fill ``out`` (seconds x channels) and ``marks`` (t0..t4 [s]).

    Args:
        p: packed parameters (``P_*``).
        sched: test sequences, rows (duration_s, load_start_pct, load_end_pct).
        noise: standard normal draws, seconds x ``N_*`` channels.
        acq: 1 where an acquisition (a logged row) ends that second.
        start_delays: extra ignition delay of each start [s] (random-delay form).
        out: output rows (``R_*``, ``X_*``), one per second; filled in place.
        marks: t0..t4 [s]; filled in place.

    Returns:
        the number of seconds simulated.
    """
    dt = 1.0
    n_max = out.shape[0]
    n_seq = sched.shape[0]
    test_total = 0.0
    for k in range(n_seq):
        test_total += sched[k, 0]
    cw = p[P_C_WATER_NODE]
    cs = p[P_C_STEEL_NODE]
    t_room0 = p[P_ROOM_BASE]
    # --- state
    t_init = p[P_T_INIT]
    tw = np.full(N_WATER, t_init)
    ts = np.full(N_WATER, t_init)
    n_pipe = int(p[P_PIPE_CELLS])
    tp = np.full(N_PIPE_MAX, t_init)
    t_pipe_wall = t_init
    n_loop = 5
    tl = np.full(n_loop, t_init)
    t_ret = t_init
    t_ref = t_init
    twall = np.full(N_WALL, t_init)
    transit = np.zeros(TRANSIT_MAX)
    n_transit = int(p[P_WALL_DELAY_S])
    tfs = np.full(2, t_init)
    # bed and fuel
    bed = 0.0
    e_bed = 0.0
    ignited = False
    fed_ar = 0.0
    fed_dry = 0.0
    burnt_dry = 0.0
    fines_dry = 0.0
    charge_left = 0.0
    # controller
    mode = OFF
    mode_time = 0.0
    since_ign = 1e9
    since_start = 1e9
    p_cmd = 0.0
    integ = 0.0
    stage = 0.0
    n_starts = 0
    air = 0.0
    at_min_time = 0.0
    burn_time = 0.0
    # bench
    flow = 0.0
    valve = 0.0
    bench_i = 0.0
    ripple = 0.0
    room_ou = 0.0
    # sensors (lagged true values)
    s_tin = t_init
    s_tout = t_init
    s_tbw = t_init
    s_tfg = t_init
    s_troom = t_room0
    s_ctrl = t_init
    an_buf = np.zeros((64, 3))
    an_o2 = 20.95
    an_co2 = 0.04
    an_co = 0.0
    draught_ou = 0.0
    press_ou = 0.0
    rh_ou = 0.0
    # scheduler
    phase = PREHEAT
    phase_start = 0.0
    hold_since = -1.0
    seq_idx = 0
    seq_start = 0.0
    for m in range(5):
        marks[m] = np.nan
    win_t = np.zeros(4096)
    win_y = np.zeros(4096)
    win_head = 0
    win_n = 0
    t_fg_prev = t_init
    flow_set = 0.0
    ret_set = p[P_PREHEAT_T]
    pump_on = True
    enabled = False
    heater_ok = True
    last_tin_r = t_init
    # energy of the stores at the start
    n_run = 0
    feed_factor = 1.0
    since_ign_flame = 1e9
    q_fs = np.zeros(2)
    q_in_steel = np.zeros(N_WATER)
    q_sw = np.zeros(N_WATER)
    q_jk = np.zeros(N_WATER)
    q_mix = np.zeros(N_WATER)  # into node j from node j + 1
    q_seg = np.zeros(N_WALL + 1)
    c_fs1 = p[P_FG_C] if p[P_FG_FORM] == 1.0 else 0.0
    x_fg_nom = p[P_MCP_GAS_NOM]
    for i in range(n_max):
        t = (i + 1) * dt
        # ------------------------------------------------------------ bench commands
        load = 0.0
        sequence = -1.0
        if phase == PREHEAT:
            load = p[P_PREHEAT_LOAD]
            ret_set = p[P_PREHEAT_T]
            pump_on, enabled, heater_ok = True, False, True
        elif phase == START_UP:
            load = sched[0, 1]
            ret_set = p[P_RETURN_SET]
            pump_on, enabled, heater_ok = True, True, False
        elif phase == TEST:
            elapsed = t - dt - seq_start
            while seq_idx < n_seq - 1 and elapsed >= sched[seq_idx, 0]:
                seq_start += sched[seq_idx, 0]
                seq_idx += 1
                elapsed = t - dt - seq_start
            load = _load_at(sched, seq_idx, elapsed + dt)
            sequence = seq_idx
            ret_set = p[P_RETURN_SET]
            pump_on, enabled, heater_ok = True, True, False
        elif phase == COOLING_1:
            load = p[P_COOL1_LOAD]
            ret_set = p[P_COOL1_RETURN]
            pump_on, enabled, heater_ok = True, False, False
        else:
            load = 0.0
            pump_on, enabled, heater_ok = False, False, False
        flow_set = load / 100.0 * p[P_FLOW_PER_PCT] * 100.0 if pump_on else 0.0
        # ------------------------------------------------------------ room
        room_ou += (
            -room_ou * dt / p[P_ROOM_OU_TAU]
            + p[P_ROOM_OU_SIG] * math.sqrt(2.0 * dt / p[P_ROOM_OU_TAU]) * noise[i, N_ROOM]
        )
        t_room = (
            t_room0
            + p[P_ROOM_AMP] * math.sin(2.0 * math.pi * (t + p[P_ROOM_PHASE_S]) / 86400.0)
            + room_ou
        )
        # ------------------------------------------------------------ pump
        ripple += (
            -ripple * dt / 30.0 + p[P_FLOW_RIPPLE] * math.sqrt(2.0 * dt / 30.0) * noise[i, N_RIPPLE]
        )
        if pump_on:
            target = flow_set / (1.0 + p[P_FLOW_BIAS]) * (1.0 + ripple)
            flow = _lag(flow, target, dt, p[P_TAU_FLOW])
        else:
            flow = _lag(flow, 0.0, dt, p[P_TAU_FLOW] * 0.5)
            if flow < 1.0:
                flow = 0.0
        mcp = flow / 3600.0 * CP_WATER
        t_in = t_ret
        # ------------------------------------------------------------ boiler controller
        t_ctrl = s_ctrl + p[P_CTRL_OFFSET]
        t_set = p[P_SET_T]
        prev_mode = mode
        if not enabled:
            if mode in (PREPURGE, IGNITION, RAMP, MODULATE):
                mode = BURNOUT
            elif mode == WAIT:
                mode = OFF
            elif mode == BURNOUT and mode_time >= p[P_BURNOUT_S]:
                mode = OFF
        else:
            if mode == OFF:
                mode = PREPURGE if t_ctrl < t_set - 3.0 else WAIT
            elif mode == WAIT:
                if t_ctrl <= p[P_RESTART_T] and mode_time >= p[P_MIN_OFF_S]:
                    mode = PREPURGE
            elif mode == PREPURGE:
                if mode_time >= p[P_PREPURGE_S]:
                    mode = IGNITION
            elif mode == IGNITION:
                if mode_time >= p[P_IGN_PROGRAM_S]:
                    mode = RAMP
            elif mode == RAMP:
                if t_ctrl >= p[P_SHUTOFF_T]:
                    mode = BURNOUT
                elif mode_time >= p[P_START_HOLD_S] or t_ctrl >= t_set - p[P_RAMP_HANDOVER_K]:
                    mode = MODULATE
                    integ = p_cmd
                    stage = p_cmd
            elif mode == MODULATE:
                if t_ctrl >= p[P_SHUTOFF_T]:
                    mode = BURNOUT
                elif (
                    t_ctrl >= t_set + p[P_STOP_HYST_K]
                    and at_min_time >= 300.0
                    and burn_time >= p[P_MIN_BURN_S]
                ):
                    mode = BURNOUT
            elif mode == BURNOUT:
                if mode_time >= p[P_BURNOUT_S]:
                    mode = WAIT
        if mode != prev_mode:
            mode_time = 0.0
            if mode == PREPURGE:
                ignited = False
                n_starts += 1
                since_start = 0.0
                burn_time = 0.0
            if mode == IGNITION:
                since_ign = 0.0
                charge_left = p[P_CHARGE_AR_KG]
            if mode == MODULATE:
                at_min_time = 0.0
        # power command [kW, LHV basis as the controller thinks of it]
        if mode == RAMP:
            frac = min(mode_time / p[P_RAMP_S], 1.0)
            p_cmd = p[P_P_MIN] + (p[P_P_START] - p[P_P_MIN]) * frac
        elif mode == MODULATE:
            err = t_set - t_ctrl
            cont = p[P_KP] * err + integ
            if (
                p[P_P_MIN] < cont < p[P_P_MAX]
                or (cont >= p[P_P_MAX] and err < 0)
                or (cont <= p[P_P_MIN] and err > 0)
            ):
                integ += p[P_KP] * err * dt / p[P_TI_S]  # conditional integration
            integ = min(max(integ, p[P_P_MIN] - 2.0), p[P_P_MAX] + 2.0)
            cont = min(max(p[P_KP] * err + integ, p[P_P_MIN]), p[P_P_MAX])
            step_kw = (p[P_P_MAX] - p[P_P_MIN]) / p[P_N_STAGES]
            if abs(cont - stage) > 0.6 * step_kw:
                stage = p[P_P_MIN] + step_kw * math.floor((cont - p[P_P_MIN]) / step_kw + 0.5)
            p_cmd = min(max(stage, p[P_P_MIN]), p[P_P_MAX])
            if p_cmd <= p[P_P_MIN] + 1e-9:
                at_min_time += dt
            else:
                at_min_time = 0.0
        else:
            p_cmd = 0.0
        # auger (pulse-width modulation; volumetric, as-received mass)
        auger_on = False
        if mode == IGNITION:
            if charge_left > 0.0:
                auger_on = True
        elif mode == RAMP or mode == MODULATE:
            duty = p_cmd / p[P_P_AUGER_CAP]
            phase_in = (t % p[P_AUGER_PERIOD_S]) / p[P_AUGER_PERIOD_S]
            auger_on = phase_in < duty
        if (t % p[P_AUGER_PERIOD_S]) < dt:  # a new auger period: its own pellet charge
            feed_factor = max(1.0 + p[P_FEED_SIG] * noise[i, N_FEED], 0.3)
        feed_ar = p[P_AUGER_AR_KG_S] * feed_factor if auger_on else 0.0
        if mode == IGNITION:
            charge_left -= feed_ar * dt
        feed_dry = feed_ar * (1.0 - p[P_MOISTURE])
        fed_ar += feed_ar * dt
        fed_dry += feed_dry * dt
        fines = feed_dry * p[P_FINES_FRAC]
        fines_dry += fines * dt
        bed += (feed_dry - fines) * dt
        # igniter (runs a fixed time from the ignition program's start)
        ign_on = mode in (IGNITION, RAMP, MODULATE) and since_ign < p[P_IGNITER_S]
        q_ign = p[P_IGNITER_W] / 1000.0 if ign_on else 0.0
        # ignition of the bed (physical)
        q_ign_bed = 0.0
        if not ignited and since_ign < 1e8 and bed > 1e-4:
            ready = since_ign >= p[P_IGN_DELAY_BG_S]
            if p[P_IGN_FORM] == 1.0:  # the bed must reach its ignition temperature
                q_ign_bed = q_ign * p[P_IGN_BED_ETA]
                # the igniter heats the bed's surface layer: at most 1.5 charges of pellets
                layer = min(bed, 1.5 * p[P_CHARGE_AR_KG])
                e_need = (p[P_IGN_BED_C0] + p[P_IGN_BED_CP] * layer) * p[P_IGN_BED_DT]
                ready = ready and e_bed >= e_need
            elif p[P_IGN_FORM] == 2.0:
                k_start = min(n_starts - 1, start_delays.shape[0] - 1)
                ready = ready and since_ign >= p[P_IGN_DELAY_BG_S] + start_delays[k_start]
            if ready and mode in (IGNITION, RAMP, MODULATE):
                ignited = True
                since_ign_flame = 0.0
                q_ign_bed = 0.0  # from now the igniter air feeds the flame
        if not ignited:
            since_ign_flame = 1e9
        bed_heat_out = e_bed / 60.0 if ignited else e_bed / p[P_IGN_BED_TAU_LOSS]
        # burning
        tau_bed = p[P_TAU_BED]
        if ignited and since_ign_flame < 600.0:
            tau_bed *= p[P_SMOULDER_START]
        if mode in (BURNOUT, WAIT, OFF):
            tau_bed *= p[P_SMOULDER_STOP]
        burn = bed / tau_bed if ignited else 0.0
        bed -= burn * dt
        burnt_dry += burn * dt
        if ignited and bed < 1e-6 and mode in (BURNOUT, WAIT, OFF):
            ignited = False
            bed = max(bed, 0.0)
        # fan air [m3N/s]
        fuel_cmd = p_cmd / p[P_LHV_DOC]  # dry kg/s the controller believes it feeds
        if mode == PREPURGE:
            air_target = p[P_AIR_PURGE]
        elif mode == IGNITION:
            air_target = p[P_AIR_IGNITION]
        elif mode == RAMP or mode == MODULATE:
            xh = fuel_cmd * 3600.0
            lam_ss = p[P_LAM_A] + p[P_LAM_B] * xh + p[P_LAM_CURV] * (xh - p[P_LAM_XMID]) ** 2
            air_target = max(lam_ss, 1.15) * p[P_AIR_MIN] * fuel_cmd
        elif mode == BURNOUT:
            air_target = p[P_AIR_BURNOUT]
        else:
            air_target = 0.0
        air = _lag(air, air_target, dt, p[P_TAU_FAN])
        fan_frac = air / p[P_AIR_PURGE]
        # ------------------------------------------------------------ combustion
        ts_mean = 0.0
        for j in range(N_WATER):
            ts_mean += ts[j] / N_WATER
        q_fuel = q_lat = q_chem = q_ash = q_hx = 0.0
        lam = 1e9
        co = 0.0
        mcp_gas = 0.0
        q_to_steel_air = 0.0
        q_ign_steel = 0.0
        if burn > 1e-7:
            lam = max(air / (p[P_AIR_MIN] * burn), 1.02)
            mg = p[P_GAS_A0] + p[P_GAS_A1] * lam
            mv = p[P_VAPOUR_PER_KG]
            t_guess = 0.5 * (t_fg_prev + t_room)
            mcp_gas = burn * (mg * (1.0 + 1.0e-4 * t_guess) + mv * (1.86 + 3.0e-4 * t_guess))
            q_fuel = burn * p[P_HHV]
            q_lat = burn * mv * DH_VAP
            q_ash = 0.0002 * q_fuel
            p_burn_kw = burn * p[P_LHV_DOC]
            x_load = (p[P_P_MAX] - p_burn_kw) / (p[P_P_MAX] - p[P_P_MIN])
            x_load = min(max(x_load, 0.0), 1.0)
            co = p[P_CO_PMAX] + (p[P_CO_PMIN] - p[P_CO_PMAX]) * x_load
            co += 3000.0 * max(0.0, 1.3 - lam)
            co += p[P_CO_START] * math.exp(-since_ign_flame / 200.0)
            co += 400.0 * max(0.0, (60.0 - ts_mean) / 30.0)
            v_dry = p[P_VDRY0] + p[P_VDRY1] * lam
            q_chem = burn * v_dry * co * 1e-6 * 1.25 * 10_103.0
            q_avail = q_fuel + q_ign - q_lat - q_chem - q_ash
            t_ad = t_room + q_avail / mcp_gas
            t_exit_steel = 0.5 * (ts[0] + ts[1])
            d_x = p[P_DT_X0] * (mcp_gas / x_fg_nom) ** p[P_DT_X_EXP]
            t_x = min(t_exit_steel + d_x, t_ad - 1.0)
            t_x = max(t_x, t_room)
            q_hx = mcp_gas * (t_ad - t_x)
            t_gas = t_x
        else:
            # no flame: fan air or the idle draught through the body
            m_air = max(air * 1.293, p[P_DRAUGHT_AIR_KG_S])  # fan air or the idle draught
            mcp_gas = m_air * CP_AIR
            t_gas = t_room + p[P_DRAUGHT_EFF] * (ts_mean - t_room)
            q_to_steel_air = mcp_gas * (t_gas - t_room)  # taken from the steel
            q_ign_steel = q_ign - q_ign_bed  # igniter air warms the chamber
        # flue-gas stores (flue_gas_lag effect)
        q_fs_steel = 0.0
        q_fs[0] = q_fs[1] = 0.0
        if p[P_FG_FORM] == 1.0:
            for k in range(2):
                ntu = 3.0
                t_out_k = tfs[k] + (t_gas - tfs[k]) * math.exp(-ntu)
                q_fs[k] = mcp_gas * (t_gas - t_out_k)
                t_gas = t_out_k
        elif p[P_FG_FORM] == 2.0:
            ratio = max(mcp_gas / x_fg_nom, 0.02)
            ntu = p[P_FG_NTU0] * ratio ** (-0.4)
            t_out_k = tfs[0] + (t_gas - tfs[0]) * math.exp(-ntu)
            q_fs[0] = mcp_gas * (t_gas - t_out_k)
            t_gas = t_out_k
            q_fs_steel = p[P_FG_G_STEEL] * (tfs[0] - ts[0])
        t_fg_prev = t_gas
        q_sens = mcp_gas * (t_gas - t_room)
        # ------------------------------------------------------------ body
        q_in_steel[:] = 0.0
        q_rad = 0.0
        q_wall_out = 0.0
        q_transit_in = 0.0
        if p[P_BODY_FORM] == 1.0:  # refractory lining radiating to the firebox steel
            q_ref_in = p[P_REF_FRAC] * q_hx
            q_rad = (
                SIGMA
                * p[P_REF_EA]
                * ((t_ref + 273.15) ** 4 - (ts[N_WATER - 1] + 273.15) ** 4)
                / 1000.0
            )
            for j in range(N_WATER):
                q_in_steel[j] += (q_hx - q_ref_in) * p[P_HEAT_W0 + j]
            q_in_steel[N_WATER - 1] += q_rad
        elif p[P_BODY_FORM] == 2.0:  # heat through a delayed, distributed wall
            q_ref_in = 0.0
            q_transit_in = q_hx
            g = p[P_WALL_G]
            q_wall_out = g * (twall[N_WALL - 1] - ts_mean)
            for j in range(N_WATER):
                q_in_steel[j] += q_wall_out * p[P_HEAT_W0 + j]
        else:
            q_ref_in = 0.0
            for j in range(N_WATER):
                q_in_steel[j] += q_hx * p[P_HEAT_W0 + j]
        q_in_steel[N_WATER - 1] += q_ign_steel + bed_heat_out
        q_in_steel[0] += q_fs_steel
        # steel <-> water, water losses, mixing (explicit, old temperatures)
        q_mix[:] = 0.0
        for j in range(N_WATER):
            q_sw[j] = p[P_UA_SW_NODE] * (ts[j] - tw[j])
            q_jk[j] = p[P_UA_JACKET_NODE] * (tw[j] - t_room)
        for j in range(N_WATER - 1):
            g_mix = p[P_G_MIX_STABLE] if tw[j] >= tw[j + 1] else p[P_G_MIX_UNSTABLE]
            q_mix[j] = g_mix * (tw[j + 1] - tw[j])
        q_back = p[P_PIPE_G_BACK] * (tw[0] - tp[0])
        # --- energy of the stores before the step
        e_before = 0.0
        for j in range(N_WATER):
            e_before += cw * tw[j] + cs * ts[j]
        for c in range(n_pipe):
            e_before += p[P_PIPE_C_CELL] * tp[c]
        e_before += p[P_PIPE_C_WALL] * t_pipe_wall + p[P_C_REF] * t_ref
        for c in range(N_WALL):
            e_before += p[P_WALL_C_SEG] * twall[c]
        for c in range(n_transit):
            e_before += transit[c]
        e_before += p[P_FG_C] * tfs[0] + c_fs1 * tfs[1] + e_bed
        # steel update
        air_share = q_to_steel_air / N_WATER
        for j in range(N_WATER):
            ts[j] += dt / cs * (q_in_steel[j] - q_sw[j] - air_share)
        # refractory / wall / transit
        if p[P_BODY_FORM] == 1.0:
            t_ref += dt / p[P_C_REF] * (q_ref_in - q_rad)
        elif p[P_BODY_FORM] == 2.0:
            out_transit = transit[n_transit - 1] if n_transit > 0 else q_transit_in * dt
            for c in range(n_transit - 1, 0, -1):
                transit[c] = transit[c - 1]
            if n_transit > 0:
                transit[0] = q_transit_in * dt
            q_seg[:] = 0.0
            for c in range(N_WALL - 1):
                q_seg[c + 1] = p[P_WALL_G] * (twall[c] - twall[c + 1])
            twall[0] += (out_transit - q_seg[1] * dt) / p[P_WALL_C_SEG]
            for c in range(1, N_WALL - 1):
                twall[c] += dt * (q_seg[c] - q_seg[c + 1]) / p[P_WALL_C_SEG]
            twall[N_WALL - 1] += dt * (q_seg[N_WALL - 1] - q_wall_out) / p[P_WALL_C_SEG]
        # flue stores
        if p[P_FG_FORM] == 1.0:
            for k in range(2):
                tfs[k] += dt * q_fs[k] / p[P_FG_C]
        elif p[P_FG_FORM] == 2.0:
            tfs[0] += dt * (q_fs[0] - q_fs_steel) / p[P_FG_C]
        # bed heat
        e_bed += (q_ign_bed - bed_heat_out) * dt
        # water nodes: implicit upwind advection from the bottom (return) to the top
        t_up = t_in
        for j in range(N_WATER - 1, -1, -1):
            q_exp = q_sw[j] - q_jk[j] + q_mix[j]
            if j > 0:
                q_exp -= q_mix[j - 1]
            if j == 0:
                q_exp -= q_back
            tw[j] = (cw * tw[j] + dt * (mcp * t_up + q_exp)) / (cw + dt * mcp)
            t_up = tw[j]
        # exit pipe: implicit upwind cells with wall or back-conduction
        q_pipe_loss = 0.0
        h_wall = p[P_PIPE_H_WALL] * (0.3 + 0.7 * min(flow / p[P_FLOW_NOM], 1.5) ** 0.8)
        t_up = tw[0]
        q_pw = 0.0
        for c in range(n_pipe):
            loss_c = p[P_PIPE_UA_CELL] * (tp[c] - t_room)
            q_wc = h_wall / n_pipe * (tp[c] - t_pipe_wall)
            q_pw += q_wc
            q_pipe_loss += loss_c
            q_exp = -loss_c - q_wc + (q_back if c == 0 else 0.0)
            tp[c] = (p[P_PIPE_C_CELL] * tp[c] + dt * (mcp * t_up + q_exp)) / (
                p[P_PIPE_C_CELL] + dt * mcp
            )
            t_up = tp[c]
        t_pipe_out = t_up
        q_wall_loss = p[P_PIPE_UA_WALL] * (t_pipe_wall - t_room)
        q_pipe_loss += q_wall_loss
        if p[P_PIPE_C_WALL] > 0.0:
            t_pipe_wall += dt * (q_pw - q_wall_loss) / p[P_PIPE_C_WALL]
        # --- energy after the step, and the balance
        e_after = 0.0
        for j in range(N_WATER):
            e_after += cw * tw[j] + cs * ts[j]
        for c in range(n_pipe):
            e_after += p[P_PIPE_C_CELL] * tp[c]
        e_after += p[P_PIPE_C_WALL] * t_pipe_wall + p[P_C_REF] * t_ref
        for c in range(N_WALL):
            e_after += p[P_WALL_C_SEG] * twall[c]
        for c in range(n_transit):
            e_after += transit[c]
        e_after += p[P_FG_C] * tfs[0] + c_fs1 * tfs[1] + e_bed
        q_store = (e_after - e_before) / dt
        q_water = mcp * (t_pipe_out - t_in)
        q_jacket = 0.0
        for j in range(N_WATER):
            q_jacket += q_jk[j]
        q_flue_to_room = q_sens if burn > 1e-7 else 0.0
        q_draught = q_sens if burn <= 1e-7 else 0.0
        residual = (
            q_fuel + q_ign - q_lat - q_chem - q_ash - q_sens - q_water - q_jacket
            - q_pipe_loss - q_store
        )  # fmt: skip
        # ------------------------------------------------------------ bench loop
        t_up = t_pipe_out
        for c in range(n_loop):
            c_l = p[P_C_LOOP] / n_loop
            loss = p[P_UA_LOOP] / n_loop * (tl[c] - t_room)
            tl[c] = (c_l * tl[c] + dt * (mcp * t_up - loss)) / (c_l + dt * mcp)
            t_up = tl[c]
        # split-range controller: heater (preheat only) or cold-water mixing valve
        err_b = ret_set - (last_tin_r if not math.isnan(last_tin_r) else t_ret)
        y_b = p[P_BENCH_KP] * err_b + bench_i
        if -1.0 < y_b < 1.0 or (y_b >= 1.0 and err_b < 0) or (y_b <= -1.0 and err_b > 0):
            bench_i += p[P_BENCH_KP] * err_b * dt / p[P_BENCH_TI_S]
        bench_i = min(max(bench_i, -1.2), 1.2)
        if not heater_ok:
            bench_i = min(bench_i, 0.05)
        y_b = min(max(p[P_BENCH_KP] * err_b + bench_i, -1.0), 1.0)
        q_heater = p[P_HEATER_KW] * max(y_b, 0.0) if heater_ok and pump_on else 0.0
        valve_cmd = -min(y_b, 0.0) * p[P_VALVE_MAX]
        rate = p[P_VALVE_MAX] / p[P_VALVE_STROKE_S]
        if abs(valve_cmd - valve) > p[P_VALVE_DEADBAND]:  # stiction: moves only past it
            valve += min(max(valve_cmd - valve, -rate * dt), rate * dt)
        if mcp > 0.0:
            t_mix = (1.0 - valve) * t_up + valve * p[P_T_COLD] + q_heater / mcp
            t_ret = _lag(t_ret, t_mix, dt, p[P_TAU_RETURN])
        else:
            t_ret = _lag(t_ret, t_room, dt, 3600.0)
        # ------------------------------------------------------------ instruments
        s_tin = _lag(s_tin, t_in, dt, p[P_TAU_TW])
        t_sensor_out = (1.0 - p[P_SENSOR_WALL_W]) * t_pipe_out + p[P_SENSOR_WALL_W] * t_pipe_wall
        s_tout = _lag(s_tout, t_sensor_out, dt, p[P_TAU_TW])
        i0 = int(p[P_BW_NODE])
        t_bw_true = (1.0 - p[P_BW_FRAC]) * tw[i0] + p[P_BW_FRAC] * tw[min(i0 + 1, N_WATER - 1)]
        s_tbw = _lag(s_tbw, t_bw_true, dt, p[P_TAU_BW])
        s_ctrl = _lag(s_ctrl, tw[0], dt, p[P_TAU_BW])
        s_tfg = _lag(s_tfg, t_gas, dt, p[P_TAU_FG])
        s_troom = _lag(s_troom, t_room, dt, 60.0)
        hours = t / 3600.0
        r_flow = (
            flow * (1.0 + p[P_FLOW_BIAS]) + (p[P_FLOW_NOISE_REL] * flow + 0.3) * noise[i, N_FLOW]
        )
        if flow < 2.0:
            r_flow = 0.0
        r_flow = _quant(max(r_flow, 0.0), 0.1)
        r_tin = _quant(
            s_tin + p[P_OFF_TIN] + p[P_DRIFT_TIN] * hours + p[P_NOISE_TW] * noise[i, N_TIN],
            0.01,
        )
        r_tout = _quant(
            s_tout + p[P_OFF_TOUT] + p[P_DRIFT_TOUT] * hours + p[P_NOISE_TW] * noise[i, N_TOUT],
            0.01,
        )
        r_tbw = _quant(
            s_tbw + p[P_OFF_TBW] + p[P_DRIFT_TBW] * hours + p[P_NOISE_TBW] * noise[i, N_TBW],
            p[P_Q_TBW],
        )
        r_tfg = _quant(s_tfg + p[P_OFF_TFG] + p[P_REL_TFG] * s_tfg + 0.1 * noise[i, N_TFG], 0.1)
        # gas analyser: sample line delay, cell lag
        if burn > 1e-7:
            v_dry = p[P_VDRY0] + p[P_VDRY1] * lam
            o2_true = 100.0 * 0.21 * (lam - 1.0) * p[P_AIR_MIN] / v_dry
            co2_true = 100.0 * p[P_VCO2] / v_dry
            co_true = co
        else:
            o2_true, co2_true, co_true = 20.95, 0.04, 0.0
        slot = i % 64
        an_buf[slot, 0], an_buf[slot, 1], an_buf[slot, 2] = o2_true, co2_true, co_true
        d = int(p[P_AN_DELAY_S])
        old = (i - d) % 64 if i >= d else 0
        src = an_buf[old] if i >= d else an_buf[0]
        an_o2 = _lag(an_o2, src[0], dt, p[P_AN_TAU_S])
        an_co2 = _lag(an_co2, src[1], dt, p[P_AN_TAU_S])
        an_co = _lag(an_co, src[2], dt, p[P_AN_TAU_S])
        r_o2 = _quant(an_o2 + p[P_OFF_O2] + p[P_DRIFT_O2] * hours + 0.03 * noise[i, N_O2], 0.01)
        r_co2 = _quant(an_co2 * (1.0 + p[P_REL_CO2]) + 0.03 * noise[i, N_CO2], 0.01)
        r_co = _quant(max(an_co * (1.0 + 0.03 * noise[i, N_CO]) + 2.0 * noise[i, N_CO2], 0.0), 1.0)
        # velocity of the wet gas (or air) in the DN100 duct at the probe temperature
        if burn > 1e-7:
            v_n = burn * (p[P_VDRY0] + p[P_VDRY1] * lam + p[P_VAPOUR_PER_KG] / 0.804)
        else:
            v_n = mcp_gas / CP_AIR / 1.293
        press = p[P_PRESSURE] + press_ou
        v_act = v_n * (t_gas + 273.15) / 273.15 * 1013.25 / press / p[P_DUCT_AREA]
        r_vel = _quant(max(v_act + 0.02 * noise[i, N_VEL], 0.0), 0.01)
        draught_ou += (
            -draught_ou * dt / 20.0 + p[P_DRAUGHT_SIG] * math.sqrt(dt / 10.0) * noise[i, N_DRAUGHT]
        )
        r_draught = _quant(-12.0 + draught_ou, 0.1)
        vib = p[P_BAL_VIB] * noise[i, N_VIB] if auger_on else 0.0
        r_mass = _quant(
            p[P_BAL_M0] - fed_ar + p[P_BAL_DRIFT] * hours + p[P_BAL_NOISE] * noise[i, N_MASS] + vib,
            p[P_BAL_RES],
        )
        r_room = _quant(s_troom + p[P_OFF_ROOM] + 0.05 * noise[i, N_ROOM2], 0.01)
        press_ou += -press_ou * dt / 7200.0 + 0.3 * math.sqrt(2.0 * dt / 7200.0) * noise[i, N_PRESS]
        r_press = _quant(press, 0.1)
        rh_ou += -rh_ou * dt / 3600.0 + 2.0 * math.sqrt(2.0 * dt / 3600.0) * noise[i, N_RH]
        r_rh = _quant(min(max(p[P_RH] + rh_ou, 5.0), 95.0), 0.1)
        p_el = p[P_PEL_OFF]
        if mode != OFF and mode != WAIT and air_target > 0.0:
            p_el += max(p[P_FAN_W0] + p[P_FAN_W1] * fan_frac, 2.0)
        if auger_on:
            p_el += p[P_AUGER_W]
        if ign_on:
            p_el += p[P_IGNITER_W]
        r_pel = _quant(p_el + 0.3 * noise[i, N_PEL], 0.1)
        r_on = 1.0 if mode in (PREPURGE, IGNITION, RAMP, MODULATE, BURNOUT) else 0.0
        # ------------------------------------------------------------ clocks
        mode_time += dt
        since_start += dt
        since_ign += dt
        if ignited:
            since_ign_flame += dt
        if mode in (RAMP, MODULATE):
            burn_time += dt
        # ------------------------------------------------------------ outputs
        row = out[i]
        row[R_TIME] = t
        row[R_PHASE] = phase
        row[R_SEQUENCE] = sequence
        row[R_FLOW] = r_flow
        row[R_TIN] = r_tin
        row[R_TOUT] = r_tout
        row[R_TBW] = r_tbw
        row[R_TFG] = r_tfg
        row[R_O2] = r_o2
        row[R_CO2] = r_co2
        row[R_CO] = r_co
        row[R_VEL] = r_vel
        row[R_DRAUGHT] = r_draught
        row[R_MASS] = r_mass
        row[R_ROOM] = r_room
        row[R_PRESS] = r_press
        row[R_RH] = r_rh
        row[R_PEL] = r_pel
        row[R_FLOWSET] = flow_set
        row[R_ON] = r_on
        row[X_Q_FUEL] = q_fuel
        row[X_Q_IGN] = q_ign
        row[X_Q_LAT] = q_lat
        row[X_Q_CHEM] = q_chem
        row[X_Q_ASH] = q_ash
        row[X_Q_FLUE] = q_flue_to_room
        row[X_Q_DRAUGHT] = q_draught
        row[X_Q_WATER] = q_water
        row[X_Q_JACKET] = q_jacket
        row[X_Q_PIPE] = q_pipe_loss
        row[X_Q_STORE] = q_store
        row[X_RESIDUAL] = residual
        row[X_T_TOP] = tw[0]
        row[X_T_BOTTOM] = tw[N_WATER - 1]
        row[X_T_BW] = t_bw_true
        row[X_T_OUT] = t_pipe_out
        row[X_T_IN] = t_in
        row[X_T_FG] = t_gas
        row[X_T_ROOM] = t_room
        row[X_FLOW] = flow
        row[X_FED_AR] = fed_ar
        row[X_FED_DRY] = fed_dry
        row[X_BURNT_DRY] = burnt_dry
        row[X_FINES_DRY] = fines_dry
        row[X_BED_DRY] = bed
        row[X_MODE] = mode
        row[X_LAMBDA] = lam if lam < 1e8 else np.nan
        row[X_P_CMD] = p_cmd
        row[X_STARTS] = n_starts
        row[X_IGNITED] = 1.0 if ignited else 0.0
        row[X_T_STEEL] = ts_mean
        row[X_VALVE] = valve
        row[X_HEATER] = q_heater
        n_run = i + 1
        # ------------------------------------------------------------ scheduler rules
        if acq[i] == 0:
            continue
        last_tin_r = r_tin
        elapsed_phase = t - phase_start
        if phase == PREHEAT:
            ok = (
                abs(r_tout - p[P_PREHEAT_T]) <= p[P_PREHEAT_TOL]
                and abs(r_tin - p[P_PREHEAT_T]) <= p[P_PREHEAT_TOL]
            )
            if ok:
                if hold_since < 0.0:
                    hold_since = t
            else:
                hold_since = -1.0
            if (hold_since >= 0.0 and t - hold_since >= p[P_PREHEAT_HOLD_S]) or (
                elapsed_phase >= p[P_PREHEAT_MAX_S]
            ):
                phase, phase_start = START_UP, t
                marks[0] = t
        elif phase == START_UP:
            # "while the burner fires": the program runs and the flue gas shows a flame
            if r_on >= 0.5 and r_tfg > r_tbw + 20.0:
                win_t[win_head] = t
                win_y[win_head] = r_tfg
                win_head = (win_head + 1) % 4096
                win_n = min(win_n + 1, 4096)
            else:
                win_n = 0
            # drop points older than the window
            slope = np.inf
            full = False
            if win_n >= 3:
                st = sy = stt = sty = 0.0
                n_in = 0
                t_first = t
                for q in range(win_n):
                    idx = (win_head - 1 - q) % 4096
                    if win_t[idx] < t - p[P_T1_WINDOW_S]:
                        break
                    dtq = win_t[idx] - t
                    st += dtq
                    sy += win_y[idx]
                    stt += dtq * dtq
                    sty += dtq * win_y[idx]
                    n_in += 1
                    t_first = win_t[idx]
                full = t - t_first >= 0.98 * p[P_T1_WINDOW_S]
                den = n_in * stt - st * st
                if n_in >= 3 and den > 0:
                    slope = (n_in * sty - st * sy) / den
            rise = slope * 60.0 if full else np.inf
            if (elapsed_phase >= p[P_T1_MIN_S] and rise < p[P_T1_MAX_RISE]) or (
                elapsed_phase >= p[P_T1_MAX_S]
            ):
                phase, phase_start = TEST, t
                seq_start = t
                seq_idx = 0
                marks[1] = t
        elif phase == TEST:
            if elapsed_phase >= test_total - 1e-9:
                phase, phase_start = COOLING_1, t
                marks[2] = t
        elif phase == COOLING_1:
            if r_tout <= p[P_COOL1_UNTIL] or elapsed_phase >= p[P_COOL1_MAX_S]:
                phase, phase_start = COOLING_2, t
                marks[3] = t
        elif phase == COOLING_2:
            if t - marks[2] >= p[P_COOL2_AFTER_T2_S] - 1e-9:
                marks[4] = t
                phase = DONE
                break
    return n_run
