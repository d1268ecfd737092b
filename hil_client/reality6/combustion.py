"""Fuel stoichiometry and flue-gas bookkeeping of the reality-6 plant.

Follows Carlon et al. (2015), Section 2.1 and 2.4:

* Eq. 3: Q_fuel = m_fuel,dry * HHV_dry / 3.6e3 (kW with m in kg/h), HHV on dry basis.
* Eq. 4: Q_fg,sens = (m_fg * cp_fg + m_w,fg * cp_vap) * (T_fg - T_room) / 3.6e3.
* Eq. 5: Q_fg,chem = m_CO,fg * dH_CO,comb / 3.6e3.
* Eq. 6: Q_fg,lat = m_w,fg * dH_vap,w / 3.6e3 (HHV basis: the vapour's latent heat is lost).
* Eq. 9: lambda = facA + facB * m_fuel,dry (kg/h) for the excess-air ratio.

Assumptions (ours): complete conversion of C to CO2 (the CO is a small extra loss and does not
reduce the CO2), volumes in m3 at 0 C and 1013 hPa; the usual textbook stoichiometry
(air_min = (1.866 C + 5.56 H + 0.7 S - 0.7 O) / 0.21 per kg dry fuel); the dry flue gas mass
per kg dry fuel is linear in lambda, MFG0 + MFG1 * lambda.
"""

from __future__ import annotations

from dataclasses import dataclass

CP_WATER_KJ_KG_K = 4.186
CP_FLUE_DRY_KJ_KG_K = 1.04
CP_VAPOUR_KJ_KG_K = 1.87
DH_VAP_WATER_KJ_KG = 2442.0
DH_CO_COMB_KJ_KG = 10_100.0
RHO_CO2_KG_M3 = 1.977
RHO_SO2_KG_M3 = 2.926
RHO_N2_KG_M3 = 1.2505
RHO_O2_KG_M3 = 1.429
RHO_AIR_KG_M3 = 1.293
RHO_CO_KG_M3 = 1.250
RHO_VAPOUR_KG_M3 = 0.804
ASH_LOSS_FRACTION = 0.0002  # EN 14785 value used by the paper for Q_ash / Q_fuel
ROOM_AIR_O2_PCT = 20.9
ROOM_AIR_CO2_PCT = 0.04


@dataclass(frozen=True)
class FuelStoichiometry:
    """Per-kg-dry-fuel flue-gas figures of one fuel (m3 at 0 C, 1013 hPa and kg)."""

    hhv_dry_kJ_kg: float
    moisture_ar: float
    carbon: float
    air_min_m3_kg: float
    v_co2_m3_kg: float
    v_so2_m3_kg: float
    v_n2_fuel_m3_kg: float
    vapour_kg_kg: float
    dry_gas_mass_const_kg_kg: float  # MFG0: dry gas mass without the air's lambda share
    dry_gas_mass_per_lambda_kg_kg: float  # MFG1 = air_min * rho_air
    dry_gas_volume_const_m3_kg: float  # dry gas volume without the air's lambda share
    lhv_ar_kJ_kg: float  # net calorific value as received

    @property
    def hhv_ar_kJ_kg(self) -> float:
        return self.hhv_dry_kJ_kg * (1.0 - self.moisture_ar)


def stoichiometry(
    fuel: dict, *, hhv_dry_kJ_kg: float | None = None, moisture_ar: float | None = None
) -> FuelStoichiometry:
    """Flue-gas figures per kg of dry fuel for a fuel dict of the boiler YAML.

    `hhv_dry_kJ_kg` and `moisture_ar` override the documented values (the plant's real lot).
    """
    c, h, o = float(fuel["c"]), float(fuel["h"]), float(fuel["o"])
    n, s = float(fuel["n"]), float(fuel["s"])
    hhv = float(fuel["hhv_dry_kJ_kg"]) if hhv_dry_kJ_kg is None else float(hhv_dry_kJ_kg)
    w = float(fuel["moisture"]) if moisture_ar is None else float(moisture_ar)
    water_per_dry = w / (1.0 - w)
    air_min = (1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21
    v_co2 = 1.866 * c
    v_so2 = 0.7 * s
    v_n2_fuel = 0.8 * n
    v_h2o = 11.1 * h + 1.244 * water_per_dry
    mfg0 = (
        RHO_CO2_KG_M3 * v_co2
        + RHO_SO2_KG_M3 * v_so2
        + RHO_N2_KG_M3 * v_n2_fuel
        - RHO_O2_KG_M3 * 0.21 * air_min  # oxygen consumed by the fuel
    )
    mfg1 = RHO_AIR_KG_M3 * air_min
    vd0 = v_co2 + v_so2 + v_n2_fuel - 0.21 * air_min
    vapour = RHO_VAPOUR_KG_M3 * v_h2o
    lhv_dry = hhv - DH_VAP_WATER_KJ_KG * 9.0 * h
    lhv_ar = lhv_dry * (1.0 - w) - DH_VAP_WATER_KJ_KG * w
    return FuelStoichiometry(
        hhv_dry_kJ_kg=hhv,
        moisture_ar=w,
        carbon=c,
        air_min_m3_kg=air_min,
        v_co2_m3_kg=v_co2,
        v_so2_m3_kg=v_so2,
        v_n2_fuel_m3_kg=v_n2_fuel,
        vapour_kg_kg=vapour,
        dry_gas_mass_const_kg_kg=mfg0,
        dry_gas_mass_per_lambda_kg_kg=mfg1,
        dry_gas_volume_const_m3_kg=vd0,
        lhv_ar_kJ_kg=lhv_ar,
    )


def dry_o2_pct(st: FuelStoichiometry, excess_air: float) -> float:
    """Dry flue-gas O2 (vol-%) at complete combustion for an excess-air ratio."""
    v_o2 = 0.21 * (excess_air - 1.0) * st.air_min_m3_kg
    v_dry = st.dry_gas_volume_const_m3_kg + excess_air * st.air_min_m3_kg
    return 100.0 * v_o2 / v_dry
