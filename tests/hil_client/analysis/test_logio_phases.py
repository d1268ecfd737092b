"""Reading lab logs (bad input refused with a clear message) and finding phases."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import LogError, fill_gaps, read_log
from hil_client.analysis.phases import MARKS, find_phases, rise_rate_K_min
from hil_client.cli import main as hil_client_main

HEADER = (
    "time_s,water_flow_kg_h,water_in_temp_C,water_out_temp_C,boiler_water_temp_C,"
    "flue_gas_temp_C,flue_gas_O2_pct,balance_mass_kg,room_temp_C"
)


def _write(tmp_path, text: str):
    path = tmp_path / "log.csv"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time_s,water_flow_kg_h\n1,2\n", "missing required column 'water_in_temp_C'"),
        (
            HEADER + "\n1,1,1,1,1,1,1,1,1\n1,2,1,1,1,1,1,1,1\n",
            "'time_s' is not increasing at row 3 (1 -> 1) with other readings than the row",
        ),
        (HEADER + "\n2,1,1,1,1,1,1,1,1\n1,1,1,1,1,1,1,1,1\n", "not increasing at row 3 (2 -> 1)"),
        (HEADER + "\n1,1,1,1,1,x,1,1,1\n", "column 'flue_gas_temp_C' row 2: 'x' is not a number"),
        (HEADER + "\n1,1,1,1\n", "row 2 has 4 fields"),
        # a short row with rows after it is no cut-off write: refused wherever it is
        (HEADER + "\n1,1,1,1\n2,1,1,1,1,1,1,1,1", "row 2 has 4 fields"),
        (HEADER + "\n1,1,1,1,1,1,1,1,1\n2,1,1,1,1,1,1,1,1,9", "row 3 has 10 fields"),
        (HEADER + "\n", "no data rows"),
        ("", "empty file"),
        (HEADER + "\n,1,1,1,1,1,1,1,1\n", "column 'time_s' row 2 is empty"),
        (HEADER + "\n1,1,1,1,1,1,1,1,1\ninf,1,1,1,1,1,1,1,1\n", "'time_s' row 3: 'inf' is not"),
        # a spreadsheet's export in another locale: the separator is named, not a column
        (HEADER.replace(",", ";") + "\n1;1;1;1;1;1;1;1;1\n", "separated by semicolons"),
        (HEADER.replace(",", "\t") + "\n1\t1\t1\t1\t1\t1\t1\t1\t1\n", "separated by tabs"),
        # a column the format names holds readings: text there is refused
        (HEADER + ",boiler_on\n1,1,1,1,1,1,1,1,1,on\n", "column 'boiler_on' row 2: 'on'"),
    ],
)
def test_bad_logs_are_refused_naming_what_is_wrong(tmp_path, text, message):
    with pytest.raises(LogError) as info:
        read_log(_write(tmp_path, text))
    assert message in str(info.value) and "\n" not in str(info.value)


def test_a_row_written_twice_is_read_once_and_said(tmp_path):
    """A stranger's probe: a logger that wrote 200 rows twice (the same time and readings)
    had its log refused ("'time_s' is not increasing"), though reading each once loses
    nothing; a time repeated with other readings stays refused (above)."""
    rows = [f"{i},{i},1,1,1,1,1,{9 - i / 10},1" for i in range(1, 6)]
    twice = [rows[0], rows[1], rows[1], rows[2], rows[3], rows[3], rows[3], rows[4]]
    log = read_log(_write(tmp_path, HEADER + ",phase\n" + "\n".join(f"{r},test" for r in twice)))
    assert log["time_s"].tolist() == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert log["water_flow_kg_h"].tolist() == [1.0, 2.0, 3.0, 4.0, 5.0]
    assert log.text["phase"] == ["test"] * 5
    (note,) = log.notes
    assert "3 row(s) written twice" in note and "the first at row 4" in note, note


def test_a_last_row_cut_short_by_a_killed_acquisition_is_left_out_and_named(tmp_path, capsys):
    """A logger killed mid-write leaves its last row short and without a line end (its
    last field may be a number cut in two, 1.2 of 1.25): the row is left out, every
    complete row is kept, and the user is told in one line."""
    from hil_client.cli import _warn_tolerated

    full = "\n".join(f"{i},1,1,1,1,1,1,1,1" for i in range(1, 4))
    path = _write(tmp_path, HEADER + "\n" + full + "\n4,1,1,1.2")
    log = read_log(path)
    _warn_tolerated([log])
    assert log["time_s"].tolist() == [1.0, 2.0, 3.0]
    assert len(log.notes) == 1 and "line 5" in log.notes[0] and "4 of 9" in log.notes[0]
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "warning" in err and "cut short" in err


@pytest.mark.parametrize(
    ("last", "kept"),
    [
        ("231.84000", True),  # whole, only the final line end missing
        ("1000.00000", True),
        ("23", False),  # cut inside the number: 23 of 231.84000
        ("231.8", False),
        ("231.8400", False),
    ],
)
def test_a_last_row_without_a_line_end_is_kept_only_when_its_last_field_is_whole(
    tmp_path, last, kept
):
    """The last row has all its fields but no line end: the logger may have been killed
    inside its last field, whose cut number would be read as a wrong reading (a balance of
    23 kg instead of 231.84, a fuel power of 167 kW); a field shaped like the one above it
    is kept, a shorter one is left out and named."""
    rows = [f"{i},1,1,1,1,1,1,1,231.84{i}00" for i in range(1, 4)]
    path = _write(tmp_path, HEADER + "\n" + "\n".join(rows) + f"\n4,1,1,1,1,1,1,1,{last}")
    log = read_log(path)
    column = HEADER.split(",")[-1]
    if kept:
        assert log["time_s"].tolist() == [1.0, 2.0, 3.0, 4.0] and not log.notes
        assert log[column][-1] == float(last)
    else:
        assert log["time_s"].tolist() == [1.0, 2.0, 3.0]
        assert len(log.notes) == 1 and f"'{last}'" in log.notes[0] and "line 5" in log.notes[0]


def test_a_labs_own_text_column_is_kept_and_not_analysed(tmp_path):
    """CONTRACT section 3 lists the columns analyses read; a lab's own (an operator's note)
    is data beside them: it was refused ('ok' is not a number)."""
    log = read_log(
        _write(tmp_path, HEADER + ",operator_note\n1,1,1,1,1,1,1,1,1,ok\n2,1,1,1,1,1,1,1,1,\n")
    )
    assert log.text["operator_note"] == ["ok", ""] and len(log) == 2
    assert any("'operator_note' is text" in note for note in log.notes)


def test_a_spreadsheets_trailing_unnamed_columns_are_no_readings(tmp_path):
    """Excel writes empty columns after the last one it was given: two of them were
    refused as "column '' appears twice" (a stranger's probe). Unnamed columns are no
    readings; one that holds values is named in the notes."""
    rows = "\n".join(f"{i},1,1,1,1,1,1,1,1,," for i in range(1, 4))
    log = read_log(_write(tmp_path, HEADER + ",,\n" + rows + "\n"))
    assert "" not in log.columns and len(log) == 3 and not log.notes
    rows = "\n".join(f"{i},1,1,1,1,1,1,1,1,7," for i in range(1, 4))
    log = read_log(_write(tmp_path, HEADER + ",,\n" + rows + "\n"))
    assert log.notes == [f"{tmp_path / 'log.csv'}: column 10 has no name; not analysed"]
    # the header's trailing unnamed columns alone, the rows without them (a re-probe)
    rows = "\n".join(f"{i},1,1,1,1,1,1,1,1" for i in range(1, 4))
    log = read_log(_write(tmp_path, HEADER + ",,\n" + rows + "\n"))
    assert len(log) == 3 and not log.notes


def test_a_spreadsheets_byte_order_mark_is_not_part_of_the_first_name(tmp_path):
    """A CSV saved by a spreadsheet starts with a UTF-8 byte-order mark: its first column
    is still ``time_s`` (it was once refused as missing)."""
    full = "\n".join(f"{i},1,1,1,1,1,1,1,1" for i in range(1, 4))
    path = _write(tmp_path, "\ufeff" + HEADER + "\n" + full + "\n")
    assert read_log(path)["time_s"].tolist() == [1.0, 2.0, 3.0]


def test_a_byte_order_mark_before_windows_1252_text_and_on_the_meta_file(tmp_path):
    """A re-probe: a log that begins with UTF-8's byte-order mark but holds Windows-1252
    bytes further on (a note typed in a spreadsheet on Windows) read its first column as
    'ï»¿time_s' and was refused; a meta file saved with the mark was not JSON."""
    full = "\n".join(f"{i},1,1,1,1,1,1,1,1,Kessel w\xe4rmer" for i in range(1, 4))
    path = tmp_path / "log.csv"
    path.write_bytes(b"\xef\xbb\xbf" + (HEADER + ",note\n" + full + "\n").encode("cp1252"))
    path.with_name("log.meta.json").write_bytes(b"\xef\xbb\xbf" + b'{"test": "stationary"}')
    log = read_log(path)
    assert log["time_s"].tolist() == [1.0, 2.0, 3.0] and log.meta == {"test": "stationary"}
    assert log.text["note"][-1] == "Kessel w\u00e4rmer"
    assert any("read as Windows-1252" in note for note in log.notes)


def test_an_instruments_error_code_is_a_missing_reading_and_named(tmp_path):
    """-999 from a thermocouple amplifier or 1e30 from a logger's overflow is no
    temperature: read as one it would swamp every figure; it is missing, and the user is
    told which column and row. A fault report reads the log as it is."""
    rows = ["1,1,1,1,1,-999,1,1,1", "2,1,1,1,1,1e30,1,1,1", "3,1,1,1,1,1500,1,1,1"]
    path = _write(tmp_path, HEADER + "\n" + "\n".join(rows) + "\n")
    log = read_log(path)
    assert np.isnan(log["flue_gas_temp_C"][:2]).all() and log["flue_gas_temp_C"][2] == 1500.0
    assert len(log.notes) == 1
    assert "'flue_gas_temp_C': 2 reading(s)" in log.notes[0] and "row 2: '-999'" in log.notes[0]
    assert read_log(path, as_read=True)["flue_gas_temp_C"][1] == 1e30
    # an infinite reading is the same, in a column of any unit (here one with none)
    path = _write(tmp_path, HEADER + ",boiler_on\n" + "\n".join(r + ",inf" for r in rows))
    log = read_log(path)
    assert np.isnan(log["boiler_on"]).all() and "3 reading(s) not finite" in log.notes[-1]


def test_empty_fields_are_missing_values_and_can_be_filled(tmp_path):
    log = read_log(
        _write(tmp_path, HEADER + "\n1,1,,1,1,1,1,1,1\n2,1,3,1,1,1,1,1,1\n3,1,5,1,1,1,1,1,1\n")
    )
    assert np.isnan(log["water_in_temp_C"][0])
    filled = fill_gaps(np.array([1.0, np.nan, 3.0, np.nan]), np.array([0.0, 1.0, 2.0, 3.0]))
    assert filled.tolist() == [1.0, 2.0, 3.0, 3.0]


@pytest.mark.parametrize("step_s", [1.0, 40.0, 45.0, 120.0])
def test_rise_rate_of_a_known_ramp(step_s):
    """At any step: rows 40, 45 or 120 s apart never filled the 300-s window (the last
    within it 280 s back), so t1 was never found in a log of a real-time server at x400
    (a re-probe)."""
    t = np.arange(0.0, 2400.0, step_s)
    y = np.where(t < 1200, 0.02 * t, 24.0)  # 1.2 K/min, then flat
    rate = rise_rate_K_min(t, y)
    assert np.isnan(rate[np.searchsorted(t, 100.0)])
    assert rate[np.searchsorted(t, 1000.0)] == pytest.approx(1.2)
    assert rate[-1] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("protocol", ["stationary", "load_cycle"])
def test_phases_from_signals_match_the_runner(run_log, protocol, tmp_path):
    rec = run_log(protocol, "windhager_12kw")
    log = read_log(rec.path)
    from_column = find_phases(log)
    assert from_column.source == "phase column"
    assert from_column.as_dict() == {k: rec.meta[k] for k in from_column.as_dict()}
    signals = find_phases(log, prefer_signals=True)
    assert signals.source == "signals"
    # t0, t1, t3, t4 follow the runner's own rules exactly; t2 from the flow setpoint step
    assert signals.as_dict() == from_column.as_dict()
    # without the phase, setpoint and boiler_on columns (a real lab's CSV), from flow alone
    keep = [c for c in log.columns if c not in ("water_flow_setpoint_kg_h", "boiler_on")]
    bare = tmp_path / "bare.csv"
    data = np.column_stack([log[c] for c in keep])
    np.savetxt(bare, data, delimiter=",", header=",".join(keep), comments="", fmt="%.6f")
    found = find_phases(read_log(bare))
    assert found.source == "signals"
    for key, value in from_column.as_dict().items():
        # the flow meter's 10 s lag and the burner seen through the flue gas: within 1 min
        assert found.as_dict()[key] == pytest.approx(value, abs=60), key


def test_a_record_cut_in_its_first_cooling_ends_that_cooling_and_says_so(run_log, tmp_path):
    """An acquisition killed 10 min before the circulation stops (a real lab's CSV, no
    phase or setpoint column): t0 to t2 as in the whole record, the first cooling ends
    with the last row, and the log's notes say that no second cooling was recorded."""
    rec = run_log("stationary", "windhager_12kw")
    log = read_log(rec.path)
    keep = [c for c in log.columns if c not in ("phase", "sequence", "water_flow_setpoint_kg_h")]
    rows = log.t <= rec.meta["t3_s"] - 600.0
    cut = tmp_path / "cut.csv"
    data = np.column_stack([log[c][rows] for c in keep])
    np.savetxt(cut, data, delimiter=",", header=",".join(keep), comments="", fmt="%.6f")
    short = read_log(cut)
    found = find_phases(short)
    for key in ("t0_s", "t1_s", "t2_s"):
        # as from the whole record without these columns: within the flow meter's lag
        assert found.as_dict()[key] == pytest.approx(rec.meta[key], abs=60), key
    assert found.t3 == found.t4 == pytest.approx(short.t[-1])
    assert any("no second cooling" in note for note in short.notes)


def test_a_meta_file_nested_thousands_deep_is_one_line(tmp_path):
    path = _write(tmp_path, HEADER + "\n1,1,1,1,1,1,1,1,1\n2,1,1,1,1,1,1,1,1\n")
    path.with_name(path.stem + ".meta.json").write_text('{"a": ' + "[" * 3000 + "]" * 3000 + "}")
    with pytest.raises(LogError, match="nested too deeply"):
        read_log(path)


def test_marks_an_interrupted_run_did_not_reach_are_unknown_not_errors(run_log, tmp_path):
    """An interrupted run writes ``null`` for the marks it did not reach (CONTRACT section 3:
    "where known"); every analysis refused its own client's meta file for it ("t1_s = None
    is not a finite number of seconds; remove t0_s..t4_s"). Null is unknown: the phases come
    from the signals where they show them, and a run cut before a whole test is named so."""
    import json

    rec = run_log("stationary", "windhager_12kw")
    log = read_log(rec.path)
    keep = [c for c in log.columns if c not in ("phase", "sequence")]

    def write(rows: np.ndarray, name: str, reached: tuple[str, ...]) -> Path:
        path = tmp_path / f"{name}.csv"
        data = np.column_stack([log[c][rows] for c in keep])
        np.savetxt(path, data, delimiter=",", header=",".join(keep), comments="", fmt="%.6f")
        marks = {k: (rec.meta[k] if k in reached else None) for k in MARKS}
        path.with_name(f"{name}.meta.json").write_text(json.dumps(marks))
        return path

    whole = write(log.t >= 0, "whole", ("t0_s", "t1_s"))  # marks lost, the record whole
    found = find_phases(read_log(whole))
    assert found.source == "signals"
    assert found.t2 == pytest.approx(rec.meta["t2_s"], abs=60)
    cut = write(log.t <= rec.meta["t0_s"] + 600.0, "cut", ("t0_s",))  # killed in start-up
    with pytest.raises(LogError, match=r"the run was cut short .*records t0_s, the rest not"):
        find_phases(read_log(cut))
    # what the balance takes: the phases it recorded, the one cut in ending at its last row
    partial = find_phases(read_log(cut), partial=True)
    assert (partial.t0, partial.reached, partial.cut_in) == (rec.meta["t0_s"], 1, "start_up")
    assert partial.t1 == partial.t4 == log.t[log.t <= rec.meta["t0_s"] + 600.0][-1]
    assert partial.as_dict() == {"t0_s": rec.meta["t0_s"]} | dict.fromkeys(MARKS[1:])
    # cut in a cooling: the marks it recorded, not the signals' guess at the rest (the
    # signals had put t3 and t4 at its last row; a re-probe)
    cooling = write(log.t <= rec.meta["t2_s"] + 600.0, "cooling", ("t0_s", "t1_s", "t2_s"))
    partial = find_phases(read_log(cooling), partial=True)
    assert (partial.reached, partial.cut_in, partial.t2) == (3, "cooling_1", rec.meta["t2_s"])
    assert partial.as_dict()["t3_s"] is None
    # a mark after a null, or none at all, is no record of a run cut short
    gapped = write(log.t <= rec.meta["t1_s"] + 600.0, "gapped", ("t0_s", "t2_s"))
    with pytest.raises(LogError):
        find_phases(read_log(gapped), partial=True)
    # on a whole record the signals find the phases, and the unused marks are said (they
    # were dropped without a word)
    gapped_whole = read_log(write(log.t >= 0, "gapped_whole", ("t0_s", "t2_s", "t3_s")))
    assert find_phases(gapped_whole).source == "signals"
    said = [n for n in gapped_whole.notes if "given after t1_s = null" in n]
    assert len(said) == 1 and "t2_s, t3_s" in said[0], gapped_whole.notes


def test_a_log_of_two_plants_is_analysed_on_one(run_log, tmp_path, capsys):
    """A run that went on after a break (``--on-restart continue``: a restarted server, a
    time jump, ``rig_epoch`` one higher) holds two plants; the analyses joined them as if
    continuous (a stranger's validate: start-up fuel +80 %, r = 0). Now they read the
    longest plant's rows and say so."""
    from hil_client.analysis.logio import one_plant
    from hil_client.cli import main

    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    header = lines[0].split(",")
    i_time, i_epoch = header.index("time_s"), header.index("rig_epoch")
    rows = [line.split(",") for line in lines[1:]]
    cut = 3000  # the first plant's rows; the second starts 600 s later (the outage)
    for row in rows[cut:]:
        row[i_time] = f"{float(row[i_time]) + 600.0:.3f}"
        row[i_epoch] = "1"
    two = tmp_path / "two.csv"
    two.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    log = one_plant(read_log(two))
    assert len(log) == len(rows) - cut and np.all(log["rig_epoch"] == 1)
    assert log.t[0] == pytest.approx(float(rows[cut][i_time]))
    assert main(["balance", str(two), "--boiler", "windhager_12kw"]) == 0
    err = capsys.readouterr().err
    assert "holds 2 plants" in err and "only rig_epoch 1" in err
    single = one_plant(read_log(rec.path))  # one plant: the log as it is
    assert len(single) == len(rows) and not single.notes


def test_a_later_plant_in_the_start_up_starts_up_from_its_first_row(run_log, tmp_path):
    """A stranger's probe: a run that went on (``--on-restart continue``) after a break in
    its start-up, cut short in its test: the later plant's rows hold the run's t1, not its
    t0, and balance refused ("cannot find t1") though the meta file records t1. Its rows
    start up from their first on; a later plant that begins in a later phase (the test
    restarted there) takes its phases from its rows, with no note blaming the meta file or
    the phase column for marks the slicing left out."""
    import json

    from hil_client.analysis.logio import one_plant

    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    header = lines[0].split(",")
    i_time, i_epoch = header.index("time_s"), header.index("rig_epoch")
    rows = [line.split(",") for line in lines[1:]]
    t = np.array([float(r[i_time]) for r in rows])
    for name, at_s in (
        ("in_start_up", 0.5 * (rec.meta["t0_s"] + rec.meta["t1_s"])),
        ("in_test", rec.meta["t1_s"] + 600.0),
    ):
        cut = int(np.searchsorted(t, at_s))
        shifted = [list(r) for r in rows]
        for row in shifted[cut:]:
            row[i_time] = f"{float(row[i_time]) + 600.0:.3f}"
            row[i_epoch] = "1"
        path = tmp_path / f"{name}.csv"
        path.write_text("\n".join([lines[0], *(",".join(r) for r in shifted)]) + "\n")
        marks = {k: rec.meta[k] + (600.0 if rec.meta[k] > at_s else 0.0) for k in MARKS}
        marks.update(dict.fromkeys(("t2_s", "t3_s", "t4_s")))  # cut short in its test
        path.with_name(f"{name}.meta.json").write_text(json.dumps(marks))
        log = one_plant(read_log(path))
        phases = find_phases(log, partial=True)
        if name == "in_start_up":
            assert phases.source.startswith("meta file")
            assert phases.t0 == log.t[0] and phases.t1 == marks["t1_s"]
            assert phases.cut_in == "test"
        else:
            assert phases.source == "signals"
        stray = [n for n in log.notes if "given after" in n or "holds no" in n]
        assert not stray, stray


_BASE = (
    "time_s,phase,water_flow_kg_h,water_in_temp_C,water_out_temp_C,boiler_water_temp_C,"
    "flue_gas_temp_C,flue_gas_O2_pct,balance_mass_kg,room_temp_C\n"
    "1,preheat,300,50,60,60,150,8,250,20\n"
    "2,start_up,300,50,60.5,60,151,8,249.99,20\n"
    "3,start_up,300,50,61,60.5,152,8,,20\n"
)


_NO_READING_NOTE = "column 'balance_mass_kg': 1 field(s) written as no reading (first row 4: '{}')"


@pytest.mark.parametrize(
    ("variant", "note"),
    [
        (lambda t: t + ",,,,,,,,,\n,,,,,,,,,\n", None),  # Excel's rows of empty fields
        (lambda t: t.replace("time_s,phase", "TIME_S,Phase", 1), "'TIME_S' as 'time_s'"),
        (lambda t: "# bench 3, operator JS\n# exported\n" + t, "line 1 (a comment)"),
        (lambda t: "sep=,\n" + t, "line 1 (sep=) before the header"),
        (lambda t: t.replace("preheat", "vorwärmen"), "read as Windows-1252"),
        # Excel's, R's and pandas', SQL's no reading, a dash: read as such, and said (a
        # stranger's probe: NA, NaN, null, '-' went silently, where inf was said)
        (lambda t: t.replace(",,20\n", ",#N/A,20\n"), _NO_READING_NOTE.format("#N/A")),
        (lambda t: t.replace(",,20\n", ",#div/0!,20\n"), _NO_READING_NOTE.format("#div/0!")),
        (lambda t: t.replace(",,20\n", ",NA,20\n"), _NO_READING_NOTE.format("NA")),
        (lambda t: t.replace(",,20\n", ",-,20\n"), _NO_READING_NOTE.format("-")),
        (lambda t: t.replace(",,20\n", ",null,20\n"), _NO_READING_NOTE.format("null")),
        (lambda t: t.replace(",,20\n", ",NaN,20\n"), _NO_READING_NOTE.format("NaN")),
        (lambda t: t.replace("\n2,", "\n# operator: flow check\n2,") + "# end\n", "2 comment"),
        (lambda t: ",,,,\n" + t, None),  # a row of empty fields above the header
    ],
    ids=[
        "empty-rows",
        "letter-case",
        "comments",
        "sep-line",
        "windows-1252",
        "n-a",
        "div0",
        "NA",
        "dash",
        "null",
        "NaN",
        "comments-among-rows",
        "empty-row-on-top",
    ],
)
def test_spreadsheet_exports_read_as_the_log_they_hold(tmp_path, variant, note):
    """What spreadsheets do to a CSV was refused, some with a wrong reason ("missing
    required column 'time_s'" for a header in capitals or under a comment; a stranger's
    probe). Each reads as the log it holds, and what was done is said in the notes."""
    base, other = tmp_path / "base.csv", tmp_path / "other.csv"
    base.write_text(_BASE)
    encoding = "cp1252" if "vorw" in variant(_BASE) else "utf-8"
    other.write_bytes(variant(_BASE).encode(encoding))
    a, b = read_log(base), read_log(other)
    assert a.columns.keys() == b.columns.keys()
    for name in a.columns:
        assert np.array_equal(a[name], b[name], equal_nan=True), name
    assert (note is None and not b.notes) or any(note in n for n in b.notes), b.notes


def test_what_is_no_lab_log_is_refused_in_a_line_that_shows_it(tmp_path):
    """A device streams forever (balance /dev/zero ran until killed); NUL bytes in a field
    went raw into the message; a byte that is no text names the line."""
    with pytest.raises(LogError, match="not a regular file"):
        read_log(Path("/dev/zero"))
    # beside a log: a FIFO hung the reader, /dev/zero ran out of memory (a re-probe)
    beside = tmp_path / "beside.csv"
    beside.write_text(_BASE)
    os.mkfifo(tmp_path / "beside.meta.json")
    with pytest.raises(LogError, match=r"beside\.meta\.json: not a regular file"):
        read_log(beside)
    (tmp_path / "beside.meta.json").unlink()
    (tmp_path / "beside.meta.json").symlink_to("/dev/zero")
    with pytest.raises(LogError, match=r"beside\.meta\.json: not a regular file"):
        read_log(beside)
    nul = tmp_path / "nul.csv"
    nul.write_text(_BASE.replace("151,", "1" + "\0" * 4096 + ",", 1))
    with pytest.raises(LogError) as info:
        read_log(nul)
    message = str(info.value)
    assert "\0" not in message and len(message) < 300 and "line 3 holds NUL bytes" in message
    from hil_client.analysis.logio import _shown  # a field shown in a message, beyond that

    assert _shown("1" + "\0" * 4096) == "1" + "\\x00" * 9 + "..."
    utf16 = tmp_path / "utf16.csv"
    utf16.write_bytes(_BASE.encode("utf-16"))  # with its byte-order mark: read as such
    assert np.array_equal(read_log(utf16).t, [1.0, 2.0, 3.0])
    utf16.write_bytes(_BASE.encode("utf-16-le"))  # without: named, not "missing 'time_s'"
    with pytest.raises(LogError, match="line 1 holds NUL bytes: UTF-16 without its"):
        read_log(utf16)
    loop = tmp_path / "loop.csv"  # (said to be no such file: a stranger's probe)
    loop.symlink_to(loop)
    with pytest.raises(LogError, match="a symbolic link that leads to no file"):
        read_log(loop)
    na_time = tmp_path / "na_time.csv"  # #N/A in time_s is no comment line: refused
    na_time.write_text(_BASE.replace("\n2,", "\n#N/A,", 1))
    with pytest.raises(LogError, match="column 'time_s' row 3: '#N/A' is no time"):
        read_log(na_time)
    na_time.write_text(_BASE.replace("\n2,", "\nNaN,", 1))  # (not "row 3 is empty": a probe)
    with pytest.raises(LogError, match="column 'time_s' row 3: 'NaN' is no time"):
        read_log(na_time)
    both = tmp_path / "both.csv"
    both.write_text(_BASE.replace("phase,", "TIME_S,", 1).replace(",preheat,", ",0,"))
    with pytest.raises(LogError, match="'time_s' and 'TIME_S' differ only in letter case"):
        read_log(both)
    binary = tmp_path / "binary.csv"
    binary.write_bytes(_BASE.encode() + b"\x81\x8d\x8f\x90\x9d\n")
    with pytest.raises(LogError, match=r"line 5: byte 0x81 is neither UTF-8 nor Windows-1252"):
        read_log(binary)


def test_marks_of_another_log_within_the_record_are_refused(run_log, tmp_path, capsys):
    """A stationary log without its phase column, beside the load cycle's meta file (its
    marks inside the record): the test ran two hours past the burner's last firing, with
    confident figures and no word (a stranger's probe), then with a note beside figures
    still wrong (an 8-h test, 10.9 kW of fuel for 6 h and 14.3 kW: another). t3, where the
    circulation stops, is far from the log's: refused, naming it, in one line; the log's
    own marks pass."""
    import json

    stationary, cycle = (
        run_log("stationary", "windhager_12kw"),
        run_log("load_cycle", "windhager_12kw"),
    )
    log = read_log(stationary.path)
    keep = [c for c in log.columns if c not in ("phase", "sequence")]
    path = tmp_path / "st.csv"
    data = np.column_stack([log[c] for c in keep])
    np.savetxt(path, data, delimiter=",", header=",".join(keep), comments="", fmt="%.6f")
    for meta, far in ((stationary.meta, False), (cycle.meta, True)):
        marks = {k: meta[k] for k in MARKS}
        if marks["t3_s"] > log.t[-1]:
            pytest.skip("the load cycle's t3 lies beyond the stationary record")
        path.with_name("st.meta.json").write_text(json.dumps(marks))
        again = read_log(path)
        if not far:
            phases = find_phases(again)
            assert phases.source == "meta file" and phases.t3 == meta["t3_s"]
            continue
        with pytest.raises(LogError) as info:
            find_phases(again)
        assert f"t3_s = {meta['t3_s']:g} s" in str(info.value)
        assert "marks of another log?" in str(info.value)
        out = tmp_path / "b.json"
        argv = ["balance", str(path), "--boiler", "windhager_12kw", "--out", str(out)]
        assert hil_client_main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "st.meta.json: " in err and not out.exists(), err


def test_a_phase_column_is_read_in_any_case_and_one_without_the_names_is_said(tmp_path):
    """Phase names padded with spaces, or in capitals, were not the phases (and a column
    of a lab's own names was ignored without a word; a stranger's probe). A balance
    logged in grams is taken as missing with a hint at the unit, not as error codes."""
    rows = ["preheat", "start_up", "start_up", "test", "test", "cooling_1", "cooling_2"]
    body = "".join(f"{i + 1},{p},300,50,60,60,150,8,{250000 - i},20\n" for i, p in enumerate(rows))
    header = _BASE.splitlines()[0] + "\n"
    padded = tmp_path / "padded.csv"
    padded.write_text(header + body.replace(",test,", ", TEST ,"))
    assert find_phases(read_log(padded)).source == "phase column"
    other = tmp_path / "other.csv"
    other.write_text(header + body.replace(",test,", ",Volllast,"))
    log = read_log(other)
    with pytest.raises(LogError):
        find_phases(log)  # no meta file, and the signals of seven rows show no phases
    assert any("the phase column holds no test" in n for n in log.notes), log.notes
    assert any("another unit than its name's (balance_mass_kg)" in n for n in log.notes)


def test_two_runs_in_one_log_are_refused_where_the_phase_column_starts_over(
    run_log, tmp_path, capsys
):
    """A stranger's probe: a stationary test with a load cycle appended (time running on)
    was analysed as one run: the whole load cycle became the first run's second cooling
    (23.4 h, 8.94 kg of fuel), and calibrate wrote UA_off 0.09 W/K (documented 2.9) with
    exit 0. The phase column going back is a second run: refused, naming where."""
    first, second = (
        run_log("stationary", "windhager_12kw").path.read_text().splitlines(),
        run_log("load_cycle", "windhager_12kw").path.read_text().splitlines(),
    )
    header = first[0].split(",")
    col = header.index("time_s")
    end = float(first[-1].split(",")[col])
    shifted = []
    for line in second[1:]:
        fields = line.split(",")
        fields[col] = f"{float(fields[col]) + end + 1.0:g}"
        shifted.append(",".join(fields))
    path = tmp_path / "stitched.csv"
    path.write_text("\n".join([*first, *shifted]) + "\n")
    code = hil_client_main(["balance", str(path), "--boiler", "windhager_12kw"])
    err = capsys.readouterr().err
    assert code == 2
    second_start = float(shifted[0].split(",")[col])
    assert f"goes back from cooling_2 to preheat at time_s = {second_start:g}:" in err
    assert "two runs in one log" in err and len(err.strip().splitlines()) == 1
    # without the phase column the signals read both runs as one test of 22.7 h: the
    # circulation's stop between them (the first run's second cooling) is refused
    header_cols = [c for c in header if c not in ("phase", "sequence")]
    keep = [header.index(c) for c in header_cols]
    bare = tmp_path / "stitched_bare.csv"
    rows = [[line.split(",")[k] for k in keep] for line in [*first[1:], *shifted]]
    bare.write_text("\n".join([",".join(header_cols), *map(",".join, rows)]) + "\n")
    code = hil_client_main(["balance", str(bare), "--boiler", "windhager_12kw"])
    err = capsys.readouterr().err
    assert code == 2 and "the water stops circulating from time_s = " in err
    assert "two runs in one log?" in err and len(err.strip().splitlines()) == 1


def test_a_phase_column_that_leaves_a_phase_out_is_said(run_log, tmp_path):
    """A phase column without its test rows (relabelled) fell back to the signals without
    a word, where a lab's own names were said (a stranger's probe)."""
    log = read_log(run_log("stationary", "windhager_12kw").path)
    lines = log.path.read_text().splitlines()
    col = lines[0].split(",").index("phase")
    out = [lines[0]]
    for line in lines[1:]:
        fields = line.split(",")
        if fields[col] == "test":
            fields[col] = "start_up"
        out.append(",".join(fields))
    path = tmp_path / "no_test.csv"
    path.write_text("\n".join(out) + "\n")
    relabelled = read_log(path)
    assert find_phases(relabelled).source != "phase column"
    said = [n for n in relabelled.notes if "the phase column holds no test" in n]
    assert len(said) == 1, relabelled.notes


def test_a_phase_column_cut_short_without_its_meta_gives_the_phases_it_holds(run_log, tmp_path):
    """A re-probe: a stationary log cut at 12,000 s with its phase column but without its
    meta file was refused ("cannot find t2: no change of flow before the first cooling").
    The column holds preheat, start-up and part of the test: those are the phases, the
    test the one it was cut in."""
    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    col = lines[0].split(",").index("time_s")
    kept = [line for line in lines[1:] if float(line.split(",")[col]) <= 12_000.0]
    path = tmp_path / "cut.csv"  # no meta file beside it
    path.write_text("\n".join([lines[0], *kept]) + "\n")
    log = read_log(path)
    phases = find_phases(log, partial=True)
    assert phases.source.startswith("phase column") and phases.cut_in == "test"
    assert (phases.t0, phases.t1) == pytest.approx((rec.meta["t0_s"], rec.meta["t1_s"]), abs=1.0)
    with pytest.raises(LogError):  # the analyses that need a whole test still refuse it
        find_phases(log)


@pytest.mark.parametrize("step", [60, 90, 120])
def test_phases_from_the_signals_of_rows_a_minute_or_two_apart(run_log, tmp_path, step):
    """A re-probe: without a phase column, rows 60 s apart put t2 44 min late (the first
    cooling's level was read over 120 rows, two hours, into the test)."""
    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h not in ("phase", "sequence")]
    rows = [r.split(",") for r in lines[1:]][::step]
    path = tmp_path / f"s{step}.csv"  # no meta file beside it
    path.write_text("\n".join(",".join(r[i] for i in keep) for r in [header, *rows]) + "\n")
    phases = find_phases(read_log(path))
    for key in ("t0_s", "t1_s", "t2_s", "t3_s"):  # within two rows of the bench's marks
        assert abs(getattr(phases, key[:2]) - rec.meta[key]) <= 2 * step, key


