"""A plain one-node Type 869 model (digest section 1) to measure the background gap.

Written for the tests only, from the paper's equations with the documented parameters: one
node of capacity Ctherm + water (Eq. 2), ideal control of the outlet at 70 C within
[Pmin, Pmax], start at Pstart for 15 min, off above 85 C and on again below 55 C, flue-gas
temperature by Eq. 8, excess air by Eq. 9, flue-gas losses by Eq. 4 and 6, Q_ash by
EN 14785, UA_amb,ON/OFF (Eq. 10). Driven by the log's flow, return and room temperature.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CP_W = 4.186


def _per_kg(boiler: dict) -> tuple[float, ...]:
    """Dry-gas mass per kg dry fuel as a + b lambda, vapour per kg, LHV as received."""
    f = boiler["fuel"]
    amin = (1.866 * f["c"] + 5.56 * f["h"] + 0.7 * f["s"] - 0.7 * f["o"]) / 0.21
    # dry gas mass: CO2 + N2(fuel) + SO2 + (lambda air_min) air - O2 consumed
    co2 = 1.977 * 1.866 * f["c"]
    fixed = co2 + 1.2505 * 0.8 * f["n"] + 2.926 * 0.7 * f["s"] - 1.429 * 0.21 * amin
    per_lam = (0.79 * 1.2505 + 0.21 * 1.429) * amin
    wd = f["moisture"] / (1.0 - f["moisture"])
    vap = 9.0 * f["h"] + wd + 0.008 * 1.293 * amin  # fuel water + a little air humidity
    lat = (9.0 * f["h"] + wd) * 2442.0
    w = f["moisture"]
    lhv_ar = f["hhv_dry_kJ_kg"] * (1 - w) - 2442.0 * (9 * f["h"] * (1 - w) + w)
    return fixed, per_lam, vap, lat, lhv_ar, f["hhv_dry_kJ_kg"], w, amin


@njit(cache=True)
def _q_hx(p: float, tfg: float, t_room: float, pars: np.ndarray) -> float:
    """Heat to the node at firing ``p`` (Eq. 1 with Eq. 3-6, 9; Q_ash = 0.02 % points)."""
    fac_a, fac_b, fixed, per_lam, vap, lat, lhv_ar, hhv, w = pars[9:18]
    m_ar = p * 3600.0 / lhv_ar
    m_dry = m_ar * (1.0 - w)
    lam = max(fac_a + fac_b * m_dry, 1.0)
    q_fuel = m_dry * hhv / 3600.0
    m_fg = (fixed + per_lam * lam) * m_dry
    sens = (m_fg * 1.05 + vap * m_dry * 1.88) * (tfg - t_room) / 3600.0
    return q_fuel * (1.0 - 0.0002) - sens - m_dry * lat / 3600.0


@njit(cache=True)
def _run(
    flow: np.ndarray,
    t_in: np.ndarray,
    t_room: np.ndarray,
    dt: np.ndarray,
    i_t0: int,
    i_t2: int,
    t_start: float,
    pars: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    c, ua_on, ua_off, p_min, p_max, p_start, dtnom, dthx, m_nom = pars[:9]
    w_el_kw = pars[18]
    n = flow.shape[0]
    temp = np.empty(n)
    q_w = np.empty(n)
    t = t_in[i_t0]
    on = False
    t_on = 0.0
    for k in range(n):
        if k == i_t0:
            on = True
            t_on = 0.0
        if k == i_t2:
            on = False
        if k < i_t0:
            temp[k] = np.nan
            q_w[k] = np.nan
            continue
        h = dt[k]
        m = max(flow[k], 0.0)
        tfg = t_in[k] + dtnom + dthx * (1.0 - m / m_nom)

        if on:
            t_on += h
            if t > 85.0 and t_on > 60.0:
                on = False
        elif k < i_t2 and t < 55.0:
            on = True
            t_on = 0.0
        if on:
            ua = ua_on / 1000.0
            if t_on < t_start:
                p = p_start
                extra = w_el_kw
            else:
                extra = 0.0
                need = c * (70.0 - t) / h + m * CP_W / 3600.0 * (70.0 - t_in[k])
                need += ua * (70.0 - t_room[k])
                lo, hi = p_min, p_max
                if _q_hx(hi, tfg, t_room[k], pars) <= need:
                    p = hi
                elif _q_hx(lo, tfg, t_room[k], pars) >= need:
                    p = lo
                else:
                    for _ in range(40):
                        mid = 0.5 * (lo + hi)
                        if _q_hx(mid, tfg, t_room[k], pars) < need:
                            lo = mid
                        else:
                            hi = mid
                    p = 0.5 * (lo + hi)
            qh = _q_hx(p, tfg, t_room[k], pars) + extra
        else:
            ua = ua_off / 1000.0
            qh = 0.0
        t_new = t + h * (qh - m * CP_W / 3600.0 * (t - t_in[k]) - ua * (t - t_room[k])) / c
        t = t_new
        temp[k] = t
        q_w[k] = m * CP_W / 3600.0 * (t - t_in[k])
    return temp, q_w


def one_node(cols: dict[str, np.ndarray], meta: dict, boiler: dict) -> tuple[np.ndarray, ...]:
    """Model boiler temperature and heat to water [kW] along the log, from t0 on."""
    t = np.asarray(cols["time_s"], dtype=float)
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0]))
    fixed, per_lam, vap, lat, lhv_ar, hhv, w, _ = _per_kg(boiler)
    c = boiler["c_therm_kJ_K"] + boiler["vol_water_m3"] * 985.0 * CP_W
    m_nom = boiler["p_nom_kW"] * 3600.0 / (CP_W * 15.0)
    pars = np.array(
        [
            c,
            boiler["ua_amb_on_W_K"],
            boiler["ua_amb_off_W_K"],
            boiler["p_min_kW"],
            boiler["p_max_kW"],
            boiler["p_start_kW"],
            boiler["dt_nom_K"],
            boiler["dt_hx_wat_K"],
            m_nom,
            boiler["fac_a_lambda"],
            boiler["fac_b_lambda_h_kg"],
            fixed,
            per_lam,
            vap,
            lat,
            lhv_ar,
            hhv,
            w,
            boiler["w_el_Wh"] * 3600.0 / 900.0 / 1000.0,
        ]
    )
    i_t0 = int(np.searchsorted(t, meta["t0_s"]))
    i_t2 = int(np.searchsorted(t, meta["t2_s"]))
    flow = np.nan_to_num(np.asarray(cols["water_flow_kg_h"], dtype=float))
    return _run(
        flow,
        np.asarray(cols["water_in_temp_C"], dtype=float),
        np.asarray(cols["room_temp_C"], dtype=float),
        dt,
        i_t0,
        i_t2,
        900.0,
        pars,
    )


def gap(cols: dict[str, np.ndarray], meta: dict, boiler: dict) -> dict[str, dict[str, float]]:
    """RMSD and r of boiler temperature and heat to water per phase (paper Table 4)."""
    temp, q_model = one_node(cols, meta, boiler)
    t = np.asarray(cols["time_s"], dtype=float)
    m = np.asarray(cols["water_flow_kg_h"], dtype=float)
    q_meas = m * CP_W / 3600.0 * (cols["water_out_temp_C"] - cols["water_in_temp_C"])
    out = {}
    for name, a, b in (
        ("start_up", meta["t0_s"], meta["t1_s"]),
        ("test", meta["t1_s"], meta["t2_s"]),
        ("stand_by", meta["t2_s"], meta["t4_s"]),
    ):
        sel = (t >= a) & (t < b)
        dtemp = temp[sel] - cols["boiler_water_temp_C"][sel]
        dq = q_model[sel] - q_meas[sel]
        out[name] = {
            "T_rmsd": float(math.sqrt(np.nanmean(dtemp**2))),
            "T_maxdev": float(np.nanmax(np.abs(dtemp))),
            "Q_rmsd": float(math.sqrt(np.nanmean(dq**2))),
            "Q_maxdev": float(np.nanmax(np.abs(dq))),
            "T_r": float(np.corrcoef(temp[sel], cols["boiler_water_temp_C"][sel])[0, 1]),
            "Q_r": float(np.corrcoef(q_model[sel], q_meas[sel])[0, 1]),
        }
    return out
