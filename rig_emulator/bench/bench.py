"""The test bench around the boiler: water loop, room, balance and flue-gas duct.

The bench is the plant the instruments look at. It owns the boiler state and steps it with
the inputs the test controller sets (flow and return setpoints, pump, boiler on/off, external
heating during preheat). Everything here is deterministic; instrument errors come later.

Assumptions (ours, the paper is silent): the boiler stands on the balance with its ash box,
so the balance loses the fuel as received (moisture included) less its ash; the chimney is
DN100 and the bench holds the draught at -12 Pa (digest section 5); without firing, the
draught pulls air through the idle boiler, which leaves at the boiler's temperature and
carries off the heat Eq. 14-16 give it, (UAamb,OFF - UAamb,ON) (T_boiler - T_room): its
velocity in the duct follows (:func:`idle_air_factor`; a fixed 0.25 m/s carried 2.1 W/K
where the 12-kW boiler's model loses 1.63, and calibrate found UA_on 37 % low from a
noiseless log: a stranger's review). The boiler's hopper
holds ``hopper_fuel_kg`` of the balance's first reading; the lab tops it up to that level
whenever less than ``refill_below_kg`` is left (an operator, or the level switch of a
bench left to run for days), so the balance rises in one step by what was tipped in, as
on a real bench, and never reads less than the empty boiler (a stranger's probe read
-142 kg after six simulated days of firing). The analyses take refills out.

Unmodelled effects (CONTRACT section 4; :mod:`rig_emulator.bench.effects`) are given to the
bench as resolved settings or a profile's ``effects`` mapping. With none on, the bench steps
the pure model (:func:`bench_step`); otherwise :func:`bench_step_effects`, which steps the
plant of :mod:`rig_emulator.bench.plant`. The fuel-energy bias needs no kernel of its own:
it scales what the balance loses per kg of fuel the model burns (its ``balance`` stage).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from rig_emulator.bench.effects import EffectSettings, resolve_effects
from rig_emulator.bench.loop import LoopConfig, condition_return, follow_flow
from rig_emulator.bench.plant import (
    balance_factor,
    controller_horizon_s,
    effect_state,
    forward_sensor,
    new_effect_state,
    pack_effect_constants,
    plant_step,
)
from rig_emulator.bench.room import RoomConditions
from rig_emulator.model import boiler as bm
from rig_emulator.model.constants import CO2_AMBIENT_PCT, CP_WATER, O2_AMBIENT_PCT, T_NORMAL_K
from rig_emulator.model.layout import (
    MODULATING,
    N_OUTPUTS,
    S_FUEL,
    S_T,
    STARTUP,
    Y_CO2,
    Y_FG_WET,
    Y_LAMBDA,
    Y_MODE,
    Y_O2,
    Y_P_EL,
    Y_Q_WATER,
    Y_T_BOILER,
    Y_T_FG,
    Y_T_OUT,
    index_of,
)
from rig_emulator.model.params import BoilerParams

EffectsArg = EffectSettings | Mapping[str, Mapping[str, float]] | None

# bench constants, state, inputs and outputs: one declaration each (see model.layout)
BENCH_CONSTANT_FIELDS = (
    "flow_time_constant_s",
    "loop_capacity_kJ_K",
    "loop_ua_kW_K",
    "conditioning_time_constant_s",
    "cooling_capacity_kW",
    "heating_capacity_kW",
    "velocity_factor",  # actual m/s per (m3(N)/h K / hPa)
    "idle_air_factor",  # m/s hPa / K: the idle draught's velocity per (T_boiler / p_room)
    "draught_Pa",
    "initial_balance_kg",
    "balance_loss_per_kg_dry",  # balance loss per kg of dry fuel the model burns [kg]
    "hopper_fuel_kg",
    "refill_below_kg",
)
BC = index_of(BENCH_CONSTANT_FIELDS)
BC_TAU_FLOW = BC["flow_time_constant_s"]
BC_LOOP_CAP = BC["loop_capacity_kJ_K"]
BC_LOOP_UA = BC["loop_ua_kW_K"]
BC_TAU_COND = BC["conditioning_time_constant_s"]
BC_COOL_MAX = BC["cooling_capacity_kW"]
BC_HEAT_MAX = BC["heating_capacity_kW"]
BC_VELOCITY_FACTOR = BC["velocity_factor"]
BC_IDLE_AIR = BC["idle_air_factor"]
BC_DRAUGHT = BC["draught_Pa"]
BC_BALANCE0 = BC["initial_balance_kg"]
BC_BALANCE_PER_KG = BC["balance_loss_per_kg_dry"]
BC_HOPPER = BC["hopper_fuel_kg"]
BC_REFILL_BELOW = BC["refill_below_kg"]
N_BENCH_CONSTANTS = len(BENCH_CONSTANT_FIELDS)

BENCH_STATE_FIELDS = ("water_flow_kg_h", "return_temp_C", "time_s", "refilled_kg")
BS = index_of(BENCH_STATE_FIELDS)
BS_FLOW, BS_T_RETURN, BS_TIME = BS["water_flow_kg_h"], BS["return_temp_C"], BS["time_s"]
BS_REFILLED = BS["refilled_kg"]

#: What the test controller and the room give the bench each step.
INPUT_FIELDS = (
    "water_flow_setpoint_kg_h",
    "return_setpoint_C",
    "pump_on",
    "boiler_command",
    "return_heating",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
)
U = index_of(INPUT_FIELDS)
U_FLOW_SP = U["water_flow_setpoint_kg_h"]
U_RETURN_SP = U["return_setpoint_C"]
U_PUMP = U["pump_on"]
U_BOILER_ON = U["boiler_command"]
U_HEATING = U["return_heating"]
U_ROOM = U["room_temp_C"]
U_PRESSURE = U["ambient_pressure_hPa"]
U_HUMIDITY = U["relative_humidity_pct"]
N_INPUTS = len(INPUT_FIELDS)

BENCH_OUTPUT_FIELDS = (
    "time_s",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "balance_mass_kg",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "conditioning_kW",
    "boiler_on",
)
YB = index_of(BENCH_OUTPUT_FIELDS)
YB_TIME = YB["time_s"]
YB_FLOW = YB["water_flow_kg_h"]
YB_T_IN = YB["water_in_temp_C"]
YB_T_OUT = YB["water_out_temp_C"]
YB_ROOM = YB["room_temp_C"]
YB_PRESSURE = YB["ambient_pressure_hPa"]
YB_HUMIDITY = YB["relative_humidity_pct"]
YB_BALANCE = YB["balance_mass_kg"]
YB_VELOCITY = YB["flue_gas_velocity_m_s"]
YB_DRAUGHT = YB["chimney_draught_Pa"]
YB_CONDITIONING = YB["conditioning_kW"]
YB_FIRING_FLAG = YB["boiler_on"]
N_BENCH_OUTPUTS = len(BENCH_OUTPUT_FIELDS)


@dataclass(frozen=True, slots=True)
class BenchConfig:
    """Everything about the bench that is not the boiler (units in the names)."""

    loop: LoopConfig = field(default_factory=LoopConfig)
    room: RoomConditions = field(default_factory=RoomConditions)
    initial_water_temp_C: float = 22.0
    initial_balance_kg: float = 250.0
    #: fuel in the hopper at the start, part of the first reading [kg]
    hopper_fuel_kg: float = 100.0
    #: the lab tops the hopper up to ``hopper_fuel_kg`` when less than this is left [kg]
    refill_below_kg: float = 10.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.refill_below_kg < self.hopper_fuel_kg <= self.initial_balance_kg:
            raise ValueError(
                "BenchConfig: needs 0 <= refill_below_kg < hopper_fuel_kg <= "
                f"initial_balance_kg, got {self.refill_below_kg:g}, {self.hopper_fuel_kg:g}, "
                f"{self.initial_balance_kg:g}"
            )

    chimney_diameter_m: float = 0.10
    draught_Pa: float = -12.0


#: Gas constant and isobaric heat capacity of dry air [J/(kg K)], as Eq. 14-16 take them
R_AIR_J_KG_K = 287.05
CP_AIR_J_KG_K = 1006.0


def idle_air_factor(params: BoilerParams, duct_area_m2: float) -> float:
    """The idle draught's duct velocity per (absolute boiler temperature / room pressure)
    [m/s hPa/K]: the air of Eq. 14-16 carries (UAamb,OFF - UAamb,ON) [W/K] off the idle
    boiler, m cp = rho v A cp with rho = p / (R T) at the boiler's temperature, so
    v = (UAamb,OFF - UAamb,ON) R T / (p cp A) (none where UAamb,ON >= UAamb,OFF)."""
    carried_W_K = max(params.ua_amb_off_W_K - params.ua_amb_on_W_K, 0.0)
    return carried_W_K * R_AIR_J_KG_K / (100.0 * CP_AIR_J_KG_K * duct_area_m2)


def pack_bench_constants(params: BoilerParams, cfg: BenchConfig, c: np.ndarray) -> np.ndarray:
    """The bench's constant array (layout ``BC_*``)."""
    bc = np.zeros(N_BENCH_CONSTANTS)
    loop = cfg.loop
    bc[BC_TAU_FLOW] = loop.flow_time_constant_s
    bc[BC_LOOP_CAP] = loop.capacity_kJ_K
    bc[BC_LOOP_UA] = loop.loop_ua_W_K / 1000.0
    bc[BC_TAU_COND] = loop.conditioning_time_constant_s
    bc[BC_COOL_MAX] = loop.cooling_capacity_kW
    bc[BC_HEAT_MAX] = loop.heating_capacity_kW
    area = math.pi * cfg.chimney_diameter_m**2 / 4.0
    bc[BC_VELOCITY_FACTOR] = 1013.25 / (T_NORMAL_K * 3600.0 * area)
    bc[BC_IDLE_AIR] = idle_air_factor(params, area)
    bc[BC_DRAUGHT] = cfg.draught_Pa
    bc[BC_BALANCE0] = cfg.initial_balance_kg
    # the balance loses the fuel as received less its ash, which stays in the ash box
    bc[BC_BALANCE_PER_KG] = params.fuel.balance_loss_per_kg_dry
    bc[BC_HOPPER] = cfg.hopper_fuel_kg
    bc[BC_REFILL_BELOW] = cfg.refill_below_kg
    return bc


