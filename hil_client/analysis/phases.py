"""Phase boundaries t0..t4 of a lab log (Fig. 3 of Carlon et al. 2015).

Taken, in this order of preference, from the ``phase`` column, the meta file (all five
marks t0_s..t4_s; marks that cannot be the log's are refused, see :func:`_from_meta`), or
the signals:

- t0: the burner first fires (``boiler_on``), or, without that column, the flue gas first
  runs 20 K hotter than the water inside the boiler or its O2 falls below 19 vol-%;
- t1: after t0, the least-squares rise of the flue-gas temperature over 5 min first falls
  below 0.5 K/min (at least 5 min after t0): the rule the runner applies;
- t3: circulation stops: the flow setpoint's last non-zero row, or, without that column,
  the last row before which the flow falls below 5 % of its maximum for good; a record
  cut short while the water still circulates ends its first cooling with its last row
  (named in the log's notes: no second cooling);
- t2: the first cooling is the constant-flow segment ending at t3; t2 is where the flow
  (setpoint) last changed by more than 5 % before it;
- t4: the end of the record.

A boundary is the time of the last row of the phase before it (as the runner records it).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from hil_client.analysis.logio import EPOCH_KEPT, LabLog, LogError, fill_gaps, flow_column
from rig_emulator.yamlio import finite_number

NAMES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
MARKS = ("t0_s", "t1_s", "t2_s", "t3_s", "t4_s")


@dataclass(frozen=True, slots=True)
class Phases:
    """Phase boundaries [s] and where they came from."""

    t0: float
    t1: float
    t2: float
    t3: float
    t4: float
    source: str
    #: marks reached (5: all; fewer: a run cut short, its later marks at its last row)
    reached: int = 5

    def bounds(self, name: str) -> tuple[float, float]:
        """(start, end] of a phase; ``preheat`` starts at -inf."""
        edges = (-np.inf, self.t0, self.t1, self.t2, self.t3, self.t4)
        i = NAMES.index(name)
        return edges[i], edges[i + 1]

    def mask(self, name: str, t: np.ndarray) -> np.ndarray:
        lo, hi = self.bounds(name)
        return (t > lo) & (t <= hi)

    def as_dict(self) -> dict[str, float | None]:
        """The marks; one a run cut short did not reach is None."""
        values = (self.t0, self.t1, self.t2, self.t3, self.t4)
        return {
            key: v if i < self.reached else None
            for i, (key, v) in enumerate(zip(MARKS, values, strict=True))
        }

    @property
    def cut_in(self) -> str | None:
        """The phase a run cut short ended in (None: every mark reached)."""
        return None if self.reached == 5 else NAMES[self.reached]


def _from_column(log: LabLog, partial: bool = False) -> Phases | None:
    """The phases from the ``phase`` column (its names in any letter case, spaces around
    them ignored); None, said in the log's notes, where it does not hold them all. With
    ``partial``, a column that holds the phases in order up to one it ends in (a run cut
    short without its meta file) gives those (a re-probe: refused, "cannot find t2")."""
    if not log.has("phase"):
        return None
    phase = _column_names(log)
    t = log.t
    bounds = {}
    last = None  # the latest of the format's phases so far
    for i in range(1, len(phase)):
        if phase[i] != phase[i - 1] and phase[i] in NAMES:
            if last is not None and NAMES.index(phase[i]) < NAMES.index(last):
                # a run's phases only go on (a restarted phase keeps its name): a second run
                # appended (its rows were read as the first run's second cooling, with its
                # firing and fuel, and a confident parameter file: a stranger's probe)
                raise LogError(
                    f"{log.path or 'the log'}: the phase column goes back from {last} to "
                    f"{phase[i]} at time_s = {t[i]:g}: two runs in one log; split it there"
                )
            last = phase[i]
            bounds.setdefault(phase[i], t[i - 1])
    missing = [n for n in ("start_up", "test", "cooling_1", "cooling_2") if n not in bounds]
    unknown = set(phase) - set(NAMES) - {""}
    present = sorted(NAMES.index(p) for p in set(phase) & set(NAMES))
    # a phase left out between two the column holds (a log that begins or ends mid-run, a
    # later plant's rows, lacks those before or after: no note for those)
    between = NAMES[present[0] : present[-1] + 1] if present else ()
    held = set(phase)
    skipped = [n for n in between if n not in held]
    if missing and (unknown or skipped):  # a lab's own names, a phase left out (ignored
        log.notes.append(  # without a word: a stranger's probe)
            f"the phase column holds no {', '.join(skipped if not unknown else missing)} "
            f"(the log format's phase names: {', '.join(NAMES)}); the phases come from the "
            "meta file or the signals"
        )
    reached = next((i for i, n in enumerate(NAMES[1:]) if n not in bounds), 4)
    if missing and partial and not unknown and not skipped and reached >= 1:
        ends = [float(bounds[n]) for n in NAMES[1 : 1 + reached]] + [float(t[-1])] * (5 - reached)
        source = f"phase column, the run cut short in its {NAMES[reached]} phase"
        return Phases(*ends, source=source, reached=reached)  # type: ignore[arg-type]
    if missing:  # (a run cut short holds the phases it reached)
        return None
    return Phases(
        bounds["start_up"],
        bounds["test"],
        bounds["cooling_1"],
        bounds["cooling_2"],
        float(t[-1]),
        "phase column",
    )


def _column_names(log: LabLog) -> list[str]:
    """The ``phase`` column's names, in lower case, spaces around them left out."""
    return [p.strip().lower() for p in log.text["phase"]]


