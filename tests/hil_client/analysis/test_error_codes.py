"""Instruments' error codes inside the plausible ranges: all nines beyond a column's other
readings, and the codes a meta file declares, are missing, not readings."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.error_codes import (
    ALL_NINES,
    CodesError,
    all_nines_codes,
    declared_codes,
    nines_verdict,
)
from hil_client.analysis.logio import LogError, read_log
from hil_client.cli import main


def test_all_nines_beyond_their_neighbours_are_codes():
    flow = np.array([0.0, 512.3, 9999.0, 600.1, 9999.0, 598.7])
    assert all_nines_codes(flow).tolist() == [False, False, True, False, True, False]
    # a large boiler's real 9999 kg/h among readings of 9,100-10,450 stays a reading
    big = np.array([9100.0, 9999.0, 10450.0, 9800.0])
    assert not all_nines_codes(big).any()
    # a CO analyser that reads down to -200 ppm (a profile the emulator allows) and -999
    co = np.array([-200.0, -999.0, 35.0, 120.0, np.nan])
    assert all_nines_codes(co).tolist() == [False, True, False, False, False]
    # a column of nothing but nines: no reading to tell a code from (a barometer logging
    # whole hPa on a day at 999, a re-probe; or a sensor open all run, a stuck column the
    # analyses' checks name)
    assert not all_nines_codes(np.full(4, 999.0)).any()
    # ... nor between two levels: a meter at a whole 999 kg/h with its code 9999 in
    # between, or one at 9999 that read 999 a while (re-probes: taking the most common
    # value for the readings dropped the real ones of the second); said, not guessed
    steady = np.where(np.arange(20) % 10 == 5, 9999.0, 999.0)
    assert not all_nines_codes(steady).any()
    assert nines_verdict(steady)[1] == [999.0, 9999.0]
    assert nines_verdict(np.full(4, 999.0))[1] == [999.0] and nines_verdict(flow)[1] == []
    # the same with the pump's 0 first: every 999 lay beyond it, most of the column; kept
    # and said, and the 9999 a code (a re-probe: the whole column emptied)
    pumped = np.r_[0.0, steady]
    codes, kept = nines_verdict(pumped)
    assert np.flatnonzero(codes).tolist() == [6, 16] and kept == [999.0]
    # open for five minutes between readings of 120 and 125 C: the whole stretch
    flue = np.r_[np.full(200, 120.0), np.full(300, 999.9), np.full(200, 125.0)]
    assert all_nines_codes(flue).sum() == 300
    # ... but not for most of the log: a meter at 999 most of the run reads the same
    flue = np.r_[np.full(10, 120.0), np.full(300, 999.9), np.full(10, 125.0)]
    assert not all_nines_codes(flue).any() and nines_verdict(flue)[1] == [999.9]
    # as a float32 register carries 999.9, and as the client prints 9999.9 and -999.9
    # from one (%.4f, %.5f: a re-probe), and one decimal more
    coded = np.array([80.0, float(np.float32(999.9)), 9999.9004, 81.0, -999.90002, -9999.99])
    assert all_nines_codes(coded).tolist() == [False, True, True, False, True, True]
    # near misses are readings: 1000, 998, 99.9 (two nines), 9999.5
    near = np.array([20.0, 1000.0, 998.0, 99.9, 9999.5])
    assert not all_nines_codes(near).any()
    assert 99.99 not in ALL_NINES and 999.0 in ALL_NINES and -99999.0 in ALL_NINES


def test_real_readings_that_are_all_nines_stay_readings():
    """Re-probes of rules that dropped all nines beyond the column's other readings, or
    far from either neighbour: a start-up's CO peak of 999 ppm between 964 and 973 and a
    CO of 999 between 630 and 1259 (benchmark plants' logs), a barometer's 999.9 hPa
    after 1000.0 (99 % of the column)."""
    co = np.array([120.0, 640.0, 964.0, 999.0, 973.0, 972.0, 610.0])
    assert not all_nines_codes(co).any()
    # and on the way up, every 5 s (another benchmark plant's start-up)
    assert not all_nines_codes(np.array([0.0, 126.0, 630.0, 999.0, 1259.0, 1052.0])).any()
    pressure = np.r_[np.full(60, 1000.0), np.full(5000, 999.9)]
    assert not all_nines_codes(pressure).any()


COLUMNS = ["time_s", "water_flow_kg_h", "flue_gas_temp_C", "water_flow_setpoint_kg_h"]
NOT_READINGS = ["water_flow_setpoint_kg_h", "boiler_on", "phase"]


def _declared(declared, tmp_path, columns=COLUMNS, text=("phase",)):
    meta = {"missing_values": declared}
    return declared_codes(meta, columns, NOT_READINGS, text, tmp_path / "x.meta.json")


def test_declared_codes_for_every_reading_column_or_per_column(tmp_path):
    every = _declared([32767, -1], tmp_path)
    # never time_s, nor a command: a setpoint of 0 or -1 is no code (a re-probe: a
    # declaration of 0 emptied boiler_on, rig_epoch and the setpoint)
    assert set(every) == {"water_flow_kg_h", "flue_gas_temp_C"}
    assert every["water_flow_kg_h"].tolist() == [-1.0, 32767.0]  # sorted
    one = _declared({"flue_gas_temp_C": 0}, tmp_path)
    assert list(one) == ["flue_gas_temp_C"] and one["flue_gas_temp_C"].tolist() == [0.0]
    # named as the header spells it (the reader takes 'Flue_Gas_Temp_C' as the format's
    # name: a re-probe), a command when named, and an empty list (an exporter's: none)
    named = _declared(
        {"FLUE_gas_temp_C": -9, "water_flow_setpoint_kg_h": [], "water_flow_kg_h": []}, tmp_path
    )
    assert named["flue_gas_temp_C"].tolist() == [-9.0] and named["water_flow_kg_h"].size == 0
    assert _declared([], tmp_path)["water_flow_kg_h"].size == 0
    assert declared_codes({"boiler": "x"}, COLUMNS, NOT_READINGS, (), tmp_path / "x") == {}


@pytest.mark.parametrize(
    ("declared", "message"),
    [
        ({"water_flw_kg_h": -1}, "names column 'water_flw_kg_h', which the log does not have"),
        ({"time_s": 0}, "names 'time_s'"),
        ({"Phase": "x"}, "names 'Phase', a text column: it holds no readings"),
        (["-999"], "'-999' is not a finite number"),
        (True, "True' is not a finite number"),
        ([float("nan")], "is not a finite number"),
        (10**400, "is not a finite number"),
        ({"flue_gas_temp_C": [[1]]}, "of 'flue_gas_temp_C': '[1]' is not a finite number"),
    ],
)
def test_a_declaration_that_cannot_be_read_is_named(tmp_path, declared, message):
    with pytest.raises(CodesError, match=r"x\.meta\.json: 'missing_values'") as err:
        _declared(declared, tmp_path)
    assert message in str(err.value)


def _rewrite(src: Path, dst: Path, change: dict[str, dict[int, str]]) -> None:
    """Copy the log ``src`` to ``dst`` with fields replaced: column -> {row index: text}."""
    with open(src, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    for name, fields in change.items():
        j = header.index(name)
        for i, text in fields.items():
            rows[1 + i][j] = text
    with open(dst, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def test_codes_in_a_run_are_missing_and_the_balance_stands(run_log, tmp_path, capsys):
    """A stranger's probe: a flow of 9999 gave a direct efficiency of 115 %, a balance at
    -999 kg a fuel of 1,508 kg; a flue gas of 999.9 (a thermocouple open) and CO of -999
    ppm were readings too. With the codes missing the balance is the clean log's."""
    rec = run_log("stationary", "windhager_12kw")
    clean = tmp_path / "clean.csv"
    shutil.copy(rec.path, clean)
    shutil.copy(rec.path.with_name(rec.path.stem + ".meta.json"), tmp_path / "clean.meta.json")
    coded = tmp_path / "coded.csv"
    n = len(rec["time_s"])
    rows = range(n // 3, n // 3 + 300)  # five minutes of the test phase
    _rewrite(
        rec.path,
        coded,
        {
            "water_flow_kg_h": {i: "9999" for i in rows},
            "balance_mass_kg": {i: "-999" for i in rows},
            "flue_gas_temp_C": {i: "999.9" for i in rows},
            "flue_gas_CO_ppm": {i: "-999.0" for i in rows},
        },
    )
    shutil.copy(rec.path.with_name(rec.path.stem + ".meta.json"), tmp_path / "coded.meta.json")
    log = read_log(coded)
    for name in ("water_flow_kg_h", "balance_mass_kg", "flue_gas_temp_C", "flue_gas_CO_ppm"):
        assert np.isnan(log[name][list(rows)]).all(), name
        assert any(f"column '{name}': 300 reading(s)" in note for note in log.notes), log.notes
    results = {}
    for path in (clean, coded):
        assert main(["balance", str(path)]) == 0
        data = json.loads(path.with_name(path.stem + ".balance.json").read_text())
        results[path.stem] = next(r for r in data["balance"] if r["phase"] == "test")
    assert "error code" in capsys.readouterr().err
    # five minutes in about three hours, interpolated or skipped: within 1 % of the clean
    # log's figures (the codes had moved them by 30 % and by a factor of 100)
    for key in ("eta_direct", "eta_indirect", "fuel_as_received_kg"):
        assert results["coded"][key] == pytest.approx(results["clean"][key], rel=0.01), key


def test_declared_codes_in_the_meta_file_are_missing(tmp_path):
    path = tmp_path / "lab.csv"
    path.write_text(
        "time_s,water_flow_kg_h,flue_gas_temp_C,lab_note,water_flow_setpoint_kg_h\n"
        "0,600,120,-1,-1\n1,-1,121,-1,-1\n2,601,32767,-1,-1\n3,602,122,-1,-1\n"
    )
    required = ("time_s", "water_flow_kg_h", "flue_gas_temp_C")
    assert read_log(path, required)["water_flow_kg_h"][1] == -1.0  # undeclared: a reading
    meta = path.with_name("lab.meta.json")
    meta.write_text(json.dumps({"missing_values": [-1, 32767]}))
    log = read_log(path, required)
    assert np.isnan(log["water_flow_kg_h"][1]) and np.isnan(log["flue_gas_temp_C"][2])
    assert np.isnan(log["lab_note"]).all()  # the lab's own column too
    assert (log["water_flow_setpoint_kg_h"] == -1.0).all()  # a command: no code
    assert log["water_flow_kg_h"][[0, 2, 3]].tolist() == [600.0, 601.0, 602.0]
    meta.write_text(json.dumps({"missing_values": {"flue_gas_temp_C": 32767}}))
    log = read_log(path, required)
    assert log["water_flow_kg_h"][1] == -1.0 and np.isnan(log["flue_gas_temp_C"][2])
    meta.write_text(json.dumps({"missing_values": {"flue_gas_temp": 32767}}))
    with pytest.raises(LogError, match="names column 'flue_gas_temp', which the log"):
        read_log(path, required)


def test_a_bad_declaration_is_one_line_and_exit_2(run_log, tmp_path, capsys):
    rec = run_log("stationary", "windhager_12kw")
    path = tmp_path / "run.csv"
    shutil.copy(rec.path, path)
    meta = dict(rec.meta, missing_values={"water_flow": -1})
    path.with_name("run.meta.json").write_text(json.dumps(meta))
    assert main(["balance", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "names column 'water_flow'" in err, err
    assert not path.with_name("run.balance.json").exists()


def test_a_column_of_nothing_but_two_nines_levels_is_kept_and_said(tmp_path):
    path = tmp_path / "lab.csv"
    rows = [f"{i},{9999 if i % 10 == 5 else 999},120" for i in range(20)]
    path.write_text("time_s,water_flow_kg_h,flue_gas_temp_C\n" + "\n".join(rows) + "\n")
    log = read_log(path, ("time_s", "water_flow_kg_h"))
    assert np.isfinite(log["water_flow_kg_h"]).all()
    said = [n for n in log.notes if "all-nines values (999, 9999) that may be" in n]
    assert len(said) == 1 and "missing_values names codes" in said[0], log.notes
    # the meta file names 9999: the log can tell them apart now, and says nothing more (a
    # re-probe: "cannot tell apart; kept" and "taken as missing" of one column)
    path.with_name("lab.meta.json").write_text('{"missing_values": {"water_flow_kg_h": 9999}}')
    log = read_log(path, ("time_s", "water_flow_kg_h"))
    assert np.isnan(log["water_flow_kg_h"]).sum() == 2
    assert not any("may be" in n for n in log.notes), log.notes