@njit(cache=True)
def bench_step(c, s, bc, bs, u, y, yb, dt_s):
    """Advance boiler and bench by ``dt_s`` [s]; states ``s``/``bs`` and outputs ``y``/``yb``
    are updated in place; ``u`` holds the inputs (layout ``U_*``)."""
    room = u[U_ROOM]
    flow = follow_flow(bs[BS_FLOW], u[U_FLOW_SP], u[U_PUMP] > 0.5, dt_s, bc[BC_TAU_FLOW])
    t_in = bs[BS_T_RETURN]
    bm.step(c, s, flow, t_in, room, u[U_BOILER_ON] > 0.5, dt_s, y)
    m_cp = flow * CP_WATER / 3600.0
    t_forward = t_in + y[Y_Q_WATER] / m_cp if m_cp > 0.0 else y[Y_T_OUT]
    _loop_and_outputs(s, bc, bs, u, y, yb, dt_s, flow, t_in, t_forward)


@njit(cache=True)
def bench_step_effects(c, s, bc, bs, u, y, yb, dt_s, fc, fs, history, horizon_s):
    """:func:`bench_step` with the unmodelled effects of ``fc`` (state ``fs``, history
    ``history``, controller horizon ``horizon_s``; see :mod:`rig_emulator.bench.plant`): the
    boiler is :func:`~rig_emulator.bench.plant.plant_step` and the forward reading comes
    from the bench's ``forward_sensor`` stage."""
    room = u[U_ROOM]
    flow = follow_flow(bs[BS_FLOW], u[U_FLOW_SP], u[U_PUMP] > 0.5, dt_s, bc[BC_TAU_FLOW])
    t_in = bs[BS_T_RETURN]
    plant_step(c, s, fc, fs, horizon_s, flow, t_in, room, u[U_BOILER_ON] > 0.5, dt_s, y)
    m_cp = flow * CP_WATER / 3600.0
    t_forward = t_in + y[Y_Q_WATER] / m_cp if m_cp > 0.0 else y[Y_T_OUT]
    _loop_and_outputs(s, bc, bs, u, y, yb, dt_s, flow, t_in, t_forward)
    yb[YB_T_OUT] = forward_sensor(fc, fs, history, flow, t_forward, y[Y_T_OUT], room, dt_s)


