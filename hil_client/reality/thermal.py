"""Thermal parts of the real boiler and its bench (numba kernels, one substep each).

Every update is written so that the energy it books closes exactly per step (to floating
rounding): the fluxes booked are the ones the update used.

- :func:`chain_step`: the body as a chain of lumps (metal layers, water, firebox) joined by
  conductances, backward Euler (unconditionally stable), solved with the Thomas algorithm.
  With C_k the capacities, L_k the conductance between lump k and k+1, Q_k the heat put
  into lump k, the water lump ``iw`` carrying the flow m cp (T_in - T_w) and the loss to
  the room UA (T_room - T_w):

      C_k (T_k' - T_k) / h = Q_k + L_(k-1) (T_(k-1)' - T_k') + L_k (T_(k+1)' - T_k') + sinks_k

  so that sum_k C_k (T_k' - T_k) = h (sum Q_k - m cp (T_w' - T_in) - UA (T_w' - T_room))
  holds to rounding: the storage change, the heat to water and the room loss are booked
  with the new water temperature.
- :func:`plug_pipe_step`: the exit pipe as plug flow (cells advected without mixing: a
  transport dead time of pipe mass / flow), each cell losing heat to the room with its own
  time constant (exact exponential).
- :func:`mixed_pipe_step`: the exit pipe as a mixed water volume with a pipe-wall node that
  loses heat to the room by natural convection, h ~ dT^(1/4) (conductance frozen over the
  step, backward Euler for the pair).
- :func:`storage_step`: flue-gas heat storage (refractory, duct): the gas leaves a storage
  node at T_s + (T_gas - T_s) exp(-NTU) and gives the difference to it; the node loses
  heat to the room (explicit, stable for C / (W + UA) >> h).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def chain_step(temps, caps, links, q_in, n, iw, h, flow_kW_K, t_in, ua_kW_K, t_room, work):
    """Advance the chain of ``n`` lumps by ``h`` seconds in place (see module docstring).

    ``links[k]`` joins lump k and k+1 [kW/K]; ``q_in[k]`` [kW]; ``work`` is scratch of size
    >= 4 n. Returns (heat to water [kJ], loss to the room [kJ]) over the step."""
    a = work[0:n]  # sub-diagonal
    b = work[n : 2 * n]  # diagonal
    c = work[2 * n : 3 * n]  # super-diagonal
    d = work[3 * n : 4 * n]  # right-hand side
    for k in range(n):
        b[k] = caps[k] / h
        d[k] = caps[k] / h * temps[k] + q_in[k]
        a[k] = 0.0
        c[k] = 0.0
    for k in range(n - 1):
        g = links[k]
        b[k] += g
        b[k + 1] += g
        c[k] = -g
        a[k + 1] = -g
    b[iw] += flow_kW_K + ua_kW_K
    d[iw] += flow_kW_K * t_in + ua_kW_K * t_room
    # Thomas algorithm
    for k in range(1, n):
        m = a[k] / b[k - 1]
        b[k] -= m * c[k - 1]
        d[k] -= m * d[k - 1]
    temps[n - 1] = d[n - 1] / b[n - 1]
    for k in range(n - 2, -1, -1):
        temps[k] = (d[k] - c[k] * temps[k + 1]) / b[k]
    tw = temps[iw]
    return h * flow_kW_K * (tw - t_in), h * ua_kW_K * (tw - t_room)


@njit(cache=True)
def plug_pipe_step(cells, t_boiler, flow_kg_h, h, cell_kg, carry, tau_loss_s, t_room):
    """Plug flow through ``cells`` (index 0 at the boiler, the sensor at the end).

    ``carry[0]`` accumulates the mass that has flowed in since the last whole cell. Every
    cell then relaxes towards the room: T' = T_room + (T - T_room) exp(-h / tau_loss)."""
    carry[0] += max(flow_kg_h, 0.0) * h / 3600.0
    n = cells.size
    shifts = 0
    while carry[0] >= cell_kg and shifts < n:
        for k in range(n - 1, 0, -1):
            cells[k] = cells[k - 1]
        cells[0] = t_boiler
        carry[0] -= cell_kg
        shifts += 1
    if shifts == n:
        carry[0] = carry[0] % cell_kg
    decay = np.exp(-h / tau_loss_s)
    for k in range(n):
        cells[k] = t_room + (cells[k] - t_room) * decay
    return cells[n - 1]


@njit(cache=True)
def mixed_pipe_step(
    state, t_boiler, flow_kg_h, h, water_kJ_K, wall_kJ_K, g_wall_kW_K, g_loss40_kW_K, t_room
):
    """Mixed pipe water ``state[0]`` with its wall ``state[1]``; returns the water's
    temperature. The wall loses G(dT) (T_wall - T_room) with G = g_loss40 (|dT| / 40 K)^0.25
    (natural convection), frozen over the step."""
    tw, tm = state[0], state[1]
    f = max(flow_kg_h, 0.0) * 4.186 / 3600.0  # [kW/K]
    g_loss = g_loss40_kW_K * max(abs(tm - t_room) / 40.0, 0.05) ** 0.25
    # backward Euler of the 2x2 system
    a11 = water_kJ_K / h + f + g_wall_kW_K
    a12 = -g_wall_kW_K
    a22 = wall_kJ_K / h + g_wall_kW_K + g_loss
    b1 = water_kJ_K / h * tw + f * t_boiler
    b2 = wall_kJ_K / h * tm + g_loss * t_room
    det = a11 * a22 - a12 * a12
    tw_new = (b1 * a22 - a12 * b2) / det
    tm_new = (a11 * b2 - a12 * b1) / det
    state[0] = tw_new
    state[1] = tm_new
    return tw_new


@njit(cache=True)
def storage_step(t_store, i, t_gas, w_kW_K, ntu, cap_kJ_K, ua_kW_K, t_room, h):
    """Gas at ``t_gas`` passes storage node ``t_store[i]``; returns (gas temperature after
    it, heat lost by the node to the room over the step [kJ])."""
    ts = t_store[i]
    t_after = ts + (t_gas - ts) * np.exp(-ntu)
    q_gas = w_kW_K * (t_gas - t_after)
    q_room = ua_kW_K * (ts - t_room)
    t_store[i] = ts + h * (q_gas - q_room) / cap_kJ_K
    return t_after, h * q_room
