"""The test bench around the boiler (water loop, room, balance, flue duct)."""

from rig_emulator.bench.bench import Bench, BenchConfig, BenchInputs, BenchOutputs
from rig_emulator.bench.loop import LoopConfig
from rig_emulator.bench.room import RoomConditions

__all__ = ["Bench", "BenchConfig", "BenchInputs", "BenchOutputs", "LoopConfig", "RoomConditions"]
