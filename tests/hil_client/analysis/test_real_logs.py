"""Real logs are data, not errors (issue 10, CONTRACT section 4): a generated corpus of the
ways lab logs differ from the project's own (zero flow, gaps, constant or missing columns,
1-10 s or irregular sampling, a record that starts mid-test, a balance refill). Every one
gives a diagnosis (exit 0 and a diagnosis.json) or one line naming what is wrong (exit 2);
never a traceback, and ``calibrate`` keeps what it can."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import yaml

from hil_client.cli import main
from hil_client.protocol.definition import DEFINITION_DIR
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.instruments.profile import PROFILE_DIR

BOILER = "windhager_6kw"
OPTIONAL = (
    "phase",
    "sequence",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "water_flow_setpoint_kg_h",
    "boiler_on",
)


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A stationary test and a load cycle of the emulated lab with the exit-pipe effect,
    acquired every 5 s (a lab's 1-10 s; a fifth of the rows of 1 s: the corpus's diagnoses
    and calibrations take the suite's time by the row, and the variants then thin or
    jitter further)."""
    out = tmp_path_factory.mktemp("real")
    profile = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    profile["effects"] = {"outlet_sensor_pipe": {"strength": 1.0}}
    (out / "p.yaml").write_text(yaml.safe_dump(profile))
    paths = {}
    for test in ("stationary", "load_cycle"):
        protocol = yaml.safe_load((DEFINITION_DIR / f"{test}.yaml").read_text())
        protocol["acquisition_period_s"] = 5
        (out / f"{test}.yaml").write_text(yaml.safe_dump(protocol))
        path = out / f"{test}.csv"
        argv = ["run", str(out / f"{test}.yaml"), "--boiler", BOILER]
        argv += ["--profile", str(out / "p.yaml")]
        assert main([*argv, "--seed", "4", "--out", str(path), "--quiet"]) == 0
        path.with_name(path.stem + ".meta.json").unlink()
        paths[test] = path
    return paths


def _read(path):
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], rows[1:]


def _write(path, header, rows):
    with path.open("w", newline="") as fh:
        csv.writer(fh).writerows([header, *rows])


def _column(header, rows, name):
    j = header.index(name)
    return np.array([float(r[j]) if r[j] else np.nan for r in rows])


def _set(header, rows, name, values):
    j = header.index(name)
    for r, v in zip(rows, values, strict=True):
        r[j] = "" if np.isnan(v) else f"{v:.6g}"


def zero_flow(header, rows, rng):
    """The pump stops for 10 min in the middle of the test (flow exactly 0)."""
    t = _column(header, rows, "time_s")
    flow = _column(header, rows, "water_flow_kg_h")
    mid = t[0] + 0.45 * (t[-1] - t[0])
    flow[(t > mid) & (t < mid + 600)] = 0.0
    _set(header, rows, "water_flow_kg_h", flow)
    return header, rows


def gaps(header, rows, rng):
    """5 % of the fields empty, and a 15-min outage of every instrument."""
    t = _column(header, rows, "time_s")
    mid = t[0] + 0.3 * (t[-1] - t[0])
    for name in header[1:]:
        if name in ("phase", "sequence"):
            continue
        v = _column(header, rows, name)
        v[rng.random(len(v)) < 0.05] = np.nan
        v[(t > mid) & (t < mid + 900)] = np.nan
        _set(header, rows, name, v)
    return header, rows


def constant_columns(header, rows, rng):
    """A dead analyser (O2 frozen), a room sensor stuck, electricity meter at 0."""
    for name, value in (("flue_gas_O2_pct", 20.9), ("room_temp_C", 21.0)):
        _set(header, rows, name, np.full(len(rows), value))
    return header, rows


def bare(header, rows, rng):
    """Only the required columns (no phase, sequence, setpoint, boiler_on, ...)."""
    keep = [i for i, h in enumerate(header) if h not in OPTIONAL]
    return [header[i] for i in keep], [[r[i] for i in keep] for r in rows]


def every_10_s(header, rows, rng):
    """Sampled every 10 s (every second row of the 5-s record)."""
    return header, rows[::2]


def irregular(header, rows, rng):
    """Irregular sampling: 5 or 10 s between rows (1 or 2 rows of the 5-s record)."""
    idx = np.cumsum(rng.integers(1, 3, len(rows)))
    return header, [rows[i] for i in idx[idx < len(rows)]]


