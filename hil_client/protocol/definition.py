"""Test methods as data: the schema of protocol YAML files and its validation.

A protocol file describes the shared sequence of Fig. 3 (Carlon et al. 2015, Section 2.3)
and the measuring cycle between t1 and t2 as a list of sequences. Loads are in percent of
nominal load and become flow setpoints as load * Pnom / (cp_w * flow_spread_K).

    name: load_cycle            # label
    test: load_cycle            # stationary | load_cycle | other label written to the meta file
    acquisition_period_s: 1     # one log row per period [s]
    flow_spread_K: 15           # spread of the load-to-flow conversion [K]
    preheat:   {temperature_C: 45, tolerance_K: 0.5, hold_s: 60, load_pct: 100,
                max_duration_s: 14400}
    start_up:  {return_setpoint_C: 55, t1_window_s: 300, t1_max_rise_K_min: 0.5,
                min_duration_s: 300, max_duration_s: 7200}
    test_sequence: {return_setpoint_C: 55,
                sequences: [{name: peak, load_pct: 100, duration: "00:04:52"},
                            {name: gradient_100_48, load_pct: [100, 48], duration: 1560}]}
    cooling_1: {load_pct: 20, return_setpoint_C: 55, until_forward_C: 55,
                max_duration_s: 10800}
    cooling_2: {until_after_t2_s: 28800}

A sequence whose ``load_pct`` is a pair is a linear ramp from the first to the second value.
Durations are seconds or "HH:MM:SS".

Bounds (a file outside them is refused, naming the key): every duration and the whole
record (longest preheat + longest start-up + the measuring cycle + the longer of the first
cooling and the second) at most :data:`MAX_RECORD_S` (a week: the paper's records last
under a day and a long bench test a few days, while a typo such as 1e12 s would run for
ever and fill the disk); the acquisition period within :data:`ACQUISITION_PERIOD_S`
(0.1..600 s: a real-time emulator ticks at 10 Hz, so a faster logger reads the same state
again, and the phase rules look at minutes, the t1 slope over 5 min, the preheat hold of
1 min, which a logger slower than 10 min cannot follow); tolerances and the t1 rise positive,
hold times not negative, each minimum duration at most its maximum. Sequence names are
written into the lab log, so they are unique, not blank, and may not hold a comma, a quote
or control characters; a sequence lasts one acquisition period at least (a shorter one
was never logged nor its setpoint written); ``HH:MM:SS`` has minutes and seconds under 60.
What the setpoints of a protocol make of a given boiler is checked against the emulator's
command limits by :func:`hil_client.protocol.runner.check_setpoints`.
"""

from __future__ import annotations

import math
import re
import unicodedata
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig_emulator.yamlio import finite_number, read_yaml, resolve_named

DEFINITION_DIR = Path(__file__).parent / "definitions"

#: Longest duration of any key, and of the whole record [s]: a week (module docstring).
MAX_RECORD_S = 7 * 86400.0
#: Accepted acquisition periods [s] (module docstring).
ACQUISITION_PERIOD_S = (0.1, 600.0)


class ProtocolError(ValueError):
    """A protocol file is malformed; the message names the file and key."""


@dataclass(frozen=True, slots=True)
class Sequence:
    """One step of the measuring cycle: a constant load or a linear ramp [% of nominal]."""

    name: str
    load_start_pct: float
    load_end_pct: float
    duration_s: float

    def load_at(self, elapsed_s: float) -> float:
        """Load [% of nominal] ``elapsed_s`` seconds into the sequence."""
        if self.load_start_pct == self.load_end_pct:
            return self.load_start_pct
        w = min(max(elapsed_s / self.duration_s, 0.0), 1.0)
        return self.load_start_pct + (self.load_end_pct - self.load_start_pct) * w


@dataclass(frozen=True, slots=True)
class Preheat:
    temperature_C: float
    tolerance_K: float
    hold_s: float
    load_pct: float
    max_duration_s: float


@dataclass(frozen=True, slots=True)
class StartUp:
    return_setpoint_C: float
    t1_window_s: float
    t1_max_rise_K_min: float
    min_duration_s: float
    max_duration_s: float


@dataclass(frozen=True, slots=True)
class CoolingOne:
    load_pct: float
    return_setpoint_C: float
    until_forward_C: float
    max_duration_s: float


