"""Each effect form changes the signals its fingerprint (CONTRACT section 4) names and
leaves the others: same background and seed, with and without the effect."""

from __future__ import annotations

import numpy as np
import pytest

from hil_client.reality import EFFECT_FORMS
from tests.hil_client.reality.conftest import run


def _rows(cols, meta, start: float, end: float) -> np.ndarray:
    t = cols["time_s"]
    return (t > start) & (t <= end)


def _test_rows(cols, meta) -> np.ndarray:
    """The settled test phase: from 1 h after t1 to t2."""
    return _rows(cols, meta, meta["t1_s"] + 3600, meta["t2_s"])


def _fuel_per_kwh(cols, meta) -> float:
    L = meta["ledger"]
    m = _test_rows(cols, meta)
    idx = np.flatnonzero(m)
    fed = L["fuel_fed_as_received_kg"][idx[-1]] - L["fuel_fed_as_received_kg"][idx[0]]
    heat = (L["heat_to_water_kJ"][idx[-1]] - L["heat_to_water_kJ"][idx[0]]) / 3600.0
    return fed / heat


def _mean(cols, meta, key, ledger=True) -> float:
    src = meta["ledger"] if ledger else cols
    return float(np.nanmean(src[key][_test_rows(cols, meta)]))


@pytest.mark.parametrize("form", EFFECT_FORMS["outlet_sensor_pipe"])
def test_pipe_moves_only_the_forward_sensor(form):
    base_c, base_m = run("stationary")
    c, m = run("stationary", "outlet_sensor_pipe", form, 0.0)  # the weakest
    # the boiler water and the balance do not see the pipe (the return conditioning reads
    # the pipe's outlet, which moves the water by hundredths of a kelvin; row by row the
    # power levels' limit cycle may switch at other instants, so means are compared)
    for key in ("boiler_water_true_C", "heat_to_water_true_kW"):
        assert _mean(c, m, key) == pytest.approx(_mean(base_c, base_m, key), abs=0.1)
    assert _mean(c, m, "boiler_water_temp_C", False) == pytest.approx(
        _mean(base_c, base_m, "boiler_water_temp_C", False), abs=0.1
    )
    assert _fuel_per_kwh(c, m) == pytest.approx(_fuel_per_kwh(base_c, base_m), rel=0.003)
    # once circulation stops the forward sensor falls below the boiler water, by far more
    # than without the pipe (Section 3.2: the measured outlet falls below the boiler's)
    late0 = _rows(base_c, base_m, base_m["t3_s"] + 3600, base_m["t4_s"])
    late1 = _rows(c, m, m["t3_s"] + 3600, m["t4_s"])
    gap0 = np.nanmean(base_c["boiler_water_temp_C"][late0] - base_c["water_out_temp_C"][late0])
    gap1 = np.nanmean(c["boiler_water_temp_C"][late1] - c["water_out_temp_C"][late1])
    assert gap1 - gap0 > 3.0


@pytest.mark.parametrize("form", EFFECT_FORMS["fuel_energy_bias"])
def test_fuel_bias_moves_only_fuel_against_heat(form):
    base_c, base_m = run("stationary")
    c, m = run("stationary", "fuel_energy_bias", form, 0.0)  # the weakest
    assert _mean(c, m, "boiler_water_true_C") == pytest.approx(
        _mean(base_c, base_m, "boiler_water_true_C"), abs=0.15
    )
    assert _mean(c, m, "heat_to_water_true_kW") == pytest.approx(
        _mean(base_c, base_m, "heat_to_water_true_kW"), rel=0.01
    )
    ratio = _fuel_per_kwh(c, m) / _fuel_per_kwh(base_c, base_m)
    assert abs(ratio - 1.0) > 0.03  # above a lab analysis' 2-3 % uncertainty of the HHV


def test_moisture_also_raises_the_latent_loss():
    base_c, base_m = run("stationary")
    c, m = run("stationary", "fuel_energy_bias", "moisture", 1.0)
    idx0, idx1 = np.flatnonzero(_test_rows(base_c, base_m)), np.flatnonzero(_test_rows(c, m))

    def flue_share(meta, idx):
        L = meta["ledger"]
        fed = L["fuel_fed_kJ"][idx[-1]] - L["fuel_fed_kJ"][idx[0]]
        return (L["flue_gas_and_ash_kJ"][idx[-1]] - L["flue_gas_and_ash_kJ"][idx[0]]) / fed

    assert flue_share(m, idx1) > flue_share(base_m, idx0) + 0.005


