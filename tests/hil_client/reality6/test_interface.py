"""Interface of hil_client.reality6: names, columns, determinism, errors, CSV, sampling."""

from __future__ import annotations

import csv
import re

import numpy as np
import pytest

from hil_client.protocol.runner import LOG_COLUMNS
from hil_client.reality6 import EFFECT_FORMS, draw_background, simulate_log, write_log_csv

from .conftest import background, boiler, log

#: CONTRACT section 3's columns, as the project's own logger declares them (it appends its
#: optional extensions after ``boiler_on``)
COLUMNS = LOG_COLUMNS[: LOG_COLUMNS.index("boiler_on") + 1]


def test_effect_forms_are_new_snake_case_names():
    assert set(EFFECT_FORMS) == {
        "body_heat_diffusion",
        "outlet_sensor_pipe",
        "ignition_delay",
        "flue_gas_lag",
        "fuel_energy_bias",
    }
    all_forms = [f for forms in EFFECT_FORMS.values() for f in forms]
    assert len(all_forms) == len(set(all_forms))
    for forms in EFFECT_FORMS.values():
        assert len(forms) >= 2
        for f in forms:
            assert re.fullmatch(r"[a-z][a-z0-9]*(_[a-z0-9]+)*", f)


def test_draw_background_floats_and_deterministic():
    b = boiler("windhager_12kw")
    a = draw_background(np.random.default_rng(3), b)
    c = draw_background(np.random.default_rng(3), b)
    d = draw_background(np.random.default_rng(4), b)
    assert a == c
    assert a != d
    assert all(type(v) is float for v in a.values())


def test_columns_and_meta():
    cols, meta = log("windhager_6kw", "load_cycle", sample_s=2.0)
    assert tuple(cols) == COLUMNS
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    assert np.all(np.diff(cols["time_s"]) == 2.0)
    assert set(np.unique(cols["boiler_on"])) <= {0, 1}
    assert set(cols["phase"]) == {"preheat", "start_up", "test", "cooling_1", "cooling_2"}
    assert "stationary_13" in set(cols["sequence"])
    for k in ("effect", "form", "strength", "background", "t0_s", "t1_s", "t2_s", "t3_s", "t4_s"):
        assert k in meta
    assert meta["effect"] == "none"
    assert 0 < meta["t0_s"] < meta["t1_s"] < meta["t2_s"] <= meta["t3_s"] < meta["t4_s"]
    assert meta["t4_s"] - meta["t2_s"] == pytest.approx(28_800, abs=1)
    assert meta["t2_s"] - meta["t1_s"] == pytest.approx(28_800, abs=1)
    # the balance falls as the auger feeds, on a 0.02 kg grid
    bal = cols["balance_mass_kg"]
    assert bal[0] - bal[-1] > 2.0
    assert np.allclose(np.round(bal / 0.02) * 0.02, bal)
    # the analyser has a few calibration gaps, the temperatures none
    assert 0 < np.isnan(cols["flue_gas_O2_pct"]).sum() < 0.05 * n
    assert not np.isnan(cols["water_out_temp_C"]).any()


def test_same_seed_same_log_different_seed_different_log():
    a, ma = log("windhager_12kw", "stationary", effect="flue_gas_lag", strength=0.5, seed=11)
    b, mb = log("windhager_12kw", "stationary", effect="flue_gas_lag", strength=0.5, seed=11)
    c, _ = log("windhager_12kw", "stationary", effect="flue_gas_lag", strength=0.5, seed=12)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert ma == mb
    assert not np.array_equal(a["water_out_temp_C"], c["water_out_temp_C"])
    assert ma["form"] == EFFECT_FORMS["flue_gas_lag"][0]


@pytest.mark.parametrize(
    "kw",
    [
        {"test": "stationary_x"},
        {"effect": "bogus"},
        {"effect": "flue_gas_lag", "form": "dead_leg_tee_pocket"},
        {"effect": "flue_gas_lag", "strength": 1.5},
        {"effect": "flue_gas_lag", "strength": -0.1},
        {"sample_s": 0.0},
        {"sample_s": -1.0},
    ],
)
def test_bad_arguments_raise_value_error(kw):
    args = {"test": "stationary", "effect": None, "form": None, "strength": 0.0, "sample_s": 1.0}
    args.update(kw)
    test = args.pop("test")
    with pytest.raises(ValueError):
        simulate_log(
            boiler("windhager_6kw"), test, background=background("windhager_6kw", 0), seed=1, **args
        )


def test_none_and_zero_strength_equal_no_effect():
    a, _ = log("windhager_6kw", "stationary", effect=None)
    b, _ = log("windhager_6kw", "stationary", effect="none")
    c, _ = log("windhager_6kw", "stationary", effect="ignition_delay", strength=0.0)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
        np.testing.assert_array_equal(a[k], c[k])


def test_jitter_and_sampling(tmp_path):
    cols, _ = log("windhager_6kw", "stationary", sample_s=5.0, jitter=True)
    t = cols["time_s"]
    assert np.all(np.diff(t) > 0)
    dts = np.diff(t)
    assert dts.std() > 0.01  # irregular
    assert (dts > 7.5).sum() > 0  # a few dropped rows
    regular, _ = log("windhager_6kw", "stationary", sample_s=5.0)
    assert 0.98 * len(regular["time_s"]) < len(t) < len(regular["time_s"])
    path = tmp_path / "log.csv"
    write_log_csv(cols, path)
    with path.open() as fh:
        rows = list(csv.reader(fh))
    assert rows[0][0] == "time_s"
    assert rows[0] == list(COLUMNS)
    assert len(rows) == len(t) + 1
    i_o2 = rows[0].index("flue_gas_O2_pct")
    n_empty = sum(1 for r in rows[1:] if r[i_o2] == "")
    assert n_empty == int(np.isnan(cols["flue_gas_O2_pct"]).sum()) > 0
