"""``hil-client run`` against a bench device of someone else's making
(:mod:`tests.hil_client.rigs.foreign_device`): what the Modbus specification leaves to a
device (fewer registers a read, no FC15, a float at its type's largest value, a gateway's
transient exception) is no reason for a run that looks clean and is not, or for one that
stops."""

from __future__ import annotations

import json
import math
import struct
import time
from pathlib import Path

import numpy as np

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from hil_client.modbus_client import IN_ORDER_EVIDENCE
from hil_client.protocol.rig import RigCommand
from hil_client.rigs.modbus import ModbusRig
from rig_emulator.registers import load_map
from tests.hil_client.rigs.foreign_device import ForeignDevice, Quirks
from tests.hil_client.timed_protocol import timed_protocol

# phases ended by their time-outs: t0 = 20, t1 = 40, t2 = 70, t3 = 90, t4 = 110 (1-s rows)
PROTOCOL = timed_protocol(
    "foreign", [("peak", 100, 30)], cooling_1_s=20, cooling_2_after_t2_s=40, preheat_s=20,
    start_up_s=(10, 10, 20),
)  # fmt: skip
FLT_MAX = struct.unpack(">f", b"\x7f\x7f\xff\xff")[0]  # the largest finite float32
UNIT_1_READINGS = ("water_flow_kg_h", "water_out_temp_C", "boiler_water_temp_C")


def _run(device: ForeignDevice, tmp_path: Path, *extra: str) -> int:
    protocol = tmp_path / "foreign.yaml"
    protocol.write_text(PROTOCOL)
    rig = f"modbus://127.0.0.1:{device.port}"
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", "--rig", rig]
    return main([*argv, "--out", str(tmp_path / "log.csv"), *extra])


