"""Combustion stoichiometry of the Table 1 fuel."""

import math

import pytest

from rig_emulator.model import constants as k
from rig_emulator.model.fuel import stoichiometry


def test_stoichiometric_air_of_table1_pellets(params_12kw):
    fuel = params_12kw.fuel
    st = stoichiometry(fuel)
    # hand calculation with the digest's formula: (1.866*0.5031 + 5.56*0.0605 + 0.7*0.0001
    # - 0.7*0.4310) / 0.21 = 4.636 m3(N)/kg dry; textbook wood 4.5-4.7
    assert st.air_min_m3 == pytest.approx(4.636, abs=0.002)
    assert st.m_h2o_kg == pytest.approx(8.937 * 0.0605 + 0.0594 / (1 - 0.0594), rel=1e-12)


@pytest.mark.parametrize("lam", [1.2, 1.5, 2.0, 3.0, 4.5])
def test_dry_composition_closes_and_inverts(params_12kw, lam):
    st = stoichiometry(params_12kw.fuel)
    o2, co2, n2, so2 = st.composition_dry_pct(lam)
    assert o2 + co2 + n2 + so2 == pytest.approx(100.0, abs=1e-9)
    assert st.lambda_from_o2(o2) == pytest.approx(lam, rel=1e-12)
    # digest section 1: for wood lambda ~ 21 / (21 - O2) to within about 1 %
    assert 21.0 / (21.0 - o2) == pytest.approx(lam, rel=0.01)


def test_dry_mass_and_heat_capacity_are_consistent(params_12kw):
    st = stoichiometry(params_12kw.fuel)
    lam = 2.0
    v = st.dry_volume_m3(lam)
    a0, a1 = st.dry_mass_coeffs()
    b0, b1 = st.dry_heat_capacity_coeffs()
    mass = a0 + a1 * lam
    # density of a dry flue gas is between N2 and CO2 at normal state
    assert k.RHO_N_N2 < mass / v < k.RHO_N_CO2
    # mean cp between the lowest and highest component cp
    assert k.CP_CO2 < (b0 + b1 * lam) / mass < k.CP_N2


def test_net_calorific_value(params_12kw):
    fuel = params_12kw.fuel
    # LHV = HHV - 2442 kJ/kg * 8.937 * H: 20070 - 1320.4 = 18749.6 kJ/kg dry
    assert fuel.lhv_dry_kJ_kg == pytest.approx(18749.6, abs=0.1)
    assert math.isclose(fuel.as_received_per_kg_dry, 1 / (1 - 0.0594))
