"""Register maps as data (schema, validation, codec, Markdown reference); no protocol code."""

from rig_emulator.registers.codec import (
    decode,
    encode,
    invalid_value,
    legacy_map_identity,
    map_identity,
    precision,
    reading_range,
    run_decoder,
    run_encoder,
    written_value,
)
from rig_emulator.registers.schema import (
    MAP_DIR,
    Device,
    MapError,
    Point,
    RegisterMap,
    control_units,
    emulator_units,
    instrument_units,
    load_map,
    map_from_mapping,
)

__all__ = [
    "MAP_DIR",
    "Device",
    "MapError",
    "Point",
    "RegisterMap",
    "control_units",
    "decode",
    "emulator_units",
    "encode",
    "instrument_units",
    "invalid_value",
    "legacy_map_identity",
    "load_map",
    "map_from_mapping",
    "map_identity",
    "precision",
    "reading_range",
    "run_decoder",
    "run_encoder",
    "written_value",
]