@njit(cache=True)
def _loop_and_outputs(s, bc, bs, u, y, yb, dt_s, flow, t_in, t_forward):
    """Return conditioning and bench outputs after the boiler's step (see bench_step)."""
    room = u[U_ROOM]
    t_ret, q_cond = condition_return(
        t_in,
        flow,
        t_forward,
        u[U_RETURN_SP],
        room,
        u[U_HEATING] > 0.5,
        dt_s,
        bc[BC_LOOP_CAP],
        bc[BC_LOOP_UA],
        bc[BC_TAU_COND],
        bc[BC_COOL_MAX],
        bc[BC_HEAT_MAX],
    )
    bs[BS_FLOW] = flow
    bs[BS_T_RETURN] = t_ret
    bs[BS_TIME] += dt_s
    yb[YB_TIME] = bs[BS_TIME]
    yb[YB_FLOW] = flow
    yb[YB_T_IN] = t_in
    yb[YB_T_OUT] = y[Y_T_OUT]
    yb[YB_ROOM] = room
    yb[YB_PRESSURE] = u[U_PRESSURE]
    yb[YB_HUMIDITY] = u[U_HUMIDITY]
    fed_kg = s[S_FUEL] * bc[BC_BALANCE_PER_KG]
    if bc[BC_HOPPER] + bs[BS_REFILLED] - fed_kg < bc[BC_REFILL_BELOW]:  # topped up
        bs[BS_REFILLED] = fed_kg
    yb[YB_BALANCE] = bc[BC_BALANCE0] + bs[BS_REFILLED] - fed_kg
    if y[Y_FG_WET] > 0.0:
        # actual volume flow at flue-gas temperature and room pressure over the duct area
        yb[YB_VELOCITY] = (
            y[Y_FG_WET] * (y[Y_T_FG] + T_NORMAL_K) * bc[BC_VELOCITY_FACTOR] / u[U_PRESSURE]
        )
    else:  # the idle draught (Eq. 14-16), at the boiler's temperature
        yb[YB_VELOCITY] = bc[BC_IDLE_AIR] * (y[Y_T_BOILER] + T_NORMAL_K) / u[U_PRESSURE]
    yb[YB_DRAUGHT] = bc[BC_DRAUGHT]
    yb[YB_CONDITIONING] = q_cond
    mode = y[Y_MODE]
    yb[YB_FIRING_FLAG] = 1.0 if (mode == STARTUP or mode == MODULATING) else 0.0


