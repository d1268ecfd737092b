"""When the burner actually burns, read from the flue gas: the firing the model replays.

The paper validated Type 869 with the measured on/off commands as inputs (Carlon et al.
2015, Section 3.2). A real boiler's own controller (its restart rule, minimum burn time,
pre-purge and ignition) decides *when* it burns, and none of that is in the model; so the
diagnosis replays the combustion the lab observed instead of letting the model's
thermostat decide, and compares the rest.

Combustion is observed where the dry O2 falls below :data:`O2_BURNING_PCT` (air alone reads
20.9 vol-%; a pellet flame at any load of the modulation range reads 5-16 vol-%). Runs
shorter than :data:`MIN_RUN_S` are flicker of the threshold and are merged into their
neighbours. Without a usable O2 column (missing or constant), the ``boiler_on`` column, or
else the flue gas running 20 K hotter than the boiler water, marks the firing.

The start and the stop of each burn are refined with the flue-gas temperature, whose probe
answers in seconds while the analyser's sample line delays O2 by tens of seconds: a start
is the first row, at most :data:`ONSET_LOOKBACK_S` before the O2 crossing, where the flue
gas has risen :data:`ONSET_RISE_K` above its value before the burn; a stop is the first
row, at most as long before the O2 crossing, where the flue gas has fallen
:data:`STOP_FALL_K` below its value in the flame (a pellet flame's flue gas modulates by a
few kelvin; a dying flame's falls by tens within a minute). Without that refinement the
model keeps its flame for the sample line's delay after the real one went out.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from hil_client.analysis.logio import LabLog, fill_gaps, refills

O2_BURNING_PCT = 19.0
MIN_RUN_S = 90.0
ONSET_RISE_K = 3.0
ONSET_LOOKBACK_S = 180.0
STOP_FALL_K = 10.0
#: Least fuel a burn of the burner feeds [kg]: two steps of the balance (0.02 kg, Section
#: 2.2).
NO_FEED_KG = 0.04


@dataclass(frozen=True, slots=True)
class Firing:
    """Observed combustion per row and the rows where burns start and stop."""

    burning: np.ndarray  # bool per row
    starts: np.ndarray  # row indices where a burn starts
    stops: np.ndarray  # row indices of the first row after a burn
    source: str


def _merge_short_runs(state: np.ndarray, t: np.ndarray, min_run_s: float) -> np.ndarray:
    """Runs of equal state shorter than ``min_run_s`` take the state of the run before."""
    state = state.copy()
    for _ in range(3):  # a merge can create a new short run; three passes settle it
        edges = np.flatnonzero(np.diff(state.astype(np.int8))) + 1
        bounds = np.concatenate(([0], edges, [len(state)]))
        changed = False
        for a, b in itertools.pairwise(bounds):
            if a == 0 or b >= len(state):
                continue  # the first and last runs are cut by the record, not short
            if t[b - 1] - t[a] < min_run_s:
                state[a:b] = state[a - 1]
                changed = True
        if not changed:
            break
    return state


def _usable(values: np.ndarray) -> bool:
    ok = values[~np.isnan(values)]
    return len(ok) > 10 and float(np.ptp(ok)) > 1.0


def observe_firing(log: LabLog) -> Firing:
    """Observed combustion of a log (see the module docstring)."""
    t = log.t
    o2 = log["flue_gas_O2_pct"]
    fg = fill_gaps(log["flue_gas_temp_C"], t)
    if _usable(o2):
        burning = fill_gaps(o2, t) < O2_BURNING_PCT
        source = "O2"
    elif log.has("boiler_on") and _usable(log["boiler_on"] * 10.0):
        burning = fill_gaps(log["boiler_on"], t) >= 0.5
        source = "boiler_on"
    else:
        burning = fg > fill_gaps(log["boiler_water_temp_C"], t) + 20.0
        source = "flue gas"
    burning = _merge_short_runs(np.nan_to_num(burning).astype(bool), t, MIN_RUN_S)
    change = np.flatnonzero(np.diff(burning.astype(np.int8))) + 1
    starts = change[burning[change]]
    stops = change[~burning[change]]
    if source == "O2" and np.isfinite(fg).all():
        refined = []
        for i in starts:
            lo = int(np.searchsorted(t, t[i] - ONSET_LOOKBACK_S))
            base = fg[lo]
            hot = np.flatnonzero(fg[lo : i + 1] > base + ONSET_RISE_K)
            refined.append(lo + int(hot[0]) if len(hot) else i)
        starts = np.array(refined, dtype=int)
        for i, j in zip(change[burning[change]], starts, strict=True):
            burning[j:i] = True
        refined = []
        for i in stops:
            lo = int(np.searchsorted(t, t[i] - ONSET_LOOKBACK_S))
            lo = max(lo, int(starts[starts < i][-1]) + 1 if np.any(starts < i) else lo)
            flame = fg[lo]
            cold = np.flatnonzero(fg[lo : i + 1] < flame - STOP_FALL_K)
            refined.append(lo + int(cold[0]) if len(cold) else i)
        new_stops = np.array(refined, dtype=int)
        for i, j in zip(stops, new_stops, strict=True):
            burning[j:i] = False
        starts, stops = _join_flicker(burning, t, starts, new_stops)
    if log.has("balance_mass_kg"):
        starts, stops = _drop_burnouts(burning, t, log["balance_mass_kg"], starts, stops)
    return Firing(burning, starts.astype(int), stops.astype(int), source)


def _drop_burnouts(
    burning: np.ndarray, t: np.ndarray, mass: np.ndarray, starts: np.ndarray, stops: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A burn after a stop during which the balance loses less than
    :data:`NO_FEED_KG` is the bed burning out (smouldering on the draught), not the burner
    starting again: the burner feeds at least Pmin's fuel, tenths of a kilogram in the
    minutes a burn lasts. It is not firing (the model's burner stays off); the burn at the
    record's start, burns where the balance has too few readings and burns across a refill
    of the balance (:func:`~hil_client.analysis.logio.refills`: its feed cannot be read
    across it) are kept."""
    keep_starts, keep_stops = [], []
    for i in starts:
        later = stops[stops > i]
        end = int(later[0]) if len(later) else len(t)
        readings = mass[i:end][np.isfinite(mass[i:end])]
        after_a_stop = i > 0 and np.any(stops < i) and len(readings) >= 10
        refilled = bool(refills(mass[i:end], t[i:end]))
        lost = float(readings[:5].mean() - readings[-5:].mean()) if len(readings) else 0.0
        if after_a_stop and not refilled and lost < NO_FEED_KG:
            burning[i:end] = False
            continue
        keep_starts.append(i)
        if len(later):
            keep_stops.append(end)
    # a stop belongs to a kept burn (the record may start burning)
    first_burn_stop = [int(j) for j in stops if not np.any(starts < j)]
    keep_stops = sorted(set(keep_stops) | set(first_burn_stop))
    return np.array(keep_starts, dtype=int), np.array(keep_stops, dtype=int)


def _join_flicker(
    burning: np.ndarray, t: np.ndarray, starts: np.ndarray, stops: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A stop followed by a start within :data:`MIN_RUN_S` is one burn (a bed burning out
    on the fan's air after the burner was switched off dips the flue gas and the O2 in
    turn); ``burning`` is filled in between."""
    keep_starts, keep_stops = list(starts), []
    for j in stops:
        later = [i for i in keep_starts if i > j]
        if later and t[later[0]] - t[j] < MIN_RUN_S:
            burning[j : later[0]] = True
            keep_starts.remove(later[0])
        else:
            keep_stops.append(j)
    return np.array(keep_starts, dtype=int), np.array(keep_stops, dtype=int)


def windows_after(t: np.ndarray, rows: np.ndarray, length_s: float, end: int) -> list[np.ndarray]:
    """Row indices of the window of ``length_s`` after each of ``rows`` (cut at ``end``)."""
    out = []
    for i in rows:
        j = min(int(np.searchsorted(t, t[i] + length_s)), end)
        if j - i >= 3:
            out.append(np.arange(i, j))
    return out
