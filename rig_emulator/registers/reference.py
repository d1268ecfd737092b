"""The Markdown reference of a register map, generated from its YAML (docs/register_map.md)."""

from __future__ import annotations

import re

from rig_emulator.registers.codec import accepted_range
from rig_emulator.registers.schema import BIT_TABLES, Point, RegisterMap

_FUNCTION = {
    "input": "FC4 read input registers",
    "holding": "FC3 read, FC6/FC16 write holding registers",
    "coil": "FC1 read, FC5/FC15 write coils",
    "discrete": "FC2 read discrete inputs",
}
_PLC_BASE = {"coil": 1, "discrete": 10001, "input": 30001, "holding": 40001}
_PLC_BASE_6 = {"coil": 1, "discrete": 100001, "input": 300001, "holding": 400001}
_PLC_5_MAX = 9998  # the last address whose 5-digit number stays in its table's 10000
_BREAK = re.compile(r"\s*[\r\n]+\s*")


def _number(x: float) -> str:
    """``x`` short (``1e+09``), with the digits it needs (42949672.95, not 4.29497e+07)."""
    if abs(x) == float("inf"):
        return ""
    short = f"{x:g}"
    return short if float(short) == x else f"{x:.12g}"


def _code(text: str) -> str:
    """A name as inline code on one line (a backtick in it ended a single-backtick span: a
    re-probe)."""
    text = _BREAK.sub(" ", text)
    return f"`` {text} ``" if "`" in text else f"`{text}`"


def _cell(text: str) -> str:
    """Free text as one table cell: a line break would end the row and a ``|`` open a
    column (a stranger's probe: a two-line description with a pipe broke the table)."""
    return _BREAK.sub(" ", text).strip().replace("|", "\\|")


def plc_number(table: str, address: int) -> str:
    """The PLC-style number of a 0-based address: the 5-digit form (40001 + address) while
    it stays unambiguous, up to address 9998, the 6-digit one (400001 + address) beyond (a
    stranger's probe: holding 9999 was printed 50000, discrete 20000 as 30001, an input
    register's number of another table)."""
    if address <= _PLC_5_MAX:
        return str(_PLC_BASE[table] + address)
    return f"{_PLC_BASE_6[table] + address:06d}"


def _range(point: Point) -> str:
    """What a write of ``point`` can set: its declared range as far as its encoding carries
    it (:func:`~rig_emulator.registers.codec.accepted_range`; a lockstep advance of
    1..86400 s as a uint16 takes 1..65535 only)."""
    lo, hi = accepted_range(point)
    if lo > hi:
        return "none"
    return _number(lo) if lo == hi else f"{_number(lo)}..{_number(hi)}"


def markdown(register_map: RegisterMap) -> str:
    """Reference tables, one per device, with everything a lab needs to configure a client."""
    lines = [
        f"# Register map {_code(register_map.name)}",
        "",
        "Generated from the YAML map by `rig-emulator map-doc`; do not edit by hand.",
        "",
        register_map.description,
        "",
        "Conventions:",
        "",
        "- Addresses are 0-based protocol addresses (the PLC-style number is given too).",
        *(
            [
                "  PLC numbers are 5-digit up to address 9998 (40001 + address), 6-digit",
                "  beyond (400001 + address).",
            ]
            if any(p.address > _PLC_5_MAX for d in register_map.devices for p in d.points)
            else []
        ),
        "- Registers are 16-bit big-endian. 32/64-bit values span consecutive registers:",
        "  `ABCD` sends the most significant word first, `CDAB` the least significant first.",
        "- Integer points are scaled: value = raw x scale + offset.",
        "- Writes: only `rw` points accept them. A write outside `min..max`, of NaN or",
        "  infinity, or covering only part of a multi-register value is refused with exception",
        "  03 (illegal data value) and changes nothing; a write to a read-only point or to an",
        "  unmapped address gets exception 02 (illegal data address).",
        "- An unknown unit ID is answered with exception 0B (gateway target device failed to",
        "  respond) at once, never left to time out.",
        "- `lockstep_advance` (simulation control): in lockstep mode, writing N advances the",
        "  simulation by N seconds; the write's reply is sent once the new state is readable,",
        "  and `lockstep_counter` counts completed advances.",
        "- The clock commands (`speed_factor`, `clock_mode`, `reset`, `lockstep_advance`) of a",
        "  real-time server are refused with exception 01 unless it runs with",
        "  `serve --allow-control`; a server started with `--lockstep` accepts them, also once",
        "  a client switched it to real time (where an advance gets exception 03: time moves",
        "  by itself). A long advance runs in slices, so other clients",
        "  are answered meanwhile; writes of other clients wait for it to end, so they land",
        "  between advances, never inside one. A real-time tick that cannot keep up drops the",
        "  rest (see `achieved_speed` and `tick_overrun`) instead of chasing it.",
        "",
    ]
    for device in register_map.devices:
        lines += [
            f"## Unit {device.unit_id}: {_code(device.name)}",
            "",
            _BREAK.sub(" ", device.instrument).strip(),  # (its lines made a table: a probe)
            "",
        ]
        for table in ("input", "holding", "discrete", "coil"):
            points = device.table(table)
            if not points:
                continue
            lines += [
                f"### {table} ({_FUNCTION[table]})",
                "",
                "| address | PLC no. | name | type | words | scale | offset | unit | access "
                "| range | signal | description |",
                "|---:|---:|---|---|---|---:|---:|---|---|---|---|---|",
            ]
            for p in points:
                words = "" if table in BIT_TABLES or p.width == 1 else p.word_order
                span = f"{p.address}" if p.width == 1 else f"{p.address}-{p.address + p.width - 1}"
                scale = (
                    ""
                    if p.datatype.startswith("float") or p.datatype == "bool"
                    else _number(p.scale)
                )
                offset = "" if not scale else _number(p.offset)
                rng = _range(p) if p.writable else ""
                lines.append(
                    f"| {span} | {plc_number(table, p.address)} | {_cell(p.name)} | "
                    f"{p.datatype} | {words} | {scale} | {offset} | {_cell(p.unit)} | "
                    f"{p.access} | {rng} | `{p.signal}` | {_cell(p.description)} |"
                )
            lines.append("")
    return "\n".join(lines).rstrip() + "\n"
