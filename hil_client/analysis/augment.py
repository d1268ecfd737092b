"""Low-order augmentations of the calibrated one-node model, one per candidate effect.

Each augmentation adds one or two parameters to the model's predictions of the lab signals;
the diagnosis fits them on the calibration log only (:mod:`hil_client.analysis.diagnose`).
They are deliberately simpler than the emulator's plant effects:

- ``body_heat_diffusion`` (tau_body [s]): the water sees the node temperature through a
  first-order lag (the metal between flame and water), so it lags at start-up and after
  load steps: T_w' = T_w + (T_node - T_w) dt / tau_body;
- ``outlet_sensor_pipe`` (pipe_kg [kg], tau_loss [s]): the forward sensor reads a mixed pipe
  volume fed by the flow and losing heat to the room:
  m_p dT_s/dt = m_w (T_node - T_s) - m_p (T_s - T_room) / tau_loss;
- ``ignition_delay`` (delay [s]): the bed releases heat ``delay`` after the bench switches
  the boiler on, while the balance loses fuel from the switch-on;
- ``flue_gas_lag`` (tau_fg [s]): the flue-gas temperature follows the model's with a
  first-order lag;
- ``fuel_energy_bias`` (bias [-]): the balance loses (1 + bias) times the model's fuel.
"""

from __future__ import annotations

import numpy as np
from numba import njit

EFFECTS = (
    "body_heat_diffusion",
    "outlet_sensor_pipe",
    "ignition_delay",
    "flue_gas_lag",
    "fuel_energy_bias",
)

#: Parameters of each augmentation: name -> (initial value, lower bound, upper bound).
PARAMETERS: dict[str, dict[str, tuple[float, float, float]]] = {
    "none": {},
    # time constants below 30 s are the sensors' own (thermowells, probes), not the body's
    "body_heat_diffusion": {"tau_body_s": (300.0, 30.0, 5000.0)},
    # a pipe of 30 cm holds 0.1-0.4 kg of water: up to 2 kg allowed
    "outlet_sensor_pipe": {"pipe_kg": (0.3, 0.02, 2.0), "tau_loss_s": (1800.0, 60.0, 1e5)},
    "ignition_delay": {"delay_s": (60.0, 0.0, 900.0)},
    "flue_gas_lag": {"tau_fg_s": (120.0, 30.0, 3000.0)},
    "fuel_energy_bias": {"bias": (0.0, -0.3, 0.3)},
}


@njit(cache=True)
def first_order_lag(x, dt, tau):
    """``x`` through a first-order lag of time constant ``tau`` [s] (exact per step)."""
    out = np.empty_like(x)
    y = x[0]
    for i in range(x.size):
        a = np.exp(-dt[i] / tau)
        y = x[i] + (y - x[i]) * a
        out[i] = y
    return out


@njit(cache=True)
def pipe_sensor(t_node, flow_kg_h, room, dt, pipe_kg, tau_loss):
    """Forward sensor in a mixed pipe volume fed by the flow, losing heat to the room."""
    out = np.empty_like(t_node)
    ts = t_node[0]
    for i in range(t_node.size):
        k_flow = flow_kg_h[i] / 3600.0 / pipe_kg  # [1/s]
        k_loss = 1.0 / tau_loss
        k = k_flow + k_loss
        target = (k_flow * t_node[i] + k_loss * room[i]) / k
        ts = target + (ts - target) * np.exp(-k * dt[i])
        out[i] = ts
    return out
