"""Faults through the server, over real sockets: the command block of the simulation
control (applied, refused whole with 03, refused with 01 on a real-time server without
--allow-control), the truth unit, the Python API, the dashboard's active faults, and
``serve --faults`` from the command line."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
from pymodbus.exceptions import ModbusIOException

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.cli import main as rig_emulator_main
from rig_emulator.faults import faults_from_list, load_faults, read_journal
from rig_emulator.faults.wire import KIND_CODES, SIGNAL_CODES
from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, client, point, read_point, start_boiler, write


def _block(srv, kind: str, target: int, parameter: float, duration: float, at_s: float = 0.0):
    """The 11 registers of the command block, command 1 (set)."""
    words = []
    for name, value in (
        ("fault_kind", KIND_CODES[kind]),
        ("fault_target", target),
        ("fault_parameter", parameter),
        ("fault_duration", duration),
        ("fault_at", at_s),
        ("fault_command", 1),
    ):
        words += encode(point(srv, "sim_control", name)[1], value)
    return words


def test_command_block_sets_and_clears_faults(serve, tmp_path):
    journal = tmp_path / "j.jsonl"
    srv = serve(fault_log=journal)
    c = client(srv.port)
    start_boiler(c, srv, 600)
    co = SIGNAL_CODES["flue_gas_CO_ppm"]
    r = c.write_registers(10, _block(srv, "dropout", co, 0.0, 5.0), device_id=100)
    assert not r.isError()
    dev, count = point(srv, "sim_control", "active_fault_count")
    assert read_point(c, dev, count) == 1.0
    assert math.isnan(read_point(c, *point(srv, "flue_gas_analyser", "CO")))
    assert read_point(c, *point(srv, "flue_gas_analyser", "status")) == 4.0
    truth = read_point(c, *point(srv, "truth", "flue_gas_CO_ppm"))
    assert truth == srv.values()["true_flue_gas_CO_ppm"] and truth > 0
    assert read_point(c, *point(srv, "sim_control", "fault_command")) == 0.0  # a trigger
    # a block that is no fault: refused whole (03), nothing set
    for bad in (
        _block(srv, "dropout", 99, 0.0, 5.0),  # no such signal
        _block(srv, "exception", 5, 300.0, 5.0),  # no such exception code
        _block(srv, "no_reply", 100, 0.0, 5.0),  # the simulation control
        _block(srv, "no_reply", 99, 0.0, 5.0),  # a unit the bench does not have
    ):
        r = c.write_registers(10, bad, device_id=100)
        assert r.isError() and r.exception_code == 3
    assert read_point(c, dev, count) == 1.0
    assert read_point(c, *point(srv, "sim_control", "fault_kind")) == KIND_CODES["dropout"]
    # clear: command 2
    assert not c.write_registers(20, [2], device_id=100).isError()
    assert read_point(c, dev, count) == 0.0
    assert not math.isnan(read_point(c, *point(srv, "flue_gas_analyser", "CO")))
    c.close()
    kinds = [(e["event"], e["kind"], e["source"], e.get("reason")) for e in read_journal(journal)]
    assert kinds == [("start", "dropout", "modbus", None), ("end", "dropout", "modbus", "cleared")]


def test_fault_block_on_a_realtime_server_needs_allow_control(serve):
    srv = serve(lockstep=False, speed=1.0)
    c = client(srv.port)
    co = SIGNAL_CODES["flue_gas_CO_ppm"]
    r = c.write_registers(10, _block(srv, "dropout", co, 0.0, 5.0), device_id=100)
    assert r.isError() and r.exception_code == 1
    assert srv.server.active_faults() == []
    c.close()
    allowed = serve(lockstep=False, speed=1.0, allow_control=True)
    c = client(allowed.port)
    r = c.write_registers(10, _block(allowed, "dropout", co, 0.0, 5.0), device_id=100)
    assert not r.isError() and len(allowed.server.active_faults()) == 1
    c.close()


def test_python_api_and_truth(serve):
    srv = serve(profile="lab", seed=5)
    c = client(srv.port)
    start_boiler(c, srv, 900)
    srv.call(_inject(srv.server, {"kind": "offset", "signal": "balance_mass_kg", "value": 15.0}))
    assert not write(c, srv, *ADVANCE, 1).isError()
    reading = read_point(c, *point(srv, "balance", "mass"))
    truth = srv.server.truth("balance_mass_kg")
    # +15 kg on top of the instrument's own error (accuracy 0.05 kg, noise, 0.02 kg steps)
    assert abs(reading - truth - 15.0) < 0.2
    assert srv.server.active_faults()[0]["kind"] == "offset"
    srv.server.clear_faults()
    assert srv.server.active_faults() == []
    c.close()


async def _inject(server, fault):
    server.inject(fault)


def test_dashboard_lists_active_faults(tmp_path):
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: no_reply, unit: 2, at_s: 0}\n")
    http = free_port()
    with rig_emulator_serve(
        "windhager_12kw", "--lockstep", "--http", str(http), "--faults", str(faults)
    ) as (port, _):
        assert wait_for_port("127.0.0.1", http, 30.0)
        c = client(port)
        from rig_emulator.registers import load_map

        register_map = load_map()
        dev = register_map.device("sim_control")
        p = next(q for q in dev.points if q.name == "lockstep_advance")
        assert not c.write_registers(p.address, encode(p, 1), device_id=100).isError()
        c.close()
        with urllib.request.urlopen(f"http://127.0.0.1:{http}/api/state", timeout=10) as r:
            state = json.loads(r.read())
    assert [(f["kind"], f["unit"], f["source"]) for f in state["faults"]] == [
        ("no_reply", 2, "file")
    ]


def test_serve_refuses_a_bad_faults_file(tmp_path, capsys):
    bad = tmp_path / "faults.yaml"
    bad.write_text("faults:\n  - {kind: delay, unit: 3}\n")
    code = rig_emulator_main(["serve", "--boiler", "windhager_12kw", "--faults", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "faults[0].delay_ms: missing" in err and str(bad) in err
    code = rig_emulator_main(["serve", "--boiler", "windhager_12kw", "--faults", "nope.yaml"])
    assert code == 2 and "nope.yaml" in capsys.readouterr().err
    # and as a user sees it: a subprocess, one line, exit 2, no traceback
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "rig_emulator.cli",
            "serve",
            "--boiler",
            "windhager_12kw",
            "--faults",
            str(bad),
            "--port",
            str(free_port()),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0


@pytest.mark.parametrize(
    ("entry", "where"),
    [
        ("{kind: no_reply, unit: 99, at_s: 0}", "faults[0].unit: unit 99 is not on the bench"),
        (
            "{kind: random, rate_per_h: 6, kinds: [no_reply], units: [2, 9]}",
            "faults[0].units: unit 9 is not on the bench",
        ),
    ],
)
def test_a_fault_on_a_unit_the_bench_does_not_have_is_refused(tmp_path, capsys, entry, where):
    """A typo (99 for 9) would give a fault that hits no instrument, silently."""
    bad = tmp_path / "faults.yaml"
    bad.write_text(f"faults:\n  - {entry}\n")
    code = rig_emulator_main(["serve", "--boiler", "windhager_12kw", "--faults", str(bad)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and where in err, err


def test_numbers_in_exponent_form_are_numbers_in_a_faults_file(tmp_path):
    """YAML 1.1 reads 1e3 (no dot) as text; a faults file takes it as the number it is."""
    path = tmp_path / "faults.yaml"
    path.write_text("faults:\n  - {kind: delay, unit: 1, delay_ms: 8e2, at_s: 1E3, for_s: 6e1}\n")
    (spec,) = load_faults(path)
    assert (spec.parameter, spec.at_s, spec.for_s) == (800.0, 1000.0, 60.0)


def test_a_fault_window_inside_one_advance_is_over_after_it(serve, tmp_path):
    """CONTRACT section 5: a fault "starts at at_s and lasts for_s" in simulated seconds.
    One lockstep advance of 880 s over a balance busy from 740 to 750 s: afterwards the
    balance answers, and the journal gives the window's own times."""
    journal = tmp_path / "j.jsonl"
    faults = faults_from_list(
        [{"kind": "exception", "unit": 5, "code": 6, "at_s": 740, "for_s": 10}]
    )
    srv = serve(faults=faults, fault_log=journal)
    c = client(srv.port)
    assert not write(c, srv, *ADVANCE, 880).isError()
    assert read_point(c, *point(srv, "balance", "mass")) > 0
    c.close()
    events = [(e["event"], e["t_sim_s"]) for e in read_journal(journal)]
    assert events == [("start", 740.0), ("end", 750.0)]


