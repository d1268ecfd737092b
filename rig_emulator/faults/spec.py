"""Faults as data: the entries of ``FAULTS.yaml`` (CONTRACT section 5), validated.

    faults:
      - {kind: no_reply, unit: 2, at_s: 600, for_s: 120}      # analyser silent for 2 min
      - {kind: exception, unit: 5, code: 6, at_s: 900, for_s: 30}  # balance busy
      - {kind: delay, unit: 1, delay_ms: 800, at_s: 1200, for_s: 60}
      - {kind: disconnect, at_s: 1500}                        # every connection closed once
      - {kind: stuck, signal: flue_gas_temp_C, at_s: 1800, for_s: 300}
      - {kind: drift, signal: water_out_temp_C, rate_per_h: 2.0, at_s: 2000}
      - {kind: spike, signal: flue_gas_O2_pct, value: 25.0, at_s: 2400}
      - {kind: dropout, signal: flue_gas_CO_ppm, at_s: 2500, for_s: 60}
      - {kind: offset, signal: balance_mass_kg, value: 15.0, at_s: 3000}  # refill
      - {kind: random, rate_per_h: 2, kinds: [no_reply, spike, dropout], seed: 7}

Times are simulated seconds. ``for_s`` absent: until cleared (a spike lasts one second,
i.e. one acquisition at the usual 1 s period; a disconnect happens once). Communication
faults name a ``unit`` (0 = every instrument unit; the simulation control, unit 100, and
the truth unit 101 are never faulted, so faults can always be cleared). Instrument faults
name a lab-log ``signal`` (a measured signal of :mod:`rig_emulator.signals`).

``kind: random`` draws faults at ``rate_per_h`` (a Poisson process in simulated time,
seeded by ``seed``) from ``kinds``, each lasting ``fault_for_s`` [60 s], on ``units``
[every instrument unit of the server's map] or ``signals`` [every measured signal it
publishes], from
``at_s`` [0] for ``for_s`` [forever]; ``params`` may set each drawn kind's parameters,
e.g. ``{delay: {delay_ms: 500}}`` (defaults: :data:`RANDOM_DEFAULTS`).

A bad entry raises :class:`FaultError` naming the file, the entry and the field.
"""

from __future__ import annotations

import datetime
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from rig_emulator.signals import MEASURED
from rig_emulator.yamlio import read_yaml

COMM_KINDS = ("delay", "no_reply", "exception", "disconnect")
INSTRUMENT_KINDS = ("stuck", "drift", "spike", "dropout", "offset")
KINDS = (*COMM_KINDS, *INSTRUMENT_KINDS)
#: The kind's own parameter (None: it has none).
PARAMETER = {
    "delay": "delay_ms",
    "no_reply": None,
    "exception": "code",
    "disconnect": None,
    "stuck": None,
    "drift": "rate_per_h",
    "spike": "value",
    "dropout": None,
    "offset": "value",
}
CONTROL_UNIT = 100  # the simulation control: never faulted
TRUTH_UNIT = 101  # the plant's true values: never faulted
#: the emulator's own units, not instruments: never faulted, never reached by a broadcast
EMULATOR_UNITS = (CONTROL_UNIT, TRUTH_UNIT)
NEVER_FAULTED = EMULATOR_UNITS
#: the shipped map's instrument units: random faults draw from them without a map
SHIPPED_INSTRUMENT_UNITS = (1, 2, 3, 4, 5, 6, 7)
SPIKE_FOR_S = 1.0  # a spike without for_s: one acquisition at the usual 1 s period
MAX_DELAY_MS = 600_000.0
#: Parameters of randomly drawn faults unless the entry's ``params`` says otherwise.
RANDOM_DEFAULTS: dict[str, dict[str, float]] = {
    "delay": {"delay_ms": 2000.0},
    "exception": {"code": 6.0},  # server device busy
    "drift": {"rate_per_h": 2.0},
    "spike": {"value": 9999.0},  # an open-circuit or overload reading
    "offset": {"value": 15.0},  # a refill of the balance
}
_COMMON = ("kind", "at_s", "for_s")
_RANDOM_KEYS = (
    "kind",
    "at_s",
    "for_s",
    "rate_per_h",
    "kinds",
    "seed",
    "fault_for_s",
    "units",
    "signals",
    "params",
)


