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


def test_the_replay_of_the_emulators_own_clean_load_cycle_is_the_log(run_log):
    """The model replayed with the firing the log shows is the plant that wrote it: the
    restart in the 13 % step (the burner switched on again by the replay, not out of a
    cut-out) runs the start-up at Pstart as the emulator's restart did. It ended at 70 C
    as a first start would and left 11 K in the water (a new user's probe)."""
    from hil_client.analysis.logio import read_log
    from hil_client.analysis.phases import find_phases
    from hil_client.analysis.replay import prepare
    from rig_emulator.boilers import load_boiler

    log = read_log(run_log("load_cycle", "windhager_12kw").path)
    case = prepare(log, find_phases(log), load_boiler("windhager_12kw"))
    assert len(case.firing.starts) == 2  # t0 and the restart
    # the log rounds temperatures to 1e-5 K and the replay reads them back as inputs
    residual = case.lab["boiler_water_temp_C"] - case.model["t_boiler_C"]
    assert np.abs(residual).max() < 1e-3
