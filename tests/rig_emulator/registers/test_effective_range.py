"""A point's effective range (what its encoding carries) and map-doc's cells (a stranger's
probe of maps of their own: clipped setpoints, PLC numbers of another table, broken rows)."""

from __future__ import annotations

from typing import Any

from rig_emulator.registers import map_from_mapping
from rig_emulator.registers.codec import accepted_range, encodable_range
from rig_emulator.registers.reference import markdown, plc_number


def _map(*points: dict[str, Any]):
    return map_from_mapping(
        {"name": "t", "devices": [{"name": "plc", "unit_id": 1, "points": list(points)}]}
    )


def _point(**raw: Any):
    return _map({"name": "p", **raw}).devices[0].points[0]


FLOW_U16 = {
    "name": "flow_setpoint",
    "signal": "water_flow_setpoint_kg_h",
    "table": "holding",
    "address": 0,
    "datatype": "uint16",
    "scale": 0.01,
    "access": "rw",
}


def test_accepted_range_is_the_declared_one_narrowed_to_the_encoding() -> None:
    flow = _point(**{k: v for k, v in FLOW_U16.items() if k != "name"})
    assert encodable_range(flow) == (0.0, 65535 * 0.01)
    assert accepted_range(flow) == (0.0, 655.35)  # not the signal's 0..2000
    as_float = _point(
        signal="water_flow_setpoint_kg_h", table="holding", address=0, datatype="float32"
    )
    assert accepted_range(as_float) == (0.0, 2000.0)
    offset = _point(
        signal="return_setpoint_C",
        table="holding",
        address=0,
        datatype="int16",
        scale=-0.001,
        offset=40.0,
        access="rw",
    )
    lo, hi = encodable_range(offset)  # a negative scale: the ends swap
    assert (lo, hi) == (32767 * -0.001 + 40.0, -32768 * -0.001 + 40.0)
    short = _point(
        signal="lockstep_advance_s", table="holding", address=0, datatype="uint16", access="rw"
    )
    assert accepted_range(short) == (1.0, 65535.0)  # 1..86400 s declared, a uint16 to 65535


def _rows(doc: str) -> list[list[str]]:
    return [
        [c.strip() for c in line.strip("|").split(" | ")]
        for line in doc.splitlines()
        if line.startswith("| ") and not line.startswith("| address")
    ]


def test_map_doc_shows_the_effective_range() -> None:
    doc = markdown(
        _map(
            FLOW_U16,
            {
                "name": "advance",
                "signal": "lockstep_advance_s",
                "table": "holding",
                "address": 1,
                "datatype": "uint16",
                "access": "rw",
            },
            {
                "name": "energy_limit",
                "signal": "fault_duration_s",
                "table": "holding",
                "address": 2,
                "datatype": "uint32",
                "scale": 0.01,
                "access": "rw",
            },
        )
    )
    ranges = {row[2]: row[9] for row in _rows(doc)}
    assert ranges["flow_setpoint"] == "0..655.35"
    assert ranges["advance"] == "1..65535"
    assert ranges["energy_limit"] == "0..42949672.95"  # every digit, not 4.29497e+07


def test_plc_numbers_stay_in_their_table() -> None:
    assert plc_number("holding", 0) == "40001"
    assert plc_number("holding", 9998) == "49999"
    assert plc_number("holding", 9999) == "410000"  # 5 digits: 50000, no table's
    assert plc_number("discrete", 20000) == "120001"  # 5 digits: 30001, an input's
    assert plc_number("input", 65534) == "365535"
    assert plc_number("coil", 9998) == "9999"
    assert plc_number("coil", 9999) == "010000"  # 5 digits: 10000, a discrete input's
    doc = markdown(
        _map(
            {"name": "a", "signal": "room_temp_C", "table": "holding", "address": 9998,
             "datatype": "int16"},
            {"name": "d", "signal": "water_in_temp_C", "table": "input", "address": 9999,
             "datatype": "int16"},
        )
    )  # fmt: skip
    assert [row[1] for row in _rows(doc)] == ["310000", "49999"]
    assert "6-digit" in doc  # the convention said where it applies
    assert "6-digit" not in markdown(_map({**FLOW_U16, "address": 9998}))


def test_map_doc_cells_hold_line_breaks_and_pipes() -> None:
    doc = markdown(
        _map(
            {
                "name": "a|b",
                "signal": "room_temp_C",
                "table": "input",
                "address": 0,
                "datatype": "float32",
                "description": "line one\nline two | with pipe\n",
            }
        )
    )
    (line,) = [x for x in doc.splitlines() if x.startswith("| 0-1 ")]
    assert line == (
        "| 0-1 | 30001 | a\\|b | float32 | ABCD |  |  | C | r |  | `room_temp_C` "
        "| line one line two \\| with pipe |"
    )


def test_names_with_backticks_and_instrument_text_with_lines_stay_in_their_place():
    """A re-probe: a backtick in a device name broke its heading's code span, and an
    instrument text of several lines starting with '|' made a table in the reference."""
    from dataclasses import replace

    from rig_emulator.registers import load_map
    from rig_emulator.registers.reference import markdown

    shipped = load_map()
    odd = replace(shipped.devices[0], name="dev`x", instrument="a\n| a | b |\n|---|---|")
    text = markdown(replace(shipped, devices=(odd, *shipped.devices[1:])))
    assert "## Unit 1: `` dev`x ``" in text
    assert "\n| a | b |" not in text and "a | a | b | |---|---|" in text
