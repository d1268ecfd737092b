"""What every candidate shares: the evidence thresholds, the :class:`Assessment` a
candidate gives the diagnosis, and :class:`CurveCandidate`, a candidate that predicts one
lab signal and is scored by blocked cross-validation in time where its effect acts.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from hil_client.analysis.evidence import BlockGain, Evidence, cross_validate
from hil_client.analysis.replay import Case
from rig_emulator.model import constants as k

#: Out-of-sample evidence needed to name an effect [standard errors]: one-sided p ~ 0.001,
#: about 0.007 over the five candidates.
Z_MIN = 3.0


#: Share of the held-out squared residual where the effect acts that it must remove.
REL_MIN = 0.2


#: Held-out RMSD an effect must remove where it acts [signal units]: what the bench's
#: sensors resolve (Pt100 class A/B tolerances, Section 2.2); for the pipe, which is read
#: from the forward sensor against the boiler water's, what two class-A Pt100s at 80 C
#: (0.15 K + 0.002 T: 0.31 K each) can disagree by in how they follow a change, 0.44 K.
ABS_MIN = {"water_out_temp_C": 0.5, "boiler_water_temp_C": 0.2, "flue_gas_temp_C": 1.0}


#: Resolution of each signal [signal units]: readings 0.01 K, Pt100 noise (Section 2.2).
NOISE_FLOOR = {"water_out_temp_C": 0.02, "boiler_water_temp_C": 0.02, "flue_gas_temp_C": 0.1}


def straight_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares slope and intercept of ``y`` on ``x`` (``np.polyfit(x, y, 1)`` in
    closed form: the grid searches fit one per grid point and block, and polyfit's general
    solver took a fifth of a diagnosis); ``x`` must not be constant."""
    x_mean, y_mean = float(np.mean(x)), float(np.mean(y))
    dx = x - x_mean  # (sums of products, not np.dot: BLAS's threads, spinning for a core
    slope = float(np.sum(dx * (y - y_mean)) / np.sum(dx * dx))  # on a loaded machine,
    return slope, y_mean - slope * x_mean  # took 28 ms a call, a thousand times longer)


#: Air's dry O2 [vol-%] and how close to it the analyser reads once combustion has ended.
O2_AIR_PCT = 20.95


AIR_O2_MARGIN_PCT = 0.5


BLOCK_S = 3600.0


BALANCE_STEP_KG = 0.02  # the balance's resolution (Section 2.2)


@dataclass
class Assessment:
    """What a candidate found on the calibration log."""

    effect: str
    signal: str
    locus: str
    params: dict[str, float]
    units: list  # bootstrap units
    decide: Callable[[Sequence], tuple[bool, float, str]]  # units -> (named?, z, reason)
    rmsd_before: float
    rmsd_after: float
    #: how far the effect's physical mark stands beyond the floor a real boiler's
    #: background reaches without it (1: at the floor); ranks the named candidates
    margin: float = 0.0
    #: the separate events (stops, starts, low-flow periods, the closure's loads) the
    #: evidence was read in; 0 where it is not read event by event
    events: int = 0
    #: the verdict of the held-out evidence alone, the physical mark aside (units ->
    #: named?); None: :attr:`decide` has no mark of its own to set aside
    evidence: Callable[[Sequence], bool] | None = None

    def verdict(self, units: Sequence | None = None) -> tuple[bool, float, str]:
        """(named?, z, why) on ``units`` (default: the log's own); evidence that is not a
        number (a signal the log lacks entirely) names nothing."""
        named, z, why = self.decide(self.units if units is None else units)
        if named and math.isnan(z):
            return False, z, "its evidence is not a number (a signal it needs is missing)"
        return named, z, why

    def evidence_named(self) -> bool:
        """Whether the held-out evidence alone would name it, however far its mark stands
        from its floor: with :attr:`margin` >= 1 this tells *what* stopped a candidate
        (too little evidence, too small a mark, or both)."""
        if self.evidence is None:
            return self.verdict()[0]
        return bool(self.evidence(self.units))


