"""``body_heat_diffusion``: the body heats from the combustion chamber outwards.

The one node of capacity C = Ctherm + water is split into ``nodes`` metal nodes in series
(together ``metal_share`` C) and the water node ((1 - metal_share) C); the heat to the
exchanger enters the first metal node and is conducted node to node to the water; the water
node carries the flow, the loss to the room and the boiler's own sensor:

    C_m dT_1/dt = Q_hx + Q_el,ign - G (T_1 - T_2),   C_m = metal_share C / nodes
    C_m dT_i/dt = G (T_(i-1) - T_i) - G (T_i - T_(i+1))
    C_w dT_w/dt = G (T_n - T_w) - m_w cp_w (T_w - T_w,in) - UA (T_w - T_room)

Total capacity and every loss are the model's (Eq. 2, 7, 10 split over the nodes), so
energy is conserved and only the timing of the heat to water changes: the water lags at
start-up and after load steps, and the metal, hotter than the water by Q tau / C_metal in
steady firing, gives its excess ((nodes + 1) / (2 nodes) Q tau) to the water after a stop.

Numerics: backward Euler over the metal nodes and the water node (a tridiagonal system,
L-stable for any conduction time constant). Its step-end temperatures define the heat
flows, so the balance Q_in = Q_water + Q_amb + sum C_i dT_i/dt closes to rounding.

Stage: ``heat_store``. The controller waits out 0.8 tau (assumption: behind the lag an
ideal one-step controller would hunt between Pmin and Pmax).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig_emulator.bench.effects._spec import EffectSpec, ParamSpec
from rig_emulator.model import boiler as bm
from rig_emulator.model.layout import index_of

#: Maximum number of metal nodes.
MAX_BODY_NODES = 6
#: Share of the conduction time constant the controller waits out (assumption).
HORIZON_PER_BODY_TAU = 0.8

CONSTANTS = (
    "on",
    "metal_nodes",  # [-]
    "metal_node_capacity_kJ_K",
    "water_capacity_kJ_K",
    "link_conductance_kW_K",
)
C = index_of(CONSTANTS)
C_ON = C["on"]
C_NODES = C["metal_nodes"]
C_CM = C["metal_node_capacity_kJ_K"]
C_CW = C["water_capacity_kJ_K"]
C_G = C["link_conductance_kW_K"]

STATE = tuple(f"metal_{i}_C" for i in range(MAX_BODY_NODES))  # metal nodes, flame side first
S_METAL = index_of(STATE)["metal_0_C"]  # the others follow in order


def pack(values, params) -> dict[str, float]:
    """Constants from the resolved parameters and the boiler (its capacity C)."""
    n = int(values["nodes"])
    cap = params.capacity_kJ_K
    c_metal = values["metal_share"] * cap
    return {
        "metal_nodes": n,
        "metal_node_capacity_kJ_K": c_metal / n,
        "water_capacity_kJ_K": cap - c_metal,
        "link_conductance_kW_K": n * c_metal / values["time_constant_s"],
    }


@njit(cache=True)
def body_chain(fc, fs, row, t_w0, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s):
    """Advance metal nodes and water node by backward Euler (equations above); the metal
    temperatures are in row ``row`` of ``fs``.

    Returns (water temperature at the end [C], heat stored in all nodes [kW]).
    """
    n = int(fc[row, C_NODES])
    cm = fc[row, C_CM] / dt_s
    cw = fc[row, C_CW] / dt_s
    g = fc[row, C_G]
    # tridiagonal system over nodes 0..n (n = water): sub a, diagonal b, super c, rhs d
    b = np.empty(n + 1)
    d = np.empty(n + 1)
    for i in range(n):
        b[i] = cm + 2.0 * g
        d[i] = cm * fs[row, S_METAL + i]
    b[0] = cm + g
    d[0] += q_in_kW
    b[n] = cw + g + m_cp + ua
    d[n] = cw * t_w0 + m_cp * water_in_C + ua * room_C
    # Thomas algorithm, a = c = -g everywhere
    for i in range(1, n + 1):
        w = -g / b[i - 1]
        b[i] += w * g
        d[i] -= w * d[i - 1]
    t_new = d[n] / b[n]
    stored = fc[row, C_CW] * (t_new - t_w0)
    t_next = t_new
    for i in range(n - 1, -1, -1):
        t_i = (d[i] + g * t_next) / b[i]
        stored += fc[row, C_CM] * (t_i - fs[row, S_METAL + i])
        fs[row, S_METAL + i] = t_i
        t_next = t_i
    return t_new, stored / dt_s


@njit(cache=True, inline="always")
def heat_store(c, fc, fs, row, t0_C, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s):
    """``heat_store``: the metal chain and the water node, or the model's one node if off."""
    if fc[row, C_ON] < 0.5:
        return bm.model_heat_store(
            c, fc, fs, row, t0_C, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s
        )
    t1, q_stored = body_chain(fc, fs, row, t0_C, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s)
    return t1, t1, q_stored


EFFECT = EffectSpec(
    name="body_heat_diffusion",
    params=(
        ParamSpec(
            "time_constant_s",
            "s",
            250.0,
            "linear",
            0.0,
            3600.0,
            doc="tau = C_metal / G_path, G_path = G / nodes the series conductance of the "
            "whole path (0: the one-node model)",
        ),
        ParamSpec(
            "metal_share",
            "-",
            0.40,
            "shape",
            0.05,
            0.95,
            doc="share of the node's capacity in the metal (lab: Ctherm / C of Table 3)",
        ),
        ParamSpec(
            "nodes",
            "-",
            3.0,
            "shape",
            1.0,
            MAX_BODY_NODES,
            integer=True,
            doc="metal nodes in series",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: v["time_constant_s"] > 0.0,
    stages={"heat_store": heat_store},
    constants=CONSTANTS,
    state=STATE,
    pack=pack,
    initial_state=lambda t_C: dict.fromkeys(STATE, t_C),
    horizon_s=lambda v: HORIZON_PER_BODY_TAU * v["time_constant_s"],
)
