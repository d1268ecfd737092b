"""Fuel stoichiometry and flue-gas composition of the reality7 plant.

The combustion follows the digest's stoichiometric set (paper Section 2.1, Eq. 4-6 and 9):
volumes in m3 at 0 C and 1013 hPa per kg of dry fuel,

    air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21
    V_CO2 = 1.866 C,  V_H2O = 11.1 H + 1.244 w,  V_N2 = 0.79 lambda air_min + 0.8 N,
    V_O2 = 0.21 (lambda - 1) air_min.

The plant itself works with the actual air flow instead of lambda, so that purge air, burn-out
and idle draught (no fuel, or a bed burning down under a fan at constant speed) come out of the
same formulas.
"""

from __future__ import annotations

from dataclasses import dataclass

#: normal densities [kg/m3 at 0 C, 1013 hPa]
RHO_CO2 = 1.977
RHO_SO2 = 2.927
RHO_N2 = 1.2506
RHO_O2 = 1.429
RHO_H2O = 0.804
RHO_CO = 1.250
#: latent heat of water at 25 C [kJ/kg] (digest: dH_vap,w; HHV basis, so it is a loss, Eq. 5)
DH_VAP = 2442.0
#: heating value of CO [kJ/kg] (digest, Eq. 6: about 10.1 MJ/kg)
DH_CO = 10100.0


@dataclass(frozen=True)
class Fuel:
    """A fuel lot: dry-basis mass fractions, HHV on dry basis, moisture as received."""

    hhv_dry: float  # kJ/kg dry
    c: float
    h: float
    o: float
    n: float
    s: float
    ash: float
    moisture: float  # kg water per kg as received

    @property
    def w_dry(self) -> float:
        """Moisture per kg of dry fuel."""
        return self.moisture / (1.0 - self.moisture)

    @property
    def air_min(self) -> float:
        """Stoichiometric air [m3N per kg dry fuel]."""
        return (1.866 * self.c + 5.56 * self.h + 0.7 * self.s - 0.7 * self.o) / 0.21

    @property
    def v_h2o(self) -> float:
        """Water vapour in the flue gas [m3N per kg dry fuel] (hydrogen plus moisture)."""
        return 11.1 * self.h + 1.244 * self.w_dry

    @property
    def lhv_dry(self) -> float:
        """Net calorific value [kJ/kg dry], the vapour from hydrogen not condensed."""
        return self.hhv_dry - DH_VAP * 8.936 * self.h

    @property
    def lhv_ar(self) -> float:
        """Net calorific value as received [kJ/kg], the moisture evaporated as well."""
        return self.lhv_dry * (1.0 - self.moisture) - DH_VAP * self.moisture


def fuel_from_boiler(boiler: dict) -> Fuel:
    """The nominal fuel of a parameter file (CONTRACT section 2, paper Table 1)."""
    f = boiler["fuel"]
    return Fuel(
        hhv_dry=float(f["hhv_dry_kJ_kg"]),
        c=float(f["c"]),
        h=float(f["h"]),
        o=float(f["o"]),
        n=float(f["n"]),
        s=float(f["s"]),
        ash=float(f["ash"]),
        moisture=float(f["moisture"]),
    )
