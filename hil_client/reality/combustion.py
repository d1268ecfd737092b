"""Combustion of the real boiler's fuel, written from Carlon et al. (2015) Section 2.1 and the
digest's stoichiometric set (complete conversion of C, H, S; volumes at 0 C, 1013.25 hPa).

Per kg of *dry* fuel with mass fractions c, h, o, n, s (dry basis) and moisture
w = M_ar / (1 - M_ar) kg per kg dry fuel (M_ar: moisture as received):

    O_min   = 1.866 c + 5.56 h + 0.7 s - 0.7 o          [Nm3 O2 / kg]
    air_min = O_min / 0.21                              [Nm3 air / kg]
    V_CO2 = 1.866 c,  V_SO2 = 0.7 s,  V_N2,fuel = 0.8 n,  V_H2O = 11.1 h + 1.244 w

For an air volume V_air [Nm3/h] burning B [kg dry/h] the dry flue gas holds
V_O2 = 0.21 V_air - O_min B and V_N2 = 0.79 V_air + 0.8 n B, so that
lambda = V_air / (air_min B) and the dry-gas O2 follows as a volume fraction.

The flue-gas loss terms are Eq. 4-6 of the paper: sensible heat of dry gas plus vapour
against the room temperature, latent heat of the fuel's water (hydrogen and moisture; HHV
basis), and the chemical loss of CO (Eq. 5). Mean specific heats over 20-200 C are the
assumption here (textbook values, e.g. VDI Heat Atlas D1).

This module is independent of the emulator's model: nothing is imported from it.
"""

from __future__ import annotations

import math
from typing import Any

# --- constants (textbook values; units in the names)
NORMAL_DENSITY_KG_NM3 = {  # ideal-gas densities at 0 C, 1013.25 hPa
    "CO2": 1.977,
    "SO2": 2.926,
    "N2": 1.2506,
    "O2": 1.429,
    "H2O": 0.804,
    "air": 1.293,
    "CO": 1.250,
}
CP_KJ_KG_K = {"CO2": 0.92, "SO2": 0.64, "N2": 1.04, "O2": 0.92, "H2O": 1.88}  # 20-200 C means
CP_AIR_KJ_KG_K = 1.006
DH_VAP_KJ_KG = 2442.0  # latent heat of water at 25 C (reference of the HHV)
DH_CO_KJ_KG = 10_100.0  # heat of combustion of CO (paper, Eq. 5: about 10.1 MJ/kg)
CP_WATER_KJ_KG_K = 4.186  # liquid water, 40-80 C
RHO_WATER_KG_M3 = 983.0  # liquid water at 60 C
ASH_LOSS_SHARE = 0.0002  # Q_ash: 0.02 percentage points of Q_fuel (EN 14785, digest)


def fuel_constants(fuel: dict[str, float], moisture_ar: float | None = None) -> dict[str, Any]:
    """Per-kg-dry-fuel figures of the stoichiometric set above.

    Args:
        fuel: the boiler file's ``fuel`` mapping (CONTRACT section 2).
        moisture_ar: moisture as received [-] if it differs from the file's (the
            ``fuel_energy_bias`` moisture form).
    """
    c, h, o, n, s = (float(fuel[k]) for k in ("c", "h", "o", "n", "s"))
    m_ar = float(fuel["moisture"]) if moisture_ar is None else float(moisture_ar)
    w = m_ar / (1.0 - m_ar)
    o_min = 1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o
    hhv = float(fuel["hhv_dry_kJ_kg"])
    water_h_kg = 11.1 * h * NORMAL_DENSITY_KG_NM3["H2O"]  # water formed from hydrogen
    lhv_dry = hhv - DH_VAP_KJ_KG * water_h_kg
    return {
        "o_min_nm3_kg": o_min,
        "air_min_nm3_kg": o_min / 0.21,
        "v_co2_nm3_kg": 1.866 * c,
        "v_so2_nm3_kg": 0.7 * s,
        "v_n2_fuel_nm3_kg": 0.8 * n,
        "water_from_h_kg_kg": water_h_kg,
        "moisture_kg_kg_dry": w,
        "moisture_ar": m_ar,
        "hhv_dry_kJ_kg": hhv,
        "lhv_dry_kJ_kg": lhv_dry,
        # LHV of the fuel as received (what a volumetric auger delivers per kg)
        "lhv_ar_kJ_kg": lhv_dry * (1.0 - m_ar) - DH_VAP_KJ_KG * m_ar,
        "ash_kg_kg": float(fuel["ash"]),
    }


def lambda_from_air(v_air_nm3_h: float, burn_dry_kg_h: float, air_min_nm3_kg: float) -> float:
    """Excess-air ratio: supplied over stoichiometric air (Eq. 9's lambda)."""
    if burn_dry_kg_h <= 0.0:
        return math.inf
    return v_air_nm3_h / (air_min_nm3_kg * burn_dry_kg_h)


def dry_gas_o2_pct(v_air_nm3_h: float, burn_dry_kg_h: float, fc: dict[str, Any]) -> float:
    """O2 [vol-%, dry] of the flue gas of ``burn_dry_kg_h`` in ``v_air_nm3_h`` of air."""
    v_o2 = 0.21 * v_air_nm3_h - fc["o_min_nm3_kg"] * burn_dry_kg_h
    v_dry = (
        v_o2
        + 0.79 * v_air_nm3_h
        + (fc["v_n2_fuel_nm3_kg"] + fc["v_co2_nm3_kg"] + fc["v_so2_nm3_kg"]) * burn_dry_kg_h
    )
    return 100.0 * v_o2 / v_dry


def humidity_ratio(room_temp_C: float, rel_humidity_pct: float, pressure_hPa: float) -> float:
    """Water vapour per kg dry air [kg/kg]: x = 0.622 p_v / (p - p_v), p_v = phi p_sat with
    the Magnus formula p_sat = 6.112 exp(17.62 t / (243.12 + t)) hPa."""
    p_sat = 6.112 * math.exp(17.62 * room_temp_C / (243.12 + room_temp_C))
    p_v = rel_humidity_pct / 100.0 * p_sat
    return 0.622 * p_v / (pressure_hPa - p_v)