def mid_test_start(header, rows, rng):
    """The record starts 2 h into the test (no preheat, no start-up)."""
    t = _column(header, rows, "time_s")
    keep = [r for r, ti in zip(rows, t, strict=True) if ti >= t[0] + 4 * 3600]
    t0 = float(keep[0][0])
    for r in keep:
        r[0] = f"{float(r[0]) - t0:g}"
    return header, keep


def refill(header, rows, rng):
    """A pellet refill: the balance jumps by +15 kg during the test."""
    t = _column(header, rows, "time_s")
    mass = _column(header, rows, "balance_mass_kg")
    mass[t > t[0] + 0.5 * (t[-1] - t[0])] += 15.0
    _set(header, rows, "balance_mass_kg", mass)
    return header, rows


def cut_short(header, rows, rng):
    """The acquisition killed 20 min after the circulation stopped: no settled second
    cooling (the stand-by the flue gas's idle level is read from), the file valid up to
    the cut."""
    t = _column(header, rows, "time_s")
    flowing = np.flatnonzero(_column(header, rows, "water_flow_kg_h") > 0.0)
    end = t[flowing[-1]] + 1200.0 if len(flowing) else t[-1]
    return header, [r for r, ti in zip(rows, t, strict=True) if ti <= end]


def analyser_off(header, rows, rng):
    """The gas analyser not connected: the O2 column is there, every field empty."""
    _set(header, rows, "flue_gas_O2_pct", np.full(len(rows), np.nan))
    return header, rows


