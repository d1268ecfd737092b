"""``hil-client run`` and ``gap-benchmark`` refuse bad input before any file is written:
exit code 2, one line naming what is wrong, an existing ``--out`` left as it was."""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from pathlib import Path

import pytest
import yaml

from hil_client.cli import main
from hil_client.lablog import LabLogWriter
from hil_client.protocol.runner import LOG_COLUMNS
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.registers import load_map

SHORT = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"
KEPT = "an earlier log the run must not replace\n"


def _refused(capsys, argv: list[str], message: str) -> str:
    """Run ``argv``; assert exit 2 with one stderr line holding ``message``."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


def _kept(tmp_path: Path) -> Path:
    out = tmp_path / "log.csv"
    out.write_text(KEPT)
    return out


def _protocol(tmp_path: Path, mutate: Callable[[dict], object]) -> str:
    data = yaml.safe_load(SHORT.read_text())
    mutate(data)
    path = tmp_path / "protocol.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def _seq(data: dict, **changes: object) -> None:
    data["test_sequence"]["sequences"][0].update(changes)


def test_a_boiler_too_big_for_the_bench_is_refused_and_the_log_kept(tmp_path, capsys):
    # a consistent 40 kW boiler: its nominal load at a 15 K spread needs 2291 kg/h, more
    # than the bench's flow range
    big = yaml.safe_load((BOILER_DIR / "windhager_6kw.yaml").read_text())
    big.update(name="big40", p_nom_kW=40.0, p_max_kW=44.0, p_min_kW=12.0, p_start_kW=44.0)
    big.update(c_therm_kJ_K=400.0, vol_water_m3=0.15, fac_b_lambda_h_kg=-0.33)
    boiler = tmp_path / "big40.yaml"
    boiler.write_text(yaml.safe_dump(big))
    out = _kept(tmp_path)
    argv = ["run", "stationary", "--boiler", str(boiler), "--quiet", "--out", str(out)]
    err = _refused(capsys, argv, "water_flow_setpoint_kg_h: 2291.1")
    assert "big40" in err and "'preheat.load_pct'" in err and "0..2000" in err
    assert out.read_text() == KEPT
    assert not (tmp_path / "log.meta.json").exists()


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d["test_sequence"].update(return_setpoint_C=500), "return_setpoint_C: 500"),
        (lambda d: d["test_sequence"].update(return_setpoint_C=-300), "return_setpoint_C: -300"),
        (lambda d: d["preheat"].update(temperature_C=400), "'preheat.temperature_C'"),
        (lambda d: d.update(flow_spread_K=1e-6), "water_flow_setpoint_kg_h"),
    ],
)
def test_setpoints_out_of_the_emulators_range_are_refused(tmp_path, capsys, mutate, message):
    out = _kept(tmp_path)
    protocol = _protocol(tmp_path, mutate)
    argv = ["run", protocol, "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    err = _refused(capsys, argv, message)
    assert "outside" in err and protocol in err
    assert out.read_text() == KEPT


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: _seq(d, duration="nan:00:00"), "HH:MM:SS"),
        (lambda d: _seq(d, duration="inf:00:00"), "HH:MM:SS"),
        (lambda d: _seq(d, duration="99999999:00:00"), "more than a week"),
        (lambda d: _seq(d, duration=1e12), "more than a week"),
        (lambda d: d.update(acquisition_period_s=1e-6), "0.1..600 s"),
        (lambda d: d.update(acquisition_period_s=1e9), "0.1..600 s"),
        (lambda d: d["start_up"].update(min_duration_s=9000), "exceeds 'start_up.max_duration_s'"),
        (lambda d: d["preheat"].update(tolerance_K=-0.5), "'preheat.tolerance_K' must be > 0"),
        (lambda d: d["preheat"].update(hold_s=-60), "'preheat.hold_s'"),
        (lambda d: d["start_up"].update(t1_max_rise_K_min=-0.5), "'start_up.t1_max_rise_K_min'"),
        (lambda d: _seq(d, name="a,b\nc"), "'test_sequence.sequences[0].name'"),
        (lambda d: _seq(d, name='say "peak"'), "may not hold a comma, a quote"),
        # a spreadsheet's formula in the log's sequence column (a stranger's probe)
        (lambda d: _seq(d, name="=1+1"), "may not begin with = + - @: a spreadsheet"),
        (lambda d: _seq(d, name="＝1+1"), "may not begin with = + - @: a spreadsheet"),
        (lambda d: _seq(d, name="tab\there"), "control characters"),
        # a stranger's probe: flows of a few kg/h, and only "preheat timed out" hours later
        (
            lambda d: d.update(flow_spread_K=1000),
            "'start_up.return_setpoint_C' (55 C) + 'flow_spread_K' (1000 K) = 1055 C: the "
            "flows would be set for a forward water at or above the 100 C at which it boils",
        ),
        # a stranger's probe: float("-00") is -0.0, so "-00:10:00" played +600 s; Arabic-Indic
        # digits read as 10 h; a name given as a number was "missing"; a ramp's bad end was
        # named load_pct.b, a key the file does not have; a line break in the protocol's name
        (lambda d: _seq(d, duration="-00:10:00"), "HH:MM:SS"),
        (lambda d: _seq(d, duration="+00:10:00"), "HH:MM:SS"),
        (lambda d: _seq(d, duration="\u0661\u0660:00:00"), "HH:MM:SS"),
        (lambda d: _seq(d, name=12), "'test_sequence.sequences[0].name' must be a non-empty text"),
        (lambda d: d.update(name=5), "key 'name' must be a non-empty text"),
        (lambda d: d.update(name="two\nlines"), "key 'name'"),
        (lambda d: _seq(d, load_pct=[100, 300]), "'test_sequence.sequences[0].load_pct[1]'"),
    ],
)
def test_protocols_that_would_hang_or_corrupt_the_log_are_refused(
    tmp_path, capsys, mutate, message
):
    out = _kept(tmp_path)
    protocol = _protocol(tmp_path, mutate)
    argv = ["run", protocol, "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    _refused(capsys, argv, message)
    assert out.read_text() == KEPT


def test_a_command_refused_mid_run_is_one_line(tmp_path, capsys, monkeypatch):
    # a setpoint the up-front check did not catch: one line, exit 2, no traceback
    monkeypatch.setattr("hil_client.cli.check_setpoints", lambda *args: None)
    protocol = _protocol(tmp_path, lambda d: d["test_sequence"].update(return_setpoint_C=500))
    out = tmp_path / "log.csv"
    argv = ["run", protocol, "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    err = _refused(capsys, argv, "return_setpoint_C: 500.0 outside 10..90")
    assert "the log keeps the " in err and " rows written" in err


def test_out_below_a_file_is_refused(tmp_path, capsys):
    (tmp_path / "p.sh").write_text("#!/bin/sh\n")
    argv = ["run", "stationary", "--boiler", "windhager_6kw", "--out", str(tmp_path / "p.sh/a.csv")]
    _refused(capsys, argv, "is a file, not a directory")
    for out in ("p.sh", "p.sh/sub"):
        argv = ["gap-benchmark", "--cases", "1", "--out", str(tmp_path / out)]
        _refused(capsys, argv, "--out: ")
    assert (tmp_path / "p.sh").read_text() == "#!/bin/sh\n"
    # an empty path was taken as '.', and the error named '.' (a stranger's probe)
    _refused(
        capsys, ["run", "stationary", "--boiler", "windhager_6kw", "--out", ""], "an empty path"
    )


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--seed", "-1"], "--seed: -1 is outside 0..4294967295"),
        (["--seed", str(2**32)], "--seed"),
        (["--cases", "100000000000"], "--cases: 100000000000 is outside 1..10000"),
        (["--cases", "0"], "--cases"),
        (["--workers", "0"], "--workers"),
    ],
)
def test_gap_benchmark_bounds(tmp_path, capsys, option, message):
    out = tmp_path / "gap"
    _refused(capsys, ["gap-benchmark", *option, "--out", str(out)], message)
    assert not out.exists()


@pytest.mark.parametrize("port", ["0", "70000"])
def test_rig_port_outside_1_to_65535_is_refused(tmp_path, capsys, port):
    out = _kept(tmp_path)
    rig = f"modbus://127.0.0.1:{port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", rig, "--out", str(out)]
    _refused(capsys, argv, "bad port (1..65535)")
    assert out.read_text() == KEPT


def _map_without(tmp_path: Path, drop: Callable[[dict], object]) -> str:
    data = yaml.safe_load(Path(load_map().source).read_text())
    drop(data)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def _drop_device(name: str) -> Callable[[dict], object]:
    return lambda d: d.update(devices=[dev for dev in d["devices"] if dev["name"] != name])


@pytest.mark.parametrize(
    ("drop", "message"),
    [
        (_drop_device("sim_control"), "no point for 'sim_time_s'"),
        (_drop_device("balance"), "no point for 'balance_mass_kg'"),
    ],
)
def test_a_map_without_what_the_modbus_rig_needs_is_refused(tmp_path, capsys, serve, drop, message):
    srv = serve()
    out = _kept(tmp_path)
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    argv += ["--map", _map_without(tmp_path, drop), "--out", str(out)]
    _refused(capsys, argv, message)
    assert out.read_text() == KEPT


def test_an_invalid_map_is_refused_for_the_local_rig_too(tmp_path, capsys):
    def overlap(data: dict) -> None:
        data["devices"][0]["points"][1]["address"] = data["devices"][0]["points"][0]["address"]

    out = _kept(tmp_path)
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", "local", "--quiet"]
    argv += ["--map", _map_without(tmp_path, overlap), "--out", str(out)]
    _refused(capsys, argv, "--map: ")
    assert out.read_text() == KEPT


def test_a_server_running_another_boiler_is_refused(tmp_path, capsys, serve):
    srv = serve(boiler="windhager_6kw")
    out = _kept(tmp_path)
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    err = _refused(capsys, [*argv, "--out", str(out)], "runs another boiler")
    assert "windhager_6kw" in err and "windhager_12kw" in err
    assert out.read_text() == KEPT


def test_the_meta_file_records_the_servers_boiler(tmp_path, capsys, serve):
    from rig_emulator.boilers import load_boiler
    from rig_emulator.emulator import boiler_identity

    srv = serve(boiler="windhager_6kw", seed=5)
    out = tmp_path / "log.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_6kw", "--rig", rig, "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    meta = json.loads((tmp_path / "log.meta.json").read_text())
    assert meta["server_boiler_id"] == f"{boiler_identity(load_boiler('windhager_6kw')):08x}"
    assert meta["server_boiler_id"] == f"{int(srv.values()['boiler_id']):08x}"
    assert meta["seed"] == 5  # the server's (it was null: a stranger's probe)


def test_the_log_writer_quotes_a_text_field_that_would_break_the_row(tmp_path):
    path = tmp_path / "log.csv"
    numbers = [1.5] * (len(LOG_COLUMNS) - 3)
    with LabLogWriter(path) as writer:
        writer((1.0, "test", "a,b\nc", *numbers))
        writer((2.0, "test", 'say "x"', *numbers[:-1], float("nan")))
        writer((3.0, "test", "plain", *numbers))
    rows = list(csv.reader(path.open(newline="")))
    assert [len(r) for r in rows] == [len(LOG_COLUMNS)] * 4
    assert [r[2] for r in rows[1:]] == ["a,b\nc", 'say "x"', "plain"]
    # the quoted rows' numbers are written as the plain row's; a missing one is empty
    assert rows[1][3:] == rows[3][3:] and rows[1][0] == "1.000"
    assert rows[2][-1] == "" and rows[2][3:-1] == rows[3][3:-1]


@pytest.mark.parametrize("protocol", ["stationary", "load_cycle"])
@pytest.mark.parametrize("boiler", ["windhager_6kw", "windhager_12kw"])
def test_the_shipped_protocols_pass_the_setpoint_check(protocol, boiler):
    from hil_client.protocol.definition import load_protocol
    from hil_client.protocol.runner import check_setpoints, setpoints
    from rig_emulator.boilers import load_boiler

    proto, params = load_protocol(protocol), load_boiler(boiler)
    check_setpoints(proto, params.p_nom_kW, boiler)  # raises if not
    flows = [v for _, c, v in setpoints(proto, params.p_nom_kW) if c == "water_flow_setpoint_kg_h"]
    assert max(flows) > 300  # the nominal load's flow is among the values checked


def test_a_run_refused_at_its_first_step_keeps_the_previous_logs(tmp_path, capsys, serve):
    """A TLS client whose role may not drive the lockstep clock (an observer) fails at
    its first step: the previous run's log, meta and events files are as they were."""
    from rig_emulator.certs import make_lab_certificates
    from rig_emulator.modbus.roles import DEFAULT_POLICY
    from rig_emulator.modbus.tls import server_context
    from rig_emulator.modbus.transports import Transports

    certs = tmp_path / "certs"
    make_lab_certificates(certs)
    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem")
    )

    async def roles() -> None:
        Transports(srv.server.modbus_server).authorise(DEFAULT_POLICY)

    srv.call(roles())
    out = _kept(tmp_path)
    meta = tmp_path / "log.meta.json"
    meta.write_text('{"earlier": true}')
    tls = ["--tls-cert", str(certs / "observer.pem"), "--tls-key", str(certs / "observer.key")]
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    rig = ["--rig", f"modbus+tls://127.0.0.1:{srv.port}", *tls, "--tls-ca", str(certs / "ca.pem")]
    assert main([*argv, *rig]) == 1
    err = capsys.readouterr().err
    assert "refused" in err and "no row was acquired; the previous run's log is back" in err
    assert out.read_text() == KEPT and meta.read_text() == '{"earlier": true}'
    assert not list(tmp_path.glob("log.previous*")) and not list(tmp_path.glob("*.previous"))
    # without an earlier run, nothing is left: no header-only log, no meta, no events
    fresh = tmp_path / "fresh" / "log.csv"
    fresh_argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--quiet", "--out", str(fresh)]
    assert main([*fresh_argv, *rig]) == 1
    assert "no row was acquired; no log written" in capsys.readouterr().err
    assert list(fresh.parent.iterdir()) == []
    # plain Modbus/TCP at the TLS port: the server closes it; the message says what to try
    assert main([*fresh_argv, "--rig", f"modbus://127.0.0.1:{srv.port}"]) == 1
    assert "modbus+tls://?" in capsys.readouterr().err


