"""The out-of-sample evidence: an AR(1) error model that does not let thousands of
correlated rows make a small improvement look certain, and blocked cross-validation."""

from __future__ import annotations

import itertools

import numpy as np

from hil_client.analysis.evidence import Evidence, block_gain, cross_validate, folds


def _ar1(rng, n, rho, sd):
    e = np.empty(n)
    e[0] = rng.normal(0, sd)
    innovation = sd * np.sqrt(1 - rho**2)
    for i in range(1, n):
        e[i] = rho * e[i - 1] + rng.normal(0, innovation)
    return e


def test_correlated_rows_are_not_independent_evidence():
    """A candidate that removes a constant 0.1 (1 % of the squared residual of unit noise)
    from 20,000 rows: strong evidence on white residuals (z ~ 7), none on residuals with a
    lag-1 autocorrelation of 0.99 (z ~ 7 / sqrt(199) ~ 0.5), whatever the draw."""
    for seed in range(5):
        rng = np.random.default_rng(seed)
        for rho, strong in ((0.0, True), (0.99, False)):
            e = _ar1(rng, 20_000, rho, 1.0)
            ev = Evidence((block_gain("b", e + 0.1, e, noise_floor=0.0),))
            assert (ev.z > 3.0) == strong, (seed, rho, ev.z)


def test_a_real_effect_on_correlated_residuals_is_strong_evidence():
    rng = np.random.default_rng(2)
    e = _ar1(rng, 3000, 0.99, 0.3)
    effect = 3.0 * np.exp(-np.arange(3000) / 300.0)  # a transient of 3 K, 5-min decay
    ev = Evidence((block_gain("stop", e + effect, e, noise_floor=0.02),))
    # z ~ sqrt(sum delta^2) / (2 sd sqrt((1 + rho) / (1 - rho))) = 36.7 / 8.5 ~ 4.3 here
    assert ev.z > 3.0 and ev.relative_gain > 0.8


def test_folds_keep_neighbours_apart_and_cover_every_block():
    f = folds(10, k_max=4)
    assert sorted(i for fold in f for i in fold) == list(range(10))
    for fold in f:
        assert all(b - a > 1 for a, b in itertools.pairwise(fold))


def test_cross_validation_scores_only_held_out_blocks():
    """A 'fit' that memorises the training rows gains nothing on held-out rows."""
    rng = np.random.default_rng(3)
    y = rng.normal(0, 1, 600)
    blocks = [("b", np.arange(i, i + 100)) for i in range(0, 600, 100)]

    def fit(train):
        rows = np.concatenate([block[1] for block in train])
        return {"mean": float(np.mean(y[rows]))}

    def residuals(theta, block):
        return y[block[1]] - (theta["mean"] if theta else 0.0)

    ev, thetas = cross_validate(blocks, fit, residuals, noise_floor=0.0)
    assert len(ev.blocks) == 6 and len(thetas) == 6
    assert ev.z < 3.0  # noise: no evidence
    single, _ = cross_validate(blocks[:1], fit, residuals, noise_floor=0.0)
    assert not single.blocks  # one block: nothing to fit on, no evidence
