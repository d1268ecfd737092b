"""Out-of-sample evidence for a candidate effect, honest about autocorrelated residuals.

A candidate is scored only on rows it was not fitted on (blocked cross-validation in time:
the rows where the effect acts are cut into contiguous blocks, each block is predicted with
parameters fitted on the others). On a held-out block the gain is
D = sum(r_base^2) - sum(r_cand^2). With r_base = r_cand + delta (delta: the candidate's
change of the prediction), D = sum(delta^2) + 2 sum(delta r_cand): its randomness is the
error e ~ r_cand projected on delta. Neighbouring rows of a log are strongly correlated (a
1-s log of a process with minute time constants), so e is taken as AR(1) with the lag-1
autocorrelation rho and variance s^2 of r_cand in the block, and

    Var(D) = 4 s^2 (1 + rho) / (1 - rho) sum(delta^2)

(the variance of a smooth weighted sum of an AR(1) series; Wilks, Statistical Methods in
the Atmospheric Sciences, Sect. 5.2.4). The evidence z = sum_b D_b / sqrt(sum_b Var(D_b))
thus counts 20,000 correlated rows as the few dozen independent pieces of information they
are, and a 1 % improvement never becomes "very strong evidence". s has a floor, the
resolution of the signal (:data:`NOISE_FLOOR`), so a noiseless log does not claim
certainty either.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

#: A block's autocorrelation is capped: rho -> 1 would make any block worthless.
RHO_MAX = 0.995


def gain_variance(r_base: np.ndarray, r_cand: np.ndarray, noise_floor: float) -> float:
    """Var(D) of a block (see the module docstring)."""
    delta = r_base - r_cand
    n = len(r_cand)
    if n < 3:
        return 4.0 * noise_floor**2 * float(np.dot(delta, delta))
    e = r_cand - r_cand.mean()
    ss = float(np.dot(e, e))
    var = max(ss / (n - 1), noise_floor**2)
    rho = float(np.dot(e[:-1], e[1:])) / ss if ss > 0 else 0.0
    rho = min(max(rho, 0.0), RHO_MAX)
    return 4.0 * var * (1.0 + rho) / (1.0 - rho) * float(np.dot(delta, delta))


@dataclass(frozen=True, slots=True)
class BlockGain:
    """One held-out block: its sum of squared residuals before and after, and the variance
    of the gain's sum; ``kind`` tags the block (e.g. after a start or after a stop)."""

    kind: str
    sse_base: float
    sse_cand: float
    var_gain: float
    n: int

    @property
    def gain(self) -> float:
        return self.sse_base - self.sse_cand


def block_gain(kind: str, r_base: np.ndarray, r_cand: np.ndarray, noise_floor: float) -> BlockGain:
    return BlockGain(
        kind,
        float(np.dot(r_base, r_base)),
        float(np.dot(r_cand, r_cand)),
        gain_variance(r_base, r_cand, noise_floor),
        len(r_cand),
    )


@dataclass(frozen=True, slots=True)
class Evidence:
    """Pooled out-of-sample evidence of a candidate over its held-out blocks."""

    blocks: tuple[BlockGain, ...]

    @property
    def gain(self) -> float:
        return sum(b.gain for b in self.blocks)

    @property
    def sse_base(self) -> float:
        return sum(b.sse_base for b in self.blocks)

    @property
    def n(self) -> int:
        return sum(b.n for b in self.blocks)

    @property
    def z(self) -> float:
        var = sum(b.var_gain for b in self.blocks)
        if var <= 0.0:
            return 0.0 if self.gain <= 0 else math.inf
        return self.gain / math.sqrt(var)

    @property
    def relative_gain(self) -> float:
        return self.gain / self.sse_base if self.sse_base > 0 else 0.0

    def rmsd(self) -> tuple[float, float]:
        """Held-out RMSD before and after."""
        n = max(self.n, 1)
        after = sum(b.sse_cand for b in self.blocks)
        return math.sqrt(self.sse_base / n), math.sqrt(after / n)

    def of_kind(self, kind: str) -> Evidence:
        return Evidence(tuple(b for b in self.blocks if b.kind == kind))

    def resampled(self, rng: np.random.Generator) -> Evidence:
        """The blocks drawn again with replacement (a block bootstrap)."""
        if not self.blocks:
            return self
        idx = rng.integers(0, len(self.blocks), len(self.blocks))
        return Evidence(tuple(self.blocks[i] for i in idx))


def folds(n_blocks: int, k_max: int = 6) -> list[list[int]]:
    """Blocks assigned round-robin to at most ``k_max`` folds (neighbours apart)."""
    k = min(n_blocks, k_max)
    return [list(range(f, n_blocks, k)) for f in range(k)]


def cross_validate(
    blocks: Sequence[tuple],
    fit: Callable[[list[tuple]], dict[str, float]],
    residuals: Callable[[dict[str, float] | None, tuple], np.ndarray],
    noise_floor: float,
) -> tuple[Evidence, list[dict[str, float]]]:
    """Blocked cross-validation: for each fold, ``fit`` on the other blocks and score the
    fold's blocks; a block is a tuple whose first item is its kind; ``residuals(None,
    block)`` are the base model's. With a single block there is nothing to fit on: the
    evidence is empty."""
    gains: list[BlockGain] = []
    thetas: list[dict[str, float]] = []
    if len(blocks) < 2:
        return Evidence(()), thetas
    for fold in folds(len(blocks)):
        theta = fit([blocks[i] for i in range(len(blocks)) if i not in fold])
        thetas.append(theta)
        for i in fold:
            block = blocks[i]
            gains.append(
                block_gain(block[0], residuals(None, block), residuals(theta, block), noise_floor)
            )
    return Evidence(tuple(gains)), thetas
