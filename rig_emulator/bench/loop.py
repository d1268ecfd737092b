"""The bench's water loop: pump/valve, return conditioning and the loop's own water.

The bench (Wieselburg, EN 303-5 set-up, digest section 6) imposes the load through the water
flow and conditions the return to its set temperature; there is no buffer tank.

Model (assumptions ours, the paper gives no figures):
- the flow follows its setpoint with a first-order lag ``flow_time_constant_s`` (pump and
  valve); a stopped pump gives zero flow;
- the return side is one mixed water node of capacity ``loop_volume_m3`` (pipes, exchanger),
  losing ``loop_ua_W_K`` to the room; the water leaving it is the boiler's return;
- a conditioning exchanger drives that node to the return setpoint with time constant
  ``conditioning_time_constant_s`` as long as its power stays within limits: it can cool by
  up to ``cooling_capacity_kW`` and heat only while external heating is enabled (the preheat
  "with outside help" before t0), by up to ``heating_capacity_kW``. Outside those limits the
  node follows its own energy balance, so the whole circuit heats up when the boiler delivers
  more than the cooler can take, and the return follows the boiler's outlet when that is
  colder than the setpoint.

Each step is solved exactly for inputs held over the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from numba import njit

from rig_emulator.model.constants import CP_WATER, RHO_WATER


@dataclass(frozen=True, slots=True)
class LoopConfig:
    """Configuration of the water loop (units in the names)."""

    flow_time_constant_s: float = 10.0
    loop_volume_m3: float = 0.02
    loop_ua_W_K: float = 2.0
    conditioning_time_constant_s: float = 30.0
    cooling_capacity_kW: float = 30.0
    heating_capacity_kW: float = 15.0

    @property
    def capacity_kJ_K(self) -> float:
        return self.loop_volume_m3 * RHO_WATER * CP_WATER


@njit(cache=True)
def follow_flow(flow_kg_h, setpoint_kg_h, pump_on, dt_s, tau_s):
    """Flow at the end of a step [kg/h]: first-order approach to the setpoint (0 if pump off)."""
    target = setpoint_kg_h if pump_on else 0.0
    return target + (flow_kg_h - target) * math.exp(-dt_s / tau_s)


@njit(cache=True)
def condition_return(
    t_loop_C,
    flow_kg_h,
    t_forward_C,
    setpoint_C,
    room_C,
    heating,
    dt_s,
    cap_kJ_K,
    ua_kW_K,
    tau_s,
    cooling_max_kW,
    heating_max_kW,
):
    """Advance the return node by one step.

    Args:
        t_loop_C: return-node temperature at the start of the step [C].
        flow_kg_h: loop flow [kg/h]; t_forward_C: mean boiler outlet over the step [C].
        setpoint_C: return set temperature [C]; heating: external heating allowed.
        cap_kJ_K, ua_kW_K, tau_s, cooling_max_kW, heating_max_kW: the loop (LoopConfig).

    Returns:
        (temperature at the end of the step [C], mean conditioning power removed [kW]).
    """
    m_cp = flow_kg_h * CP_WATER / 3600.0
    e = math.exp(-dt_s / tau_s)
    t_new = setpoint_C + (t_loop_C - setpoint_C) * e
    t_mean = setpoint_C + (t_loop_C - setpoint_C) * (1.0 - e) * tau_s / dt_s
    q = (
        m_cp * (t_forward_C - t_mean)
        - ua_kW_K * (t_mean - room_C)
        - cap_kJ_K * (t_new - t_loop_C) / dt_s
    )
    q_lo = -heating_max_kW if heating else 0.0
    if q_lo <= q <= cooling_max_kW:
        return t_new, q
    q = cooling_max_kW if q > cooling_max_kW else q_lo
    b = m_cp + ua_kW_K
    t_eq = (m_cp * t_forward_C + ua_kW_K * room_C - q) / b
    return t_eq + (t_loop_C - t_eq) * math.exp(-b * dt_s / cap_kJ_K), q
