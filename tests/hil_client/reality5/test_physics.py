"""Plant 5: energy and mass close every step, steady state matches the closed form, and the
no-effect background leaves a Table-4-sized gap to a plain Type 869."""

from __future__ import annotations

import numpy as np
import pytest

from hil_client.reality5 import draw_background
from hil_client.reality5.core import Params
from hil_client.reality5.reference import phase_gap, steady_state

from .conftest import BOILERS, TESTS, sim

CASES = [
    (None, None),
    ("body_heat_diffusion", "burner_flange_path"),
    ("outlet_sensor_pipe", "thermosiphon_exchange"),
    ("ignition_delay", "char_shrinking_core"),
    ("flue_gas_lag", "flue_collector_mass"),
    ("fuel_energy_bias", "calcite_additive"),
]


@pytest.mark.parametrize(("effect", "form"), CASES)
def test_energy_and_mass_close_every_step(boilers, backgrounds, effect, form):
    b = boilers["windhager_12kw"]
    cols, meta = sim(b, "load_cycle", backgrounds["windhager_12kw"], effect, form, 1.0, seed=5)
    tr, p = meta["truth"], Params(**meta["params"])
    # dE/dt = inputs - outputs, exactly per 1 s step (to float rounding of ~2e4 kJ)
    resid = np.diff(tr["E_stored_kJ"]) - (tr["q_in_kW"][1:] - tr["q_out_kW"][1:]) * 1.0
    assert np.abs(resid).max() < 1e-8
    # burnt + bed = fed; the balance loses exactly the as-received fuel fed
    assert np.abs(tr["burnt_kg"] + tr["bed_kg"] - tr["fed_dry_kg"]).max() < 1e-10
    fed_ar = tr["fed_dry_kg"] / (1 - p.w_ar)
    assert np.allclose(tr["balance_kg"], p.hopper - fed_ar, atol=1e-10)
    assert np.all(np.diff(tr["balance_kg"]) <= 1e-15)
    # the reading: 0.02 kg steps around truth + offset + drift, within the noise
    true = np.interp(cols["time_s"], tr["time_s"], tr["balance_kg"])
    err = cols["balance_mass_kg"] - true - p.bal_off - p.bal_drift * cols["time_s"] / 3600
    assert np.abs(err).max() < 0.01 + 6 * (p.bal_noise + p.bal_vib)
    assert np.allclose(np.round(cols["balance_mass_kg"] / 0.02) * 0.02, cols["balance_mass_kg"])


@pytest.mark.parametrize("name", BOILERS)
def test_steady_state_matches_closed_form(boilers, name):
    """Last 2 h of the nominal test: mean Q_w, T_fg, O2 = closed form at the mean firing."""
    b = boilers[name]
    bg = draw_background(np.random.default_rng(2), b)
    bg.update(foul_amp=0.0, flicker=0.0, k_auger=1.08)  # headroom, no saw-tooth, no flicker
    _, meta = sim(b, "stationary", bg, seed=2)
    tr, p = meta["truth"], Params(**meta["params"])
    sel = (tr["time_s"] > meta["t2_s"] - 7200) & (tr["time_s"] < meta["t2_s"])
    x = tr["r_burn_kg_s"][sel].mean() / p.r_max_d
    ss = steady_state(p, x, tr["T_w"][sel].mean(), tr["T_room"][sel].mean())
    assert tr["Q_w_kW"][sel].mean() == pytest.approx(ss["Q_w"], rel=5e-3)
    assert tr["T_fg"][sel].mean() == pytest.approx(ss["T_fg"], abs=0.5)
    assert tr["O2"][sel].mean() == pytest.approx(ss["O2"], abs=0.05)
    assert 0.80 < ss["eta"] < 0.90  # paper: about 85 % of Q_fuel (HHV) to water
    assert tr["Q_w_kW"][sel].mean() == pytest.approx(b["p_nom_kW"], rel=0.05)


@pytest.mark.parametrize("test", TESTS)
@pytest.mark.parametrize("name", BOILERS)
def test_background_gap_is_table4_sized(boilers, name, test):
    """Median over 4 cases of the t1..t2 gap to a plain Type 869 (Table 3 values).

    Table 4 gives T RMSD 1.36-2.63 K and Q RMSD 0.30-0.67 kW for its four runs. One synthetic
    case depends on its drawn controller, stop/restart rules and sensor offsets (the 13 % step's
    on/off timing dominates the load cycle), so we test the median of four cases against about
    a factor of two around the paper's range: T in [0.8, 4.5] K, Q in [0.12, 0.9] kW (the 6 kW
    boiler runs half the flow, so its Q gap is smaller).
    """
    b = boilers[name]
    gaps = []
    for k in range(4):
        bg = draw_background(np.random.default_rng(200 + k), b)
        cols, meta = sim(b, test, bg, seed=k, sample_s=2.0)
        g = phase_gap(b, cols, meta)
        gaps.append((g["T_rmsd_K"], g["Q_rmsd_kW"]))
    t_med, q_med = np.median(np.array(gaps), axis=0)
    assert 0.8 <= t_med <= 4.5, gaps
    assert 0.12 <= q_med <= 0.9, gaps


def test_protocol_phases(baselines):
    for (_, test), (cols, meta) in baselines.items():
        t = [meta[f"t{k}_s"] for k in range(5)]
        assert 0 < t[0] < t[1] < t[2] <= t[3] < t[4]
        assert t[2] - t[1] == pytest.approx(6 * 3600 if test == "stationary" else 8 * 3600, abs=1)
        assert t[4] - t[2] == pytest.approx(8 * 3600, abs=1)
        assert 300 <= t[1] - t[0] <= 7200
        test_rows = cols["phase"] == "test"
        assert cols["water_flow_setpoint_kg_h"][cols["phase"] == "cooling_2"].max() == 0
        if test == "load_cycle":
            assert "stationary_13" in set(cols["sequence"][test_rows])