def _events(tmp_path: Path) -> list[dict]:
    lines = (tmp_path / "log.modbus_events.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines]


def _rig_steps(device: ForeignDevice, steps: int, boiler_on: bool = False) -> ModbusRig:
    """The Modbus rig on ``device``, ``steps`` lockstep steps of 1 s taken."""
    rig = ModbusRig(f"modbus://127.0.0.1:{device.port}", load_map(), timeout_s=1.0)
    for _ in range(steps):
        rig.apply(RigCommand(500.0, 40.0, pump_on=True, boiler_on=boiler_on))
        rig.advance(1.0)
    return rig


def test_a_unit_that_takes_fewer_registers_a_read_is_read_in_pieces(tmp_path, capsys):
    """A stranger's probe: a device that takes 8 registers a read (the spec lets it take
    fewer than 125) answered the bench PLC's 14 and the analyser's 11 with 03 (or 02); the
    run completed, exit 0, with no flow, forward, boiler-water, O2 or CO2 in any row. The
    blocks are read in halves, learned once: every reading is there."""
    for code in (3, 2):
        with ForeignDevice(Quirks(max_registers=8, max_registers_code=code)) as device:
            assert _run(device, tmp_path) == 0, capsys.readouterr().err
            refused = [r for r in device.requests if r[4] is not None]
        log = read_log(tmp_path / "log.csv")
        for signal in (*UNIT_1_READINGS, "flue_gas_O2_pct", "flue_gas_CO2_pct"):
            assert np.all(np.isfinite(log[signal])), signal
        # each block refused once (units 1 and 2), never again: learned, not asked each row
        assert sorted((unit, quantity) for unit, _, _, quantity, _ in refused) == [
            (1, 14),
            (2, 11),
        ]
        assert all(r[3] <= 8 for r in device.requests[-20:] if r[0] in (1, 2))
        seen = [e for e in _events(tmp_path) if e["event"] == "exception"]
        assert {(e["unit"], e["code"]) for e in seen} == {(1, code), (2, code)}


def test_a_unit_refusing_its_reads_even_in_pieces_is_named(tmp_path):
    """A stranger's probe: every read of a unit refused for the whole run left it looking
    clean. Its fields are empty, the rig says so once as it happens (naming the unit and
    its fields) and again at the end (the readings it never gave); the pieces are asked
    once, then the block alone each row."""
    with ForeignDevice(Quirks(refuse_units=frozenset({2}), refuse_code=2)) as device:
        rig = _rig_steps(device, 5)
        rig.close()
        asked = [r for r in device.requests if r[0] == 2 and r[1] == 4]
    o2 = "flue_gas_O2_pct, flue_gas_CO2_pct, flue_gas_CO_ppm, flue_gas_NOx_ppm"
    assert len(rig.notes) == 1, rig.notes
    assert rig.notes[0].startswith(f"unit 2 refused the read of {o2}"), rig.notes
    assert "in pieces down to one point at a time too" in rig.notes[0]
    assert rig.end_notes() == [  # the log's columns (analyser_status is none)
        f"unit 2 refused every read of this run (exception 02): {o2}, flue_gas_SO2_ppm "
        "never read, empty in every row"
    ]
    assert math.isnan(rig.read()["flue_gas_O2_pct"])
    # the block, then its halves and theirs down to single points (11 registers: 2 + 2 +
    # 2 + 2 + 2 reads) once, then the block alone in each of the other 4 rows
    assert len(asked) == 1 + 10 + 4, asked


def test_a_run_tells_a_refusing_unit_as_it_happens_and_at_its_end(tmp_path, capsys):
    """Through ``hil-client run``: the unit refusing even its pieces is a warning when it
    happens and again at the end (the readings it never gave), both in the meta's notes;
    the run completes, its other readings there."""
    with ForeignDevice(Quirks(refuse_units=frozenset({2}), refuse_code=2)) as device:
        assert _run(device, tmp_path) == 0
    err = capsys.readouterr().err.splitlines()
    during = [line for line in err if "in pieces down to one point at a time too" in line]
    ended = [line for line in err if "unit 2 refused every read of this run" in line]
    assert len(during) == 1 and len(ended) == 1, err
    assert err.index(during[0]) < err.index(ended[0])
    notes = json.loads((tmp_path / "log.meta.json").read_text())["notes"]
    assert any("in pieces down to one point" in n for n in notes), notes
    assert any("unit 2 refused every read of this run" in n for n in notes), notes
    log = read_log(tmp_path / "log.csv")
    assert np.all(np.isnan(log["flue_gas_O2_pct"]))
    assert np.all(np.isfinite(log["water_flow_kg_h"]))


def test_coils_go_as_fc5_to_a_device_without_fc15(tmp_path, capsys):
    """A stranger's probe: a device answering FC15 with 01 (illegal function), FC5 being
    there, never got the burner or the pump switched on; the run completed, exit 0, with a
    warning of 660 failed writes. The coils go as FC5 once FC15 is refused, learned per
    unit; a device that refuses both stops the run in one line, as a 03 to a plant command
    does."""
    with ForeignDevice(Quirks(no_fc15=True)) as device:
        assert _run(device, tmp_path) == 0
        fc15 = [r for r in device.requests if r[1] == 15]
        fc5 = [r for r in device.requests if r[1] == 5]
    err = capsys.readouterr().err
    assert "writes failed" not in err, err
    log = read_log(tmp_path / "log.csv")
    assert np.all(log["boiler_on"][(log["time_s"] > 22) & (log["time_s"] <= 70)] == 1.0)
    assert np.all(np.isfinite(log["water_flow_kg_h"])) and np.nanmax(log["water_flow_kg_h"]) > 0
    assert [(unit, code) for unit, _, _, _, code in fc15] == [(1, 1), (1, 1), (7, 1)]
    assert {(unit, address) for unit, _, address, _, _ in fc5} == {(1, 0), (1, 1), (7, 0)}
    (tmp_path / "both").mkdir()
    with ForeignDevice(Quirks(no_fc5=True)) as device:
        assert _run(device, tmp_path / "both") == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert (
        "unit 1 refused the write of pump_on = 1 with exception 01 (illegal function) both as "
        "FC15 (write multiple coils) and as FC5 (write single coil) while it answered its "
        "reads: the device cannot be switched by Modbus, so the test method cannot be "
        "carried out; stopped after time_s = 1 s"
    ) in err[0]


def _at_limits(signal: str, high: float) -> object:
    """A device's value of ``signal``: ``high`` from 30.5 s to 33.5 s, ``-high`` from 50.5 s
    to 52.5 s (3 and 2 rows)."""

    def served(name: str, time_s: float) -> float | None:
        if name != signal:
            return None
        return high if 30 < time_s < 34 else -high if 50 < time_s < 53 else None

    return served


def test_a_float32_at_its_largest_value_is_the_registers_limit(tmp_path, capsys):
    """A stranger's probe: a float32 forward temperature of 3.4028235e38 (FLT_MAX, the
    most the register holds) was logged as a temperature in 9 rows, no warning, and the
    summary printed "inf kWh". Either end of a float's register counts as its limit, as an
    integer's: logged empty, with the warning."""
    with ForeignDevice(Quirks(override=_at_limits("water_out_temp_C", FLT_MAX))) as device:
        assert _run(device, tmp_path) == 0
    err = capsys.readouterr().err
    log = read_log(tmp_path / "log.csv")
    forward = log["water_out_temp_C"]
    assert np.isnan(forward).sum() == 5 and np.nanmax(np.abs(forward)) < 100
    said = "water_out_temp_C (unit 1 point 'forward_temp' at "
    assert said in err, err


def test_the_limit_note_counts_and_names_both_limits(tmp_path):
    """A stranger's probe: +327.67 in 18 rows and -327.67 in 21 rows of an int16 x0.01
    flue gas were told as "at -327.67, 39 rows". Each limit is named with its own rows."""
    quirks = Quirks(override=_at_limits("flue_gas_temp_C", 1e9))  # (saturates the int16)
    with ForeignDevice(quirks) as device:
        rig = _rig_steps(device, 60)
        rig.close()
    note = rig.limit_note()
    assert note is not None
    assert (
        "flue_gas_temp_C (unit 4 point 'flue_gas_temp' at -327.67, 2 rows, and at 327.67, 3 rows)"
    ) in note, note
    assert rig.end_notes() == [note]


def test_transient_exceptions_of_the_simulation_control_are_asked_again(tmp_path, capsys):
    """A stranger's probe: one gateway exception (0B, or 0A) on unit 100 among thousands
    stopped the run, exit 1 ("unit 100: function 4 refused with exception 0B"), or, before
    the first row, never let it start. 06, 0A and 0B are transient: asked again after a
    short pause, recorded as events; the run completes. One that persists still stops it,
    within the reply timeout."""
    # the requests to unit 100, from 0: 11 reads showing the order it answers in, its
    # status (11), clock (12) and map id (13) before the first row, then a lockstep advance
    # (even) and a read of the clock (odd) each row, and each one asked again; 150-151: one
    # refused twice, 180-181: busy twice
    transient = {11: 0x0B, 13: 0x0A, 40: 0x0B, 41: 0x0A, 101: 0x0B, 150: 0x0A, 151: 0x0B}
    transient |= {180: 0x06, 181: 0x06}
    with ForeignDevice(Quirks(sim_control_exceptions=transient.get)) as device:
        assert _run(device, tmp_path) == 0, capsys.readouterr().err
    meta = json.loads((tmp_path / "log.meta.json").read_text())
    assert meta["complete"] is True
    retried = [e for e in _events(tmp_path) if e.get("retried")]
    codes = [e["code"] for e in retried]
    # (a busy 06 to a pipelined request the connection itself asks again once, alone: one
    # or both of the two come up to the rig)
    assert [c for c in codes if c != 0x06] == [0x0B, 0x0A, 0x0B, 0x0A, 0x0B, 0x0A, 0x0B], retried
    assert 1 <= codes.count(0x06) <= 2, retried
    assert {e["unit"] for e in retried} == {100}
    assert len(read_log(tmp_path / "log.csv")["time_s"]) == 110  # no row lost
    # an advance refused once and then carried out is no failed write
    assert "writes failed" not in capsys.readouterr().err

    (tmp_path / "persistent").mkdir()

    def busy_from_the_40th(n: int) -> int | None:
        return 0x06 if n >= 40 else None

    with ForeignDevice(Quirks(sim_control_exceptions=busy_from_the_40th)) as device:
        started = time.monotonic()
        assert _run(device, tmp_path / "persistent", "--reply-timeout", "1") == 1
        took = time.monotonic() - started
    err = capsys.readouterr().err  # (an advance or a read of the clock: function 16 or 4)
    assert "unit 100: function " in err and " refused with exception 06" in err, err
    # bounded by the reply timeout (1 s) with the run around it; an unbounded retry would
    # run on for the protocol's 110 s (generous: the machine is shared)
    assert took < 30.0


def test_a_server_without_the_simulation_control_is_told_at_once(tmp_path, capsys):
    """A stranger's re-probe: a server without unit 100 (its map had the simulation control
    at unit 99; the emulator answers 0B for a unit it does not have) took the whole
    --reply-timeout (21 s with 20) asking again before the same one-line error, which came
    at once before 0A and 0B were taken for passing. A 0B from the very first request is a
    map question: told at once, the unit asked no more than it takes to find out."""
    for code in (0x0B, 0x0A):
        with ForeignDevice(Quirks(sim_control_exceptions=lambda n, c=code: c)) as device:
            assert _run(device, tmp_path, "--reply-timeout", "20") == 1
            asked = [r for r in device.requests if r[0] == 100]
        err = capsys.readouterr().err
        assert f"unit 100: function 4 refused with exception {code:02X}" in err, err
        # the 11 pipelined reads showing the order it answers in, and the two of its status
        # and clock (asked again with pauses doubling up to 1 s, 20 s of reply timeout took
        # 25 more)
        assert len(asked) == IN_ORDER_EVIDENCE + 1 + 2, asked


def test_a_passing_refusal_of_a_block_answered_before_is_no_device_limit(
    serve_process, tmp_path, capsys
):
    """A stranger's re-probe: emulator exception faults answering 03 (10 s on unit 2) and 02
    (5 s on unit 1) were taken for a device that cannot take the block: asked in halves,
    a warning and a meta note that the unit refused the read "in pieces down to one point
    at a time too: those fields are empty while it does", five exception events for the
    fault's first row instead of one. A block its unit answered whole is not asked in
    pieces: the rows' fields empty, one event a row, the block whole again after."""
    faults = tmp_path / "faults.yaml"
    faults.write_text(
        "faults:\n"
        "  - {kind: exception, unit: 2, code: 3, at_s: 30, for_s: 10}\n"
        "  - {kind: exception, unit: 1, code: 2, at_s: 60, for_s: 5}\n"
    )
    server = serve_process("--boiler", "windhager_12kw", "--lockstep", "--faults", str(faults))
    assert _run(server, tmp_path) == 0
    err = capsys.readouterr().err
    assert "in pieces" not in err, err
    meta = json.loads((tmp_path / "log.meta.json").read_text())
    assert not any("in pieces" in note for note in meta["notes"]), meta["notes"]
    refused = [e for e in _events(tmp_path) if e["event"] == "exception" and e["function"] < 5]
    per_row = {(e["unit"], e["function"], e["time_s"], *e["signals"]) for e in refused}
    assert len(per_row) == len(refused), refused  # one event a read and row
    assert {(e["unit"], e["code"]) for e in refused} == {(2, 3), (1, 2)}
    # the analyser's whole block each row (its six readings in 11 registers), never halves
    assert {len(e["signals"]) for e in refused if e["unit"] == 2} == {6}
    log = read_log(tmp_path / "log.csv")
    after = log["time_s"] >= 70  # (both faults over: every reading there)
    for signal in (*UNIT_1_READINGS, "flue_gas_O2_pct", "flue_gas_CO2_pct"):
        assert np.all(np.isfinite(log[signal][after])), signal


def test_a_tls_roles_refusal_of_fc15_is_not_taken_for_a_device_without_it(tmp_path, serve):
    """A stranger's re-probe: a TLS observer's coil writes refused with 01 (its role may
    not write) were taken for a unit without FC15: every coil asked again as FC5, refused
    too, and the unit's coils went as FC5 for the rest of the run. Over Modbus/TCP Security
    a 01 to FC15 is the role's: no FC5."""
    from rig_emulator.certs import make_lab_certificates
    from rig_emulator.modbus.roles import DEFAULT_POLICY
    from rig_emulator.modbus.tls import server_context
    from rig_emulator.modbus.transports import Transports

    certs = tmp_path / "certs"
    make_lab_certificates(certs)
    context = server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem")
    srv = serve(lockstep=False, speed=30.0, ssl_context=context)

    async def roles() -> None:
        Transports(srv.server.modbus_server).authorise(DEFAULT_POLICY)

    srv.call(roles())
    protocol = tmp_path / "foreign.yaml"
    protocol.write_text(PROTOCOL)
    tls = ["--tls-cert", str(certs / "observer.pem"), "--tls-key", str(certs / "observer.key")]
    rig = ["--rig", f"modbus+tls://127.0.0.1:{srv.port}", *tls, "--tls-ca", str(certs / "ca.pem")]
    argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--quiet", *rig]
    assert main([*argv, "--out", str(tmp_path / "log.csv")]) == 0
    refused = [e for e in _events(tmp_path) if e["event"] == "exception" and e["code"] == 1]
    assert any(e["function"] == 15 for e in refused), refused  # (the role's refusals)
    assert not any(e["function"] == 5 for e in refused), refused
