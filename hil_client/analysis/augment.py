"""Low-order augmentations of the calibrated one-node model, the kernels of the candidates
of :mod:`hil_client.analysis.candidates`.

They are deliberately simpler than any real plant's effects (and than the emulator's):

- a first-order lag, exact per step for piecewise-constant input:
  y_i = x_i + (y_(i-1) - x_i) exp(-dt_i / tau) (the body between flame and water, the flue
  gas's storage, a sensor's response);
- the forward sensor in a mixed pipe volume fed by the flow, losing heat to the room and
  coupled to the boiler by conduction along the pipe:
  m_p dT_s/dt = m_w (T_b - T_s) + (m_p / tau_c) (T_b - T_s) - (m_p / tau_loss) (T_s - T_room).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig_emulator.model.constants import CP_WATER

EFFECTS = (
    "body_heat_diffusion",
    "outlet_sensor_pipe",
    "ignition_delay",
    "flue_gas_lag",
    "fuel_energy_bias",
)


@njit(cache=True)
def first_order_lag(x, dt, tau):
    """``x`` through a first-order lag of time constant ``tau`` [s] (exact per step)."""
    out = np.empty_like(x)
    y = x[0]
    for i in range(x.size):
        a = np.exp(-dt[i] / tau) if tau > 0.0 else 0.0
        y = x[i] + (y - x[i]) * a
        out[i] = y
    return out


@njit(cache=True)
def pipe_sensor(t_boiler, flow_kg_h, room, dt, pipe_kg, tau_loss, tau_coupling):
    """Forward sensor in a mixed pipe volume (see the module docstring); exact per step.

    ``pipe_kg`` [kg] > 0, ``tau_loss`` and ``tau_coupling`` [s] > 0 (a very large value
    switches the loss or the coupling off)."""
    out = np.empty_like(t_boiler)
    ts = t_boiler[0]
    k_loss = 1.0 / tau_loss
    k_couple = 1.0 / tau_coupling
    for i in range(t_boiler.size):
        k_flow = max(flow_kg_h[i], 0.0) / 3600.0 / pipe_kg  # [1/s]
        k = k_flow + k_couple + k_loss
        target = ((k_flow + k_couple) * t_boiler[i] + k_loss * room[i]) / k
        ts = target + (ts - target) * np.exp(-k * dt[i])
        out[i] = ts
    return out


@njit(cache=True)
def two_lump_water(q_hx_kW, flow_kg_h, t_in, room, ua_kW_K, dt, t0, c_metal, c_water, g_kW_K):
    """Water temperature of a body split into metal and water (``body_heat_diffusion``).

    The exchanger's heat enters the metal (capacity ``c_metal`` [kJ/K]), which passes it to
    the water (``c_water``) through the conductance ``g_kW_K``; the water carries the flow
    and the loss to the room:

        C_m dT_m/dt = Q_hx - G (T_m - T_w)
        C_w dT_w/dt = G (T_m - T_w) - m_w cp_w (T_w - T_in) - UA (T_w - T_room)

    Backward Euler per step (stable for any step). Both start at ``t0`` [C]."""
    cp = CP_WATER
    out = np.empty_like(q_hx_kW)
    tm = t0
    tw = t0
    for i in range(q_hx_kW.size):
        h = dt[i]
        a = max(flow_kg_h[i], 0.0) * cp / 3600.0 + ua_kW_K[i]
        # [C_m/h + G, -G; -G, C_w/h + G + a] [tm', tw'] = [C_m tm/h + Q, C_w tw/h + a_src]
        a11 = c_metal / h + g_kW_K
        a22 = c_water / h + g_kW_K + a
        b1 = c_metal * tm / h + q_hx_kW[i]
        b2 = (
            c_water * tw / h + max(flow_kg_h[i], 0.0) * cp / 3600.0 * t_in[i] + ua_kW_K[i] * room[i]
        )
        det = a11 * a22 - g_kW_K * g_kW_K
        tm = (b1 * a22 + g_kW_K * b2) / det
        tw = (a11 * b2 + g_kW_K * b1) / det
        out[i] = tw
    return out
