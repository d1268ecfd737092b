"""The fault report's matching and its log detectors, on synthetic data with known answers."""

from __future__ import annotations

import numpy as np

from hil_client.analysis.fault_report import compare, fault_windows


def _journal(*faults: dict) -> list[dict]:
    events = []
    for i, f in enumerate(faults, 1):
        start = {"event": "start", "id": i, "t_sim_s": f["start"], **f["what"]}
        events.append(start)
        if f.get("end") is not None:
            events.append({"event": "end", "id": i, "t_sim_s": f["end"], **f["what"]})
    return events


def test_windows_pair_starts_and_ends():
    journal = _journal(
        {"start": 10.0, "end": 20.0, "what": {"kind": "no_reply", "unit": 2}},
        {"start": 15.0, "what": {"kind": "dropout", "signal": "x"}},
    )
    windows = fault_windows(journal)
    assert [(w["kind"], w["start_s"], w["end_s"]) for w in windows] == [
        ("no_reply", 10.0, 20.0),
        ("dropout", 15.0, None),
    ]


def test_client_events_match_by_unit_kind_and_time():
    journal = _journal(
        {"start": 10.0, "end": 13.0, "what": {"kind": "no_reply", "unit": 2}},
        {"start": 20.0, "end": 22.0, "what": {"kind": "exception", "unit": 5, "code": 6}},
        {"start": 30.0, "end": 31.0, "what": {"kind": "delay", "unit": 4}},
    )
    events = [
        {"event": "no_reply", "unit": 2, "server_time_s": 11.0},
        {"event": "no_reply", "unit": 3, "server_time_s": 11.0},  # another unit: false
        {"event": "exception", "unit": 5, "code": 4, "server_time_s": 21.0},  # wrong code
        {"event": "timeout", "unit": 2, "server_time_s": 50.0},  # no fault then: false
    ]
    report = compare(journal, events)
    rows = {r["kind"]: r for r in report["faults"]}
    assert rows["no_reply"]["detected"] and rows["no_reply"]["first_seen_s"] == 11.0
    assert rows["exception"]["detected"] and rows["exception"]["code_match"] is False
    assert not rows["delay"]["detected"]
    assert (report["detected"], report["missed"], report["false"]) == (2, 1, 2)


def test_faults_before_the_first_row_or_after_the_last_are_outside_the_run():
    """A client that joined a running server late, or stopped early, could not see faults
    wholly outside its rows: they were counted missed (6 of 9 in a stranger's run)."""
    journal = _journal(
        {"start": 10.0, "end": 50.0, "what": {"kind": "no_reply", "unit": 2}},  # before
        {"start": 90.0, "end": 110.0, "what": {"kind": "no_reply", "unit": 3}},  # overlaps
        {"start": 150.0, "end": 160.0, "what": {"kind": "exception", "unit": 5, "code": 6}},
        {"start": 130.0, "what": {"kind": "delay", "unit": 4}},  # after, never ended
    )
    server_time = np.arange(100.0, 121.0)  # the log's rows: 100..120 s
    report = compare(journal, [], server_time=server_time)
    assert [(f["kind"], f["start_s"]) for f in report["faults"]] == [("no_reply", 90.0)]
    assert (report["detected"], report["missed"]) == (0, 1)  # the one it could have seen
    outside = sorted((f["kind"], f["start_s"]) for f in report["outside_run"])
    assert outside == [("delay", 130.0), ("exception", 150.0), ("no_reply", 10.0)]


def test_a_fault_that_ends_as_the_first_row_is_read_is_outside_the_run():
    """A stranger's probe: a spike at 0 for 1 s, the log's first row at 1.0 s reading the
    value after it (a window ends before its end), was counted missed."""
    journal = _journal(
        {"start": 0.0, "end": 1.0, "what": {"kind": "spike", "signal": "a"}},
        {"start": 0.0, "end": 2.0, "what": {"kind": "spike", "signal": "a"}},  # row 1.0 in it
    )
    t = np.arange(1.0, 60.0)
    columns = {"a": np.where(t == 1.0, 99.0, 22.0)}
    report = compare(journal, [], columns, t)
    assert [(f["start_s"], f["end_s"]) for f in report["outside_run"]] == [(0.0, 1.0)]
    assert [(r["end_s"], r["detected"]) for r in report["faults"]] == [(2.0, False)]


