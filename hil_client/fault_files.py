"""The client's side of fault injection on disk: its Modbus events and the fault report.

``NAME.modbus_events.jsonl`` beside ``NAME.csv`` holds one JSON line per event the Modbus
rig saw (:attr:`hil_client.rigs.modbus.ModbusRig.comm_events`); ``hil-client run
--fault-report`` or ``hil-client fault-report`` compare them (and the log) with the
server's fault journal (:mod:`hil_client.analysis.fault_report`).

A journal is one server start's: its lines carry the server's ``epoch_id``, the run's meta
the first server's (``server_epoch_id``) and each gap the server's after it. A journal is
compared with the rows (``rig_epoch``) of the plant(s) its server served and the events of
those rows only, each plant's rows in its own server time (a stranger's probe: after a
server killed and restarted under ``run --on-restart continue``, both servers' journals
were matched with the rows and events of either plant by server time alone). A journal or
a log without epoch ids is compared whole, as before.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil_client.analysis.fault_report import (
    INSTRUMENT_UNITS_ANY,
    check_journal,
    check_log_served,
    compare,
    journal_epoch,
)
from hil_client.analysis.logio import LabLog, read_log
from hil_client.jsonio import strict_json
from hil_client.protocol.rig import LOG_COLUMNS
from rig_emulator.atomic import write_atomically
from rig_emulator.registers import RegisterMap, instrument_units, load_map
from rig_emulator.signals import MEASURED
from rig_emulator.yamlio import finite_number

#: the instruments' readings a lab log holds (not the commands and setpoints it echoes)
READINGS = frozenset(LOG_COLUMNS) & frozenset(MEASURED)


def events_path(log_path: Path) -> Path:
    """``NAME.modbus_events.jsonl`` beside ``NAME.csv``."""
    log_path = Path(log_path)
    return log_path.with_name(log_path.stem + ".modbus_events.jsonl")


class EventsWriter:
    """The Modbus events beside a log, written as they come (one flushed line each, as the
    log's rows are), so a killed client leaves the events of every row it logged."""

    def __init__(self, log_path: Path) -> None:
        self.path = events_path(log_path)
        self._file = self.path.open("w", encoding="utf-8")
        self.written = 0

    def catch_up(self, events: Sequence[dict[str, Any]]) -> None:
        """Write those of ``events`` (the rig's whole list so far) not written yet."""
        for event in events[self.written :]:
            self._file.write(json.dumps(event, allow_nan=False) + "\n")
        if len(events) > self.written:
            self._file.flush()
            self.written = len(events)

    def close(self) -> None:
        self._file.close()


def read_jsonl(path: Path, what: str, notes: list[str] | None = None) -> list[dict[str, Any]]:
    """The lines of a JSONL file; a bad line raises ValueError naming file and line. A last
    line cut short (no newline after it: the writer was killed, or its disk filled up) is
    left out, said in ``notes``, as a lab log's is (it refused the whole journal: a
    stranger's probe)."""
    out = []
    if Path(path).exists() and not Path(path).is_file():  # a FIFO or a device: read forever
        raise ValueError(f"{path}: not a regular file ({what})")
    try:
        text = Path(path).read_text(encoding="utf-8-sig")  # an editor's byte-order mark
    except UnicodeDecodeError as exc:  # the error named no file (a stranger's probe)
        raise ValueError(
            f"{path}: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at {exc.start}) ({what})"
        ) from None
    lines = text.splitlines()
    for number, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            item = json.loads(line)
        except (json.JSONDecodeError, RecursionError):  # nested a thousand deep: no journal
            if number == len(lines) and not text.endswith("\n") and notes is not None:
                notes.append(f"{path}: its last line is cut short ({what}): left out")
                break
            raise ValueError(f"{path}: line {number} is not JSON ({what})") from None
        if not isinstance(item, dict):
            raise ValueError(f"{path}: line {number} is not a JSON object ({what})")
        out.append(item)
    return out


def unit_signals(register_map: RegisterMap) -> dict[int, list[str]]:
    """The lab-log signals each instrument unit of ``register_map`` serves."""
    units = instrument_units(register_map)
    return {
        d.unit_id: list(dict.fromkeys(p.signal for p in d.points if p.signal in READINGS))
        for d in register_map.devices
        if d.unit_id in units
    }


def fault_report(
    log_path: Path,
    journal_path: Path,
    slack_s: float = 2.0,
    register_map: RegisterMap | None = None,
) -> dict[str, Any]:
    """Compare the run's events and log with the server's journal (ValueError if a file
    is not what it should be). A log without a Modbus events file beside it (another
    acquisition program's) is compared alone, its units' readings found through
    ``register_map`` (the shipped map if None)."""
    notes: list[str] = []
    journal = read_jsonl(journal_path, "the server's fault journal", notes)
    check_journal(journal, str(journal_path))
    events_file = events_path(log_path)
    events = None
    if events_file.exists():
        events = read_jsonl(events_file, "Modbus events", notes)
        _check_events(events, events_file)
    else:  # (it was refused: a lab's own acquisition program writes no such file)
        notes.append(
            f"{log_path}: no Modbus events file beside it ({events_file.name}): the log alone "
            "is compared: a unit's silence or exception shows as its readings left empty, a "
            "delay or a disconnect leaves no mark in them (unjudged), and false alarms are "
            "not counted"
        )
    # time_s and the faulted readings are all a comparison needs (the analyses' columns
    # were required: a lab's program logging the analyser alone was refused, a probe)
    log = read_log(Path(log_path), ("time_s",), as_read=True)
    if events is None:
        _check_log_holds_a_faulted_reading(log, journal, register_map or load_map())
    check_log_served(log.meta, str(log_path), str(journal_path), journal_epoch(journal))
    offset = log.meta.get("server_time_offset_s", 0.0)
    offset = finite_number(offset) or 0.0
    server_time = log.t - offset
    columns = log.columns
    plant = _journal_plant(log, journal_epoch(journal), Path(journal_path), offset)
    if plant is not None:  # (the rows and events of the journal's server only)
        rows, server_time, note = plant
        columns = {name: column[rows] for name, column in log.columns.items()}
        if events is not None:
            kept = _events_of(events, log, rows)
            left = len(events) - len(kept)
            events = kept
            note += f", {left} of the client's events of other plants" if left else ""
        if not rows.all():
            notes.append(note)
    report = compare(
        journal,
        events,
        columns,
        server_time,
        slack_s,
        str(journal_path),
        unit_signals(register_map or load_map()) if events is None else None,
    )
    report["log"] = str(log_path)
    report["journal"] = str(journal_path)
    report["notes"] = notes
    return report


def _check_log_holds_a_faulted_reading(
    log: LabLog, journal: Sequence[dict[str, Any]], register_map: RegisterMap
) -> None:
    """Refuse a log compared alone (no events file) that has no column of any reading the
    journal's faults concern: nothing in it could show one (a re-probe: a log of time_s
    alone gave "3 unjudged", exit 0)."""
    by_unit = unit_signals(register_map)
    concerned: dict[str, None] = {}
    for event in journal:
        if event.get("event") != "start":
            continue
        if isinstance(event.get("signal"), str):
            concerned[event["signal"]] = None
        elif event.get("unit") == INSTRUMENT_UNITS_ANY:
            concerned.update(dict.fromkeys(s for signals in by_unit.values() for s in signals))
        else:
            concerned.update(dict.fromkeys(by_unit.get(event.get("unit"), [])))
    if concerned and not any(name in log.columns for name in concerned):
        shown = ", ".join(list(concerned)[:6]) + (", ..." if len(concerned) > 6 else "")
        raise ValueError(
            f"{log.path}: no column of a reading the journal's faults concern ({shown}): "
            "nothing in it can show them (a fault report needs time_s and those readings)"
        )


def _rig_epochs(log: LabLog) -> np.ndarray:
    """The ``rig_epoch`` of each row (0: a log without the column, one plant)."""
    epochs = log.columns.get("rig_epoch")
    return np.zeros(len(log)) if epochs is None else np.asarray(epochs, dtype=float)


def _journal_plant(
    log: LabLog, epoch: str | None, journal_path: Path, offset: float
) -> tuple[np.ndarray, np.ndarray, str] | None:
    """The rows of ``log`` the journal's server (``epoch``) served (a boolean mask), their
    server times and a note saying which they are; None where the journal or the log's
    meta carries no epoch id (all the rows compared, as before). ValueError (a journal of
    another server's start) where that server served none of the rows.

    The plants: ``server_epoch_id`` of the meta served ``rig_epoch`` 0; a gap's
    ``server_epoch_id`` the ``rig_epoch`` it gives (a replay rebuilds the same plant on a
    new server: both journals compare with its rows; an aborting gap's server served
    none). Each plant's rows have their own offset: the gap that ends it says its last
    row's log and server time; the last plant's is the meta's ``server_time_offset_s``."""
    first = log.meta.get("server_epoch_id")
    if epoch is None or not isinstance(first, str):
        return None
    listed = log.meta.get("gaps")  # (a meta whose gaps were 5 was a traceback: a re-probe)
    gaps = [g for g in listed if isinstance(g, dict)] if isinstance(listed, list) else []
    served: dict[int, set[str]] = {0: {first.lower()}}  # rig_epoch -> its servers' epoch ids
    offsets: dict[int, float] = {}  # rig_epoch -> log time minus server time
    for gap in gaps:
        plant, server = gap.get("rig_epoch"), gap.get("server_epoch_id")
        if gap.get("action") == "abort" or isinstance(plant, bool) or not isinstance(plant, int):
            continue
        if isinstance(server, str):
            served.setdefault(plant, set()).add(server.lower())
        log_time = finite_number(gap.get("start_time_s"))
        server_time = finite_number(gap.get("server_time_before_s"))
        if plant >= 1 and log_time is not None and server_time is not None:
            offsets.setdefault(plant - 1, log_time - server_time)
    plants = sorted(k for k, ids in served.items() if epoch in ids)
    shown = "; ".join(f"rig_epoch {k}: {', '.join(sorted(served[k]))}" for k in sorted(served))
    rig_epoch = _rig_epochs(log)
    rows = np.isin(rig_epoch, plants)
    if not rows.any():
        raise ValueError(
            f"{journal_path}: its server (epoch_id {epoch}) served none of the rows of "
            f"{log.path} ({shown}): the journal of another server's start"
        )
    server_time = np.full(len(log), math.nan)
    for k in plants:
        here = rig_epoch == k
        server_time[here] = log.t[here] - offsets.get(k, offset)
    t = log.t[rows]
    which = ", ".join(f"{k:g}" for k in plants)
    span = f"time_s {t[0]:g}..{t[-1]:g}"
    note = (
        f"{journal_path}: its server (epoch_id {epoch}) served rig_epoch {which} of "
        f"{log.path}: only those rows ({span}) and their client events are compared; "
        f"left out: {int((~rows).sum())} row(s) of other plants ({shown})"
    )
    return rows, server_time[rows], note


def _events_of(
    events: Sequence[dict[str, Any]], log: LabLog, rows: np.ndarray
) -> list[dict[str, Any]]:
    """The client's events of ``rows``: an event's ``time_s`` is its row's (the row at or
    before it; the first row before the log's first)."""
    if not events:
        return []
    times = np.array([float(e["time_s"]) for e in events])
    index = np.clip(np.searchsorted(log.t, times, side="right") - 1, 0, len(log) - 1)
    return [e for e, keep in zip(events, rows[index], strict=True) if keep]


def _check_events(events: Sequence[dict[str, Any]], path: Path) -> None:
    """Refuse an events line that is not what ``run`` writes: ValueError naming the file,
    the line and the field (a NaN or text time was counted as a false alarm)."""
    for number, event in enumerate(events, 1):
        if not isinstance(event.get("event"), str):
            raise ValueError(f"{path}: line {number}: field 'event' is missing or not text")
        for key in ("time_s", "server_time_s"):
            value = event.get(key)
            if finite_number(value) is None:
                shown = f"{value!r}" if len(repr(value)) <= 40 else f"{repr(value)[:20]}..."
                raise ValueError(
                    f"{path}: line {number}: field '{key}' = {shown} is not a finite number"
                )


def write_report(report: dict[str, Any], out: Path) -> None:
    write_atomically(out, strict_json(report, indent=2) + "\n")


def summary(report: dict[str, Any]) -> str:
    kinds = ", ".join(
        f"{kind} {c['detected']}/{c['detected'] + c['missed']}"
        for kind, c in sorted(report["by_kind"].items())
    )
    unseen = len(report.get("unseen", ()))
    never = f", {unseen} never served (between two of the server's steps)" if unseen else ""
    outside = len(report.get("outside_run", ()))
    if outside:
        never += f", {outside} outside the run (before its first row or after its last)"
    still = len(report.get("no_trace", ()))
    if still:
        never += f", {still} stuck on a reading that was not moving anyway (no trace to find)"
    beyond = report.get("events_outside_run", 0)
    if beyond:
        never += (
            f"; {beyond} of the client's events lie beyond the log's rows and are not counted"
            " (the events file of a longer run, or a log cut or shifted?)"
        )
    unjudged = len(report.get("unjudged", ()))
    if unjudged:
        never += f", {unjudged} unjudged (no mark in the readings, and no Modbus events)"
    journalled = len(report["faults"]) + outside + len(report.get("unseen", ())) + still
    journalled += unjudged
    # (faults in the run the log could not judge were "none in the run": a re-probe)
    none = "none judged" if unjudged else "none in the run" if journalled else "none journalled"
    false = "false not counted" if report["false"] is None else f"{report['false']} false"
    return (
        f"faults: {report['detected']} detected, {report['missed']} missed, "
        f"{false}{never} ({kinds or none})"
    )