@pytest.mark.parametrize("step", [1, 60])
def test_a_record_begun_with_the_burner_firing_starts_where_its_signals_say(
    run_log, tmp_path, step
):
    """A re-probe: a record begun an hour into the test got a preheat of its first row and
    a start-up of five minutes at full load, and validate ran the model from there. A
    record whose flue gas has settled at its first full window is read as test from its
    first row; one whose flue gas still rises (begun in the start-up) starts up there."""
    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h not in ("phase", "sequence")]
    col = header.index("time_s")
    rows = [r.split(",") for r in lines[1:]][::step]
    for name, at_s in (
        ("in_test", rec.meta["t1_s"] + 3600.0),
        ("in_start_up", rec.meta["t0_s"] + 120.0),
    ):
        path = tmp_path / f"{name}.csv"  # no meta file beside it
        cut = [r for r in rows if float(r[col]) >= at_s]
        path.write_text("\n".join(",".join(r[i] for i in keep) for r in [header, *cut]) + "\n")
        log = read_log(path)
        phases = find_phases(log)
        if name == "in_test":
            assert phases.t0 == phases.t1 < log.t[0]  # no preheat, no start-up
            assert phases.mask("test", log.t)[0]
            assert "its test is read from its first row" in log.notes[-1]
        else:
            # t0 at the first row, as a later plant's rows begun in the start-up get it
            assert phases.t0 == log.t[0]  # (test_a_later_plant_in_the_start_up...)
            # t1 within two rows of the bench's mark, a minute at least (the slope window)
            assert abs(phases.t1 - rec.meta["t1_s"]) <= 2 * max(step, 60), phases.t1
            assert "its start-up is read from its first row" in log.notes[-1]
        assert abs(phases.t2 - rec.meta["t2_s"]) <= 2 * step  # the rest as before


