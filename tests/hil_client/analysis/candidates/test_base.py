"""A curve candidate's grid fit (:class:`hil_client.analysis.candidates.base.GridSSE`): the
table of sums of squares per grid point and block gives, for any set of blocks (each
fold's and the final fit's), the grid point a direct search over that set gives."""

from __future__ import annotations

import itertools
from types import SimpleNamespace

import numpy as np

from hil_client.analysis.candidates.base import CurveCandidate


def _candidate_and_case():
    t = np.arange(600.0)
    rng = np.random.default_rng(4)
    # each block its own slope and swing, so that each set of blocks has its own best fit
    slope = np.repeat([0.0, 0.06, 0.02, 0.05, 0.01, 0.04], 100)
    swing = np.repeat([4.0, 0.0, 3.0, 1.0, 2.0, 0.5], 100)
    lab = slope * t + swing * np.sin(t / 40.0) + rng.normal(0.0, 0.3, t.size)
    case = SimpleNamespace(t=t, lab={"x": lab}, settled=np.zeros(t.size, bool))
    case.settled[:50] = True

    def predict(case, theta):
        if theta is None:
            return np.zeros_like(case.t)
        return theta["slope"] * case.t + theta["swing"] * np.sin(case.t / 40.0)

    blocks = [("b", np.arange(a, a + 80), -1) for a in range(60, 560, 100)]
    candidate = CurveCandidate(
        effect="test",
        signal="x",
        locus="test",
        grid={"slope": np.linspace(0.0, 0.06, 7), "swing": np.linspace(0.0, 4.0, 5)},
        predict=predict,
        blocks=lambda case: blocks,
        nuisance_drift=False,
    )
    return candidate, case, blocks


def _direct_fit(candidate, case, blocks):
    """The grid point of least squares on ``blocks``, searched directly (the noise leaves
    no ties, so the order of the search does not matter)."""
    best, best_sse = None, np.inf
    for slope in candidate.grid["slope"]:
        for swing in candidate.grid["swing"]:
            theta = {"slope": float(slope), "swing": float(swing)}
            r = candidate.residual(case, theta)
            sse = sum(float(np.sum(r[rows] ** 2)) for _, rows, _ in blocks)
            if sse < best_sse:
                best, best_sse = theta, sse
    return best


def test_the_table_fits_every_set_of_blocks_as_a_direct_search_does():
    candidate, case, blocks = _candidate_and_case()
    table = candidate.grid_sse(case, blocks)
    assert len(table.thetas) == 7 * 5 and all(len(row) == len(blocks) for row in table.table)
    fits = set()
    for k in range(1, len(blocks) + 1):
        for train in itertools.combinations(blocks, k):
            fit = table.best(list(train))
            assert fit == _direct_fit(candidate, case, list(train))
            fits.add(tuple(fit.values()))
    assert len(fits) > 5  # the sets of blocks disagree: the test tells them apart


def test_a_tie_goes_to_the_first_grid_point():
    candidate, case, blocks = _candidate_and_case()
    case.lab["x"] = np.zeros_like(case.t)  # every point with swing 0 and slope 0 fits
    table = candidate.grid_sse(case, blocks)
    table.table[1] = list(table.table[0])  # a second point as good as the first
    assert table.best(blocks) is table.thetas[0]
