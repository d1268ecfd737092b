"""The reality3 API: every effect and form, both tests and both boilers, determinism, CSV."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hil_client.reality3 import (
    EFFECT_FORMS,
    LOG_COLUMNS,
    draw_background,
    simulate_log,
    write_log_csv,
)

EFFECTS = ("body_heat_diffusion", "outlet_sensor_pipe", "ignition_delay", "flue_gas_lag")
EFFECTS += ("fuel_energy_bias",)
PHASES = {"preheat", "start_up", "test", "cooling_1", "cooling_2"}


def test_effect_forms_vocabulary():
    assert set(EFFECT_FORMS) == set(EFFECTS)
    for forms in EFFECT_FORMS.values():
        assert len(forms) == 2 and len(set(forms)) == 2
    taken = {
        "refractory_radiation", "delayed_conducting_wall", "distributed_wall", "two_lumps",
        "tank_cascade", "plug_flow_dead_time", "bed_ignition_temperature", "gamma_delay",
        "dead_time", "bed_ramp", "second_order_store", "regenerative_refractory",
        "first_order", "wet_batch", "fines_unburnt", "hhv_bias", "moisture",
    }  # fmt: skip
    assert not taken & {f for forms in EFFECT_FORMS.values() for f in forms}


def _check_log(cols: dict, meta: dict, boiler: dict, test: str) -> None:
    assert list(cols) == list(LOG_COLUMNS)
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    marks = [meta[f"t{i}_s"] for i in range(5)]
    assert 0.0 < marks[0] < marks[1] < marks[2] < marks[3] < marks[4]
    assert marks[4] - marks[2] == pytest.approx(8 * 3600.0, abs=2.0)
    assert marks[2] - marks[1] == pytest.approx(6 * 3600 if test == "stationary" else 8 * 3600)
    t = cols["time_s"]
    assert t[0] == 0.0 and np.all(np.diff(t) > 0.0) and t[-1] <= marks[4] + 1e-9
    for name, v in cols.items():
        if name in ("phase", "sequence"):
            continue
        assert np.all(np.isfinite(v)), name
    assert set(np.unique(cols["phase"])) == PHASES
    # phases agree with the marks
    in_test = (t >= marks[1] + 1.0) & (t < marks[2] - 1.0)
    assert np.all(cols["phase"][in_test] == "test")
    assert np.all(cols["phase"][t > marks[3] + 1.0] == "cooling_2")
    if test == "load_cycle":
        assert {"peak", "stationary_13", "gradient_30_13"} <= set(cols["sequence"][in_test])
    # plausible ranges
    assert np.all(cols["water_flow_kg_h"][t > marks[3] + 180.0] == 0.0)  # pump run-down
    m_nom = boiler["p_nom_kW"] * 3600.0 / (4.186 * 15.0)
    assert np.max(cols["water_flow_setpoint_kg_h"]) == pytest.approx(m_nom, rel=1e-3)
    assert 60.0 < np.median(cols["boiler_water_temp_C"][in_test]) < 80.0
    assert np.min(cols["flue_gas_O2_pct"]) >= 0.0
    assert np.max(cols["flue_gas_O2_pct"]) < 21.5
    assert set(np.unique(cols["boiler_on"])) == {0.0, 1.0}
    assert np.all(cols["boiler_on"][t < marks[0]] == 0.0)
    assert np.all(cols["electric_power_W"] > 0.0)
    assert np.min(cols["chimney_draught_Pa"]) < 0.0


@pytest.mark.parametrize("name", ["windhager_12kw", "windhager_6kw"])
@pytest.mark.parametrize("test", ["stationary", "load_cycle"])
def test_every_effect_form_and_strength(boilers, name, test):
    boiler = boilers[name]
    bg = draw_background(np.random.default_rng(1), boiler)
    cols, meta = simulate_log(
        boiler, test, background=bg, effect=None, form=None, strength=0.0, seed=1, sample_s=5.0
    )
    _check_log(cols, meta, boiler, test)
    assert meta["truth"]["effect"] == "none"
    for effect, forms in EFFECT_FORMS.items():
        for form in forms:
            for strength in (0.0, 0.5, 1.0):
                cols, meta = simulate_log(
                    boiler, test, background=bg, effect=effect, form=form,
                    strength=strength, seed=1, sample_s=5.0,
                )  # fmt: skip
                _check_log(cols, meta, boiler, test)
                truth = meta["truth"]
                assert (truth["effect"], truth["form"], truth["strength"]) == (
                    effect,
                    form,
                    strength,
                )
                assert truth["form_params"]
                assert json.loads(json.dumps(meta)) == meta  # a meta.json as it is


@pytest.mark.parametrize(("effect", "form"), [(e, f) for e, fs in EFFECT_FORMS.items() for f in fs])
def test_same_seed_same_log(boilers, effect, form):
    boiler = boilers["windhager_6kw"]
    bg = draw_background(np.random.default_rng(4), boiler)
    kw = dict(background=bg, effect=effect, form=form, strength=0.5, sample_s=2.0, jitter=True)
    a, ma = simulate_log(boiler, "load_cycle", seed=9, **kw)
    b, mb = simulate_log(boiler, "load_cycle", seed=9, **kw)
    c, _ = simulate_log(boiler, "load_cycle", seed=10, **kw)
    assert ma == mb
    for name in a:
        assert np.array_equal(a[name], b[name]), name
    assert len(c["time_s"]) != len(a["time_s"]) or not np.array_equal(
        c["water_out_temp_C"], a["water_out_temp_C"]
    )


def test_background_draw_is_reproducible_and_varies(boilers):
    boiler = boilers["windhager_12kw"]
    a = draw_background(np.random.default_rng(2), boiler)
    b = draw_background(np.random.default_rng(2), boiler)
    c = draw_background(np.random.default_rng(3), boiler)
    assert a == b and a != c
    assert all(isinstance(v, (float, str)) for v in a.values())


@pytest.mark.parametrize("sample_s", [1.0, 3.0, 10.0])
def test_sampling_and_jitter(boilers, sample_s):
    boiler = boilers["windhager_6kw"]
    bg = draw_background(np.random.default_rng(6), boiler)
    cols, meta = simulate_log(
        boiler, "stationary", background=bg, effect=None, form=None, strength=0.0, seed=6,
        sample_s=sample_s,
    )  # fmt: skip
    assert np.allclose(np.diff(cols["time_s"]), sample_s)
    jit, meta_j = simulate_log(
        boiler, "stationary", background=bg, effect=None, form=None, strength=0.0, seed=6,
        sample_s=sample_s, jitter=True,
    )  # fmt: skip
    d = np.diff(jit["time_s"])
    assert d.min() >= 0.6 * sample_s - 1e-3 and d.max() <= 1.4 * sample_s + 1e-3
    assert d.std() > 0.1 * sample_s
    assert abs(d.mean() - sample_s) < 0.02 * sample_s
    assert meta_j["t2_s"] == meta["t2_s"]  # the plant does not depend on the acquisition
    with pytest.raises(ValueError, match="sample_s"):
        simulate_log(
            boiler, "stationary", background=bg, effect=None, form=None, strength=0.0, seed=6,
            sample_s=0.5,
        )  # fmt: skip


def test_bad_effect_and_test_names(boilers):
    boiler = boilers["windhager_6kw"]
    bg = draw_background(np.random.default_rng(0), boiler)
    with pytest.raises(ValueError, match="effect"):
        simulate_log(boiler, "stationary", background=bg, effect="x", form=None, strength=0, seed=0)
    with pytest.raises(ValueError, match="form"):
        simulate_log(
            boiler, "stationary", background=bg, effect="ignition_delay", form="radiant_hot_steel",
            strength=0, seed=0,
        )  # fmt: skip
    with pytest.raises(ValueError, match="test"):
        simulate_log(boiler, "sprint", background=bg, effect=None, form=None, strength=0, seed=0)


def test_write_log_csv(boilers, tmp_path):
    boiler = boilers["windhager_6kw"]
    bg = draw_background(np.random.default_rng(0), boiler)
    cols, _ = simulate_log(
        boiler, "stationary", background=bg, effect=None, form=None, strength=0.0, seed=0,
        sample_s=10.0,
    )  # fmt: skip
    cols = dict(cols)
    co = cols["flue_gas_CO_ppm"].copy()
    co[3] = np.nan
    cols["flue_gas_CO_ppm"] = co
    reordered = {k: cols[k] for k in reversed(list(cols))}
    path = tmp_path / "log.csv"
    write_log_csv(reordered, path)
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header = rows[0]
    assert header[0] == "time_s" and set(header) == set(LOG_COLUMNS)
    assert len(rows) == len(cols["time_s"]) + 1
    i_co = header.index("flue_gas_CO_ppm")
    assert rows[4][i_co] == ""
    assert rows[5][i_co] != ""
    i_t = header.index("water_out_temp_C")
    assert float(rows[10][i_t]) == pytest.approx(cols["water_out_temp_C"][9], abs=1e-3)
    assert rows[1][header.index("phase")] == "preheat"