@dataclass(frozen=True, slots=True)
class ProtocolDefinition:
    """A whole test method (see the module docstring for the file form)."""

    name: str
    test: str
    acquisition_period_s: float
    flow_spread_K: float
    preheat: Preheat
    start_up: StartUp
    test_return_setpoint_C: float
    sequences: tuple[Sequence, ...]
    cooling_1: CoolingOne
    cooling_2_until_after_t2_s: float

    test_duration_s: float = 0.0  #: duration of the measuring cycle t1..t2 [s], derived

    def __post_init__(self) -> None:
        object.__setattr__(self, "test_duration_s", sum(s.duration_s for s in self.sequences))


#: One part of an "HH:MM:SS" duration: ASCII digits, a decimal fraction allowed, no sign.
_CLOCK_PART = re.compile(r"[0-9]+(?:\.[0-9]*)?")


def parse_duration(value: Any, key: str, source: str) -> float:
    """Seconds from a number or an "HH:MM:SS" string."""
    if isinstance(value, str):
        parts = [part.strip() for part in value.split(":")]
        try:
            # ASCII digits only: float() read "-00" as -0.0, so "-00:10:00" played +600 s,
            # and Arabic-Indic digits as 10 h (a stranger's probe)
            if len(parts) != 3 or not all(_CLOCK_PART.fullmatch(x) for x in parts):
                raise ValueError
            h, m, s = (float(x) for x in parts)
            if not all(math.isfinite(x) and x >= 0 for x in (h, m, s)) or m >= 60 or s >= 60:
                raise ValueError
        except ValueError:
            raise ProtocolError(
                f"{source}: key '{key}' must be seconds or HH:MM:SS, got {value!r}"
            ) from None
        seconds = h * 3600 + m * 60 + s
    else:
        seconds = _number(value, key, source)
    if seconds <= 0:
        raise ProtocolError(f"{source}: key '{key}' must be a positive duration")
    if seconds > MAX_RECORD_S:
        raise ProtocolError(
            f"{source}: key '{key}' is {seconds:g} s, more than a week ({MAX_RECORD_S:g} s)"
        )
    return seconds


def _number(value: Any, key: str, source: str) -> float:
    number = finite_number(value)
    if number is None:
        shown = f"{value!r}" if len(repr(value)) <= 40 else f"{repr(value)[:20]}..."
        raise ProtocolError(f"{source}: key '{key}' must be a finite number, got {shown}")
    return number


def _section(data: Mapping[str, Any], key: str, source: str) -> Mapping[str, Any]:
    if key not in data:
        raise ProtocolError(f"{source}: missing required key '{key}'")
    value = data[key]
    if not isinstance(value, Mapping):
        raise ProtocolError(f"{source}: key '{key}' must be a mapping")
    return value


def _get(section: Mapping[str, Any], prefix: str, key: str, source: str, kind: str = "num") -> Any:
    """A number of ``section``; ``kind``: ``num``, ``load`` (0..120 %), ``duration`` (see
    :func:`parse_duration`), ``positive`` (> 0) or ``hold`` (a time that may be 0)."""
    full = f"{prefix}.{key}" if prefix else key
    if key not in section:
        raise ProtocolError(f"{source}: missing required key '{full}'")
    if kind == "duration":
        return parse_duration(section[key], full, source)
    value = _number(section[key], full, source)
    if kind == "load" and not 0.0 <= value <= 120.0:
        raise ProtocolError(f"{source}: key '{full}' must be a load in 0..120 %, got {value}")
    if kind == "positive" and value <= 0:
        raise ProtocolError(f"{source}: key '{full}' must be > 0, got {value:g}")
    if kind == "hold" and not 0.0 <= value <= MAX_RECORD_S:
        raise ProtocolError(f"{source}: key '{full}' must be 0..{MAX_RECORD_S:g} s, got {value:g}")
    return value


def _text_key(
    section: Mapping[str, Any], key: str, full: str, source: str, in_log: bool = True
) -> str:
    """A non-empty text key without control characters and, ``in_log`` (a field of the lab
    log), commas or quotes (:func:`_log_text`); a key given as a number was said to be
    missing (a stranger's probe)."""
    if key not in section or section[key] is None:
        raise ProtocolError(f"{source}: missing required key '{full}' (a non-empty text)")
    value = section[key]
    if not isinstance(value, str) or not value.strip():
        raise ProtocolError(f"{source}: key '{full}' must be a non-empty text, got {value!r:.40}")
    if not in_log and _control_free(value):
        return value
    # (a stranger's probe: '=...' went in; a re-probe: a full-width '＝' too)
    if unicodedata.normalize("NFKC", value).lstrip().startswith(_FORMULA_STARTS):
        raise ProtocolError(
            f"{source}: key '{full}' {value!r:.40} may not begin with "
            f"{' '.join(_FORMULA_STARTS)}: a spreadsheet opening the lab log would run it as "
            "a formula"
        )
    if not _log_text(value):
        raise ProtocolError(
            f"{source}: key '{full}' {value!r:.40} may not hold "
            + (
                "a comma, a quote or control characters (it is a field of the lab log)"
                if in_log
                else "control characters"
            )
        )
    return value