def test_a_record_cut_short_in_its_test_without_marks_is_said_so(run_log, tmp_path):
    """A re-probe: validate and calibrate on a log cut short in its test, with no phase
    column or meta file beside it, said only "cannot find t2"."""
    rec = run_log("stationary", "windhager_12kw")
    lines = rec.path.read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h not in ("phase", "sequence")]
    col = header.index("time_s")
    rows = [r.split(",") for r in lines[1:]]
    cut = [r for r in rows if float(r[col]) <= rec.meta["t1_s"] + 3600.0]
    path = tmp_path / "cut.csv"
    path.write_text("\n".join(",".join(r[i] for i in keep) for r in [header, *cut]) + "\n")
    with pytest.raises(LogError, match="cannot find t2") as info:
        find_phases(read_log(path))
    assert f"ends at time_s {float(cut[-1][col]):g} with the water circulating" in str(info.value)
    assert "its phase column or meta file" in str(info.value)  # what it lacks
    # with its phase column, cut short in the test too: it is not sent for the column it
    # has (a stranger's probe)
    head = ",".join(header)
    path.write_text("\n".join([head, *(",".join(r) for r in cut)]) + "\n")
    with pytest.raises(LogError, match="cannot find t2") as info:
        find_phases(read_log(path))
    assert "its phase column ends before the first cooling too" in str(info.value)


def test_a_meta_file_with_a_key_twice_is_refused_naming_it(tmp_path):
    """A stranger's probe: a meta file holding t3_s twice was read with the last one, in
    silence (the YAML files refuse a key twice)."""
    log = tmp_path / "twice.csv"
    log.write_text(_BASE)
    log.with_name("twice.meta.json").write_text('{"t3_s": 2.0, "test": "stationary", "t3_s": 3.0}')
    with pytest.raises(LogError, match=r"twice\.meta\.json: key 't3_s' appears twice"):
        read_log(log)
