"""Time loop of plant 5 (numba): boiler, burner controller, bench and instruments, 1 s steps.

Energy (kJ, kW, temperatures in C), paper Eq. (1)-(2) split into stores:

    E = C_w T_w + C_s T_s + C_p T_p + C_fl T_fl + C_box T_box + (M_bed + M_char) HHV
    dE/dt = m_feed,dry HHV + P_ig - (Q_w + Q_fg,sens + Q_fg,lat + Q_fg,chem + Q_ash + Q_env
            + Q_pipe + Q_box,loss)

- Q_fuel = m_dry HHV (Eq. 3) enters with the fed fuel; the bed releases r HHV - Q_chem - Q_ash.
- Q_fg,sens = (m_fg cp_fg + m_vap cp_vap)(T_fg - T_room) (Eq. 4); Q_fg,lat = m_w,fuel dH_vap
  (Eq. 6); Q_fg,chem = m_CO dH_CO (Eq. 5); Q_w = m_w cp_w (T_out - T_in) (Eq. 7) integrated over
  the step.
- Gas leaves the exchanger at T_ex = T_room + eps (T_s - T_room) + dTx(x), dTx = dTn (a + (1-a) x)
  times a fouling factor (own law, replaces Eq. 8); the gas gives Q_hx to the steel body.
- Steel <-> water coupling UA_sw (pairwise exact exponential exchange); water through the boiler and
  the 30 cm exit pipe as mixed nodes with exact exponential advection, so every step closes.
- Stand-by losses: cladding UA_env (T_w - T_room) always, plus the draught air through the idle
  exchanger (natural draught ~ 0.6 + 0.4 sqrt(dT / 40 K)) inside Q_fg,sens: Eq. (14)-(16).
- Stoichiometry per kg dry fuel (Nm3): O2 demand 1.866 C + 5.56 H + 0.7 S - 0.7 O, CO2 1.866 C,
  N2 0.79 V_air + 0.8 N, H2O 8.937 H + moisture (kg); burning is capped by the air (lambda >= 1.02).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

CP_W = 4.186  # kJ/(kg K), water
DH_VAP = 2442.0  # kJ/kg, latent heat of water at 25 C
RHO_AIR, RHO_CO = 1.293, 1.25  # kg/Nm3
CP_FG, CP_VAP = 1.04, 1.87  # kJ/(kg K), dry flue gas and water vapour
H2O_H = 8.937  # kg water formed per kg hydrogen
H_CO = 10100.0  # kJ/kg, heat of combustion of CO

# the lab-log numeric columns, then the truth columns kept per 1 s step in ``meta['truth']``
_COL_NAMES = """time_s water_flow_kg_h water_in_temp_C water_out_temp_C boiler_water_temp_C
    flue_gas_temp_C flue_gas_O2_pct flue_gas_CO2_pct flue_gas_CO_ppm flue_gas_velocity_m_s
    chimney_draught_Pa balance_mass_kg room_temp_C ambient_pressure_hPa relative_humidity_pct
    electric_power_W water_flow_setpoint_kg_h boiler_on"""
_TRUTH_NAMES = """T_w T_s T_p T_in m_w_kg_s T_fg O2 r_burn_kg_s feed_dry_kg_s bed_kg fed_dry_kg
    burnt_kg balance_kg E_stored_kJ q_in_kW q_out_kW Q_w_kW Q_sens_kW Q_lat_kW Q_chem_ash_kW
    Q_amb_kW x_cmd state T_room lambda CO2 CO"""
COLS, TRUTH = tuple(_COL_NAMES.split()), tuple(_TRUTH_NAMES.split())
NCOL = len(COLS) + len(TRUTH)
J = {name: i for i, name in enumerate(COLS + TRUTH)}
C_T, C_FLOW, C_TIN, C_TOUT, C_TBW, C_TFG, C_O2, C_CO2, C_CO = range(9)
C_VEL, C_DR, C_BAL, C_ROOM, C_P, C_RH, C_PEL, C_FSET, C_ON = range(9, 18)
X_O2, X_CO2, X_CO, NT0 = J["O2"], J["CO2"], J["CO"], len(COLS)

_FIELD_NAMES = """
hhv fc fh fo fn fs residue w_ar co2_extra ash_loss r_aug_ar duty_max t_aug r_max_d air_unit
lam_a lam_b purge_frac ign_air_frac v_idle_ref eps_idle tau_bed burnout_slow flicker
flicker_tau t_light p_ig m_charge m_glow dT_cc_max tau_cc dT_flame co_nom c_w c_s ua_sw
ua_env dTn a_x foul_amp t_clean m_nom m_fg_nom c_p ua_pl ua_pc t_set ctrl_off tau_ctrl
t_ctrl db kp ki q_step x_min x_start t_stop t_restart t_demand dT_lowstop t_lowstop min_burn
min_off t_pre t_dwell t_ramp t_hold dT_handover t_post pel_off pel_fan0 pel_fan1 p_aug_el
p_clean_el t_clean_run tau_flow flow_ripple qh_max qc_a qc_b qc_lo m_loop ua_loop tau_cond
hunt_amp hunt_per tau_stag t_init hopper t_room0 room_amp room_phase p0 p_amp rh0 off_in
off_out off_bw drift_in drift_out tau_in tau_out tau_bw n_wt k_pos tau_prof fg_err tau_fg
n_fg fg_turb o2_delay o2_tau o2_off o2_span n_o2 co2_delay co2_off co2_span co_off flue_area
v_off v_noise v_cut draught bal_off bal_drift bal_noise bal_vib room_off flow_off flow_noise
pel_noise az_period az_len az_phase pre_T pre_tol pre_hold pre_max pre_load su_load su_ret
su_min su_max su_win su_rise test_ret test_len c1_load c1_ret c1_until c1_max c2_after eff
form e1 e2 e3 e4 e5 e6
"""
FIELDS = tuple(_FIELD_NAMES.split())
Params = namedtuple("Params", FIELDS)
N_NOISE = 21


@njit(cache=True)
def _xch(ta, ca, tb, cb, ua, dt):
    """Exact heat exchange between two capacities over dt; returns new temperatures."""
    if ua <= 0.0:
        return ta, tb
    k = 1.0 / ca + 1.0 / cb
    q = (ta - tb) * (1.0 - math.exp(-ua * k * dt)) / k
    return ta - q / ca, tb + q / cb


@njit(cache=True)
def _lag(y, x, tau, dt):
    return y + (x - y) * (1.0 - math.exp(-dt / tau))


@njit(cache=True)
def run(p, seg_t, seg_d, seg_l0, seg_l1, nz, n_max):
    """Simulate preheat .. t4 at 1 s; returns (out rows, phase codes, segment index, t0..t4)."""
    dt = 1.0
    out = np.full((n_max, NCOL), np.nan)
    pha = np.zeros(n_max, np.int8)
    seq = np.full(n_max, -1, np.int16)
    ev = np.full(5, -1.0)
    fl, film = p.eff == 1 and p.form == 0, p.eff == 1 and p.form == 1
    tsy, stem = p.eff == 2 and p.form == 0, p.eff == 2 and p.form == 1
    crust, char = p.eff == 3 and p.form == 0, p.eff == 3 and p.form == 1
    box, bim = p.eff == 4 and p.form == 0, p.eff == 4 and p.form == 1
    c_fl = p.e2 if fl else 0.0
    c_box = p.e2 if box else 0.0
    o2d = 1.866 * p.fc + 5.56 * p.fh + 0.7 * p.fs - 0.7 * p.fo
    wat = H2O_H * p.fh + p.w_ar / (1.0 - p.w_ar)
    v0 = p.air_unit * (p.lam_a * p.x_min + p.lam_b)
    v1 = p.air_unit * (p.lam_a + p.lam_b)
    m_ref = p.e1 * p.r_max_d * p.e2 if char else 1.0
    t0 = p.t_init
    tw = ts = tp = tfl = tbox = tin = tin_c = tloop = tctrl = t0
    y_in, y_out, y_bw, y_fg = t0, t0, t0, t0
    y_room = p.t_room0 + p.room_amp * math.sin(p.room_phase)
    y_o2, y_co2, y_co, y_f = 20.9, 0.04, 0.0, 0.0
    tcc, tcc_ref, prof, y_bm = t0, t0, 0.0, 0.0
    m = mb = mc = fed_d = fed_ar = burnt = 0.0
    fr = fk = fgt = dr = room_ou = 0.0
    unsat = trim = 0.0
    ph, hold, fg_t0, on_t = 0, 0.0, t0, 0.0
    cs, t_s, x, x_dem, e_prev, acc = 0, 0.0, 0.0, 0.0, 0.0, 0.0
    off_t, burn_t, low_t, charge_t, ig_t, t_cr, t_lit = 1e9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    flame_t = -1.0
    lit, v_fan, t_on_clean, clean_t, dem_t = False, 0.0, 0.0, 0.0, 0.0
    t_charge = p.m_charge / p.r_aug_ar
    n = n_max
    for i in range(n_max):
        t = i * dt
        troom = p.t_room0 + p.room_amp * math.sin(2 * math.pi * t / 86400 + p.room_phase) + room_ou
        room_ou += -room_ou * dt / 3600 + 0.05 * math.sqrt(2 * dt / 3600) * nz[18, i]
        pamb = p.p0 + p.p_amp * math.sin(2 * math.pi * t / 86400 + p.room_phase + 1.0)
        rh = min(max(p.rh0 - 1.5 * (troom - p.t_room0), 10.0), 95.0)
        # ---- protocol (bench decides on the previous step's measured values)
        heat_ok, enable, k_seg, fset, tret = True, False, -1, 0.0, 0.0
        if ph == 0:  # the operator trims the return so that the forward sensor reads 45 C
            if i > 0:
                trim = min(max(trim + (p.pre_T - out[i - 1, C_TOUT]) * dt / 600, -2.0), 2.0)
            fset, tret = p.pre_load * p.m_nom, p.pre_T + trim
            ok = i > 0 and abs(out[i - 1, C_TOUT] - p.pre_T) < p.pre_tol
            ok = ok and abs(out[i - 1, C_TIN] - p.pre_T) < p.pre_tol
            hold = hold + dt if ok else 0.0
            if hold >= p.pre_hold or t >= p.pre_max:
                ph, ev[0], fg_t0 = 1, t, out[i - 1, C_TFG]
        if ph == 1:
            fset, tret, enable = p.su_load * p.m_nom, p.su_ret, True
            tsu, w = t - ev[0], int(p.su_win)
            on_t = on_t + dt if out[i - 1, C_ON] > 0 else 0.0
            if tsu >= p.su_min and i > w + 61:  # 1 min means; armed after 10 min of firing
                armed = out[i - 1, C_TFG] > fg_t0 + 0.3 * p.dTn + 5.0 and on_t >= 600.0
                rise = np.mean(out[i - 60 : i, C_TFG]) - np.mean(out[i - 60 - w : i - w, C_TFG])
                if (armed and rise < p.su_rise * p.su_win / 60.0) or tsu >= p.su_max:
                    ph, ev[1] = 2, t
        if ph == 2:
            tau = t - ev[1]
            if tau >= p.test_len:
                ph, ev[2] = 3, t
            else:
                k_seg = 0
                while k_seg < len(seg_t) - 1 and tau >= seg_t[k_seg] + seg_d[k_seg]:
                    k_seg += 1
                f = min(max((tau - seg_t[k_seg]) / seg_d[k_seg], 0.0), 1.0)
                load = seg_l0[k_seg] + (seg_l1[k_seg] - seg_l0[k_seg]) * f
                fset, tret, enable, heat_ok = load * p.m_nom, p.test_ret, True, False
        if ph == 3:
            fset, tret, heat_ok = p.c1_load * p.m_nom, p.c1_ret, False
            if out[i - 1, C_TOUT] <= p.c1_until or t - ev[2] >= p.c1_max:
                ph, ev[3] = 4, t
        if ph == 4:
            fset, tret = 0.0, p.c1_ret
        # ---- bench: flow and return conditioning (capacity-limited, lagged, hunting)
        fr += -fr * dt / 30 + math.sqrt(2 * dt / 30) * nz[0, i]
        m = _lag(m, fset * (1 + p.flow_ripple * fr) if fset > 0 else 0.0, p.tau_flow, dt)
        if fset <= 0 and m < 1e-3 * p.m_nom:
            m = 0.0
        if m > 0:
            mcp = m * CP_W
            tloop = tw + (tloop - tw) * math.exp(-m * dt / p.m_loop)
            tl = troom + (tloop - troom) * math.exp(-p.ua_loop / mcp)
            # cooler pre-set by the load programme: extraction within [qlo, qhi]; heater if allowed
            qhi = p.qc_a * fset / p.m_nom + p.qc_b
            qlo = -p.qh_max if heat_ok else p.qc_lo * fset / p.m_nom
            lo, hi = tl - qhi / mcp, tl - qlo / mcp
            unsat = _lag(unsat, 1.0 if lo < tret < hi else 0.0, 60.0, dt)
            tin_c = _lag(tin_c, min(max(tret, lo), hi), p.tau_cond, dt)
            tin = tin_c + p.hunt_amp * unsat * math.sin(2 * math.pi * t / p.hunt_per)
        else:
            tin_c = _lag(tin_c, troom + 0.3 * (tw - troom), p.tau_stag, dt)
            tin = tin_c
        # ---- burner controller (own flow sensor, stepped PI, quantised modulation)
        tctrl = _lag(tctrl, tw, p.tau_ctrl, dt)
        tc = tctrl + p.ctrl_off + 0.02 * nz[16, i]
        t_s += dt
        if not enable and 1 <= cs <= 5:
            cs, t_s = (6 if cs >= 2 else 0), 0.0
        if 2 <= cs <= 5 and tc >= p.t_stop:
            cs, t_s = 6, 0.0
        if cs == 0:
            off_t += dt
            dem_t = dem_t + dt if tc < p.t_set - 10.0 else 0.0
            if enable and off_t >= p.min_off and (tc <= p.t_restart or dem_t >= p.t_demand):
                cs, t_s, clean_t, t_on_clean, t_cr = 1, 0.0, p.t_clean_run, 0.0, 0.0
        elif cs == 1 and t_s >= p.t_pre:
            cs, t_s, charge_t, ig_t, flame_t, tcc_ref = 2, 0.0, 0.0, 0.0, -1.0, tcc
        elif cs == 2:
            if flame_t < 0 and tcc > tcc_ref + p.dT_flame:
                flame_t = t_s
            if (flame_t >= 0 and t_s - flame_t >= p.t_dwell) or t_s > 1800:
                cs, t_s, burn_t = 3, 0.0, 0.0
        elif cs == 3:
            x = p.x_min + (p.x_start - p.x_min) * min(t_s / p.t_ramp, 1.0)
            if t_s >= p.t_ramp:
                cs, t_s = 4, 0.0
        elif cs == 4:
            x = p.x_start
            if t_s >= p.t_hold or tc >= p.t_set - p.dT_handover:
                cs, t_s, x_dem, acc, e_prev = 5, 0.0, x, 0.0, p.t_set - tc
        elif cs == 5:
            acc += dt
            if acc >= p.t_ctrl:
                acc -= p.t_ctrl
                e = p.t_set - tc
                dx = p.kp * (e - e_prev) + (p.ki * e * p.t_ctrl / 60 if abs(e) > p.db else 0.0)
                e_prev = e
                x_dem = min(max(x_dem + dx, p.x_min), 1.0)
                x = min(max(round(x_dem / p.q_step) * p.q_step, p.x_min), 1.0)
            low_t = low_t + dt if x <= p.x_min + 1e-9 and tc > p.t_set + p.dT_lowstop else 0.0
            if low_t >= p.t_lowstop and burn_t >= p.min_burn:
                cs, t_s, low_t = 6, 0.0, 0.0
        elif cs == 6 and t_s >= p.t_post:
            cs, t_s, off_t = 0, 0.0, 0.0
        burn_t += dt
        t_cr += dt
        # ---- auger (pulsed), fan, igniter
        frac = 0.0
        if cs == 2 and charge_t < t_charge:
            frac = min(1.0, t_charge - charge_t)
            charge_t += dt
        elif 3 <= cs <= 5:
            on = x * p.duty_max * p.t_aug
            s0 = t % p.t_aug
            frac = max(0.0, min(s0 + dt, on) - s0) + max(0.0, min(s0 + dt, p.t_aug + on) - p.t_aug)
        feed_ar = p.r_aug_ar * frac
        if cs == 1 or cs == 6:
            vt = p.purge_frac * v1
        elif cs == 2:
            vt = p.ign_air_frac * v1
        elif cs >= 3:
            vt = p.air_unit * (p.lam_a * x + p.lam_b)
        else:
            vt = 0.0
        v_fan = _lag(v_fan, vt, 5.0, dt)
        fan_on = v_fan > 0.05 * v1
        v_idle = p.v_idle_ref * (0.6 + 0.4 * math.sqrt(max(ts - troom, 0.0) / 40.0))
        v_air = max(v_fan, v_idle)
        ig_on = cs == 2 and (flame_t < 0 or t_s - flame_t < p.t_dwell)
        p_ig = p.p_ig if ig_on else 0.0
        # ---- bed: lighting, burning (first-order bed, optional crust / char pool)
        feed_d = feed_ar * (1.0 - p.w_ar)
        fch = p.e1 if char else 0.0
        mb += feed_d * (1 - fch) * dt
        mc += feed_d * fch * dt
        fed_d += feed_d * dt
        fed_ar += feed_ar * dt
        if ig_on:
            ig_t += dt
        if not lit and ig_on and ig_t >= p.t_light and mb + mc > 0.3 * p.m_charge:
            lit, t_lit = True, 0.0
        fk += -fk * dt / p.flicker_tau + math.sqrt(2 * dt / p.flicker_tau) * nz[19, i]
        rb = rc = 0.0
        if lit:
            af = 1.0 if fan_on else 1.0 / p.burnout_slow
            kb = af * max(1.0 + p.flicker * fk, 0.3) / p.tau_bed
            if crust:
                kb *= p.e1 + (1 - p.e1) * (1 - math.exp(-t_cr / p.e2))
            rb = mb * kb
            if char and mc > 0:
                rc = af * mc ** (2.0 / 3.0) * m_ref ** (1.0 / 3.0) / p.e2
            r_cap = 0.21 * v_air / (o2d * 1.02)
            if rb + rc > r_cap:
                rb, rc = rb * r_cap / (rb + rc), rc * r_cap / (rb + rc)
            rb, rc = min(rb, mb / dt), min(rc, mc / dt)
            if mb + mc < p.m_glow and feed_d == 0.0:
                lit = False
            t_lit += dt
        mb -= rb * dt
        mc -= rc * dt
        r = rb + rc
        burnt += r * dt
        xb = r / p.r_max_d
        tcc = _lag(tcc, ts + p.dT_cc_max * math.sqrt(min(xb, 1.5)), p.tau_cc, dt)
        # ---- flue gas: composition, CO, temperatures, losses
        psat = 6.1094 * math.exp(17.625 * troom / (troom + 243.04))
        x_h = 0.622 * rh / 100 * psat / (pamb - rh / 100 * psat)
        v_o2 = max(0.21 * v_air - o2d * r, 1e-12)
        v_co2 = (1.866 * p.fc + p.co2_extra) * r + 0.0004 * v_air
        v_n2 = 0.79 * v_air + 0.8 * p.fn * r
        vd = v_o2 + v_co2 + v_n2 + 0.7 * p.fs * r
        lam = 0.21 * v_air / (o2d * r) if r > 1e-9 else 1e3
        co = 0.0
        if r > 1e-9:
            co = p.co_nom * (1 + 4 * (1 - min(xb, 1.0)) ** 2) * (1 + 6 * math.exp(-t_lit / 120))
            co *= math.exp(max(1.3 - lam, 0.0) * 10) * math.exp(0.15 * nz[20, i])
            co = min(max(co, 0.0 if fan_on else 1500.0), 20000.0)
        v_co = co * 1e-6 * vd
        v_co2 -= v_co
        v_o2 += 0.5 * v_co
        q_chem = v_co * RHO_CO * H_CO
        m_fgd = v_air * RHO_AIR + r * (1 - p.residue - H2O_H * p.fh)
        m_vap = r * wat + v_air * RHO_AIR * x_h
        mcp_g = m_fgd * CP_FG + m_vap * CP_VAP
        foul = p.foul_amp * min(t_on_clean / p.t_clean, 1.5)
        dtx = p.dTn * (p.a_x + (1 - p.a_x) * min(xb, 1.3)) * min(1.0, xb / 0.15) * (1 + foul)
        t_ex = troom + p.eps_idle * (ts - troom) + dtx
        if bim:
            y_bm = _lag(y_bm, dtx, p.e2, dt)
            lo_b = p.dTn * (p.a_x + (1 - p.a_x) * p.x_min)
            t_ex += dtx * p.e1 * p.e3 * min(max((y_bm - lo_b) / (p.dTn - lo_b), 0.0), 1.0)
        q_lat = r * wat * DH_VAP
        q_ash = p.ash_loss * r * p.hhv
        q_hx = r * p.hhv - q_chem - q_ash + p_ig - mcp_g * (t_ex - troom) - q_lat
        t_out, q_box = t_ex, 0.0
        if box:
            ntu = p.e1 * (max(m_fgd, 1e-6) / p.m_fg_nom) ** -0.4
            t_out = tbox + (t_ex - tbox) * math.exp(-ntu)
            q_box = mcp_g * (t_ex - t_out)
        q_sens = mcp_g * (t_out - troom)
        # ---- energy updates (each flux applied once to both sides)
        if fl and q_hx > 0:
            tfl += p.e1 * q_hx * dt / c_fl
            ts += (1 - p.e1) * q_hx * dt / p.c_s
        else:
            ts += q_hx * dt / p.c_s
        if box:
            tbox += q_box * dt / c_box
        ua = p.ua_sw
        if film:
            film_law = 0.5 * ((m / p.m_nom) ** 0.8 + (abs(ts - tw) / 20.0) ** (1.0 / 3.0))
            ua = p.e1 * (1.0 - p.e2 + p.e2 * film_law)
        ts, tw = _xch(ts, p.c_s, tw, p.c_w, ua, dt)
        if fl:
            tfl, tw = _xch(tfl, c_fl, tw, p.c_w, p.e3, dt)
        q_w = 0.0
        if m > 0:
            tw_new = tin + (tw - tin) * math.exp(-m * CP_W * dt / p.c_w)
            e_flow = p.c_w * (tw - tw_new)
            tw, tavg = tw_new, tin + e_flow / (m * CP_W * dt)
            tp_new = tavg + (tp - tavg) * math.exp(-m * CP_W * dt / p.c_p)
            q_w = (e_flow - p.c_p * (tp_new - tp)) / dt
            tp = tp_new
        g = p.ua_pc
        if tsy and m < 0.02 * p.m_nom:
            g += p.e2 * math.sqrt(max(tw - tp, 0.0) / 10.0)
        tw, tp = _xch(tw, p.c_w, tp, p.c_p, g, dt)
        q_env = p.ua_env * (tw - troom)
        tw -= q_env * dt / p.c_w
        q_pl = (p.e1 if tsy else p.ua_pl) * (tp - troom)
        tp -= q_pl * dt / p.c_p
        q_bl = 0.0
        if box:
            q_bl = p.e3 * (tbox - troom)
            tbox -= q_bl * dt / c_box
        e_new = p.c_w * tw + p.c_s * ts + p.c_p * tp + c_fl * tfl + c_box * tbox
        e_new += (mb + mc) * p.hhv
        q_in = feed_d * p.hhv + p_ig
        q_amb = q_env + q_pl + q_bl
        q_out = q_w + q_sens + q_lat + q_chem + q_ash + q_amb
        if lit and fan_on:
            t_on_clean += dt
        if t_on_clean >= p.t_clean:
            t_on_clean, clean_t = 0.0, p.t_clean_run
        # ---- truth
        o = out[i]
        o[C_T] = t
        tv1 = (tw, ts, tp, tin, m, t_out, 100 * v_o2 / vd, r, feed_d, mb + mc, fed_d, burnt)
        tv2 = (p.hopper - fed_ar, e_new, q_in, q_out, q_w, q_sens, q_lat, q_chem + q_ash, q_amb)
        tv3 = (x, float(cs), troom, lam, 100 * max(v_co2, 0.0) / vd, co)
        for k in range(12):
            o[NT0 + k] = tv1[k]
        for k in range(9):
            o[NT0 + 12 + k] = tv2[k]
        for k in range(6):
            o[NT0 + 21 + k] = tv3[k]
        # ---- instruments
        y_f = _lag(y_f, m * 3600, 2.0, dt)
        fm = y_f * (1 + p.flow_off) + p.flow_noise * p.m_nom * 3600 * nz[1, i]
        o[C_FLOW] = fm if fm > 0.01 * p.m_nom * 3600 else 0.0
        y_in = _lag(y_in, tin, p.tau_in, dt)
        o[C_TIN] = y_in + p.off_in + p.drift_in * t / 3600 + p.n_wt * nz[2, i]
        tread, tau_o = tp, p.tau_out
        if stem:
            hr = (m / p.m_nom) ** 0.8 + p.e3
            tread = tp - p.e2 * (tp - troom) / math.cosh(p.e1 * math.sqrt(hr))
            tau_o += p.e4 / hr
        y_out = _lag(y_out, tread, tau_o, dt)
        o[C_TOUT] = y_out + p.off_out + p.drift_out * t / 3600 + p.n_wt * nz[3, i]
        prof = _lag(prof, tw - tin if m > 0 else 0.0, p.tau_prof, dt)
        y_bw = _lag(y_bw, tw - p.k_pos * prof, p.tau_bw, dt)
        o[C_TBW] = y_bw + p.off_bw + p.n_wt * nz[4, i]
        fgt += -fgt * dt / 20 + math.sqrt(2 * dt / 20) * nz[17, i]
        y_fg = _lag(y_fg, t_out + p.fg_turb * fgt * (1.0 if lit else 0.2), p.tau_fg, dt)
        o[C_TFG] = y_fg + p.fg_err * (0.3 + 0.005 * abs(y_fg)) + p.n_fg * nz[5, i]
        j1 = max(i - int(p.o2_delay), 0)
        j2 = max(i - int(p.o2_delay + p.co2_delay), 0)
        y_o2 = _lag(y_o2, out[j1, X_O2], p.o2_tau, dt)
        y_co2 = _lag(y_co2, out[j2, X_CO2], p.o2_tau, dt)
        y_co = _lag(y_co, out[j2, X_CO], p.o2_tau, dt)
        if ((t / p.az_period + p.az_phase) % 1.0) * p.az_period >= p.az_len:
            o[C_O2] = p.o2_off + p.o2_span * y_o2 + p.n_o2 * nz[6, i]
            o[C_CO2] = p.co2_off + p.co2_span * y_co2 + 0.05 * nz[7, i]
            cm = p.co2_span * y_co + p.co_off + (0.03 * y_co + 2.0) * nz[8, i]
            o[C_CO] = max(cm, 0.0)
        vflow = (vd + m_vap / 0.804) * (t_out + 273.15) / 273.15 * 1013.25 / pamb
        vm = vflow / p.flue_area + p.v_off + p.v_noise * nz[9, i]
        o[C_VEL] = vm if vm >= p.v_cut else 0.0
        dr += -dr * dt / 20 + math.sqrt(2 * dt / 20) * nz[10, i]
        o[C_DR] = p.draught + 0.8 * dr
        bal = p.hopper - fed_ar + p.bal_off + p.bal_drift * t / 3600
        bal += (p.bal_noise + (p.bal_vib if frac > 0 else 0.0)) * nz[11, i]
        o[C_BAL] = round(bal / 0.02) * 0.02
        y_room = _lag(y_room, troom, 60.0, dt)
        o[C_ROOM] = y_room + p.room_off + 0.03 * nz[12, i]
        o[C_P] = pamb + 0.05 * nz[13, i]
        o[C_RH] = rh + 0.3 * nz[14, i]
        pel = p.pel_off + p.p_aug_el * frac + 1000 * p_ig
        if v_fan > 0.01 * v1:
            pel += max(p.pel_fan0 + (p.pel_fan1 - p.pel_fan0) * (v_fan - v0) / (v1 - v0), 2.0)
        if clean_t > 0:
            pel += p.p_clean_el
            clean_t -= dt
        o[C_PEL] = pel + p.pel_noise * nz[15, i]
        o[C_FSET], o[C_ON] = fset * 3600, 1.0 if 2 <= cs <= 5 else 0.0
        pha[i], seq[i] = ph, k_seg
        if ph == 4 and t >= ev[2] + p.c2_after:
            ev[4], n = t, i + 1
            break
    return out[:n], pha[:n], seq[:n], ev
