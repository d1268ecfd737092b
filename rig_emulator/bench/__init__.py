"""The test bench around the boiler (water loop, room, balance, flue duct) and the
unmodelled effects of the real bench (:mod:`rig_emulator.bench.effects`)."""

from rig_emulator.bench.bench import BENCH_OUTPUT_FIELDS, Bench, BenchConfig
from rig_emulator.bench.effects import (
    EFFECT_NAMES,
    EffectError,
    EffectSettings,
    check_effects,
    effects_at,
    lab_parameters,
    resolve_effects,
    strength_ranges,
)
from rig_emulator.bench.loop import LoopConfig
from rig_emulator.bench.room import RoomConditions

__all__ = [
    "BENCH_OUTPUT_FIELDS",
    "EFFECT_NAMES",
    "Bench",
    "BenchConfig",
    "EffectError",
    "EffectSettings",
    "LoopConfig",
    "RoomConditions",
    "check_effects",
    "effects_at",
    "lab_parameters",
    "resolve_effects",
    "strength_ranges",
]
