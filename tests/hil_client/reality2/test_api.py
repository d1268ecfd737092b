"""The plant's API as the gap benchmark uses it: forms, columns, determinism, sampling,
CSV, bad input, and that it needs none of the emulator's physics or the analysis."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from hil_client.reality2 import EFFECT_FORMS, simulate_log, write_log_csv
from tests.hil_client.reality2.conftest import background, boiler, run

CONTRACT_COLUMNS = (
    "time_s",
    "phase",
    "sequence",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "balance_mass_kg",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "water_flow_setpoint_kg_h",
    "boiler_on",
)
EFFECTS = (
    "body_heat_diffusion",
    "outlet_sensor_pipe",
    "ignition_delay",
    "flue_gas_lag",
    "fuel_energy_bias",
)


def test_every_listed_effect_has_at_least_two_distinct_forms():
    assert set(EFFECT_FORMS) == set(EFFECTS)
    for forms in EFFECT_FORMS.values():
        assert len(forms) >= 2 and len(set(forms)) == len(forms)


def test_log_has_the_contract_columns_and_phases_in_order():
    columns, meta = run()
    assert tuple(columns) == CONTRACT_COLUMNS
    n = len(columns["time_s"])
    assert all(len(v) == n for v in columns.values())
    phases = [p for i, p in enumerate(columns["phase"]) if i == 0 or columns["phase"][i - 1] != p]
    assert phases == ["preheat", "start_up", "test", "cooling_1", "cooling_2"]
    # the marks are where the phase column changes, and t4 = t2 + 8 h (protocol)
    t, ph = columns["time_s"], columns["phase"]
    assert meta["t1_s"] == pytest.approx(t[np.flatnonzero(ph == "test")[0] - 1])
    assert meta["t4_s"] - meta["t2_s"] == pytest.approx(8 * 3600.0)
    test_rows = ph == "test"
    assert meta["t2_s"] - meta["t1_s"] == pytest.approx(6 * 3600.0)  # stationary: 6 h
    assert set(columns["sequence"][test_rows]) == {"stationary_100"}
    assert set(columns["sequence"][~test_rows]) == {""}


def test_load_cycle_runs_its_sequences_in_order():
    columns, meta = run(test="load_cycle")
    seq = [s for i, s in enumerate(columns["sequence"]) if s and columns["sequence"][i - 1] != s]
    assert seq[0] == "peak" and seq[-1] == "stationary_13" and len(seq) == 11
    assert meta["t2_s"] - meta["t1_s"] == pytest.approx(8 * 3600.0, abs=2.0)


def test_same_seed_same_log_other_seed_other_log():
    a, _ = run(seed=3)
    b, _ = simulate_log(
        boiler("windhager_12kw"),
        "stationary",
        background=background("windhager_12kw", 3),
        effect=None,
        form=None,
        strength=0.0,
        seed=3,
        sample_s=1.0,
        jitter=False,
    )
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=a[k].dtype != object), k
    c, _ = run(seed=4)
    assert len(c["time_s"]) != len(a["time_s"]) or not np.array_equal(
        c["water_out_temp_C"], a["water_out_temp_C"], equal_nan=True
    )


@pytest.mark.parametrize("sample_s", [2.0, 5.0, 10.0])
def test_sampling_period_sets_the_row_spacing(sample_s):
    fine, _ = run(seed=3)
    coarse, _ = run(seed=3, sample_s=sample_s)
    dt = np.diff(coarse["time_s"])
    assert np.all(dt[:-1] == sample_s)  # the last row is t4 itself
    assert len(coarse["time_s"]) == pytest.approx(len(fine["time_s"]) / sample_s, rel=0.02)


def test_jitter_gives_irregular_strictly_increasing_times():
    columns, meta = run(seed=3, sample_s=5.0, jitter=True)
    dt = np.diff(columns["time_s"])
    assert np.all(dt > 0)
    assert dt.std() > 0.5  # irregular
    assert 3.0 < np.median(dt) < 7.0
    assert meta["jitter"] is True


def test_missing_readings_are_nan_and_written_as_empty_fields(tmp_path):
    columns, _ = run(seed=3)
    n_nan = sum(int(np.isnan(v).sum()) for k, v in columns.items() if v.dtype != object)
    assert n_nan > 0  # dropouts are drawn per background: seed 3 has some
    path = tmp_path / "log.csv"
    write_log_csv(columns, path)
    with path.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        rows = list(reader)
    assert header[0] == "time_s" and tuple(header) == CONTRACT_COLUMNS
    assert len(rows) == len(columns["time_s"])
    empty = sum(field == "" for row in rows for j, field in enumerate(row) if j >= 3)
    assert empty == n_nan
    assert "nan" not in path.read_text().lower()
    # numbers read back as written
    j = header.index("water_out_temp_C")
    k = np.flatnonzero(~np.isnan(columns["water_out_temp_C"]))[100]
    assert float(rows[k][j]) == pytest.approx(columns["water_out_temp_C"][k], abs=1e-6)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"effect": "rust"}, "unknown effect"),
        ({"effect": "flue_gas_lag", "form": "wet_batch"}, "has forms"),
        ({"effect": "flue_gas_lag", "form": "second_order_store", "strength": 1.5}, "strength"),
        ({"sample_s": 0.5}, "sample_s"),
        ({"sample_s": 11.0}, "sample_s"),
    ],
)
def test_bad_arguments_are_refused_with_a_clear_message(kwargs, match):
    args = {"effect": None, "form": None, "strength": 0.5, "seed": 1, "sample_s": 1.0}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        simulate_log(
            boiler("windhager_6kw"),
            "stationary",
            background=background("windhager_6kw", 1),
            jitter=False,
            **args,
        )
    with pytest.raises(ValueError, match="test must be"):
        simulate_log(
            boiler("windhager_6kw"),
            "sprint",
            background=background("windhager_6kw", 1),
            effect=None,
            form=None,
            strength=0.0,
            seed=1,
        )


def test_plant_imports_neither_the_emulator_physics_nor_the_analysis():
    code = textwrap.dedent(
        """
        import sys, yaml, numpy as np
        from pathlib import Path
        import hil_client.reality2 as plant
        boiler = yaml.safe_load(Path("rig_emulator/boilers/windhager_6kw.yaml").read_text())
        bg = plant.draw_background(np.random.default_rng(1), boiler)
        for effect, forms in plant.EFFECT_FORMS.items():
            plant.simulate_log(boiler, "stationary", background=bg, effect=effect,
                               form=forms[-1], strength=0.5, seed=1, sample_s=10.0, jitter=True)
        bad = [m for m in sys.modules if m.startswith(("rig_emulator.model",
               "rig_emulator.bench", "rig_emulator.instruments", "hil_client.analysis"))]
        print("BAD", bad)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=True
    )
    assert "BAD []" in out.stdout, out.stdout + out.stderr


def test_background_is_drawn_per_case_and_finite():
    a = background("windhager_12kw", 1)
    b = background("windhager_12kw", 2)
    assert a != b
    for v in a.values():
        if isinstance(v, float):
            assert math.isfinite(v)
