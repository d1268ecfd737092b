"""Warnings for what in a log looks like a wrong unit or a broken sensor
(hil_client.analysis.sanity): each mutation a stranger's probe made of a lab log (a flow in
l/min, temperatures in kelvin, a stuck forward sensor, oxygen offset or read as a fraction,
a negative flow, a drifting balance) gave confident figures without a word. Each is now
named in one line by every analysis; the emulator's own logs get none."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil_client.analysis.logio import LabLog, LogError, read_log
from hil_client.analysis.sanity import refuse_wrong_units, suspicious
from hil_client.cli import main
from rig_emulator.boilers import load_boiler

BOILER = "windhager_12kw"


def _mutated(log: LabLog, **changes) -> LabLog:
    columns = dict(log.columns)
    for name, change in changes.items():
        columns[name] = change(columns[name].copy(), log.t)
    return LabLog(log.path, columns, log.text, log.meta)


def _drift(mass, t):
    return mass + 0.2e-3 * (t - t[0])  # +0.72 kg/h, a balance creeping up


_WATER_AND_ROOM = ("water_in_temp_C", "water_out_temp_C", "boiler_water_temp_C", "room_temp_C")


MUTATIONS = {
    "flow in l/min": ({"water_flow_kg_h": lambda x, t: x / 60.0}, "is the flow in kg/h"),
    "kelvin": ({n: lambda x, t: x + 273.15 for n in _WATER_AND_ROOM}, "kelvin?"),
    "stuck forward": (
        {"water_out_temp_C": lambda x, t: np.full_like(x, 60.0)},
        "'water_out_temp_C' reads 60 throughout while the boiler burns fuel",
    ),
    "O2 offset": ({"flue_gas_O2_pct": lambda x, t: x + 5.0}, "reads above air's"),
    "O2 fraction": ({"flue_gas_O2_pct": lambda x, t: x / 100.0}, "a fraction, not vol-%"),
    "negative flow": ({"water_flow_kg_h": lambda x, t: -x}, "negative"),
    "drifting balance": ({"balance_mass_kg": _drift}, "a drifting balance?"),
    "balance drifting down": (
        {"balance_mass_kg": lambda x, t: x - 0.5 / 3600.0 * (t - t[0])},
        "loses",
    ),  # stand-by 'fuel' of 3 kg (a re-probe)
    "flue gas in kelvin": ({"flue_gas_temp_C": lambda x, t: x + 273.15}, "below"),
    # a stranger's probes: fuel 0.00 kg and -0.23 kg in the results, no word
    "balance sign reversed": ({"balance_mass_kg": lambda x, t: -x}, "while the boiler fires"),
    "balance mirrored": ({"balance_mass_kg": lambda x, t: 500.0 - x}, "while the boiler fires"),
}


@pytest.fixture(scope="module")
def logs(run_log):
    return {p: read_log(run_log(p, BOILER).path) for p in ("stationary", "load_cycle")}


def test_the_emulators_own_logs_raise_no_warning(logs):
    for log in logs.values():
        assert suspicious(log, load_boiler(BOILER)) == []


@pytest.mark.parametrize("mutation", MUTATIONS)
def test_each_wrong_unit_or_broken_sensor_is_named_in_one_line(logs, mutation):
    changes, said = MUTATIONS[mutation]
    found = suspicious(_mutated(logs["stationary"], **changes), load_boiler(BOILER))
    assert any(said in line for line in found), found
    assert all(line.startswith(str(logs["stationary"].path)) for line in found)
    assert all("\n" not in line for line in found)


def test_balance_prints_the_warning_and_still_gives_its_figures(logs, tmp_path, capsys):
    """A flow read a third low: a direct efficiency of some 28 %, odd but not impossible
    (a flow in l/min, 1.3 %, is refused: see below); the figures stay (a warning cannot know
    the right unit), the warning names where to look."""
    src = logs["stationary"]
    lines = src.path.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("water_flow_kg_h")
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        r[col] = f"{float(r[col]) / 3.0:.5f}" if r[col] else r[col]
    path = tmp_path / "third.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    out = tmp_path / "b.json"
    assert main(["balance", str(path), "--boiler", BOILER, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"hil-client: warning: {path}: the heat to the water is" in err
    assert json.loads(out.read_text())["balance"]


def _rewritten(src, tmp_path, name: str, column: str, change, every: int = 1) -> object:
    """``src`` with ``column`` changed, without its phase columns (a lab's own log, whose
    phases are found from the signals) and without its meta file; ``every``: only every
    so many rows kept (a lab's slower acquisition)."""
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index(column)
    keep = [i for i, h in enumerate(header) if h not in ("phase", "sequence")]
    rows = [r.split(",") for r in lines[1::every]]
    for r in rows:
        if r[col]:
            r[col] = f"{change(float(r[col])):.6g}"
    path = tmp_path / name
    text = [",".join(r[i] for i in keep) for r in [header, *rows]]
    path.write_text("\n".join(text) + "\n")
    return path


def test_where_the_phases_cannot_be_found_the_error_says_what_looks_wrong(logs, tmp_path, capsys):
    """A time in milliseconds gave "the flue-gas temperature never settles": true, and no
    help. The one error line now says what in the log looks like a wrong unit as well. A
    time in milliseconds from the first row (1000 s per row) is refused before any fit:
    calibrate wrote UA_off 0.0029 W/K +- 4.5e-05 from one (a stranger's probe)."""
    no_setpoint = _rewritten(
        logs["stationary"].path, tmp_path, "sp.csv", "water_flow_setpoint_kg_h", lambda v: 0.0
    )
    lmin = _rewritten(no_setpoint, tmp_path, "lmin.csv", "water_flow_kg_h", lambda v: v / 60)
    assert main(["balance", str(lmin), "--boiler", BOILER]) == 2
    err = capsys.readouterr().err.strip()
    # (a flow in l/min is now refused by its unit before the phases are looked for)
    assert "'water_flow_kg_h'" in err and "kg/h" in err and len(err.splitlines()) == 1, err
    # a time in milliseconds is refused before any fit, by its step or, logged faster
    # than every 0.6 s, by its span (a re-probe: 0.5-s rows in ms still calibrated)
    for scale, said in ((1e3, "a median of 1000 s per row"), (500, "spans 302 days")):
        path = _rewritten(
            logs["stationary"].path, tmp_path, "ms.csv", "time_s", lambda v, k=scale: v * k
        )
        for command in ("balance", "validate", "calibrate"):
            out = tmp_path / f"{command}_out{'.yaml' if command == 'calibrate' else ''}"
            assert main([command, str(path), "--boiler", BOILER, "--out", str(out)]) == 2
            err = capsys.readouterr().err.strip()
            assert said in err and "a time in milliseconds?" in err, err
            assert len(err.splitlines()) == 1 and not out.exists()
    # one row's wild time is that row's, in a line of readable length (a stranger's probe:
    # a last row of 1e300 gave 300 digits of days and "a time in milliseconds?")
    lines = logs["stationary"].path.read_text().splitlines()
    wild = tmp_path / "wild.csv"
    wild.write_text("\n".join([*lines[:-1], "1e300" + lines[-1][lines[-1].index(",") :]]) + "\n")
    assert main(["balance", str(wild), "--boiler", BOILER]) == 2
    err = capsys.readouterr().err.strip()
    assert "the row at 1e+300 s comes " in err and "a wrong time in that row?" in err, err
    assert len(err) < 300 and "milliseconds" not in err
    first = lines[1][lines[1].index(",") :]  # a wild first row is that row's (a re-probe)
    wild.write_text("\n".join([lines[0], "-1e9" + first, *lines[2:]]) + "\n")
    assert main(["balance", str(wild), "--boiler", BOILER]) == 2
    err = capsys.readouterr().err.strip()
    assert "the row at -1e+09 s lies " in err and "before the row after" in err, err


def test_a_short_part_load_test_is_no_wrong_unit(tmp_path):
    """A re-probe: a clean run of a 25-min test at 35 % read 19 % "direct efficiency" over
    the whole log (the preheat's bench-heated water, the stand-by's losses) and warned of
    wrong units. Only the firing is read now, and only over a kilogram of fuel."""
    import yaml

    from hil_client.protocol.definition import DEFINITION_DIR

    data = yaml.safe_load((DEFINITION_DIR / "stationary.yaml").read_text())
    data["test_sequence"]["sequences"] = [{"name": "short", "load_pct": 35, "duration": 1500}]
    protocol = tmp_path / "short.yaml"
    protocol.write_text(yaml.safe_dump(data))
    out = tmp_path / "short.csv"
    argv = ["run", str(protocol), "--boiler", "windhager_6kw", "--rig", "local", "--quiet"]
    assert main([*argv, "--out", str(out)]) == 0
    assert suspicious(read_log(out), load_boiler("windhager_6kw")) == []


def test_a_flow_read_backwards_is_refused_by_every_analysis(logs, tmp_path, capsys):
    """A stranger's probe: a flow meter mounted the wrong way round (every reading negated)
    gave a warning, and then validate fed the model a flow running backwards through the
    boiler: a Table 4 of 1e42 K, written with exit 0; balance wrote a negative heat to the
    water. Every analysis now refuses the log in one line, exit 2, and writes nothing."""
    negative = _rewritten(
        logs["stationary"].path, tmp_path, "neg.csv", "water_flow_kg_h", lambda v: -v
    )
    val = _rewritten(logs["load_cycle"].path, tmp_path, "val.csv", "water_flow_kg_h", abs)
    runs = {
        "balance": [str(negative), "--out", str(tmp_path / "b.json")],
        "validate": [str(negative), "--out", str(tmp_path / "v")],
        "calibrate": [str(negative), "--out", str(tmp_path / "c.yaml")],
        "diagnose": [
            *("--calibration", str(negative), "--validation", str(val)),
            *("--out", str(tmp_path / "d")),
        ],
    }
    for command, rest in runs.items():
        assert main([command, *rest, "--boiler", BOILER]) == 2, command
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert "'water_flow_kg_h' reads a median of" in err and "sign" in err, err
    assert not any((tmp_path / n).exists() for n in ("b.json", "v", "c.yaml", "d"))


def test_a_meters_zero_in_a_long_standstill_is_no_reversed_flow(logs):
    """A re-probe: a log whose flow meter reads -0.3 kg/h at standstill (its zero), over
    more than half the record (a long second cooling with the pump off), had a negative
    median and was refused as a flow read backwards; its sign is read from the rows where
    the water moves. The reversed meter is still named."""
    log = logs["stationary"]
    standstill = log.t > log.t[int(0.4 * len(log))]
    zero = _mutated(log, water_flow_kg_h=lambda x, t: np.where(standstill, -0.3, x))
    assert float(np.nanmedian(zero["water_flow_kg_h"])) < 0.0
    assert not [w for w in suspicious(zero, load_boiler(BOILER)) if "water_flow_kg_h" in w]
    reversed_meter = _mutated(zero, water_flow_kg_h=lambda x, t: -x)
    assert any("negative" in w for w in suspicious(reversed_meter, load_boiler(BOILER)))


# --- what no boiler's bench reads: refused -----------------------------------------------

_KELVIN = {n: (lambda v: v + 273.15) for n in _WATER_AND_ROOM}
REFUSED = {
    # ten "(kelvin?)" warnings, then exit 0 everywhere with confident results (a probe)
    "kelvin": (_KELVIN, "column 'water_in_temp_C' reads a median of", ": kelvin? convert to C"),
    "flue gas in kelvin": (
        {"flue_gas_temp_C": lambda v: v + 273.15},
        "column 'flue_gas_temp_C' never reads below",
        "kelvin? convert to C",
    ),
    "O2 fraction": (
        {"flue_gas_O2_pct": lambda v: v / 100.0},
        "column 'flue_gas_O2_pct' reads at most 0.2",
        "a fraction, not vol-%",
    ),
    "flow in l/min": (
        {"water_flow_kg_h": lambda v: v / 60.0 / 0.978},
        "column 'water_flow_kg_h': the heat to the water is",
        "(20%-150% for any boiler)",
    ),
    "balance in grams": (
        {"balance_mass_kg": lambda v: v * 1000.0},
        "column 'balance_mass_kg' reads around",
        ": grams? (kg expected)",
    ),
}


def _changed(src, tmp_path, name: str, changes: dict, every: int = 1) -> object:
    path = src
    for k, (column, change) in enumerate(changes.items()):
        path = _rewritten(path, tmp_path, name, column, change, every if k == 0 else 1)
    return path


@pytest.mark.parametrize("mutation", REFUSED)
def test_a_unit_no_bench_reads_is_refused_by_every_analysis(logs, tmp_path, capsys, mutation):
    """A stranger's probes: temperatures in kelvin under _C names, oxygen as a fraction, a
    flow in l/min under water_flow_kg_h (heat to water 2 % of the fuel's energy) gave
    warnings and then results with exit 0; a balance in grams was taken as missing whole
    ("has no values" from diagnose, and calibrate and validate dropped it quietly). Every
    analysis now refuses the log in one line naming the file, the column and the figure,
    exit 2, and writes nothing; in diagnose either log."""
    changes, column, said = REFUSED[mutation]
    # (logged every 5 s, as labs also log: every analysis reads them whole, a fifth as long)
    bad = _changed(logs["stationary"].path, tmp_path, "bad.csv", changes, every=5)
    good = _rewritten(logs["load_cycle"].path, tmp_path, "good.csv", "room_temp_C", float, every=5)
    runs = {
        "balance": [str(bad), "--out", str(tmp_path / "b.json")],
        "validate": [str(bad), "--out", str(tmp_path / "v")],
        "calibrate": [str(bad), "--out", str(tmp_path / "c.yaml")],
        "diagnose": [
            *("--calibration", str(good), "--validation", str(bad)),
            *("--out", str(tmp_path / "d")),
        ],
    }
    for command, rest in runs.items():
        assert main([command, *rest, "--boiler", BOILER]) == 2, command
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert err.startswith(f"hil-client: error: {bad}: {column}"), err
        assert said in err, err
    assert not any((tmp_path / n).exists() for n in ("b.json", "v", "c.yaml", "d"))


def test_a_refused_heat_names_the_temperatures_where_they_are_at_fault(logs):
    """A stranger's probe: the forward and return swapped, and the water temperatures in
    Fahrenheit, were refused as "column 'water_flow_kg_h': ...", the flow being right."""
    params, log = load_boiler(BOILER), logs["stationary"]
    forward, back = log["water_out_temp_C"], log["water_in_temp_C"]
    swapped = _mutated(log, water_out_temp_C=lambda x, t: back.copy())
    swapped.columns["water_in_temp_C"] = forward.copy()
    fahrenheit = _mutated(log, **{n: (lambda x, t: x * 1.8 + 32.0) for n in _WATER_AND_ROOM[:3]})
    # the forward and return alone in Fahrenheit (a re-probe: "swapped?")
    two = _mutated(log, **{n: (lambda x, t: x * 1.8 + 32.0) for n in _WATER_AND_ROOM[:2]})
    for bad, said in (
        (swapped, "columns 'water_in_temp_C' and 'water_out_temp_C': the heat to the water is -"),
        (two, "column 'water_out_temp_C': the heat to the water is"),
        (fahrenheit, "column 'water_out_temp_C': the heat to the water is"),
    ):
        with pytest.raises(LogError) as info:
            refuse_wrong_units(bad, params)
        assert said in str(info.value), str(info.value)
    assert "Fahrenheit?" in str(info.value)


def test_a_flow_of_zero_or_one_value_or_no_fuel_is_data_not_a_wrong_unit(logs):
    """CONTRACT section 4: zero flow and constant columns are data. The heat to the water
    of a flow that reads zero (or one value) throughout, or of a balance that loses no fuel,
    is no ground to refuse a log."""
    params = load_boiler(BOILER)
    log = logs["stationary"]
    for changes in (
        {"water_flow_kg_h": lambda x, t: np.zeros_like(x)},
        {"water_flow_kg_h": lambda x, t: np.full_like(x, 5.0)},
        {"water_flow_kg_h": lambda x, t: x / 60.0, "balance_mass_kg": lambda x, t: x * 0 + 250},
        {"water_flow_kg_h": lambda x, t: x / 60.0, "balance_mass_kg": lambda x, t: x * np.nan},
    ):
        refuse_wrong_units(_mutated(log, **changes), params)
    # the warning band stays a warning
    third = _mutated(log, water_flow_kg_h=lambda x, t: x / 3.0)
    refuse_wrong_units(third, params)
    assert any("is the flow in kg/h" in w for w in suspicious(third, params))


def test_a_log_of_another_boiler_size_is_warned_by_calibrate(run_log, tmp_path, capsys):
    """A stranger's probe: a 6-kW boiler's log calibrated as the 12-kW one (no meta file to
    tell) fitted dTnom 43 K (documented 97) and Pstart 7.1 kW (13.2) with no word. The fits
    stay, a warning names both figures, and the uncertainty file flags them."""
    src = run_log("stationary", "windhager_6kw").path
    bare = _rewritten(src, tmp_path, "six.csv", "room_temp_C", float)  # no meta file
    out = tmp_path / "c.yaml"
    assert main(["calibrate", str(bare), "--boiler", BOILER, "--out", str(out)]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "another boiler size" in ln]
    assert len(said) == 1, said
    assert "windhager_12kw" in said[0] and "13.2" in said[0] and "97" in said[0], said
    flags = json.loads(out.with_suffix(".uncertainty.json").read_text())
    assert "far_from_documentation" in flags["p_start_kW"]
    assert "far_from_documentation" in flags["dt_nom_K"]
    assert not flags["p_start_kW"]["implausible"]  # the fit is kept


def test_a_log_of_its_own_boiler_size_is_not_warned(logs, tmp_path, capsys):
    out = tmp_path / "c.yaml"
    src = logs["stationary"].path
    assert main(["calibrate", str(src), "--boiler", BOILER, "--out", str(out)]) == 0
    assert "another boiler size" not in capsys.readouterr().err
    flags = json.loads(out.with_suffix(".uncertainty.json").read_text())
    assert not any("far_from_documentation" in v for v in flags.values())


def test_too_few_rows_are_said_as_such(logs, tmp_path, capsys):
    """A stranger's probe: logs of 1, 2 or 20 rows said "cannot find t0: the burner never
    fires"; they say how many rows they have and the least the phases need."""
    lines = _rewritten(logs["stationary"].path, tmp_path, "x.csv", "room_temp_C", float)
    text = lines.read_text().splitlines()
    for n in (1, 2, 20):
        path = tmp_path / f"rows{n}.csv"
        path.write_text("\n".join(text[: n + 1]) + "\n")
        assert main(["balance", str(path), "--boiler", BOILER, "--out", str(tmp_path / "b")]) == 2
        err = capsys.readouterr().err.strip()
        assert err == (
            f"hil-client: error: {path}: only {n} data row(s); finding the phases from the "
            "signals needs at least 50 (preheat, start-up, test and two coolings, some ten "
            "readings each)"
        ), err


def test_every_warning_names_its_file(tmp_path, capsys):
    """A stranger's probe: diagnose warned "the record ends before the circulation stops"
    of the validation log without naming it (the phases' notes carry no file)."""
    from hil_client.cli import _warn_tolerated

    log = LabLog(tmp_path / "v.csv", {"time_s": np.arange(3.0)}, {}, {})
    log.notes.append("the record ends before the circulation stops (acquisition cut short?)")
    log.notes.append(f"{log.path}: 1 comment line(s) (#...) among the rows skipped")
    _warn_tolerated([log])
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"hil-client: warning: {log.path}: the record ends before the circulation stops "
        "(acquisition cut short?)",
        f"hil-client: warning: {log.path}: 1 comment line(s) (#...) among the rows skipped",
    ]