def _column_begins_late(log: LabLog) -> str | None:
    """The phase the ``phase`` column begins in where it is one of the format's after
    ``preheat`` and the column holds no other names: a record begun mid-run, whose column
    lacks the marks before that phase, so :func:`_from_column` gives no phases and the
    signals find them (the source said "signals" alone, as if the log had no phase column:
    a stranger's probe); None otherwise (no column, one from ``preheat``, or one with names
    of its own, of which a note speaks; or the rows of a later plant, begun mid-run by the
    break, of which :func:`~hil_client.analysis.logio.one_plant`'s note speaks)."""
    if not log.has("phase") or log.meta.get(EPOCH_KEPT) is not None:
        return None
    held = [p for p in _column_names(log) if p]
    if not held or set(held) - set(NAMES) or held[0] == NAMES[0]:
        return None
    return held[0]


def _log_name(log: LabLog) -> str:
    """The log as its notes name it: the path as given (its name alone was not what the
    user typed beside every other message: a stranger's probe)."""
    return str(log.path) if log.path else "the log"


def _meta_file(log: LabLog) -> Path | str:
    """The log's meta file, as messages name it."""
    return log.path.with_name(log.path.stem + ".meta.json") if log.path else "meta file"


def _from_meta(log: LabLog) -> Phases | None:
    """The marks t0_s..t4_s of the meta file; None unless it gives all five (CONTRACT
    section 3: "where known"; an interrupted run's meta file keeps the marks it reached),
    and then the signals tell.

    Marks that cannot be this log's are refused (:class:`LogError` naming the meta file and
    the mark) rather than replaced by marks found from the signals: they are the bench's
    record of when it switched, and a lab user takes the phases of a balance or a
    validation for the recorded ones, while a guess from the signals can put them minutes
    away; a meta file that contradicts its log (edited, or beside another or a truncated
    log) is worth knowing about, and the message says how to fall back to the signals.
    Refused: a mark that is no finite number, marks out of order (t0 < t1 < t2 < t3 <=
    t4), t0..t3 outside the record. A t4_s after the last row is the record's end (its
    last row cut short and left out)."""
    return _meta_marks(log, partial=False)


