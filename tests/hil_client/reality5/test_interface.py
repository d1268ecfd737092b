"""Plant 5 interface: names, determinism, sampling and jitter, CSV, errors, import isolation."""

from __future__ import annotations

import subprocess
import sys
import time

import numpy as np
import pytest

from hil_client.reality5 import EFFECT_FORMS, draw_background, simulate_log, write_log_csv
from hil_client.reality5.plant import COLUMNS

from .conftest import sim

EFFECTS = set(["body_heat_diffusion", "outlet_sensor_pipe", "ignition_delay", "flue_gas_lag"])
EFFECTS.add("fuel_energy_bias")
AVOIDED = """dead_time mixed_volume distributed_wall two_lump bed_ramp hhv_bias moisture first_order
second_order_store refractory_radiation delayed_wall tank_cascade dead_time_wall
bed_ignition_temperature random_start_delay regenerative_refractory wet_batch fines_unburnt"""


def test_effect_forms_vocabulary():
    assert set(EFFECT_FORMS) == EFFECTS
    names = [f for forms in EFFECT_FORMS.values() for f in forms]
    assert all(len(forms) >= 2 for forms in EFFECT_FORMS.values())
    assert len(set(names)) == len(names) and not set(names) & set(AVOIDED.split())


def test_background_is_drawn_from_rng(boilers):
    b = boilers["windhager_6kw"]
    a1 = draw_background(np.random.default_rng(4), b)
    a2 = draw_background(np.random.default_rng(4), b)
    a3 = draw_background(np.random.default_rng(5), b)
    assert a1 == a2 and a1 != a3
    assert all(isinstance(v, float) for v in a1.values())


def test_same_seed_same_log(boilers, backgrounds):
    b, bg = boilers["windhager_12kw"], backgrounds["windhager_12kw"]
    kw = {"background": bg, "effect": "flue_gas_lag", "form": "bimetal_bypass", "strength": 0.5}
    c1, m1 = simulate_log(b, "load_cycle", seed=9, jitter=True, **kw)
    c2, _ = simulate_log(b, "load_cycle", seed=9, jitter=True, **kw)
    c3, _ = simulate_log(b, "load_cycle", seed=10, jitter=True, **kw)
    for k in COLUMNS:
        nan = c1[k].dtype != object
        assert np.array_equal(c1[k], c2[k], equal_nan=nan)
    assert not np.array_equal(c1["water_out_temp_C"], c3["water_out_temp_C"])
    assert m1["t4_s"] > m1["t0_s"]


@pytest.mark.parametrize("sample_s", [1.0, 2.0, 5.0, 10.0])
def test_columns_and_sampling(boilers, backgrounds, sample_s):
    b, bg = boilers["windhager_6kw"], backgrounds["windhager_6kw"]
    cols, _ = sim(b, "stationary", bg, seed=1, sample_s=sample_s)
    assert list(cols) == list(COLUMNS)
    assert len({len(v) for v in cols.values()}) == 1
    assert np.allclose(np.diff(cols["time_s"]), sample_s)
    assert set(cols["phase"]) == {"preheat", "start_up", "test", "cooling_1", "cooling_2"}
    assert set(np.unique(cols["boiler_on"])) <= {0.0, 1.0}
    cj, _ = sim(b, "stationary", bg, seed=1, sample_s=sample_s, jitter=True)
    dt = np.diff(cj["time_s"])
    assert dt.min() > 0 and not np.allclose(dt, sample_s)
    assert len(cj["time_s"]) < len(cols["time_s"])
    assert dt.max() >= 2 * sample_s  # dropped rows


def test_write_log_csv(tmp_path, baselines):
    cols, _ = baselines[("windhager_12kw", "stationary")]
    path = tmp_path / "log.csv"
    write_log_csv(cols, path)
    lines = path.read_text().splitlines()
    assert lines[0].split(",") == list(COLUMNS) and len(lines) == len(cols["time_s"]) + 1
    o2 = COLUMNS.index("flue_gas_O2_pct")
    gaps = [ln for ln in lines[1:] if ln.split(",")[o2] == ""]  # analyser auto-zero
    assert gaps and len(gaps) < 0.05 * len(lines)
    assert float(lines[1].split(",")[0]) == pytest.approx(cols["time_s"][0])


def test_bad_names_raise(boilers, backgrounds):
    b, bg = boilers["windhager_6kw"], backgrounds["windhager_6kw"]
    for test, effect, form, s in [
        ("bogus", None, None, 0.0),
        ("stationary", "bogus", None, 0.0),
        ("stationary", "flue_gas_lag", "bogus", 0.0),
        ("stationary", "flue_gas_lag", "two_lump", 0.0),
        ("stationary", None, "bimetal_bypass", 0.0),
        ("stationary", "flue_gas_lag", "bimetal_bypass", 1.5),
    ]:
        with pytest.raises(ValueError):
            sim(b, test, bg, effect, form, s)


def test_load_cycle_is_fast(boilers, backgrounds):
    b, bg = boilers["windhager_12kw"], backgrounds["windhager_12kw"]
    sim(b, "load_cycle", bg, seed=0)
    t = time.perf_counter()
    sim(b, "load_cycle", bg, "ignition_delay", "char_shrinking_core", 1.0, seed=1, jitter=True)
    assert time.perf_counter() - t < 3.0


def test_imports_only_itself():
    code = "\n".join(
        [
            "import sys, hil_client.reality5",
            "r = 'hil_client.reality'",
            "no = ('rig_emulator', 'hil_client.analysis')",
            "bad = [m for m in sys.modules if m.startswith(no)",
            "       or (m.startswith(r) and not m.startswith(r + '5'))]",
            "ok = ('numpy', 'scipy', 'numba', 'yaml', 'llvmlite', 'hil_client', 'cython_runtime')",
            "third = {m.split('.')[0] for m in sys.modules} - set(sys.stdlib_module_names)",
            "print(bad, sorted(t for t in third if not t.startswith(ok) and t[0] != '_'))",
        ]
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[] []", out.stdout
