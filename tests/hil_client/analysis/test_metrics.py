"""Every metric on small hand-made series with known answers."""

import math

import numpy as np
import pytest

from hil_client.analysis.metrics import (
    autocorrelation,
    correlation,
    lag_at_peak,
    max_deviation,
    rmsd,
    table4_metrics,
    theil_shares,
)


def test_max_deviation_rmsd_and_correlation():
    model = np.array([1.0, 2.0, 3.0, 4.0])
    lab = np.array([1.0, 2.0, 3.0, 6.0])
    assert max_deviation(model, lab) == 2.0
    assert rmsd(model, lab) == pytest.approx(1.0)  # sqrt(4 / 4)
    assert correlation(model, 2 * model + 1) == pytest.approx(1.0)
    assert correlation(model, -model) == pytest.approx(-1.0)
    assert math.isnan(correlation(model, np.ones(4)))  # a flat series has no correlation
    assert table4_metrics(model, lab)["n"] == 4


def test_theil_shares_separate_bias_variance_and_covariance():
    lab = np.sin(np.linspace(0, 20 * np.pi, 2000, endpoint=False))  # zero mean
    bias, var, cov = theil_shares(lab + 0.5, lab)
    assert (bias, var, cov) == pytest.approx((1.0, 0.0, 0.0), abs=1e-9)
    bias, var, cov = theil_shares(2 * lab, lab)
    assert var == pytest.approx(1.0, abs=1e-6) and bias == pytest.approx(0.0, abs=1e-9)
    bias, var, cov = theil_shares(-lab, lab)
    assert cov == pytest.approx(1.0, abs=1e-6)


def test_lag_at_peak_finds_a_known_delay():
    rng = np.random.default_rng(3)
    signal = np.convolve(rng.standard_normal(4000), np.ones(30) / 30, mode="same")
    model = signal[200:3800]
    lab = signal[80:3680]  # the lab shows what the model did 120 s earlier
    assert lag_at_peak(model, lab, 1.0) == pytest.approx(120.0)
    assert lag_at_peak(lab, model, 1.0) == pytest.approx(-120.0)  # the lab ahead
    assert lag_at_peak(model[::10], lab[::10], 10.0) == pytest.approx(120.0)  # 10-s rows


def test_autocorrelation_of_noise_and_of_structure():
    rng = np.random.default_rng(0)
    noise = rng.standard_normal(20_000)
    assert abs(autocorrelation(noise, 60)) < 0.03  # 2 / sqrt(n) ~ 0.014
    slow = np.sin(np.linspace(0, 4 * np.pi, 20_000))
    assert autocorrelation(slow, 60) > 0.99