class Bench:
    """The boiler on its test bench, advanced step by step.

    Attributes:
        c, s: boiler constants and state arrays; bc, bs: bench constants and state;
        u: inputs (set with :meth:`set_inputs`); y, yb: outputs of the last step;
        effects: the resolved unmodelled effects; fc, fs, history: their constants, state
        and history (:mod:`rig_emulator.bench.plant`; unused when no effect with a compiled
        stage is on).

    Args:
        params: the boiler; config: the bench;
        effects: unmodelled effects, resolved (:class:`EffectSettings`) or as a profile's
            ``effects`` mapping (validated here); None: none (the model).
    """

    def __init__(
        self,
        params: BoilerParams,
        config: BenchConfig | None = None,
        effects: EffectsArg = None,
    ) -> None:
        self.params = params
        self.config = config or BenchConfig()
        if not isinstance(effects, EffectSettings):
            effects = resolve_effects(effects)
        self.effects = effects
        self.c = bm.pack_constants(params)
        self.bc = pack_bench_constants(params, self.config, self.c)
        # the effects' balance stages (the fuel-energy bias: 1 / (1 + b) the mass)
        self.bc[BC_BALANCE_PER_KG] *= balance_factor(effects)
        self._dynamic = effects.dynamic
        self.fc = pack_effect_constants(effects, params)
        self.horizon_s = controller_horizon_s(effects)
        self.u = np.zeros(N_INPUTS)
        self.y = np.zeros(N_OUTPUTS)
        self.yb = np.zeros(N_BENCH_OUTPUTS)
        self._room_varies = bool(self.config.room.profile)
        self.reset()

    def reset(self) -> None:
        """Return to the initial state: water at the initial temperature, boiler off."""
        t = self.config.initial_water_temp_C
        self.s = bm.new_state(t)
        self.bs = np.zeros(len(BENCH_STATE_FIELDS))
        self.bs[BS_T_RETURN] = t
        self.fs, self.history = new_effect_state(t)
        # the kernel's arrays, bound once (the step is called once per simulated second)
        self._args = (self.c, self.s, self.bc, self.bs, self.u, self.y, self.yb)
        self._fx_args = (self.fc, self.fs, self.history, self.horizon_s)
        self.set_inputs(0.0, t, True, False, False)
        self.u[U_ROOM], self.u[U_PRESSURE], self.u[U_HUMIDITY] = self.config.room.at(0.0)

    def initial_outputs(self) -> None:
        """Fill :attr:`y` and :attr:`yb` with the idle state before the first step."""
        t = float(self.s[S_T])
        room, pressure, humidity = self.config.room.at(0.0)
        self.y[:] = 0.0
        self.y[Y_T_BOILER] = self.y[Y_T_OUT] = self.y[Y_T_FG] = t
        self.y[Y_LAMBDA] = math.inf
        self.y[Y_O2], self.y[Y_CO2] = O2_AMBIENT_PCT, CO2_AMBIENT_PCT
        self.y[Y_P_EL] = self.params.p_el_off_W
        yb = self.yb
        yb[:] = 0.0
        yb[YB_T_IN] = self.bs[BS_T_RETURN]
        yb[YB_T_OUT] = t
        yb[YB_ROOM], yb[YB_PRESSURE], yb[YB_HUMIDITY] = room, pressure, humidity
        yb[YB_BALANCE] = self.bc[BC_BALANCE0]
        yb[YB_VELOCITY] = self.bc[BC_IDLE_AIR] * (t + T_NORMAL_K) / pressure
        yb[YB_DRAUGHT] = self.bc[BC_DRAUGHT]

    def effect_state(self, name: str) -> dict[str, float]:
        """The plant state of the effect ``name`` by field name (its module's ``state``)."""
        return effect_state(self.fs, name)

    @property
    def time_s(self) -> float:
        return float(self.bs[BS_TIME])

    def set_inputs(
        self,
        flow_setpoint_kg_h: float,
        return_setpoint_C: float,
        pump_on: bool,
        boiler_on: bool,
        return_heating: bool,
    ) -> None:
        """Set what the test controller commands (held until changed)."""
        u = self.u
        u[U_FLOW_SP] = flow_setpoint_kg_h
        u[U_RETURN_SP] = return_setpoint_C
        u[U_PUMP] = pump_on
        u[U_BOILER_ON] = boiler_on
        u[U_HEATING] = return_heating

    def step(self, dt_s: float) -> None:
        """Advance the bench by ``dt_s`` seconds; results in :attr:`y` and :attr:`yb`."""
        u = self.u
        if self._room_varies:
            u[U_ROOM], u[U_PRESSURE], u[U_HUMIDITY] = self.config.room.at(float(self.bs[BS_TIME]))
        if self._dynamic:
            bench_step_effects(*self._args, dt_s, *self._fx_args)
        else:
            bench_step(*self._args, dt_s)
