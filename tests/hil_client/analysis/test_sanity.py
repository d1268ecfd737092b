"""Warnings for what in a log looks like a wrong unit or a broken sensor
(hil_client.analysis.sanity): each mutation a stranger's probe made of a lab log (a flow in
l/min, temperatures in kelvin, a stuck forward sensor, oxygen offset or read as a fraction,
a negative flow, a drifting balance) gave confident figures without a word. Each is now
named in one line by every analysis; the emulator's own logs get none."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil_client.analysis.logio import LabLog, read_log
from hil_client.analysis.sanity import suspicious
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
    "kelvin": ({n: lambda x, t: x + 273.15 for n in _WATER_AND_ROOM}, "(kelvin?)"),
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
    """A flow in l/min: the direct efficiency of 1.3 % came without a word; the figures stay
    (a warning cannot know the right unit), the warning names where to look."""
    src = logs["stationary"]
    lines = src.path.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index("water_flow_kg_h")
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        r[col] = f"{float(r[col]) / 60.0:.5f}" if r[col] else r[col]
    path = tmp_path / "lmin.csv"
    path.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    out = tmp_path / "b.json"
    assert main(["balance", str(path), "--boiler", BOILER, "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"hil-client: warning: {path}: the heat to the water is" in err
    assert json.loads(out.read_text())["balance"]


def _rewritten(src, tmp_path, name: str, column: str, change) -> object:
    """``src`` with ``column`` changed, without its phase columns (a lab's own log, whose
    phases are found from the signals) and without its meta file."""
    lines = src.read_text().splitlines()
    header = lines[0].split(",")
    col = header.index(column)
    keep = [i for i, h in enumerate(header) if h not in ("phase", "sequence")]
    rows = [r.split(",") for r in lines[1:]]
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
    assert "cannot find" in err and "kg/h" in err and len(err.splitlines()) == 1, err
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
