"""Whether a held-out log is the calibration log's record again (CONTRACT section 4: the
held-out log stays held out, nothing is fitted or selected on it).

The same file and a byte copy are found by the command line. A record exported again is
not a copy: its times re-based or made absolute, its numbers rounded, its rows thinned,
some dropped, or a part of it cut out; ``diagnose`` took such copies as held out and
scored 85-98 % shrinkage measured on the calibration data itself (strangers' probes).

Two logs are the same record where, on one alignment of their times, their boiler-water
and flue-gas temperatures agree to within :data:`SAME_RECORD_K` in the median over the
rows the burner fires in both, and those rows make at least half of the firing of the
log that fires the shorter time. The alignments tried: their own times (a row dropped, a
part cut out), each counted from its start (times re-based on export), their first
firings (both at once), and the best match of their flue-gas changes (a part cut out and
re-based), the last two each to within the sparser log's step. The firing rows are the
ones that tell: two clean emulated runs of different tests share their preheat exactly,
and cool to the same room temperature for hours, where 0.006 K apart in the median made
them one record (a re-probe). Two runs of the same test differ by their instruments'
noise (0.05-0.1 K).

Not found: a copy processed beyond the threshold (averaged over 10 s, rounded to one
decimal, noise of 0.03 K added: 0.02-0.03 K apart), which a threshold cannot tell from
another run of a deterministic plant. Two clean emulated runs that fire the same way for
most of the shorter one's firing (a 4-h and a 6-h stationary test) are one record there,
which they are.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from hil_client.analysis.firing import observe_firing
from hil_client.analysis.logio import LabLog, fill_gaps

#: The most two records' temperatures differ in the median to be the same record [K]: a
#: re-export rounded to two decimals (0.005 K), a column nudged by a hundredth.
SAME_RECORD_K = 0.02

#: The signals compared: the water's slow one, the flue gas's fast one.
COLUMNS = ("boiler_water_temp_C", "flue_gas_temp_C")

#: The least share of the shorter firing the shared rows make.
SHARED_MIN = 0.5


@dataclass
class _Record:
    """What is compared of a log: its times, the rows its burner fires (every row where it
    never does), its temperatures with their gaps filled."""

    t: np.ndarray
    firing: np.ndarray
    values: dict[str, np.ndarray]

    @classmethod
    def of(cls, log: LabLog) -> _Record:
        burning = observe_firing(log).burning
        firing = burning if burning.any() else np.ones(len(log), dtype=bool)
        return cls(log.t, firing, {name: fill_gaps(log[name], log.t) for name in COLUMNS})

    @cached_property  # (asked for at every shift tried)
    def step(self) -> float:
        return float(np.median(np.diff(self.t)))

    @cached_property
    def firing_s(self) -> float:
        return float(self.firing.sum()) * self.step


def same_record(a: LabLog, b: LabLog) -> bool:
    """Whether ``a`` and ``b`` hold the same record, or one holds a part of the other (see
    the module docstring); symmetric."""
    if len(a) < 2 or len(b) < 2:
        return False
    ra, rb = _Record.of(a), _Record.of(b)
    if any(np.isnan(r.values[name]).all() for r in (ra, rb) for name in COLUMNS):
        return False
    shifts = [0.0, float(a.t[0] - b.t[0])]
    # a thinned copy's first firing row, or its best match, is up to one of its steps (or
    # of the match's grid) from the other's
    sparse, dense = max(ra.step, rb.step), min(ra.step, rb.step)
    for centre, within in (
        (float(a.t[np.argmax(ra.firing)] - b.t[np.argmax(rb.firing)]), sparse),
        (_best_match(ra, rb, max(sparse, MATCH_GRID_S)), max(sparse, MATCH_GRID_S)),
    ):
        reach = min(int(np.ceil(within / dense)), MATCH_REACH) if dense > 0 else 0
        shifts += [centre + k * dense for k in range(-reach, reach + 1)]
    return any(_follows(ra, rb, shift) for shift in dict.fromkeys(shifts))


#: The grid the flue gas's changes are matched on [s], and the most steps of the denser
#: log tried either side of a match.
MATCH_GRID_S = 10.0
MATCH_REACH = 60


def _best_match(a: _Record, b: _Record, grid_s: float) -> float:
    """The shift [s] that lays ``b``'s flue-gas changes best on ``a``'s (cross-correlation
    on a grid of ``grid_s``): a copy cut after its first firing and its times re-based
    lines up with neither its start nor its firing (a re-probe: 85 % shrinkage on the
    calibration data itself). Only a candidate: :func:`_follows` judges it."""
    changes = []
    for r in (a, b):
        t = np.arange(r.t[0], r.t[-1], grid_s)
        y = np.interp(t, r.t, np.nan_to_num(r.values["flue_gas_temp_C"]))
        changes.append((t[0], np.diff(y)))
    (start_a, da), (start_b, db) = changes
    if len(da) < 2 or len(db) < 2:
        return 0.0
    size = 1 << int(np.ceil(np.log2(len(da) + len(db))))
    spectrum = np.fft.rfft(da, size) * np.conj(np.fft.rfft(db, size))
    corr = np.fft.irfft(spectrum, size)
    lag = int(np.argmax(corr))
    lag = lag - size if lag > size // 2 else lag  # (a's row lag = b's row 0)
    return float(start_a - start_b + lag * grid_s)


def _follows(a: _Record, b: _Record, shift: float) -> bool:
    """Whether ``b``, its times moved by ``shift`` [s], follows ``a`` over the rows both
    fire in; compared at the rows of the sparser of the two (a thinned copy's rows are rows
    of the other, whichever of the two it is)."""
    ta, tb = a.t, b.t + shift
    lo, hi = max(ta[0], tb[0]), min(ta[-1], tb[-1])
    if not hi > lo:
        return False
    (sparse, ts), (dense, td) = ((a, ta), (b, tb)) if a.step >= b.step else ((b, tb), (a, ta))
    # firing in both: the sparse log's row, and the dense log's row at or before it
    nearest = np.clip(np.searchsorted(td, ts, side="right") - 1, 0, len(td) - 1)
    shared = (ts >= lo) & (ts <= hi) & sparse.firing & dense.firing[nearest]
    if shared.sum() < 2 or shared.sum() * sparse.step < SHARED_MIN * min(a.firing_s, b.firing_s):
        return False
    for name in COLUMNS:
        apart = np.abs(np.interp(ts[shared], td, dense.values[name]) - sparse.values[name][shared])
        if not float(np.nanmedian(apart)) <= SAME_RECORD_K:
            return False
    return True
