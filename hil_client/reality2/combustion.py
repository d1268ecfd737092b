"""Stoichiometry of the fuel (digest section 1, textbook combustion calculation).

Per kg of dry fuel, volumes in m3(N) (0 C, 1013.25 hPa): stoichiometric air
``air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21``; CO2 ``1.866 C``; SO2 ``0.7 S``;
nitrogen from the fuel ``0.8 N``; at excess-air ratio lambda the dry gas holds
``0.79 lambda air_min`` N2 from the air and ``0.21 (lambda - 1) air_min`` O2. The water vapour
is what the hydrogen forms (8.94 kg per kg H) plus the moisture.
"""

from __future__ import annotations

from collections.abc import Mapping

from hil_client.reality2.layout import DH_VAP

#: Normal densities [kg/m3(N)] (DIN 1343).
RHO_N = {"co2": 1.977, "so2": 2.926, "n2": 1.2505, "o2": 1.429, "h2o": 0.804, "air": 1.293}


def stoichiometry(fuel: Mapping[str, float], moisture: float) -> dict[str, float]:
    """Named flue-gas coefficients per kg of dry fuel for ``moisture`` (as received).

    Returns ``air_min`` [m3N/kg], ``vdry0``/``vdry1`` (dry volume = vdry0 + vdry1 lambda),
    ``gas_a0``/``gas_a1`` (dry mass [kg/kg] = a0 + a1 lambda), ``vco2`` [m3N/kg],
    ``vapour`` [kg/kg] and ``lhv`` [kJ/kg dry].
    """
    c, h, o, n, s = (float(fuel[k]) for k in ("c", "h", "o", "n", "s"))
    air_min = (1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21
    vco2, vso2, vn2 = 1.866 * c, 0.7 * s, 0.8 * n
    vdry0 = vco2 + vso2 + vn2 - 0.21 * air_min
    gas_a0 = vco2 * RHO_N["co2"] + vso2 * RHO_N["so2"] + vn2 * RHO_N["n2"]
    gas_a0 -= 0.21 * air_min * RHO_N["o2"]
    gas_a1 = air_min * (0.79 * RHO_N["n2"] + 0.21 * RHO_N["o2"])
    vapour = 8.937 * h + moisture / (1.0 - moisture)
    lhv = float(fuel["hhv_dry_kJ_kg"]) - DH_VAP * 8.937 * h
    return {
        "air_min": air_min,
        "vdry0": vdry0,
        "vdry1": air_min,
        "gas_a0": gas_a0,
        "gas_a1": gas_a1,
        "vco2": vco2,
        "vapour": vapour,
        "lhv": lhv,
    }


def o2_dry_pct(st: Mapping[str, float], lam: float) -> float:
    """Dry O2 [vol-%] at excess-air ratio ``lam``."""
    return 100.0 * 0.21 * (lam - 1.0) * st["air_min"] / (st["vdry0"] + st["vdry1"] * lam)