@dataclass(frozen=True)
class GridSSE:
    """Sums of squares of a candidate's residual per grid point and block
    (:meth:`CurveCandidate.grid_sse`)."""

    blocks: list[tuple]
    thetas: list[dict[str, float]]
    #: per grid point: the sum of squares on each of ``blocks``
    table: list[list[float]]

    def best(self, blocks: list[tuple]) -> dict[str, float]:
        """The first grid point of least sum of squares on ``blocks`` (some of the table's,
        summed in the order given)."""
        index = {id(b): i for i, b in enumerate(self.blocks)}
        columns = [index[id(b)] for b in blocks]
        best, best_sse = None, math.inf
        for theta, row in zip(self.thetas, self.table, strict=True):
            sse = sum(row[i] for i in columns)
            if sse < best_sse:
                best, best_sse = theta, sse
        assert best is not None
        return best


@dataclass(frozen=True)
class CurveCandidate:
    effect: str
    signal: str
    locus: str
    grid: dict[str, np.ndarray]
    predict: Callable[[Case, dict[str, float] | None], np.ndarray]
    #: (kind, rows, anchor row or -1): where the effect acts, in blocks
    blocks: Callable[[Case], list[tuple[str, np.ndarray, int]]]
    nuisance_drift: bool
    #: a block's residual is taken relative to its mean over this long before its anchor
    #: [s] (the response to a start or stop, not the mismatch the plant carried into it,
    #: which the flow washes out of the water as :func:`carried_share` says; only the
    #: water's signal is anchored before); negative: over this long from the anchor on
    anchor_s: float | None = None
    #: the physical mark the data must show for the effect to be named, read from the
    #: unaugmented model's residual: (case, blocks, residual) -> (mark over its floor,
    #: why not when below 1)
    fingerprint: Callable[[Case, list, np.ndarray], tuple[float, str]] | None = None
    #: fitted parameters that must reach a floor for the effect to be named, with why:
    #: below it the fit describes something else (a sensor's own lag)
    floors: dict[str, tuple[float, str]] = field(default_factory=dict)

    def residual(self, case: Case, theta: dict[str, float] | None) -> np.ndarray:
        """Lab minus prediction, less the sensor's offset (and drift) fitted on the settled
        rows, where no candidate acts."""
        r = case.lab[self.signal] - self.predict(case, theta)
        ref = case.settled
        x = case.t - case.t[ref].mean()
        if self.nuisance_drift and np.ptp(case.t[ref]) >= 7200.0:
            slope, intercept = straight_line(x[ref], r[ref])
            return r - (intercept + slope * x)
        return r - float(np.mean(r[ref]))

    def block_residual(self, case: Case, r: np.ndarray, block: tuple) -> np.ndarray:
        """The residual on one block, anchored at its transition when it has one: less the
        mismatch carried into it as it decays (anchored before) or less the mean after it."""
        _, rows, anchor = block
        if self.anchor_s is None or anchor < 0:
            return r[rows]
        if self.anchor_s < 0:  # the reference follows the anchor
            j = int(np.searchsorted(case.t, case.t[anchor] - self.anchor_s))
            return r[rows] - (float(np.mean(r[anchor:j])) if j > anchor else float(r[anchor]))
        j = int(np.searchsorted(case.t, case.t[anchor] - self.anchor_s))
        before = r[j:anchor][np.isfinite(r[j:anchor])]
        carried = float(np.mean(before)) if len(before) else float(r[anchor])
        return r[rows] - carried * carried_share(case, anchor)[rows]

    def grid_sse(self, case: Case, blocks: list[tuple]) -> GridSSE:
        """Each point of the grid with the sum of squares of its residual on each block:
        the residual over the whole log is computed once per point, and every fit on any
        set of the blocks (the folds' and the final one) is read from the table."""
        names = list(self.grid)
        thetas, table = [], []
        for point in np.array(np.meshgrid(*self.grid.values())).reshape(len(names), -1).T:
            theta = dict(zip(names, point.tolist(), strict=True))
            full = self.residual(case, theta)
            thetas.append(theta)
            table.append([float(np.sum(self.block_residual(case, full, b) ** 2)) for b in blocks])
        return GridSSE(blocks, thetas, table)

    def decide(self, units: Sequence[BlockGain]) -> tuple[bool, float, str]:
        ev = Evidence(tuple(units))
        z = ev.z
        if not ev.blocks:
            return False, 0.0, "too few blocks to test out of sample"
        before, after = ev.rmsd()
        if z < Z_MIN:
            return False, z, f"held-out evidence {z:.1f} < {Z_MIN:g} standard errors"
        if ev.relative_gain < REL_MIN:
            return False, z, f"explains {ev.relative_gain:.0%} < {REL_MIN:.0%} where it acts"
        if before - after < ABS_MIN[self.signal]:
            return False, z, f"removes {before - after:.2g} < {ABS_MIN[self.signal]:g} RMSD"
        return True, z, "named"

    def evidence(self, units: Sequence[BlockGain]) -> bool:
        """The held-out evidence alone (:meth:`decide` before the fingerprint)."""
        named, z, _ = self.decide(units)
        return named and not math.isnan(z)

    def assess(self, case: Case) -> Assessment:
        blocks = self.blocks(case)
        table = self.grid_sse(case, blocks) if blocks else None
        residuals: dict[tuple | None, np.ndarray] = {}  # per theta scored (None: the base)

        def block_residual(theta: dict[str, float] | None, block: tuple) -> np.ndarray:
            key = None if theta is None else tuple(theta.items())
            if key not in residuals:
                residuals[key] = self.residual(case, theta)
            return self.block_residual(case, residuals[key], block)

        ev, _ = cross_validate(
            blocks,
            lambda train: table.best(train),
            block_residual,
            NOISE_FLOOR[self.signal],
        )
        theta = table.best(blocks) if table else {}
        before, after = ev.rmsd() if ev.blocks else (math.nan, math.nan)
        decide = self.decide
        # without a fingerprint of its own, the mark is the RMSD it removes where it acts
        margin = (before - after) / ABS_MIN[self.signal] if ev.blocks else 0.0
        if self.fingerprint is not None and blocks:
            margin, why = self.fingerprint(case, blocks, self.residual(case, None))
            for name, (floor, reason) in self.floors.items():
                if theta.get(name, math.inf) < floor:
                    margin, why = 0.0, f"{name} {theta[name]:.3g} < {floor:g}: {reason}"
            if margin < 1.0:

                def decide(units, why=why):
                    _, z, _ = self.decide(units)
                    return False, z, why

        return Assessment(
            self.effect,
            self.signal,
            self.locus,
            theta,
            list(ev.blocks),
            decide,
            before,
            after,
            float(margin) if math.isfinite(margin) else 0.0,
            len({anchor for _, _, anchor in blocks}),
            self.evidence,
        )

    def prediction(self, case: Case, theta: dict[str, float]) -> dict[str, np.ndarray]:
        """The lab signals this effect changes, as the model with it predicts them."""
        return {self.signal: self.predict(case, theta)}

    def held_out(self, case: Case, theta: dict[str, float]) -> tuple[float, float]:
        """RMSD before and after on another log, where the effect acts (parameters frozen)."""
        blocks = self.blocks(case)
        if not blocks or not theta:
            return math.nan, math.nan
        full0, full1 = self.residual(case, None), self.residual(case, theta)
        r0 = np.concatenate([self.block_residual(case, full0, b) for b in blocks])
        r1 = np.concatenate([self.block_residual(case, full1, b) for b in blocks])
        return float(np.sqrt(np.mean(r0**2))), float(np.sqrt(np.mean(r1**2)))


