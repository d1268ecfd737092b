"""Fuel stoichiometry (complete conversion), per kg of dry fuel, from the ultimate analysis.

Volumes in m3 at 0 C and 1013 hPa (m3N). Assumptions: air is 21 vol-% O2 and 1.293 kg/m3N;
fuel nitrogen leaves as N2; sulphur as SO2; the fuel's hydrogen leaves as vapour (9 kg per kg H)
together with the fuel moisture. Equations (digest Sec. 1):

    air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21,  V_CO2 = 1.866 C,  V_SO2 = 0.7 S,
    V_N2,fuel = 0.8 N,  O2 need = 0.21 air_min,
    LHV_ar = HHV_dry (1 - w) - dH_vap (9 H (1 - w) + w)     [kJ/kg as received].
"""

from __future__ import annotations

DH_VAP_KJ_KG = 2442.0  # latent heat of water at 25 C


def stoichiometry(fuel: dict) -> dict[str, float]:
    """Air need, product volumes and net calorific value of the fuel mapping of a boiler YAML."""
    c, h, o, s, n = (float(fuel[k]) for k in ("c", "h", "o", "s", "n"))
    w = float(fuel["moisture"])
    air_min_v = (1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21
    hhv = float(fuel["hhv_dry_kJ_kg"])
    return {
        "air_min_v": air_min_v,
        "air_min_mass": air_min_v * 1.293,
        "o2_need": 0.21 * air_min_v,
        "v_co2": 1.866 * c,
        "v_so2": 0.7 * s,
        "v_n2f": 0.8 * n,
        "lhv_ar": hhv * (1.0 - w) - DH_VAP_KJ_KG * (9.0 * h * (1.0 - w) + w),
    }


def o2_dry_pct(lam: float, fuel: dict) -> float:
    """Dry-gas O2 (vol-%) of complete combustion at excess air ratio ``lam``."""
    st = stoichiometry(fuel)
    va = lam * st["air_min_v"]
    v_o2 = 0.21 * va - st["o2_need"]
    v_dry = st["v_co2"] + st["v_so2"] + st["v_n2f"] + 0.79 * va + v_o2
    return 100.0 * v_o2 / v_dry
