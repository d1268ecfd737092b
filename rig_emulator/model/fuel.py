"""Fuel properties and complete-combustion stoichiometry (Table 1 of Carlon et al. 2015).

Volumes in m3(N) (0 C, 1013.25 hPa) and masses in kg, both per kg of *dry* fuel; the fuel's
mass fractions are on a dry basis, its moisture on an as-received basis.

Stoichiometry (textbook combustion calculation, e.g. Baehr, Thermodynamik, or EN 14785):

    air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21
    V_CO2 = 1.866 C;  V_SO2 = 0.7 S;  V_N2 = 0.79 lambda air_min + 0.8 N
    V_O2  = 0.21 (lambda - 1) air_min
    m_H2O = 8.937 H + w     (w = moisture per kg dry fuel)

Assumptions: complete conversion (the chemical loss of CO is accounted for separately and is
too small to change the volumes); air humidity is not added to the flue gas.
"""

from __future__ import annotations

from dataclasses import dataclass

from rig_emulator.model import constants as k


@dataclass(frozen=True, slots=True)
class Fuel:
    """A solid fuel.

    Attributes:
        hhv_dry_kJ_kg: gross calorific value, dry basis [kJ/kg].
        c, h, o, n, s, ash: mass fractions of the dry fuel [-].
        moisture: water mass fraction of the fuel as received [-].
    """

    hhv_dry_kJ_kg: float
    c: float
    h: float
    o: float
    n: float
    s: float
    ash: float
    moisture: float

    @property
    def water_per_kg_dry(self) -> float:
        """Moisture per kg of dry fuel [kg/kg]."""
        return self.moisture / (1.0 - self.moisture)

    @property
    def as_received_per_kg_dry(self) -> float:
        """Mass of fuel as received per kg of dry fuel [kg/kg]."""
        return 1.0 / (1.0 - self.moisture)

    @property
    def balance_loss_per_kg_dry(self) -> float:
        """What a balance under boiler and ash box loses per kg of dry fuel burnt [kg/kg]:
        the fuel as received less its ash, which stays in the ash box (assumption of the
        bench, :mod:`rig_emulator.bench.bench`)."""
        return self.as_received_per_kg_dry - self.ash

    @property
    def lhv_dry_kJ_kg(self) -> float:
        """Net calorific value, dry basis [kJ/kg]: HHV less the latent heat of the water
        formed from hydrogen (8.937 kg H2O per kg H, at 25 C)."""
        return self.hhv_dry_kJ_kg - k.DH_VAP_WATER * 8.937 * self.h


@dataclass(frozen=True, slots=True)
class Stoichiometry:
    """Flue-gas quantities per kg of dry fuel, linear in lambda where they depend on it.

    Attributes:
        air_min_m3: stoichiometric air [m3(N)/kg].
        v_co2_m3, v_so2_m3: CO2 and SO2 volumes [m3(N)/kg].
        v_n2_fuel_m3: nitrogen from the fuel [m3(N)/kg].
        m_h2o_kg: water vapour (formed plus moisture) [kg/kg].
    """

    air_min_m3: float
    v_co2_m3: float
    v_so2_m3: float
    v_n2_fuel_m3: float
    m_h2o_kg: float

    def dry_volume_m3(self, lam: float) -> float:
        """Dry flue-gas volume [m3(N)/kg dry fuel] at excess-air ratio ``lam``."""
        return (
            self.v_co2_m3
            + self.v_so2_m3
            + self.v_n2_fuel_m3
            + 0.79 * lam * self.air_min_m3
            + k.O2_AIR * (lam - 1.0) * self.air_min_m3
        )

    def dry_mass_kg(self, lam: float) -> float:
        """Dry flue-gas mass [kg/kg dry fuel] at excess-air ratio ``lam``."""
        a0, a1 = self.dry_mass_coeffs()
        return a0 + a1 * lam

    def dry_mass_coeffs(self) -> tuple[float, float]:
        """(a0, a1) with dry flue-gas mass = a0 + a1 lambda [kg/kg dry fuel]."""
        a = self.air_min_m3
        a0 = (
            self.v_co2_m3 * k.RHO_N_CO2
            + self.v_so2_m3 * k.RHO_N_SO2
            + self.v_n2_fuel_m3 * k.RHO_N_N2
            - k.O2_AIR * a * k.RHO_N_O2
        )
        a1 = 0.79 * a * k.RHO_N_N2 + k.O2_AIR * a * k.RHO_N_O2
        return a0, a1

    def dry_heat_capacity_coeffs(self) -> tuple[float, float]:
        """(b0, b1) with sum(m_i cp_i) of the dry flue gas = b0 + b1 lambda [kJ/(K kg fuel)]."""
        a = self.air_min_m3
        b0 = (
            self.v_co2_m3 * k.RHO_N_CO2 * k.CP_CO2
            + self.v_so2_m3 * k.RHO_N_SO2 * k.CP_SO2
            + self.v_n2_fuel_m3 * k.RHO_N_N2 * k.CP_N2
            - k.O2_AIR * a * k.RHO_N_O2 * k.CP_O2
        )
        b1 = 0.79 * a * k.RHO_N_N2 * k.CP_N2 + k.O2_AIR * a * k.RHO_N_O2 * k.CP_O2
        return b0, b1

    def wet_volume_m3(self, lam: float) -> float:
        """Wet flue-gas volume [m3(N)/kg dry fuel]."""
        return self.dry_volume_m3(lam) + self.m_h2o_kg / k.RHO_N_H2O

    def composition_dry_pct(self, lam: float) -> tuple[float, float, float, float]:
        """Dry flue-gas composition (O2, CO2, N2, SO2) [vol-%] at excess-air ratio ``lam``."""
        v = self.dry_volume_m3(lam)
        o2 = k.O2_AIR * (lam - 1.0) * self.air_min_m3
        n2 = 0.79 * lam * self.air_min_m3 + self.v_n2_fuel_m3
        return 100 * o2 / v, 100 * self.v_co2_m3 / v, 100 * n2 / v, 100 * self.v_so2_m3 / v

    def lambda_from_o2(self, o2_dry_pct: float) -> float:
        """Excess-air ratio from the dry O2 reading [vol-%], the exact inverse of
        :meth:`composition_dry_pct` (for wood close to 21 / (21 - O2))."""
        x = o2_dry_pct / 100.0
        a = self.air_min_m3
        rest = self.v_co2_m3 + self.v_so2_m3 + self.v_n2_fuel_m3 - k.O2_AIR * a
        return (x * rest + k.O2_AIR * a) / (a * (k.O2_AIR - x))


def stoichiometry(fuel: Fuel) -> Stoichiometry:
    """Complete-combustion stoichiometry of ``fuel`` (module docstring equations)."""
    air_min = (1.866 * fuel.c + 5.56 * fuel.h + 0.7 * fuel.s - 0.7 * fuel.o) / k.O2_AIR
    return Stoichiometry(
        air_min_m3=air_min,
        v_co2_m3=1.866 * fuel.c,
        v_so2_m3=0.7 * fuel.s,
        v_n2_fuel_m3=0.8 * fuel.n,
        m_h2o_kg=8.937 * fuel.h + fuel.water_per_kg_dry,
    )