class FaultError(ValueError):
    """A fault entry is malformed; the message names the file, entry and field."""


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """One fault: ``kind`` on ``unit`` (communication) or ``signal`` (instrument), from
    ``at_s`` (None: as soon as it is set) for ``for_s`` (None: until cleared / once)."""

    kind: str
    at_s: float | None = None
    for_s: float | None = None
    unit: int | None = None
    signal: str | None = None
    parameter: float | None = None  # delay_ms, code, rate_per_h or value

    @property
    def is_comm(self) -> bool:
        return self.kind in COMM_KINDS

    @property
    def target(self) -> str:
        return f"unit {self.unit}" if self.is_comm else str(self.signal)

    def as_dict(self) -> dict[str, Any]:
        """The entry as ``FAULTS.yaml`` would write it."""
        out: dict[str, Any] = {"kind": self.kind}
        if self.is_comm:
            out["unit"] = self.unit
        else:
            out["signal"] = self.signal
        name = PARAMETER[self.kind]
        if name is not None:
            out[name] = int(self.parameter) if name == "code" else self.parameter
        if self.at_s is not None:
            out["at_s"] = self.at_s
        if self.for_s is not None:
            out["for_s"] = self.for_s
        return out


@dataclass(frozen=True, slots=True)
class RandomSpec:
    """Faults drawn at random (see the module docstring)."""

    rate_per_h: float
    kinds: tuple[str, ...]
    seed: int = 0
    at_s: float = 0.0
    for_s: float | None = None
    fault_for_s: float = 60.0
    #: () : every instrument unit of the map served (:attr:`FaultEngine.instrument_units`)
    units: tuple[int, ...] = ()
    #: () : every measured signal the map served publishes (:attr:`FaultEngine.signals`)
    signals: tuple[str, ...] = ()
    params: Mapping[str, Mapping[str, float]] = field(default_factory=dict)

    kind = "random"

    def parameter(self, kind: str) -> float | None:
        name = PARAMETER[kind]
        if name is None:
            return None
        given = self.params.get(kind, {})
        return float(given.get(name, RANDOM_DEFAULTS[kind][name]))

    def as_dict(self) -> dict[str, Any]:
        return {
            "kind": "random",
            "rate_per_h": self.rate_per_h,
            "kinds": list(self.kinds),
            "seed": self.seed,
            "at_s": self.at_s,
            "for_s": self.for_s,
            "fault_for_s": self.fault_for_s,
            "units": list(self.units),
            "signals": list(self.signals),
            "params": {k: dict(v) for k, v in self.params.items()},
        }


Entry = FaultSpec | RandomSpec


def _number(where: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    """A number (numpy's too: a value taken from an array or a table)."""
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Real):
        shown = f"'{value}'" if isinstance(value, datetime.date | datetime.time) else repr(value)
        raise FaultError(f"{where}: must be a number, not {shown}")
    given = value
    try:
        value = float(value)
    except OverflowError:  # an integer of hundreds of digits
        raise FaultError(f"{where}: too large a number (at most {high:g})") from None
    too_low = value <= low if low_open else value < low
    if not math.isfinite(value) or too_low or value > high:
        bound = f"> {low:g}" if low_open else f">= {low:g}"
        raise FaultError(f"{where}: {_given(given)} must be finite, {bound} and <= {high:g}")
    return value


def _given(value: Any) -> str:
    """A number as given, every digit (a stranger's probe: ``:g`` showed an at_s of
    1000000001 as 1e+09, which looked within its bound of 1e+09)."""
    if isinstance(value, numbers.Integral):
        return str(int(value))
    return repr(float(value))


def _integer(where: str, value: Any, low: int, high: int) -> int:
    """A whole number (numpy's integers too)."""
    if value is None:  # ("not None" for a key left out: a stranger's probe)
        raise FaultError(f"{where}: missing (a whole number, {low}..{high})")
    if isinstance(value, bool | np.bool_) or not isinstance(value, numbers.Integral):
        raise FaultError(f"{where}: must be a whole number, not {value!r}")
    value = int(value)
    if not low <= value <= high:
        raise FaultError(f"{where}: {value} is outside {low}..{high}")
    return value


def _unit(where: str, value: Any) -> int:
    return _integer(where, value, 0, 247)


def _signal(where: str, value: Any) -> str:
    if value not in MEASURED:
        raise FaultError(f"{where}: {value!r} is not a measured lab-log signal")
    return str(value)


def check_parameter(where: str, kind: str, value: Any) -> float:
    """The kind's parameter, validated (``where`` names it in the error)."""
    if kind == "delay":
        return _number(where, value, 0.0, MAX_DELAY_MS, low_open=True)
    if kind == "exception":
        return float(_integer(where, value, 1, 255))
    return _number(where, value, -1e9, 1e9)


