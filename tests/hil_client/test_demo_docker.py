"""The demo pipeline, the live view and the docker-compose file."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hil_client.cli import _build_parser as client_parser
from hil_client.cli import main
from hil_client.demo import main as demo_main
from hil_client.wait_for_port import main as wait_main
from hil_client.wait_for_port import wait_for_port
from rig_emulator.cli import _build_parser as emulator_parser

REPO = Path(__file__).resolve().parents[2]
SHORT = str(REPO / "tests" / "data" / "short_protocol.yaml")


def test_demo_runs_through_modbus_and_writes_the_report(tmp_path, capsys):
    assert demo_main([str(tmp_path), "--protocol", SHORT]) == 0
    out = capsys.readouterr().out
    assert "results in" in out
    for name in (
        "short_protocol.csv",
        "short_protocol.meta.json",
        "report.md",
        "fig7_energy_temperatures.png",
        "server.log",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    assert (tmp_path / "fig7_energy_temperatures.png").read_bytes()[:4] == b"\x89PNG"
    report = (tmp_path / "report.md").read_text()
    assert "Energy balance" in report and "fig7_energy_temperatures.png" in report
    assert "connected" in (tmp_path / "server.log").read_text()


def test_live_view_updates_in_place(tmp_path, capsys):
    import io

    from hil_client.progress import LiveView
    from hil_client.protocol.runner import LOG_COLUMNS

    out = tmp_path / "live.csv"
    assert main(["run", SHORT, "--boiler", "windhager_6kw", "--out", str(out), "--live"]) == 0
    err = capsys.readouterr().err
    assert "phase cooling_2" in err and "done in" in err  # the final state is shown
    stream = io.StringIO()
    view = LiveView(3600.0, stream, interval_s=0.0)
    row = tuple(1.0 for _ in LOG_COLUMNS)
    view((10.0, "test", "peak", *row[3:]))
    view((11.0, "test", "peak", *row[3:]))
    text = stream.getvalue()
    assert text.count("\x1b[5F") == 1  # the second frame moved the cursor up over the first
    assert "sequence peak" in text and "simulated 00:00:11" in text


def test_compose_services_use_the_same_cli():
    compose = yaml.safe_load((REPO / "docker-compose.yml").read_text())
    services = compose["services"]
    assert set(services) == {"emulator", "client"}
    emulator = services["emulator"]["command"]
    assert emulator[:2] == ["rig-emulator", "serve"]
    args = emulator_parser().parse_args(emulator[1:])  # valid for the real parser
    assert (args.host, args.port, args.lockstep) == ("0.0.0.0", 5020, True)
    assert services["emulator"]["ports"] == ["127.0.0.1:5020:5020"]  # loopback only
    client = " ".join(services["client"]["command"][-1].split())
    wait, run = client.split(" && ")
    assert wait == "python -m hil_client.wait_for_port emulator 5020 --timeout 120"
    run_args = client_parser().parse_args(run.split()[1:])
    assert run_args.rig == "modbus://emulator:5020" and run_args.protocol == "load_cycle"
    assert services["client"]["depends_on"]["emulator"]["condition"] == "service_healthy"
    assert "./out:/out" in services["client"]["volumes"]
    assert (REPO / "Dockerfile").read_text().startswith("#")


def test_compose_tls_variant_uses_the_same_cli():
    base = yaml.safe_load((REPO / "docker-compose.yml").read_text())["services"]
    services = yaml.safe_load((REPO / "docker-compose.tls.yml").read_text())["services"]
    emulator = emulator_parser().parse_args(services["emulator"]["command"][1:])
    assert (emulator.port, emulator.tcp_port) == (802, 5020)
    assert emulator.tls_ca == "/certs/ca.pem" and emulator.tls_cert == "/certs/server.pem"
    # the base health check still finds plain TCP on 5020 inside the container
    assert "5020" in " ".join(base["emulator"]["healthcheck"]["test"])
    assert services["emulator"]["ports"] == ["802:802"]
    client = " ".join(services["client"]["command"][-1].split())
    wait, run = client.split(" && ")
    assert wait == "python -m hil_client.wait_for_port emulator 802 --timeout 120"
    run_args = client_parser().parse_args(run.split()[1:])
    assert run_args.rig == "modbus+tls://emulator:802"
    assert str(run_args.tls_cert) == "/certs/engineer.pem"


def test_wait_for_port(capsys):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        assert wait_main(["127.0.0.1", str(s.getsockname()[1]), "--timeout", "5"]) == 0
    assert wait_main(["127.0.0.1", "1", "--timeout", "0.3"]) == 1
    assert "not reachable" in capsys.readouterr().err
    assert not wait_for_port("127.0.0.1", 1, 60.0, alive=lambda: False)  # gives up at once


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--boiler", "nosuch"], "--boiler: unknown boiler 'nosuch'"),
        # before a server is started for it (it started one, then failed: a stranger's probe)
        (["--protocol", "nosuch"], "--protocol: unknown protocol 'nosuch'"),
        (["IN_A_FILE/sub"], "out_dir: cannot make"),
    ],
)
def test_the_demo_refuses_bad_input_in_one_line(tmp_path, capsys, argv, message):
    """No traceback for a mistyped boiler or an out_dir under a file (both gave one)."""
    (tmp_path / "afile").write_text("")
    argv = [a.replace("IN_A_FILE", str(tmp_path / "afile")) for a in argv]
    if argv[0].startswith("--"):
        argv = [str(tmp_path / "out"), *argv]
    with pytest.raises(SystemExit) as info:
        demo_main(argv)
    err = capsys.readouterr().err
    assert info.value.code == 2 and message in err and "Traceback" not in err


def test_the_demo_report_says_why_its_balance_leaves_a_figure_unknown(run_log, tmp_path):
    """A re-probe: once the balance's warnings went to standard error, the demo's report
    showed "-" in its table without a word; it gives the reasons under the table."""
    import argparse
    import csv

    from hil_client.demo import REPORT, _report

    rec = run_log("stationary", "windhager_12kw")
    with rec.path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    o2 = rows[0].index("flue_gas_O2_pct")
    for row in rows[1:]:
        row[o2] = ""  # the analyser gave nothing
    with (tmp_path / "log.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    meta = rec.path.with_name(rec.path.stem + ".meta.json")
    (tmp_path / "log.meta.json").write_text(meta.read_text())
    args = argparse.Namespace(boiler="windhager_12kw", protocol="stationary", speed=1.0)
    _report(args, tmp_path, "log.csv", 5020, ["--lockstep"])
    report = (tmp_path / REPORT).read_text()
    assert "warning: column 'flue_gas_O2_pct' has no readings" in report
