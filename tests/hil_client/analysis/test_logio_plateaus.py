"""The stationary steps found from the flow (:func:`flow_plateaus`): the run's median kept
as the run grows must give exactly what the definition gives, a median of the whole run at
every row."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hil_client.analysis.logio import PLATEAU_MIN_S, LabLog, fill_gaps, flow_plateaus


def _by_definition(flow: np.ndarray, t: np.ndarray, rows: np.ndarray) -> list:
    """The plateaus as the docstring defines them: np.median of the run so far at each row
    (quadratic; the reference, written apart from the code under test)."""
    idx = np.flatnonzero(rows)
    out, start = [], idx[0]
    for i in range(idx[0] + 1, idx[-1] + 2):
        end = i == idx[-1] + 1
        level = float(np.median(flow[start:i]))
        if end or abs(flow[i] - level) > 0.02 * max(level, 1.0):
            if t[i - 1] - t[start] >= PLATEAU_MIN_S:
                out.append((int(start), int(i), level))
            start = i
    return out


def _log(flow: np.ndarray, step_s: float) -> LabLog:
    t = np.arange(len(flow)) * step_s
    return LabLog(Path("x.csv"), {"time_s": t, "water_flow_kg_h": flow}, {})


@pytest.mark.parametrize("seed", range(6))
def test_the_running_median_gives_the_definitions_plateaus(seed):
    """Steps of 25-70 min with noise (odd and even run lengths, ties from rounding to the
    flow meter's 0.1 kg/h, a NaN gap filled in time) give the same rows and levels, to
    the last bit, as the median of the whole run at every row."""
    rng = np.random.default_rng(seed)
    levels = rng.permutation([0.0, 150.0, 300.0, 600.0, 900.0])  # neighbours differ
    flow = np.concatenate([lv + rng.normal(0, 1, rng.integers(250, 700)) for lv in levels])
    flow = np.round(flow, 1)
    flow[rng.integers(0, len(flow), 5)] = np.nan
    log = _log(flow, 6.0)
    rows = np.zeros(len(flow), bool)
    rows[rng.integers(0, 100) : len(flow) - rng.integers(1, 100)] = True
    expected = _by_definition(fill_gaps(flow, log.t), log.t, rows)
    assert len(expected) >= 3  # the case has plateaus to find
    assert flow_plateaus(log, rows) == expected


def test_a_flow_column_without_a_reading_keeps_its_one_run_of_nan():
    """An all-NaN flow has no order to keep: one run, level NaN, as the definition gives."""
    log = _log(np.full(400, np.nan), 5.0)
    found = flow_plateaus(log, np.ones(400, bool))
    assert len(found) == 1 and found[0][:2] == (0, 400) and np.isnan(found[0][2])
