"""``rig-emulator`` commands available before the Modbus server."""

import pytest

from rig_emulator.cli import main


def test_steady_prints_the_energy_split(capsys):
    assert main(["steady", "--boiler", "windhager_12kw", "--load", "100"]) == 0
    out = capsys.readouterr().out
    assert "Q_water" in out and "85." in out  # about 85 % to water (Section 3.2.1)


def test_check_prints_parameters(capsys):
    assert main(["check", "--boiler", "windhager_6kw"]) == 0
    assert "dt_nom_K: 42.15" in capsys.readouterr().out


@pytest.mark.parametrize(
    "args", [["steady", "--boiler", "nope"], ["steady", "--boiler", "windhager_6kw", "--load", "0"]]
)
def test_bad_input_exit_2(capsys, args):
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig-emulator: error:") and err.count("\n") == 1


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_runs_logs_connections_and_stops_on_sigterm():
    import signal
    import subprocess
    import sys
    import time

    from pyModbusTCP.client import ModbusClient

    port = _free_port()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rig_emulator.cli",
            "serve",
            "--boiler",
            "windhager_12kw",
            "--port",
            str(port),
            "--lockstep",
        ],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        client = ModbusClient(host="127.0.0.1", port=port, unit_id=100, timeout=2)
        deadline = time.monotonic() + 60
        regs = None
        while regs is None and time.monotonic() < deadline:
            regs = client.read_input_registers(0, 4)  # sim_time (float64)
            if regs is None:
                time.sleep(0.2)
        assert regs == [0, 0, 0, 0]
        client.close()
        time.sleep(0.3)
    finally:
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0
    assert f"serving windhager_12kw on 127.0.0.1:{port} (lockstep" in err
    assert "connected (1 open)" in err and "disconnected" in err
    assert "stopping at simulated time" in err
    assert "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--map", "nope.yaml"], "nope.yaml: cannot read"),
        (["--profile", "nope"], "unknown profile 'nope'"),
        (["--speed", "-3"], "--speed"),
        (["--port", "70000"], "--port"),
    ],
)
def test_serve_refuses_bad_input_with_exit_2(capsys, args, message):
    assert main(["serve", "--boiler", "windhager_12kw", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_map_doc_writes_the_reference(tmp_path):
    out = tmp_path / "map.md"
    assert main(["map-doc", "--out", str(out)]) == 0
    assert "## Unit 2: `flue_gas_analyser`" in out.read_text()
