"""Encoding signal values into Modbus registers and back, as a point of a map says.

Integers are scaled: raw = round((value - offset) / scale), saturated to the type's range;
a measured signal's (an instrument's reading) saturates short of the type's invalid code,
the way instruments clip at their range ends, as only a missing reading (NaN: a dropout)
takes that code, as a float reading's NaN. A counter or an identifier (the lockstep counter,
the plant's ids) uses the type's whole range: 0xFFFF is one of its values. Floats are IEEE 754,
big-endian within each 16-bit word; ``ABCD`` sends the most significant word first, ``CDAB``
the least significant first (word-swapped, as many PLCs and analysers do).

Word-swapping falls out of the byte order: a little-endian value read as little-endian
16-bit words gives the words in reverse order, each with its bytes in big-endian order.
"""

from __future__ import annotations

import hashlib
import math
import struct
import sys
from collections.abc import Callable, Mapping, Sequence
from functools import cache

from rig_emulator.registers.datatypes import DATATYPES
from rig_emulator.registers.schema import Point, RegisterMap
from rig_emulator.signals import MEASURED

_READINGS = frozenset(MEASURED)


def _structs(point: Point) -> tuple[struct.Struct, struct.Struct]:
    """(value struct, words struct) of a point, in its word order."""
    return _structs_of(point.datatype, point.word_order)


@cache  # keyed by two short strings: hashing a whole Point costs more than the packing
def _structs_of(datatype: str, word_order: str) -> tuple[struct.Struct, struct.Struct]:
    code = DATATYPES[datatype].code
    width = struct.calcsize(code) // 2
    order = "<" if word_order == "CDAB" and width > 1 else ">"
    return struct.Struct(order + code), struct.Struct(order + "H" * width)


def _invalid_raw(point: Point) -> int | None:
    """The raw code an integer point keeps for no reading: its type's invalid code
    (:attr:`~rig_emulator.registers.datatypes.DataType.invalid_raw`) on a measured signal;
    None on a float point (NaN), a bit, or a signal that is no reading (a counter, an id)."""
    return DATATYPES[point.datatype].invalid_raw if point.signal in _READINGS else None


def invalid_value(point: Point) -> float | None:
    """The value an integer point of a measured signal carries at its type's invalid code
    (None: a float point, whose invalid reading is NaN, a bit, or no reading)."""
    raw = _invalid_raw(point)
    return None if raw is None else raw * point.scale + point.offset


def reading_range(point: Point) -> tuple[float, float]:
    """The lowest and highest value an integer point serves as a reading, its invalid code
    left out (a float point: any)."""
    datatype = DATATYPES[point.datatype]
    if datatype.is_float or datatype.is_bit:
        return -math.inf, math.inf
    lo, hi = datatype.int_range
    invalid = _invalid_raw(point)
    lo, hi = (lo + 1, hi) if invalid == lo else (lo, hi - 1) if invalid == hi else (lo, hi)
    ends = sorted((lo * point.scale + point.offset, hi * point.scale + point.offset))
    return ends[0], ends[1]


#: the largest finite value of each float type (half, single, double)
_FLOAT_MAX = {
    "e": 65504.0,
    "f": struct.unpack(">f", b"\x7f\x7f\xff\xff")[0],
    "d": sys.float_info.max,
}


def encodable_range(point: Point) -> tuple[float, float]:
    """The lowest and highest value ``point``'s encoding carries: an integer type's whole
    raw range, scaled (a command's: no invalid code), a float type's largest finite value
    either side, a bit's 0 and 1."""
    datatype = DATATYPES[point.datatype]
    if datatype.is_bit:
        return 0.0, 1.0
    if datatype.is_float:
        return -_FLOAT_MAX[datatype.code], _FLOAT_MAX[datatype.code]
    lo, hi = datatype.int_range
    ends = sorted((lo * point.scale + point.offset, hi * point.scale + point.offset))
    return ends[0], ends[1]


def carries_between(point: Point, low: float, high: float) -> bool:
    """Whether a write of ``point`` can carry some value in ``low..high`` (its encoding's
    steps: a uint32 at scale 10 carries no value in 1..5, a re-probe found a lockstep
    advance so mapped served, and every write refused)."""
    lo, hi = accepted_range(point)
    lo, hi = max(lo, low), min(hi, high)
    if lo > hi:
        return False
    datatype = DATATYPES[point.datatype]
    if datatype.is_float:
        return True
    if datatype.is_bit:
        return any(lo <= v <= hi for v in (0.0, 1.0))
    a, b = sorted(((lo - point.offset) / point.scale, (hi - point.offset) / point.scale))
    return math.ceil(a - 1e-9) <= math.floor(b + 1e-9)


