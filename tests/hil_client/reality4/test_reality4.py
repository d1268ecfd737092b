"""Tests of the reality4 plant: columns, marks, determinism, mass and energy closure."""

import itertools
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality4 import EFFECT_FORMS, draw_background, simulate_log, write_log_csv
from hil_client.reality4.plant import COLUMNS

ROOT = Path(__file__).resolve().parents[3]
BOILER = yaml.safe_load((ROOT / "rig_emulator/boilers/windhager_6kw.yaml").read_text())
BG = draw_background(np.random.default_rng(7), BOILER)

CASES = [(None, None, 0.0)] + [
    (e, f, s) for e, forms in EFFECT_FORMS.items() for f in forms for s in (0.0, 1.0)
]


def _energy_residual(truth):
    e_in = truth["E_fuel_kJ"] + truth["E_igniter_kJ"]
    e_out = truth["E_water_kJ"] + truth["E_room_kJ"] + truth["E_flue_kJ"] + truth["E_storage_kJ"]
    return (e_in - e_out) / truth["E_fuel_kJ"]


def test_effect_forms_shape():
    assert set(EFFECT_FORMS) == {
        "body_heat_diffusion",
        "outlet_sensor_pipe",
        "ignition_delay",
        "flue_gas_lag",
        "fuel_energy_bias",
    }
    assert all(len(v) == 2 for v in EFFECT_FORMS.values())


@pytest.mark.parametrize("test", ["stationary", "load_cycle"])
@pytest.mark.parametrize("effect,form,strength", CASES)
def test_columns_and_marks(test, effect, form, strength):
    cols, meta = simulate_log(
        BOILER,
        test,
        background=BG,
        effect=effect,
        form=form,
        strength=strength,
        seed=11,
        sample_s=5.0,
    )
    assert next(iter(cols)) == "time_s"
    assert set(COLUMNS) <= set(cols)
    n = len(cols["time_s"])
    assert all(len(v) == n for v in cols.values())
    marks = [meta[f"t{k}_s"] for k in range(5)]
    assert all(a < b for a, b in itertools.pairwise(marks)), marks
    assert 6 * 3600 < marks[4] - marks[1] < 17 * 3600
    ph = cols["phase"]
    assert set(ph) == {"preheat", "start_up", "test", "cooling_1", "cooling_2"}
    assert np.all(cols["water_flow_kg_h"][ph == "cooling_2"] == 0.0)
    assert abs(_energy_residual(meta["truth"])) < 1e-6


def test_deterministic_and_jitter(tmp_path):
    kw = dict(background=BG, effect="flue_gas_lag", form="soot_fouled_hx", strength=0.5, seed=5)
    a, ma = simulate_log(BOILER, "stationary", **kw, sample_s=3.0, jitter=True)
    b, mb = simulate_log(BOILER, "stationary", **kw, sample_s=3.0, jitter=True)
    for k in a:
        if a[k].dtype.kind == "f":
            np.testing.assert_array_equal(a[k], b[k])
        else:
            assert (a[k] == b[k]).all()
    assert ma["t2_s"] == mb["t2_s"]
    dt = np.diff(a["time_s"])
    assert dt.min() > 1.0 and dt.std() > 0.1
    path = tmp_path / "log.csv"
    write_log_csv(a, path)
    head = path.read_text().splitlines()[:2]
    assert head[0].startswith("time_s,")
    assert len(head[1].split(",")) == len(a)


def test_mass_and_energy_stationary():
    cols, meta = simulate_log(
        BOILER, "stationary", background=BG, effect=None, form=None, strength=0.0, seed=2
    )
    tr = meta["truth"]
    # the balance loses the fed fuel as received; the ash stays on it
    drop_true = tr["balance_start_kg"] - tr["balance_end_kg"]
    assert drop_true == pytest.approx(tr["fed_kg"] * (1 - tr["ash_ar"]), rel=1e-9)
    drop_meas = cols["balance_mass_kg"][0] - cols["balance_mass_kg"][-1]
    assert abs(drop_meas - drop_true) < 0.05
    assert tr["fed_kg"] == pytest.approx(tr["burnt_kg"] + tr["bed_end_kg"], abs=1e-9)
    # energy: fuel (+ igniter) heat = water heat + room + flue losses + storage change
    assert abs(_energy_residual(tr)) < 0.01
    # stationary nominal load: heat to water from the log, 75-95 % of fuel heat
    ph = cols["phase"] == "test"
    q_w = cols["water_flow_kg_h"] * 4.186 * (cols["water_out_temp_C"] - cols["water_in_temp_C"])
    q_w = q_w[ph].mean() / 3600.0
    assert 0.8 * BOILER["p_nom_kW"] < q_w < 1.2 * BOILER["p_nom_kW"]
    # flue gas and analyser plausible
    assert 8.0 < np.nanmean(cols["flue_gas_O2_pct"][ph]) < 19.0