def test_a_profile_fault_on_a_unit_the_bench_does_not_have_is_refused(tmp_path, capsys):
    profile = tmp_path / "faulty.yaml"
    profile.write_text(
        "name: faulty\nfaults:\n  - {kind: random, rate_per_h: 6, kinds: [delay], units: [9, 42]}\n"
    )
    code = rig_emulator_main(
        ["serve", "--boiler", "windhager_12kw", "--lockstep", "--profile", str(profile)]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "unit 9 is not on the bench" in err, err


def test_a_fault_on_every_unit_leaves_a_unit_the_bench_lacks_answering_0B(serve):
    """Unit 0 in a fault means every unit of the bench; a unit the bench does not have
    still gets 0B, as without faults (it timed out under ``no_reply`` on unit 0)."""
    srv = serve()
    srv.call(_inject(srv.server, {"kind": "no_reply", "unit": 0}))
    c = client(srv.port, timeout_s=0.5)
    try:
        r = c.read_holding_registers(0, count=1, device_id=9)
        assert r.isError() and r.exception_code == 0x0B
    finally:
        c.close()
    c = client(srv.port, timeout_s=0.5)
    try:
        with pytest.raises(ModbusIOException):  # the fault acts on the bench's units
            c.read_input_registers(0, count=2, device_id=1)
    finally:
        c.close()


def test_the_journal_writes_a_reading_as_its_register_serves_it(serve, tmp_path):
    """An offset beyond what the flue-gas probe's int16 in hundredths can carry clips at
    327.67 C on the wire; the journal wrote the engine's 1000-K-high value, which no client
    ever read (a stranger's probe)."""
    journal = tmp_path / "j.jsonl"
    faults = faults_from_list(
        [{"kind": "offset", "signal": "flue_gas_temp_C", "value": 1000.0, "at_s": 60}]
    )
    srv = serve(faults=faults, fault_log=journal)
    c = client(srv.port)
    assert not write(c, srv, *ADVANCE, 120).isError()
    served = read_point(c, *point(srv, "flue_gas_probe", "flue_gas_temp"))
    c.close()
    (start,) = [e for e in read_journal(journal) if e["event"] == "start"]
    assert served == pytest.approx(327.67)  # int16 x 0.01: 32767, its invalid code 0x8000
    assert start["served"]["reading"] == pytest.approx(served)
    assert start["served"]["truth"] < 100.0  # the plant's own flue gas, unclipped
    # and on the register's steps: 0.01 K, not 68.5197... (a re-probe)
    instrument = start["served"]["instrument"]
    assert instrument == round(instrument, 2)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_journal_that_cannot_be_written_costs_its_lines_not_the_run(tmp_path):
    """A stranger's probe with ``--fault-log /dev/full`` (a full disk): the lockstep advance
    that started or ended a fault answered exception 04 although it had advanced (the
    client's next step went two), the log got two tracebacks, and the stop said "cannot
    serve ... No space left on device" with exit 2. Now one warning, the steps exact, the
    fault served, a clean stop, and exit 1 for the journal lines lost (a later probe: a
    CI job saw exit 0 and never learned the journal was incomplete)."""
    import signal

    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 5, code: 6, at_s: 1, for_s: 5}\n")
    options = ("--lockstep", "--faults", str(faults), "--fault-log", "/dev/full")
    with rig_emulator_serve("windhager_12kw", *options, stderr=subprocess.PIPE) as (port, proc):
        from rig_emulator.registers import load_map

        sim = load_map().device("sim_control")
        sim_time = next(p for p in sim.points if p.name == "sim_time")
        advance = next(p for p in sim.points if p.name == "lockstep_advance")
        c = client(port, timeout_s=60)
        replies = []
        for step in range(1, 8):
            reply = c.write_registers(advance.address, encode(advance, 1), device_id=100)
            replies.append(reply.isError())
            assert read_point(c, sim, sim_time) == step
            if step == 3:  # inside the window: the balance is busy
                busy = c.read_input_registers(0, count=2, device_id=5)
                assert busy.isError() and busy.exception_code == 6
        c.close()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=60)
        err = proc.stderr.read().decode()
    assert replies == [False] * 7
    assert code == 1, err  # a clean stop, and exit 1 for the lines lost (a probe: it was 0)
    assert "Traceback" not in err and "cannot serve" not in err, err
    assert err.count("fault journal /dev/full: cannot write") == 1, err
    assert "line(s) lost" in err, err