def error_codes(header, rows, rng):
    """A thermocouple amplifier logs -999 for 2 % of the flue-gas readings, the boiler
    probe's transmitter 9999 once: error codes, not temperatures."""
    fg = _column(header, rows, "flue_gas_temp_C")
    fg[rng.random(len(fg)) < 0.02] = -999.0
    water = _column(header, rows, "boiler_water_temp_C")
    water[len(water) // 2] = 9999.0
    _set(header, rows, "flue_gas_temp_C", fg)
    _set(header, rows, "boiler_water_temp_C", water)
    return header, rows


def stuck_balance(header, rows, rng):
    """The balance's reading frozen for the whole record (a load cell stuck, or its
    channel logging a constant): no fuel can be read from it."""
    mass = _column(header, rows, "balance_mass_kg")
    _set(header, rows, "balance_mass_kg", np.full(len(rows), mass[0]))
    return header, rows


def byte_order_mark(header, rows, rng):
    """Saved by a spreadsheet: a UTF-8 byte-order mark before the first column's name."""
    return ["\ufeff" + header[0], *header[1:]], rows


VARIANTS = (
    stuck_balance,
    byte_order_mark,
    analyser_off,
    error_codes,
    cut_short,
    zero_flow,
    gaps,
    constant_columns,
    bare,
    every_10_s,
    irregular,
    mid_test_start,
    refill,
)


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: v.__name__)
def test_diagnose_and_calibrate_take_real_logs(logs, variant, tmp_path, capsys):
    rng = np.random.default_rng(7)
    cal = tmp_path / "cal.csv"
    _write(cal, *variant(*_read(logs["stationary"]), rng))
    val = tmp_path / "val.csv"
    _write(val, *variant(*_read(logs["load_cycle"]), rng))
    capsys.readouterr()
    argv = ["--calibration", str(cal), "--validation", str(val), "--boiler", BOILER]
    code = main(["diagnose", *argv, "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code in (0, 2), err
    if code == 2:  # one line naming what is wrong, nothing written
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert not (tmp_path / "d").exists()
    else:
        result = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
        # never silently wrong: the plant's effect, or no verdict
        assert result["effect"] in ("outlet_sensor_pipe", "none")
        assert 0.0 <= result["confidence"] <= 1.0
        # nothing named on evidence that is not a number (a signal the log lacks)
        assert not [c["effect"] for c in result["candidates"] if c["named"] and c["score"] is None]
        assert isinstance(result["unexplained_gap"], bool)
    code = main(["calibrate", str(cal), "--boiler", BOILER, "--out", str(tmp_path / "p.yaml")])
    err = capsys.readouterr().err
    assert code in (0, 2), err
    if code == 2:
        assert err.count("\n") == 1 and "Traceback" not in err, err
    else:
        assert (tmp_path / "p.yaml").exists()


def test_a_calibration_log_without_its_analyser_names_no_fuel_on_nan(logs, tmp_path, capsys):
    """The analyser disconnected for the calibration log only: the closure has no flue-gas
    loss to count, so the fuel is not read (an empty O2 column once named the fuel on a
    closure that was not a number)."""
    cal = tmp_path / "cal.csv"
    _write(cal, *analyser_off(*_read(logs["stationary"]), None))
    argv = ["--calibration", str(cal), "--validation", str(logs["load_cycle"])]
    assert main(["diagnose", *argv, "--boiler", BOILER, "--out", str(tmp_path / "d")]) == 0
    result = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    fuel = next(c for c in result["candidates"] if c["effect"] == "fuel_energy_bias")
    assert not fuel["named"] and fuel["evidence_units"] == 0


def test_a_log_cut_mid_line_before_its_cooling_gets_one_line(logs, tmp_path, capsys):
    """The acquisition killed in the test phase while writing a row: the half row is
    tolerated, a record without the end of its test is not (a record cut in its first
    cooling is, see test_logio_phases); the user reads one line, the error, not a warning
    about the half row before it."""
    text = logs["stationary"].read_text()
    cal = tmp_path / "cal.csv"
    cal.write_text(text[: int(0.4 * len(text))].rsplit("\n", 1)[0] + "\n12345.6,7")
    capsys.readouterr()
    argv = ["--calibration", str(cal), "--validation", str(logs["load_cycle"])]
    code = main(["diagnose", *argv, "--boiler", BOILER, "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "cannot find" in err, err


def test_the_held_out_log_must_be_another_log(logs, tmp_path, capsys):
    """The calibration log given again as the held-out one (by another path: a copy)
    would report a shrinkage on the data it was fitted on: one line, exit 2."""
    copy = tmp_path / "copy.csv"
    copy.write_bytes(logs["stationary"].read_bytes())
    capsys.readouterr()
    argv = ["--calibration", str(logs["stationary"]), "--validation", str(copy)]
    code = main(["diagnose", *argv, "--boiler", BOILER, "--out", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "same log" in err, err
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("variant", (every_10_s, irregular), ids=lambda v: v.__name__)
def test_calibrate_finds_the_load_cycles_plateaus_at_any_sampling(logs, variant, tmp_path):
    """The stationary intervals are found by time, not by row count: the load cycle's
    50-min plateaus are as usable sampled every 10 s as every second."""
    cal = tmp_path / "lc.csv"
    _write(cal, *variant(*_read(logs["load_cycle"]), np.random.default_rng(3)))
    out = tmp_path / "p.yaml"
    assert main(["calibrate", str(cal), "--boiler", BOILER, "--out", str(out)]) == 0
    fitted = json.loads(out.with_name("p.uncertainty.json").read_text())
    # the plateaus span flows from 13 % to 100 % load: the Fig. 4 slope is fitted from them
    assert fitted["dt_hx_wat_K"]["points"] >= 3


def test_calibrate_without_a_stationary_interval_keeps_the_documented_values(logs, tmp_path):
    """A boiler whose water never holds within 3 K during the test (here: a 3-K square wave
    every 10 min added to the reading, as a staged controller's swing might look) gives no
    stationary interval; calibrate still fits what the rest of the log gives, keeps the
    documentation values of Eq. 8, Eq. 9 and the electric power, flags them, writes the
    file and exits 0."""
    header, rows = _read(logs["stationary"])
    col, t_col = header.index("boiler_water_temp_C"), header.index("time_s")
    for row in rows:
        if row[col]:
            swing = 3.0 if int(float(row[t_col]) // 600) % 2 else 0.0
            row[col] = f"{float(row[col]) + swing:.2f}"
    cal = tmp_path / "swing.csv"
    _write(cal, header, rows)
    out = tmp_path / "p.yaml"
    assert main(["calibrate", str(cal), "--boiler", BOILER, "--out", str(out)]) == 0
    fitted = json.loads(out.with_name("p.uncertainty.json").read_text())
    doc = yaml.safe_load((BOILER_DIR / f"{BOILER}.yaml").read_text())
    written = yaml.safe_load(out.read_text())
    for key in ("dt_nom_K", "fac_a_lambda"):
        assert fitted[key]["value"] is None and fitted[key]["kept"] == doc[key]
        assert "no stationary interval" in fitted[key]["why"]
        assert written[key] == doc[key]
    # the second cooling is still fitted, and used
    assert fitted["ua_amb_off_W_K"]["value"] == pytest.approx(written["ua_amb_off_W_K"])
