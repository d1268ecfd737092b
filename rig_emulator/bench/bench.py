"""The test bench around the boiler: water loop, room, balance and flue-gas duct.

The bench is the plant the instruments look at. It owns the boiler state and steps it with
the inputs the test controller sets (flow and return setpoints, pump, boiler on/off, external
heating during preheat). Everything here is deterministic; instrument errors are added later.

Assumptions (ours, the paper is silent): the boiler stands on the balance with its ash box,
so the balance loses the fuel as received (moisture included) less its ash; the chimney is
DN100 and the bench holds the draught at -12 Pa (digest section 5); without firing, the
fan-less draught pulls ``idle_velocity_m_s`` of air through the idle boiler.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from rig_emulator.bench.loop import LoopConfig, condition_return, follow_flow
from rig_emulator.bench.room import RoomConditions
from rig_emulator.model import boiler as bm
from rig_emulator.model.constants import CP_WATER, T_NORMAL_K
from rig_emulator.model.params import BoilerParams


@dataclass(frozen=True, slots=True)
class BenchConfig:
    """Everything about the bench that is not the boiler (units in the names)."""

    loop: LoopConfig = field(default_factory=LoopConfig)
    room: RoomConditions = field(default_factory=RoomConditions)
    initial_water_temp_C: float = 22.0
    initial_balance_kg: float = 250.0
    chimney_diameter_m: float = 0.10
    draught_Pa: float = -12.0
    idle_velocity_m_s: float = 0.25


@dataclass(slots=True)
class BenchInputs:
    """What the test controller sets on the bench."""

    flow_setpoint_kg_h: float = 0.0
    return_setpoint_C: float = 45.0
    pump_on: bool = True
    boiler_on: bool = False
    return_heating: bool = False


@dataclass(slots=True)
class BenchOutputs:
    """True plant values after a step (before any instrument)."""

    time_s: float
    water_flow_kg_h: float
    water_in_temp_C: float
    water_out_temp_C: float
    room_temp_C: float
    ambient_pressure_hPa: float
    relative_humidity_pct: float
    balance_mass_kg: float
    flue_gas_velocity_m_s: float
    chimney_draught_Pa: float
    conditioning_kW: float
    boiler: bm.BoilerOutputs


class Bench:
    """The boiler on its test bench, advanced step by step."""

    def __init__(self, params: BoilerParams, config: BenchConfig | None = None) -> None:
        self.params = params
        self.config = config or BenchConfig()
        self.coeffs = bm.coefficients(params)
        self.inputs = BenchInputs()
        self._area = math.pi * self.config.chimney_diameter_m**2 / 4.0
        self._ash_loss = params.fuel.ash  # ash per kg dry fuel stays on the balance
        self.reset()

    def reset(self) -> None:
        """Return to the initial state: water at the initial temperature, boiler off."""
        t = self.config.initial_water_temp_C
        self.time_s = 0.0
        self.state = bm.BoilerState(t_boiler_C=t)
        self.flow_kg_h = 0.0
        self.t_return_C = t
        self.inputs = BenchInputs(return_setpoint_C=t)

    def step(self, dt_s: float) -> BenchOutputs:
        """Advance the bench by ``dt_s`` seconds with the current inputs."""
        cfg = self.config
        inp = self.inputs
        room_C, pressure_hPa, humidity = cfg.room.at(self.time_s)
        flow = follow_flow(
            self.flow_kg_h, inp.flow_setpoint_kg_h, inp.pump_on, dt_s, cfg.loop.flow_time_constant_s
        )
        t_in = self.t_return_C
        self.state, out = bm.step(
            self.params, self.coeffs, self.state, flow, t_in, room_C, inp.boiler_on, dt_s
        )
        m_cp = flow * CP_WATER / 3600.0
        t_forward = t_in + out.q_water_kW / m_cp if m_cp > 0.0 else out.t_out_C
        self.t_return_C, q_cond = condition_return(
            cfg.loop, t_in, flow, t_forward, inp.return_setpoint_C, room_C, inp.return_heating, dt_s
        )
        self.flow_kg_h = flow
        self.time_s += dt_s
        if out.flue_gas_wet_m3n_h > 0.0:
            actual = (
                out.flue_gas_wet_m3n_h
                * (out.t_flue_gas_C + T_NORMAL_K)
                / T_NORMAL_K
                * (1013.25 / pressure_hPa)
            )
            velocity = actual / 3600.0 / self._area
        else:
            velocity = cfg.idle_velocity_m_s
        fuel_dry = self.state.fuel_dry_kg
        balance = cfg.initial_balance_kg - fuel_dry * (
            self.coeffs.as_received_factor - self._ash_loss
        )
        return BenchOutputs(
            time_s=self.time_s,
            water_flow_kg_h=flow,
            water_in_temp_C=t_in,
            water_out_temp_C=out.t_out_C,
            room_temp_C=room_C,
            ambient_pressure_hPa=pressure_hPa,
            relative_humidity_pct=humidity,
            balance_mass_kg=balance,
            flue_gas_velocity_m_s=velocity,
            chimney_draught_Pa=cfg.draught_Pa,
            conditioning_kW=q_cond,
            boiler=out,
        )
