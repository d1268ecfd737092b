"""Combustion stoichiometry of the plant (digest sections 1-2, paper Eq. 3-6 and 9).

Volumes are m3 at 0 C and 1013.25 hPa per kg of dry fuel (digest section 1):
air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21, V_CO2 = 1.866 C, V_N2 = 0.79 V_air + 0.8 N,
V_O2 = 0.21 (V_air - air_min r). Unburnt carbon (fraction ``fc`` of the fuel carbon) takes
neither oxygen nor forms CO2; CO replaces CO2 volume for volume and leaves half its oxygen.
"""

from __future__ import annotations

import math

from numba import njit

#: specific heats [kJ/(kg K)] and enthalpies [kJ/kg]
CP_FG = 1.05  # dry flue gas (Eq. 4)
CP_VAP = 1.88  # water vapour (Eq. 4)
CP_AIR = 1.006
DH_VAP = 2442.0  # latent heat of water at 25 C (Eq. 6)
DH_CO = 10100.0  # combustion of CO (Eq. 5)
HHV_CARBON = 32790.0  # unburnt carbon in the ash
RHO_AIR_N = 1.293  # kg/Nm3
RHO_CO2_N = 1.977
RHO_CO_N = 1.250
RHO_N2_N = 1.2505
RHO_O2_N = 1.429
RHO_SO2_N = 2.926
RHO_H2O_N = 0.804


@njit(cache=True)
def air_min(c: float, h: float, o: float, s: float, fc: float) -> float:
    """Stoichiometric dry air [Nm3/kg dry fuel] with a fraction ``fc`` of the carbon unburnt."""
    v = (1.866 * c * (1.0 - fc) + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21
    return max(v, 1e-6)


@njit(cache=True)
def flue_gas(
    r_dry: float,
    v_air: float,
    x_air: float,
    c: float,
    h: float,
    o: float,
    n: float,
    s: float,
    wd: float,
    fc: float,
    co_ppm: float,
) -> tuple[float, float, float, float, float, float, float, float]:
    """Dry flue gas of ``r_dry`` kg/h of dry fuel burning in ``v_air`` Nm3/h of dry air.

    Returns (V_dry Nm3/h, O2 vol-% dry, CO2 vol-% dry, m_fg dry kg/h, m_vap_fuel kg/h,
    m_vap_air kg/h, m_CO kg/h, CO ppm actually formed).
    """
    amin = air_min(c, h, o, s, fc)
    v_o2 = max(0.21 * v_air - 0.21 * amin * r_dry, 0.0)
    v_co2_tot = 1.866 * c * (1.0 - fc) * r_dry
    v_n2 = 0.79 * v_air + 0.8 * n * r_dry
    v_so2 = 0.7 * s * r_dry
    v_dry0 = v_co2_tot + v_n2 + v_o2 + v_so2
    v_co = min(co_ppm * 1e-6 * v_dry0, 0.5 * v_co2_tot)
    v_co2 = v_co2_tot - v_co
    v_o2 += 0.5 * v_co
    v_dry = v_co2 + v_co + v_n2 + v_o2 + v_so2
    if v_dry > 1e-9:
        o2 = 100.0 * v_o2 / v_dry
        co2 = 100.0 * v_co2 / v_dry
        ppm = 1e6 * v_co / v_dry
    else:
        o2 = 20.95
        co2 = 0.04
        ppm = 0.0
    m_fg = (
        RHO_CO2_N * v_co2 + RHO_CO_N * v_co + RHO_N2_N * v_n2 + RHO_O2_N * v_o2 + RHO_SO2_N * v_so2
    )
    m_vap_fuel = (9.0 * h + wd) * r_dry
    m_vap_air = x_air * RHO_AIR_N * v_air
    return v_dry, o2, co2, m_fg, m_vap_fuel, m_vap_air, RHO_CO_N * v_co, ppm


@njit(cache=True)
def co_ppm_model(lam: float, co_base: float, t_lit: float, burnout: bool) -> float:
    """CO in the dry flue gas [ppm]: rich and very lean combustion, cold start, burn-out."""
    if lam <= 0.0:
        return 0.0
    co = co_base * (1.0 + math.exp(min((1.35 - lam) / 0.07, 8.0)))
    if lam > 3.0:
        co += 20.0 * (lam - 3.0) ** 2
    co += 1500.0 * math.exp(-t_lit / 120.0)
    if burnout:
        co += 600.0
    return min(co, 20000.0)


@njit(cache=True)
def humidity_ratio(t_c: float, rh_pct: float, p_hpa: float) -> float:
    """Water per kg of dry air (Magnus formula for saturation pressure)."""
    ps = 6.112 * math.exp(17.62 * t_c / (243.12 + t_c))
    pv = min(max(rh_pct, 0.0), 100.0) / 100.0 * ps
    return 0.622 * pv / max(p_hpa - pv, 1.0)


def hhv_channiwala(c: float, h: float, o: float, n: float, s: float, ash: float) -> float:
    """Channiwala-Parikh correlation of the dry HHV [kJ/kg] (used only as a ratio)."""
    return (
        1000.0
        * (
            34.91 * c * 100
            + 117.83 * h * 100
            + 10.05 * s * 100
            - 10.34 * o * 100
            - 1.51 * n * 100
            - 2.11 * ash * 100
        )
        / 100.0
    )


def lhv_as_received(fuel: dict) -> float:
    """Net calorific value as received [kJ/kg] from the dry HHV, hydrogen and moisture."""
    w = float(fuel["moisture"])
    return float(fuel["hhv_dry_kJ_kg"]) * (1.0 - w) - DH_VAP * (9.0 * fuel["h"] * (1.0 - w) + w)


def gas_numbers(
    r_dry: float, lam: float, fuel: dict, x_air: float = 0.008, fc: float = 0.0
) -> dict[str, float]:
    """Flue-gas numbers of a steady fire (Python helper for calibration and tests)."""
    wd = fuel["moisture"] / (1.0 - fuel["moisture"])
    amin = air_min(fuel["c"], fuel["h"], fuel["o"], fuel["s"], fc)
    v_air = lam * amin * r_dry
    out = flue_gas(
        r_dry, v_air, x_air, fuel["c"], fuel["h"], fuel["o"], fuel["n"], fuel["s"], wd, fc, 0.0
    )
    w_g = (out[3] * CP_FG + (out[4] + out[5]) * CP_VAP) / 3600.0
    return {
        "v_air": v_air,
        "v_dry": out[0],
        "o2": out[1],
        "co2": out[2],
        "m_fg": out[3],
        "m_vap_fuel": out[4],
        "m_vap_air": out[5],
        "w_g": w_g,
        "air_min": amin,
    }


__all__ = [
    "CP_AIR",
    "CP_FG",
    "CP_VAP",
    "DH_CO",
    "DH_VAP",
    "HHV_CARBON",
    "RHO_AIR_N",
    "RHO_H2O_N",
    "air_min",
    "co_ppm_model",
    "flue_gas",
    "gas_numbers",
    "hhv_channiwala",
    "humidity_ratio",
    "lhv_as_received",
]