def _meta_marks(log: LabLog, partial: bool) -> Phases | None:
    """:func:`_from_meta`; with ``partial``, also the marks an interrupted run reached (at
    least t0_s, then each up to the first null), the rest at the record's last row."""
    meta_file = _meta_file(log)
    fix = "; remove t0_s..t4_s from it to find the phases from the signals"
    for key in MARKS:
        v = log.meta.get(key)
        bad = finite_number(v) is None  # (an int of 401 digits overflowed: a probe)
        if v is not None and bad:  # null: not reached (an interrupted run writes that)
            shown = f"{v!r}" if len(repr(v)) <= 40 else f"{repr(v)[:20]}..."
            raise LogError(f"{meta_file}: {key} = {shown} is not a finite number of seconds{fix}")
    present = [key for key in MARKS if log.meta.get(key) is not None]
    reached = next((i for i, key in enumerate(MARKS) if log.meta.get(key) is None), 5)
    if reached < 5 and not (partial and reached and present == list(MARKS[:reached])):
        return None
    first, last = float(log.t[0]), float(log.t[-1])
    values = [float(log.meta[key]) for key in MARKS[:reached]] + [last] * (5 - reached)
    name = log.path.name if log.path else "the log"
    for key, v in zip(MARKS[:reached], values[:4], strict=False):
        if not first <= v <= last:
            raise LogError(
                f"{meta_file}: {key} = {v:g} lies outside the record of {name} (time_s "
                f"{first:g}..{last:g}): marks of another log, or the log cut short{fix}"
            )
    for i in range(1, reached):
        if not (values[i - 1] < values[i] or (i == 4 and values[3] == values[4])):
            raise LogError(
                f"{meta_file}: {MARKS[i]} = {values[i]:g} is not after "
                f"{MARKS[i - 1]} = {values[i - 1]:g}{fix}"
            )
    if values[4] > last + 1.0:  # (it was taken in silence: a stranger's probe)
        log.notes.append(
            f"{meta_file}: t4_s = {values[4]:g} lies after the record's last row ({last:g}):"
            " the second cooling is read to that row (the log cut short?)"
        )
    values[4] = min(values[4], last)
    if reached == 5:
        return Phases(*values, source="meta file")  # type: ignore[arg-type]
    source = f"meta file, the run cut short in its {NAMES[reached]} phase"
    return Phases(*values, source=source, reached=reached)  # type: ignore[arg-type]


def rise_rate_K_min(t: np.ndarray, y: np.ndarray, window_s: float = 300.0) -> np.ndarray:
    """Least-squares slope of ``y`` over the trailing window at every row [K/min]
    (NaN until the window is full). The window reaches back to the latest row at least
    ``window_s`` old, so it fills whatever the step (rows every 40 s never filled 300 s:
    the last row within it was 280 s back, and t1 was never found from the signals in a
    log of a real-time server at x400: a re-probe)."""
    y = fill_gaps(y, t)
    cs, cy, ctt, cty = (np.concatenate(([0.0], np.cumsum(a))) for a in (t, y, t * t, t * y))
    j = np.maximum(np.searchsorted(t, t - window_s, side="right") - 1, 0)
    i1 = np.arange(1, len(t) + 1)
    n = i1 - j
    st, sy = cs[i1] - cs[j], cy[i1] - cy[j]
    stt, sty = ctt[i1] - ctt[j], cty[i1] - cty[j]
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = (n * sty - st * sy) / (n * stt - st * st) * 60.0
    full = (t - t[j] >= window_s * 0.98) & (n >= 3)
    return np.where(full, rate, np.nan)


def _first_firing(log: LabLog) -> int | None:
    """The row the burner first fires (``boiler_on``, or, without it, the flue gas 20 K
    hotter than the water or the O2 below 19 vol-%); None if it never does."""
    t = log.t
    if log.has("boiler_on") and np.nanmax(log["boiler_on"]) >= 0.5:
        return int(np.argmax(log["boiler_on"] >= 0.5))
    hot = fill_gaps(log["flue_gas_temp_C"], t) > fill_gaps(log["boiler_water_temp_C"], t) + 20.0
    lean = fill_gaps(log["flue_gas_O2_pct"], t) < 19.0
    firing = np.flatnonzero(hot | lean)
    return int(firing[0]) if len(firing) else None


def _circulating_rows(log: LabLog) -> np.ndarray:
    """The rows the water circulates: a non-zero flow setpoint, or, without that column, a
    flow above 5 % of its maximum."""
    t = log.t
    if log.has("water_flow_setpoint_kg_h"):
        return np.flatnonzero(fill_gaps(log["water_flow_setpoint_kg_h"], t) > 0.0)
    flow = fill_gaps(log["water_flow_kg_h"], t)
    if np.isnan(flow).all():
        return np.array([], dtype=int)
    with np.errstate(invalid="ignore"):
        return np.flatnonzero(flow > 0.05 * np.nanmax(flow))


#: How far the meta file's t0 and t3 may lie from the burner's first firing and the last
#: circulating row the signals show [s]: the flue gas's 20 K comes a minute or two after
#: the burner's switch, an ignition takes minutes on top; the pump stops at t3 at once.
MARK_SLACK_S = 900.0


