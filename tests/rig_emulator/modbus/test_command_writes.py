"""Writes of command signals over real TCP, with a map of our own that publishes each command
in several points (aliases): a whole-valued command takes whole numbers only, and every
point of a written command reads the new value as soon as the write is answered."""

from __future__ import annotations

import json
import struct
import urllib.request
from pathlib import Path
from typing import Any

import pytest
import yaml

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.registers import RegisterMap, encode, load_map, map_from_mapping
from tests.modbus_helpers import ADVANCE, client, point, read_point, write

ILLEGAL_DATA_VALUE = 3

#: The flow setpoint in three encodings, the boiler's switch in four (a float32 point of a
#: switch can carry 0.5 whatever the map checks say of scales), the clock mode as float32.
ALIAS_MAP: dict[str, Any] = {
    "name": "aliases",
    "devices": [
        {
            "name": "plc",
            "unit_id": 1,
            "instrument": "PLC publishing each command in several encodings",
            "points": [
                {"name": "sp_int", "signal": "water_flow_setpoint_kg_h", "table": "holding",
                 "address": 0, "datatype": "int16", "scale": 0.5, "access": "rw"},
                {"name": "sp_float", "signal": "water_flow_setpoint_kg_h", "table": "holding",
                 "address": 20, "datatype": "float32", "access": "rw"},
                {"name": "sp_cdab", "signal": "water_flow_setpoint_kg_h", "table": "holding",
                 "address": 22, "datatype": "float32", "word_order": "CDAB", "access": "rw"},
                {"name": "cmd_u16", "signal": "boiler_command", "table": "holding",
                 "address": 30, "datatype": "uint16", "access": "rw"},
                {"name": "cmd_float", "signal": "boiler_command", "table": "holding",
                 "address": 31, "datatype": "float32", "access": "rw"},
                {"name": "cmd_coil", "signal": "boiler_command", "table": "coil",
                 "address": 0, "datatype": "bool", "access": "rw"},
                {"name": "burner", "signal": "boiler_on", "table": "input",
                 "address": 0, "datatype": "uint16"},
            ],
        },
        {
            "name": "sim_control",
            "unit_id": 100,
            "instrument": "emulator",
            "points": [
                {"name": "lockstep_advance", "signal": "lockstep_advance_s", "table": "holding",
                 "address": 4, "datatype": "uint32", "access": "rw"},
                {"name": "clock_mode", "signal": "clock_mode", "table": "holding",
                 "address": 10, "datatype": "float32", "access": "rw"},
            ],
        },
    ],
}  # fmt: skip


def _alias_map() -> RegisterMap:
    return map_from_mapping(ALIAS_MAP, source="aliases.yaml")


def _float32(value: float) -> list[int]:
    """The two registers (ABCD) a client's encoder sends for ``value``."""
    return list(struct.unpack(">HH", struct.pack(">f", value)))


def _read(c, srv, name: str) -> float:
    device = "sim_control" if name in ("lockstep_advance", "clock_mode") else "plc"
    return read_point(c, *point(srv, device, name))


def _reads(c, srv, *names: str) -> dict[str, float]:
    return {name: _read(c, srv, name) for name in names}


SETPOINTS = ("sp_int", "sp_float", "sp_cdab")
SWITCHES = ("cmd_u16", "cmd_float", "cmd_coil")


def test_a_fraction_written_to_a_whole_command_is_refused(serve) -> None:
    """A stranger's probe: raw 1 written to ``boiler_command`` published as int16 x0.5 (0.5)
    was accepted; the burner fired on "0.5" while the uint16 point of the same command read
    0 ("off"). A value of a whole-valued command (a switch, a mode, a code) that is not a
    whole number gets 03 and changes nothing, whatever the map allows (here a float32)."""
    srv = serve(register_map=_alias_map())
    c = client(srv.port, timeout_s=60.0)  # the advance's reply comes once done: a loaded CI
    try:
        for fraction in (0.5, 0.999, 1e-6):
            r = c.write_registers(31, _float32(fraction), device_id=1)  # cmd_float
            assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE, fraction
        assert srv.values()["boiler_command"] == 0.0
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 0.0)
        # the clock mode 0.5 (int() of it: real time) is refused the same way
        r = c.write_registers(10, _float32(0.5), device_id=100)
        assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE
        assert _read(c, srv, "clock_mode") == 1.0  # lockstep still
        assert not write(c, srv, *ADVANCE, 600).isError()  # refused in real time
        assert _read(c, srv, "burner") == 0.0  # the burner never fired
        # a whole number in the same encoding is a command like any other
        assert not c.write_registers(31, _float32(1.0), device_id=1).isError()
        assert srv.values()["boiler_command"] == 1.0
    finally:
        c.close()


