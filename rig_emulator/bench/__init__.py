"""The test bench around the boiler (water loop, room, balance, flue duct)."""

from rig_emulator.bench.bench import BENCH_OUTPUT_FIELDS, Bench, BenchConfig
from rig_emulator.bench.loop import LoopConfig
from rig_emulator.bench.room import RoomConditions

__all__ = ["BENCH_OUTPUT_FIELDS", "Bench", "BenchConfig", "LoopConfig", "RoomConditions"]
