"""The API the gap benchmark calls: forms, determinism, sampling, columns, the CSV, and the
plant's independence from the emulator and the analysis (checked in a subprocess)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest

from hil_client.reality import EFFECT_FORMS, simulate_log, write_log_csv
from tests.hil_client.reality.conftest import background, boiler, run

CONTRACT_COLUMNS = [
    "time_s", "phase", "sequence", "water_flow_kg_h", "water_in_temp_C", "water_out_temp_C",
    "boiler_water_temp_C", "flue_gas_temp_C", "flue_gas_O2_pct", "flue_gas_CO2_pct",
    "flue_gas_CO_ppm", "flue_gas_velocity_m_s", "chimney_draught_Pa", "balance_mass_kg",
    "room_temp_C", "ambient_pressure_hPa", "relative_humidity_pct", "electric_power_W",
    "water_flow_setpoint_kg_h", "boiler_on",
]  # fmt: skip


def test_every_effect_has_two_forms():
    assert set(EFFECT_FORMS) == {
        "body_heat_diffusion",
        "outlet_sensor_pipe",
        "ignition_delay",
        "flue_gas_lag",
        "fuel_energy_bias",
    }
    for forms in EFFECT_FORMS.values():
        assert len(set(forms)) >= 2


def test_columns_are_the_contracts():
    cols, _ = run("stationary")
    assert list(cols) == CONTRACT_COLUMNS
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    assert set(cols["boiler_on"][~np.isnan(cols["boiler_on"])]) <= {0.0, 1.0}


def test_deterministic_for_a_seed():
    a, _ = run("load_cycle", "flue_gas_lag", "second_order", 0.3, jitter=True)
    b, _ = simulate_log(
        boiler(),
        "load_cycle",
        background=background(),
        effect="flue_gas_lag",
        form="second_order",
        strength=0.3,
        seed=7,
        sample_s=5.0,
        jitter=True,
    )
    for k in a:
        if a[k].dtype == object:
            assert list(a[k]) == list(b[k])
        else:
            np.testing.assert_array_equal(a[k], b[k])
    c, _ = run("load_cycle", "flue_gas_lag", "second_order", 0.3, jitter=True, seed=8)
    assert not np.array_equal(a["water_out_temp_C"][:1000], c["water_out_temp_C"][:1000])


@pytest.mark.parametrize("sample_s", [1.0, 2.0, 10.0])
def test_regular_sampling(sample_s):
    cols, _ = run("stationary", sample_s=sample_s)
    np.testing.assert_allclose(np.diff(cols["time_s"]), sample_s, atol=1e-6)


def test_jittered_sampling_is_irregular_and_increasing():
    cols, _ = run("stationary", sample_s=2.0, jitter=True)
    d = np.diff(cols["time_s"])
    assert np.all(d > 0)
    assert d.min() >= 0.75 * 2.0 - 1e-3 and d.max() <= 2.25 * 2.0 + 1e-3
    assert d.std() > 0.1
    assert np.sum(d > 1.3 * 2.0) >= 1  # a missed acquisition or more


def test_dropouts_are_nan_and_written_empty(tmp_path):
    cols, _ = run("stationary", bg_items=(("dropout_p", 0.01),))
    nans = np.isnan(cols["water_out_temp_C"])
    assert 0 < nans.sum() < 0.05 * len(nans)
    path = tmp_path / "log.csv"
    write_log_csv(cols, path)
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    assert header == CONTRACT_COLUMNS
    j = header.index("water_out_temp_C")
    i = int(np.flatnonzero(nans)[0])
    assert body[i][j] == ""
    ok = int(np.flatnonzero(~nans)[0])
    assert float(body[ok][j]) == pytest.approx(cols["water_out_temp_C"][ok], abs=0.005)
    assert body[i][header.index("phase")] in {
        "preheat",
        "start_up",
        "test",
        "cooling_1",
        "cooling_2",
    }


def test_write_log_csv_puts_time_first_and_refuses_ragged(tmp_path):
    path = tmp_path / "x.csv"
    write_log_csv({"a": np.array([1.0, np.nan]), "time_s": np.array([0.0, 1.0])}, path)
    assert path.read_text().splitlines() == ["time_s,a", "0.000,1.0000", "1.000,"]
    with pytest.raises(ValueError, match="column a"):
        write_log_csv({"time_s": np.array([0.0, 1.0]), "a": np.array([1.0])}, path)
    with pytest.raises(ValueError, match="time_s"):
        write_log_csv({"a": np.array([1.0])}, path)


def test_bad_arguments_are_named():
    kw = {"background": background(), "seed": 1, "sample_s": 5.0, "jitter": False}
    with pytest.raises(ValueError, match="unknown effect"):
        simulate_log(boiler(), "stationary", effect="nope", form="x", strength=0.5, **kw)
    with pytest.raises(ValueError, match="unknown form"):
        simulate_log(boiler(), "stationary", effect="flue_gas_lag", form="x", strength=0.5, **kw)
    with pytest.raises(ValueError, match="strength"):
        simulate_log(
            boiler(), "stationary", effect="flue_gas_lag", form="first_order", strength=2, **kw
        )
    with pytest.raises(ValueError, match="test"):
        simulate_log(boiler(), "other", effect=None, form=None, strength=0.0, **kw)
    with pytest.raises(ValueError, match="sample_s"):
        simulate_log(
            boiler(), "stationary", effect=None, form=None, strength=0.0, **(kw | {"sample_s": 20})
        )


def test_the_projects_reader_finds_the_phases(tmp_path):
    """The project's log reader and phase finder (which the plant does not use) read the CSV
    without phase columns and find t0..t3 near the plant's own marks."""
    from hil_client.analysis.logio import read_log
    from hil_client.analysis.phases import find_phases

    cols, meta = run("stationary")
    path = tmp_path / "blind.csv"
    write_log_csv({k: v for k, v in cols.items() if k not in ("phase", "sequence")}, path)
    ph = find_phases(read_log(path))
    assert ph.t0 == pytest.approx(meta["t0_s"], abs=120)
    assert ph.t2 == pytest.approx(meta["t2_s"], abs=120)


FORBIDDEN = (
    "rig_emulator.model",
    "rig_emulator.bench",
    "rig_emulator.instruments",
    "hil_client.analysis",
)


def test_plant_imports_neither_the_emulator_nor_the_analysis(tmp_path):
    """In a fresh interpreter: import the plant, run a log with an effect, write it; then no
    module of the emulator's model, bench or instruments nor of the analysis is loaded."""
    boiler_path = tmp_path / "b.json"
    boiler_path.write_text(json.dumps(boiler()))
    code = f"""
import json, sys
import numpy as np
from hil_client.reality import draw_background, simulate_log, write_log_csv
b = json.load(open({str(boiler_path)!r}))
bg = draw_background(np.random.default_rng(3), b)
cols, meta = simulate_log(b, "load_cycle", background=bg, effect="ignition_delay",
                          form="bed_ramp", strength=0.5, seed=3, sample_s=10.0, jitter=True)
write_log_csv(cols, {str(tmp_path / "l.csv")!r})
bad = sorted(m for m in sys.modules if m.startswith({FORBIDDEN!r}))
print(json.dumps({{"rows": len(cols["time_s"]), "bad": bad}}))
"""
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=True
    )
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["rows"] > 3000
    assert result["bad"] == []