def test_every_point_of_a_written_command_reads_it_at_once(serve) -> None:
    """A stranger's probe: in lockstep, after ``sp_float`` = 500 (FC16) its alias ``sp_int``
    read the old 0 until the next advance, while the server's own state said 500 for both.
    Each write function, each encoding: the aliases read the new value in the next request
    (and FC23's own read, in the same request)."""
    srv = serve(register_map=_alias_map())
    c = client(srv.port)
    try:
        assert not write(c, srv, "plc", "sp_float", 500.0).isError()  # FC16
        assert _reads(c, srv, *SETPOINTS) == dict.fromkeys(SETPOINTS, 500.0)
        assert not c.write_register(0, 700, device_id=1).isError()  # FC06: sp_int 350
        assert _reads(c, srv, *SETPOINTS) == dict.fromkeys(SETPOINTS, 350.0)
        # FC23 writes sp_cdab and reads sp_float and sp_cdab back in one request
        _, cdab = point(srv, "plc", "sp_cdab")
        r = c.readwrite_registers(
            read_address=20, read_count=4, write_address=22, values=encode(cdab, 125.5),
            device_id=1,
        )  # fmt: skip
        assert not r.isError()
        assert struct.unpack(">f", struct.pack(">HH", *r.registers[:2]))[0] == 125.5
        assert _reads(c, srv, *SETPOINTS) == dict.fromkeys(SETPOINTS, 125.5)
        assert not c.write_coil(0, True, device_id=1).isError()  # FC05
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
        assert not c.write_register(30, 0, device_id=1).isError()  # FC06
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 0.0)
        assert not c.write_coils(0, [True], device_id=1).isError()  # FC15
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
        assert srv.values()["water_flow_setpoint_kg_h"] == 125.5
    finally:
        c.close()


def test_a_write_giving_one_command_two_values_is_refused(serve) -> None:
    """One FC16 over ``cmd_u16`` and ``cmd_float`` (the same switch) saying on and off:
    after it the two points could only disagree, so it gets 03 and changes nothing; the
    same write saying on twice is accepted."""
    srv = serve(register_map=_alias_map())
    c = client(srv.port)
    try:
        r = c.write_registers(30, [1, *_float32(0.0)], device_id=1)
        assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE
        assert srv.values()["boiler_command"] == 0.0
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 0.0)
        assert not c.write_registers(30, [1, *_float32(1.0)], device_id=1).isError()
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
    finally:
        c.close()