def _check_against_signals(log: LabLog, phases: Phases) -> None:
    """:class:`LogError` where the meta file's t0 is far from the log's first firing, or its
    t3 (the circulation stops) from the log's last circulating row: marks of another log
    taken within the record gave confident figures of phases that were not (a test phase
    with the burner off for two hours; a stranger's probe), and a note beside those figures
    was not enough (a stranger's probe: a load cycle's marks on a stationary log gave an
    8-h test and 10.9 kW of fuel where 6 h and 14.3 kW were true). Refused as marks
    outside the record are (:func:`_from_meta`). (t2 has no such mark: a load cycle's
    last, lowest step can leave the burner off for an hour and more before it.)"""
    far = []
    first = _first_firing(log)
    if first is not None and abs(phases.t0 - log.t[first]) > MARK_SLACK_S:
        far.append(f"t0_s = {phases.t0:g} s, the burner first firing at {log.t[first]:g} s")
    running = _circulating_rows(log)
    if len(running) and running[-1] < len(log) - 2:  # (a record cut short circulates on)
        stop = float(log.t[running[-1]])
        if abs(phases.t3 - stop) > MARK_SLACK_S:
            far.append(f"t3_s = {phases.t3:g} s, the circulation stopping at {stop:g} s")
    if far:
        meta_file = _meta_file(log)
        raise LogError(
            f"{meta_file}: {'; '.join(far)} in {_log_name(log)} (more than "
            f"{MARK_SLACK_S / 60:g} min apart): marks of another log? remove t0_s..t4_s "
            "from it to find the phases from the signals"
        )


#: The longest the water may stop circulating between the burner's first firing and the
#: end of the first cooling found from the signals [s]: the protocol circulates throughout
#: (start-up, test and first cooling); a stop this long is the second cooling of one run
#: and the preheat of another appended to it.
STOP_INSIDE_MAX_S = 900.0


def _refuse_a_stop_inside(log: LabLog, running: np.ndarray, i0: int, i3: int) -> None:
    """:class:`LogError` where the circulation stops for over :data:`STOP_INSIDE_MAX_S`
    between rows ``i0`` and ``i3`` (a stationary test with a load cycle appended read as
    one test of 22.7 h, with confident figures: a stranger's probe)."""
    t = log.t
    inside = running[(running >= i0) & (running <= i3)]
    for a, b in itertools.pairwise(inside):
        if b - a > 1 and t[b - 1] - t[a + 1] > STOP_INSIDE_MAX_S:
            raise LogError(
                f"{log.path or 'the log'}: the water stops circulating from time_s = "
                f"{t[a + 1]:g} to {t[b - 1]:g}, inside the run the signals find "
                f"(first firing {t[i0]:g} to the circulation's end {t[i3]:g}): two runs in "
                "one log? split it there, or give its phase column or meta file"
            )


def _from_signals(log: LabLog) -> Phases:
    t = log.t
    path = log.path
    fg = fill_gaps(log["flue_gas_temp_C"], t)
    i0 = _first_firing(log)
    if i0 is None:
        raise LogError(f"{path}: cannot find t0: the burner never fires")
    t0 = float(t[max(i0 - 1, 0)])
    rate = rise_rate_K_min(t, fg)
    ok = np.flatnonzero((t >= t0 + 300.0) & (rate < 0.5))
    if not len(ok):
        raise LogError(f"{path}: cannot find t1: the flue-gas temperature never settles")
    t1 = float(t[ok[0]])
    if i0 == 0:  # the record begins with the burner firing: its start-up or its test?
        settled = ok[0] == np.searchsorted(t, t0 + 300.0)  # at its first full window
        if settled:  # (a preheat of its first row and a start-up of 5 min at full load
            t0 = t1 = t0 - float(np.median(np.diff(t)))  # were made up: a re-probe)
        log.notes.append(
            f"{_log_name(log)} begins with the burner firing (time_s {t[0]:g}) and "
            + (
                "its flue gas settled: no preheat or start-up is in it, and its test is read "
                "from its first row"
                if settled
                else "its flue gas rising: its start-up is read from its first row"
            )
        )
    flow = fill_gaps(log[flow_column(log)], t)
    running = _circulating_rows(log)
    if not len(running):
        raise LogError(f"{path}: cannot find t3: the water never circulates")
    i3 = int(running[-1])
    _refuse_a_stop_inside(log, running, i0, i3)
    cut_short = i3 >= len(t) - 2
    if cut_short:  # the record ends before the circulation stops: no second cooling
        i3 = len(t) - 1
        log.notes.append(
            "the record ends before the circulation stops (acquisition cut short?): no"
            " second cooling, and its last constant-flow stretch is read as the first"
        )
    t3 = float(t[i3])
    # the first cooling: constant flow back from t3 (skip the lag of its last 30 s), in
    # time, not rows (120 rows of a 60-s log reach two hours back, into the test: t2 came
    # 44 min late; a re-probe)
    before_end = t < t3 - 30.0
    near = before_end & (t >= t3 - 120.0)
    if not near.any():  # rows sparser than the window: the last one before the lag
        near = before_end & (t >= t[before_end][-1]) if before_end.any() else t <= t3
    level = np.median(flow[near])
    off = np.flatnonzero(before_end & (np.abs(flow - level) > 0.05 * level) & (t > t1))
    if not len(off):
        raise LogError(
            f"{path}: cannot find t2: no change of flow before the first cooling"
            + (
                f" (the record ends at time_s {t[-1]:g} with the water circulating: cut "
                "short in its test? "
                # (a log whose phase column ends in its test was sent for the column it has:
                # a stranger's probe)
                + (
                    "its phase column ends before the first cooling too: give the whole run)"
                    if log.has("phase")
                    else "give the whole run, or its phase column or meta file)"
                )
                if cut_short
                else ""
            )
        )
    t2 = float(t[off[-1]])
    return Phases(t0, t1, t2, t3, float(t[-1]), "signals")


