"""Closed forms used to check and size plant 5.

``steady_state``: plant 5 at constant firing fraction x (no fouling, no flicker). With the body
at T_s = T_w + Q_hx / UA_sw and the gas at T_ex = T_room + eps (T_s - T_room) + dTx(x):

    Q_hx (1 + mcp_g eps / UA_sw) = r HHV (1 - a_ash) - Q_chem - Q_lat
                                   - mcp_g (eps (T_w - T_room) + dTx)
    Q_w = Q_hx - UA_env (T_w - T_room) - UA_pipe (T_w - T_room),   eta = Q_w / (r HHV)

``type869``: the plain one-node Type 869 of the paper (Eq. 2-10, Table 3 values from the boiler
file) driven by a log's measured flow, return and room temperature from t0; it holds 70 C
(dead-beat between Pmin and Pmax), starts at Pstart until 70 C, stops above 85 C, restarts
below 55 C, adds Wel over 15 min per start, UA_ON / UA_OFF by burner state. ``phase_gap`` gives
its t1..t2 RMSD to a log (Table 4 metrics), used to size the background.
"""

from __future__ import annotations

import math

import numpy as np

from .core import CP_FG, CP_VAP, CP_W, DH_VAP, H2O_H, H_CO, RHO_AIR, RHO_CO


def steady_state(p, x: float, tw: float, troom: float, rh: float = 50.0, pamb: float = 1000.0):
    """Plant 5's steady operating point at firing fraction x (fan and bed in equilibrium)."""
    r = x * p.r_max_d
    o2d = 1.866 * p.fc + 5.56 * p.fh + 0.7 * p.fs - 0.7 * p.fo
    v_air = p.air_unit * (p.lam_a * x + p.lam_b)
    lam = 0.21 * v_air / (o2d * r)
    psat = 6.1094 * math.exp(17.625 * troom / (troom + 243.04))
    x_h = 0.622 * rh / 100 * psat / (pamb - rh / 100 * psat)
    wat = H2O_H * p.fh + p.w_ar / (1 - p.w_ar)
    v_o2 = 0.21 * v_air - o2d * r
    v_co2 = (1.866 * p.fc + p.co2_extra) * r + 0.0004 * v_air
    vd = v_o2 + v_co2 + 0.79 * v_air + 0.8 * p.fn * r + 0.7 * p.fs * r
    co = p.co_nom * (1 + 4 * (1 - min(x, 1.0)) ** 2) * math.exp(max(1.3 - lam, 0.0) * 10)
    co *= math.exp(0.5 * 0.15**2)  # mean of the log-normal flicker
    q_chem = co * 1e-6 * vd * RHO_CO * H_CO
    m_fgd = v_air * RHO_AIR + r * (1 - p.residue - H2O_H * p.fh)
    mcp_g = m_fgd * CP_FG + (r * wat + v_air * RHO_AIR * x_h) * CP_VAP
    dtx = p.dTn * (p.a_x + (1 - p.a_x) * x) * min(1.0, x / 0.15)
    q_lat = r * wat * DH_VAP
    a = r * p.hhv * (1 - p.ash_loss) - q_chem - q_lat - mcp_g * (p.eps_idle * (tw - troom) + dtx)
    q_hx = a / (1 + mcp_g * p.eps_idle / p.ua_sw)
    ts = tw + q_hx / p.ua_sw
    t_fg = troom + p.eps_idle * (ts - troom) + dtx
    q_w = q_hx - (p.ua_env + p.ua_pl) * (tw - troom)
    o2 = 100 * (v_o2 + 0.5 * co * 1e-6 * vd) / vd
    return {
        "Q_fuel": r * p.hhv,
        "Q_w": q_w,
        "eta": q_w / (r * p.hhv),
        "T_fg": t_fg,
        "lambda": lam,
        "O2": o2,
        "T_s": ts,
        "Q_sens": mcp_g * (t_fg - troom),
    }