def split_rows(rows: np.ndarray, t: np.ndarray, length_s: float) -> list[np.ndarray]:
    """Contiguous runs of ``rows``, cut into pieces of at most ``length_s``."""
    if not len(rows):
        return []
    runs = np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)
    out = []
    for run in runs:
        piece = (t[run] - t[run[0]]) // length_s
        out += [run[piece == p] for p in np.unique(piece)]
    return [p for p in out if len(p) >= 10]


def carried_share(case: Case, anchor: int) -> np.ndarray:
    """Share of a mismatch of the water's temperature at row ``anchor`` left in each row
    (1 up to the anchor): lab and model water follow the same measured flow, return and
    room (the single node, Eq. 2), so their difference decays as
    exp(-integral (m_w cp_w + UA) / C dt) when no heat enters either; a mismatch carried
    into a stop is not a constant (with the bench's flow, C / (m_w cp_w) is 20-35 min, a
    30-min window)."""

    def compute() -> np.ndarray:
        p = case.params
        ua = np.where(case.firing.burning, p.ua_amb_on_W_K, p.ua_amb_off_W_K) / 1000.0
        rate = (np.maximum(case.flow, 0.0) * k.CP_WATER / 3600.0 + ua) / p.capacity_kJ_K
        lost = np.cumsum(np.nan_to_num(rate) * case.dt)
        share = np.exp(-(lost - lost[anchor]))
        share[: anchor + 1] = 1.0
        return share

    return case.memo(("carried_share", int(anchor)), compute)