def fault_from_mapping(data: Any, where: str) -> Entry:
    """One entry of ``faults:`` validated (``where`` prefixes every error)."""
    if not isinstance(data, Mapping):
        raise FaultError(f"{where}: expected a mapping with 'kind'")
    kind = data.get("kind")
    if kind == "random":
        return _random_from_mapping(data, where)
    if kind is None:  # (said as "None is not one of ...": a stranger's probe)
        raise FaultError(f"{where}: missing 'kind' (one of {', '.join(KINDS)}, random)")
    if kind not in KINDS:
        raise FaultError(f"{where}.kind: {kind!r} is not one of {', '.join(KINDS)}, random")
    allowed = (*_COMMON, "unit" if kind in COMM_KINDS else "signal")
    if PARAMETER[kind] is not None:
        allowed = (*allowed, PARAMETER[kind])
    for key in data:
        if key not in allowed:
            raise FaultError(f"{where}.{key}: not a field of kind {kind} ({', '.join(allowed)})")
    at_s = data.get("at_s")
    at_s = None if at_s is None else _number(f"{where}.at_s", at_s, 0.0, 1e9)
    for_s = data.get("for_s")
    for_s = None if for_s is None else _number(f"{where}.for_s", for_s, 0.0, 1e9, low_open=True)
    unit = signal = parameter = None
    if kind in COMM_KINDS:
        unit = _unit(f"{where}.unit", data.get("unit", 0 if kind == "disconnect" else None))
        if kind == "disconnect" and unit != 0:
            raise FaultError(
                f"{where}.unit: {unit}: a disconnect closes every connection, of every unit"
                " (a TCP connection carries them all); give 0 or none"
            )
    else:
        if "signal" not in data:
            raise FaultError(f"{where}.signal: missing (an instrument fault names a signal)")
        signal = _signal(f"{where}.signal", data["signal"])
    name = PARAMETER[kind]
    if name is not None:
        if name not in data:
            raise FaultError(f"{where}.{name}: missing (kind {kind} needs it)")
        parameter = check_parameter(f"{where}.{name}", kind, data[name])
    return FaultSpec(kind, at_s, for_s, unit, signal, parameter)


def _random_from_mapping(data: Mapping, where: str) -> RandomSpec:
    for key in data:
        if key not in _RANDOM_KEYS:
            raise FaultError(
                f"{where}.{key}: not a field of kind random ({', '.join(_RANDOM_KEYS)})"
            )
    if "rate_per_h" not in data:
        raise FaultError(f"{where}.rate_per_h: missing (kind random needs it)")
    rate = _number(f"{where}.rate_per_h", data["rate_per_h"], 0.0, 1e6, low_open=True)
    kinds = data.get("kinds")
    if not isinstance(kinds, list) or not kinds:
        raise FaultError(f"{where}.kinds: must be a non-empty list of fault kinds")
    for i, kind in enumerate(kinds):
        if kind not in KINDS:
            raise FaultError(f"{where}.kinds[{i}]: {kind!r} is not one of {', '.join(KINDS)}")
    seed = _integer(f"{where}.seed", data.get("seed", 0), 0, 2**63 - 1)
    at_s = _number(f"{where}.at_s", data.get("at_s", 0.0), 0.0, 1e9)
    for_s = data.get("for_s")
    for_s = None if for_s is None else _number(f"{where}.for_s", for_s, 0.0, 1e9, low_open=True)
    fault_for_s = _number(
        f"{where}.fault_for_s", data.get("fault_for_s", 60.0), 0.0, 1e9, low_open=True
    )
    # absent: every instrument unit of the map served, whichever those are (a fixed 1-7
    # refused the whole file with a map whose instruments sit elsewhere: a stranger's probe)
    units = data.get("units", [])
    if not isinstance(units, list) or ("units" in data and not units):
        raise FaultError(f"{where}.units: must be a non-empty list of unit IDs")
    units = [_unit(f"{where}.units[{i}]", u) for i, u in enumerate(units)]
    # absent: every measured signal the map served publishes (a fixed list drew faults on
    # signals a map without the FID never served, journalled and never seen: a re-probe)
    signals = data.get("signals", [])
    if not isinstance(signals, list) or ("signals" in data and not signals):
        raise FaultError(f"{where}.signals: must be a non-empty list of signals")
    signals = [_signal(f"{where}.signals[{i}]", s) for i, s in enumerate(signals)]
    raw_params = data.get("params") or {}
    if not isinstance(raw_params, Mapping):
        raise FaultError(f"{where}.params: must be a mapping of kind -> parameters")
    params: dict[str, dict[str, float]] = {}
    for kind, given in raw_params.items():
        name = PARAMETER.get(kind) if kind in KINDS else None
        if name is None:
            raise FaultError(f"{where}.params.{kind}: not a kind with a parameter")
        if not isinstance(given, Mapping) or set(given) - {name}:
            raise FaultError(f"{where}.params.{kind}: must be {{{name}: NUMBER}}")
        if kind not in kinds:  # (it was ignored without a word: a stranger's probe)
            raise FaultError(
                f"{where}.params.{kind}: '{kind}' is not among the kinds drawn "
                f"({', '.join(kinds)}): add it to 'kinds' or leave its parameters out"
            )
        if name in given:
            value = check_parameter(f"{where}.params.{kind}.{name}", kind, given[name])
            params[kind] = {name: value}
    return RandomSpec(
        rate, tuple(kinds), seed, at_s, for_s, fault_for_s, tuple(units), tuple(signals), params
    )