def accepted_range(point: Point) -> tuple[float, float]:
    """The values a write of ``point`` can set: its declared ``min..max`` where its encoding
    carries them, narrowed to what the encoding does (a stranger's probe: a flow setpoint
    as uint16 x0.01 carries at most 655.35 kg/h; a run that wanted 687 had it clipped on
    the wire without a word, its log saying 687, and map-doc showed 0..2000). Empty (low
    above high) where the two do not meet."""
    lo, hi = encodable_range(point)
    return max(point.minimum, lo), min(point.maximum, hi)


def _raw(point: Point, value: float) -> int:
    """The raw integer of ``value``: its type's invalid code for no reading (NaN: a
    dropout; it read as 0, a silently wrong reading), else saturated at the type's range
    short of the invalid code, so that a reading beyond the range, however far, clips at
    its end and never reads as a dropout (a -999 spike on an int16 in hundredths did)."""
    datatype = DATATYPES[point.datatype]
    lo, hi = datatype.int_range
    invalid = _invalid_raw(point)
    if math.isnan(value):
        return datatype.invalid_raw if invalid is None else invalid
    if invalid == lo:
        lo += 1
    elif invalid == hi:
        hi -= 1
    scaled = (value - point.offset) / point.scale
    return lo if scaled <= lo else hi if scaled >= hi else round(scaled)


def encode(point: Point, value: float) -> list[int]:
    """Registers (16-bit unsigned ints) that carry ``value`` as ``point`` says."""
    if point.datatype == "bool":
        return [1 if value >= 0.5 else 0]
    values, words = _structs(point)
    raw = value if DATATYPES[point.datatype].is_float else _raw(point, value)
    return list(words.unpack(values.pack(raw)))


_Segment = tuple[struct.Struct | None, struct.Struct | None, tuple[Point | None, ...]]


def _segments(points: Sequence[Point]) -> list[_Segment]:
    """A contiguous run of points cut into segments that one struct packs at once.

    A segment is (value struct, words struct, per point: the point if its value is a scaled
    integer, else None); bools are segments of their own with no structs. Consecutive points
    of one byte order pack as one: a word-swapped (CDAB) value is its little-endian bytes read
    as little-endian words, so several of them concatenate the same way.
    """
    segments: list[_Segment] = []
    order, codes, words, scaled = "", "", 0, []

    def close() -> None:
        if codes:
            segments.append(
                (struct.Struct(order + codes), struct.Struct(order + "H" * words), tuple(scaled))
            )

    for p in points:
        if p.datatype == "bool":
            close()
            order, codes, words, scaled = "", "", 0, []
            segments.append((None, None, (None,)))
            continue
        p_order = "<" if p.word_order == "CDAB" and p.width > 1 else ">"
        if p_order != order:
            close()
            order, codes, words, scaled = p_order, "", 0, []
        codes += DATATYPES[p.datatype].code
        words += p.width
        scaled.append(None if DATATYPES[p.datatype].is_float else p)
    close()
    return segments


def run_encoder(points: Sequence[Point]) -> Callable[[Mapping[str, float]], list[int]]:
    """A function from signal values to the registers of ``points`` (a contiguous run):
    the :func:`encode` of each point, concatenated, a segment at a time."""
    signals = iter([p.signal for p in points])
    plan = [
        (values, words, tuple((next(signals), p) for p in scaled))
        for values, words, scaled in _segments(points)
    ]

    def encode_run(signal_values: Mapping[str, float]) -> list[int]:
        regs: list[int] = []
        for values, words, items in plan:
            if values is None or words is None:
                regs += [1 if signal_values[name] >= 0.5 else 0 for name, _ in items]
            else:
                raw = [
                    signal_values[name] if p is None else _raw(p, signal_values[name])
                    for name, p in items
                ]
                regs += words.unpack(values.pack(*raw))
        return regs

    return encode_run


