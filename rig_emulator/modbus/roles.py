"""Role-based authorisation of Modbus/TCP Security (the roles of the client certificates).

A role says which units a client may read and which it may write. The defaults
(CONTRACT section 6), derived from the served register map by what its devices publish,
not by their unit IDs (:func:`default_policy`):

- ``observer`` reads every unit and writes none;
- ``operator`` also writes the instruments: the devices publishing a measured signal or a
  command of the plant (the shipped map's units 1-7);
- ``engineer`` also writes the simulation control: the devices publishing a clock or fault
  command (:func:`~rig_emulator.registers.control_units`; the shipped map's unit 100).

Any other device (the truth unit, a device of status signals only) is read only. A device
publishing a simulation-control command is simulation control as a whole, even if it also
has instrument points: roles are granted per unit, and the operator must not reach the
clock through a shared unit.

A certificate without the role extension gets ``default_role`` (``observer``); a role the
policy does not know may do nothing. A ``ROLES.yaml`` file redefines them, with unit IDs
taken as written (here the defaults of the shipped map)::

    default_role: observer          # optional; for certificates without the role extension
    roles:
      observer: {read: all, write: []}
      operator: {read: all, write: [1, 2, 3, 4, 5, 6, 7]}
      engineer: {read: all, write: [1, 2, 3, 4, 5, 6, 7, 100]}

``read``/``write`` are ``all`` or a list of unit IDs (1-247: 0 is the serial line's
broadcast and 248-255 are reserved, so no unit of a map has them); a key left out is no
unit (``write: all`` alone reads nothing: the start-up summary says what each role reads
and writes). The role only decides who may ask: what may be written at all (``rw`` points,
ranges) is still checked by the server.

A request is allowed only if the role may do every part of it (:func:`rights_needed`):
reads (1, 2, 3, 4, 7, 11, 12, 17, 20, 24, and 43/14 read device identification) need
``read``; writes whose answer holds no register value (5, 6, 15, 16, 21, 22) need ``write``;
23 (read/write multiple registers), which writes and then returns the registers it reads,
and every other function code (8 diagnostics, other 43 MEI types, codes nobody defined)
need both. An FC23 by a role that writes a unit but may not read it used to write and
return that unit's registers (a stranger's probe).

Role names are text of any script, spaces of any kind included, without a character of
:data:`rig_emulator.names.HIDDEN_CATEGORIES` (a control or format character, a line or
paragraph separator, a surrogate, a private-use or unassigned code point: they let a name
display as another, or as nothing), and not in angle brackets: ``<...>`` is the form of
the server's own stand-ins (:data:`INVALID_ROLE`, the role of a certificate whose role extension is
malformed, which may do nothing whatever a file says). Logs show a role by :func:`shown`,
as written but for such characters, so a certificate's role cannot write lines of its own
into the log.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig_emulator.modbus.conformance import ENCAPSULATED_INTERFACE, MEI_READ_DEVICE_ID
from rig_emulator.names import hidden_character, shown
from rig_emulator.registers import RegisterMap, control_units, instrument_units
from rig_emulator.yamlio import read_yaml

READ = "read"
WRITE = "write"
#: function codes that only read (43 only with MEI type 14, see :func:`rights_needed`)
READ_FUNCTIONS = frozenset({1, 2, 3, 4, 7, 11, 12, 17, 20, 24, 43})
#: function codes that only write: their answer echoes the request or a count
WRITE_FUNCTIONS = frozenset({5, 6, 15, 16, 21, 22})
ALL_UNITS = frozenset(range(256))
#: the unit IDs a ROLES.yaml may name (Modbus over Serial Line V1.02 section 2.2: 0 is the
#: broadcast address, 248-255 are reserved; a map's units are 1-247)
UNIT_IDS = range(1, 248)
#: the role of a certificate whose role extension is malformed (not one UTF8String, given
#: twice, not parsed): no ROLES.yaml can name it (its ``<``), and it may do nothing
INVALID_ROLE = "<invalid role extension>"
#: The instruments and the simulation control of the shipped map (:data:`DEFAULT_POLICY`)
INSTRUMENT_UNITS = frozenset(range(1, 8))
SIM_CONTROL_UNIT = 100


class RolesError(ValueError):
    """A bad ROLES.yaml (the message names the file and the key at fault)."""


@dataclass(frozen=True)
class Role:
    """What one role may do: the units it may read and the units it may write."""

    name: str
    read_units: frozenset[int]
    write_units: frozenset[int]

    def refusal(self, unit_id: int, function_code: int, mei_type: int | None = None) -> str | None:
        """Why this role may not send ``function_code`` (of ``mei_type`` for 43) to
        ``unit_id`` (None: it may): every right the request needs must be granted."""
        needed = rights_needed(function_code, mei_type)
        if READ in needed and unit_id not in self.read_units:
            return f"may not read unit {unit_id}"
        if WRITE in needed and unit_id not in self.write_units:
            return f"may not write unit {unit_id}"
        return None


def rights_needed(function_code: int, mei_type: int | None = None) -> frozenset[str]:
    """The rights (:data:`READ`, :data:`WRITE`) a request of ``function_code`` needs: both
    unless it only reads or only writes (the module docstring); FC 43 only reads for MEI
    type 14 (read device identification; 13, CANopen, may write)."""
    if function_code == ENCAPSULATED_INTERFACE and mei_type != MEI_READ_DEVICE_ID:
        return frozenset({READ, WRITE})
    if function_code in READ_FUNCTIONS:
        return frozenset({READ})
    if function_code in WRITE_FUNCTIONS:
        return frozenset({WRITE})
    return frozenset({READ, WRITE})


@dataclass(frozen=True)
class RolePolicy:
    """The roles of a server and the role of a certificate without the role extension."""

    roles: Mapping[str, Role]
    default_role: str

    def refusal(
        self, role: str, unit_id: int, function_code: int, mei_type: int | None = None
    ) -> str | None:
        """Why ``role`` may not send ``function_code`` (of ``mei_type`` for 43) to
        ``unit_id`` (None: it may)."""
        if role == INVALID_ROLE:  # never a policy's role, whatever it holds
            return "the certificate's role extension is malformed, so it may send nothing"
        known = self.roles.get(role)
        if known is None:
            return f"unknown role '{role}', which may send nothing"
        return known.refusal(unit_id, function_code, mei_type)

    def summary(self) -> str:
        """What each role may read and write, for the log (``operator reads every unit,
        writes units 1-7``): a role granted writes without reads was shown as writing
        "every unit" while it could read nothing (a stranger's probe)."""
        return "; ".join(
            f"{shown(name)} reads {_shown_units(role.read_units)}, "
            f"writes {_shown_units(role.write_units)}"
            for name, role in self.roles.items()
        )


def _shown_units(units: frozenset[int]) -> str:
    if not units:
        return "no unit"
    if units == ALL_UNITS:
        return "every unit"
    runs: list[list[int]] = []
    for unit in sorted(units):
        if runs and unit == runs[-1][1] + 1:
            runs[-1][1] = unit
        else:
            runs.append([unit, unit])
    shown = ", ".join(str(a) if a == b else f"{a}-{b}" for a, b in runs)
    return f"unit{'s' if len(units) > 1 else ''} {shown}"


def _default_roles(instruments: frozenset[int], control: frozenset[int]) -> RolePolicy:
    return RolePolicy(
        roles={
            "observer": Role("observer", ALL_UNITS, frozenset()),
            "operator": Role("operator", ALL_UNITS, instruments),
            "engineer": Role("engineer", ALL_UNITS, instruments | control),
        },
        default_role="observer",
    )


#: The default roles of the shipped map (``default_policy(load_map())``)
DEFAULT_POLICY = _default_roles(INSTRUMENT_UNITS, frozenset({SIM_CONTROL_UNIT}))


def default_policy(register_map: RegisterMap) -> RolePolicy:
    """The default roles (module docstring) of a server of ``register_map``: the units each
    role writes follow what the devices publish, not their numbers (with the simulation
    control at unit 7 and an instrument at unit 100, the operator could advance and reset
    the clock, and with instruments at units 31 and 247 it was refused its pump and
    setpoint writes: a stranger's probe). The shipped map gives :data:`DEFAULT_POLICY`."""
    return _default_roles(instrument_units(register_map), control_units(register_map))


def _units(value: Any, where: str) -> frozenset[int]:
    if value == "all":
        return ALL_UNITS
    if value is None:
        return frozenset()
    if not isinstance(value, list):
        raise RolesError(f"{where}: '{value}' is neither 'all' nor a list of unit IDs")
    units = set()
    for item in value:
        if isinstance(item, str):  # ('1' is not a unit ID, said of a quoted 1: a probe)
            raise RolesError(f"{where}: {item!r:.40} is text: a unit ID is a number, unquoted")
        if isinstance(item, bool) or not isinstance(item, int) or item not in UNIT_IDS:
            written = str(item).lower() if isinstance(item, bool) else item  # (as in YAML)
            raise RolesError(
                f"{where}: '{written}' is not a unit ID (1-247; 0 is the broadcast address, "
                "248-255 are reserved)"
            )
        units.add(item)
    return frozenset(units)


def _check_role_name(name: Any, source: str) -> None:
    """RolesError unless ``name`` is a role a certificate may name (module docstring): a
    name of the stand-ins' form ``<...>`` (a file defining ``<invalid role extension>`` gave
    its rights to every malformed role extension), or holding a character of
    :data:`rig_emulator.names.HIDDEN_CATEGORIES` (named by its code point), is refused;
    ``a->b``, ``op<1>`` and ``lab tech`` with a no-break space are names (they were
    refused: a stranger's probe)."""
    if not isinstance(name, str) or not name.strip():
        shown_name = shown(name) if isinstance(name, str) else name
        raise RolesError(f"{source}: role name '{shown_name}' is not a non-empty text")
    hidden = hidden_character(name)
    if hidden is not None:
        raise RolesError(f"{source}: role name '{shown(name)}' holds {hidden}")
    if name.startswith("<") and name.endswith(">"):
        raise RolesError(
            f"{source}: role name '{name}' is in angle brackets, the form of the server's own "
            "stand-ins (a malformed role extension may do nothing)"
        )


def policy_from_mapping(data: Any, source: str) -> RolePolicy:
    """A :class:`RolePolicy` from the parsed content of a ROLES.yaml (``source`` names it in
    errors)."""
    if not isinstance(data, dict):
        raise RolesError(f"{source}: expected a mapping with 'roles'")
    unknown = sorted(set(data) - {"roles", "default_role"})
    if unknown:
        raise RolesError(f"{source}: unknown key '{unknown[0]}' (expected roles, default_role)")
    entries = data.get("roles")
    if not isinstance(entries, dict) or not entries:
        raise RolesError(f"{source}: 'roles' must be a non-empty mapping of role names")
    roles: dict[str, Role] = {}
    for name, spec in entries.items():
        _check_role_name(name, source)
        where = f"{source}: roles.{name}"
        if not isinstance(spec, dict):
            raise RolesError(f"{where}: expected a mapping with read and write")
        extra = sorted(set(spec) - {"read", "write"})
        if extra:
            raise RolesError(f"{where}: unknown key '{extra[0]}' (expected read, write)")
        roles[name] = Role(
            name,
            _units(spec.get("read"), f"{where}.read"),
            _units(spec.get("write"), f"{where}.write"),
        )
    default = data.get("default_role", "observer")
    if default not in roles:
        raise RolesError(
            f"{source}: default_role '{shown(str(default))}' is not one of the roles "
            f"({', '.join(roles)})"
        )
    return RolePolicy(roles, default)


def load_policy(path: str | Path | None) -> RolePolicy:
    """The policy of a ROLES.yaml, or :data:`DEFAULT_POLICY` for None."""
    if path is None:
        return DEFAULT_POLICY
    return policy_from_mapping(read_yaml(Path(path), RolesError), str(path))


class RefusalLog:
    """Decides which refusals get a log line, so a flood does not flood the log: the first
    refusal of each (connection, reason) is logged, and at most ``burst`` lines per
    ``window_s`` in all; the rest are counted and reported with the next line logged."""

    def __init__(self, burst: int = 20, window_s: float = 60.0, max_keys: int = 10000) -> None:
        self.burst = burst
        self.window_s = window_s
        self.max_keys = max_keys
        self._seen: set[tuple[str, str]] = set()
        self._window_start = -float("inf")
        self._in_window = 0
        self.suppressed = 0

    def admit(self, connection: str, reason: str, now: float | None = None) -> int | None:
        """None if this refusal is not to be logged; else how many were suppressed before
        it (and the count restarts)."""
        key = (connection, reason)
        if key in self._seen:
            self.suppressed += 1
            return None
        now = time.monotonic() if now is None else now
        if now - self._window_start >= self.window_s:
            self._window_start, self._in_window = now, 0
        if self._in_window >= self.burst:
            self.suppressed += 1
            return None
        if len(self._seen) >= self.max_keys:
            self._seen.clear()
        self._seen.add(key)
        self._in_window += 1
        suppressed, self.suppressed = self.suppressed, 0
        return suppressed

    def forget(self, connection: str) -> None:
        """A connection closed: its keys may go (a new one from the same port logs again)."""
        self._seen = {k for k in self._seen if k[0] != connection}