def test_a_fault_on_every_unit_leaves_the_maps_own_units_wherever_they_are(serve):
    """A re-probe: with the simulation control at unit 7 (and the boiler controller at
    100), a no_reply on every unit (0) silenced the simulation control, so no client could
    advance the clock or clear the fault, while a fault on the controller at 100 was
    refused as "the emulator's own"."""
    from tests.rig_emulator.transports.remapped import shipped_map_with_units

    swapped = shipped_map_with_units(sim_control=7, boiler_controller=100)
    faults = faults_from_list([{"kind": "no_reply", "unit": 0}])
    srv = serve(register_map=swapped, faults=faults)
    c = client(srv.port, timeout_s=1.0)
    try:
        answer = c.read_input_registers(0, count=4, device_id=7)  # sim_time, unit 7 now
        assert not answer.isError()
        with pytest.raises(ModbusIOException):  # the controller, unit 100 now: faulted
            c.read_input_registers(0, count=1, device_id=100)
    finally:
        c.close()


def test_random_faults_without_units_draw_from_the_maps_instruments(tmp_path):
    """A stranger's map with the simulation control at unit 7 and the balance at 31: a
    random generator without ``units`` defaulted to 1-7, so ``serve`` refused the whole
    file ("unit 7 is the emulator's own"), and with 31 never drawn. It now draws from the
    instrument units of the map served."""
    import signal

    from rig_emulator.registers import instrument_units
    from rig_emulator.yamlio import dump_yaml, read_yaml
    from tests.rig_emulator.transports.remapped import MAP_DIR, shipped_map_with_units

    units = {"sim_control": 7, "balance": 31}
    data = read_yaml(MAP_DIR / "wieselburg_bench.yaml", ValueError)
    names = {d["name"]: d["unit_id"] for d in data["devices"]}
    moved = {name: unit for name, unit in units.items() if name in names}
    displaced = [n for n, u in names.items() if u == 7 and n != "sim_control"]
    moved.update(dict.fromkeys(displaced, 1 + max(names.values())))  # the device at 7
    for device in data["devices"]:
        device["unit_id"] = moved.get(device["name"], device["unit_id"])
    map_file = tmp_path / "moved.yaml"
    map_file.write_text(dump_yaml(data))
    bench = instrument_units(shipped_map_with_units(**moved))
    assert 7 not in bench and 31 in bench
    faults = tmp_path / "faults.yaml"
    faults.write_text(
        "faults:\n  - {kind: random, rate_per_h: 3600, kinds: [no_reply], fault_for_s: 1,"
        " seed: 3}\n"
    )
    journal = tmp_path / "j.jsonl"
    options = ("--lockstep", "--map", str(map_file), "--faults", str(faults))
    options += ("--fault-log", str(journal))
    with rig_emulator_serve("windhager_12kw", *options, stderr=subprocess.PIPE) as (port, proc):
        from rig_emulator.registers import load_map

        sim = load_map(map_file).device("sim_control")
        advance = next(p for p in sim.points if p.name == "lockstep_advance")
        c = client(port, timeout_s=60)
        assert not c.write_registers(advance.address, encode(advance, 120), device_id=7).isError()
        c.close()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=60)
        err = proc.stderr.read().decode()
    assert code == 0, err
    drawn = {e["unit"] for e in read_journal(journal) if e["event"] == "start"}
    # 120 draws at one a second from eight units: each one drawn, no other
    assert drawn == set(bench), (drawn, bench)