def run_decoder(points: Sequence[Point]) -> Callable[[Sequence[int]], list[float]]:
    """A function from the registers of ``points`` (a contiguous run, from its first
    address) to their values, in order: :func:`decode` of each, a segment at a time."""
    plan = [
        (values, words, scaled, words.size // 2 if words else len(scaled))
        for values, words, scaled in _segments(points)
    ]

    def decode_run(registers: Sequence[int]) -> list[float]:
        out: list[float] = []
        i = 0
        for values, words, scaled, n in plan:
            chunk = registers[i : i + n]
            i += n
            if values is None or words is None:
                out += [1.0 if r else 0.0 for r in chunk]
            else:
                raw = values.unpack(words.pack(*chunk))
                out += [
                    r if p is None else r * p.scale + p.offset
                    for r, p in zip(raw, scaled, strict=True)
                ]
        return out

    return decode_run


def decode(point: Point, registers: list[int]) -> float:
    """The value carried by ``registers`` (as many as the point is wide)."""
    if point.datatype == "bool":
        return 1.0 if registers[0] else 0.0
    values, words = _structs(point)
    raw = values.unpack(words.pack(*registers[: point.width]))[0]
    if DATATYPES[point.datatype].is_float:
        return raw
    return raw * point.scale + point.offset


def written_value(point: Point, registers: list[int]) -> float:
    """The value a client's write of ``registers`` carries, checked against the point's
    range as written: the float nearest to a bound its type cannot carry exactly is that
    bound (float32 has no 0.01; the 0.0099999998 a client's encoder sends for it is 0.01),
    so the documented ends of a range can be written; anything else is not moved, and the
    range check refuses what lies outside (a float64 just below 0, which the type carries
    exactly, too: a re-probe)."""
    value = decode(point, registers)
    datatype = DATATYPES[point.datatype]
    if datatype.is_float:
        for bound in (point.minimum, point.maximum):
            try:
                carried = struct.unpack(datatype.code, struct.pack(datatype.code, bound))[0]
            except (OverflowError, struct.error):  # beyond the type: no write reaches it
                continue
            if carried != bound and value == carried:  # a bound the type cannot carry
                return bound  # (0 and 1e9 it can: a value just outside those is outside)
    return value


def precision(point: Point, value: float) -> float:
    """Largest difference between ``value`` and its decoded encoding (encoding precision)."""
    if point.datatype == "bool":
        return 0.5
    datatype = DATATYPES[point.datatype]
    if datatype.is_float:
        return abs(value) * datatype.relative_precision + 1e-45
    return abs(point.scale) / 2.0


def map_identity(register_map: RegisterMap) -> int:
    """A 32-bit hash of what a map puts on the wire and what its writes may set: per unit,
    each point's signal, table, address, type, word order, scale and offset, its access
    and, if writable, the values a write can set (:func:`accepted_range`); names, units and
    texts left out. The server publishes it (``map_id``), so a client whose map differs
    stops before it reads a swapped, rescaled or word-swapped value as a reading, or before
    a run whose writes the server refuses (a server whose map narrowed the flow setpoint
    to 0..500 kg/h shared the shipped map's id: every setpoint write of a 6-h run got 03,
    exit 0; a stranger's probe). What changes no byte and no answer changes no id: the
    word order of a one-register point, the range a map declares beyond what its encoding
    carries, an offset of -0."""
    wire = sorted(
        (
            d.unit_id,
            p.table,
            p.address,
            p.signal,
            p.datatype,
            p.word_order if p.width > 1 else "",
            p.scale,
            p.offset + 0.0,
            p.access,
            tuple(x + 0.0 for x in accepted_range(p)) if p.writable else (),
        )
        for d in register_map.devices
        for p in d.points
    )
    digest = hashlib.blake2b(repr(wire).encode(), digest_size=4).digest()
    return int.from_bytes(digest, "big")


def legacy_map_identity(register_map: RegisterMap) -> int:
    """The ``map_id`` servers of earlier releases published for ``register_map``: the
    points on the wire only (signal, table, address, type, word order, scale, offset), not
    the access or ranges of writes. A client accepts a server publishing it for the
    client's own map (a re-probe: a new client refused an earlier server serving the very
    same shipped map, and advised a --map that could not help); such a server's ranges
    are not checked before the run, its refusals stop the run when they come."""
    wire = sorted(
        (d.unit_id, p.table, p.address, p.signal, p.datatype, p.word_order, p.scale, p.offset)
        for d in register_map.devices
        for p in d.points
    )
    digest = hashlib.blake2b(repr(wire).encode(), digest_size=4).digest()
    return int.from_bytes(digest, "big")