def test_log_detectors_find_spike_offset_and_stuck_only_where_they_are():
    rng = np.random.default_rng(0)
    t = np.arange(200.0)
    base = 60 + 0.05 * t + rng.normal(0, 0.02, t.size)
    spiked = base.copy()
    spiked[50] = 300.0
    shifted = base.copy()
    shifted[120:] += 15.0
    stuck = base.copy()
    stuck[150:170] = stuck[150]
    columns = {"a": spiked, "b": shifted, "c": stuck, "d": base}
    journal = _journal(
        {"start": 50.0, "end": 51.0, "what": {"kind": "spike", "signal": "a"}},
        {"start": 120.0, "what": {"kind": "offset", "signal": "b"}},
        {"start": 150.0, "end": 170.0, "what": {"kind": "stuck", "signal": "c"}},
        {"start": 60.0, "end": 61.0, "what": {"kind": "spike", "signal": "d"}},  # none there
        {"start": 10.0, "what": {"kind": "drift", "signal": "d"}},
    )
    report = compare(journal, [], columns, t)
    found = {(r["kind"], r["signal"]): r["detected"] for r in report["faults"]}
    assert found == {
        ("spike", "a"): True,
        ("offset", "b"): True,
        ("stuck", "c"): True,
        ("spike", "d"): False,  # the detector does not see what is not there
        ("drift", "d"): False,
    }
    assert report["false"] == 0


def test_a_spike_among_a_dropouts_empty_rows_is_told_from_the_readings_either_side():
    """A stranger's probe: a spike to 5000 ppm logged amid a dropout's empty rows was
    missed (its neighbours were no readings); they are the readings next to it now. A
    reading in the gap at the level either side is no spike."""
    t = np.arange(300.0)
    co = 40.0 + np.sin(t / 200.0)
    co[100:200] = np.nan  # the dropout
    co[150] = 5000.0  # the spike within it
    level = co.copy()
    level[150] = 40.5  # a reading at the level either side
    journal = _journal(
        {"start": 150.0, "end": 151.0, "what": {"kind": "spike", "signal": "co"}},
        {"start": 150.0, "end": 151.0, "what": {"kind": "spike", "signal": "level"}},
    )
    report = compare(journal, [], {"co": co, "level": level}, t)
    assert [(r["signal"], r["detected"]) for r in report["faults"]] == [
        ("co", True),
        ("level", False),
    ]


def test_a_stuck_fault_on_a_reading_that_was_not_moving_is_no_trace_not_detected():
    """A stranger's probe: a stuck fault on the clean profile's forward temperature, at its
    set point (70.00000 for hours), was "detected" in the log; the same fault, made up, on
    another still column was "missed". A reading held where it stood still anyway leaves
    nothing to find: neither detected nor missed, listed under no_trace. A still column
    that was moving before the window is still a fault the log shows."""
    t = np.arange(400.0)
    still = np.full(t.size, 70.0)
    held = 60 + 0.05 * t
    held[300:330] = held[300]  # moving, then held by the fault
    columns = {"still": still, "held": held}
    journal = _journal(
        {"start": 100.0, "end": 130.0, "what": {"kind": "stuck", "signal": "still"}},
        {"start": 300.0, "end": 330.0, "what": {"kind": "stuck", "signal": "held"}},
    )
    report = compare(journal, [], columns, t)
    assert [(f["signal"], f["start_s"]) for f in report["no_trace"]] == [("still", 100.0)]
    assert [(r["signal"], r["detected"]) for r in report["faults"]] == [("held", True)]
    assert report["detected"] == 1 and report["missed"] == 0
    # rows without a reading in the window (a dropout) change nothing: still no trace
    # (such a stuck O2 at air's 20.95 % was missed: a stranger's probe)
    still[110:115] = np.nan
    report = compare(journal, [], columns, t)
    assert [(f["signal"], f["start_s"]) for f in report["no_trace"]] == [("still", 100.0)]
    # but a reading held between two dropouts, nothing read just before it, is a fault the
    # log shows (a re-probe: it passed as not moving)
    held[290:300] = np.nan
    report = compare(journal, [], columns, t)
    assert [(r["signal"], r["detected"]) for r in report["faults"]] == [("held", True)]
    # held from the middle to the log's end, no end journalled: it moves elsewhere (the
    # rows it holds counted as a column not moving, and it was missed: a re-probe)
    late = 60 + 0.05 * t
    late[180:] = late[180]
    journal = _journal({"start": 180.0, "what": {"kind": "stuck", "signal": "late"}})
    report = compare(journal, [], {"late": late}, t)
    assert [(r["signal"], r["detected"]) for r in report["faults"]] == [("late", True)]
