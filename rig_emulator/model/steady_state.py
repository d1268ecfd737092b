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

import numpy as np

from rig_emulator.model import constants as k
from rig_emulator.model.boiler import (
    co_stationary_ppm,
    excess_air,
    flue_gas_loss_per_kg,
    flue_gas_temperature,
)
from rig_emulator.model.layout import K_HHV, K_LHV, K_P_MAX, K_P_MIN, K_SET, K_UA_ON


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
    c: np.ndarray, firing_kW: float, flow_kg_h: float, t_in_C: float, room_C: float
) -> tuple[float, float, float, float]:
    """(Q_hx, Q_fuel, flue-gas loss [kW], T_fg [C]) in stationary firing (Eq. 1, 3-6, 8, 9)."""
    x = firing_kW * 3600.0 / c[K_LHV]
    lam = excess_air(c, x)
    t_fg = flue_gas_temperature(c, t_in_C, flow_kg_h, x)
    sens, lat, chem = flue_gas_loss_per_kg(c, lam, t_fg, room_C, co_stationary_ppm(c, firing_kW))
    q_fuel = x / 3600.0 * c[K_HHV]
    q_fg = x / 3600.0 * (sens + lat + chem)
    q_hx = q_fuel * (1.0 - k.ASH_LOSS_FRACTION) - q_fg
    return q_hx, q_fuel, q_fg, t_fg


def steady_state(c: np.ndarray, flow_kg_h: float, t_in_C: float, room_C: float) -> SteadyState:
    """Steady state of the firing boiler (constants ``c`` of ``pack_constants``) for a held
    flow [kg/h], return and room temperature [C]."""
    m_cp = flow_kg_h * k.CP_WATER / 3600.0
    ua = c[K_UA_ON]
    p_min, p_max = c[K_P_MIN], c[K_P_MAX]
    q_set = m_cp * (c[K_SET] - t_in_C) + ua * (c[K_SET] - room_C)

    def hx(power: float) -> float:
        return exchanger_heat(c, power, flow_kg_h, t_in_C, room_C)[0]

    if hx(p_min) >= q_set:
        power = p_min
    elif hx(p_max) <= q_set:
        power = p_max
    else:
        # imported here: scipy.optimize takes a quarter of a second to load, and every
        # command that never asks for a steady state (serve, run, --help) paid it at start
        from scipy.optimize import brentq

        power = brentq(lambda w: hx(w) - q_set, p_min, p_max, xtol=1e-12)
    q_hx, q_fuel, q_fg, t_fg = exchanger_heat(c, power, flow_kg_h, t_in_C, room_C)
    t = (q_hx + m_cp * t_in_C + ua * room_C) / (m_cp + ua)
    return SteadyState(
        t_boiler_C=t,
        firing_kW=power,
        fuel_dry_kg_h=power * 3600.0 / c[K_LHV],
        t_flue_gas_C=t_fg,
        q_fuel_kW=q_fuel,
        q_hx_kW=q_hx,
        q_water_kW=m_cp * (t - t_in_C),
        q_amb_kW=ua * (t - room_C),
        q_flue_gas_kW=q_fg,
    )
