"""The run summary of ``hil-client run`` against a real ``rig-emulator serve --lockstep``
with instrument faults (CONTRACT section 5): a missing reading and a balance glitch."""

from __future__ import annotations

import math

import pytest

from hil_client.cli import main
from hil_client.protocol.runner import LOG_COLUMNS
from hil_client.summary import RunSummary
from tests.hil_client.test_modbus_client_window import PROTOCOL


def _run(serve_process, tmp_path, faults: str, capsys) -> tuple[int, str, str]:
    (tmp_path / "faults.yaml").write_text(f"faults:\n{faults}")
    server = serve_process(
        "--boiler", "windhager_12kw", "--lockstep", "--faults", str(tmp_path / "faults.yaml")
    )
    protocol = tmp_path / "quick.yaml"
    protocol.write_text(PROTOCOL)
    code = main(
        ["run", str(protocol), "--boiler", "windhager_12kw", "--out", str(tmp_path / "log.csv"),
         "--rig", f"modbus://127.0.0.1:{server.port}"]
    )  # fmt: skip
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_a_missing_reading_and_a_balance_glitch_print_no_nan_and_no_empty_store(
    serve_process, tmp_path, capsys
):
    """A stranger's probe: one missing forward reading made the phase's heat to water
    ``nan kWh`` (the sum took NaN), and one balance reading of -0.001 kg (0xFFFFFFFF)
    between 180-kg readings was "the pellet store ran empty"."""
    code, out, err = _run(
        serve_process,
        tmp_path,
        "  - {kind: dropout, signal: water_out_temp_C, at_s: 70, for_s: 1}\n"
        "  - {kind: spike, signal: balance_mass_kg, value: -0.001, at_s: 80}\n",
        capsys,
    )
    assert code == 0, err
    table = out[out.index("phase ") : out.index("simulated ")]
    assert "nan" not in table and "inf" not in table, table
    assert "ran empty" not in err + out
    # the row without a forward reading is named, with its phase's rows
    notes = [line for line in table.splitlines() if "heat to water leaves out" in line]
    assert len(notes) == 1 and "leaves out 1 of its" in notes[0], table
    heat = [line.split()[2] for line in table.splitlines()[1:] if not line.startswith("note")]
    assert all(math.isfinite(float(x)) for x in heat), table


def test_a_store_that_really_runs_empty_is_still_said(serve_process, tmp_path, capsys):
    """The balance reading stays below 0 kg (an offset of -300 kg on its 250 kg from 80 s
    on): the pellet store ran empty, said as before."""
    code, _, err = _run(
        serve_process,
        tmp_path,
        "  - {kind: offset, signal: balance_mass_kg, value: -300, at_s: 80}\n",
        capsys,
    )
    assert code == 0, err
    assert "the pellet store ran empty" in err


def _row(t: float, mass: float, forward: float = 70.0) -> tuple:
    values = dict.fromkeys(LOG_COLUMNS, 0.0)
    values.update(time_s=t, phase="test", balance_mass_kg=mass, water_flow_kg_h=600.0)
    values.update(water_in_temp_C=55.0, water_out_temp_C=forward, boiler_water_temp_C=70.0)
    return tuple(values[name] for name in LOG_COLUMNS)


@pytest.mark.parametrize(
    ("masses", "empty_at"),
    [
        ([180.0, 180.0, -0.001, 180.0, 180.0], None),  # a glitch: no empty store, no refill
        ([0.2, -0.1, 180.0, -0.001], None),  # the last reading alone: unconfirmed
        ([0.2, 0.0, -0.1, -0.2], 3.0),  # stays below: empty from the first below 0
        ([0.2, -0.1, 0.0, 0.0], 2.0),  # at 0 after it: empty too
    ],
)
def test_a_reading_below_zero_is_an_empty_store_only_when_the_next_stays(masses, empty_at):
    summary = RunSummary()
    for i, mass in enumerate(masses):
        summary(_row(float(i + 1), mass))
    assert summary.empty_at_s == empty_at
    if empty_at is None and masses[0] == 180.0:  # (the rise back was taken as a refill)
        assert summary.phases["test"].fuel_kg == pytest.approx(0.0)


def test_an_infinite_heat_reading_is_skipped_never_printed():
    """An infinite forward temperature (a float32 register's +Inf, which a device may
    serve) gave ``inf kWh`` (a stranger's probe)."""
    summary = RunSummary()
    for i, forward in enumerate([70.0, math.inf, math.nan, 70.0]):
        summary(_row(float(i + 1), 180.0, forward))
    table = summary.table()
    assert "nan" not in table and "inf" not in table, table
    assert "leaves out 2 of its 4 rows" in table
    # 600 kg/h heated 15 K for the 2 rows read, 1 s each (Eq. 7 with water's cp near 4.19)
    assert summary.phases["test"].heat_to_water_kWh == pytest.approx(
        2 * 600 / 3600 * 4.19 * 15 / 3600, rel=0.01
    )