def test_a_renamed_copy_of_the_servers_boiler_is_the_same_boiler(tmp_path, capsys, serve):
    """The boiler id is of the parameters, not the file's name: a lab's copy named
    my_lab_boiler with the same values runs against the server."""
    data = yaml.safe_load((BOILER_DIR / "windhager_12kw.yaml").read_text())
    data["name"] = "my_lab_boiler"
    copy = tmp_path / "mine.yaml"
    copy.write_text(yaml.safe_dump(data))
    srv = serve(boiler="windhager_12kw")
    out = tmp_path / "log.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", str(copy), "--rig", rig, "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0, capsys.readouterr().err


def test_commands_the_server_refused_are_not_a_silent_success(tmp_path, capsys, serve):
    """The bench PLC answers 04 for ten minutes (an injected fault; a TLS observer's 01 is
    the same to the rig): the run goes on, as acquisition must, but says in one warning and
    in the meta file's notes that the plant did not get those commands."""
    from rig_emulator.faults import faults_from_list

    faults = faults_from_list(
        [{"kind": "exception", "unit": 1, "code": 4, "at_s": 60, "for_s": 600}]
    )
    srv = serve(faults=faults)
    out = tmp_path / "log.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "setpoint or switch writes failed (exception 04; the first to unit 1)" in err
    notes = json.loads((tmp_path / "log.meta.json").read_text())["notes"]
    assert any("the plant did not get those commands" in n for n in notes)


