"""Closed-form steady state of the one-node model (dT_boiler/dt = 0).

With the return temperature, flow and room held, Eq. 2 and 10 in steady state give

    Q_hx = m_w cp_w (T - T_in) / 3600 + UA_on (T - T_room)

If the heat needed at the set temperature lies between what the burner delivers at Pmin and
Pmax, T = T_set and the firing power solves Q_hx(P) = that heat; otherwise the burner sits at
the bound and T follows from the same equation. The algebraic root replaces the time
integration, which is what the simulation must converge to.
"""

from __future__ import annotations

from dataclasses import dataclass

from scipy.optimize import brentq

from rig_emulator.model import constants as k
from rig_emulator.model.boiler import BoilerCoefficients, flue_gas_temperature
from rig_emulator.model.emissions import co_ppm
from rig_emulator.model.params import BoilerParams


@dataclass(frozen=True, slots=True)
class SteadyState:
    """Steady operating point: temperatures [C], powers [kW], fuel [kg/h dry]."""

    t_boiler_C: float
    firing_kW: float
    fuel_dry_kg_h: float
    t_flue_gas_C: float
    q_fuel_kW: float
    q_hx_kW: float
    q_water_kW: float
    q_amb_kW: float
    q_flue_gas_kW: float  # sensible + latent + chemical


def exchanger_heat(
    p: BoilerParams, c: BoilerCoefficients, firing_kW: float, flow_kg_h: float, t_in_C: float,
    room_C: float,
) -> tuple[float, float, float, float]:
    """(Q_hx, Q_fuel, flue-gas loss [kW], T_fg [C]) in stationary firing (no start transient)."""
    x = firing_kW * 3600.0 / c.lhv
    lam = p.fac_a_lambda + p.fac_b_lambda_h_kg * x
    t_fg = flue_gas_temperature(p, c, t_in_C, flow_kg_h, x)
    co = co_ppm(
        firing_kW, p.p_min_kW, p.p_max_kW, p.co_ppm_at_p_min, p.co_ppm_at_p_max, 0.0, 0.0,
        p.co_transient_s, float("inf"), float("inf"),
    )
    per_h = x / 3600.0
    q_fuel = per_h * c.hhv
    sens = ((c.b0 + c.b1 * lam) + c.m_h2o * k.CP_VAPOUR) * (t_fg - room_C)
    chem = co * 1e-6 * (c.v_dry0 + c.v_dry1 * lam) * k.RHO_N_CO * k.DH_COMB_CO
    q_fg = per_h * (sens + c.latent + chem)
    q_hx = q_fuel * (1.0 - k.ASH_LOSS_FRACTION) - q_fg
    return q_hx, q_fuel, q_fg, t_fg


def steady_state(
    p: BoilerParams, c: BoilerCoefficients, flow_kg_h: float, t_in_C: float, room_C: float
) -> SteadyState:
    """Steady state of the firing boiler for a held flow [kg/h], return and room [C]."""
    m_cp = flow_kg_h * k.CP_WATER / 3600.0
    ua = c.ua_on

    def need(t: float) -> float:
        return m_cp * (t - t_in_C) + ua * (t - room_C)

    def hx(power: float) -> float:
        return exchanger_heat(p, c, power, flow_kg_h, t_in_C, room_C)[0]

    q_set = need(p.set_temp_C)
    if hx(p.p_min_kW) >= q_set:
        power = p.p_min_kW
    elif hx(p.p_max_kW) <= q_set:
        power = p.p_max_kW
    else:
        power = brentq(lambda w: hx(w) - q_set, p.p_min_kW, p.p_max_kW, xtol=1e-12)
    q_hx, q_fuel, q_fg, t_fg = exchanger_heat(p, c, power, flow_kg_h, t_in_C, room_C)
    t = (q_hx + m_cp * t_in_C + ua * room_C) / (m_cp + ua)
    return SteadyState(
        t_boiler_C=t,
        firing_kW=power,
        fuel_dry_kg_h=power * 3600.0 / c.lhv,
        t_flue_gas_C=t_fg,
        q_fuel_kW=q_fuel,
        q_hx_kW=q_hx,
        q_water_kW=m_cp * (t - t_in_C),
        q_amb_kW=ua * (t - room_C),
        q_flue_gas_kW=q_fg,
    )