def test_aliases_agree_at_once_on_a_real_time_server(tmp_path: Path) -> None:
    """The stranger's alias probe on a real-time ``rig-emulator serve --map`` process: the
    tick publishes every 10 s here (``--tick-hz 0.1``), so an alias that waited for the tick
    read the old value; it reads the written one in the next request. A fraction written to
    the switch gets 03 there too."""
    path = tmp_path / "aliases.yaml"
    path.write_text(yaml.safe_dump(ALIAS_MAP, sort_keys=False))
    register_map = load_map(path)

    class Served:  # what the map helpers need of a server
        map = register_map

    serving = rig_emulator_serve("windhager_12kw", "--map", str(path), "--tick-hz", "0.1")
    with serving as (port, _process):
        c = client(port)
        try:
            assert not write(c, Served, "plc", "sp_float", 500.0).isError()
            assert _reads(c, Served, *SETPOINTS) == dict.fromkeys(SETPOINTS, 500.0)
            assert not c.write_coil(0, True, device_id=1).isError()
            assert _reads(c, Served, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
            r = c.write_registers(31, _float32(0.5), device_id=1)
            assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE
            assert _reads(c, Served, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
        finally:
            c.close()


@pytest.mark.parametrize("value", [0.5, 0.75])
def test_the_dashboard_write_of_a_fraction_to_a_switch_is_refused(serve, value: float) -> None:
    """The dashboard's write (``write_signal``) encodes the value into the first writable
    point: 0.5 on a uint16 switch went out rounded to 0 and was applied as "off"."""
    srv = serve(register_map=_alias_map())
    refused = srv.call(srv.server.write_signal("boiler_command", value))
    assert refused is not None and "whole" in refused and "03" in refused
    assert srv.values()["boiler_command"] == 0.0
    assert srv.call(srv.server.write_signal("boiler_command", 1.0)) is None
    c = client(srv.port)
    try:
        assert _reads(c, srv, *SWITCHES) == dict.fromkeys(SWITCHES, 1.0)
    finally:
        c.close()


def _small_map(name: str, plc: list[dict], sim: tuple[dict, ...] = ()) -> dict[str, Any]:
    """A map of a PLC (unit 1) with ``plc``'s points and the simulation control (unit 100)
    with the lockstep advance at holding 0-1 and ``sim``'s points."""
    advance = {"name": "lockstep_advance", "signal": "lockstep_advance_s", "table": "holding",
               "address": 0, "datatype": "uint32", "access": "rw"}  # fmt: skip
    return {
        "name": name,
        "devices": [
            {"name": "plc", "unit_id": 1, "instrument": "PLC", "points": plc},
            {"name": "sim_control", "unit_id": 100, "instrument": "emulator",
             "points": [advance, *sim]},
        ],
    }  # fmt: skip


def _holding(name: str, signal: str, address: int, datatype: str, **more: Any) -> dict:
    """A writable holding-register point."""
    return {"name": name, "signal": signal, "table": "holding", "address": address,
            "datatype": datatype, "access": "rw", **more}  # fmt: skip


#: The fault block right after the advance, so one FC16 covers both.
FAULT_AFTER_ADVANCE = _small_map(
    "fault_after_advance",
    [{"name": "flow", "signal": "water_flow_kg_h", "table": "input", "address": 0,
      "datatype": "float32"}],
    (
        _holding("fault_kind", "fault_kind", 2, "uint16"),
        _holding("fault_target", "fault_target", 3, "uint16"),
        _holding("fault_parameter", "fault_parameter", 4, "float32"),
        _holding("fault_duration", "fault_duration_s", 6, "float32"),
        _holding("fault_at", "fault_at_s", 8, "float32"),
        _holding("fault_command", "fault_command", 10, "uint16"),
    ),
)  # fmt: skip


def test_a_write_refused_in_real_time_sets_no_fault(serve) -> None:
    """A review: on a real-time server with --allow-control, one write covering an advance
    (refused in real time, 03) and the fault block set its fault first, then answered 03:
    an illegal request changed something. Every refusal now comes before anything is
    applied."""
    srv = serve(
        register_map=map_from_mapping(FAULT_AFTER_ADVANCE, source="fault_after_advance.yaml"),
        lockstep=False,
        speed=1.0,
        allow_control=True,
    )
    c = client(srv.port)
    try:
        words = []
        for name, value in (
            ("lockstep_advance", 60),
            ("fault_kind", 2),  # no_reply
            ("fault_target", 1),
            ("fault_parameter", 0.0),
            ("fault_duration", 5.0),
            ("fault_at", 0.0),
            ("fault_command", 1),
        ):
            words += encode(point(srv, "sim_control", name)[1], value)
        r = c.write_registers(0, words, device_id=100)
        assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE
        assert srv.server.active_faults() == []
        # the block alone is a fault like any other
        assert not c.write_registers(2, words[2:], device_id=100).isError()
        assert len(srv.server.active_faults()) == 1
    finally:
        c.close()


#: The flow setpoint in tenths (uint16) and as a float32 side by side.
TWO_ENCODINGS = _small_map(
    "two_encodings",
    [
        _holding("sp_tenths", "water_flow_setpoint_kg_h", 0, "uint16", scale=0.1),
        _holding("sp_f32", "water_flow_setpoint_kg_h", 1, "float32"),
    ],
)


def test_one_value_in_two_encodings_is_one_value(serve) -> None:
    """A re-probe: one FC16 writing 500.3 kg/h to its uint16 x0.1 point and its float32
    point (500.29998779 as float32) got 03 as "two values", though no client can write
    500.3 more alike; the values agree within the two points' steps and are one, taken
    from the finer point. Two values beyond those steps are still refused."""
    srv = serve(register_map=map_from_mapping(TWO_ENCODINGS, source="two.yaml"))
    c = client(srv.port)
    try:
        assert not c.write_registers(0, [5003, *_float32(500.3)], device_id=1).isError()
        # the float32's value (its step 3e-5 kg/h against the tenths' 0.05)
        assert (
            srv.values()["water_flow_setpoint_kg_h"]
            == struct.unpack(">f", struct.pack(">f", 500.3))[0]
        )
        r = c.write_registers(0, [5003, *_float32(500.5)], device_id=1)
        assert r.isError() and r.exception_code == ILLEGAL_DATA_VALUE
    finally:
        c.close()


def test_the_dashboard_sets_through_the_finest_point_and_says_what_it_set(tmp_path) -> None:
    """A re-probe: the dashboard's control wrote through the first writable point of a
    command, so 501 kg/h through a point of 2-kg/h steps went out as 500, and its answer
    said 501. It now writes through the finest point, and answers with the value the server
    holds."""
    steps_of_2 = _holding("sp_steps_of_2", "water_flow_setpoint_kg_h", 0, "uint16", scale=2)
    coarse = _small_map("coarse", [steps_of_2])
    fine = _small_map(
        "fine", [steps_of_2, _holding("sp_f32", "water_flow_setpoint_kg_h", 10, "float32")]
    )
    for register_map, applied in ((coarse, 500.0), (fine, 501.0)):
        path = tmp_path / f"{register_map['name']}.yaml"
        path.write_text(yaml.safe_dump(register_map, sort_keys=False))
        http = free_port()
        options = ("--lockstep", "--map", str(path), "--http", str(http), "--http-control")
        with rig_emulator_serve("windhager_12kw", *options):
            assert wait_for_port("127.0.0.1", http, 30.0)
            request = urllib.request.Request(
                f"http://127.0.0.1:{http}/api/control",
                data=json.dumps({"signal": "water_flow_setpoint_kg_h", "value": 501}).encode(),
                method="POST",
                headers={"Content-Type": "application/json"},
            )
            with urllib.request.urlopen(request, timeout=10) as reply:
                answer = json.loads(reply.read())
        assert answer == {"ok": True, "signal": "water_flow_setpoint_kg_h", "value": applied}
