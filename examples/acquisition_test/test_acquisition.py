"""The acquisition script (``acquire.py``, pyModbusTCP) against every fault kind, with the
``rig_emulator`` fixture of the project's pytest plugin: a lockstep emulator per test,
stepped one second between rows, faults set through the wire, truth read from the plant.

This is how a lab tests its own acquisition software in CI (see the README).
"""

from __future__ import annotations

import csv
import math

import pytest
from acquire import ANALYSER_COLUMNS, Acquisition


def _start_boiler(rig) -> None:
    rig.write("water_flow_setpoint_kg_h", 600.0)
    rig.write("return_setpoint_C", 55.0)
    rig.write("boiler_command", 1)
    rig.advance(600)  # firing: temperatures and the balance move


def _acquire(rig, rows: int, tmp_path, timeout_s: float = 0.5) -> list[dict]:
    acquisition = Acquisition(rig.host, rig.port, timeout_s=timeout_s)
    return acquisition.run(str(tmp_path / "acq.csv"), rows, lambda: rig.advance(1))


def test_no_fault_every_column_is_filled(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rows = _acquire(rig_emulator, 5, tmp_path)
    assert all(row["errors"] == "" for row in rows)
    assert all(value is not None for row in rows for value in row.values() if value != "")
    with open(tmp_path / "acq.csv") as fh:
        assert len(list(csv.DictReader(fh))) == 5


def test_no_reply_leaves_the_units_columns_empty(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "no_reply", "unit": 2, "at_s": 603, "for_s": 3})
    rows = _acquire(rig_emulator, 8, tmp_path)
    for row in rows:
        silent = 603 <= row["sim_time_s"] < 606
        assert (row["errors"] == "2:timeout") == silent, row
        assert all((row[c] is None) == silent for c in ANALYSER_COLUMNS), row
        assert row["water_out_temp_C"] is not None  # other units answer


@pytest.mark.parametrize(("delay_ms", "lost"), [(200, False), (1500, True)])
def test_delay_is_late_or_a_timeout(rig_emulator, tmp_path, delay_ms, lost):
    _start_boiler(rig_emulator)
    # set at t = 600 for 3 s: the rows at 601 and 602 are acquired while it acts
    rig_emulator.inject({"kind": "delay", "unit": 5, "delay_ms": delay_ms, "for_s": 3})
    rows = _acquire(rig_emulator, 4, tmp_path)
    balance = [row["balance_mass_kg"] is None for row in rows]
    assert balance == ([True, True, False, False] if lost else [False] * 4)


@pytest.mark.parametrize(("unit", "code"), [(5, 6), (0, 11), (4, 4)])
def test_exception_is_logged_with_its_code(rig_emulator, tmp_path, unit, code):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "exception", "unit": unit, "code": code, "for_s": 3})
    first, second, third = _acquire(rig_emulator, 3, tmp_path)
    units = [1, 2, 4, 5, 6] if unit == 0 else [unit]
    expected = ";".join(
        f"{u}:exception {code:02d}" for u in units for _ in range(2 if u == 5 else 1)
    )
    assert first["errors"] == second["errors"] == expected
    assert third["errors"] == ""


def test_disconnect_is_survived(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "disconnect", "at_s": 602})
    rows = _acquire(rig_emulator, 5, tmp_path)
    assert [row["sim_time_s"] for row in rows] == [601.0, 602.0, 603.0, 604.0, 605.0]
    assert all(row["errors"] == "" for row in rows)  # reconnected, nothing lost
    assert all(row["flue_gas_O2_pct"] is not None for row in rows)


def test_stuck_reading_while_the_plant_moves(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "stuck", "signal": "flue_gas_temp_C", "for_s": 30})
    truth_before = rig_emulator.truth("flue_gas_temp_C")
    rows = _acquire(rig_emulator, 20, tmp_path)
    assert len({row["flue_gas_temp_C"] for row in rows}) == 1
    assert abs(rig_emulator.truth("flue_gas_temp_C") - truth_before) > 0.05  # it moved


def test_drift_grows_at_its_rate(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "drift", "signal": "water_out_temp_C", "rate_per_h": 360.0})
    rows = _acquire(rig_emulator, 30, tmp_path)
    error = rows[-1]["water_out_temp_C"] - rig_emulator.truth("water_out_temp_C")
    # 360 K/h for 30 s = 3 K; float32 on the wire: 1e-5 K
    assert error == pytest.approx(3.0, abs=1e-4)


def test_spike_is_one_row(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "spike", "signal": "flue_gas_O2_pct", "value": 25.0, "at_s": 605})
    rows = _acquire(rig_emulator, 10, tmp_path)
    assert [row["sim_time_s"] for row in rows if row["flue_gas_O2_pct"] == 25.0] == [605.0]


@pytest.mark.parametrize(
    ("signal", "flag"),
    [
        ("flue_gas_CO_ppm", "analyser_status"),  # float32: NaN, status bit 0 off, bit 2 on
        ("flue_gas_temp_C", None),  # int16: its invalid code 0x8000
        ("balance_mass_kg", "balance_stable"),  # int32: 0x80000000; not stable
    ],
)
def test_dropout_is_an_empty_field_and_the_instrument_says_so(rig_emulator, tmp_path, signal, flag):
    _start_boiler(rig_emulator)
    rig_emulator.advance(10)  # the balance has been stable a while
    rig_emulator.inject({"kind": "dropout", "signal": signal, "for_s": 4})
    rows = _acquire(rig_emulator, 5, tmp_path)
    assert [row[signal] is None for row in rows] == [True, True, True, False, False]
    assert all(row["errors"] == "" for row in rows)  # the unit answered: the reading is bad
    if flag == "analyser_status":
        assert [row[flag] for row in rows[:4]] == [4.0, 4.0, 4.0, 1.0]
    elif flag == "balance_stable":
        assert rows[0][flag] == 0.0


def test_offset_is_a_refill_of_the_balance(rig_emulator, tmp_path):
    _start_boiler(rig_emulator)
    rig_emulator.inject({"kind": "offset", "signal": "balance_mass_kg", "value": 15.0})
    rows = _acquire(rig_emulator, 3, tmp_path)
    jump = rows[-1]["balance_mass_kg"] - rig_emulator.truth("balance_mass_kg")
    assert jump == pytest.approx(15.0, abs=0.001)  # int32 at 1 g
    assert not math.isnan(jump)


@pytest.mark.rig_emulator(profile="lab_faulty", seed=3)
def test_lab_faulty_profile_never_breaks_the_script(rig_emulator, tmp_path):
    """Realistic random faults at a low rate over two simulated hours, one row a minute."""
    acquisition = Acquisition(rig_emulator.host, rig_emulator.port, timeout_s=0.3)
    rows = acquisition.run(str(tmp_path / "acq.csv"), 120, lambda: rig_emulator.advance(60))
    assert [row["sim_time_s"] for row in rows] == [60.0 * (i + 1) for i in range(120)]


@pytest.mark.parametrize("args", [["127.0.0.1", "five", "out.csv", "10"], ["h", "1", "o", "x"]])
def test_a_bad_number_on_the_command_line_is_one_line(args, capsys):
    """A probe: ``acquire.py 127.0.0.1 24412 out.csv abc`` ended in a traceback."""
    from acquire import main

    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("acquire.py: error: "), err
