"""The real boiler, its controller, the bench and the instruments, stepped together (numba).

One call runs a whole test as the lab does: the protocol's phases and their end rules are
evaluated on the *readings* at each acquisition (as a lab's test controller does), the plant
is stepped in substeps of at most 1 s between acquisitions.

Plant (per substep h), with the names of :mod:`hil_client.reality.params`:

1. Controller (its own, not Type 869's): stage machine OFF -> PURGE (fan, no fuel) ->
   IGNITION (igniter, fuel at a share of Pstart) -> RAMP (fuel ramp to Pstart) -> HOLD
   (Pstart) -> MODULATE (PI on its own boiler-water sensor, anti-windup by conditional
   integration, power levels quantised with hysteresis) -> POSTRUN (fan, no fuel) -> WAIT
   (restart once below the restart temperature and after a minimum off time); a stop only
   after a minimum burn time (or above a safety limit). Fuel comes in auger pulses.
2. Bed: dry inventory M fed at F, burning at R = k M once lit (exact exponential per
   step, so that fed = burnt + change of inventory exactly); lit a short delay after the
   first feed of a start.
3. Combustion chamber (Eq. 1): Q_rel (HHV) + igniter = Q_ash + Q_fg,lat + Q_fg,chem +
   Q_bc,room + W (T_ch - T_room), W = (m_fg cp_fg + m_vap cp_vap) the gas's heat capacity
   flow; the gas then passes the exchanger, leaving at
   T_x = T_sink + (T_ch - T_sink) exp(-NTU), NTU = NTU_nom (W / W_nom)^(-n) (Q_rel /
   Q_rel,nom)^m (the exchanger's efficiency varying with load: convective in the gas flow,
   radiative in the fire); Q_hx = W (T_ch - T_x) enters the body.
4. Body: chain of lumps (:func:`thermal.chain_step`), heat to water m cp (T_w - T_in).
5. Exit pipe to the forward sensor, flue-gas storage (effects), return conditioning of the
   bench (capacity-limited heater/cooler, two lags), room.

Energy ledger (kJ, cumulative, per row): fuel fed x HHV + igniter = heat to water + flue
gas and ash + room + change of storage (lumps, flue storage, bed inventory x HHV).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hil_client.reality.thermal import chain_step, mixed_pipe_step, plug_pipe_step, storage_step

# ---- row layout of the log matrix (numbers)
C_TIME, C_PHASE, C_SEQ = 0, 1, 2
C_FLOW, C_TIN, C_TOUT, C_TBW, C_TFG, C_O2, C_CO2, C_CO = 3, 4, 5, 6, 7, 8, 9, 10
C_VEL, C_DRAUGHT, C_BAL, C_ROOM, C_P, C_RH, C_PEL, C_SET, C_ON = 11, 12, 13, 14, 15, 16, 17, 18, 19
N_COLS = 20
# ---- truth/ledger layout
L_FED, L_IGN, L_WATER, L_FLUE, L_ROOM, L_STORE = 0, 1, 2, 3, 4, 5
L_TW, L_TFWD, L_TIN, L_FLOW, L_TFG, L_FEED_AR, L_BED, L_FIRE, L_QW, L_TMETAL = (
    6,
    7,
    8,
    9,
    10,
    11,
    12,
    13,
    14,
    15,
)
L_BURNT, L_TROOM, L_O2 = 16, 17, 18
N_LEDGER = 19

# controller stages
S_OFF, S_PURGE, S_IGN, S_RAMP, S_HOLD, S_MOD, S_POST, S_WAIT = 0, 1, 2, 3, 4, 5, 6, 7
# phases
PH_PRE, PH_SU, PH_TEST, PH_C1, PH_C2 = 0, 1, 2, 3, 4

RHO_AIR_N = 1.293
CP_W = 4.186


@njit(cache=True)
def _gas(p, burn_kg_h, v_air, x_air, co_ppm):
    """Dry-gas O2 and CO2 [vol-%], dry volume [Nm3/h], heat-capacity flow W [kW/K], latent
    and chemical loss [kW] of ``burn_kg_h`` dry fuel in ``v_air`` Nm3/h of air."""
    v_o2 = max(0.21 * v_air - p.o_min * burn_kg_h, 0.0)
    v_n2 = 0.79 * v_air + p.v_n2f * burn_kg_h
    v_co2 = p.v_co2 * burn_kg_h
    v_so2 = p.v_so2 * burn_kg_h
    v_dry = v_o2 + v_n2 + v_co2 + v_so2
    m_dry_cp = (
        v_o2 * 1.429 * 0.92 + v_n2 * 1.2506 * 1.04 + v_co2 * 1.977 * 0.92 + v_so2 * 2.926 * 0.64
    )
    m_vap_fuel = (p.water_h + p.moist_true) * burn_kg_h
    m_vap_air = x_air * RHO_AIR_N * v_air
    w = (m_dry_cp + (m_vap_fuel + m_vap_air) * 1.88) / 3600.0
    q_lat = m_vap_fuel * 2442.0 / 3600.0
    q_chem = co_ppm * 1e-6 * v_dry * 1.25 * 10100.0 / 3600.0
    o2 = 100.0 * v_o2 / v_dry if v_dry > 0 else 20.95
    co2 = 100.0 * v_co2 / v_dry if v_dry > 0 else 0.04
    return o2, co2, v_dry, w, q_lat, q_chem, m_vap_fuel + m_vap_air


@njit(cache=True)
def _lag(y, x, h, tau):
    if tau <= 0.0:
        return x
    return x + (y - x) * math.exp(-h / tau)


@njit(cache=True)
def run_test(p, seq_load0, seq_load1, seq_dur, max_rows):
    """Run one test; returns (log matrix rows x N_COLS, ledger rows x N_LEDGER, n_rows,
    phase marks t0..t4 [s], timed_out flags per phase)."""
    np.random.seed(int(p.seed))
    out = np.full((max_rows, N_COLS), np.nan)
    led = np.zeros((max_rows, N_LEDGER))
    marks = np.full(5, np.nan)
    timeouts = np.zeros(5)
    n_seq = seq_load0.size
    m_nom = p.p_nom * 3600.0 / (CP_W * p.spread_K)

    # ---- body chain
    temps = np.full(6, p.t_init)
    caps = np.zeros(6)
    links = np.zeros(6)
    q_in = np.zeros(6)
    work = np.zeros(24)
    if p.body_form == 1:  # distributed wall: 4 metal layers, heat enters the fire side
        n_nodes, iw = 5, 4
        for k in range(4):
            caps[k] = p.c_metal / 4.0
        g = 4.0 * p.c_metal / p.tau_body
        for k in range(4):
            links[k] = g
    elif p.body_form == 2:  # firebox lump - water - exchanger lump
        n_nodes, iw = 3, 1
        caps[0] = p.split_cap * p.c_metal
        caps[2] = (1.0 - p.split_cap) * p.c_metal
        links[1] = caps[2] / p.tau_mw
    else:  # metal tightly coupled to the water
        n_nodes, iw = 2, 1
        caps[0] = p.c_metal
        links[0] = p.c_metal / p.tau_mw
    caps[iw] = p.c_water

    # ---- pipe, flue storage
    cells = np.full(24, p.t_init)
    carry = np.zeros(1)
    pipe_state = np.full(2, p.t_init)
    t_store = np.full(2, p.t_init)
    n_store = 1 if p.flue_form == 1 else (2 if p.flue_form == 2 else 0)

    # ---- bed, controller, bench, sensors
    bed = 0.0
    lit = False
    feed_clock = -1.0  # time since the first feed of this start [s]; <0 none yet
    since_light = 1e9
    since_stop = 1e9
    stage = S_OFF
    t_stage = 0.0
    burn_time = 0.0
    off_time = 1e9
    integ = p.p_start
    p_level = p.p_start
    aug_clock = 0.0
    flow = 0.0
    t_in_act = p.t_init
    t_r1 = p.t_init
    t_fwd_water = p.t_init
    s_in = s_out = s_bw = s_ctrl = p.t_init
    s_fg = p.t_init
    o2_l1 = o2_l2 = o2_l3 = 20.95
    co2_l1 = co2_l2 = co2_l3 = 0.04
    co_l1 = co_l2 = co_l3 = 0.0
    hopper = p.hopper_kg
    e_fed = e_ign = e_water = e_flue = e_room = 0.0
    feed_ar_cum = 0.0
    burnt_cum = 0.0
    store0 = p.hhv_true * bed
    for k in range(n_nodes):
        store0 += caps[k] * temps[k]
    cap_s = p.flue_cap / max(n_store, 1)
    for k in range(n_store):
        store0 += cap_s * t_store[k]

    # ---- protocol state
    phase = PH_PRE
    phase_start = 0.0
    hold_since = -1.0
    seq_i = 0
    seq_start = 0.0
    t = 0.0
    row = 0
    marks_t2 = -1.0
    q_w_last = 0.0
    fire_last = 0.0
    tmetal_last = p.t_init
    o2_true = 20.95
    v_last = 0.0
    pel = p.pel_off
    draught_v_air = p.draught_kW_K * 3600.0 / (1.006 * RHO_AIR_N)
    while row < max_rows:
        # next acquisition instant
        interval = p.sample_s
        if p.jitter > 0:
            interval = p.sample_s * (1.0 + 0.5 * (np.random.random() - 0.5))
            if np.random.random() < 0.005:
                interval += p.sample_s
        t_next = round((t + interval) * 1000.0) / 1000.0
        n_sub = max(math.ceil((t_next - t) / 1.0 - 1e-9), 1)
        h = (t_next - t) / n_sub
        enable = phase == PH_SU or phase == PH_TEST
        pump = phase != PH_C2
        for _ in range(n_sub):
            tm = t + h  # end of the substep
            # ---- room
            t_room = (
                p.room0
                + p.room_amp * math.sin(2 * math.pi * tm / p.room_period_s + p.room_phase)
                + p.room_trend_K_h * tm / 3600.0
            )
            pres = p.p0_hPa + p.p_amp * math.sin(2 * math.pi * tm / 86400.0 + p.room_phase)
            rh = p.rh0 + p.rh_amp * math.sin(2 * math.pi * tm / p.room_period_s + 1.0)
            psat = 6.112 * math.exp(17.62 * t_room / (243.12 + t_room))
            x_air = 0.622 * rh / 100.0 * psat / (pres - rh / 100.0 * psat)
            # ---- bench commands: flow set point and return set point
            ret_set = p.test_ret
            heating = False
            if phase == PH_PRE:
                load = p.pre_load
                ret_set = p.pre_temp
                heating = True
            elif phase == PH_SU:
                load = seq_load0[0]
                ret_set = p.su_ret
            elif phase == PH_TEST:
                el = tm - seq_start
                while seq_i < n_seq - 1 and el >= seq_dur[seq_i]:
                    seq_start += seq_dur[seq_i]
                    seq_i += 1
                    el = tm - seq_start
                frac = min(max(el / seq_dur[seq_i], 0.0), 1.0)
                load = seq_load0[seq_i] + (seq_load1[seq_i] - seq_load0[seq_i]) * frac
            elif phase == PH_C1:
                load = p.c1_load
                ret_set = p.c1_ret
            else:
                load = 0.0
            flow_set = load / 100.0 * m_nom if pump else 0.0
            flow = _lag(flow, flow_set, h, p.flow_tau_s if pump else 3.0)

            # ---- controller
            t_stage += h
            off_time += h
            if stage >= S_IGN and stage <= S_MOD:
                burn_time += h
            if not enable:
                if stage >= S_PURGE and stage <= S_MOD:
                    stage, t_stage = S_POST, 0.0
                    since_stop = 0.0
                elif stage == S_WAIT:
                    stage, t_stage = S_OFF, 0.0
            if stage == S_OFF and enable:
                stage, t_stage, burn_time = S_PURGE, 0.0, 0.0
            elif stage == S_PURGE and t_stage >= p.t_purge_s:
                stage, t_stage = S_IGN, 0.0
                feed_clock = 0.0
            elif stage == S_IGN and t_stage >= p.t_ign_stage_s:
                stage, t_stage = S_RAMP, 0.0
            elif stage == S_RAMP and t_stage >= p.t_ramp_s:
                stage, t_stage = S_HOLD, 0.0
            elif stage == S_HOLD and (t_stage >= p.t_hold_s or s_ctrl >= p.t_set - p.hold_exit_K):
                stage, t_stage = S_MOD, 0.0
                integ = p.p_start
                p_level = p.p_start
            elif stage == S_POST and t_stage >= p.t_post_s:
                stage, t_stage = (S_WAIT if enable else S_OFF), 0.0
                off_time = 0.0
            elif stage == S_WAIT and s_ctrl < p.t_restart and off_time >= p.min_off_s:
                stage, t_stage, burn_time = S_PURGE, 0.0, 0.0
            hot = s_ctrl > p.t_safety or (s_ctrl > p.t_shut and burn_time >= p.min_burn_s)
            if stage >= S_IGN and stage <= S_MOD and hot:
                stage, t_stage = S_POST, 0.0
                since_stop = 0.0
            # firing power command [kW]
            p_cmd = 0.0
            if stage == S_IGN:
                p_cmd = p.ign_share * p.p_start
            elif stage == S_RAMP:
                f = min(t_stage / p.t_ramp_s, 1.0)
                p_cmd = p.p_start * (p.ign_share + (1.0 - p.ign_share) * f)
            elif stage == S_HOLD:
                p_cmd = p.p_start
            elif stage == S_MOD:
                err = p.t_set - s_ctrl
                p_raw = p.kp_kW_K * err + integ
                sat_hi = p_raw >= p.p_max and err > 0
                sat_lo = p_raw <= p.p_min and err < 0
                if not (sat_hi or sat_lo):
                    integ += p.kp_kW_K * h / p.ti_s * err
                integ = min(max(integ, p.p_min - 2.0), p.p_max + 2.0)
                p_raw = min(max(p.kp_kW_K * err + integ, p.p_min), p.p_max)
                at_bound = p_raw <= p.p_min or p_raw >= p.p_max
                if at_bound or abs(p_raw - p_level) > 0.6 * p.p_step_kW:
                    p_level = p_raw
                p_cmd = p_level
            firing = stage >= S_IGN and stage <= S_MOD
            # auger pulses: as-received feed of the nominal fuel for p_cmd (LHV basis)
            feed_ar = 0.0
            if p_cmd > 0.0:
                mean_ar = p_cmd * 3600.0 / p.lhv_ar_nom
                max_ar = p.aug_max_share * p.p_max * 3600.0 / p.lhv_ar_nom
                duty = min(mean_ar / max_ar, 1.0)
                aug_clock = (aug_clock + h) % p.aug_period_s
                on_s = duty * p.aug_period_s
                # share of this substep the auger runs (window [0, on_s) of its period)
                a0 = aug_clock - h
                run = 0.0
                if a0 >= 0.0:
                    run = max(0.0, min(aug_clock, on_s) - max(a0, 0.0))
                else:
                    run = max(0.0, min(aug_clock, on_s)) + max(
                        0.0, min(p.aug_period_s, on_s) - (a0 + p.aug_period_s)
                    )
                feed_ar = max_ar * run / h
            feed_dry = feed_ar * (1.0 - p.moist_ar_true)
            # ---- bed
            if feed_dry > 0.0 and feed_clock < 0.0:
                feed_clock = 0.0
            if feed_clock >= 0.0:
                feed_clock += h
            if not lit and feed_clock >= p.light_delay_s and bed > 0.0:
                lit = True
                since_light = 0.0
            k_burn = 0.0
            if lit:
                k_burn = 1.0 / p.bed_tau_s
                if p.ign_form == 2 and feed_clock >= 0.0:
                    k_burn *= max(min(feed_clock / p.ign_ramp_s, 1.0), 0.02)
            since_light += h
            since_stop += h
            if k_burn > 0.0:
                dec = math.exp(-k_burn * h)
                bed_new = bed * dec + feed_dry / 3600.0 / k_burn * (1.0 - dec)
            else:
                bed_new = bed + feed_dry / 3600.0 * h
            burnt = bed + feed_dry / 3600.0 * h - bed_new  # [kg dry]
            bed = bed_new
            if lit and bed < 1e-5 and feed_dry == 0.0:
                lit = False
                feed_clock = -1.0
            burn_kg_h = burnt * 3600.0 / h
            # ---- air
            if stage == S_OFF or stage == S_WAIT:
                v_air = draught_v_air
            else:
                v_air = p.fan_min_nm3_h
                if p_cmd > 0.0:
                    dry_cmd = p_cmd * 3600.0 / p.lhv_ar_nom * (1.0 - p.moist_ar_nom)
                    lam_t = max(p.lam_a + p.lam_b * dry_cmd, p.lam_floor)
                    v_air = max(lam_t * p.air_min * dry_cmd, p.fan_min_nm3_h)
            # ---- CO [ppm dry] while something burns
            co = 0.0
            if burn_kg_h > 1e-6:
                load_f = min(max((p.p_max - p_cmd) / (p.p_max - p.p_min), 0.0), 1.0)
                co = p.co_at_max + (p.co_at_min - p.co_at_max) * load_f
                co += p.co_start_ppm * math.exp(-since_light / p.co_tau_s)
                co += p.co_stop_ppm * math.exp(-since_stop / p.co_tau_s) if not firing else 0.0
            o2_true, co2_true, v_dry, w_gas, q_lat, q_chem, m_vap = _gas(
                p, burn_kg_h, v_air, x_air, co
            )
            q_rel = burn_kg_h * p.hhv_true / 3600.0
            if stage >= S_IGN and stage <= S_MOD and burn_time < p.t_igniter_s:
                q_ign = p.p_ign_W / 1000.0
            else:
                q_ign = 0.0
            q_ash = 0.0002 * q_rel
            q_bc = p.bc_share * q_rel
            h_gas = q_rel + q_ign - q_ash - q_chem - q_lat - q_bc
            t_ch = t_room + h_gas / w_gas
            # exchanger: the gas meets the water side near the return inlet
            ff = flow / (flow + 0.05 * m_nom)
            t_sink = temps[iw] - p.sink_kappa * (temps[iw] - t_in_act) * ff
            # radiative share of the exchange rises with the fire (see simulate.py):
            # NTU x (fire share)^m over the modulation range, blended linearly back to the
            # bare convective law between Pmin and half of it (ignition, burn-out, draught)
            fire_share = q_rel / p.q_rel_nom_kW
            g_fire = max(fire_share, p.fire_share_min) ** p.ntu_fire_exp
            blend = min(max(2.0 * fire_share / p.fire_share_min - 1.0, 0.0), 1.0)
            g_fire = 1.0 + (g_fire - 1.0) * blend
            ntu = min(p.ntu_nom * (w_gas / p.w_nom_kW_K) ** (-p.ntu_exp) * g_fire, 30.0)
            t_x = t_sink + (t_ch - t_sink) * math.exp(-ntu)
            q_hx = w_gas * (t_ch - t_x)
            # flue-gas storage after the exchanger (effect)
            t_gas = t_x
            room_store = 0.0
            for k in range(n_store):
                t_gas, qr = storage_step(
                    t_store, k, t_gas, w_gas, p.flue_ntu, cap_s, p.flue_ua_kW_K, t_room, h
                )
                room_store += qr
            # ---- body
            for k in range(n_nodes):
                q_in[k] = 0.0
            if p.body_form == 2:
                q_in[0] = p.split_share * q_hx
                q_in[2] = (1.0 - p.split_share) * q_hx
                dt_fw = abs(temps[0] - temps[1])
                links[0] = caps[0] / p.tau_body * min(max((dt_fw / 20.0) ** (1.0 / 3.0), 0.3), 3.0)
            else:
                q_in[0] = q_hx
            t_in_step = t_in_act
            fk = flow * CP_W / 3600.0
            e_w, e_r = chain_step(
                temps,
                caps,
                links,
                q_in,
                n_nodes,
                iw,
                h,
                fk,
                t_in_step,
                p.ua_shell_kW_K,
                t_room,
                work,
            )
            tw = temps[iw]
            # ---- ledger
            e_fed += feed_dry / 3600.0 * h * p.hhv_true
            e_ign += q_ign * h
            e_water += e_w
            e_flue += h * (w_gas * (t_gas - t_room) + q_lat + q_chem + q_ash)
            e_room += e_r + room_store + h * q_bc
            feed_ar_cum += feed_ar / 3600.0 * h
            burnt_cum += burnt
            hopper -= feed_ar / 3600.0 * h
            # ---- exit pipe (effect) to the forward sensor
            if p.pipe_form == 1:
                t_fwd_water = plug_pipe_step(
                    cells, tw, flow, h, p.pipe_kg / 24.0, carry, p.pipe_tau_loss_s, t_room
                )
            elif p.pipe_form == 2:
                wcap = p.pipe_kg * CP_W
                t_fwd_water = mixed_pipe_step(
                    pipe_state,
                    tw,
                    flow,
                    h,
                    wcap,
                    0.8 * wcap,
                    1.6 * wcap / 60.0,
                    1.8 * wcap / p.pipe_tau_loss_s,
                    t_room,
                )
            else:
                t_fwd_water = tw
            # ---- return conditioning of the bench
            if pump and flow > 0.01 * m_nom:
                fc = flow * CP_W / 3600.0
                ripple = p.ret_ripple_K * math.sin(2 * math.pi * tm / p.ret_ripple_period_s)
                want = ret_set + p.ret_offset_K + ripple
                q_cond = fc * (t_fwd_water - want)
                q_cond = min(q_cond, p.q_cool_max_kW)
                q_cond = max(q_cond, -p.q_heat_max_kW if heating else 0.0)
                target = t_fwd_water - q_cond / fc
                t_r1 = _lag(t_r1, target, h, p.ret_tau_s)
                t_in_act = _lag(t_in_act, t_r1, h, p.ret_tau2_s)
            else:
                t_r1 = _lag(t_r1, t_room, h, p.ret_stag_tau_s)
                t_in_act = _lag(t_in_act, t_room, h, p.ret_stag_tau_s)
            # ---- sensors (first-order responses)
            strat = p.strat_beta * (tw - t_in_act) * ff
            s_in = _lag(s_in, t_in_act, h, p.tau_water_s)
            s_out = _lag(s_out, t_fwd_water, h, p.tau_water_s + p.well_tau_s)
            s_bw = _lag(s_bw, tw + strat, h, p.tau_water_s)
            s_ctrl = _lag(s_ctrl, tw + p.ctrl_offset_K, h, p.ctrl_tau_s)
            s_fg = _lag(s_fg, t_gas, h, p.tau_flue_s)
            third = p.o2_delay_s / 3.0
            o2_l1 = _lag(o2_l1, o2_true, h, third)
            o2_l2 = _lag(o2_l2, o2_l1, h, third)
            o2_l3 = _lag(o2_l3, o2_l2, h, third)
            co2_l1 = _lag(co2_l1, co2_true, h, third)
            co2_l2 = _lag(co2_l2, co2_l1, h, third)
            co2_l3 = _lag(co2_l3, co2_l2, h, third)
            co_l1 = _lag(co_l1, co, h, third)
            co_l2 = _lag(co_l2, co_l1, h, third)
            co_l3 = _lag(co_l3, co_l2, h, third)
            # electricity
            if stage == S_OFF or stage == S_WAIT:
                pel = p.pel_off
            elif firing:
                lf = min(max((p_cmd - p.p_min) / (p.p_max - p.p_min), 0.0), 1.0)
                pel = p.pel_min + (p.pel_max - p.pel_min) * lf + q_ign * 1000.0
            else:
                pel = p.pel_min
            # flue-gas velocity in the DN100 duct at the measuring point
            v_wet = v_dry + m_vap / 0.804
            v_last = v_wet * (t_gas + 273.15) / 273.15 * (1013.25 / pres) / 3600.0 / p.duct_area_m2
            q_w_last = fk * (tw - t_in_step)
            fire_last = p_cmd
            tmetal_last = temps[0]
            t = tm
        t = t_next
        # ---- acquisition (readings)
        hours = t / 3600.0
        nw = p.noise_water_K
        r_flow = flow * (1.0 + p.flow_gain) + np.random.normal() * p.flow_noise * m_nom
        if flow < 0.01 * m_nom:
            r_flow = 0.0
        r_flow = max(round(r_flow * 10.0) / 10.0, 0.0)
        r_in = s_in + p.off_in + p.drift_in * hours + np.random.normal() * nw
        r_out = s_out + p.off_out + p.drift_out * hours + np.random.normal() * nw
        r_bw = s_bw + p.off_bw + p.drift_bw * hours + np.random.normal() * nw
        r_fg = s_fg + p.off_fg + np.random.normal() * p.noise_flue_K
        r_o2 = o2_l3 + p.o2_off + np.random.normal() * p.o2_noise
        r_co2 = co2_l3 * (1.0 + p.co2_gain) + np.random.normal() * 0.03
        r_co = max(co_l3 * (1.0 + 0.03 * np.random.normal()), 0.0)
        r_vel = max(v_last + np.random.normal() * 0.02, 0.0)
        r_dr = -12.0 + p.draught_off + np.random.normal() * 0.3
        r_bal = round((hopper + p.tare_kg + np.random.normal() * 0.004) / 0.02) * 0.02
        r_room = t_room + p.room_off + np.random.normal() * 0.05
        r_p = pres + np.random.normal() * 0.1
        r_rh = rh + np.random.normal() * 0.3
        r_pel = max(pel + np.random.normal() * 0.5, 0.0)
        on = 1.0 if firing else 0.0
        out[row, C_TIME] = t
        out[row, C_PHASE] = phase
        out[row, C_SEQ] = seq_i if phase == PH_TEST else -1
        out[row, C_FLOW] = r_flow
        out[row, C_TIN] = round(r_in * 100.0) / 100.0
        out[row, C_TOUT] = round(r_out * 100.0) / 100.0
        out[row, C_TBW] = round(r_bw * 100.0) / 100.0
        out[row, C_TFG] = round(r_fg * 10.0) / 10.0
        out[row, C_O2] = round(r_o2 * 100.0) / 100.0
        out[row, C_CO2] = round(r_co2 * 100.0) / 100.0
        out[row, C_CO] = round(r_co)
        out[row, C_VEL] = round(r_vel * 100.0) / 100.0
        out[row, C_DRAUGHT] = round(r_dr * 10.0) / 10.0
        out[row, C_BAL] = r_bal
        out[row, C_ROOM] = round(r_room * 10.0) / 10.0
        out[row, C_P] = round(r_p * 10.0) / 10.0
        out[row, C_RH] = round(r_rh * 10.0) / 10.0
        out[row, C_PEL] = round(r_pel * 10.0) / 10.0
        out[row, C_SET] = load / 100.0 * m_nom if pump else 0.0
        out[row, C_ON] = on
        for c in range(C_FLOW, C_PEL + 1):
            if np.random.random() < p.dropout_p:
                out[row, c] = np.nan
        store = p.hhv_true * bed
        for k in range(n_nodes):
            store += caps[k] * temps[k]
        for k in range(n_store):
            store += cap_s * t_store[k]
        led[row, L_FED] = e_fed
        led[row, L_IGN] = e_ign
        led[row, L_WATER] = e_water
        led[row, L_FLUE] = e_flue
        led[row, L_ROOM] = e_room
        led[row, L_STORE] = store - store0
        led[row, L_TW] = temps[iw]
        led[row, L_TFWD] = t_fwd_water
        led[row, L_TIN] = t_in_act
        led[row, L_FLOW] = flow
        led[row, L_TFG] = s_fg
        led[row, L_FEED_AR] = feed_ar_cum
        led[row, L_BED] = bed
        led[row, L_FIRE] = fire_last
        led[row, L_QW] = q_w_last
        led[row, L_TMETAL] = tmetal_last
        led[row, L_BURNT] = burnt_cum
        led[row, L_TROOM] = t_room
        led[row, L_O2] = o2_true
        row += 1

        # ---- phase rules on the readings
        el_ph = t - phase_start
        if phase == PH_PRE:
            ok = abs(r_out - p.pre_temp) <= p.pre_tol and abs(r_in - p.pre_temp) <= p.pre_tol
            if ok:
                if hold_since < 0:
                    hold_since = t
            else:
                hold_since = -1.0
            done = ok and t - hold_since >= p.pre_hold
            if done or el_ph >= p.pre_max:
                timeouts[0] = 0.0 if done else 1.0
                phase, phase_start = PH_SU, t
                marks[0] = t
        elif phase == PH_SU:
            # least-squares slope of the flue-gas reading over the window while firing
            st = sy = stt = sty = 0.0
            n_pts = 0
            j = row - 1
            t_first = t
            while j >= 0 and out[j, C_TIME] >= t - p.su_win:
                if out[j, C_ON] < 0.5 or out[j, C_PHASE] != PH_SU:
                    break
                yj = out[j, C_TFG]
                if not math.isnan(yj):
                    tj = out[j, C_TIME] - t
                    st += tj
                    sy += yj
                    stt += tj * tj
                    sty += tj * yj
                    n_pts += 1
                    t_first = out[j, C_TIME]
                j -= 1
            slope = math.inf
            den = n_pts * stt - st * st
            if n_pts >= 3 and den > 0:
                slope = (n_pts * sty - st * sy) / den * 60.0
            full = t - t_first >= 0.98 * p.su_win
            done = full and slope < p.su_rise and el_ph >= p.su_min
            if done or el_ph >= p.su_max:
                timeouts[1] = 0.0 if done else 1.0
                phase, phase_start = PH_TEST, t
                seq_i, seq_start = 0, t
                marks[1] = t
        elif phase == PH_TEST:
            total = 0.0
            for k in range(n_seq):
                total += seq_dur[k]
            if el_ph >= total:
                phase, phase_start = PH_C1, t
                marks[2] = t
                marks_t2 = t
        elif phase == PH_C1:
            done = r_out <= p.c1_until
            if done or el_ph >= p.c1_max:
                timeouts[3] = 0.0 if done else 1.0
                phase, phase_start = PH_C2, t
                marks[3] = t
        else:
            if t >= marks_t2 + p.c2_after:
                marks[4] = t
                break
    return out, led, row, marks, timeouts
