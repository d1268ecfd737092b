"""The boiler as the real bench has it: the Type 869 step skeleton with the effects' stages.

:func:`plant_step` is the model's step skeleton (:func:`rig_emulator.model.boiler.
step_skeleton`) with, at each named point, the stage of the registered effect
(:mod:`rig_emulator.bench.effects`) that contributes one there, or the model's neutral
stage where none does; :func:`forward_sensor` is the forward reading at the bench's
``forward_sensor`` point. Everything here is built from the registry: an effect's stages,
constants and state come from its own module.

Layout: the effect constants ``fc`` and state ``fs`` are 2-D, one row per registered
effect (:data:`ROW`, registry order), each row laid out by its effect's ``constants`` /
``state`` names; an effect that is off has a zero constant row (``on`` = 0), and its stages
then act as the neutral ones, so with every effect off the plant is the model bit for bit.
``history`` is the array of the ``forward_sensor`` stage. The bench calls these kernels only
when an effect with a compiled stage is on; otherwise it steps the pure model.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig_emulator.bench.effects import REGISTRY, EffectSettings
from rig_emulator.model import boiler as bm
from rig_emulator.model.layout import index_of
from rig_emulator.model.params import BoilerParams

#: Row of each registered effect in ``fc``/``fs``.
ROW = index_of(tuple(REGISTRY))
N_FX_CONSTANTS = max(len(spec.constants) for spec in REGISTRY.values())
N_FX_STATE = max((len(spec.state) for spec in REGISTRY.values()), default=0) or 1
HISTORY_SHAPE = tuple(max(spec.history_shape[i] for spec in REGISTRY.values()) for i in (0, 1))


@njit(cache=True)
def neutral_forward_sensor(fc, fs, row, history, flow_kg_h, t_outlet_C, t_boiler_C, room_C, dt_s):
    """``forward_sensor`` without an effect: the sensor reads the boiler's outlet, which
    Type 869 takes as the node temperature ``t_boiler_C`` [C]."""
    return t_boiler_C


_NEUTRAL = {
    "flame_clock": bm.model_flame_clock,
    "fuel_bed": bm.model_fuel_bed,
    "flue_gas": bm.model_flue_gas,
    "heat_store": bm.model_heat_store,
    "forward_sensor": neutral_forward_sensor,
}


def _stage(point: str):
    """(stage function, row) at ``point``: the registered effect's, else the neutral one."""
    for name, spec in REGISTRY.items():
        if point in spec.stages:
            return spec.stages[point], ROW[name]
    return _NEUTRAL[point], 0


_flame_clock, _ROW_FLAME_CLOCK = _stage("flame_clock")
_fuel_bed, _ROW_FUEL_BED = _stage("fuel_bed")
_flue_gas, _ROW_FLUE_GAS = _stage("flue_gas")
_heat_store, _ROW_HEAT_STORE = _stage("heat_store")
_forward_sensor, _ROW_FORWARD_SENSOR = _stage("forward_sensor")
#: Row of each skeleton point (order of :data:`rig_emulator.model.boiler.STAGE_POINTS`).
_ROWS = (_ROW_FLAME_CLOCK, _ROW_FUEL_BED, _ROW_FLUE_GAS, _ROW_HEAT_STORE)


def pack_effect_constants(fx: EffectSettings, params: BoilerParams) -> np.ndarray:
    """The effect constants (one row per effect) for resolved settings and a boiler."""
    fc = np.zeros((len(ROW), N_FX_CONSTANTS))
    for name in fx.active:
        spec = REGISTRY[name]
        row = fc[ROW[name]]
        row[0] = 1.0  # on
        index = index_of(spec.constants)
        for key, value in spec.pack(fx[name], params).items():
            row[index[key]] = value
    return fc


def controller_horizon_s(fx: EffectSettings) -> float:
    """What the effects that are on add to the controller's horizon [s]."""
    return float(sum(REGISTRY[name].horizon_s(fx[name]) for name in fx.active))


def balance_factor(fx: EffectSettings) -> float:
    """Factor on the balance's loss per kg of fuel burnt (the ``balance`` stages)."""
    factor = 1.0
    for name in fx.active:
        spec = REGISTRY[name]
        if spec.balance_factor is not None:
            factor *= spec.balance_factor(fx[name])
    return factor


def new_effect_state(t_C: float) -> tuple[np.ndarray, np.ndarray]:
    """(state, history) of a plant at rest at ``t_C`` [C] with an empty bed."""
    fs = np.zeros((len(ROW), N_FX_STATE))
    for name, spec in REGISTRY.items():
        index = index_of(spec.state)
        for key, value in spec.initial_state(t_C).items():
            fs[ROW[name], index[key]] = value
    return fs, np.zeros(HISTORY_SHAPE)


def effect_state(fs: np.ndarray, name: str) -> dict[str, float]:
    """The state of effect ``name`` by field name."""
    state = REGISTRY[name].state
    return {key: float(fs[ROW[name], i]) for i, key in enumerate(state)}


@njit(cache=True)
def plant_step(c, s, fc, fs, horizon_s, water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y):
    """The model's step skeleton with the effects' stages.

    Same arguments, state and outputs as :func:`rig_emulator.model.boiler.step`, plus the
    effect constants ``fc`` and state ``fs`` (updated in place) and what the effects add to
    the controller's horizon ``horizon_s`` [s] (:func:`controller_horizon_s`). With every
    effect off it is the model bit for bit. Fuel masses are in kg of nominal energy (HHV);
    the ``balance`` stages act in the bench (:class:`~rig_emulator.bench.bench.Bench`).
    Electric power follows the controller, as in the model.
    """
    bm.step_skeleton(
        c, s, fc, fs, _ROWS, water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y,
        horizon_s, _flame_clock, _fuel_bed, _flue_gas, _heat_store,
    )  # fmt: skip


@njit(cache=True, inline="always")
def forward_sensor(fc, fs, history, flow_kg_h, t_outlet_C, t_boiler_C, room_C, dt_s):
    """The forward reading [C] at the bench's ``forward_sensor`` point: the registered
    stage there (the exit pipe), or the boiler's outlet. The stage is not called while its
    effect is off (its ``on`` constant, column 0, is 0): a call costs more than the rest of
    the bench's step."""
    if fc[_ROW_FORWARD_SENSOR, 0] < 0.5:
        return t_boiler_C
    return _forward_sensor(
        fc, fs, _ROW_FORWARD_SENSOR, history, flow_kg_h, t_outlet_C, t_boiler_C, room_C, dt_s
    )