def faults_from_list(data: Any, source: str = "<faults>", key: str = "faults") -> list[Entry]:
    """The entries of a ``faults:`` list (``source`` and ``key`` name it in errors)."""
    if data is None:
        return []
    if not isinstance(data, Sequence) or isinstance(data, str | bytes):
        raise FaultError(f"{source}: '{key}' must be a list of faults")
    return [fault_from_mapping(item, f"{source}: {key}[{i}]") for i, item in enumerate(data)]


def _field(where: str, i: int, entries: Sequence[Entry], name: str) -> str:
    """``where[i].name`` in a list of faults, ``where.name`` for one fault on its own."""
    listed = len(entries) > 1 or where.endswith("faults")
    return f"{where}[{i}].{name}" if listed else f"{where}.{name}"


def check_units(
    entries: Sequence[Entry],
    units: frozenset[int] | set[int],
    where: str,
    own: frozenset[int] = frozenset(EMULATOR_UNITS),
) -> None:
    """Each communication fault names a unit the bench has, or 0 (every unit): a fault on a
    unit nobody polls would hit nothing, silently (a typo, 99 for 9); never one of the
    emulator's own units ``own`` (the map's: :func:`~rig_emulator.registers.emulator_units`),
    so faults can always be cleared."""
    for i, entry in enumerate(entries):
        if isinstance(entry, RandomSpec):
            named = [(_field(where, i, entries, "units"), u) for u in entry.units]
            comm = [k for k in entry.kinds if k in ("delay", "no_reply", "exception")]
            if comm and not entry.units and not units - own:
                raise FaultError(
                    f"{_field(where, i, entries, 'kinds')}: {', '.join(comm)} need an "
                    "instrument unit, and the map has none"
                )
        elif entry.is_comm:
            named = [(_field(where, i, entries, "unit"), entry.unit)]
        else:
            named = []
        for field_name, unit in named:
            if unit in own:
                raise FaultError(
                    f"{field_name}: unit {unit} is the emulator's own (simulation control, "
                    "truth), never faulted"
                )
            if unit and unit not in units:
                known = ", ".join(str(u) for u in sorted(units) if u not in own)
                raise FaultError(
                    f"{field_name}: unit {unit} is not on the bench (units {known}, 0: all)"
                )


class ReadingRange(NamedTuple):
    """What an integer register serves of a signal: its lowest and highest reading, the
    register (for messages) and its step, the reading's resolution."""

    lo: float
    hi: float
    register: str
    step: float

    def served(self, value: float) -> float:
        """``value`` as the register serves it: clipped to its range, on its steps (NaN
        stays NaN)."""
        if value != value:
            return value
        clipped = min(max(value, self.lo), self.hi)
        steps = round((clipped - self.lo) / self.step) if self.step > 0 else 0
        return round(self.lo + steps * self.step, 9) if self.step > 0 else clipped


def check_spikes(entries: Sequence[Entry], ranges: Mapping[str, ReadingRange], where: str) -> None:
    """Each spike's value is one its signal's register can serve (``ranges``: per signal
    published as an integer, the lowest and highest reading and the register in words): an
    int16 in hundredths of a kelvin clipped a -999 spike onto its invalid code, which
    acquisition software reads as a dropout."""
    for i, entry in enumerate(entries):
        if isinstance(entry, RandomSpec) or entry.kind != "spike":
            continue
        known = ranges.get(str(entry.signal))
        if known is None:
            continue
        lo, hi, register, step = known
        value = float(entry.parameter or 0.0)
        # within half a step of the ends is the end itself, as the register serves it: the
        # command block carries the value as a float32 (327.67 is 327.6700134 there, and the
        # register's own end was refused; a re-probe); a millionth of the range let the
        # int32 balance's invalid code through (a re-probe)
        slack = 0.5 * step
        if not lo - slack <= value <= hi + slack:
            raise FaultError(
                f"{_field(where, i, entries, 'value')}: {_given(value)} is outside what"
                f" {entry.signal}'s register serves ({lo:.10g}..{hi:.10g}: {register})"
            )


def load_faults(path: str | Path) -> list[Entry]:
    """The faults of a ``FAULTS.yaml`` file (a mapping with the list ``faults:``)."""
    path = Path(path)
    data = read_yaml(path, FaultError)
    if not isinstance(data, Mapping) or "faults" not in data:
        raise FaultError(f"{path}: expected a mapping with a list 'faults:'")
    extra = [k for k in data if k not in ("faults", "description")]
    if extra:
        raise FaultError(f"{path}: unknown key '{extra[0]}' (expected faults, description)")
    return faults_from_list(data["faults"], str(path))
