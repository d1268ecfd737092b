"""What the client saw against what the server did: the fault report (CONTRACT section 5).

Inputs: the server's fault journal (``--fault-log``: one line per fault start and end, in
the server's simulated time), the client's Modbus events (``LOG.modbus_events.jsonl``,
written by ``hil-client run``: timeouts, dropped replies, exceptions with their code, late
replies, invalid readings, lost connections, each with the server time of its row) and the
lab log itself.

Each journalled fault is **detected** when the client saw its mark on its target within
the fault's window [start, end + ``slack_s``] (server time):

- ``no_reply``: a ``no_reply`` or ``timeout`` on the unit (0: on any instrument unit);
- ``delay``: a ``late`` reply or a ``timeout`` on the unit;
- ``exception``: an ``exception`` on the unit (``code_match`` says whether the code was
  the journalled one);
- ``disconnect``: a lost connection;
- ``dropout``: an ``invalid`` reading of the signal (or its unit failing);
- ``spike``, ``offset``, ``stuck``: found in the log column by the detectors below;
- ``drift``: never from the readings alone (no reference): counted as missed unless the
  reading leaves its instrument's plausible range (not checked here).

Log detectors (robust scale ``s``: 1.4826 x the median absolute first difference of the
column; its resolution ``q``: the coarsest 10^-d, d = 0..9, that every reading is a whole
multiple of, as the log writes them or the register's step rounds them, 0 if none): a
spike is a row more than ``8 s``, ``2 q`` and 1 % of the level away from both neighbours,
which agree with each other; an offset a step of that size between consecutive rows whose
new level holds for the next 5 rows; stuck at least 10 consecutive equal values in a
column that otherwise changes on most rows. ``2 q``: rounding alone moves a steady reading
by one step of its resolution, never by two. (The floor was the column's smallest nonzero
step: on a still column, a clean run's O2 at 6.25515 for hours, that is the fault's own
step, and the spike or offset was missed: a stranger's probe; ``s`` is 0 there.)

Everything the client saw that no journalled fault explains is **false** (client events
only: the detectors run inside fault windows).

A fault on a signal the log has no column for (one its client did not read, or a name no
server serves: a journal edited by hand) is listed under ``unjudged``: the log cannot say.

Without client events (``client_events`` None: the log of another acquisition program,
with no ``LOG.modbus_events.jsonl``) the log alone is compared: a ``no_reply`` or
``exception`` is detected where the unit's readings (``unit_signals``, from the register
map) are empty in a row of its window, a ``dropout`` where its signal's is; a ``delay``
or ``disconnect`` leaves no mark in the readings and is listed under ``unjudged``, and
false alarms are not counted (``false`` None).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hil_client.analysis.logio import plausible_range
from rig_emulator.faults import COMM_KINDS, KINDS
from rig_emulator.yamlio import finite_number

INSTRUMENT_UNITS_ANY = 0
_COMM_MARKS = {
    "no_reply": ("no_reply", "timeout"),
    "delay": ("late", "timeout"),
    "exception": ("exception",),
    "disconnect": ("disconnect",),
}


#: the client's events a fault may cause (what is left unexplained is a false alarm)
_FAULT_MARKS = frozenset({"timeout", "no_reply", "exception", "late", "invalid", "disconnect"})


def _journal_error(source: str, line: int, key: str, value: Any, what: str) -> ValueError:
    shown = f"{value!r}" if len(repr(value)) <= 40 else f"{repr(value)[:20]}..."
    return ValueError(f"{source}: line {line}: field '{key}' = {shown}: {what}")


def check_journal(journal: Sequence[Mapping[str, Any]], source: str = "fault journal") -> None:
    """Refuse a journal line that is not what the server writes (CONTRACT section 5):
    ValueError naming ``source``, the line (the n-th record, blank lines not counted) and
    the field. Each line: ``event`` start or end, ``id`` an integer, ``t_sim_s`` a finite
    number, ``kind`` one of the fault kinds, ``unit`` (communication faults) a unit number,
    ``signal`` (instrument faults) a name, ``code`` (exception) an integer; each id started
    once (the server numbers its faults afresh in each journal) and ended at most once,
    not before its start, with the kind and the unit or signal of its start; ``epoch_id``
    (the server's start, 8 hex digits) on every line or on none, the same on all: one
    journal is one server's."""
    starts: dict[int, tuple[float, str, int, Any]] = {}  # id -> (time, kind, line, target)
    ended: dict[int, int] = {}  # id -> line
    epoch: tuple[Any, int] | None = None  # (epoch_id, line) of the first line
    for line, event in enumerate(journal, 1):

        def bad(key: str, what: str, line: int = line, event: Mapping = event) -> ValueError:
            return _journal_error(source, line, key, event.get(key), what)

        for key in ("event", "id", "t_sim_s", "kind"):
            if key not in event:
                raise ValueError(f"{source}: line {line}: no field '{key}'")
        if epoch is None:
            epoch = (event.get("epoch_id"), line)
            if epoch[0] is not None and not _is_epoch_id(epoch[0]):
                raise bad("epoch_id", "not a server's epoch id (8 hex digits)")
        elif event.get("epoch_id") != epoch[0]:
            first = "none" if epoch[0] is None else f"{epoch[0]}"
            raise bad("epoch_id", f"line {epoch[1]} has {first}: one journal is one server's")
        if event["event"] not in ("start", "end"):
            raise bad("event", "not 'start' or 'end'")
        fid, t = event["id"], event["t_sim_s"]
        if isinstance(fid, bool) or not isinstance(fid, int):
            raise bad("id", "not an integer")
        if finite_number(t) is None:  # (an int of 401 digits overflowed: a probe)
            raise bad("t_sim_s", "not a finite number of seconds")
        kind = event["kind"]
        if kind not in KINDS:
            raise bad("kind", f"not a fault kind ({', '.join(KINDS)})")
        if kind in COMM_KINDS:
            unit = event.get("unit")
            if isinstance(unit, bool) or not isinstance(unit, int) or not 0 <= unit <= 255:
                raise bad("unit", "not a unit number 0..255")
            code = event.get("code")  # the server may write it as a float: 11.0
            if code is not None and not (finite_number(code) is not None and code == int(code)):
                raise bad("code", "not an exception code (a whole number)")
        elif not isinstance(event.get("signal"), str):
            raise bad("signal", "not the name of a lab-log column")
        target = event.get("unit") if kind in COMM_KINDS else event.get("signal")
        if event["event"] == "start":
            if fid in starts:
                raise bad("id", f"fault {fid} started already (line {starts[fid][2]})")
            starts[fid] = (float(t), kind, line, target)
        elif fid not in starts:
            raise bad("id", f"the end of fault {fid}, which has not started")
        elif fid in ended:
            raise bad("id", f"fault {fid} ended already (line {ended[fid]})")
        else:
            ended[fid] = line
            if t < starts[fid][0]:
                raise bad("t_sim_s", f"the end is before the start ({starts[fid][0]:g} s)")
            if kind != starts[fid][1]:
                raise bad("kind", f"fault {fid} started as '{starts[fid][1]}'")
            if target != starts[fid][3]:
                key = "unit" if kind in COMM_KINDS else "signal"
                raise bad(key, f"fault {fid} started on {key} {starts[fid][3]!r}")


def _is_epoch_id(value: Any) -> bool:
    return (
        isinstance(value, str)
        and len(value) == 8
        and all(c in "0123456789abcdef" for c in value.lower())
    )


def journal_epoch(journal: Sequence[Mapping[str, Any]]) -> str | None:
    """The ``epoch_id`` of the server that wrote a journal (:func:`check_journal` checked
    it is one), lower case; None if its lines carry none (an older server's)."""
    epoch = journal[0].get("epoch_id") if journal else None
    return epoch.lower() if isinstance(epoch, str) else None


#: The ``rig`` a lab log's meta file names for a run without a server (``run --rig local``).
LOCAL_RIG = "local"


def check_log_served(
    meta: Mapping[str, Any], log_name: str, journal_name: str, epoch: str | None = None
) -> None:
    """Refuse a log whose own meta file says no server ran it (``"rig": "local"``: the plant
    stepped in-process, where no journalled fault acts): ValueError naming the journal, its
    server (``epoch``, :func:`journal_epoch`) and the log. Judged, its faults were all
    "missed", exit 0 (a stranger's probe), where a Modbus log beside another server's
    journal is refused. A log without a meta file or without ``rig`` in it (another
    acquisition program's) is judged as before: nothing says it had no server. Nor is a
    Modbus rig's address compared: the journal names no address, and one address serves
    many server starts; the server's start (``epoch_id``) is what tells a journal of
    another server (compared with the meta's ``server_epoch_id`` by the caller)."""
    if meta.get("rig") != LOCAL_RIG:
        return
    server = f"its server (epoch_id {epoch})" if epoch is not None else "its server"
    raise ValueError(
        f"{journal_name}: {server} served none of the rows of {log_name}: its meta file says "
        f"rig {LOCAL_RIG} (the plant stepped in-process, no server and no fault in it): the "
        "journal of another run"
    )


def fault_windows(
    journal: Sequence[Mapping[str, Any]], source: str = "fault journal"
) -> list[dict[str, Any]]:
    """One record per journalled fault: kind, target, start and end (server time); a bad
    journal line raises ValueError (:func:`check_journal`)."""
    check_journal(journal, source)
    faults: dict[int, dict[str, Any]] = {}
    for event in journal:
        fid = int(event["id"])
        if event["event"] == "start":
            faults[fid] = {
                "id": fid,
                "kind": event["kind"],
                "unit": event.get("unit"),
                "signal": event.get("signal"),
                "code": event.get("code"),
                "start_s": float(event["t_sim_s"]),
                "end_s": None,
                "source": event.get("source"),
                # the server never served it: its whole window fell inside one step
                "seen": not (
                    isinstance(event.get("served"), Mapping)
                    and event["served"].get("seen") is False
                ),
            }
        elif fid in faults:
            faults[fid]["end_s"] = float(event["t_sim_s"])
    return list(faults.values())


def _robust_scale(x: np.ndarray) -> float:
    """1.4826 x the median absolute first difference (0 on a column still on most rows)."""
    d = np.abs(np.diff(x[np.isfinite(x)]))
    if d.size == 0:
        return math.inf
    return 1.4826 * float(np.median(d))


def _quiet_max(kind: str, x: np.ndarray, quiet: np.ndarray | None) -> float:
    """The largest the detector's own measure of ``kind`` gets on the column ``x`` by
    itself, over its rows outside every fault window (``quiet``; None: every row): a
    spike's jump away from both neighbours, an offset's step between the medians of 5
    rows before and after. A fault must stand beyond it. A column that moves in steps
    (a humidity meter's 0.1 % steps every ten rows, its median first difference 0) had
    its ordinary 0.3-0.6 % steps counted as offsets where the journal named one (31 of
    31 windows where nothing was served: a re-probe)."""
    ok = np.isfinite(x) if quiet is None else np.isfinite(x) & quiet
    if kind == "spike" and x.size >= 3:
        a, b, c = x[:-2], x[1:-1], x[2:]
        keep = ok[:-2] & ok[1:-1] & ok[2:]
        measure = np.minimum(np.abs(b - a), np.abs(b - c))[keep]
    elif kind == "offset" and x.size >= 10:
        med = np.median(np.lib.stride_tricks.sliding_window_view(x, 5), axis=1)
        whole = np.lib.stride_tricks.sliding_window_view(ok, 5).all(axis=1)
        keep = whole[:-5] & whole[5:]  # the 5 rows before and the 5 from the row on
        measure = np.abs(med[5:] - med[:-5])[keep]
    else:
        return 0.0
    return float(measure.max()) if measure.size else 0.0


#: The most decimals a column's resolution is looked for in (``run``'s log writes 5 at most).
RESOLUTION_DECIMALS = 9


def _resolution(x: np.ndarray) -> float:
    """The coarsest 10^-d (d = 0..:data:`RESOLUTION_DECIMALS`) that every finite reading of
    ``x`` is a whole multiple of: the decimals the log writes (20.95000: 0.01, the step of
    the register), 0 if none (readings with all their digits). A reading parsed from text
    is off its decimal by the float's rounding only: 1e-6 of a step, plus 4 ulp of it."""
    v = np.unique(x[np.isfinite(x)])
    if v.size == 0:
        return 0.0
    for d in range(RESOLUTION_DECIMALS + 1):
        y = v * 10.0**d
        if np.all(np.abs(y - np.round(y)) <= 1e-6 + 4 * np.finfo(float).eps * np.abs(y)):
            return 10.0**-d
    return 0.0


def _log_detects(
    kind: str, x: np.ndarray, rows: np.ndarray, quiet: np.ndarray | None = None
) -> bool:
    """Whether ``kind`` shows in the log column ``x`` at one of the row indices ``rows``
    (``quiet``: its rows outside every fault window, for the noise scale)."""
    if rows.size == 0:
        return False
    # the least jump: 8 s, 2 q (rounding moves a still reading by one q: module docstring),
    # and beyond what the column does by itself outside the faults
    least = (
        max(8 * _robust_scale(x), 2 * _resolution(x), _quiet_max(kind, x, quiet), 1e-9)
        if kind != "stuck"
        else 0.0
    )
    n = x.size
    read = np.flatnonzero(np.isfinite(x))
    # whether the column moves outside the window (a stuck reading to the log's end, half
    # its rows, counted itself as not moving and was missed: a re-probe)
    elsewhere = np.delete(x, rows)
    elsewhere = elsewhere[np.isfinite(elsewhere)]
    moves = elsewhere.size > 1 and np.mean(np.diff(elsewhere) != 0) > 0.5
    for i in rows:
        # a spike's neighbours: the readings next to it, across rows without one (a spike
        # among a dropout's empty rows was missed: a stranger's probe)
        k = int(np.searchsorted(read, i))
        if kind == "spike" and 0 < k < read.size - 1 and read[k] == i:
            a, b, c = x[read[k - 1]], x[i], x[read[k + 1]]
            level = max(abs(a), abs(c), 1.0)
            jump = max(least, 0.01 * level)
            if abs(b - a) > jump and abs(b - c) > jump and abs(a - c) < jump:
                return True
        elif kind == "offset" and i > 0 and i + 5 < n:
            before, after = x[max(0, i - 5) : i], x[i : i + 5]
            step = float(np.median(after) - np.median(before))
            level = max(abs(float(np.median(before))), 1.0)
            if abs(step) > max(least, 0.01 * level):
                return True
        elif kind == "stuck" and i + 10 <= n and np.all(x[i : i + 10] == x[i]) and moves:
            return True
    return False


#: Rows before a stuck fault's window that show whether its column was moving [rows].
STILL_BEFORE_ROWS = 10


def _already_still(x: np.ndarray, rows: np.ndarray) -> bool:
    """Whether a stuck fault on column ``x`` over ``rows`` held a reading that was not
    moving anyway: the column equal to its first value in the window over the
    :data:`STILL_BEFORE_ROWS` before and all of the window (a clean profile's forward
    temperature at its set point, 70.00000 for hours: a stranger's probe found such a
    fault counted as detected, and the same fault, made up, on another still column as
    missed). Neither detected nor missed: nothing in the log could tell."""
    if rows.size == 0 or rows[0] < STILL_BEFORE_ROWS:
        return False
    before = x[rows[0] - STILL_BEFORE_ROWS : rows[0]]
    within = x[rows]
    # rows without a reading (a dropout within or before the window) show nothing either
    # way: the same stuck fault was no trace without one and missed with one (a stranger's
    # probe); but some reading before the window must show the column still, or empty rows
    # before a held reading passed as "not moving" (a re-probe: a sensor that dropped out,
    # froze, and dropped out again was caught before)
    before, within = before[np.isfinite(before)], within[np.isfinite(within)]
    if before.size == 0 or within.size == 0:
        return False
    return bool(np.all(before == within[0]) and np.all(within == within[0]))


def _missing(name: str, values: np.ndarray) -> np.ndarray:
    """Which ``values`` of column ``name`` are no reading: empty, or beyond what its
    instrument can read (an error code such as -999: a program that logs its silences so
    had them counted as readings, a re-probe)."""
    low, high = plausible_range(name)
    with np.errstate(invalid="ignore"):
        return ~np.isfinite(values) | (values < low) | (values > high)


def _first_empty(
    columns: Mapping[str, np.ndarray], signals: Sequence[str], rows: np.ndarray
) -> tuple[int | None, bool]:
    """The first of ``rows`` where a reading of ``signals`` is missing in the log (None if
    none is), and whether any of them was read outside ``rows`` at all: a column that is
    empty throughout shows no fault (it was taken for one: a re-probe)."""
    empty = np.zeros(rows.size, dtype=bool)
    judged = False
    for signal in signals:
        if signal not in columns:
            continue
        x = np.asarray(columns[signal], dtype=float)
        missing = _missing(signal, x)
        outside = np.ones(x.size, dtype=bool)
        outside[rows] = False
        if not (~missing & outside).any():
            continue  # never read outside the window: it tells nothing
        judged = True
        empty |= missing[rows]
    first = int(rows[int(np.argmax(empty))]) if empty.any() else None
    return first, judged


def compare(
    journal: Sequence[Mapping[str, Any]],
    client_events: Sequence[Mapping[str, Any]] | None,
    log_columns: Mapping[str, np.ndarray] | None = None,
    server_time: np.ndarray | None = None,
    slack_s: float = 2.0,
    journal_name: str = "fault journal",
    unit_signals: Mapping[int, Sequence[str]] | None = None,
) -> dict[str, Any]:
    """The report: every fault detected or missed, and the client's false alarms
    (``journal_name``: the journal's file, for its errors). Neither detected nor missed:
    a fault the server journalled as never served (its window fell wholly between two of
    its evaluations, inside one lockstep step or one real-time tick), listed under
    ``unseen``; and one whose window lies wholly before the log's first row or after its
    last (``server_time``: a client that joined late or stopped early could not see it),
    listed under ``outside_run``; and a ``stuck`` fault on a column that was not moving
    before it or in it (:func:`_already_still`), under ``no_trace``. Client events beyond
    the log's rows (an events file of a longer run beside a log cut short) are no false
    alarms: counted under ``events_outside_run``, as the summary says. Without client
    events (None) the log alone is compared (see the module docstring)."""
    log_only = client_events is None
    client_events = [] if client_events is None else client_events
    windows = fault_windows(journal, journal_name)
    served = [f for f in windows if f["seen"]]  # an unserved fault: neither caught nor missed
    end_of_run = max(
        [float(e.get("server_time_s", 0.0)) for e in client_events]
        + ([float(server_time[-1])] if server_time is not None and server_time.size else [])
        + [0.0]
    )
    outside: list[dict[str, Any]] = []
    faults = served
    events_outside = 0  # client events beyond the log's rows: not this log's to count
    if server_time is not None and server_time.size:
        first, last = float(server_time[0]), float(server_time[-1])
        spanned = [
            first - slack_s <= float(e.get("server_time_s", math.nan)) <= last + slack_s
            for e in client_events
        ]
        events_outside = spanned.count(False)
        client_events = [e for e, ok in zip(client_events, spanned, strict=True) if ok]

        def in_run(fault: Mapping[str, Any]) -> bool:
            # a window ends before its end (the row read at end_s has the value after it):
            # a spike at 0 for 1 s before a first row at 1.0 no row could show, and it was
            # counted missed (a stranger's probe)
            ended = fault["end_s"] is not None and fault["end_s"] <= first + 1e-9
            return not ended and fault["start_s"] <= last + slack_s

        faults = [f for f in served if in_run(f)]
        outside = [f for f in served if not in_run(f)]
    explained: set[int] = set()
    rows_out = []
    no_trace: list[dict[str, Any]] = []
    unjudged: list[dict[str, Any]] = []
    #: per signal, its rows outside every fault window on it (the noise scale's rows)
    quiet: dict[str, np.ndarray] = {}
    if server_time is not None:
        for fault in served:
            if fault.get("signal") is None:
                continue
            end = (fault["end_s"] if fault["end_s"] is not None else end_of_run) + slack_s
            mask = quiet.setdefault(fault["signal"], np.ones(server_time.size, dtype=bool))
            mask &= ~((server_time >= fault["start_s"] - 1e-9) & (server_time <= end))
    for fault in faults:
        start = fault["start_s"]
        end = (fault["end_s"] if fault["end_s"] is not None else end_of_run) + slack_s
        kind = fault["kind"]
        detected, how, first = False, None, None
        code_match = None
        if log_only and kind in ("delay", "disconnect"):  # no mark in the readings
            unjudged.append(fault)
            continue
        if fault.get("signal") is not None and (
            (log_only and log_columns is None)
            or (log_columns is not None and fault["signal"] not in log_columns)
        ):  # a reading the log does not hold, or no server's (a typo in a journal): it
            # was counted missed (re-probes, the log alone and beside its events)
            unjudged.append(fault)
            continue
        if log_only and kind in ("no_reply", "exception", "dropout"):
            if log_columns is None or server_time is None:
                unjudged.append(fault)
                continue
            if kind == "dropout":
                signals: Sequence[str] = [fault["signal"]]
            elif fault["unit"] == INSTRUMENT_UNITS_ANY:
                signals = [s for unit in (unit_signals or {}).values() for s in unit]
            else:
                signals = (unit_signals or {}).get(fault["unit"], [])
            rows = np.flatnonzero((server_time >= start - 1e-9) & (server_time <= end))
            empty, judged = _first_empty(log_columns, signals, rows)
            if not judged:  # none of its readings logged, or never read
                unjudged.append(fault)
                continue
            if empty is not None:
                detected, how, first = True, "log: empty readings", float(server_time[empty])
            row = {**fault, "detected": detected, "how": how, "first_seen_s": first}
            if kind == "exception":
                row["code_match"] = None  # an empty field does not say which code
            rows_out.append(row)
            continue
        for index, event in enumerate(client_events):
            t = float(event.get("server_time_s", math.nan))
            if not start - 1e-9 <= t <= end:
                continue
            if kind in _COMM_MARKS:
                unit_ok = kind == "disconnect" or fault["unit"] in (
                    INSTRUMENT_UNITS_ANY,
                    event.get("unit"),
                )
                if unit_ok and event["event"] in _COMM_MARKS[kind]:
                    explained.add(index)
                    if kind == "exception":
                        code_match = code_match or event.get("code") == fault["code"]
                    if not detected:
                        detected, how, first = True, event["event"], t
            elif kind == "dropout" and fault["signal"] in event.get("signals", ()):
                explained.add(index)
                if not detected:
                    detected, how, first = True, event["event"], t
        if (
            not detected
            and kind in ("spike", "offset", "stuck")
            and log_columns is not None
            and server_time is not None
            and fault["signal"] in log_columns
        ):
            x = np.asarray(log_columns[fault["signal"]], dtype=float)
            rows = np.flatnonzero((server_time >= start - 1e-9) & (server_time <= end))
            if kind == "stuck" and _already_still(x, rows):
                no_trace.append(fault)
                continue
            if _log_detects(kind, x, rows, quiet.get(fault["signal"])):
                detected, how, first = True, f"log: {kind}", float(server_time[rows[0]])
        row = {**fault, "detected": detected, "how": how, "first_seen_s": first}
        if kind == "exception":
            row["code_match"] = bool(code_match)
        rows_out.append(row)
    false_events = [  # an ``overridden`` switch is another client's doing, not a fault's
        e
        for i, e in enumerate(client_events)
        if i not in explained and e.get("event") in _FAULT_MARKS
    ]
    by_kind: dict[str, dict[str, int]] = {}
    for row in rows_out:
        counts = by_kind.setdefault(row["kind"], {"detected": 0, "missed": 0})
        counts["detected" if row["detected"] else "missed"] += 1
    return {
        "faults": rows_out,
        "detected": sum(r["detected"] for r in rows_out),
        "missed": sum(not r["detected"] for r in rows_out),
        "unseen": [f for f in windows if not f["seen"]],
        "outside_run": outside,
        "no_trace": no_trace,
        "unjudged": unjudged,
        "false": None if log_only else len(false_events),
        "false_events": false_events,
        "events_outside_run": events_outside,
        "by_kind": by_kind,
        "slack_s": slack_s,
    }
