"""Public interface of reality7: names, columns, errors, determinism, sampling, CSV.

That it imports nothing of the project: test_gap_benchmark's per-plant check."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from hil_client.protocol.runner import LOG_COLUMNS
from hil_client.reality7 import EFFECT_FORMS, draw_background, simulate_log, write_log_csv

#: CONTRACT section 3's columns, as the project's own logger declares them (it appends its
#: optional extensions after ``boiler_on``)
CONTRACT_COLUMNS = list(LOG_COLUMNS[: LOG_COLUMNS.index("boiler_on") + 1])
# CONTRACT section 4 effect vocabulary (without "none")
CONTRACT_EFFECTS = {
    "body_heat_diffusion",
    "outlet_sensor_pipe",
    "ignition_delay",
    "flue_gas_lag",
    "fuel_energy_bias",
}
PHASES = {"preheat", "start_up", "test", "cooling_1", "cooling_2"}


@pytest.fixture(scope="module")
def log12(boiler12: dict, background12: dict) -> tuple[dict, dict]:
    return simulate_log(
        boiler12, "load_cycle", background=background12, effect=None, form=None,
        strength=0.0, seed=5,
    )  # fmt: skip


def test_effect_forms_vocabulary() -> None:
    assert set(EFFECT_FORMS) == CONTRACT_EFFECTS
    names = [f for forms in EFFECT_FORMS.values() for f in forms]
    assert len(names) == len(set(names))
    for forms in EFFECT_FORMS.values():
        assert len(forms) >= 2
        for f in forms:
            assert f == f.lower() and f.replace("_", "").isalnum()


def test_background_plain_floats_and_deterministic(boiler: dict) -> None:
    a = draw_background(np.random.default_rng(7), boiler)
    b = draw_background(np.random.default_rng(7), boiler)
    c = draw_background(np.random.default_rng(8), boiler)
    assert a == b
    assert a != c
    assert all(type(v) is float for v in a.values())


def test_columns_match_contract(log12: tuple[dict, dict]) -> None:
    cols, meta = log12
    assert list(cols) == CONTRACT_COLUMNS
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    assert set(np.unique(cols["phase"])) == PHASES
    assert {"peak", "stationary_13", "gradient_30_13"} <= set(np.unique(cols["sequence"]))
    assert set(np.unique(cols["boiler_on"])) <= {0, 1}
    for k in ("effect", "form", "strength", "background", "t0_s", "t1_s", "t2_s", "t3_s", "t4_s"):
        assert k in meta
    t = [meta[f"t{i}_s"] for i in range(5)]
    assert t == sorted(t)
    # t4 = t2 + 8 h (protocol cooling_2.until_after_t2_s)
    assert t[4] - t[2] == pytest.approx(28800.0)
    # test sequence length: the load cycle's 8 h (paper Table 2)
    assert t[2] - t[1] == pytest.approx(8 * 3600.0)
    ph = cols["phase"]
    ts = cols["time_s"]
    assert ts[ph == "test"][0] == pytest.approx(t[1])
    assert ts[ph == "cooling_2"][0] == pytest.approx(t[3])
    # pump run-down (flow_tau <= 12 s, meter lag 2 s): zero well within a minute of t3
    assert np.all(cols["water_flow_kg_h"][ph == "cooling_2"][60:] == 0.0)
    assert np.isnan(cols["flue_gas_O2_pct"]).any()  # analyser calibration gaps
    assert np.isfinite(cols["balance_mass_kg"]).all()


def test_determinism(boiler12: dict, background12: dict) -> None:
    kw = dict(background=background12, effect="flue_gas_lag", form="ceramic_foam_insert")
    a, ma = simulate_log(boiler12, "stationary", strength=0.5, seed=3, **kw)
    b, mb = simulate_log(boiler12, "stationary", strength=0.5, seed=3, **kw)
    c, _ = simulate_log(boiler12, "stationary", strength=0.5, seed=4, **kw)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert ma == mb
    assert not np.array_equal(a["flue_gas_temp_C"], c["flue_gas_temp_C"])


@pytest.mark.parametrize(
    ("effect", "form", "strength"),
    [
        ("no_such_effect", "x", 0.5),
        ("flue_gas_lag", "no_such_form", 0.5),
        ("flue_gas_lag", None, 0.5),
        ("flue_gas_lag", "dead_time", 0.5),
        ("flue_gas_lag", "ceramic_foam_insert", 1.5),
        ("flue_gas_lag", "ceramic_foam_insert", -0.1),
        ("flue_gas_lag", "ceramic_foam_insert", float("nan")),
        ("flue_gas_lag", "ceramic_foam_insert", "strong"),
    ],
)
def test_bad_arguments_raise(boiler12: dict, background12: dict, effect, form, strength) -> None:
    with pytest.raises(ValueError, match=r"effect|form|strength"):
        simulate_log(
            boiler12, "stationary", background=background12, effect=effect, form=form,
            strength=strength, seed=1,
        )  # fmt: skip


def test_bad_test_and_sampling_raise(boiler12: dict, background12: dict) -> None:
    kw = dict(background=background12, effect=None, form=None, strength=0.0, seed=1)
    with pytest.raises(ValueError, match="test"):
        simulate_log(boiler12, "marathon", **kw)
    with pytest.raises(ValueError, match="sample_s"):
        simulate_log(boiler12, "stationary", sample_s=0.5, **kw)


def test_sample_s_and_jitter(boiler12: dict, background12: dict) -> None:
    kw = dict(background=background12, effect=None, form=None, strength=0.0, seed=2)
    one, m1 = simulate_log(boiler12, "stationary", **kw)
    ten, m10 = simulate_log(boiler12, "stationary", sample_s=10.0, **kw)
    jit, _ = simulate_log(boiler12, "stationary", sample_s=5.0, jitter=True, **kw)
    assert np.all(np.diff(one["time_s"]) == 1.0)
    assert np.allclose(np.diff(ten["time_s"]), 10.0)
    assert m1["t4_s"] == m10["t4_s"]
    dj = np.diff(jit["time_s"])
    # jitter: +-20 % of the nominal 5 s (the rounding of times to 1 ms widens it by 2 ms)
    assert dj.min() >= 4.0 - 2e-3 and dj.max() <= 6.0 + 2e-3
    assert dj.std() > 0.3  # uniform +-1 s has a std of 0.58 s
    # the 10 s log samples the same plant as the 1 s log
    idx = (ten["time_s"]).astype(int)
    np.testing.assert_allclose(
        ten["water_flow_setpoint_kg_h"], one["water_flow_setpoint_kg_h"][idx]
    )


def test_write_log_csv_roundtrip(log12: tuple[dict, dict], tmp_path: Path) -> None:
    cols, _ = log12
    sub = {k: v[:4000] for k, v in cols.items()}
    path = tmp_path / "log.csv"
    write_log_csv(sub, path)
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == CONTRACT_COLUMNS
    assert len(rows) == 4001
    j = CONTRACT_COLUMNS.index("flue_gas_O2_pct")
    for i in range(4000):
        v = sub["flue_gas_O2_pct"][i]
        cell = rows[i + 1][j]
        if math.isnan(v):
            assert cell == ""  # a missing value is an empty field (CONTRACT section 3)
        else:
            assert float(cell) == pytest.approx(v, abs=1e-9)
    assert rows[1][1] == "preheat"