@pytest.mark.parametrize("slow", [False, True])
def test_a_run_whose_commands_all_arrived_has_no_such_warning(tmp_path, capsys, serve, slow):
    """Also when the bench PLC answers its writes 0.4 s late (a delay fault): late is not
    lost (60 slow writes were reported as commands the plant did not get)."""
    from rig_emulator.faults import faults_from_list

    delay = [{"kind": "delay", "unit": 1, "delay_ms": 400, "at_s": 60, "for_s": 10}]
    srv = serve(faults=faults_from_list(delay if slow else []))
    out = tmp_path / "log.csv"
    rig = f"modbus://127.0.0.1:{srv.port}"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", rig, "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    assert "writes failed" not in capsys.readouterr().err
    if slow:  # the writes were late indeed, and said so in the events file
        events = [json.loads(line) for line in (tmp_path / "log.modbus_events.jsonl").open()]
        assert any(e["event"] == "late" and e["function"] in (5, 6, 15, 16) for e in events)


def test_a_run_to_the_out_of_an_earlier_one_says_what_it_replaces(tmp_path, capsys):
    """A rerun to the same --out replaced a killed run's partial log without a word (a
    stranger's probe): one line names what is replaced; a first run says nothing."""
    out = tmp_path / "log.csv"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    assert main(argv) == 0
    assert "earlier run" not in capsys.readouterr().err
    rows = len(out.read_text().splitlines()) - 1
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert f"{out} holds an earlier run's log ({rows} rows, complete): this run replaces" in err


