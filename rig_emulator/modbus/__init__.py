"""The Modbus TCP adapter (pymodbus): a register map over the emulator."""

from rig_emulator.modbus.server import BenchServer

__all__ = ["BenchServer"]