def test_random_faults_without_signals_draw_from_what_the_map_publishes(serve, tmp_path):
    """A re-probe: a map without the FID (unit 3) and random instrument faults without
    ``signals`` drew 56 faults on flue_gas_OGC_ppm, which no instrument of that map
    serves: journalled, never seen, counted missed by any report."""
    from rig_emulator.registers import MAP_DIR, map_from_mapping
    from rig_emulator.yamlio import read_yaml

    data = read_yaml(MAP_DIR / "wieselburg_bench.yaml", ValueError)
    data["devices"] = [d for d in data["devices"] if d["name"] != "fid"]
    no_fid = map_from_mapping(data, "no_fid.yaml")
    faults = faults_from_list(
        [{"kind": "random", "rate_per_h": 3600, "kinds": ["spike"], "fault_for_s": 1, "seed": 5}]
    )
    journal = tmp_path / "j.jsonl"
    srv = serve(register_map=no_fid, faults=faults, fault_log=journal)
    c = client(srv.port)
    for _ in range(300):  # a step a second: each drawn spike is served
        assert not write(c, srv, *ADVANCE, 1).isError()
    c.close()
    drawn = {e["signal"] for e in read_journal(journal) if e["event"] == "start"}
    served = {p.signal for d in no_fid.devices if d.unit_id not in (100, 101) for p in d.points}
    assert "flue_gas_OGC_ppm" not in served and len(drawn) >= 5
    assert drawn <= served, drawn - served


