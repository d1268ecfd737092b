"""A unit that takes the plant's commands but serves no reading (a pump PLC of its own),
against real ``rig-emulator serve`` processes: a fault's exception 03 on it is transient,
a value its map refuses still stops the run."""

from __future__ import annotations

import json
from pathlib import Path

from hil_client.cli import main
from tests.hil_client.timed_protocol import timed_protocol

BOILER = "windhager_12kw"
SHIPPED_MAP = Path(__file__).resolve().parents[3] / "register_maps" / "wieselburg_bench.yaml"
# the bench PLC's command points, moved to a unit 8 of their own
COMMANDS = """\
      - {name: flow_setpoint, signal: water_flow_setpoint_kg_h, table: holding, address: 0,
         datatype: float32, access: rw}
      - {name: return_setpoint, signal: return_setpoint_C, table: holding, address: 2,
         datatype: float32, access: rw}
      - {name: pump, signal: pump_on, table: coil, address: 0, datatype: bool, access: rw}
      - {name: return_heater, signal: return_heating, table: coil, address: 1, datatype: bool,
         access: rw}
"""
PUMP_PLC = """
  - name: pump_plc
    unit_id: 8
    instrument: pump and return-conditioning PLC (commands only)
    word_order: ABCD
    points:
"""
MAP_ID_POINT = (
    "      - {name: map_id, signal: map_id, table: input, address: 30, datatype: uint32}\n"
)
# phases ended by their time-outs: t0 = 60, t1 = 120, t2 = 240, the first cooling to 600
TIMED = timed_protocol("timed", [("peak", 100, 120)], cooling_1_s=360, cooling_2_after_t2_s=400)


def _split_map(tmp_path: Path, name: str, narrow: bool = False) -> Path:
    """The shipped map with the commands on unit 8; ``narrow``: the flow setpoint taking
    0..500 kg/h only, and no ``map_id`` (the client cannot tell before it writes)."""
    text = SHIPPED_MAP.read_text()
    assert COMMANDS in text and MAP_ID_POINT in text  # (the shipped map as this test knows it)
    commands = COMMANDS
    if narrow:
        commands = commands.replace("access: rw}", "access: rw, min: 0, max: 500}", 1)
        text = text.replace(MAP_ID_POINT, "")
    text = text.replace(COMMANDS, "")
    anchor = "\n  - name: flue_gas_analyser\n"
    text = text.replace(anchor, PUMP_PLC + commands + anchor)
    path = tmp_path / name
    path.write_text(text)
    return path


def _run(port: int, out: Path, protocol: Path, register_map: Path) -> int:
    rig = f"modbus://127.0.0.1:{port}"
    return main(["run", str(protocol), "--boiler", BOILER, "--quiet", "--rig", rig,
                 "--map", str(register_map), "--out", str(out)])  # fmt: skip


def _meta(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + ".meta.json").read_text())


def test_an_exception_fault_on_a_unit_without_readings_is_transient(
    serve_process, tmp_path, capsys
):
    """A stranger's probe: a map with the command points on unit 8, which serves no
    reading, and a 5-s ``exception`` fault with code 3 on unit 8: the run stopped, exit 1,
    "unit 8 refused the write ... while it answered its reads", though unit 8 was never
    read. Its written point is read back every step: the fault's 03 comes on that read
    too, the writes are sent again, and the run completes with the warning."""
    split = _split_map(tmp_path, "split.yaml")
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 8, code: 3, at_s: 100, for_s: 5}\n")
    protocol = tmp_path / "timed.yaml"
    protocol.write_text(TIMED)
    srv = serve_process("--lockstep", "--map", str(split), "--faults", str(faults))
    out = tmp_path / "fault.csv"
    assert _run(srv.port, out, protocol, split) == 0
    err = capsys.readouterr().err
    assert "refused" not in err and "writes failed (exception 03" in err, err
    meta = _meta(out)
    assert meta["complete"] is True
    events = [json.loads(line) for line in (tmp_path / "fault.modbus_events.jsonl").open()]
    # the read-back of unit 8 (its switches, in lockstep) answered the fault's 03 too,
    # within the fault (lockstep: the log's time is the server's)
    reads = [e for e in events if e["unit"] == 8 and e["function"] in (1, 3)]
    assert reads and all(100 <= e["server_time_s"] <= 105 for e in reads), reads


def test_a_unit_without_readings_that_refuses_a_value_still_stops_the_run(
    serve_process, tmp_path, capsys
):
    """The other side: unit 8 of a server whose map narrowed the flow setpoint to
    0..500 kg/h refuses the preheat's flow with 03 while it answers the read-back: the
    value is refused for the whole run, and the run stops on the first refusal, exit 1."""
    split = _split_map(tmp_path, "split.yaml")
    narrow = _split_map(tmp_path, "narrow.yaml", narrow=True)
    protocol = tmp_path / "timed.yaml"
    protocol.write_text(TIMED)
    srv = serve_process("--lockstep", "--map", str(narrow))
    out = tmp_path / "narrow.csv"
    assert _run(srv.port, out, protocol, split) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "unit 8 refused" in err and "exception 03" in err, err
    assert _meta(out)["complete"] is False
