"""Register maps as data: the schema of ``register_maps/*.yaml`` and its validation.

A map lists devices (Modbus unit IDs), each with points that publish one signal of
:mod:`rig_emulator.signals` in one table:

    name: wieselburg_bench
    description: ...
    devices:
      - name: bench_plc               # unique
        unit_id: 1                    # 1..247, unique
        instrument: bench PLC         # free text
        word_order: ABCD              # default for the device's 32/64-bit points
        points:
          - name: water_flow          # unique within the device
            signal: water_flow_kg_h   # a signal of the catalog
            table: input              # input | holding | coil | discrete
            address: 0                # 0-based protocol address (register, or bit for coils)
            datatype: float32         # rig_emulator.registers.datatypes (bool for bits)
            word_order: CDAB          # ABCD (big-endian words) or CDAB (low word first)
            scale: 0.01               # value = raw * scale + offset (integer types)
            offset: 0
            unit: kg/h                # the signal's unit (the default), no other
            access: r                 # r | rw (rw only for command signals in holding/coil)
            min: 0                    # accepted range of writes, rw points only (default:
            max: 2000                 #   the signal's range, which a map may only narrow)
            description: ...          # default: the signal's description

A bit (a coil or a discrete input) carries an on/off signal (unit ``0/1``) or a command
of whole numbers only; a writable point of a command that takes whole numbers
(:attr:`~rig_emulator.signals.Signal.whole`) has scale 1 or -1 and a whole offset, so it
carries each whole value and no fraction; the map converts no units. A broken map is
refused with the file, device and point named.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig_emulator.names import hidden_character, shown
from rig_emulator.registers.datatypes import DATATYPES
from rig_emulator.signals import PLANT_COMMANDS, SIGNALS
from rig_emulator.yamlio import finite_number, read_yaml

#: The shipped maps, package data (the checkout's top-level ``register_maps/`` links here,
#: so an installed package has them too)
MAP_DIR = Path(__file__).resolve().parent / "maps"

TABLES = ("input", "holding", "coil", "discrete")
WORD_ORDERS = ("ABCD", "CDAB")
BIT_TABLES = ("coil", "discrete")


class MapError(ValueError):
    """A register map is malformed; the message names the file, device and point."""


def _check_shown_name(name: Any, where: str) -> None:
    """MapError if ``name`` holds a character that displays it as another or writes a line of
    its own (:func:`~rig_emulator.yamlio.hidden_character`, the rule of boiler and role
    names): the reference prints names as written (a point named with U+202E, a right-to-left
    override, and one with a line break passed: a stranger's probe). ``where`` names it by
    position, the name is shown escaped; a name that is no text is left to its own check."""
    if isinstance(name, str) and (hidden := hidden_character(name)) is not None:
        raise MapError(f"{where}: 'name' '{shown(name)}' holds {hidden}")


@dataclass(frozen=True, slots=True)
class Point:
    """One value on the wire (see the module docstring)."""

    name: str
    signal: str
    table: str
    address: int
    datatype: str
    word_order: str
    scale: float
    offset: float
    unit: str
    access: str
    minimum: float
    maximum: float
    description: str

    @property
    def width(self) -> int:
        """Registers (or bits) the point occupies."""
        return DATATYPES[self.datatype].width

    @property
    def writable(self) -> bool:
        return self.access == "rw"


@dataclass(frozen=True, slots=True)
class Device:
    """A Modbus unit: one instrument of the bench."""

    name: str
    unit_id: int
    instrument: str
    points: tuple[Point, ...]

    def table(self, table: str) -> tuple[Point, ...]:
        """Points of one table, by address."""
        return tuple(sorted((p for p in self.points if p.table == table), key=lambda p: p.address))


@dataclass(frozen=True, slots=True)
class RegisterMap:
    """A whole register map."""

    name: str
    description: str
    devices: tuple[Device, ...]
    source: str = "<map>"

    def device(self, name: str) -> Device:
        for dev in self.devices:
            if dev.name == name:
                return dev
        raise KeyError(name)

    def point(self, signal: str) -> tuple[Device, Point]:
        """The first point publishing ``signal`` (and its device)."""
        for dev in self.devices:
            for point in dev.points:
                if point.signal == signal:
                    return dev, point
        raise KeyError(signal)


def _num(value: Any, where: str, key: str) -> float:
    number = finite_number(value)
    if number is None:
        shown = f"{value!r}" if len(repr(value)) <= 40 else f"{repr(value)[:20]}..."
        raise MapError(f"{where}: '{key}' must be a finite number, got {shown}")
    return number


def _point(raw: Any, where: str, default_order: str) -> Point:
    if not isinstance(raw, Mapping):
        raise MapError(f"{where}: must be a mapping")
    allowed = {
        "name",
        "signal",
        "table",
        "address",
        "datatype",
        "word_order",
        "scale",
        "offset",
        "unit",
        "access",
        "min",
        "max",
        "description",
    }
    for key in raw:
        if key not in allowed:
            raise MapError(f"{where}: unknown key '{key}'")
    for key in ("signal", "table", "address", "datatype"):
        if key not in raw:
            raise MapError(f"{where}: missing required key '{key}'")
    signal_name = raw["signal"]
    signal = SIGNALS.get(signal_name)
    if signal is None:
        raise MapError(f"{where}: unknown signal '{signal_name}'")
    table = raw["table"]
    if table not in TABLES:
        raise MapError(f"{where}: bad table '{table}' (one of {', '.join(TABLES)})")
    datatype = raw["datatype"]
    if datatype not in DATATYPES:
        raise MapError(f"{where}: bad type '{datatype}' (one of {', '.join(DATATYPES)})")
    if (table in BIT_TABLES) != (datatype == "bool"):
        raise MapError(f"{where}: bad type '{datatype}' for table '{table}' (bool iff bits)")
    if table in BIT_TABLES and not (signal.switch or signal.whole):
        raise MapError(  # (22 C was served as 1: a stranger's probe)
            f"{where}: a bit carries 0/1, and '{signal_name}' [{signal.unit}] is neither an "
            "on/off signal nor a command of whole numbers; publish it in registers"
        )
    address = raw["address"]
    if isinstance(address, bool) or not isinstance(address, int) or address < 0:
        raise MapError(f"{where}: 'address' must be an integer >= 0")
    if address + DATATYPES[datatype].width > 65536:
        raise MapError(f"{where}: 'address' {address} runs past 65535")
    order = raw.get("word_order", default_order)
    if order not in WORD_ORDERS:
        raise MapError(f"{where}: bad word_order '{order}' (ABCD or CDAB)")
    scale = _num(raw.get("scale", 1.0), where, "scale")
    if scale == 0:
        raise MapError(f"{where}: 'scale' must not be 0")
    offset = _num(raw.get("offset", 0.0), where, "offset")
    encoding = DATATYPES[datatype]
    if (encoding.is_float or encoding.is_bit) and (scale != 1.0 or offset != 0.0):
        carried = "a bit carries 0/1" if encoding.is_bit else "a float carries the value"
        raise MapError(f"{where}: 'scale'/'offset' apply to integer types only ({carried})")
    access = raw.get("access", "r")
    # a writable point of a whole command carries each whole value and nothing between: a
    # scale of 0.5 decoded fractions (the burner fired on 0.5), one of 2 could not carry 1
    # (a re-probe: written on, it read off)
    if signal.whole and access == "rw" and not (abs(scale) == 1.0 and offset.is_integer()):
        raise MapError(
            f"{where}: '{signal_name}' takes whole numbers only, so a writable point of it "
            f"has scale 1 or -1 and a whole offset (scale {scale:g}, offset {offset:g})"
        )
    if access not in ("r", "rw"):
        raise MapError(f"{where}: bad access '{access}' (r or rw)")
    if access == "rw":
        if table not in ("holding", "coil"):
            raise MapError(f"{where}: writable points live in 'holding' or 'coil', not '{table}'")
        if signal.kind != "command":
            raise MapError(f"{where}: signal '{signal_name}' is not a command, cannot be rw")
    if access != "rw" and ("min" in raw or "max" in raw):
        raise MapError(f"{where}: 'min'/'max' apply to writable points (access: rw)")
    minimum = _num(raw.get("min", signal.minimum), where, "min") if "min" in raw else signal.minimum
    maximum = _num(raw.get("max", signal.maximum), where, "max") if "max" in raw else signal.maximum
    if minimum > maximum:
        raise MapError(f"{where}: 'min' {minimum} exceeds 'max' {maximum}")
    if access == "rw" and (minimum < signal.minimum or maximum > signal.maximum):
        raise MapError(
            f"{where}: range {minimum:g}..{maximum:g} exceeds the signal's "
            f"{signal.minimum:g}..{signal.maximum:g}"
        )
    name = raw.get("name", signal_name)
    if not isinstance(name, str) or not name:
        raise MapError(f"{where}: 'name' must be a non-empty text, got {_kind(name)}")
    unit = _text(raw, "unit", signal.unit, where)
    if _unit_key(unit) != _unit_key(signal.unit):  # (unit: K served 22 C as "22 K": a probe)
        raise MapError(
            f"{where}: 'unit' {_kind(unit)} is not the unit of '{signal_name}' "
            f"({signal.unit}): a point serves the signal in its own unit, a scale and an "
            "offset give its register's resolution, not another unit; leave 'unit' out"
        )
    return Point(
        name=name,
        signal=signal_name,
        table=table,
        address=address,
        datatype=datatype,
        word_order=order,
        scale=scale,
        offset=offset,
        unit=unit,
        access=access,
        minimum=minimum,
        maximum=maximum,
        description=_text(raw, "description", signal.description, where),
    )


def _unit_key(unit: str) -> str:
    """A unit as written, compared: spaces, a degree sign and letter case aside ('°C' and
    'C', 'kg / h' and 'kg/h' were refused as other units: a re-probe)."""
    return unit.replace(" ", "").replace("°", "").replace("deg", "").lower()


def _kind(value: Any) -> str:
    """What a value is, for a message (never the value itself: a list of YAML aliases
    nested ten deep printed for 24 s in 2.5 GB, a stranger's probe)."""
    if isinstance(value, str | int | float | bool) or value is None:
        return repr(value) if len(repr(value)) <= 40 else f"{repr(value)[:30]}..."
    return f"a {type(value).__name__}"


def _text(raw: Mapping[str, Any], key: str, default: str, where: str) -> str:
    """A free-text key (the map's name, a description, an instrument, a unit): text, a
    number as its text (``instrument: 42`` is "42"), or refused (a list was printed as such
    in the reference)."""
    value = raw.get(key, default)
    if isinstance(value, int | float) and not isinstance(value, bool):
        return str(value)
    if not isinstance(value, str):
        raise MapError(f"{where}: '{key}' must be text, got {_kind(value)}")
    return value


def map_from_mapping(data: Any, source: str = "<map>") -> RegisterMap:
    """Validate ``data`` and build a :class:`RegisterMap`."""
    if not isinstance(data, Mapping):
        raise MapError(f"{source}: expected a mapping")
    for key in data:
        if key not in ("name", "description", "devices"):
            raise MapError(f"{source}: unknown key '{key}'")
    devices_raw = data.get("devices")
    if not isinstance(devices_raw, list) or not devices_raw:
        raise MapError(f"{source}: 'devices' must be a non-empty list")
    devices: list[Device] = []
    seen_ids: dict[int, str] = {}
    for i, raw in enumerate(devices_raw):
        where = f"{source}: devices[{i}]"
        if not isinstance(raw, Mapping):
            raise MapError(f"{where}: must be a mapping")
        if "name" not in raw:
            raise MapError(f"{where}: missing required key 'name'")
        name = raw["name"]
        if not isinstance(name, str) or not name:  # (17 was "missing": a stranger's probe)
            raise MapError(f"{where}: 'name' must be a non-empty text, got {_kind(name)}")
        _check_shown_name(name, where)
        where = f"{source}: device '{name}'"
        for key in raw:
            if key not in ("name", "unit_id", "instrument", "word_order", "points"):
                raise MapError(f"{where}: unknown key '{key}'")
        if "unit_id" not in raw:  # (was "'unit_id' must be an integer": a stranger's probe)
            raise MapError(f"{where}: missing required key 'unit_id'")
        unit_id = raw["unit_id"]
        if isinstance(unit_id, bool) or not isinstance(unit_id, int) or not 1 <= unit_id <= 247:
            raise MapError(f"{where}: 'unit_id' must be an integer 1..247")
        if unit_id in seen_ids:
            raise MapError(f"{where}: unit_id {unit_id} already used by '{seen_ids[unit_id]}'")
        if name in seen_ids.values():
            raise MapError(f"{where}: device name used twice")
        seen_ids[unit_id] = name
        order = raw.get("word_order", "ABCD")
        if order not in WORD_ORDERS:
            raise MapError(f"{where}: bad word_order '{order}' (ABCD or CDAB)")
        points_raw = raw.get("points")
        if not isinstance(points_raw, list) or not points_raw:
            raise MapError(f"{where}: 'points' must be a non-empty list")
        points: list[Point] = []
        for j, praw in enumerate(points_raw):
            label = praw.get("name") if isinstance(praw, Mapping) else None
            _check_shown_name(label, f"{where} points[{j}]")
            label = label if isinstance(label, str) else f"#{j}"
            points.append(_point(praw, f"{where} point '{label}'", order))
        # counted once (a list's count per point took 108 s for a map of 32,000 points,
        # within the size limit: a stranger's probe); the first point of a name used twice
        uses = Counter(p.name for p in points)
        for point in points:
            if uses[point.name] > 1:
                raise MapError(f"{where} point '{point.name}': name used twice")
        for table in TABLES:
            used: dict[int, str] = {}
            for point in sorted((p for p in points if p.table == table), key=lambda p: p.address):
                for addr in range(point.address, point.address + point.width):
                    if addr in used:
                        raise MapError(
                            f"{where} point '{point.name}': address {addr} in table '{table}' "
                            f"overlaps point '{used[addr]}'"
                        )
                    used[addr] = point.name
        devices.append(Device(name, unit_id, _text(raw, "instrument", "", where), tuple(points)))
    return RegisterMap(
        name=_text(data, "name", Path(source).stem, source),
        description=_text(data, "description", "", source),
        devices=tuple(devices),
        source=source,
    )


def load_map(path: str | Path | None = None) -> RegisterMap:
    """Load and validate a register map (default: the shipped Wieselburg bench map)."""
    path = Path(path) if path is not None else MAP_DIR / "wieselburg_bench.yaml"
    data = read_yaml(path, MapError)
    return map_from_mapping(data, source=str(path))


def control_units(register_map: RegisterMap) -> frozenset[int]:
    """The units of ``register_map`` that drive the emulator: a device publishing a clock
    or fault command (a command that is no plant command) is the simulation control as a
    whole (roles are per unit: an operator allowed the unit would reach the clock)."""
    return frozenset(
        d.unit_id
        for d in register_map.devices
        if any(SIGNALS[p.signal].kind == "command" and p.signal not in PLANT_COMMANDS
               for p in d.points)
    )  # fmt: skip


def instrument_units(register_map: RegisterMap) -> frozenset[int]:
    """The units of ``register_map`` that are the bench's instruments: they publish a
    measured signal or a plant command, and drive nothing of the emulator."""
    control = control_units(register_map)
    return frozenset(
        d.unit_id
        for d in register_map.devices
        if d.unit_id not in control
        and any(SIGNALS[p.signal].kind == "measured" or p.signal in PLANT_COMMANDS
                for p in d.points)
    )  # fmt: skip


def emulator_units(register_map: RegisterMap) -> frozenset[int]:
    """The emulator's own units in ``register_map``, every one that is no instrument (the
    simulation control and the truth; units 100 and 101 of the shipped map). They are never
    faulted and never reached by a broadcast, wherever a map puts them (they were unit
    numbers: a map with the simulation control at unit 7 let a fault silence it, and an
    RTU broadcast reset the plant: a re-probe)."""
    return frozenset(d.unit_id for d in register_map.devices) - instrument_units(register_map)