def test_a_set_takes_only_a_block_written_for_it(serve):
    """A stranger's probe: after one valid block (an offset of 5 kg/h on the flow), a write
    of the command alone (FC6 at address 20, or FC16 of it alone) armed the block left
    there again: two offsets, the flow read 10 kg/h off. A set takes a block every field of
    which was written since the last set: the command alone, or with part of the block, gets
    03 and nothing is set; the fields first and the command last still set one (a re-probe:
    the first fix refused that, which a map with the command apart from its fields needs);
    a clear alone stays a clear."""
    srv = serve()
    c = client(srv.port)
    flow = SIGNAL_CODES["water_flow_kg_h"]
    words = _block(srv, "offset", flow, 5.0, 0.0)
    assert not c.write_registers(10, words, device_id=100).isError()
    dev, count = point(srv, "sim_control", "active_fault_count")
    assert read_point(c, dev, count) == 1.0
    command_address = point(srv, "sim_control", "fault_command")[1].address
    set_alone = c.write_register(command_address, 1, device_id=100)
    assert set_alone.isError() and set_alone.exception_code == 3, set_alone
    tail = c.write_registers(command_address - 4, words[-5:], device_id=100)  # at + command
    assert tail.isError() and tail.exception_code == 3, tail
    assert read_point(c, dev, count) == 1.0  # nothing set
    # the fields first (kind to at), the command last: a second fault
    assert not c.write_registers(10, words[:-1], device_id=100).isError()
    assert read_point(c, dev, count) == 1.0
    assert not c.write_register(command_address, 1, device_id=100).isError()
    assert read_point(c, dev, count) == 2.0
    set_again = c.write_register(command_address, 1, device_id=100)  # that block is spent
    assert set_again.isError() and set_again.exception_code == 3, set_again
    assert not c.write_register(command_address, 2, device_id=100).isError()  # clear alone
    assert read_point(c, dev, count) == 0.0


def test_random_spikes_beyond_a_register_read_its_end(serve, tmp_path):
    """A stranger's probe: random spikes of the default 9999 on the int16 flue-gas
    temperature (327.67 C at most) were taken, served at 327.67 with a warning blaming the
    map ("widen the point's type"), and journalled as asking 9999; the same spike set by
    hand is refused. A drawn spike reads its register's end, as an instrument's overload
    does, and the journal says so."""
    faults = faults_from_list(
        [{"kind": "random", "rate_per_h": 3600, "kinds": ["spike"], "seed": 7,
          "signals": ["flue_gas_temp_C"], "fault_for_s": 1}]
    )  # fmt: skip
    journal = tmp_path / "j.jsonl"
    srv = serve(faults=faults, fault_log=journal)
    c = client(srv.port)
    for _ in range(120):
        assert not write(c, srv, *ADVANCE, 1).isError()
    c.close()
    starts = [e for e in read_journal(journal) if e["event"] == "start"]
    assert len(starts) >= 5
    assert {e["value"] for e in starts} == {327.67}, starts[:3]
    assert all(e["served"]["reading"] == 327.67 for e in starts if e.get("served"))
