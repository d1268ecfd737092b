"""Bad or thin input to the analyses: refused in one line naming the file and what is
wrong, or reported as unknown with the reason, never as a made-up number."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from hil_client.analysis.balance import energy_balance, table, warnings_by_reason
from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.fault_report import check_journal, compare
from hil_client.analysis.logio import LogError, read_log
from hil_client.analysis.phases import Phases, find_phases
from hil_client.analysis.validate import compare as validation_compare
from hil_client.analysis.validate import validation_metrics
from hil_client.cli import main
from rig_emulator.boilers import load_boiler

from .test_balance import _steady_log

HEADER = (
    "time_s,water_flow_kg_h,water_in_temp_C,water_out_temp_C,boiler_water_temp_C,"
    "flue_gas_temp_C,flue_gas_O2_pct,balance_mass_kg,room_temp_C"
)
MARKS = {"t0_s": 3.0, "t1_s": 5.0, "t2_s": 7.0, "t3_s": 8.0, "t4_s": 10.0}


def _short_log(tmp_path, rows: int = 10, meta: dict | None = None):
    """A log of ``rows`` rows 1 s apart (no phase column) with a meta file."""
    path = tmp_path / "short.csv"
    body = "".join(f"{i},300,50,60,60,150,8,{250 - 0.001 * i},20\n" for i in range(1, rows + 1))
    path.write_text(HEADER + "\n" + body)
    meta = {"boiler": "windhager_6kw", **MARKS} if meta is None else meta
    path.with_name("short.meta.json").write_text(json.dumps(meta))
    return path


# --- phases from a meta file ------------------------------------------------------------


@pytest.mark.parametrize(
    ("marks", "message"),
    [
        ({"t1_s": 8.0, "t3_s": 5.0}, "t2_s = 7 is not after t1_s = 8"),  # t1 and t3 swapped
        ({"t2_s": 1e9}, "t2_s = 1e+09 lies outside the record of short.csv (time_s 1..10)"),
        ({"t2_s": math.nan}, "t2_s = nan is not a finite number"),
        ({"t2_s": "abc"}, "t2_s = 'abc' is not a finite number"),
        ({"t0_s": -5.0}, "t0_s = -5 lies outside the record"),
    ],
)
def test_meta_marks_that_cannot_be_the_logs_are_refused_naming_file_and_mark(
    tmp_path, marks, message
):
    path = _short_log(tmp_path, meta={**MARKS, **marks})
    with pytest.raises(LogError) as info:
        find_phases(read_log(path))
    text = str(info.value)
    assert text.startswith(f"{tmp_path / 'short.meta.json'}: ") and message in text
    assert "\n" not in text and "from the signals" in text


def test_meta_marks_in_order_within_the_record_are_taken(tmp_path):
    # t4 one row beyond the last (a last row cut short and left out) is the record's end
    path = _short_log(tmp_path, rows=9)
    phases = find_phases(read_log(path))
    assert phases.source == "meta file"
    assert phases.as_dict() == {**MARKS, "t4_s": 9.0}


def test_meta_keys_written_like_the_marks_but_not_as_read_are_named(tmp_path, capsys):
    """A stranger's review: ``t0`` or ``T1_s`` for ``t0_s``, ``Boiler`` for ``boiler`` were
    silently not read, the phases then coming from the signals. Each is named with the key
    meant; a lab's own keys (``operator``) and the project's (``seed``) are no note."""
    marks = {"t0": 3.0, "T1_s": 5.0, "t2 [s]": 7.0, "t3_sec": 8.0, "t4_s": 10.0}
    meta = {**marks, "Boiler": "windhager_6kw", "operator": "JS", "seed": 3, "t0_note": "x"}
    notes = read_log(_short_log(tmp_path, meta=meta)).notes
    for key, meant in [("t0", "t0_s"), ("T1_s", "t1_s"), ("t2 [s]", "t2_s"), ("t3_sec", "t3_s"),
                       ("Boiler", "boiler")]:  # fmt: skip
        assert f"key '{key}' of short.meta.json is not read: the analyses read '{meant}'" in notes
    assert len(notes) == 5  # operator, seed, t0_note and the right t4_s are no note
    # beside the key read, a variant is the lab's own (a boiler's serial: a re-probe); a
    # mark in other units is named
    marks = {k: v for k, v in MARKS.items() if k != "t1_s"}
    meta = {**marks, "boiler": "windhager_6kw", "Boiler": "BioWIN 2 serial 4711", "T1_min": 2}
    notes = read_log(_short_log(tmp_path, meta=meta)).notes
    assert notes == ["key 'T1_min' of short.meta.json is not read: the analyses read 't1_s'"]
    # where the boiler is only under the variant, the refusal names it (it came first)
    path = _short_log(tmp_path, meta={**MARKS, "Boiler": "windhager_6kw"})
    assert main(["balance", str(path), "--out", str(tmp_path / "b.json")]) == 2
    assert "key 'Boiler' of short.meta.json is not read" in capsys.readouterr().err


def test_an_interrupted_runs_partial_marks_leave_the_phases_to_the_signals(tmp_path):
    # the runner keeps the marks it reached; the signals tell (here: they cannot, 10 s)
    path = _short_log(tmp_path, meta={"t0_s": 3.0, "t1_s": 5.0})
    with pytest.raises(LogError) as info:
        find_phases(read_log(path))
    assert str(info.value) == (
        f"{path}: cannot find t1: the flue-gas temperature never settles; the run was cut "
        "short (its meta file records t0_s, t1_s, the rest not reached), so the log holds no "
        "whole test to analyse by phase"
    )


def test_a_log_whose_meta_marks_lie_beyond_it_is_refused_by_every_analysis(tmp_path, capsys):
    """A single row beside the meta file of a whole run (the probe's one_row.csv)."""
    path = _short_log(tmp_path, rows=1, meta={**MARKS, "t0_s": 14400.0, "t4_s": 65920.0})
    for argv in (
        ["validate", str(path), "--boiler", "windhager_6kw", "--out", str(tmp_path / "v")],
        ["calibrate", str(path), "--boiler", "windhager_6kw", "--out", str(tmp_path / "c.yaml")],
        ["balance", str(path), "--boiler", "windhager_6kw", "--out", str(tmp_path / "b.json")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "short.meta.json: t0_s = 14400 lies outside" in err
    assert not any(tmp_path.glob("v*")) and not any(tmp_path.glob("[bc].*"))


# --- validate -----------------------------------------------------------------------------


@pytest.mark.parametrize("rows", [1, 2, 10])
def test_a_log_too_short_to_validate_is_refused_naming_it(tmp_path, rows):
    log = read_log(_short_log(tmp_path, rows=rows, meta={}))
    # the burner on for less than two rows (t0..t2), whatever the phases say
    phases = Phases(1.0, 1.2, 1.4, 1.6, float(log.t[-1]), "test")
    with pytest.raises(LogError) as info:
        validation_compare(log, phases, load_boiler("windhager_6kw"))
    assert str(info.value).startswith(f"{log.path}: too short to validate: {rows} row(s), 0 ")


@pytest.mark.parametrize("column", ["flue_gas_O2_pct", "balance_mass_kg"])
def test_validation_without_analyser_or_balance_has_no_lab_flue_gas_loss(tmp_path, column):
    log = read_log(_short_log(tmp_path, rows=10, meta={}))
    log.columns[column] = np.full(len(log), np.nan)
    comp = validation_compare(
        log, Phases(3.0, 5.0, 7.0, 8.0, 10.0, "test"), load_boiler("windhager_6kw")
    )
    assert np.isnan(comp.lab["flue_gas_loss_kW"]).all()  # unknown, not 0
    assert np.isfinite(comp.lab["boiler_water_temp_C"]).all()


# --- balance --------------------------------------------------------------------------------


def _balance(params, **columns: np.ndarray):
    log, _ = _steady_log(params, hours=1.0)
    log.columns.update(columns)
    t_end = float(log.t[-1])
    phases = Phases(0.0, 0.5, t_end, t_end + 1, t_end + 2, "test")
    rows = energy_balance(log, params, phases)
    said = [table(rows), *(f"warning: {line}" for line in warnings_by_reason(rows))]
    return next(r for r in rows if r.phase == "test"), "\n".join(said)


def test_balance_without_o2_reports_the_flue_gas_loss_unknown_not_zero(params_12kw):
    n = 3600
    test, text = _balance(params_12kw, flue_gas_O2_pct=np.full(n, np.nan))
    assert test.q_fuel_kW > 0  # the balance still gives the fuel
    for value in (test.q_flue_gas_kW, test.lambda_mean, test.eta_indirect):
        assert math.isnan(value)
    assert "100.0%" not in text and "nan" not in text
    assert "warning: column 'flue_gas_O2_pct' has no readings" in text


def test_balance_without_mass_keeps_lambda_and_leaves_the_fuel_unknown(params_12kw):
    test, text = _balance(params_12kw, balance_mass_kg=np.full(3600, np.nan))
    # the flue-gas loss is per kg of fuel times the fuel flow: unknown without the balance
    for value in (test.fuel_as_received_kg, test.q_fuel_kW, test.q_flue_gas_kW, test.eta_direct):
        assert math.isnan(value)
    assert test.lambda_mean > 1.0  # from O2 alone
    assert "warning: column 'balance_mass_kg' has no readings" in text


def test_a_balance_read_with_its_sign_reversed_gives_no_fuel_in_balance_or_validate(
    params_12kw,
):
    """A stranger's probe: the balance's sign reversed (it gains what the burner burns)
    gave 0.00 kg of fuel in the balance's test phase and -16.32 kg in validate's cumulative
    fuel. Fuel only leaves: both say unknown, with the reason."""
    log, _ = _steady_log(params_12kw, hours=1.0)
    log.columns["balance_mass_kg"] = -log["balance_mass_kg"]
    t_end = float(log.t[-1])
    phases = Phases(0.0, 0.5, t_end, t_end + 1, t_end + 2, "test")
    test = next(r for r in energy_balance(log, params_12kw, phases) if r.phase == "test")
    for value in (test.fuel_as_received_kg, test.q_fuel_kW, test.eta_direct, test.eta_indirect):
        assert math.isnan(value)
    assert any("the balance gains" in w and "sign reversed" in w for w in test.warnings)
    comp = validation_compare(log, phases, params_12kw)
    fuel = validation_metrics(comp, log, params_12kw)["fuel"]
    assert fuel["test"]["balance_kg"] is None and fuel["total"]["balance_kg"] is None
    assert fuel["test"]["deviation_pct"] is None and fuel["test"]["model_kg"] > 0


def test_a_balance_stuck_through_firing_reads_no_fuel(params_12kw):
    test, text = _balance(params_12kw, balance_mass_kg=np.full(3600, 250.0))
    assert math.isnan(test.fuel_as_received_kg) and math.isnan(test.q_fuel_kW)
    assert math.isnan(test.q_flue_gas_kW) and math.isnan(test.eta_indirect)
    assert "the balance reads 250 kg throughout the log's 60 min of firing (stuck?)" in text
    row = next(line for line in text.splitlines() if line.startswith("test"))
    assert row.split()[2:4] == ["-", "-"]  # fuel kg, Q_fuel


def test_balance_json_writes_unknown_as_null_with_the_reason(tmp_path, capsys):
    log, _ = _steady_log(load_boiler("windhager_6kw"), hours=0.5)
    path = tmp_path / "steady.csv"
    names = list(log.columns)
    data = np.column_stack([log[c] for c in names])
    data[:, names.index("flue_gas_O2_pct")] = np.nan
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.6f")
    text = path.read_text().replace("nan", "")
    path.write_text(text)
    t_end = float(log.t[-1])
    meta = {"t0_s": 1.0, "t1_s": 2.0, "t2_s": t_end - 2, "t3_s": t_end - 1, "t4_s": t_end}
    path.with_name("steady.meta.json").write_text(json.dumps(meta))
    out = tmp_path / "b.json"
    assert main(["balance", str(path), "--boiler", "windhager_6kw", "--out", str(out)]) == 0
    said = capsys.readouterr()  # warnings on stderr, as every other (a stranger's review)
    assert said.err.startswith("hil-client: warning: ")
    # said once, of the log (the balance's own line said it again: a re-probe)
    assert said.err.count("column 'flue_gas_O2_pct' has no readings") == 1
    assert "warning" not in said.out and "test" in said.out
    test = next(r for r in json.loads(out.read_text())["balance"] if r["phase"] == "test")
    assert test["q_flue_gas_kW"] is None and test["eta_indirect"] is None
    assert test["q_fuel_kW"] > 0 and test["warnings"]


def test_balance_with_the_analyser_reading_air_while_fuel_burns_says_unknown(params_12kw):
    """O2 at air's 20.95 % through a test that burnt fuel: no row counts as firing, and the
    flue-gas loss is unknown, not 0 with an indirect efficiency of 100 %."""
    test, text = _balance(params_12kw, flue_gas_O2_pct=np.full(3600, 20.95))
    assert test.q_fuel_kW > 0 and math.isnan(test.q_flue_gas_kW)
    assert math.isnan(test.eta_indirect) and "100.0%" not in text
    assert "warning: the analyser reads air" in text


def test_a_refill_of_the_balance_is_no_fuel(params_12kw):
    """A +15 kg refill mid-test (the emulator's own offset fault) read as fuel going the
    wrong way gave 0.98 kg of fuel and a direct efficiency of 1386 %."""
    plain, _ = _balance(params_12kw)
    log, _ = _steady_log(params_12kw, hours=1.0)
    mass = log["balance_mass_kg"].copy()
    mass[len(mass) // 2 :] += 15.0
    refilled, _ = _balance(params_12kw, balance_mass_kg=mass)
    assert refilled.fuel_as_received_kg == pytest.approx(plain.fuel_as_received_kg, abs=0.02)
    assert refilled.eta_direct == pytest.approx(plain.eta_direct, rel=0.02)


# --- calibrate ----------------------------------------------------------------------------


def test_an_analyser_reading_air_fits_no_excess_air(run_log):
    """O2 at air's level through the stationary test fitted fac_a_lambda = 16 (lambda 16,
    no firing boiler's) and wrote it; now it is flagged and the documentation value kept."""
    doc = load_boiler("windhager_12kw")
    log = read_log(run_log("stationary", "windhager_12kw").path)
    phases = find_phases(log)
    air = replace(log, columns={**log.columns, "flue_gas_O2_pct": np.full(len(log), 20.95)})
    result = calibrate([(air, phases)], doc)
    flagged = [k for k in ("fac_a_lambda", "fac_b_lambda_h_kg") if k in result.flags]
    assert flagged and all("lambda outside 1..10" in result.flags[k] for k in flagged)
    assert result.params.fac_a_lambda == doc.fac_a_lambda


def test_a_stuck_balance_fits_neither_eq9_nor_pel_nor_pstart(run_log):
    doc = load_boiler("windhager_12kw")
    log = read_log(run_log("stationary", "windhager_12kw").path)
    phases = find_phases(log)
    stuck = replace(log, columns={**log.columns, "balance_mass_kg": np.full(len(log), 250.0)})
    result = calibrate([(stuck, phases)], doc)
    for key in ("fac_a_lambda", "fac_b_lambda_h_kg", "p_el_max_W", "p_el_min_W", "p_start_kW"):
        assert "stuck or empty balance" in result.flags[key], key
        assert getattr(result.params, key) == getattr(doc, key), key
    assert not len(result.fig5["fuel"])
    # what does not rest on the balance is still fitted
    assert "dt_nom_K" in result.fitted and "dt_nom_K" not in result.flags


def test_a_start_up_not_recorded_whole_gives_no_wel(run_log):
    doc = load_boiler("windhager_12kw")
    log = read_log(run_log("stationary", "windhager_12kw").path)
    phases = find_phases(log)
    keep = log.t > phases.t0 + 60.0  # the record begins a minute into the start-up
    cut = replace(
        log,
        columns={k: v[keep] for k, v in log.columns.items()},
        text={k: [x for x, y in zip(v, keep, strict=True) if y] for k, v in log.text.items()},
    )
    result = calibrate([(cut, phases)], doc)
    for key in ("w_el_Wh", "p_start_kW"):
        assert key not in result.fitted and "no start-up recorded whole" in result.flags[key]
        assert getattr(result.params, key) == getattr(doc, key)
    assert "ua_amb_off_W_K" in result.fitted  # the second cooling is still there


def test_a_log_too_short_to_calibrate_anything_is_refused(tmp_path):
    log = read_log(_short_log(tmp_path, rows=10, meta={}))
    phases = Phases(3.0, 5.0, 7.0, 8.0, 10.0, "test")
    with pytest.raises(LogError) as info:
        calibrate([(log, phases)], load_boiler("windhager_6kw"))
    assert str(info.value).startswith(f"{log.path}: nothing to calibrate")


# --- fault report journal -----------------------------------------------------------------

START = {"event": "start", "id": 1, "t_sim_s": 600.0, "kind": "no_reply", "unit": 2}
END = {**START, "event": "end", "t_sim_s": 630.0}


@pytest.mark.parametrize(
    ("lines", "message"),
    [
        ([{**START, "id": "x"}], "line 1: field 'id' = 'x': not an integer"),
        ([{**START, "t_sim_s": "abc"}], "line 1: field 't_sim_s' = 'abc': not a finite number"),
        ([{**START, "t_sim_s": math.nan}], "line 1: field 't_sim_s' = nan: not a finite"),
        ([{**START, "kind": "explode"}], "line 1: field 'kind' = 'explode': not a fault kind"),
        ([{**START, "unit": "two"}], "line 1: field 'unit' = 'two': not a unit number"),
        ([{**START, "event": "begin"}], "line 1: field 'event' = 'begin'"),
        ([START, {**END, "t_sim_s": 100.0}], "line 2: field 't_sim_s' = 100.0: the end is before"),
        ([START, END, START], "line 3: field 'id' = 1: fault 1 started already (line 1)"),
        ([END], "line 1: field 'id' = 1: the end of fault 1, which has not started"),
        ([START, {**END, "kind": "delay"}], "line 2: field 'kind' = 'delay': fault 1 started"),
        (
            [{"event": "start", "id": 1, "t_sim_s": 1.0, "kind": "spike", "signal": 5}],
            "line 1: field 'signal' = 5",
        ),
        # a stranger's probe: an end on another signal or unit closed the fault started on
        # the first
        (
            [
                {
                    "event": "start",
                    "id": 1,
                    "t_sim_s": 1.0,
                    "kind": "stuck",
                    "signal": "room_temp_C",
                },
                {
                    "event": "end",
                    "id": 1,
                    "t_sim_s": 2.0,
                    "kind": "stuck",
                    "signal": "flue_gas_temp_C",
                },
            ],
            "line 2: field 'signal' = 'flue_gas_temp_C': fault 1 started on signal 'room_temp_C'",
        ),
        ([START, {**END, "unit": 3}], "line 2: field 'unit' = 3: fault 1 started on unit 2"),
        ([{k: v for k, v in START.items() if k != "kind"}], "line 1: no field 'kind'"),
        ([{**START, "kind": "exception", "code": "x"}], "line 1: field 'code' = 'x'"),
    ],
)
def test_a_bad_journal_line_is_refused_naming_file_line_and_field(lines, message):
    with pytest.raises(ValueError) as info:
        compare(lines, [], journal_name="j.jsonl")
    assert str(info.value).startswith("j.jsonl: ") and message in str(info.value)


def test_a_journal_as_the_server_writes_it_passes():
    spike = {"event": "start", "id": 2, "t_sim_s": 1.0, "kind": "spike", "signal": "room_temp_C"}
    exc = {"event": "start", "id": 3, "t_sim_s": 2.0, "kind": "exception", "unit": 0}
    check_journal(
        [START, END, spike, {**spike, "event": "end", "t_sim_s": 1.0}, {**exc, "code": 11.0}],
        "j.jsonl",
    )
    assert compare([START, END], [], journal_name="j.jsonl")["missed"] == 1


def test_a_fault_the_server_never_served_is_neither_caught_nor_missed():
    """Its whole window fell inside one lockstep step: the journal says so, and the report
    lists it apart instead of blaming the acquisition software for missing it."""
    unseen = {"seen": False, "why": "its whole window fell between two evaluations"}
    lines = [{**START, "served": unseen}, {**END, "served": unseen}]
    report = compare(lines, [], journal_name="j.jsonl")
    assert report["missed"] == 0 and report["detected"] == 0
    assert [f["id"] for f in report["unseen"]] == [1]


def test_client_events_beyond_the_logs_rows_are_no_false_alarms():
    """A log cut at 500 s beside the events file of the whole run: the client's events of
    a fault at 600-630 s counted as false alarms while the fault itself was "outside the
    run", and the summary said "none journalled" (a stranger's probe)."""
    from hil_client.fault_files import summary

    events = [
        {"event": "no_reply", "unit": 2, "time_s": t, "server_time_s": t}
        for t in (600.0, 601.0, 602.0)
    ]
    report = compare([START, END], events, server_time=np.arange(0.0, 501.0))
    assert report["false"] == 0 and report["events_outside_run"] == 3
    assert [f["id"] for f in report["outside_run"]] == [1]
    line = summary(report)
    assert "3 of the client's events lie beyond the log's rows" in line
    assert "none in the run" in line and "none journalled" not in line
    # the whole run's log: the fault detected, nothing outside
    whole = compare([START, END], events, server_time=np.arange(0.0, 1000.0))
    assert whole["detected"] == 1 and whole["events_outside_run"] == 0


def test_a_log_of_another_boiler_is_analysed_with_a_warning(run_log, tmp_path, capsys):
    """The README's own commands once calibrated a 6-kW log as the 12-kW boiler: every
    command exited 0 and the fits were far from any boiler, without a word. Now each says
    which boiler the log was recorded with; and a log without its meta file says so."""
    import shutil

    log = run_log("stationary", "windhager_6kw").path
    assert main(["balance", str(log), "--boiler", "windhager_12kw"]) == 0
    warning = "was recorded with boiler 'windhager_6kw' (its meta file) and is analysed as "
    assert warning + "'windhager_12kw'" in capsys.readouterr().err
    out = tmp_path / "c.yaml"
    assert main(["calibrate", str(log), "--boiler", "windhager_12kw", "--out", str(out)]) == 0
    assert warning + "'windhager_12kw'" in capsys.readouterr().err
    assert main(["balance", str(log), "--boiler", "windhager_6kw"]) == 0
    assert "recorded with boiler" not in capsys.readouterr().err
    bare = tmp_path / "bare.csv"
    shutil.copy(log, bare)  # no meta file beside it
    assert main(["balance", str(bare)]) == 2
    assert "no boiler named (no meta file bare.meta.json); give --boiler" in capsys.readouterr().err


def test_a_meta_file_may_hold_the_boilers_parameters_inline(run_log, tmp_path, capsys):
    """CONTRACT section 3: the meta file's ``boiler`` is "parameter file name or inline
    parameters". Inline parameters were refused as "no boiler named" (a stranger's probe);
    they are now the boiler, and a bad one names the meta file and the key."""
    import shutil

    from rig_emulator.boilers import load_boiler

    src = run_log("stationary", "windhager_12kw").path
    named = tmp_path / "named.json"
    assert main(["balance", str(src), "--out", str(named)]) == 0
    inline = tmp_path / "inline.csv"
    shutil.copy(src, inline)
    meta = json.loads(src.with_name(src.stem + ".meta.json").read_text())
    meta["boiler"] = load_boiler("windhager_12kw").to_mapping()
    inline.with_name("inline.meta.json").write_text(json.dumps(meta))
    out = tmp_path / "inline.json"
    assert main(["balance", str(inline), "--out", str(out)]) == 0
    assert json.loads(out.read_text())["balance"] == json.loads(named.read_text())["balance"]
    capsys.readouterr()
    for boiler, said in (
        ({**meta["boiler"], "p_max_kW": "lots"}, "inline.meta.json: boiler"),
        (123, "('boiler' is int, not a name or parameters)"),
        ("windhager_99kw", "inline.meta.json: unknown boiler 'windhager_99kw'"),
    ):
        inline.with_name("inline.meta.json").write_text(json.dumps({**meta, "boiler": boiler}))
        assert main(["balance", str(inline)]) == 2
        err = capsys.readouterr().err
        assert said in err and len(err.strip().splitlines()) == 1, err


def test_the_held_out_log_may_not_be_the_calibration_log_again(run_log, tmp_path, capsys):
    """CONTRACT section 4: nothing is fitted or selected on the held-out log. The same file,
    a copy, and (strangers' probes) the same log re-exported with absolute times (+100000
    s), rounded to two decimals, or thinned to every second row, which diagnose took as
    held out and scored at 87-98 % shrinkage, are refused in one line; the emulator's own
    stationary and load-cycle pair, which share their preheat, is not."""
    import shutil

    from hil_client.analysis.logio import read_log
    from hil_client.analysis.same_record import same_record as _same_record

    # (the load cycle logged every 5 s, as labs also log: each diagnose reads both logs
    # whole, a fifth as long)
    every_s = run_log("load_cycle", "windhager_12kw").path.read_text().splitlines()
    cal = tmp_path / "load_cycle.csv"
    cal.write_text("\n".join([every_s[0], *every_s[1::5]]) + "\n")
    copy = tmp_path / "copy.csv"
    shutil.copy(cal, copy)
    lines = cal.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("time_s")
    rows = [r.split(",") for r in lines[1:]]

    def variant(name: str, change) -> object:
        path = tmp_path / name
        text = [",".join(change(list(r))) for r in rows]
        path.write_text("\n".join([lines[0], *(t for t in text if t)]) + "\n")
        return path

    def shifted(r):
        r[col] = f"{float(r[col]) + 100000.0:g}"
        return r

    text_columns = {header.index(n) for n in ("phase", "sequence") if n in header}

    def rounded(r):
        keep = {col, *text_columns}
        return [v if i in keep or not v else f"{float(v):.2f}" for i, v in enumerate(r)]

    thinned = tmp_path / "thinned.csv"
    thinned.write_text("\n".join([lines[0], *lines[1::2]]) + "\n")
    copies = [cal, copy, variant("shifted.csv", shifted), variant("rounded.csv", rounded), thinned]
    for val in copies:
        argv = ["diagnose", "--calibration", str(cal), "--validation", str(val)]
        code = main([*argv, "--boiler", "windhager_12kw", "--out", str(tmp_path / "d")])
        err = capsys.readouterr().err
        assert code == 2 and "--validation:" in err and len(err.strip().splitlines()) == 1, val
    other = run_log("stationary", "windhager_12kw").path
    assert not _same_record(read_log(cal), read_log(other))
    assert not _same_record(read_log(other), read_log(cal))


def test_a_part_or_a_thinning_of_the_calibration_log_either_way_round_is_refused(
    run_log, tmp_path, capsys
):
    """A stranger's probe: the held-out log as the calibration log less its first row, its
    odd rows, a random half of its rows, or the calibration log as a thinned copy or a later
    part of the held-out one, were taken as held out (exit 0, 85-92 % shrinkage measured
    on the calibration data itself). Each is refused, whichever role it is given."""
    from hil_client.analysis.same_record import same_record as _same_record

    # (the load cycle logged every 2 s, as labs also log: every part a half as long)
    every_s = run_log("load_cycle", "windhager_12kw").path.read_text().splitlines()
    whole = tmp_path / "load_cycle.csv"
    whole.write_text("\n".join([every_s[0], *every_s[1::2]]) + "\n")
    lines = whole.read_text().splitlines()
    rng = np.random.default_rng(3)

    def part(name: str, rows: list[str]):
        path = tmp_path / name
        path.write_text("\n".join([lines[0], *rows]) + "\n")
        return path

    body = lines[1:]
    col = lines[0].split(",").index("time_s")

    def rebased(rows: list[str]) -> list[str]:  # its times counted from its first row
        cells = [r.split(",") for r in rows]
        start = float(cells[0][col])
        for c in cells:
            c[col] = f"{float(c[col]) - start:g}"
        return [",".join(c) for c in cells]

    parts = [
        part("no_first_row.csv", body[1:]),
        # (a re-probe: rows dropped and the times re-based went through)
        part("no_first_rows_rebased.csv", rebased(body[300:])),
        part("thinned_cut_rebased.csv", rebased(body[301::5])),
        # (a re-probe: cut after the first firing and re-based, it lined up with neither
        # start nor firing)
        part("from_its_test_rebased.csv", rebased(body[1500::3])),
        part("odd_rows.csv", body[1::2]),
        part("random_half.csv", [r for r in body if rng.random() < 0.5]),
        part("every_10_s.csv", body[::5]),
        part("from_row_2500.csv", body[2500:]),
        part("first_half.csv", body[: len(body) // 2]),
    ]
    log = read_log(whole)
    for path in parts:
        other = read_log(path)
        assert _same_record(log, other) and _same_record(other, log), path.name
    argv = ["diagnose", "--calibration", str(parts[6]), "--validation", str(whole)]
    assert main([*argv, "--boiler", "windhager_12kw", "--out", str(tmp_path / "d")]) == 2
    err = capsys.readouterr().err
    assert "--validation: the same record as --calibration, or a part of it" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "d").exists()


def test_two_clean_tests_that_cool_alike_for_a_day_are_two_records(tmp_path):
    """A re-probe: two clean emulated runs, a 30-min test at 100 % and one at 80 %, each
    cooling for a day after, were refused as the same record: their preheats are the same
    and their coolings converge to the room, 0.006 K apart in the median. What is compared
    is what both fire; the firing differs."""
    import yaml

    from hil_client.analysis.same_record import same_record
    from hil_client.protocol.definition import DEFINITION_DIR

    logs = []
    for load in (100, 80):
        data = yaml.safe_load((DEFINITION_DIR / "stationary.yaml").read_text())
        step = {"name": "stationary_100", "load_pct": load, "duration": "00:30:00"}
        data["test_sequence"]["sequences"] = [step]
        data["cooling_2"] = {"until_after_t2_s": 86400}
        protocol = tmp_path / f"p{load}.yaml"
        protocol.write_text(yaml.safe_dump(data))
        log = tmp_path / f"r{load}.csv"
        argv = ["run", str(protocol), "--boiler", "windhager_12kw", "--rig", "local"]
        assert main([*argv, "--quiet", "--out", str(log)]) == 0
        logs.append(read_log(log))
    assert not same_record(*logs) and not same_record(*logs[::-1])


@pytest.mark.parametrize("target", ["short.csv", "short.meta.json", "short.modbus_events.jsonl"])
def test_balance_may_not_write_over_its_own_log(tmp_path, capsys, target):
    """``balance --out LOG.csv`` (or its meta file) wrote its JSON over the lab log and
    exited 0 (a stranger's probe): refused in one line, the files as they were."""
    path = _short_log(tmp_path)
    (tmp_path / "short.modbus_events.jsonl").write_text("")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert main(["balance", str(path), "--out", str(tmp_path / target)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "would overwrite" in err and target in err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_fault_report_and_calibrate_may_not_write_over_their_inputs(tmp_path, capsys):
    """``fault-report --out`` over its journal, and ``calibrate --out`` over the boiler file
    it takes the documentation values from, are refused and change nothing."""
    import shutil

    from rig_emulator.boilers import resolve

    path = _short_log(tmp_path)
    journal = tmp_path / "j.jsonl"
    journal.write_text("")
    boiler = tmp_path / "mine.yaml"
    shutil.copy(resolve("windhager_6kw"), boiler)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    for argv in (
        ["fault-report", str(path), "--journal", str(journal), "--out", str(journal)],
        ["fault-report", str(path), "--journal", str(journal), "--out", str(path)],
        ["calibrate", str(path), "--boiler", str(boiler), "--out", str(boiler)],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "would overwrite" in err, argv
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def _edited(run_log, tmp_path, name: str, edit) -> str:
    """The clean stationary 12-kW log with ``edit(header, row)`` applied to every row."""
    import shutil

    src = run_log("stationary", "windhager_12kw").path
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    for row in rows:
        edit(header, row)
    path = tmp_path / f"{name}.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    shutil.copy(src.with_name(src.stem + ".meta.json"), tmp_path / f"{name}.meta.json")
    return str(path)


@pytest.mark.parametrize("column", ["water_flow_kg_h", "room_temp_C", "water_in_temp_C"])
def test_a_model_input_with_no_values_is_refused_by_validate(run_log, tmp_path, capsys, column):
    """A stranger's probe: an empty flow column gave Table 4 figures of a model run at zero
    flow (RMSD 10 K, fuel -99.5 %), exit 0, no warning."""

    def empty(header, row):
        row[header.index(column)] = ""

    path = _edited(run_log, tmp_path, "empty", empty)
    assert main(["validate", path, "--boiler", "windhager_12kw", "--out", str(tmp_path / "v")]) == 2
    err = capsys.readouterr().err
    assert f"column '{column}' has no values" in err and err.count("\n") == 1
    assert not (tmp_path / "v").exists()


@pytest.mark.parametrize(("unit", "per_s"), [("hours", 1 / 3600), ("days", 1 / 86400)])
def test_a_time_in_hours_or_days_is_refused(run_log, tmp_path, capsys, unit, per_s):
    """A stranger's probe: a time column in hours (or Excel's serial days) under the name
    time_s gave a balance of Q_fuel 51,532 kW, exit 0."""

    def rescale(header, row):
        i = header.index("time_s")
        row[i] = f"{float(row[i]) * per_s:.9f}"

    path = _edited(run_log, tmp_path, unit, rescale)
    (tmp_path / f"{unit}.meta.json").unlink()  # (its marks are in seconds)
    assert main(["balance", path, "--boiler", "windhager_12kw"]) == 2
    err = capsys.readouterr().err
    assert "a time in hours, or Excel's days?" in err and err.count("\n") == 1


@pytest.mark.parametrize("written", ["6_9", "\uff15", "\u0665"])
def test_a_number_written_with_underscores_or_other_digits_is_no_number(
    run_log, tmp_path, capsys, written
):
    """Strangers' probes: Python's float() read '6_9' as 69 (and '1_000' as 1000 C), a
    full-width '５' as 5 and an Arabic-Indic '٥' as 5 (a flow of 5 kg/h, no word)."""

    def edit(header, row):
        if row[header.index("time_s")].startswith("5000."):
            row[header.index("water_flow_kg_h")] = written

    path = _edited(run_log, tmp_path, "us", edit)
    assert main(["balance", path, "--boiler", "windhager_12kw"]) == 2
    err = capsys.readouterr().err
    assert f"'{written}' is not a number" in err and err.count("\n") == 1, err


@pytest.mark.parametrize("written", ["22.5\u00a0", "\u200922.5", "22.5\u3000"])
def test_a_number_beside_a_space_of_another_script_is_still_a_number(
    run_log, tmp_path, capsys, written
):
    """A re-probe: refusing every non-ASCII character refused a no-break space after a
    number (what a spreadsheet in Windows-1252 keeps of one pasted from the web), a log
    read before; only other scripts' digits are refused."""

    def edit(header, row):
        if row[header.index("time_s")].startswith("5000."):
            row[header.index("water_in_temp_C")] = written

    path = _edited(run_log, tmp_path, "sp", edit)
    assert main(["balance", path, "--boiler", "windhager_12kw"]) == 0, capsys.readouterr().err


def test_an_integer_too_large_for_a_float_in_a_meta_file_is_one_line(tmp_path, capsys):
    """A stranger's probe: a 401-digit t1_s ended balance in OverflowError's traceback."""
    path = _short_log(tmp_path, meta={"t0_s": 3.0, "t1_s": 10**400})
    assert main(["balance", str(path), "--boiler", "windhager_6kw"]) == 2
    err = capsys.readouterr().err
    assert "t1_s = 10000000000000000000... is not a finite number" in err
    assert err.count("\n") == 1


def test_an_analyser_with_no_readings_is_said_by_validate(run_log, tmp_path, capsys):
    """A stranger's probe: balance warned of an empty O2 column, validate and diagnose
    said nothing (and the diagnosis changed)."""

    def no_o2(header, row):
        row[header.index("flue_gas_O2_pct")] = ""

    path = _edited(run_log, tmp_path, "no_o2", no_o2)
    assert main(["validate", path, "--boiler", "windhager_12kw", "--out", str(tmp_path / "v")]) == 0
    assert "column 'flue_gas_O2_pct' has no readings" in capsys.readouterr().err


def test_a_time_in_minutes_is_warned_by_the_fuel_it_would_burn(run_log, tmp_path, capsys):
    """A re-probe: 1-s rows written in minutes (0.0167 per row) pass the step's bound and
    gave a 12-kW boiler 847 kW with no word. The balance cannot lose more than the
    boiler burns at full power for as long as the record lasts (twice that, for Pstart)."""

    def minutes(header, row):
        i = header.index("time_s")
        row[i] = f"{float(row[i]) / 60:.6f}"

    path = _edited(run_log, tmp_path, "minutes", minutes)
    (tmp_path / "minutes.meta.json").unlink()  # (its marks are in seconds)
    # (refused now, its heat to the water 1/60 of the fuel's energy: the time is named)
    main(["balance", path, "--boiler", "windhager_12kw"])
    assert "is time_s in seconds (not minutes)" in capsys.readouterr().err
    clean = str(run_log("stationary", "windhager_12kw").path)
    assert main(["balance", clean, "--boiler", "windhager_12kw"]) == 0
    assert "not minutes" not in capsys.readouterr().err


# --- a stranger's probes of the log's form ------------------------------------------------


def _log_text(rows: int = 60, header: str = HEADER, sep: str = ",") -> str:
    body = "".join(
        sep.join(f"{v}" for v in (i, 300, 50, 60, 60, 150, 8, 250 - 0.001 * i, 20)) + "\n"
        for i in range(1, rows + 1)
    )
    return header.replace(",", sep) + "\n" + body


def test_a_required_column_with_a_unit_after_its_name_is_named_in_the_error(tmp_path):
    """'time_s [s]' gave "missing required column 'time_s'" with no word of the column
    that is there."""
    path = tmp_path / "units.csv"
    path.write_text(_log_text(header=HEADER.replace("time_s", "time_s [s]")))
    with pytest.raises(LogError) as info:
        read_log(path)
    assert str(info.value) == (
        f"{path}: missing required column 'time_s' (column 'time_s [s]' has a unit or note "
        "after the name: rename it 'time_s')"
    )


@pytest.mark.parametrize(("sep", "what"), [(";", "semicolons"), ("\t", "tabs")])
def test_fields_separated_otherwise_cite_no_contract_falsely(tmp_path, sep, what):
    path = tmp_path / "sep.csv"
    path.write_text(_log_text(sep=sep))
    with pytest.raises(LogError) as info:
        read_log(path)
    assert str(info.value) == (
        f"{path}: fields separated by {what}, not commas (a lab log is a CSV: commas "
        "between fields, '.' as the decimal point)"
    )


@pytest.mark.parametrize(("kind", "said"), [("gzip", "gzip"), ("zip", "a zip archive")])
def test_a_compressed_log_is_said_to_be_compressed(tmp_path, kind, said):
    """A gzip file was reported as "NUL bytes: UTF-16 without its byte-order mark"."""
    import gzip
    import zipfile

    path = tmp_path / "log.csv"
    if kind == "gzip":
        path.write_bytes(gzip.compress(_log_text().encode()))
    else:
        with zipfile.ZipFile(path, "w") as z:
            z.writestr("log.csv", _log_text())
    with pytest.raises(LogError) as info:
        read_log(path)
    assert str(info.value).startswith(f"{path}: compressed ({said}), not a lab log's text")


def test_a_balance_in_grams_is_refused_and_error_codes_are_still_missing(tmp_path):
    """A balance in grams was taken as missing whole ("has no values", or dropped quietly);
    an instrument's error code in most rows is still taken as missing (a gap is data)."""
    path = tmp_path / "g.csv"
    lines = _log_text().splitlines()
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        r[7] = f"{float(r[7]) * 1000:.1f}"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    with pytest.raises(LogError) as info:
        read_log(path)
    assert (
        str(info.value)
        == f"{path}: column 'balance_mass_kg' reads around 249970: grams? (kg expected)"
    )
    for r in rows[:40]:
        r[7] = "-999999"
    for r in rows[40:]:
        r[7] = "249.9"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    log = read_log(path)
    assert (
        np.isnan(log["balance_mass_kg"][:40]).all()
        and not np.isnan(log["balance_mass_kg"][40:]).any()
    )