def type869(boiler: dict, cols: dict, meta: dict, t_set=70.0, t_off=85.0, t_on=55.0):
    """Plain Type 869 along a log from t0; returns (time, T_boiler model, Q_w model [kW])."""
    f = boiler["fuel"]
    w, hhv = f["moisture"], f["hhv_dry_kJ_kg"]
    lhv = hhv * (1 - w) - DH_VAP * (H2O_H * f["h"] * (1 - w) + w)
    k = (1 - w) / lhv  # kg dry fuel per kJ of firing (net basis)
    wat = H2O_H * f["h"] + w / (1 - w)
    air_min = (1.866 * f["c"] + 5.56 * f["h"] + 0.7 * f["s"] - 0.7 * f["o"]) / 0.21
    c = boiler["c_therm_kJ_K"] + boiler["vol_water_m3"] * 1000 * CP_W
    m_nom = boiler["p_nom_kW"] * 3600 / (CP_W * 15)
    fa, fb = boiler["fac_a_lambda"], boiler["fac_b_lambda_h_kg"]
    sel = cols["time_s"] >= meta["t0_s"]
    t = cols["time_s"][sel]

    def ffill(a):
        a = a.copy()
        for i in range(1, len(a)):
            if not np.isfinite(a[i]):
                a[i] = a[i - 1]
        return a

    mw = ffill(cols["water_flow_kg_h"][sel])
    tin = ffill(cols["water_in_temp_C"][sel])
    troom = ffill(cols["room_temp_C"][sel])
    temp = float(cols["boiler_water_temp_C"][sel][0])
    tm, qm = np.empty(len(t)), np.empty(len(t))
    on, starting, t_start = True, True, t[0]
    for i in range(len(t)):
        dt = t[i] - t[i - 1] if i else 1.0
        mcp = mw[i] * CP_W / 3600
        enabled = t[i] < meta["t2_s"]
        if on and (temp > t_off or not enabled):
            on = False
        elif not on and enabled and temp < t_on:
            on, starting, t_start = True, True, t[i]
        ua = (boiler["ua_amb_on_W_K"] if on else boiler["ua_amb_off_W_K"]) / 1000
        dtf = boiler["dt_nom_K"] + boiler["dt_hx_wat_K"] * (1 - mw[i] / m_nom)
        dtf += tin[i] - troom[i]
        # Q_hx(P) = alpha P + beta P^2 (lambda linear in the fuel flow, Eq. 9)
        alpha = k * (hhv * (1 - 0.0002) - wat * DH_VAP - wat * CP_VAP * dtf)
        m_gas = (1 - f["ash"] - H2O_H * f["h"]) + RHO_AIR * air_min * fa  # kg dry gas / kg fuel
        alpha -= k * m_gas * CP_FG * dtf
        beta = -RHO_AIR * CP_FG * dtf * air_min * fb * 3600 * k * k
        q_el = boiler["w_el_Wh"] * 3.6 / 900 if t[i] - t_start < 900 else 0.0
        qhx = 0.0
        if on:
            if starting and temp >= t_set:
                starting = False
            if starting:
                pf = boiler["p_start_kW"]
            else:
                q_req = ((c + dt * (mcp + ua)) * t_set - c * temp) / dt
                q_req -= mcp * tin[i] + ua * troom[i] + q_el
                if abs(beta) > 1e-12:
                    disc = max(alpha * alpha + 4 * beta * q_req, 0.0)
                    pf = (-alpha + math.sqrt(disc)) / (2 * beta)
                else:
                    pf = q_req / alpha
                pf = min(max(pf, boiler["p_min_kW"]), boiler["p_max_kW"])
            qhx = alpha * pf + beta * pf * pf
        temp = (c * temp + dt * (qhx + q_el + mcp * tin[i] + ua * troom[i])) / (c + dt * (mcp + ua))
        tm[i], qm[i] = temp, mcp * (temp - tin[i])
    return t, tm, qm


def phase_gap(boiler: dict, cols: dict, meta: dict) -> dict:
    """RMSD of boiler water temperature and heat to water, model vs log, t1..t2 (Table 4)."""
    t, tm, qm = type869(boiler, cols, meta)
    sel = cols["time_s"] >= meta["t0_s"]
    tb = cols["boiler_water_temp_C"][sel]
    q = (
        cols["water_flow_kg_h"][sel]
        * CP_W
        * (cols["water_out_temp_C"][sel] - cols["water_in_temp_C"][sel])
        / 3600
    )
    ph = (t >= meta["t1_s"]) & (t < meta["t2_s"])
    ok_t, ok_q = ph & np.isfinite(tb), ph & np.isfinite(q)
    return {
        "T_rmsd_K": float(np.sqrt(np.mean((tm[ok_t] - tb[ok_t]) ** 2))),
        "Q_rmsd_kW": float(np.sqrt(np.mean((qm[ok_q] - q[ok_q]) ** 2))),
    }
