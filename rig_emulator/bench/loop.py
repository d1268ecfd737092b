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
  more than the flow can carry away at the set return, and the return follows the boiler's
  outlet when that is colder than the setpoint.

Each step is solved exactly for inputs held over the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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


def follow_flow(
    flow_kg_h: float, setpoint_kg_h: float, pump_on: bool, dt_s: float, tau_s: float
) -> float:
    """Flow at the end of a step [kg/h]: first-order approach to the setpoint (0 if pump off)."""
    target = setpoint_kg_h if pump_on else 0.0
    return target + (flow_kg_h - target) * math.exp(-dt_s / tau_s)


def condition_return(
    cfg: LoopConfig,
    t_loop_C: float,
    flow_kg_h: float,
    t_forward_C: float,
    setpoint_C: float,
    room_C: float,
    heating: bool,
    dt_s: float,
) -> tuple[float, float]:
    """Advance the return node by one step.

    Args:
        t_loop_C: return-node temperature at the start of the step [C].
        flow_kg_h: loop flow [kg/h]; t_forward_C: mean boiler outlet over the step [C].
        setpoint_C: return set temperature [C]; heating: external heating allowed.

    Returns:
        (temperature at the end of the step [C], mean conditioning power removed [kW]).
    """
    cap = cfg.capacity_kJ_K
    m_cp = flow_kg_h * CP_WATER / 3600.0
    ua = cfg.loop_ua_W_K / 1000.0
    tau = cfg.conditioning_time_constant_s
    e = math.exp(-dt_s / tau)
    t_new = setpoint_C + (t_loop_C - setpoint_C) * e
    t_mean = setpoint_C + (t_loop_C - setpoint_C) * (1.0 - e) * tau / dt_s
    q = m_cp * (t_forward_C - t_mean) - ua * (t_mean - room_C) - cap * (t_new - t_loop_C) / dt_s
    q_lo = -cfg.heating_capacity_kW if heating else 0.0
    q_hi = cfg.cooling_capacity_kW
    if q_lo <= q <= q_hi:
        return t_new, q
    q = q_hi if q > q_hi else q_lo
    b = m_cp + ua
    t_eq = (m_cp * t_forward_C + ua * room_C - q) / b
    return t_eq + (t_loop_C - t_eq) * math.exp(-b * dt_s / cap), q
