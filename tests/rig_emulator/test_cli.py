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