@pytest.mark.parametrize("form", EFFECT_FORMS["ignition_delay"])
def test_ignition_delay_feeds_before_heat_and_leaves_the_test_alone(form):
    base_c, base_m = run("stationary")
    c, m = run("stationary", "ignition_delay", form, 0.0)  # the weakest

    def pre_feed_s(cols, meta):
        """Seconds from the first fed fuel after t0 until the flue gas is 20 K warmer."""
        L = meta["ledger"]
        t = cols["time_s"]
        after = t > meta["t0_s"]
        fed = L["fuel_fed_as_received_kg"]
        i_feed = np.flatnonzero(after & (fed > fed[np.flatnonzero(after)[0]] + 1e-6))[0]
        tfg = L["flue_gas_sensor_true_C"]
        i_hot = np.flatnonzero(after & (tfg > tfg[i_feed] + 20.0))[0]
        return t[i_hot] - t[i_feed]

    assert pre_feed_s(c, m) > pre_feed_s(base_c, base_m) + 40.0
    assert _mean(c, m, "boiler_water_true_C") == pytest.approx(
        _mean(base_c, base_m, "boiler_water_true_C"), abs=0.15
    )
    assert _fuel_per_kwh(c, m) == pytest.approx(_fuel_per_kwh(base_c, base_m), rel=0.005)
    assert _mean(c, m, "flue_gas_sensor_true_C") == pytest.approx(
        _mean(base_c, base_m, "flue_gas_sensor_true_C"), abs=0.5
    )


@pytest.mark.parametrize("form", EFFECT_FORMS["flue_gas_lag"])
def test_flue_gas_lag_slows_only_the_flue_gas(form):
    base_c, base_m = run("stationary")
    c, m = run("stationary", "flue_gas_lag", form, 0.0)  # the weakest

    def drop_after_stop(cols, meta):
        """Flue-gas fall over the 5 min after t2 (burner off) [K]."""
        L, t = meta["ledger"], cols["time_s"]
        i2 = np.searchsorted(t, meta["t2_s"])
        i5 = np.searchsorted(t, meta["t2_s"] + 300)
        return L["flue_gas_sensor_true_C"][i2] - L["flue_gas_sensor_true_C"][i5]

    assert drop_after_stop(c, m) < 0.8 * drop_after_stop(base_c, base_m)
    assert _mean(c, m, "boiler_water_true_C") == pytest.approx(
        _mean(base_c, base_m, "boiler_water_true_C"), abs=0.15
    )
    assert _fuel_per_kwh(c, m) == pytest.approx(_fuel_per_kwh(base_c, base_m), rel=0.005)


@pytest.mark.parametrize("form", EFFECT_FORMS["body_heat_diffusion"])
def test_body_keeps_heating_the_water_after_a_stop(form):
    base_c, base_m = run("stationary")
    c, m = run("stationary", "body_heat_diffusion", form, 0.0)  # the weakest

    def rise_after_stop(cols, meta):
        """Water 5 min after t2 relative to t2, against the same without effect [K]."""
        L, t = meta["ledger"], cols["time_s"]
        i2 = np.searchsorted(t, meta["t2_s"])
        i5 = np.searchsorted(t, meta["t2_s"] + 300)
        return L["boiler_water_true_C"][i5] - L["boiler_water_true_C"][i2]

    assert rise_after_stop(c, m) > rise_after_stop(base_c, base_m) + 0.3
    assert _fuel_per_kwh(c, m) == pytest.approx(_fuel_per_kwh(base_c, base_m), rel=0.005)
    assert _mean(c, m, "flue_gas_sensor_true_C") == pytest.approx(
        _mean(base_c, base_m, "flue_gas_sensor_true_C"), abs=1.0
    )
    # the pipe and the forward sensor are untouched: forward follows the water as before
    rows0, rows1 = _test_rows(base_c, base_m), _test_rows(c, m)
    d0 = np.nanmean(
        base_c["water_out_temp_C"][rows0] - base_m["ledger"]["boiler_water_true_C"][rows0]
    )
    d1 = np.nanmean(c["water_out_temp_C"][rows1] - m["ledger"]["boiler_water_true_C"][rows1])
    assert d1 == pytest.approx(d0, abs=0.05)


def test_strength_orders_the_effect():
    """Stronger is bigger: the pipe's stagnation gap grows with strength."""
    gaps = []
    for s in (0.0, 0.5, 1.0):
        c, m = run("stationary", "outlet_sensor_pipe", "plug_flow", s)
        late = _rows(c, m, m["t3_s"] + 3600, m["t4_s"])
        gaps.append(np.nanmean(c["boiler_water_temp_C"][late] - c["water_out_temp_C"][late]))
    assert gaps[0] < gaps[1] < gaps[2]
