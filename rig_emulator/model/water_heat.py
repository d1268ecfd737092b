"""Heat carried by the water circuit (Carlon et al. 2015, Eq. 7).

The lab measures the heat to water as Q = m_w cp_w (T_out - T_in), with the mass flow of
the inductive meter and the forward and return temperatures; cp_w is constant
(:data:`~rig_emulator.model.constants.CP_WATER`, EN 14785's 4.19 kJ/(kg K)).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from rig_emulator.model.constants import CP_WATER

Value = TypeVar("Value", float, np.ndarray)


def heat_to_water_kW(flow_kg_h: Value, t_in_C: Value, t_out_C: Value) -> Value:
    """Heat to water [kW] (Eq. 7) for a flow [kg/h] between return and forward [C]."""
    return flow_kg_h * CP_WATER * (t_out_C - t_in_C) / 3600.0


def flow_for_heat_kg_h(heat_kW: float, spread_K: float) -> float:
    """Water flow [kg/h] that carries ``heat_kW`` at a forward-return spread (Eq. 7 solved
    for the flow)."""
    return heat_kW * 3600.0 / (CP_WATER * spread_K)
