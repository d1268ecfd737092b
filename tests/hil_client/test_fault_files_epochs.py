"""A fault journal is compared with the rows and events of its own server's plant: a
stranger's probe killed a real-time server with SIGKILL under ``run --on-restart continue``
and restarted it; both servers' journals were matched with the rows and events of either
plant by server time alone (the two servers' times overlap: each starts from 0).

The files here are as ``run`` and ``serve`` write them (a log whose ``rig_epoch`` changes, a
meta with the first server's ``server_epoch_id`` and a gap with the second's, journals with
``epoch_id`` on every line), made up so that the two plants' server times coincide."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil_client.analysis.logio import REQUIRED
from hil_client.cli import main as hil_client_main
from hil_client.fault_files import fault_report

A, B = "0000000a", "0000000b"  # the first server's epoch id, the restarted one's
O2 = "flue_gas_O2_pct"


def _write_run(tmp_path: Path) -> Path:
    """Plant 0: log time 0..99 s, server time 1000..1099 s, the balance 15 kg up from
    server time 1050 s (an offset fault of the first server), the analyser (unit 2)
    answering exception 06 at 1060..1062 s. Plant 1 (the restarted server, rig_epoch 1):
    log time 200..299 s, server time 1000..1099 s again, the balance still, O2 invalid at
    1080..1082 s (a dropout of the second server)."""
    rows = []
    for t in range(300):
        if 100 <= t < 200:
            continue  # the break
        plant = 0 if t < 100 else 1
        balance = 250.0 + (15.0 if plant == 0 and t >= 50 else 0.0)
        o2 = "" if plant == 1 and 280 <= t <= 282 else "6.25515"
        values = {name: "20.00000" for name in REQUIRED}
        values |= {"time_s": f"{t:.3f}", "balance_mass_kg": f"{balance:.5f}", O2: o2}
        rows.append([*values.values(), str(plant)])
    log = tmp_path / "run.csv"
    lines = [",".join([*REQUIRED, "rig_epoch"])] + [",".join(r) for r in rows]
    log.write_text("\n".join(lines) + "\n")
    gap = {
        "start_time_s": 99.0,
        "end_time_s": 200.0,
        "reason": "the server restarted (a new plant)",
        "action": "continue",
        "rig_epoch": 1,
        "server_time_before_s": 1099.0,
        "server_time_after_s": 1000.0,
        "server_epoch_id": B,
    }
    meta = {"server_epoch_id": A, "gaps": [gap], "server_time_offset_s": -800.0}
    (tmp_path / "run.meta.json").write_text(json.dumps(meta))
    events = [
        {"time_s": float(t), "server_time_s": 1000.0 + t, "event": "exception", "unit": 2}
        | {"code": 6, "signals": [O2]}
        for t in (60, 61, 62)
    ] + [
        {"time_s": float(t), "server_time_s": 800.0 + t, "event": "invalid", "unit": 2}
        | {"signals": [O2]}
        for t in (280, 281, 282)
    ]
    text = "".join(json.dumps(e) + "\n" for e in events)
    (tmp_path / "run.modbus_events.jsonl").write_text(text)
    return log


def _journal(path: Path, epoch: str | None, *faults: dict) -> Path:
    lines = []
    for i, (start, end, what) in enumerate(faults, 1):
        for event, t in (("start", start), ("end", end)):
            line = {"event": event, "id": i, "t_sim_s": t, **what}
            lines.append(line | ({"epoch_id": epoch} if epoch is not None else {}))
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


_FIRST = (
    (1050.0, 1099.0, {"kind": "offset", "signal": "balance_mass_kg"}),
    (1060.0, 1063.0, {"kind": "exception", "unit": 2, "code": 6}),
)
_SECOND = ((1080.0, 1083.0, {"kind": "dropout", "signal": O2}),)


def test_each_journal_is_compared_with_its_own_plants_rows_and_events(tmp_path):
    log = _write_run(tmp_path)
    first = fault_report(log, _journal(tmp_path / "a.jsonl", A, *_FIRST))
    found = {f["kind"]: (f["detected"], f["first_seen_s"]) for f in first["faults"]}
    # the offset in plant 0's rows at its own server time (the meta's offset is plant 1's:
    # plant 0's rows were read 200 s off, and the still balance of plant 1 compared)
    assert found == {"offset": (True, 1050.0), "exception": (True, 1060.0)}
    assert first["false"] == 0  # plant 1's invalid readings are not the first server's
    (note,) = first["notes"]
    assert "a.jsonl: its server (epoch_id 0000000a) served rig_epoch 0 " in note
    assert "(time_s 0..99)" in note and "left out: 100 row(s)" in note
    assert "3 of the client's events of other plants" in note

    second = fault_report(log, _journal(tmp_path / "b.jsonl", B, *_SECOND))
    assert [(f["kind"], f["detected"], f["first_seen_s"]) for f in second["faults"]] == [
        ("dropout", True, 1080.0)
    ]
    assert second["false"] == 0  # plant 0's exceptions are not the second server's
    assert "served rig_epoch 1 " in second["notes"][0] and "(time_s 200..299)" in second["notes"][0]
    # a journal or a log without epoch ids is compared whole, as before: every row and
    # event, plant 0's exceptions false alarms of the second server
    old = fault_report(log, _journal(tmp_path / "old.jsonl", None, *_SECOND))
    assert old["notes"] == [] and old["false"] == 3
    meta = tmp_path / "run.meta.json"
    meta.write_text(json.dumps({**json.loads(meta.read_text()), "server_epoch_id": None}))
    whole = fault_report(log, _journal(tmp_path / "b.jsonl", B, *_SECOND))
    assert whole["notes"] == [] and whole["false"] == 3


def test_a_journal_of_a_server_that_served_no_row_is_refused(tmp_path, capsys):
    log = _write_run(tmp_path)
    other = _journal(tmp_path / "c.jsonl", "0000000c", *_SECOND)
    out = tmp_path / "report.json"
    argv = ["fault-report", str(log), "--journal", str(other), "--out", str(out)]
    assert hil_client_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "c.jsonl: its server (epoch_id 0000000c) served none of the rows of" in err
    assert "rig_epoch 0: 0000000a; rig_epoch 1: 0000000b" in err
    assert not out.exists()


def test_a_journal_of_two_servers_is_refused(tmp_path):
    """One journal is one server's start: a line with another epoch id (or none) among
    lines with one is no journal ``serve`` writes."""
    log = _write_run(tmp_path)
    journal = _journal(tmp_path / "mixed.jsonl", A, *_FIRST)
    lines = journal.read_text().splitlines()
    lines[2] = lines[2].replace(A, B)
    journal.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"mixed.jsonl: line 3: field 'epoch_id' = '0000000b'"):
        fault_report(log, journal)


@pytest.mark.parametrize("gaps", [5, "none", {"rig_epoch": 1}])
def test_a_meta_whose_gaps_are_no_list_is_read_as_without_gaps(tmp_path, capsys, gaps):
    """A re-probe: a meta file with ``"gaps": 5`` (edited, or another program's) made
    fault-report a TypeError traceback. Without a list of gaps the rows are one plant's."""
    log = _write_run(tmp_path)
    meta = tmp_path / "run.meta.json"
    meta.write_text(json.dumps({**json.loads(meta.read_text()), "gaps": gaps}))
    out = tmp_path / "report.json"
    journal = _journal(tmp_path / "a.jsonl", A, *_FIRST)
    code = hil_client_main(["fault-report", str(log), "--journal", str(journal), "--out", str(out)])
    err = capsys.readouterr().err
    assert code in (0, 2) and "Traceback" not in err, err