#: What makes a spreadsheet read a CSV field as a formula (CSV injection, OWASP).
_FORMULA_STARTS = ("=", "+", "-", "@")


def _control_free(text: str) -> bool:
    """Whether ``text`` holds no line break or other control character."""
    return not any(unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp") for ch in text)


def _log_text(name: str) -> bool:
    """Whether ``name`` can stand in a lab-log field as it is: no comma, quote, line break
    or other control character."""
    return _control_free(name) and not any(ch in ',"' for ch in name)


#: Water boils at atmospheric pressure [C]: no forward the protocol sets may reach it.
WATER_BOILS_C = 100.0


def _not_longer(short: float, long: float, keys: tuple[str, str], source: str) -> None:
    if short > long:
        raise ProtocolError(
            f"{source}: key '{keys[0]}' ({short:g} s) exceeds '{keys[1]}' ({long:g} s)"
        )


def _check_keys(section: Mapping[str, Any], allowed: set[str], prefix: str, source: str) -> None:
    for key in section:
        if key not in allowed:
            name = f"{prefix}.{key}" if prefix else key
            known = ", ".join(sorted(allowed))  # (a stranger wrote a file from the errors)
            where = f"'{prefix}'" if prefix else "a protocol"
            raise ProtocolError(f"{source}: unknown key '{name}' (the keys of {where}: {known})")


def protocol_from_mapping(data: Any, source: str = "<protocol>") -> ProtocolDefinition:
    """Validate ``data`` and build a :class:`ProtocolDefinition`."""
    if not isinstance(data, Mapping):
        raise ProtocolError(f"{source}: expected a mapping")
    _check_keys(
        data,
        {
            "name",
            "test",
            "description",
            "acquisition_period_s",
            "flow_spread_K",
            "preheat",
            "start_up",
            "test_sequence",
            "cooling_1",
            "cooling_2",
        },
        "",
        source,
    )
    for key in ("name", "test"):  # (the meta file's, not the log's: a comma is fine)
        _text_key(data, key, key, source, in_log=False)
    period = _get(data, "", "acquisition_period_s", source, "positive")
    low, high = ACQUISITION_PERIOD_S
    if not low <= period <= high:
        raise ProtocolError(
            f"{source}: key 'acquisition_period_s' must be {low:g}..{high:g} s, got {period:g}"
        )
    spread = _get(data, "", "flow_spread_K", source, "positive")

    pre = _section(data, "preheat", source)
    _check_keys(
        pre,
        {"temperature_C", "tolerance_K", "hold_s", "load_pct", "max_duration_s"},
        "preheat",
        source,
    )
    preheat = Preheat(
        temperature_C=_get(pre, "preheat", "temperature_C", source),
        tolerance_K=_get(pre, "preheat", "tolerance_K", source, "positive"),
        hold_s=_get(pre, "preheat", "hold_s", source, "hold"),
        load_pct=_get(pre, "preheat", "load_pct", source, "load"),
        max_duration_s=_get(pre, "preheat", "max_duration_s", source, "duration"),
    )
    su = _section(data, "start_up", source)
    _check_keys(
        su,
        {
            "return_setpoint_C",
            "t1_window_s",
            "t1_max_rise_K_min",
            "min_duration_s",
            "max_duration_s",
        },
        "start_up",
        source,
    )
    start_up = StartUp(
        return_setpoint_C=_get(su, "start_up", "return_setpoint_C", source),
        t1_window_s=_get(su, "start_up", "t1_window_s", source, "duration"),
        t1_max_rise_K_min=_get(su, "start_up", "t1_max_rise_K_min", source, "positive"),
        min_duration_s=_get(su, "start_up", "min_duration_s", source, "duration"),
        max_duration_s=_get(su, "start_up", "max_duration_s", source, "duration"),
    )
    _not_longer(
        preheat.hold_s, preheat.max_duration_s, ("preheat.hold_s", "preheat.max_duration_s"), source
    )
    for key in ("min_duration_s", "t1_window_s"):
        _not_longer(
            getattr(start_up, key),
            start_up.max_duration_s,
            (f"start_up.{key}", "start_up.max_duration_s"),
            source,
        )
    ts = _section(data, "test_sequence", source)
    _check_keys(ts, {"return_setpoint_C", "sequences"}, "test_sequence", source)
    raw_sequences = ts.get("sequences")
    if not isinstance(raw_sequences, list) or not raw_sequences:
        raise ProtocolError(f"{source}: key 'test_sequence.sequences' must be a non-empty list")
    sequences = []
    for i, raw in enumerate(raw_sequences):
        prefix = f"test_sequence.sequences[{i}]"
        if not isinstance(raw, Mapping):
            raise ProtocolError(f"{source}: key '{prefix}' must be a mapping")
        _check_keys(raw, {"name", "load_pct", "duration"}, prefix, source)
        name = _text_key(raw, "name", f"{prefix}.name", source)
        if name in (s.name for s in sequences):
            raise ProtocolError(
                f"{source}: key '{prefix}.name' {name!r} names an earlier sequence too (the"
                " log's sequence column tells the steps apart by their names)"
            )
        if "load_pct" not in raw:
            raise ProtocolError(f"{source}: missing required key '{prefix}.load_pct'")
        load = raw["load_pct"]
        if isinstance(load, list):
            if len(load) != 2:
                raise ProtocolError(f"{source}: key '{prefix}.load_pct' ramp needs [from, to]")
            # named as the file writes them (load_pct.a and .b named keys it has not)
            a, b = (
                _get({f"load_pct[{i}]": v}, prefix, f"load_pct[{i}]", source, "load")
                for i, v in enumerate(load)
            )
        else:
            a = b = _get(raw, prefix, "load_pct", source, "load")
        duration = _get(raw, prefix, "duration", source, "duration")
        if duration < period:
            raise ProtocolError(
                f"{source}: key '{prefix}.duration' is {duration:g} s, less than one"
                f" acquisition period ({period:g} s): no row would log it"
            )
        sequences.append(Sequence(name, a, b, duration))
    c1 = _section(data, "cooling_1", source)
    _check_keys(
        c1,
        {"load_pct", "return_setpoint_C", "until_forward_C", "max_duration_s"},
        "cooling_1",
        source,
    )
    cooling_1 = CoolingOne(
        load_pct=_get(c1, "cooling_1", "load_pct", source, "load"),
        return_setpoint_C=_get(c1, "cooling_1", "return_setpoint_C", source),
        until_forward_C=_get(c1, "cooling_1", "until_forward_C", source),
        max_duration_s=_get(c1, "cooling_1", "max_duration_s", source, "duration"),
    )
    c2 = _section(data, "cooling_2", source)
    _check_keys(c2, {"until_after_t2_s"}, "cooling_2", source)
    test_return_C = _get(ts, "test_sequence", "return_setpoint_C", source)
    for key, return_C in (  # (the first cooling's boiler does not fire: a re-probe)
        ("start_up.return_setpoint_C", start_up.return_setpoint_C),
        ("test_sequence.return_setpoint_C", test_return_C),
    ):
        # while the boiler fires the flows are set for a forward of return + spread (a
        # spread of 1000 K gave flows of a few kg/h and a preheat that timed out: a
        # stranger's probe); a return itself outside the emulator's range is told as such
        # when the run starts
        if return_C < WATER_BOILS_C <= return_C + spread:
            raise ProtocolError(
                f"{source}: '{key}' ({return_C:g} C) + 'flow_spread_K' ({spread:g} K) = "
                f"{return_C + spread:g} C: the flows would be set for a forward water at or "
                f"above the {WATER_BOILS_C:g} C at which it boils"
            )
    protocol = ProtocolDefinition(
        name=data["name"],
        test=data["test"],
        acquisition_period_s=period,
        flow_spread_K=spread,
        preheat=preheat,
        start_up=start_up,
        test_return_setpoint_C=test_return_C,
        sequences=tuple(sequences),
        cooling_1=cooling_1,
        cooling_2_until_after_t2_s=_get(c2, "cooling_2", "until_after_t2_s", source, "duration"),
    )
    record = (
        preheat.max_duration_s
        + start_up.max_duration_s
        + protocol.test_duration_s
        + max(cooling_1.max_duration_s, protocol.cooling_2_until_after_t2_s)
    )
    if record > MAX_RECORD_S:
        raise ProtocolError(
            f"{source}: the record may last {record:g} s (the maximum durations, the "
            f"sequences and the cooling), more than a week ({MAX_RECORD_S:g} s)"
        )
    return protocol


def load_protocol(name_or_path: str) -> ProtocolDefinition:
    """Load a shipped protocol by name (``stationary``, ``load_cycle``) or a YAML path."""
    path = resolve_named(name_or_path, DEFINITION_DIR, "protocol", ProtocolError)
    data = read_yaml(path, ProtocolError)
    return protocol_from_mapping(data, source=str(path))
