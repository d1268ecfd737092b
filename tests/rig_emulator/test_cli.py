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


def test_serve_runs_logs_connections_and_stops_on_sigterm():
    import signal
    import subprocess
    import time

    from pyModbusTCP.client import ModbusClient

    from hil_client.demo import rig_emulator_serve

    with rig_emulator_serve("windhager_12kw", "--lockstep", stderr=subprocess.PIPE) as (port, proc):
        client = ModbusClient(host="127.0.0.1", port=port, unit_id=100, timeout=2)
        assert client.read_input_registers(0, 4) == [0, 0, 0, 0]  # sim_time (float64)
        client.close()
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=30)[1].decode()
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