def test_a_valid_map_for_the_local_rig_is_said_to_be_unused(tmp_path, capsys):
    """--map with --rig local was checked, then ignored without a word (a stranger's
    probe): the run goes on and says the map is for a Modbus rig."""
    from rig_emulator.registers.schema import MAP_DIR

    out = tmp_path / "local.csv"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", "local", "--quiet"]
    assert main([*argv, "--map", str(MAP_DIR / "wieselburg_bench.yaml"), "--out", str(out)]) == 0
    assert "--rig local reads no registers" in capsys.readouterr().err


def _with_file_size_limit(limit_bytes: int):
    """A child process whose files cannot grow beyond ``limit_bytes`` (a full disk, as the
    kernel reports it: EFBIG on the write; SIGXFSZ ignored so the write returns it)."""
    import resource
    import signal

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return limit


def test_a_disk_that_fills_up_ends_the_run_in_one_line_and_keeps_the_rows(tmp_path):
    """A stranger's probe with a 64-kB tmpfs: the run ended in two tracebacks and a meta
    file that said nothing. Now one line naming the log, exit 1, the rows written kept."""
    import subprocess
    import sys

    out = tmp_path / "st.csv"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "hil_client.cli",
            "run",
            "stationary",
            "--boiler",
            "windhager_12kw",
            "--rig",
            "local",
            "--out",
            str(out),
            "--quiet",
        ],
        preexec_fn=_with_file_size_limit(64 * 1024),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"cannot write {out}" in lines[0], lines
    assert 0 < out.stat().st_size <= 64 * 1024
    rows = len(out.read_text().splitlines()) - 1  # as many as the message says
    assert f"the log keeps the {rows} rows written" in lines[0], lines
    # the log ends on its last whole row (a probe: half of the last one was left there)
    text = out.read_text()
    assert text.endswith("\n")
    widths = {len(line.split(",")) for line in text.splitlines()}
    assert widths == {len(LOG_COLUMNS)}, widths


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_an_output_that_cannot_be_written_is_one_line_naming_it(tmp_path, capsys, run_log):
    """balance's --out on a full disk: a traceback before; now one line, exit 1."""
    out = tmp_path / "b.json"
    out.symlink_to("/dev/full")
    code = main(
        [
            "balance",
            str(run_log("stationary", "windhager_12kw").path),
            "--boiler",
            "windhager_12kw",
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert code == 1 and err.strip() == f"hil-client: error: writing {out}: No space left on device"


@pytest.mark.parametrize("target", ["log", "meta", "journal"])
def test_a_fault_report_may_not_replace_the_runs_own_files(tmp_path, capsys, target):
    """A re-probe: ``run --fault-report`` naming the run's own log (or its meta file, or
    its --fault-journal) replaced it with the report after the run, exit 0."""
    out, journal = tmp_path / "run.csv", tmp_path / "j.jsonl"
    journal.write_text("")
    report = {"log": out, "meta": tmp_path / "run.meta.json", "journal": journal}[target]
    argv = ["run", "stationary", "--boiler", "windhager_12kw", "--rig", "modbus://127.0.0.1:1"]
    argv += ["--out", str(out), "--fault-journal", str(journal), "--fault-report", str(report)]
    assert main(argv) == 2  # before any connection
    err = capsys.readouterr().err
    assert err.startswith(f"hil-client: error: --fault-report: '{report}' is the")
    assert "which it would overwrite" in err and not out.exists()


def test_no_output_goes_into_the_installed_package(capsys):
    """A re-probe: ``balance --out`` replaced the shipped boiler file its --boiler NAME
    resolves to (and run --fault-report the shipped map): no output goes there."""
    from rig_emulator.boilers import BOILER_DIR
    from rig_emulator.cli import main as rig_main

    stray = BOILER_DIR / "reference.md"
    try:
        assert rig_main(["map-doc", "--out", str(stray)]) == 2
        assert "lies in the installed package" in capsys.readouterr().err
        assert not stray.exists()
    finally:
        stray.unlink(missing_ok=True)


@pytest.mark.parametrize("scheme", ["modbus", "modbus+tls"])
def test_a_rig_host_that_is_no_host_name_is_one_line(tmp_path, capsys, scheme):
    """A probe: ``--rig modbus://lab..local:5020`` ended in a 40-line traceback from the
    resolver (an empty label: Python's idna codec fails), exit 1."""
    out = _kept(tmp_path)
    argv = ["run", "stationary", "--boiler", "windhager_12kw", "--out", str(out)]
    _refused(capsys, [*argv, "--rig", f"{scheme}://lab..local:5020"], "'lab..local' is no host")
    # every label under 64 but 319 characters in all: no name the resolver takes (it was
    # sent to it, and the run waited on it)
    host = ".".join(["a" * 63] * 5)
    _refused(capsys, [*argv, "--rig", f"{scheme}://{host}:5020"], "319 characters, over 253")
    assert out.read_text() == KEPT


def test_a_protocol_named_with_a_comma_or_quotes_is_accepted(tmp_path):
    """A re-probe: "EN 303-5, stationary" as the protocol's name (or its test) was refused
    as "a field of the lab log", though the name and test go to the meta file only; a
    sequence's name, which the log's sequence column holds, still may not have one."""
    from hil_client.protocol.definition import load_protocol

    path = _protocol(
        tmp_path, lambda d: d.update(name='EN 303-5, "stationary"', test="stationary, nominal")
    )
    protocol = load_protocol(path)
    assert protocol.name == 'EN 303-5, "stationary"'
