"""``hil-client``: replay the paper's test methods on a rig and log every instrument.

Exit codes: 0 success, 2 bad usage or bad input (one line naming what is wrong), 1 any
other failure.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import filecmp
import json
import math
import os
import re
import signal
import stat
import sys
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hil_client.analysis.balance import as_json as balance_json
from hil_client.analysis.balance import energy_balance
from hil_client.analysis.balance import table as balance_table
from hil_client.analysis.balance import warnings_by_reason as balance_warnings
from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.diagnose import diagnose
from hil_client.analysis.diagnosis_files import write_diagnosis
from hil_client.analysis.figures import (
    calibration_figures,
    validation_figures,
)
from hil_client.analysis.logio import (
    LabLog,
    LogError,
    one_plant,
    read_log,
    refills,
    unread_key_note,
    unread_meta_keys,
)
from hil_client.analysis.phases import Phases, find_phases
from hil_client.analysis.report import validation_report
from hil_client.analysis.same_record import SAME_RECORD_K, same_record
from hil_client.analysis.sanity import (
    check_time_step,
    refuse_reversed_flow,
    refuse_wrong_units,
    suspicious,
    too_few_rows,
)
from hil_client.analysis.validate import compare, validation_metrics
from hil_client.fault_files import EventsWriter, events_path, fault_report, write_report
from hil_client.fault_files import summary as fault_summary
from hil_client.jsonio import strict_json
from hil_client.lablog import DECIMALS, LabLogWriter, meta_path, same_companions, write_meta
from hil_client.modbus_client import READ_FUNCTIONS, WRITE_FUNCTIONS
from hil_client.progress import LiveView, ProgressLine, hms
from hil_client.protocol.definition import ProtocolError, load_protocol
from hil_client.protocol.rig import RigError
from hil_client.protocol.runner import RunResult, check_setpoints, listed, run_protocol
from hil_client.rigs.local import LocalRig, wire_only_faults
from hil_client.rigs.modbus import WRITES, MapMismatch, ModbusRig, check_map
from hil_client.rigs.transports import RIG_TIMEOUT_S, connector, tls_files
from hil_client.run_lock import RunBusy, lock_path, run_lock
from hil_client.summary import RunSummary
from rig_emulator.atomic import write_atomically
from rig_emulator.boilers import BOILER_DIR, dump_boiler, load_boiler
from rig_emulator.boilers import resolve as resolve_boiler
from rig_emulator.certs import validity_problem
from rig_emulator.cli_support import (
    Parser,
    UsageError,
    bad_input,
    boiler_arg,
    data_file,
    finite_float,
    guarded_streams,
    input_errors,
    int_in,
    output_file,
    path_arg,
    refuse_overwriting,
    release_outputs,
    report,
    report_os_error,
    text_file,
    text_input,
)
from rig_emulator.emulator import CommandError, boiler_identity
from rig_emulator.instruments import ProfileError, load_profile
from rig_emulator.model.params import BoilerParams, ParameterError, params_from_mapping
from rig_emulator.registers import MapError, RegisterMap, load_map
from rig_emulator.registers.codec import accepted_range, decode, encode


def _build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="hil-client", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    run = sub.add_parser(
        "run",
        help="play a test method on a rig and write the lab log",
        description="Play a test method (stationary, load_cycle or a PROTOCOL.yaml) on a rig "
        "and write the lab log (CSV) and its meta file.",
    )
    run.add_argument("protocol", type=text_input, help="stationary | load_cycle | PROTOCOL.yaml")
    run.add_argument(
        "--boiler", required=True, type=text_input, help="boiler NAME or parameter file PATH"
    )
    run.add_argument(
        "--rig",
        default="local",
        help="local (in-process), modbus://HOST:PORT, modbus+tls://HOST:PORT (Modbus/TCP "
        "Security, with --tls-*) or modbus-rtu:///DEVICE?baud=19200&parity=E [local]",
    )
    for option, what in (
        ("--tls-cert", "client certificate (PEM) for modbus+tls://"),
        ("--tls-key", "its private key (PEM)"),
        ("--tls-ca", "CA certificate (PEM) that signed the server's certificate"),
    ):
        run.add_argument(option, type=path_arg, default=None, help=what)
    run.add_argument(
        "--profile",
        default=None,
        type=text_input,
        help="clean | lab | lab_instruments | lab_faulty | PROFILE.yaml, for --rig local "
        "(a Modbus server runs its own: serve --profile) [clean]",
    )
    run.add_argument(
        "--seed",
        type=int_in(0, 2**32 - 1),
        default=None,
        help="random seed of the profile, for --rig local [0]",
    )
    run.add_argument(
        "--reply-timeout",
        type=finite_float(0.1, 600.0, "s"),
        default=None,
        help="how long a Modbus rig waits for an instrument's reply (and to connect) before "
        "leaving its fields empty for the row (a no_reply fault costs this per row in lockstep) "
        f"[{RIG_TIMEOUT_S:g} s]",
    )
    run.add_argument(
        "--map", default=None, type=text_input, help="register map of a Modbus rig [shipped map]"
    )
    run.add_argument(
        "--reconnect-timeout",
        type=finite_float(0.0, 1e6, "s"),
        default=None,
        help="give up after a Modbus outage this long [60 s]",
    )
    run.add_argument(
        "--on-restart",
        choices=("abort", "restart-phase", "continue"),
        default=None,
        help="a Modbus server restarted in real time, or advanced or reset by another client: "
        "stop (exit 1), restart the current phase, or go on; the log marks the break "
        "(rig_epoch, gaps in the meta file). A restarted lockstep server with the same "
        "boiler, profile and seed is rebuilt by replay whatever this says [abort]",
    )
    run.add_argument(
        "--out",
        required=True,
        type=path_arg,
        help="lab log to write (CSV), missing directories created",
    )
    run.add_argument(
        "--live", action="store_true", help="live view of phase, sequence, time and key values"
    )
    run.add_argument("--quiet", action="store_true", help="no progress line, no summary")
    run.add_argument(
        "--fault-journal",
        type=text_file,
        default=None,
        metavar="JOURNAL.jsonl",
        help="the server's fault journal (serve --fault-log), for --fault-report",
    )
    run.add_argument(
        "--fault-report",
        type=path_arg,
        default=None,
        metavar="REPORT.json",
        help="after the run, compare what the client saw with the fault journal: "
        "detected, missed, false (needs --fault-journal and a Modbus rig)",
    )
    bal = sub.add_parser(
        "balance",
        help="energy balance per phase from the instruments (Eq. 3-7)",
        description="Energy balance per phase from a lab log: fuel power from the balance "
        "(cumulative), lambda from O2, flue-gas losses, heat to water; direct and indirect "
        "efficiency. Printed as a table and written as JSON.",
    )
    bal.add_argument("log", type=data_file, help="lab log (CSV)")
    bal.add_argument(
        "--boiler",
        default=None,
        type=text_input,
        help="boiler NAME or PATH (its fuel) [the meta file's boiler]",
    )
    bal.add_argument(
        "--out",
        type=path_arg,
        default=None,
        help="JSON to write, missing directories created [LOG.balance.json]",
    )
    cal = sub.add_parser(
        "calibrate",
        help="fit the model's parameters from lab logs (Section 3.1 of the paper)",
        description="Fit dTnom, dThx,wat, facA/facB, UAamb,OFF/ON, Pel and Wel, Pstart from a "
        "stationary-test and/or a load-cycle log, starting from the boiler's documentation "
        "values. Writes a parameter file, its uncertainties and the Fig. 4/5 regressions.",
    )
    cal.add_argument("logs", nargs="+", type=data_file, help="lab logs (CSV)")
    cal.add_argument(
        "--boiler", required=True, type=text_input, help="documentation values: NAME or PATH"
    )
    cal.add_argument(
        "--out",
        required=True,
        type=path_arg,
        help="parameter file to write (YAML), missing directories created",
    )
    val = sub.add_parser(
        "validate",
        help="simulate the model with a log's measured inputs and compare (Table 4)",
        description="Simulate the model with the log's measured flow, return and room "
        "temperature and on/off commands, and compare per phase with the lab (maximum "
        "deviation, correlation, RMSD; flue-gas loss; cumulative fuel). Writes "
        "validation.json, report.md and figures to DIR.",
    )
    val.add_argument("log", type=data_file, help="lab log (CSV)")
    val.add_argument(
        "--boiler", required=True, type=text_input, help="parameters: NAME or PATH (calibrated)"
    )
    val.add_argument(
        "--out", required=True, type=path_arg, help="output directory, created with its parents"
    )
    dia = sub.add_parser(
        "diagnose",
        help="where the model departs from the lab, which unmodelled effect, how far it shrinks",
        description="Calibrate on CAL, diagnose the sim-to-real gap, and check the chosen "
        "effect on the held-out VAL log. Writes diagnosis.json, report.md and figures.",
    )
    dia.add_argument("--calibration", required=True, type=path_arg, help="CAL.csv (fitted on)")
    dia.add_argument("--validation", required=True, type=path_arg, help="VAL.csv (held out)")
    dia.add_argument("--boiler", required=True, help="documentation values: NAME or PATH")
    dia.add_argument(
        "--out", required=True, type=path_arg, help="output directory, created with its parents"
    )
    dia.add_argument(
        "--ignition-charge-kg",
        type=finite_float(0.0, 10.0, "kg"),
        default=0.0,
        help="fuel the burner's start-up program feeds before the flame by design, as "
        "received (its manual): only feed beyond it is read as an ignition delay [0]",
    )
    frep = sub.add_parser(
        "fault-report",
        help="compare what a run saw with the server's fault journal",
        description="Compare a Modbus run's events (LOG.modbus_events.jsonl) and log with "
        "the server's fault journal (serve --fault-log): each fault detected or missed, "
        "and the client's false alarms. The log of another acquisition program (no events "
        "file) is compared alone: a unit's silence or exception must show as its readings "
        "left empty. Writes REPORT.json.",
    )
    frep.add_argument(
        "log", type=data_file, help="lab log (CSV) of a Modbus run, hil-client's or your own"
    )
    frep.add_argument("--journal", required=True, type=text_file, help="fault journal (JSONL)")
    frep.add_argument(
        "--out",
        required=True,
        type=path_arg,
        help="report to write (JSON), missing directories created",
    )
    frep.add_argument(
        "--map",
        default=None,
        type=text_input,
        help="register map the server served, for a log without events: which readings "
        "each unit gives [shipped map]",
    )
    gap = sub.add_parser(
        "gap-benchmark",
        help="blind benchmark of the diagnosis on generated cases",
        description="Generate cases (one effect or none, strengths from barely detectable "
        "to strong, both boilers, both log pairs), write the stationary test and the load "
        "cycle with the chosen reality, keep the truth sealed, diagnose blind and score. "
        "Writes scores.json (with the confidence's reliability table and Brier score, and why "
        "each miss missed).",
    )
    gap.add_argument(
        "--cases", type=int_in(1, 10_000), default=48, help="number of cases, 1..10000 [48]"
    )
    gap.add_argument(
        "--reality",
        choices=("independent", "emulator"),
        default="independent",
        help="what writes the lab logs: an independently written plant, or the emulator's "
        "own [independent]",
    )
    gap.add_argument(
        "--seed", type=int_in(0, 2**32 - 1), default=0, help="seed of the case generator [0]"
    )
    gap.add_argument(
        "--out", required=True, type=path_arg, help="output directory, created with its parents"
    )
    gap.add_argument(
        "--workers", type=int_in(1, 256), default=2, help="parallel processes, 1..256 [2]"
    )
    gap.add_argument(
        "--plant",
        action="append",
        metavar="NAME",
        help="only this independent plant: reality, reality2, or the held-out reality3 to "
        "reality10 (repeatable) [reality and reality2]",
    )
    return parser


def _warn_tolerated(logs: Sequence[LabLog]) -> None:
    """A warning line for what was tolerated on reading each log; only once the logs are
    taken, so that a log refused later gets its one error line alone."""
    for log in logs:
        if log.has("balance_mass_kg"):
            log.balance_readings()  # (fuel taken off by hand is a note of its reading)
        for note in log.notes:  # each naming its file (the phases' notes did not: a probe)
            named = note if note.startswith(str(log.path)) else f"{log.path}: {note}"
            print(f"hil-client: warning: {named}", file=sys.stderr)


def _logs_with_phases(
    paths: Sequence[Path], boiler: BoilerParams | None = None
) -> list[tuple[LabLog, Phases]]:
    """Each lab log with its phases; a bad log is bad input. A log whose meta file names
    another boiler than ``boiler`` (the one it is analysed with) gets a warning: one log of
    a 6-kW boiler analysed as the 12-kW one gave fits far from any boiler, silently."""
    with bad_input(LogError):
        logs = [one_plant(read_log(path)) for path in paths]
        for log in logs:
            check_time_step(log)
            refuse_reversed_flow(log)
            refuse_wrong_units(log, boiler)
        found = [(log, _phases_or_why(log, boiler)) for log in logs]
    _warn_tolerated(logs)
    if boiler is not None:
        for log in logs:
            _warn_other_boiler(log, boiler)
            _warn_suspicious(log, boiler)
    return found


def _phases_or_why(log: LabLog, boiler: BoilerParams | None, partial: bool = False) -> Phases:
    """The log's phases (with ``partial``, those a run cut short recorded); where they
    cannot be found, the error says too what in the log looks like a wrong unit or a broken
    sensor (a time in milliseconds, a negative flow: "the water never circulates" alone
    sent the user looking at the pump)."""
    try:
        return find_phases(log, partial=partial)
    except LogError as exc:
        # (a meta file's marks found wrong keep their own message)
        few = too_few_rows(log) if str(exc).startswith(f"{log.path}: cannot find") else None
        if few is not None:
            raise LogError(few) from None
        hints = [line.split(": ", 1)[1] for line in suspicious(log, boiler)]
        if not hints:
            raise
        raise LogError(f"{exc} (and {'; '.join(hints)})") from None


def _warn_suspicious(log: LabLog, boiler: BoilerParams) -> list[str]:
    """A warning line for each thing in ``log`` that looks like a wrong unit or a broken
    sensor (:func:`hil_client.analysis.sanity.suspicious`); the lines said."""
    said = suspicious(log, boiler)
    for line in said:
        print(f"hil-client: warning: {line}", file=sys.stderr)
    return said


def _boiler_recorded(params: BoilerParams) -> str | dict[str, Any]:
    """The meta file's ``boiler`` (CONTRACT section 3): the shipped file's name where the
    run's parameters are that file's, else the parameters inline. A file of the user's own
    that keeps a shipped boiler's name was recorded by that name, and ``balance`` read the
    log with the shipped fuel (75.9 % for 84.0 %, no word; a stranger's probe)."""
    shipped = BOILER_DIR / f"{params.name}.yaml"
    try:
        if shipped.is_file() and load_boiler(str(shipped)).to_mapping() == params.to_mapping():
            return params.name
    except (OSError, ValueError, ParameterError):  # (a name no file can have)
        pass
    return params.to_mapping()


def _warn_other_boiler(log: LabLog, boiler: BoilerParams) -> None:
    """A warning when the log's meta file names another boiler than the one it is analysed
    with (by name: a calibrated file keeps its boiler's name)."""
    recorded = log.meta.get("boiler")
    if isinstance(recorded, dict):  # the run's own parameters (a file of the user's own)
        if recorded != boiler.to_mapping():  # (by its name alone, a file keeping a shipped
            print(  # boiler's name was balanced with the shipped fuel: a re-probe)
                f"hil-client: warning: {log.path} was recorded with the parameters its meta "
                f"file holds ('{recorded.get('name')}'), and is analysed with other ones "
                f"('{boiler.name}', --boiler)",
                file=sys.stderr,
            )
        return
    if isinstance(recorded, str) and recorded != boiler.name:
        print(
            f"hil-client: warning: {log.path} was recorded with boiler '{recorded}' (its meta "
            f"file) and is analysed as '{boiler.name}' (--boiler)",
            file=sys.stderr,
        )


def _check_advance(register_map: RegisterMap, period_s: float) -> None:
    """UsageError where the map's lockstep_advance cannot carry the acquisition period as
    it is (a uint16 at scale 0.001 tops at 65.5 s, one at 0.3 sends 9.9 for 10: the server
    moved on by another time, and the run stopped blaming "another client": a re-probe)."""
    _, point = register_map.point("lockstep_advance_s")
    low, high = accepted_range(point)
    carried = decode(point, encode(point, period_s))
    where = f"--map {register_map.source}: its lockstep_advance point '{point.name}'"
    if not low <= period_s <= high:  # (the message said "carries 0.3 s for 0.3 s": a probe)
        raise UsageError(
            f"{where} accepts {low:g}..{high:g} s, not the protocol's {period_s:g}-s steps"
        )
    if carried != period_s:
        raise UsageError(
            f"{where} ({point.datatype}, scale {point.scale:g}) carries {carried:.10g} s for the "
            f"protocol's {period_s:.10g}-s steps"
        )


def _file_given(name_or_path: str | Path | None) -> Path | None:
    """The file an option names where it names one (not a shipped NAME), for
    :func:`refuse_overwriting`."""
    if name_or_path is None:
        return None
    path = Path(name_or_path)
    return path if path.is_file() else None


def _log_files(log: Path) -> dict[str, Path]:
    """A lab log's own files, by what they are (for :func:`refuse_overwriting`)."""
    return {
        "the lab log": log,
        "the lab log's meta file": meta_path(log),
        "the lab log's Modbus events file": events_path(log),
    }


def _same_log(a: Path, b: Path) -> bool:
    """Whether two paths hold the same log (the same file, or the same bytes)."""
    try:
        if a.resolve() == b.resolve():
            return True
        return a.is_file() and b.is_file() and filecmp.cmp(a, b, shallow=False)
    except (OSError, RuntimeError):  # reported when it is read (a loop of links: a probe)
        return False


def _check_out_dir(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out: '{out}' exists and is not a directory")
    _check_out_parent(out)


def _check_out_parent(out: Path) -> None:
    """Refuse an ``--out`` that cannot be created because an existing ancestor of it is a
    file (checked without creating anything; :func:`output_file` creates the rest)."""
    for parent in out.parents:
        if parent.exists():
            if not parent.is_dir():
                raise UsageError(f"--out: '{parent}' is a file, not a directory")
            return


def _cmd_diagnose(args: argparse.Namespace) -> int:
    doc = boiler_arg(args.boiler)
    if _same_log(args.calibration, args.validation):
        raise UsageError(
            "--validation: the same log as --calibration; the held-out log must be another"
            " (CONTRACT section 4: nothing is fitted or selected on it)"
        )
    cal, val = _logs_with_phases([args.calibration, args.validation], doc)
    if same_record(cal[0], val[0]):
        raise UsageError(
            "--validation: the same record as --calibration, or a part of it (its firing"
            f" within {SAME_RECORD_K:g} K: re-exported, rounded, thinned or cut? two"
            " emulated runs with the same --seed, or clean ones, are one record where they"
            " run alike: give the held-out run another seed);"
            " the held-out log must be another (CONTRACT section 4: nothing is fitted or"
            " selected on it)"
        )
    _check_out_dir(args.out)
    with bad_input(LogError):
        result = diagnose(*cal, *val, doc, args.ignition_charge_kg)
    write_diagnosis(result, args.out, str(args.calibration), str(args.validation))
    for line in result.content.get("calibration_warnings", []):
        print(f"hil-client: warning: {line}", file=sys.stderr)
    print(f"effect: {result.effect} (confidence {result.confidence:.2f})")
    if result.unexplained_gap:
        top = result.where[0]
        print(f"unexplained gap: largest in {top['signal']} during {top['phase']}")
    s = result.shrinkage
    if s and s["shrink_pct"] is not None:
        verdict = "" if s["confirmed"] else "; not confirmed on held-out data"
        print(
            f"where it acts: {s['signal']} ({s['phase']}); validation RMSD "
            f"{s['validation_rmsd_before']:.4g} -> {s['validation_rmsd_after']:.4g} "
            f"({s['shrink_pct']:.0f} % smaller{verdict})"
        )
    elif s:
        print(f"where it acts: {s['signal']} ({s['phase']}); not measurable on the validation log")
    for caveat in result.caveats:
        print(f"caveat: {caveat}")
    print(f"written: {args.out / 'diagnosis.json'}, {args.out / 'report.md'}")
    return 0


def _cmd_gap_benchmark(args: argparse.Namespace) -> int:
    _check_out_dir(args.out)
    from hil_client.analysis.gap_benchmark import (
        plants_by_name,
        run_benchmark,
    )

    plants = None
    if args.plant:
        if args.reality != "independent":
            raise UsageError("--plant chooses among the independent plants (--reality independent)")
        known = plants_by_name()
        unknown = [p for p in args.plant if p not in known]
        if unknown:
            raise UsageError(f"--plant: unknown plant '{unknown[0]}'; known: {', '.join(known)}")
        plants = [known[p] for p in args.plant]
    run_benchmark(args.cases, args.seed, args.out, args.workers, args.reality, plants)
    return 0


def _cmd_validate(args: argparse.Namespace) -> int:
    params = boiler_arg(args.boiler)
    [(log, phases)] = _logs_with_phases([args.log], params)
    _check_out_dir(args.out)
    with bad_input(LogError):
        comp = compare(log, phases, params)
        result = validation_metrics(comp, log, params)
    args.out.mkdir(parents=True, exist_ok=True)
    result = {
        "log": str(args.log),
        "boiler": params.name,
        "phases": phases.as_dict() | {"source": phases.source},
        **result,
    }
    write_atomically(args.out / "validation.json", strict_json(result, indent=2) + "\n")
    figures = validation_figures(
        comp, phases, args.out / "validation", f"{args.log.name}: model ({params.name}) against lab"
    )
    report = validation_report(result, figures)
    write_atomically(args.out / "report.md", report)
    print(report.split("## Figures")[0].rstrip())
    print(
        f"\nwritten: {args.out / 'validation.json'}, {args.out / 'report.md'}, "
        + ", ".join(str(f) for f in figures)
    )
    return 0


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _cmd_calibrate(args: argparse.Namespace) -> int:
    doc = boiler_arg(args.boiler)
    if args.out.suffix not in (".yaml", ".yml"):
        raise UsageError(f"--out: '{args.out}' must name a .yaml file")
    with bad_input(ParameterError):
        documentation = resolve_boiler(args.boiler)
    refuse_overwriting(args.out, {"the --boiler file (the documentation values)": documentation})
    for log in args.logs:  # (a log named .yaml was replaced by the parameters: a probe)
        refuse_overwriting(args.out, _log_files(log))
    logs = _logs_with_phases(args.logs, doc)
    with bad_input(LogError, ParameterError):
        result = calibrate(logs, doc)
        params = params_from_mapping(result.params.to_mapping(), str(args.out))
    lines = [
        f"# calibrated by hil-client from {', '.join(str(p) for p in args.logs)}",
        f"# documentation values from {args.boiler}; fitted values +- expanded uncertainty (k=2):",
    ]
    for key, f in result.fitted.items():
        kept = f"  IMPLAUSIBLE, {getattr(params, key):.4g} written" if key in result.flags else ""
        lines.append(f"#   {key} = {f.value:.4g} +- {f.expanded:.2g}  ({f.method}){kept}")
    dump_boiler(params, output_file(args.out), header="\n".join(lines))
    side = args.out.with_suffix(".uncertainty.json")
    write_atomically(
        side,
        json.dumps(
            {
                key: {
                    "value": _finite_or_none(f.value),
                    "standard_uncertainty": _finite_or_none(f.u),
                    "expanded_uncertainty_k2": _finite_or_none(f.expanded),
                    "method": f.method,
                    "points": f.n,
                    "implausible": key in result.flags,
                    **(
                        {"kept": getattr(params, key), "why": result.flags[key]}
                        if key in result.flags
                        else {}
                    ),
                    **({"far_from_documentation": result.far[key]} if key in result.far else {}),
                }
                for key, f in result.fitted.items()
            }
            | {  # what the logs could not give: the documentation value, and why
                key: {
                    "value": None,
                    "standard_uncertainty": None,
                    "expanded_uncertainty_k2": None,
                    "method": None,
                    "points": 0,
                    "implausible": False,
                    "kept": getattr(params, key),
                    "why": why,
                }
                for key, why in result.flags.items()
                if key not in result.fitted
            },
            indent=2,
            allow_nan=False,
        )
        + "\n",
    )
    figures = calibration_figures(result, args.out.with_suffix(""))
    print(f"calibrated {params.name} from {len(args.logs)} log(s):")
    print(f"  {'parameter':<20} {'value':>10} {'+- (k=2)':>10}  {'documentation':>13}")
    for key, f in result.fitted.items():
        print(f"  {key:<20} {f.value:>10.4g} {f.expanded:>10.2g}  {getattr(doc, key):>13.4g}")
    for key, why in result.flags.items():
        written, documented = getattr(params, key), getattr(doc, key)
        kept = (
            f"documentation value {documented:.4g} kept"
            if written == documented
            else f"{written:.4g} written, at that bound (documentation value {documented:.4g})"
        )
        print(f"hil-client: warning: {key}: {why}; {kept}", file=sys.stderr)
    for line in result.warnings:
        print(f"hil-client: warning: {line}", file=sys.stderr)
    print(f"written: {args.out}, {side}, " + ", ".join(str(p) for p in figures))
    return 0


def _boiler_for(log: LabLog, name: str | None):
    """The boiler named on the command line, else in the log's meta file."""
    if name:
        params = boiler_arg(name)
        _warn_other_boiler(log, params)
        return params
    recorded = log.meta.get("boiler")
    meta = meta_path(log.path)
    if isinstance(recorded, dict):  # inline parameters (CONTRACT section 3)
        with bad_input(ParameterError):
            return params_from_mapping(recorded, f"{meta}: boiler")
    if not isinstance(recorded, str):
        if not log.meta:
            where = f"(no meta file {meta.name})"
        elif recorded is None:  # (a key 'Boiler' was noted after this error: a re-probe)
            like = [k for k, m in unread_meta_keys(log.meta).items() if m == "boiler"]
            said = f" ({unread_key_note(like[0], 'boiler', meta)})" if like else ""
            where = "in its meta file" + said
        else:
            kind = type(recorded).__name__
            where = f"in its meta file ('boiler' is {kind}, not a name or parameters)"
        raise UsageError(f"{log.path}: no boiler named {where}; give --boiler")
    try:
        return boiler_arg(recorded)
    except UsageError as exc:
        raise UsageError(f"{meta}: {exc}") from None


def _cmd_balance(args: argparse.Namespace) -> int:
    with bad_input(LogError):
        log = one_plant(read_log(args.log))
        check_time_step(log)
        refuse_reversed_flow(log)
        params = _boiler_for(log, args.boiler)
        refuse_wrong_units(log, params)
        phases = _phases_or_why(log, params, partial=True)
    _warn_tolerated([log])
    said = _warn_suspicious(log, params)
    rows = energy_balance(log, params, phases)
    out = args.out or args.log.with_name(args.log.stem + ".balance.json")
    refuse_overwriting(out, _log_files(args.log) | {"the --boiler file": _file_given(args.boiler)})
    out = output_file(out)
    # strict JSON: a figure a phase does not define (NaN, e.g. no fuel burnt) is null
    text = strict_json(balance_json(rows, phases), indent=2)
    write_atomically(out, text + "\n")
    print(f"energy balance of {args.log} ({params.name}; phases from the {phases.source})")
    print(balance_table(rows))
    for line in balance_warnings(rows):  # on stderr, as every other warning
        empty = re.match(r"column '([^']+)' has no readings", line)
        if empty and any(f"column '{empty[1]}' has no readings" in x for x in said):
            continue  # said of the log already (twice on one stream: a re-probe)
        print(f"hil-client: warning: {line}", file=sys.stderr)
    if log.has("balance_mass_kg"):  # taken out of the fuel, as said (it was not: a probe)
        found = refills(log.balance_readings()[0], log.t)  # (a dropout's return was one)
        if found:
            each = ", ".join(f"+{r.rise_kg:.2f} kg at time_s {log.t[r.start]:g}" for r in found)
            print(f"note: {len(found)} refill(s) of the balance taken out of the fuel ({each})")
    print(f"written: {out}")
    return 0


def _rig_map(args: argparse.Namespace) -> RegisterMap | None:
    """The register map a Modbus rig uses (None for the local rig); a ``--map`` given is
    validated whatever the rig, and a Modbus rig's must have every signal it reads or
    writes."""
    remote = args.rig != "local"
    if not remote and args.map is None:
        return None
    if remote and not args.rig.startswith(("modbus://", "modbus+tls://", "modbus-rtu://")):
        raise UsageError(
            f"--rig: '{args.rig}' is neither 'local' nor modbus://HOST:PORT, "
            "modbus+tls://HOST:PORT or modbus-rtu:///DEVICE"
        )
    with bad_input(MapError, prefix="--map: "):
        register_map = load_map(args.map)
        if remote:
            check_map(register_map)
    if not remote:  # (taken and ignored without a word: a stranger's probe)
        print(
            f"hil-client: warning: --map {args.map} is checked, but --rig local reads no "
            "registers: the map is for a Modbus rig",
            file=sys.stderr,
        )
    return register_map if remote else None


def _served_boiler(served: int) -> str:
    """The shipped boiler whose ``boiler_id`` is ``served``, else the id in hex."""
    for path in sorted(BOILER_DIR.glob("*.yaml")):
        try:
            if boiler_identity(load_boiler(path.stem)) == served:
                return f"{path.stem} (boiler id {served:08x})"
        except ParameterError:
            continue
    return f"boiler id {served:08x}"


def _make_rig(args: argparse.Namespace, params: BoilerParams, register_map: RegisterMap | None):
    """The rig named by --rig; bad options (and a server running another boiler than
    ``params``) raise UsageError, an unreachable server RigError."""
    if register_map is None:
        wire = ("--reply-timeout", "--reconnect-timeout", "--on-restart", "--tls-cert",
                "--tls-key", "--tls-ca")  # fmt: skip
        given = [o for o in wire if getattr(args, o[2:].replace("-", "_")) is not None]
        if given:  # nothing to wait for, reconnect to or secure in-process (they were
            print(  # taken and ignored without a word: a stranger's probe)
                f"hil-client: warning: {', '.join(given)} apply to a Modbus rig, not to "
                "--rig local",
                file=sys.stderr,
            )
        with bad_input(ProfileError, prefix="--profile: "):
            profile = load_profile(args.profile or "clean")
        wire_only = wire_only_faults(profile.faults)
        if wire_only:
            print(
                "hil-client: warning: --rig local has no wire: the profile's"
                f" {', '.join(wire_only)} faults act on a Modbus rig only (its instrument"
                " faults act here)",
                file=sys.stderr,
            )
        return LocalRig(params, profile, seed=args.seed or 0)
    timeout_s = RIG_TIMEOUT_S if args.reply_timeout is None else args.reply_timeout
    ignored = [o for o, v in (("--profile", args.profile), ("--seed", args.seed)) if v is not None]
    if ignored:  # the server's own profile and seed make the readings
        print(
            f"hil-client: warning: {' and '.join(ignored)} apply to --rig local; the server at "
            f"{args.rig} runs its own (rig-emulator serve --profile/--seed)",
            file=sys.stderr,
        )
    with bad_input(ValueError, prefix="--rig: "):
        tls = tls_files(args, args.rig)
        connect = connector(args.rig, timeout_s, tls)
        if tls is not None and (problem := validity_problem(tls.cert)):
            print(
                f"hil-client: warning: --tls-cert {tls.cert} {problem}: a server refuses it",
                file=sys.stderr,
            )
    rig = ModbusRig(
        args.rig,
        register_map,
        timeout_s=timeout_s,
        reconnect_timeout_s=60.0 if args.reconnect_timeout is None else args.reconnect_timeout,
        on_restart=args.on_restart or "abort",
        connect=connect,
    )
    served, ours = rig.identity["boiler_id"], boiler_identity(params)
    if served != ours:
        rig.close()
        raise UsageError(
            f"--boiler {args.boiler}: the server at {args.rig} runs another boiler, "
            f"{_served_boiler(served)}; {params.name} is boiler id {ours:08x}"
        )
    if rig.lockstep and not rig.fresh_start:  # (it started without a word: a stranger's probe)
        print(
            f"hil-client: warning: the server is not fresh (simulated time "
            f"{rig.sim_time_s:g} s, lockstep counter {rig.advances_before}, which wraps at "
            "65536; a fresh one reads 0 and 0):"
            " the run starts on its plant as it is, and a restart of the server cannot be "
            "replayed into this log",
            file=sys.stderr,
        )
    return rig


#: What a write came back with when the plant did not (or may not) get it; a ``late`` reply
#: was carried out, only slowly.
_FAILED_EVENTS = ("exception", "timeout", "no_reply")


def _refused_commands(events: list[dict]) -> str | None:
    """One line on the setpoint and switch writes the server refused or left unanswered
    (a TLS role that may not write, a faulty unit), or None."""
    failed = [  # (one refused with a transient code and asked again is no failure)
        e
        for e in events
        if e.get("function") in WRITE_FUNCTIONS
        and e.get("event") in _FAILED_EVENTS
        and not e.get("retried")
    ]
    if not failed:
        return None
    codes = sorted({f"exception {e['code']:02X}" for e in failed if "code" in e})
    unanswered = sorted({e["event"].replace("_", " ") for e in failed if "code" not in e})
    how = ", ".join(codes + unanswered)
    # a refused write changed nothing; one never answered may have been carried out
    got = "did not get" if not unanswered else "may not have got"
    return (
        f"{len(failed)} setpoint or switch writes failed ({how}; the first to unit "
        f"{failed[0]['unit']}): the plant {got} those commands (see the events file)"
    )


def _end_notes(rig: object) -> list[str]:
    """The rig's lines for a run's end (:meth:`hil_client.rigs.modbus.ModbusRig.end_notes`:
    units that refused every read, readings at their register's limit); none for a rig
    without them."""
    end_notes = getattr(rig, "end_notes", None)
    return end_notes() if end_notes is not None else []


#: Breaks said on stderr as they happen; the rest are in the meta file.
BREAKS_TOLD = 10


#: What another client's write of each command the rig reads back did, in words.
_OVERRIDES = {
    "boiler_command": "the boiler was switched",
    "pump_on": "the bench pump was switched",
    "return_heating": "the return heating was switched",
    "water_flow_setpoint_kg_h": "the flow setpoint was changed",
    "return_setpoint_C": "the return setpoint was changed",
}


def _overridden_what(events: list[dict]) -> str:
    """What the ``overridden`` events say was changed (an event without ``signals``, of an
    earlier release: the boiler's switch)."""
    signals = dict.fromkeys(s for e in events for s in e.get("signals") or ["boiler_command"])
    return listed([_OVERRIDES.get(s, f"{s} was changed") for s in signals])


def _overridden(events: list[dict]) -> str | None:
    """One line on the rows where a command of this run's was not what it wrote (another
    client, or a hand at the bench, switched the boiler or the pump, or wrote a setpoint),
    or None."""
    changed = [e for e in events if e.get("event") == "overridden"]
    if not changed:
        return None
    return (
        f"{_overridden_what(changed)} against this run's command on {len(changed)} row(s) "
        f"(first at time_s {changed[0]['time_s']:g}; another client or a hand at the bench): "
        "each time the command was written again, and those rows are not this protocol's "
        "(see the events file)"
    )


#: How many names an earlier run's files are tried under (``NAME.previous.csv``,
#: ``NAME.previous2.csv``, ...): each taken one is a log kept by a re-run that did not
#: complete, or another run's.
ASIDE_NAMES = 100


class _EarlierRun:
    """The files an earlier run left at ``--out`` (its log, meta and Modbus events), set
    aside while this run writes as a log of their own beside it: ``NAME.previous.csv``
    with ``NAME.previous.meta.json`` and ``NAME.previous.modbus_events.jsonl`` (the first
    of ``NAME.previous2.csv``, ... none of whose files exists), readable by every analysis
    as they are, and what a run killed with -9 leaves. Only a run that completes replaces
    them (deletes them); one that stops without a row puts them back; one that stops after
    rows (Ctrl-C, a rig error, a full disk) keeps them there beside its partial log and
    says so (a stranger's probe: Ctrl-C 2 s into a re-run, or a full disk, deleted the
    complete 18-h log at its ``--out``; and the ``.previous`` a run killed with -9 left
    was overwritten by the next run's set-aside). The name is locked as a log is
    (:mod:`hil_client.run_lock`), so no other run writes or sets aside there meanwhile.
    Logs kept so by earlier re-runs are said at the start and never touched (only this
    run's own set-aside is deleted); their lock files, left by a run killed with -9, go."""

    def __init__(self, out: Path, held: contextlib.ExitStack) -> None:
        self.out = out
        self.moved: list[tuple[Path, Path]] = []  # (at --out, aside)
        self.told = False  # where they are, said on stderr
        self._held = held
        self.left: list[Path] = []  # names holding logs that earlier re-runs kept
        self.aside = self._look_through(self._present())

    def __bool__(self) -> bool:
        return bool(self.moved)

    @property
    def log_moved(self) -> bool:
        """Whether the earlier run's log itself was set aside (else only its meta or
        events file was at ``--out``)."""
        return any(at == self.out for at, _ in self.moved)

    def _present(self) -> list[Path]:
        return [path for path in _log_files(self.out).values() if os.path.lexists(path)]

    def _aside_names(self) -> Iterator[Path]:
        """``NAME.previous.csv``, ``NAME.previous2.csv``, ... (:data:`ASIDE_NAMES`)."""
        for number in range(1, ASIDE_NAMES + 1):
            tail = f"previous{number if number > 1 else ''}"
            yield self.out.with_name(f"{self.out.stem}.{tail}{self.out.suffix}")

    def _look_through(self, present: list[Path]) -> Path | None:
        """The first free name for the earlier run's ``present`` files, locked for this run
        (None with none present; exit 2 where all are taken: the kept logs are the user's
        to look through, or where its names are too long to be made). On the way, the
        names holding kept logs are noted (:attr:`left`), and a lock file of such a name
        that no live process holds is removed (a run killed with -9 left it behind)."""
        free = None
        for aside in self._aside_names():
            files = [*_log_files(aside).values(), *same_companions(aside)]
            taken = any(os.path.lexists(path) for path in files)
            if taken or os.path.lexists(lock_path(aside)):
                try:  # (taken and let go at once: the lock file goes with it)
                    with run_lock(aside, "keeping", self.out):
                        pass
                except RunBusy:  # a live run writes or keeps there: not a kept log
                    continue
                if taken:
                    self.left.append(aside)
                    continue
            if free is None and present:
                self._refuse_too_long(present, aside)
                try:
                    self._held.enter_context(run_lock(aside, "keeping", self.out))
                except RunBusy:
                    continue
                free = aside
        if present and free is None:
            raise UsageError(
                f"--out: '{self.out}' holds an earlier run's log, and {ASIDE_NAMES} earlier "
                f"runs are kept beside it already ({self.out.stem}.previous*"
                f"{self.out.suffix}): move them away, or give another --out"
            )
        return free

    def _refuse_too_long(self, present: list[Path], aside: Path) -> None:
        """Exit 2 where a name ``present``'s files would take under ``aside`` is longer
        than the file system allows (a stranger's probe: a 236-character stem, whose
        ``.previous2.meta.json`` could not be made; the log was moved, its meta was not,
        and every later run failed so). The later names are no shorter."""
        for path, name in self._pairs(aside).items():
            if path not in present:
                continue
            try:
                os.lstat(name)
            except OSError as exc:  # (any other error: the rename says it, moving nothing)
                if exc.errno == errno.ENAMETOOLONG:
                    raise UsageError(
                        f"--out: '{self.out}' holds an earlier run's files, and the name to "
                        f"keep '{path.name}' under, '{name.name}', is too long for its file "
                        f"system ({exc.strerror}): move the earlier run's files away, or give "
                        "a shorter --out"
                    ) from None

    def _pairs(self, aside: Path) -> dict[Path, Path]:
        """Each file of the log at ``--out`` and its name under ``aside``."""
        return dict(zip(_log_files(self.out).values(), _log_files(aside).values(), strict=True))

    def set_aside(self) -> None:
        """Say which logs earlier re-runs kept, then move the earlier run's files to the
        free name, all or none: a rename that fails undoes those made (exit 2 naming the
        file; a stranger's probe: an immutable meta file left the log moved and its meta
        at ``--out``, which a later run took for an earlier run's and deleted), and a
        Ctrl-C or SIGTERM waits for the last rename, then puts them back (the run has
        written nothing yet)."""
        try:
            with _signals_held():  # (a signal that came is raised as the block ends)
                failed = self._move(self._pairs(self.aside)) if self.aside else None
                if self.left and not failed:  # (a refusal is one line)
                    print(f"hil-client: {self._left_line()}", file=sys.stderr)
                if self.moved:
                    self._held.callback(self._tell_if_left)
                    print(f"hil-client: {self._holds()}", file=sys.stderr)
        except KeyboardInterrupt:
            with _signals_held():
                self.put_back()
            raise
        if failed:
            raise UsageError(failed)

    def _move(self, names: dict[Path, Path]) -> str | None:
        """Rename the files at ``--out`` to ``names``, or none of them: at a rename that
        fails, the ones made are renamed back; the line refusing the run then (None when
        all moved)."""
        for path in self._present():
            try:
                path.replace(names[path])
            except OSError as exc:
                line = (
                    f"--out: '{self.out}' holds an earlier run's files, and '{path}' cannot "
                    f"be set aside as '{names[path].name}' ({exc.strerror or exc})"
                )
                stuck = self._undo()
                if stuck:
                    return f"{line}; {stuck}"
                return f"{line}: nothing was moved; make it movable, or give another --out"
            self.moved.append((path, names[path]))
        return None

    def _undo(self) -> str:
        """Rename the files moved so far back; what could not be (empty if all were)."""
        stuck = []
        for path, aside in reversed(self.moved):
            try:
                aside.replace(path)
            except OSError as exc:
                stuck.append(f"'{aside}' could not be put back as '{path.name}' ({exc.strerror})")
        self.moved = []
        return ", and ".join(stuck)

    def _left_line(self) -> str:
        """A line on the logs earlier re-runs kept beside ``--out``, which this run leaves."""
        kept = []
        for aside in self.left:
            files = _log_files(aside)
            if os.path.lexists(aside):
                facts = _log_facts(aside, files["the lab log's meta file"])
                kept.append(f"{aside.name} ({facts})" if facts else aside.name)
            else:
                kept.extend(path.name for path in files.values() if os.path.lexists(path))
        return (
            f"kept beside {self.out} by earlier re-runs that did not complete: "
            f"{', '.join(kept)}; this run leaves them as they are"
        )

    def _holds(self) -> str:
        """A line on the earlier run's log at ``--out`` and where it waits."""
        if self.log_moved:
            aside = dict(self.moved)
            facts = _log_facts(aside[self.out], aside.get(meta_path(self.out)))
            what = f"an earlier run's log ({facts})" if facts else "an earlier run's log"
            them = "it once it completes; until then it is"
        else:  # (no log to describe: kept, see :meth:`drop`)
            return (
                f"{self.out} holds an earlier run's files without their log: they are kept as "
                f"{self._where()}"
            )
        return f"{self.out} holds {what}: this run replaces {them} kept as {self._where()}"

    def _where(self) -> str:
        """The name the earlier run's files wait under (its log's, or each file's)."""
        if self.log_moved:
            return str(dict(self.moved)[self.out])
        return ", ".join(str(path) for _, path in self.moved)

    def kept(self, disk_full: bool = False) -> str:
        """Where the earlier run's files stay after a run that stopped with rows (and, on
        a full disk, that they take part of it: the user decides, nothing is deleted)."""
        self.told = True
        log = self.log_moved
        line = f"the earlier run's {'log is' if log else 'files are'} kept as {self._where()}"
        line += " (a run that did not complete replaces nothing"
        if disk_full:
            size = sum(path.stat().st_size for _, path in self.moved if path.is_file())
            them = ("it takes", "it", "it is") if log else ("they take", "them", "they are")
            line += (
                f"; {them[0]} {size / 1e6:.1f} MB of the full disk: delete {them[1]} only if"
                f" {them[2]} not needed"
            )
        return line + ")"

    def _tell_if_left(self) -> None:
        """Said as the run ends where nothing else said it (a run that stopped between
        its last row and its complete meta file)."""
        if self.moved and not self.told:
            print(f"hil-client: {self.kept()}", file=sys.stderr)

    def put_back(self) -> None:
        """The earlier run's files back at ``--out`` (this run wrote no row of its own)."""
        for path, aside in self.moved:
            aside.replace(path)
        self.moved = []

    def drop(self) -> None:
        """Delete the earlier run's files: this run completed, and replaces them. A meta or
        events file without its log is kept and said: a run killed with -9 between the
        renames of its set-aside leaves the log kept and its meta at ``--out`` (a re-probe:
        the next run deleted the meta of a complete 18-h log kept beside it)."""
        if self.moved and not self.log_moved:
            kept = ", ".join(str(aside) for _, aside in self.moved)
            print(
                f"hil-client: the files without a log that were at {self.out} are kept as "
                f"{kept} (a run killed while setting a log aside leaves its meta so: see the "
                "logs kept beside it)",
                file=sys.stderr,
            )
        else:
            for _, aside in self.moved:
                aside.unlink(missing_ok=True)
        self.moved = []


def _log_facts(log: Path, meta: Path | None) -> str:
    """What a log says of itself, for a line on it: its rows and whether its meta file
    says it is complete (empty where neither can be read)."""
    if not log.is_file():  # (a FIFO would be read forever)
        return ""
    try:
        with log.open("rb") as fh:
            rows = max(sum(1 for _ in fh) - 1, 0)
        loaded = json.loads(meta.read_text()) if meta and meta.is_file() else {}
    except (OSError, ValueError):
        rows, loaded = None, {}
    complete = loaded.get("complete") if isinstance(loaded, dict) else None
    done = {True: "complete", False: "not complete"}.get(complete, "")
    return ", ".join(x for x in (f"{rows} rows" if rows is not None else "", done) if x)


def _settle_previous(
    out: Path, previous: _EarlierRun, rows: int, gaps: list, completed: bool
) -> None:
    """After a run that wrote ``rows`` rows: one that completed replaces the previous
    run's files (they are deleted); one that stopped with rows keeps them where they were
    set aside; with no row, they come back and this run's own files go (a header and a
    meta file with nothing to describe), unless, with no previous run, its meta records a
    break (``gaps``: why it never got a row). A signal waits until the files are settled."""
    with _signals_held():
        if completed:
            previous.drop()
            return
        if rows:
            return
        if previous or not gaps:
            for path in _log_files(out).values():
                with contextlib.suppress(OSError):  # (a read-only file system has none to go)
                    path.unlink(missing_ok=True)
        previous.put_back()


def _what_is_kept(rows: int, previous: _EarlierRun, gaps: list, disk_full: bool = False) -> str:
    """What a run that stopped leaves at ``--out`` (see :func:`_settle_previous`)."""
    if rows:  # (a full disk loses the row it could not write: "every row" was wrong)
        kept = f"the log keeps the {rows} row{'s' if rows != 1 else ''} written"
        return f"{kept}, and {previous.kept(disk_full)}" if previous else kept
    if previous:
        return "no row was acquired; the previous run's log is back"
    if gaps:
        return "no row was acquired; the meta file records why (its gaps)"
    return "no row was acquired; no log written"


def _not_a_file(path: Path) -> bool:
    """Whether ``path`` is there and no regular file (a name too long to exist is not
    there: ``Path.exists`` raised for it, a test)."""
    try:
        return not stat.S_ISREG(path.stat().st_mode)
    except OSError:
        return False


def _refuse_shared_companions(out: Path) -> None:
    """Refuse an ``--out`` beside a log of the same name but for the case of ``.csv``:
    both logs would have one meta and one events file (a stranger's probe: a run to
    ``s.CSV`` replaced the meta of ``s.csv``, whose balance then read the other boiler)."""
    for other in same_companions(out):
        if other.is_file() and not (out.exists() and os.path.samefile(other, out)):
            raise UsageError(
                f"--out: '{out}' would share its meta and events files ('{meta_path(out).name}',"
                f" '{events_path(out).name}') with the log '{other}' beside it (the names differ"
                f" only in the case of .csv); give another --out, or move '{other.name}' away"
            )


def _busy_line(out: Path, busy: RunBusy) -> str:
    """The refusal of a run whose ``--out`` (or a name sharing its files) another run holds."""
    line = f"--out: '{out}' is being written by another run ({busy})"
    if busy.role == "keeping":
        line += f": it keeps the earlier run's files of its --out '{busy.out}' there"
    elif busy.out and os.path.realpath(busy.out) != os.path.realpath(out):
        line += (
            f": it writes '{busy.out}', whose meta and events files are this log's too (the"
            " names differ only in the case of .csv)"
        )
    return line + "; give another --out, or wait until that run ends"


def _cmd_run(args: argparse.Namespace) -> int:
    if args.out.is_symlink():  # the log is the file it names: written there, locked there
        args.out = Path(os.path.realpath(args.out))  # (the link was set aside and replaced
        # by a plain file, and a second run through it went unlocked: a re-probe)
    try:
        with contextlib.ExitStack() as held:  # the locks of --out and of the set-aside
            held.enter_context(run_lock(args.out))
            return _run(args, held)
    except RunBusy as busy:
        raise UsageError(_busy_line(args.out, busy)) from None


def _run(args: argparse.Namespace, held: contextlib.ExitStack) -> int:
    # validate everything before any file is written
    params = boiler_arg(args.boiler)
    with bad_input(ProtocolError):
        protocol = load_protocol(args.protocol)
    out: Path = args.out
    if out.suffix.lower() != ".csv":
        raise UsageError(f"--out: '{out}' must name a .csv file")
    if out.is_dir():
        raise UsageError(f"--out: '{out}' is a directory")
    for path in (out, meta_path(out), events_path(out)):  # (a FIFO was set aside as an
        if _not_a_file(path):  # earlier run's and deleted, its reader
            raise UsageError(  # getting nothing: a probe, and a re-probe at the meta file)
                f"--out: '{path}' is not a regular file; a lab log and its meta and events "
                "files are files"
            )
    _check_out_parent(out)
    refuse_overwriting(  # (a protocol saved as .csv was replaced by the log: a probe)
        out,
        {
            "the protocol file": _file_given(args.protocol),
            "the --boiler file": _file_given(args.boiler),
            "the --map file": _file_given(args.map),
        },
    )
    _refuse_shared_companions(out)
    if args.fault_report is not None and args.fault_journal is None:
        raise UsageError("--fault-report needs --fault-journal JOURNAL.jsonl")
    if args.fault_report is not None and args.rig == "local":
        raise UsageError("--fault-report needs a Modbus rig (faults act in the server)")
    if args.fault_report is not None:  # (it replaced the run's own log: a re-probe)
        refuse_overwriting(
            args.fault_report,
            _log_files(out)
            | {
                "the fault journal (--fault-journal)": args.fault_journal,
                "the protocol file": _file_given(args.protocol),
                "the --boiler file": _file_given(args.boiler),
                "the --map file": _file_given(args.map),
                "the --tls-cert file": _file_given(args.tls_cert),
                "the --tls-key file": _file_given(args.tls_key),
                "the --tls-ca file": _file_given(args.tls_ca),
            },
            "--fault-report",
        )
    register_map = _rig_map(args)
    # every setpoint the protocol writes for this boiler, against what the emulator (and
    # a Modbus rig's map) accepts: refused now, not after the log was begun
    limits = (
        {s: accepted_range(p) for s in WRITES for p in [register_map.point(s)[1]]}
        if register_map is not None
        else None
    )
    with bad_input(ProtocolError, prefix=f"{args.protocol}: "):
        check_setpoints(protocol, params.p_nom_kW, params.name, limits)
    previous = _EarlierRun(out, held)  # (its name chosen and locked: nothing moved yet)
    try:
        rig = _make_rig(args, params, register_map)
    except MapMismatch as exc:  # (exit 1, where another boiler was 2: a stranger's probe)
        raise UsageError(str(exc)) from None
    except RigError as exc:
        print(f"hil-client: error: {exc}", file=sys.stderr)
        return 1
    remote = isinstance(rig, ModbusRig)
    try:
        if isinstance(rig, ModbusRig) and rig.lockstep and register_map is not None:
            _check_advance(register_map, protocol.acquisition_period_s)
        # the files the run writes, each judged before any row (a meta file's name too
        # long was exit 1 after the run began: a stranger's probe)
        for written_file in (out, meta_path(out), events_path(out))[: 3 if remote else 2]:
            output_file(written_file)
        if args.fault_report is not None:  # (judged after the run: a re-probe)
            output_file(args.fault_report, "--fault-report")
    except UsageError:
        rig.close()
        raise

    meta = {
        "boiler": _boiler_recorded(params),
        "boiler_source": str(args.boiler),
        "test": protocol.test,
        "protocol": protocol.name,
        "rig": args.rig,
        "clock": _clock(rig) if remote else "offline",
        "profile": "set by the server" if remote else (args.profile or "clean"),
        # the server's, as it publishes it (null on a Modbus run: a stranger's probe)
        "seed": rig.identity["seed"] if remote else (args.seed or 0),
        # what the server publishes of its set-up (CONTRACT section 7)
        **(
            {
                f"server_{k}": f"{rig.identity[k]:08x}"
                # epoch_id: the first server's, as its fault journal writes it (a gap has a
                # restarted one's): the fault report compares a journal with its plant's rows
                for k in ("boiler_id", "profile_id", "epoch_id")
            }
            if remote
            else {}
        ),
        "acquisition_period_s": protocol.acquisition_period_s,
        **dict.fromkeys(("t0_s", "t1_s", "t2_s", "t3_s", "t4_s")),
        "complete": False,
        "notes": [],
        "gaps": [],
    }
    summary = RunSummary()
    expected = protocol.test_duration_s + protocol.cooling_2_until_after_t2_s + 2 * 3600
    if args.live:
        progress = LiveView(expected)
    elif not args.quiet and sys.stderr.isatty():
        progress = ProgressLine(expected)
    else:
        progress = None
    started = time.monotonic()
    # off a terminal (a CI log, docker compose) each phase mark is a line as it comes
    announce = progress is None and not args.quiet
    announced: set[str] = set()

    def save_meta(result: RunResult) -> None:
        # the marks as the log writes its times (1285.0, not 1285.0000000000364)
        meta.update({k: round(v, DECIMALS["time_s"]) for k, v in result.times.items()})
        if remote:  # the clock as it is now (another client may have changed its speed)
            meta["clock"] = _clock(rig)
            if len(rig.speeds) > 1:
                meta["clock_speeds"] = rig.speeds
        if announce:
            for key in result.times.keys() - announced:
                announced.add(key)
                wall = time.monotonic() - started
                mark = f"{key[:2]} at {hms(result.times[key])} simulated"
                print(f"hil-client: {mark}, {wall:.0f} s into the run", file=sys.stderr)
        meta["notes"] = result.notes
        meta["gaps"] = getattr(rig, "gaps", [])
        write_meta(out, meta)

    written = [0]  # rows of this run in the log
    events = None  # what faulty units did, beside the log
    finished = False  # the protocol ran to its end
    try:  # said on stderr (a killed run's partial log went without a word)
        previous.set_aside()
    except (UsageError, KeyboardInterrupt):  # (the earlier run's files are as they were)
        rig.close()
        raise
    try:
        events = EventsWriter(out) if remote else None
        with LabLogWriter(out) as writer:
            write_meta(out, meta)

            told = [0]  # breaks told on stderr
            notes_told = [0]  # the rig's notes (a unit read in pieces...) told on stderr
            switched_told = [False]  # the boiler switched against the run, told
            switch_seen = [0]  # the rig's events looked through for that

            def sink(row: tuple[object, ...]) -> None:
                with _signals_held():  # a row in the log is a row in the count
                    writer(row)
                    written[0] += 1
                gaps = getattr(rig, "gaps", ())
                if len(gaps) > told[0]:  # a break: said as it happens, not only at the end
                    for gap in gaps[told[0] : BREAKS_TOLD]:  # (two clients stepping one
                        print(f"hil-client: {_gap_line(gap)}", file=sys.stderr)  # server
                    if told[0] < BREAKS_TOLD <= len(gaps):  # made a line a step: a probe)
                        print(
                            f"hil-client: more than {BREAKS_TOLD} breaks: the rest are in the "
                            "meta file's gaps",
                            file=sys.stderr,
                        )
                    told[0] = len(gaps)
                rig_notes = getattr(rig, "notes", ())
                for note in rig_notes[notes_told[0] :]:  # said once, as it happens
                    print(f"hil-client: warning: {note}", file=sys.stderr)
                notes_told[0] = len(rig_notes)
                comm = getattr(rig, "comm_events", [])
                fresh, switch_seen[0] = comm[switch_seen[0] :], len(comm)
                # said as it happens, once (two clients fought over the burner for 155
                # rows in silence: a stranger's probe)
                changed = [e for e in fresh if e.get("event") == "overridden"]
                if not switched_told[0] and changed:
                    switched_told[0] = True
                    print(
                        f"hil-client: warning: {_overridden_what(changed)} against this run "
                        f"at time_s {row[0]:g} (another client, or a hand at the bench); its "
                        "command is written again each time, and the count comes at the end",
                        file=sys.stderr,
                    )
                summary(row)
                if events is not None:
                    events.catch_up(rig.comm_events)

            result = run_protocol(
                protocol, params.p_nom_kW, rig, sink, progress, on_phase=save_meta
            )
            finished = True
    except RigError as exc:
        if progress is not None:
            progress.done()
        kept = _what_is_kept(written[0], previous, getattr(rig, "gaps", []))
        ended = _end_notes(rig)  # (a unit silent for minutes before an outage went untold)
        for warning in ended:
            print(f"hil-client: warning: {warning}", file=sys.stderr)
        if written[0] and ended:
            meta["notes"] = [*meta["notes"], *ended]
            write_meta(out, meta)
        print(f"hil-client: error: {exc}; {kept}", file=sys.stderr)
        return 1
    except OSError as exc:  # the log's disk full, its file system gone read-only
        if progress is not None:
            progress.done()
        full = exc.errno in (errno.ENOSPC, errno.EDQUOT)  # (the kept log may be what filled it)
        kept = _what_is_kept(written[0], previous, getattr(rig, "gaps", []), disk_full=full)
        where = exc.filename or out
        print(
            f"hil-client: error: cannot write {where}: {exc.strerror or exc}; {kept}",
            file=sys.stderr,
        )
        with contextlib.suppress(OSError):  # the meta says why, where the disk lets it
            meta["notes"] = [*meta["notes"], f"stopped: cannot write {where} ({exc.strerror})"]
            write_meta(out, meta)
        return 1
    except CommandError as exc:  # a setpoint the rig refused (check_setpoints passed it)
        if progress is not None:
            progress.done()
        kept = _what_is_kept(written[0], previous, getattr(rig, "gaps", []))
        raise UsageError(f"{args.protocol}: commands {exc}; {kept}") from None
    except KeyboardInterrupt:  # Ctrl-C, SIGTERM or SIGHUP (see main)
        if progress is not None:
            progress.done()
        kept = _what_is_kept(written[0], previous, getattr(rig, "gaps", []))
        overridden = _overridden(getattr(rig, "comm_events", []))
        ended = [*filter(None, (overridden,)), *_end_notes(rig)]
        for warning in ended:  # (they came only at a run's end)
            print(f"hil-client: warning: {warning}", file=sys.stderr)
        if written[0]:  # the meta says why the run is not complete (it said nothing)
            meta["notes"] = [
                *meta["notes"],
                *getattr(rig, "notes", ()),
                *ended,
                f"interrupted (Ctrl-C, SIGTERM or SIGHUP) after {written[0]} rows",
            ]
            meta["interrupted"] = True
            # a second interrupt waits (Ctrl-C pressed twice; `timeout` signals the child
            # and its group: the meta file was left without its notes, a stranger's probe)
            with contextlib.suppress(KeyboardInterrupt), _signals_held():
                write_meta(out, meta)
        print(f"hil-client: interrupted; {kept}", file=sys.stderr)
        return 1
    finally:
        rig.close()
        if events is not None:
            events.catch_up(rig.comm_events)
            events.close()
        gaps = getattr(rig, "gaps", [])
        if not written[0] and gaps and not previous:  # the meta that stays says why
            meta["gaps"] = gaps
            write_meta(out, meta)
        if not finished:  # (one that finished replaces them once its meta says complete)
            _settle_previous(out, previous, written[0], gaps, completed=False)
    if progress is not None:
        progress.done()
    wall = time.monotonic() - started
    meta["complete"] = True
    if remote:
        meta["modbus_events"] = events_path(out).name
        meta["modbus_event_count"] = len(rig.comm_events)
        meta["server_time_offset_s"] = rig.server_time_offset_s
        refused = _refused_commands(rig.comm_events)
        if refused:  # the plant did not get them: the run is no test of this protocol
            result.notes.append(refused)
            print(f"hil-client: warning: {refused}", file=sys.stderr)
        overridden = _overridden(rig.comm_events)
        if overridden:
            result.notes.append(overridden)
            print(f"hil-client: warning: {overridden}", file=sys.stderr)
        result.notes.extend(rig.notes)  # (told on stderr as they came)
        for note in _end_notes(rig):  # (pinned readings are no value: their fields empty)
            result.notes.append(note)
            print(f"hil-client: warning: {note}", file=sys.stderr)
        absent = getattr(rig, "absent", ())
        if absent:  # a bench without that instrument (a run without an FID was refused)
            result.notes.append(f"the map has no point for {', '.join(absent)}: empty columns")
    if summary.empty_at_s is not None:  # the balance went on losing fuel it did not hold
        empty = (
            f"the balance read below 0 kg from time_s = {summary.empty_at_s:g}: the pellet"
            " store ran empty, and a real boiler would have gone out there (refill it with an"
            " offset fault on balance_mass_kg, or run shorter)"
        )
        result.notes.append(empty)
        print(f"hil-client: warning: {empty}", file=sys.stderr)
    median = summary.median_interval_s
    meta["sampling_median_s"] = None if median is None else round(median, DECIMALS["time_s"])
    slow = _slow_units(rig, len(summary.intervals_s), median) if remote else None
    coarse = _coarse_sampling(median, protocol.acquisition_period_s, meta, slow)
    if coarse:
        result.notes.append(coarse)
        print(f"hil-client: warning: {coarse}", file=sys.stderr)
    try:  # a signal after the meta says complete waits: the log replaces the earlier one
        with _signals_held():  # (the earlier log was kept, the run said "interrupted")
            save_meta(result)
            _settle_previous(out, previous, written[0], meta["gaps"], completed=True)
    except KeyboardInterrupt:
        print(
            f"hil-client: interrupted after the run completed; its log {out} and meta file "
            "are complete",
            file=sys.stderr,
        )
        return 1
    if args.fault_report is not None:
        with bad_input(ValueError, LogError, prefix="--fault-report: "):
            fault_rep = fault_report(out, args.fault_journal)
        for note in fault_rep["notes"]:
            print(f"hil-client: warning: {note}", file=sys.stderr)
        write_report(fault_rep, output_file(args.fault_report, "--fault-report"))
        if not args.quiet:
            print(fault_summary(fault_rep))
    if not args.quiet:
        times = "  ".join(f"{k[:2]}={v / 3600:.3f} h" for k, v in result.times.items())
        print(
            f"{protocol.name} on {params.name} ({args.rig}, {meta['profile']}): {result.rows} rows"
        )
        print(times)
        print(summary.table())
        for note in result.notes:
            print(f"note: {note}")
        for gap in meta["gaps"][:BREAKS_TOLD]:
            print(_gap_line(gap))
        if len(meta["gaps"]) > BREAKS_TOLD:
            print(f"{len(meta['gaps']) - BREAKS_TOLD} more breaks: see the meta file's gaps")
        print(
            f"simulated {result.duration_s / 3600:.2f} h in {wall:.2f} s "
            f"({result.duration_s / max(wall, 1e-9):,.0f} x real time)"
        )
        print(f"log: {out}\nmeta: {meta_path(out)}")
    return 0


_GAP_ACTIONS = {
    "replayed": "the run's commands were replayed on the new plant, the log goes on as one",
    "resumed": "resumed where it was",
    "reconnected": "reconnected",
    "restart-phase": "the phase starts again from the plant as it is",
    "continue": "the run goes on from the plant as it is",
    "abort": "stopped",
}


def _clock(rig: ModbusRig) -> str:
    """The meta file's ``clock``: the server's as it is now (``clock_speeds`` keeps every
    speed seen: another client changed x20 to x40, and the meta said x20: a re-probe)."""
    return "lockstep" if rig.lockstep else f"real time x{rig.speed:g}"


def _gap_line(gap: dict[str, Any]) -> str:
    """A break of the record as a sentence (the meta file's ``gaps`` entry); a change of
    the server's speed is no break: no row is missing, the plant is the same (it was told
    as "break ...; the run goes on from the plant as it is": a re-probe)."""
    start, end = gap.get("start_time_s"), gap.get("end_time_s")
    if "speed_after" in gap:
        where = "" if start is None else f" after time_s = {start:g} s"
        return (
            f"clock{where}: {gap.get('reason')}; the run goes on at the new speed, no row "
            "missed (the rows' spacing follows the speed)"
        )
    where = "before the first row" if start is None else f"after time_s = {start:g} s"
    if end is not None:
        where += f", rows again from {end:g} s"
    action = _GAP_ACTIONS.get(str(gap.get("action")), str(gap.get("action")))
    return f"break {where}: {gap.get('reason')}; {action} (rig_epoch {gap.get('rig_epoch')})"


#: Rows further apart than this many acquisition periods (median) are reported as coarse.
COARSE_SAMPLING = 1.2


def _coarse_sampling(
    median_s: float | None, period_s: float, meta: dict, slow: str | None = None
) -> str | None:
    """A note when the rows came much further apart in simulated time than the protocol's
    period: a real-time server running faster than the client reads (x1000: one row per
    100 s), so the log and its phase marks are that coarse, whatever the meta's period;
    ``slow`` (:func:`_slow_units`): the units whose timeouts made the rows that slow."""
    if median_s is None or median_s <= COARSE_SAMPLING * period_s:
        return None
    speeds = meta.get("clock_speeds")  # (x20, then x40 by another client: not "x20")
    clock = f"real time {', then '.join(f'x{s:g}' for s in speeds)}" if speeds else meta["clock"]
    head = f"rows came {median_s:g} s apart (median, simulated), not every {period_s:g} s: "
    if slow is not None:
        return (
            f"{head}each row waited for {slow}, while the server's clock ({clock}) ran on; "
            "the log and its phase marks are that coarse (a map without the unit (--map), "
            "a shorter --reply-timeout, a slower --speed or --lockstep keeps the period)"
        )
    return (
        f"{head}the server's clock ({clock}) ran faster than the client could read, or "
        "than its own tick (serve --tick-hz); the log and its phase marks are that coarse "
        "(a slower --speed, a faster tick or --lockstep keeps the period)"
    )


def _slow_units(rig: ModbusRig, rows: int, median_s: float | None) -> str | None:
    """The units that held most of the ``rows`` up (the events file's read ``timeout``s,
    and ``late`` replies), named with their signals and how often, where what they cost a
    row (the reply timeout, their late replies' waits; the median over the rows) came to
    at least half the wall
    time between rows (``median_s`` of simulated time at the server's speed): then they,
    not the server's clock, made the rows slow. Stranger's probes: an FID that never
    answered cost every row the 5-s reply timeout, rows came 50 s apart at x10, and the
    warning blamed the server's clock; a unit whose replies came 4.5 s late, just within
    the timeout, was blamed the same. Reads only: a write held behind another unit's slow
    replies times out with them, and its unit made no row slow (a re-probe: a delay fault
    on unit 1 named unit 7 too, "unit 7 (: no reply ...)", for its coil write queued
    behind). None if no unit did."""
    if median_s is None or not rows or rig.lockstep:
        return None
    held: dict[int, dict[float, float]] = {}  # unit -> row time -> what it cost the row [s]
    timed_out: dict[int, set[float]] = {}  # unit -> the rows its reads timed out on
    readings: dict[int, list[str]] = {}  # per unit (looked up once, not per event)
    for event in rig.comm_events:
        kind, unit = event.get("event"), event.get("unit")
        if unit not in readings:
            readings[unit] = rig.unit_signals(unit)
        if not readings[unit]:  # the simulation control's: the server's own pace
            continue
        if kind == "timeout" and event.get("function") in READ_FUNCTIONS:
            cost = rig.timeout_s
            timed_out.setdefault(unit, set()).add(event["time_s"])
        elif kind == "late":
            cost = float(event.get("wait_s", 0.0))
        else:
            continue
        rows_of = held.setdefault(unit, {})  # (a late write and a late read: both waited)
        rows_of[event["time_s"]] = rows_of.get(event["time_s"], 0.0) + cost
    slow = sorted(unit for unit, times in held.items() if 2 * len(times) > rows)
    costs = {unit: float(np.median(list(held[unit].values()))) for unit in slow}
    if not slow or sum(costs.values()) < 0.5 * median_s / rig.speed:
        return None
    said = []
    for unit in slow:
        signals = ", ".join(readings[unit])
        if 2 * len(timed_out.get(unit, ())) > rows:
            said.append(
                f"unit {unit} ({signals}: no reply within the reply timeout, "
                f"{rig.timeout_s:g} s, on {len(timed_out[unit])} of {rows} rows)"
            )
        else:
            said.append(
                f"unit {unit} ({signals}: replies {costs[unit]:.1f} s late a row (median) on "
                f"{len(held[unit])} of {rows} rows, within the reply timeout, "
                f"{rig.timeout_s:g} s)"
            )
    return " and ".join(said)


def _cmd_fault_report(args: argparse.Namespace) -> int:
    refuse_overwriting(
        args.out,
        _log_files(args.log)
        | {"the fault journal": args.journal, "the --map file": _file_given(args.map)},
    )
    with bad_input(MapError, prefix="--map: "):
        register_map = load_map(args.map)
    with bad_input(ValueError, LogError):
        rep = fault_report(args.log, args.journal, register_map=register_map)
    for note in rep["notes"]:
        print(f"hil-client: warning: {note}", file=sys.stderr)
    write_report(rep, output_file(args.out))
    print(fault_summary(rep))
    print(f"written: {args.out}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``hil-client``; returns the exit code."""
    commands = {
        "run": _cmd_run,
        "balance": _cmd_balance,
        "calibrate": _cmd_calibrate,
        "validate": _cmd_validate,
        "diagnose": _cmd_diagnose,
        "gap-benchmark": _cmd_gap_benchmark,
        "fault-report": _cmd_fault_report,
    }
    previous = _stop_on_signals()
    out = None
    try:
        try:
            args = _build_parser().parse_args(argv)
        except OSError as exc:  # --help's text
            return report_os_error(exc, "hil-client", "standard output")
        out = getattr(args, "out", None)
        with guarded_streams(), input_errors(), warnings.catch_warnings():
            # numpy's "mean of empty slice" on a column with no readings where a figure is
            # read: the figure is NaN and reported as missing, the warning says nothing more
            warnings.simplefilter("ignore", RuntimeWarning)
            return commands[args.command](args)
    except UsageError as exc:
        return report(exc, "hil-client")
    except OSError as exc:  # a write's error names no file: the output's, most likely
        return report_os_error(exc, "hil-client", f"writing {out}" if out else None)
    except KeyboardInterrupt:
        print("hil-client: interrupted", file=sys.stderr)
        return 1
    finally:
        release_outputs()
        _restore_signals(previous)


_STOPPING = (signal.SIGINT, signal.SIGTERM)
#: ... and SIGHUP (the terminal closed, an ssh session dropped) unless the command was
#: started ignoring it (nohup): it ended the run at once, rc 129, its meta saying nothing
#: (a probe)
_HANGUP = getattr(signal, "SIGHUP", None)


class _Held:
    """Whether :func:`_signals_held` is holding Ctrl-C and SIGTERM, and whether one came."""

    depth = 0
    pending = False


def _interrupt(signum: int, frame: Any) -> None:
    if _Held.depth:
        _Held.pending = True
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM that come in the block interrupt as it ends. Between writing a
    row and counting it, an interrupt made the meta file's count one row short of the log
    (a flaky CI run). Acts where :func:`_stop_on_signals` set the handlers."""
    _Held.depth += 1
    try:
        yield
    finally:
        _Held.depth -= 1
        if not _Held.depth and _Held.pending:
            _Held.pending = False
            raise KeyboardInterrupt


def _stop_on_signals() -> dict[int, Any]:
    """SIGTERM (timeout, a CI job cancelled, docker stop) ends a command as Ctrl-C does, so
    what it writes on the way out (a run's Modbus events, its meta file) is written; both
    raise KeyboardInterrupt, held inside :func:`_signals_held`. The handlers it replaces
    (None: one set from C), none off the main thread, where handlers cannot be set."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    stopping = list(_STOPPING)
    if _HANGUP is not None and signal.getsignal(_HANGUP) is not signal.SIG_IGN:
        stopping.append(_HANGUP)
    return {signum: signal.signal(signum, _interrupt) for signum in stopping}


def _restore_signals(previous: dict[int, Any]) -> None:
    for signum, handler in previous.items():  # one set from C cannot be put back: default
        signal.signal(signum, signal.SIG_DFL if handler is None else handler)


if __name__ == "__main__":
    sys.exit(main())
