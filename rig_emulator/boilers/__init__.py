"""Named boiler parameter files and their loader (the only I/O around the model's params)."""

from __future__ import annotations

from pathlib import Path

from rig_emulator.atomic import write_atomically
from rig_emulator.model.params import BoilerParams, ParameterError, params_from_mapping
from rig_emulator.yamlio import dump_yaml, read_yaml, resolve_named

BOILER_DIR = Path(__file__).parent


def resolve(name_or_path: str) -> Path:
    """Path of a boiler given as a shipped NAME or a PATH to a YAML file."""
    return resolve_named(name_or_path, BOILER_DIR, "boiler", ParameterError)


def load_boiler(name_or_path: str) -> BoilerParams:
    """Load and validate a boiler parameter file.

    Raises:
        ParameterError: the file is missing, is not YAML, or fails validation; the message
            names the file and the key.
    """
    path = resolve(name_or_path)
    data = read_yaml(path, ParameterError)
    return params_from_mapping(data, source=str(path))


def dump_boiler(params: BoilerParams, path: Path, header: str = "") -> None:
    """Write a parameter file of CONTRACT section 2 form."""
    text = dump_yaml(params.to_mapping())
    write_atomically(path, (header + "\n" if header else "") + text)