def _marks_in_meta(log: LabLog) -> bool:
    """Whether the meta file records marks (then they, not the column, say where a run
    cut short stopped)."""
    return any(log.meta.get(key) is not None for key in MARKS)


def _signals_found(log: LabLog, column_passed_over: bool) -> Phases:
    """:func:`_from_signals`; where the phase column was passed over because it begins
    mid-run (:func:`_column_begins_late`; ``column_passed_over``: it was looked at), the
    source says so rather than "signals" alone."""
    found = _from_signals(log)
    first = _column_begins_late(log) if column_passed_over else None
    if first is None:
        return found
    marks = " or ".join(f"t{i}" for i in range(NAMES.index(first)))  # those before it
    source = f"signals; the phase column begins mid-run, in its {first} phase: no {marks} in it"
    return replace(found, source=source)


def find_phases(log: LabLog, prefer_signals: bool = False, partial: bool = False) -> Phases:
    """Phase boundaries from the phase column, the meta file, or the signals (see above).
    With ``partial``, a run cut short (its meta file's marks up to those it reached) gives
    the phases it recorded, the one it was cut in ending at its last row (see
    :attr:`Phases.reached`), where the signals do not find all five."""
    if not prefer_signals:
        found = _from_column(log, partial and not _marks_in_meta(log))
        if found is not None:
            if partial and "t4_s" in log.meta and log.meta["t4_s"] is None:  # cut in cooling_2
                return replace(found, source="phase column, the run cut short", reached=4)
            return found
        found = _from_meta(log)
        if found is not None:
            _check_against_signals(log, found)
            return found
    reached = [key for key in MARKS if log.meta.get(key) is not None]
    if reached == list(MARKS) or not any(key in log.meta for key in MARKS):
        return _signals_found(log, not prefer_signals)
    first_null = next(key for key in MARKS if log.meta.get(key) is None)
    after = [key for key in MARKS[MARKS.index(first_null) + 1 :] if key in reached]
    if after:  # no run writes that: it stops marking at the first mark it does not reach
        meta_file = _meta_file(log)
        log.notes.append(
            f"{meta_file}: {', '.join(after)} given after {first_null} = null, which no "
            "interrupted run writes (edited?): its marks are not used; phases from the signals"
        )
    cut = _meta_marks(log, partial=True) if partial else None
    if cut is not None:  # the marks the bench recorded, not the signals' guess at the rest
        return cut  # (a run cut in a cooling got marks of its last row: a re-probe)
    try:  # a run cut short: its meta file has the marks it reached, null for the rest
        return _signals_found(log, not prefer_signals)
    except LogError as exc:
        if log.meta.get(EPOCH_KEPT) is not None:  # (its marks are set aside, not missing)
            raise LogError(
                f"{exc}; the rows of the log's longest plant (rig_epoch "
                f"{log.meta[EPOCH_KEPT]:g}) hold no whole test to analyse by phase"
            ) from None
        known = ", ".join(reached) or "no mark"
        raise LogError(
            f"{exc}; the run was cut short (its meta file records {known}, the rest not "
            "reached), so the log holds no whole test to analyse by phase"
        ) from None
