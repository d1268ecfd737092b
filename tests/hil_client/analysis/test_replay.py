"""Preparing a log for the diagnosis: refills, the observed firing."""

from __future__ import annotations

import numpy as np

from hil_client.analysis.logio import without_refills


def test_a_refill_is_taken_out_of_the_balance_and_gaps_stay():
    mass = np.array([10.0, 9.98, 24.98, 24.96, np.nan, 24.9, 24.92])
    out = without_refills(mass)
    expected = [10.0, 9.98, 9.98, 9.96, np.nan, 9.9, 9.92]  # +0.02: one step of noise stays
    np.testing.assert_allclose(out, expected, atol=1e-12)
    assert np.isnan(without_refills(np.full(3, np.nan))).all()
