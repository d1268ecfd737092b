"""``hil-client fault-report`` on the log of another acquisition program: a loop written
with pyModbusTCP (not the project's client) polls a lockstep server with faults and writes
its own CSV, with no Modbus events file; the report compares the log alone."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from pyModbusTCP.client import ModbusClient

from hil_client.cli import main as hil_client_main
from hil_client.fault_files import unit_signals
from rig_emulator.faults import faults_from_list
from rig_emulator.registers import decode, encode, load_map

STEPS = 100


def _acquire(port: int, out, failed: str) -> None:
    """A foreign acquisition: each second advance the lockstep clock, read every reading of
    the bench's instrument units, write a row; a failed read gives an empty field
    (``failed="empty"``) or repeats the last value (``"hold"``, a common bug)."""
    register_map = load_map()
    sim = register_map.device("sim_control")
    advance = next(p for p in sim.points if p.name == "lockstep_advance")
    units = unit_signals(register_map)
    points = [
        (d.unit_id, p)
        for d in register_map.devices
        if d.unit_id in units
        for p in d.points
        if p.signal in units[d.unit_id]
    ]
    names = list(dict.fromkeys(p.signal for _, p in points))
    last: dict[str, str] = dict.fromkeys(names, "")
    mb = ModbusClient(host="127.0.0.1", port=port, timeout=0.3, auto_open=True)
    lines = [",".join(["time_s", *names])]
    for step in range(1, STEPS + 1):
        mb.unit_id = sim.unit_id
        assert mb.write_multiple_registers(advance.address, encode(advance, 1.0)), (
            mb.last_error_as_txt
        )
        row = dict.fromkeys(names, "")
        for unit, p in points:
            mb.unit_id = unit
            read = mb.read_input_registers if p.table == "input" else mb.read_holding_registers
            regs = read(p.address, p.width)
            value = decode(p, regs) if regs is not None else math.nan
            text = "" if math.isnan(value) else f"{value:.5f}"
            row[p.signal] = text if text or failed == "empty" else last[p.signal]
        last.update(row)
        lines.append(",".join([f"{step:.3f}", *(row[n] for n in names)]))
    mb.close()
    out.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("failed", ["empty", "hold"])
def test_a_log_of_another_acquisition_program_is_compared_alone(serve, tmp_path, failed, capsys):
    """A probe: a lab testing its own acquisition software got "no Modbus events file
    beside it ... nothing to compare with the journal", exit 2. The log is now compared
    alone: a silent or refusing unit is detected where its readings are empty, missed
    where the program held the last value; a delay leaves no mark (unjudged)."""
    units = unit_signals(load_map())
    balance = next(u for u, s in units.items() if "balance_mass_kg" in s)
    flue = next(u for u, s in units.items() if "flue_gas_temp_C" in s)
    faults = [
        {"kind": "no_reply", "unit": balance, "at_s": 20, "for_s": 10},
        {"kind": "exception", "unit": flue, "code": 6, "at_s": 40, "for_s": 5},
        {"kind": "delay", "unit": flue, "delay_ms": 50, "at_s": 60, "for_s": 5},
        {"kind": "spike", "signal": "water_out_temp_C", "value": 300.0, "at_s": 80},
    ]
    journal = tmp_path / "journal.jsonl"
    srv = serve(faults=faults_from_list(faults), fault_log=journal, profile="lab", seed=1)
    log = tmp_path / "theirs.csv"
    _acquire(srv.port, log, failed)
    report = tmp_path / "report.json"
    code = hil_client_main(
        ["fault-report", str(log), "--journal", str(journal), "--out", str(report)]
    )
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "no Modbus events file beside it" in err and "compared alone" not in out
    rep = json.loads(report.read_text())
    rows = {f["kind"]: f for f in rep["faults"]}
    assert set(rows) == {"no_reply", "exception", "spike"}
    assert [f["kind"] for f in rep["unjudged"]] == ["delay"]
    assert rep["false"] is None and "false not counted" in out
    assert rows["spike"]["detected"]  # in the readings either way
    for kind in ("no_reply", "exception"):
        assert rows[kind]["detected"] is (failed == "empty"), rows[kind]
    if failed == "empty":
        assert rows["no_reply"]["how"] == "log: empty readings"
        assert 20.0 <= rows["no_reply"]["first_seen_s"] <= 21.0  # the first step inside


def test_a_log_alone_reads_error_codes_as_missing_and_judges_only_what_it_holds():
    """Re-probes of the log-only comparison: a program that logs -999 for a silent unit
    had that silence missed; a column empty throughout counted as the silence found; a
    spike on a reading the log does not hold was counted missed (it is unjudged)."""
    from hil_client.analysis.fault_report import compare

    n = 200
    t = np.arange(float(n))
    o2 = np.full(n, 6.2)
    o2[100:110] = -999.0  # the analyser's silence, as this program logs it
    columns = {"flue_gas_O2_pct": o2, "flue_gas_CO2_pct": np.full(n, np.nan)}
    journal = [
        {"event": "start", "id": 1, "t_sim_s": 100.0, "t_wall": 0.0, "kind": "no_reply", "unit": 2},
        {"event": "end", "id": 1, "t_sim_s": 110.0, "t_wall": 0.0, "kind": "no_reply", "unit": 2},
        {"event": "start", "id": 2, "t_sim_s": 150.0, "t_wall": 0.0, "kind": "dropout",
         "signal": "flue_gas_CO2_pct"},
        {"event": "end", "id": 2, "t_sim_s": 155.0, "t_wall": 0.0, "kind": "dropout",
         "signal": "flue_gas_CO2_pct"},
        {"event": "start", "id": 3, "t_sim_s": 170.0, "t_wall": 0.0, "kind": "spike",
         "signal": "chimney_draught_Pa", "value": 99.0},
    ]  # fmt: skip
    units = {2: ["flue_gas_O2_pct", "flue_gas_CO2_pct"]}
    report = compare(journal, None, columns, t, unit_signals=units)
    rows = {f["kind"]: f for f in report["faults"]}
    assert rows["no_reply"]["detected"] and rows["no_reply"]["first_seen_s"] == 100.0
    assert {f["kind"] for f in report["unjudged"]} == {"dropout", "spike"}, report["unjudged"]


def test_a_fault_on_a_reading_the_log_lacks_is_unjudged_beside_its_events():
    """A stranger's probe: a journal whose fault names a signal no column of the log holds
    (a journal edited by hand, 'flue_gas_tmp_C') had that fault counted missed when the
    client's events were beside the log. It is unjudged, and a fault on a column the log
    holds is still judged."""
    from hil_client.analysis.fault_report import compare

    n = 100
    t = np.arange(float(n))
    flue = 120.0 + np.random.default_rng(0).normal(0.0, 0.5, n)
    flue[50] = 400.0  # one reading, as a spike is
    columns = {"flue_gas_temp_C": flue}
    journal = [
        {"event": "start", "id": 1, "t_sim_s": 50.0, "t_wall": 0.0, "kind": "spike",
         "signal": "flue_gas_temp_C", "value": 400.0},
        {"event": "end", "id": 1, "t_sim_s": 50.5, "t_wall": 0.0, "kind": "spike",
         "signal": "flue_gas_temp_C"},
        {"event": "start", "id": 2, "t_sim_s": 70.0, "t_wall": 0.0, "kind": "spike",
         "signal": "flue_gas_tmp_C", "value": 400.0},
        {"event": "start", "id": 3, "t_sim_s": 80.0, "t_wall": 0.0, "kind": "dropout",
         "signal": "flue_gas_tmp_C"},
    ]  # fmt: skip
    report = compare(journal, [], columns, t)
    assert [f["id"] for f in report["faults"]] == [1] and report["faults"][0]["detected"]
    assert sorted(f["id"] for f in report["unjudged"]) == [2, 3]
    assert report["missed"] == 0


def test_a_log_of_the_faulted_readings_alone_is_compared(serve, tmp_path, capsys):
    """A stranger's probe: a lab's program logging time_s and the analyser's O2 alone was
    refused ("missing required column 'water_flow_kg_h'"): a fault report needs the time
    and the readings of the faults, not the analyses' columns."""
    units = unit_signals(load_map())
    analyser = next(u for u, s in units.items() if "flue_gas_O2_pct" in s)
    journal = tmp_path / "journal.jsonl"
    faults = [{"kind": "no_reply", "unit": analyser, "at_s": 20, "for_s": 10}]
    srv = serve(faults=faults_from_list(faults), fault_log=journal)
    _, o2 = srv.map.point("flue_gas_O2_pct")
    sim = srv.map.device("sim_control")
    advance = next(p for p in sim.points if p.name == "lockstep_advance")
    mb = ModbusClient(host="127.0.0.1", port=srv.port, timeout=0.3, auto_open=True)
    lines = ["time_s,flue_gas_O2_pct"]
    for step in range(1, 41):
        mb.unit_id = sim.unit_id
        assert mb.write_multiple_registers(advance.address, encode(advance, 1.0))
        mb.unit_id = analyser
        regs = mb.read_input_registers(o2.address, o2.width)
        lines.append(f"{step},{'' if regs is None else f'{decode(o2, regs):.3f}'}")
    mb.close()
    log = tmp_path / "o2.csv"
    log.write_text("\n".join(lines) + "\n")
    report = tmp_path / "report.json"
    code = hil_client_main(
        ["fault-report", str(log), "--journal", str(journal), "--out", str(report)]
    )
    assert code == 0, capsys.readouterr().err
    rows = json.loads(report.read_text())["faults"]
    assert [(r["kind"], r["detected"]) for r in rows] == [("no_reply", True)], rows
    # a log of time_s alone: nothing in it can show the fault (a re-probe: "1 unjudged
    # ... (none in the run)", exit 0), refused in one line; nothing written
    capsys.readouterr()
    bare = tmp_path / "bare.csv"
    bare.write_text("time_s\n" + "\n".join(str(i) for i in range(1, 41)) + "\n")
    out = tmp_path / "bare.json"
    assert (
        hil_client_main(["fault-report", str(bare), "--journal", str(journal), "--out", str(out)])
        == 2
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no column of a reading the journal's faults concern" in err
    assert "flue_gas_O2_pct" in err and not out.exists()
