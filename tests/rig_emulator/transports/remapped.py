"""The shipped register map with devices moved to other unit IDs (role tests)."""

from __future__ import annotations

from rig_emulator.registers import MapError, RegisterMap, map_from_mapping
from rig_emulator.registers.schema import MAP_DIR
from rig_emulator.yamlio import read_yaml


def shipped_map_with_units(**units: int) -> RegisterMap:
    """The shipped map with the devices named (``sim_control=7``) at other unit IDs."""
    data = read_yaml(MAP_DIR / "wieselburg_bench.yaml", MapError)
    for device in data["devices"]:
        device["unit_id"] = units.get(device["name"], device["unit_id"])
    return map_from_mapping(data, "remapped.yaml")
