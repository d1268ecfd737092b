"""Where the curve candidates read their effect: the runs of low flow or stagnation (the
exit pipe) and the 30 min after each stop of the burner once the analyser reads air (the
body, the flue-gas store), cut into blocks for the cross-validation.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from hil_client.analysis.candidates.base import AIR_O2_MARGIN_PCT, BLOCK_S, O2_AIR_PCT, split_rows
from hil_client.analysis.firing import MIN_RUN_S, windows_after
from hil_client.analysis.replay import Case

WINDOW_S = 1800.0


SUB_BLOCK_S = 300.0


SETTLED_BURN_S = 1800.0


#: Longest burn-out waited for after a stop [s]: a bed left on the grate can smoulder on the
#: draught for a quarter of an hour and more once the burner stops.
BURNOUT_MAX_S = 1800.0


#: Shortest stretch of air after a stop the stored heat is read from [s]: the probe's
#: settling (:data:`PROBE_SETTLE_S`), a minute of reference and a 5-min block to read the
#: fall in; a shorter one (a bed rekindling minutes after the stop) leaves the reading to
#: the next stretch.
AIR_PERIOD_MIN_S = 450.0


#: The residual after a stop is taken relative to its mean over this long from the end of
#: combustion [s].
STOP_REFERENCE_S = 60.0


#: The steady burn before a stop the water's residual is referred to [s].
PRE_STOP_S = 90.0


#: The flue gas's fall is read from this long after the end of combustion [s]: three time
#: constants of the slowest duct probe a bench uses (a sheathed thermocouple, 10-30 s in
#: gas), so the probe's own lag is not taken for stored heat.
PROBE_SETTLE_S = 90.0


#: How long after the flow falls a pipe's evidence starts (see :func:`low_flow_blocks`).
PIPE_SETTLE_S = 300.0


#: Below this share of the test's flow the forward sensor no longer reads the boiler water
#: within a sensor's lag (the exit pipe's transport and losses take over).
LOW_FLOW_SHARE = 0.3


def test_flow_kg_h(case: Case) -> float:
    """The water flow of the test phase (its median) [kg/h]."""
    test = case.phases.mask("test", case.t)
    return float(np.median(case.flow[test])) if test.any() else float(np.max(case.flow))


def low_flow_blocks(case: Case) -> list[tuple[str, np.ndarray, int]]:
    """Runs of low flow or none, in 1-h blocks anchored :data:`PIPE_SETTLE_S` into their run.

    The anchor takes out what the sensors' own lags and a flow-dependent offset of the
    boiler-water reading (stratification at its well) do within minutes of the flow
    changing; a pipe's mark is what follows: the forward reading falling away toward the
    room as the stagnant water cools, or trailing the boiler water by its transport delay."""
    t = case.t
    nominal = test_flow_kg_h(case)
    after_start = t > case.phases.t0
    low = np.flatnonzero(after_start & (case.flow < LOW_FLOW_SHARE * nominal))
    out = []
    for run in split_rows(low, t, math.inf):
        anchor = int(run[0]) + int(np.searchsorted(t[run], t[run[0]] + PIPE_SETTLE_S))
        rest = run[run > anchor]
        kind = "stagnant" if np.median(case.flow[run]) < 0.01 * nominal else "low_flow"
        out += [(kind, p, anchor) for p in split_rows(rest, t, BLOCK_S)]
    return out


def air_periods(case: Case, stop: int, end: int) -> list[tuple[int, int]]:
    """The runs of rows between ``stop`` and at most :data:`BURNOUT_MAX_S` later (and
    ``end``) where the dry O2 reads the air's (within :data:`AIR_O2_MARGIN_PCT`): no
    combustion; a bed smouldering on the draught can take the O2 down again minutes after it
    first read air (runs apart by less than a flicker of the analyser, :data:`MIN_RUN_S`, are
    one). The last run is extended to ``end``. Without a usable O2 column, the
    whole stretch from ``stop``."""
    o2 = case.log["flue_gas_O2_pct"]
    ok = np.isfinite(o2)
    if ok.sum() < 10 or float(np.ptp(o2[ok])) < 1.0:
        return [(stop, end)]
    t = case.t
    last = min(int(np.searchsorted(t, t[stop] + BURNOUT_MAX_S)), end)
    window = o2[stop:last]
    air = ~(np.isfinite(window) & (window < O2_AIR_PCT - AIR_O2_MARGIN_PCT))
    edges = np.flatnonzero(np.diff(air.astype(np.int8))) + 1
    bounds = [0, *edges.tolist(), len(air)]
    runs: list[tuple[int, int]] = []
    for x, y in itertools.pairwise(bounds):
        if not air[x]:
            continue
        if runs and t[stop + x] - t[runs[-1][1] - 1] < MIN_RUN_S:  # a flicker, not a bed
            runs[-1] = (runs[-1][0], stop + y)
        else:
            runs.append((stop + x, stop + y))
    if not runs:
        return [(last, end)] if last < end else []
    if runs[-1][1] == last:
        runs[-1] = (runs[-1][0], end)
    return runs


def stop_blocks(case: Case) -> list[tuple[str, np.ndarray, int]]:
    """The 30 min after each stop of the burner that ends at least 30 min of burning (cut at
    the next start), from the end of combustion on, in 5-min blocks anchored at that end.

    Only stops: after a start a real boiler's own start-up (purge, ignition, fuel ramp)
    differs from the model's, and an effect must not be named for absorbing that; only
    after a settled burn, so the start-up's mismatch has died out before the stop; and only
    once the analyser reads air again: heat that reaches the water, or keeps the flue gas
    hot, while the bed still burns out is combustion (the bed of ``ignition_delay``, a
    controller's post-run), not storage in metal or refractory."""
    t = case.t
    edges = case.transitions
    out = []
    for i in case.firing.stops:
        earlier = edges[edges < i]
        if len(earlier) and t[i] - t[earlier[-1]] < SETTLED_BURN_S:
            continue
        later = edges[edges > i]
        end = int(later[0]) if len(later) else len(t)
        # from the first lasting reading of air on, while it lasts (if combustion resumes
        # sooner every time, from the end of combustion for good)
        periods = air_periods(case, int(i), end)
        if not periods:
            continue
        long_enough = [(a, b) for a, b in periods if t[b - 1] - t[a] >= AIR_PERIOD_MIN_S]
        anchor, stop_reading = long_enough[0] if long_enough else periods[-1]
        for w in windows_after(t, np.array([anchor]), WINDOW_S, stop_reading):
            out += [("stop", piece, anchor) for piece in split_rows(w, t, SUB_BLOCK_S)]
    return out


def stop_blocks_from_burn(case: Case) -> list[tuple[str, np.ndarray, int]]:
    """The blocks of :func:`stop_blocks` anchored at the stop itself: their residual is
    taken relative to the steady burn just before it (the water a body warms after the
    flame goes out, measured from where it stood while burning; a body of minutes has
    given much of its heat by the time the analyser reads air)."""
    stops = case.firing.stops
    return [
        (kind, rows, int(stops[stops <= anchor][-1])) for kind, rows, anchor in stop_blocks(case)
    ]


def stop_ends(blocks: list) -> dict[int, int]:
    """Each stop's anchor (the end of combustion) and the end of its last block."""
    ends: dict[int, int] = {}
    for _, rows, anchor in blocks:
        ends[anchor] = max(ends.get(anchor, 0), int(rows[-1]) + 1)
    return ends


def per_stop(
    case: Case, blocks: list, r: np.ndarray, reference_s: float, over_s: float, from_s: float
):
    """Per stop: the residual over ``reference_s`` from ``from_s`` after the anchor, and
    over the last ``over_s`` of its window, as (reference, rows) pairs of finite values."""
    t = case.t
    out = []
    for a, e in stop_ends(blocks).items():
        ref = r[
            int(np.searchsorted(t, t[a] + from_s)) : int(
                np.searchsorted(t, t[a] + from_s + reference_s)
            )
        ]
        part = r[int(np.searchsorted(t, t[e - 1] - over_s)) : e]
        ref, part = ref[np.isfinite(ref)], part[np.isfinite(part)]
        if len(ref) and len(part):
            out.append((ref, part))
    return out
