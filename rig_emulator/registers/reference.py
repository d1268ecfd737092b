"""The Markdown reference of a register map, generated from its YAML (docs/register_map.md)."""

from __future__ import annotations

from rig_emulator.registers.schema import BIT_TABLES, RegisterMap

_FUNCTION = {
    "input": "FC4 read input registers",
    "holding": "FC3 read, FC6/FC16 write holding registers",
    "coil": "FC1 read, FC5/FC15 write coils",
    "discrete": "FC2 read discrete inputs",
}
_PLC_BASE = {"coil": 1, "discrete": 10001, "input": 30001, "holding": 40001}


def _number(x: float) -> str:
    return f"{x:g}" if abs(x) != float("inf") else ""


def markdown(register_map: RegisterMap) -> str:
    """Reference tables, one per device, with everything a lab needs to configure a client."""
    lines = [
        f"# Register map `{register_map.name}`",
        "",
        "Generated from the YAML map by `rig-emulator map-doc`; do not edit by hand.",
        "",
        register_map.description,
        "",
        "Conventions:",
        "",
        "- Addresses are 0-based protocol addresses (the PLC-style number is given too).",
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
        lines += [f"## Unit {device.unit_id}: `{device.name}`", "", device.instrument, ""]
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
                rng = f"{_number(p.minimum)}..{_number(p.maximum)}" if p.writable else ""
                lines.append(
                    f"| {span} | {_PLC_BASE[table] + p.address} | {p.name} | {p.datatype} | "
                    f"{words} | {scale} | {offset} | {p.unit} | {p.access} | {rng} | "
                    f"`{p.signal}` | {p.description} |"
                )
            lines.append("")
    return "\n".join(lines).rstrip() + "\n"
