"""``hil-client``: replay the paper's test methods on a rig and log every instrument.

Exit codes: 0 success, 2 bad usage or bad input (one line naming what is wrong), 1 any
other failure.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from hil_client.lablog import LabLogWriter, write_meta
from hil_client.progress import ProgressLine
from hil_client.protocol.definition import ProtocolError, load_protocol
from hil_client.protocol.runner import run_protocol
from hil_client.rigs.local import LocalRig
from hil_client.summary import RunSummary
from rig_emulator.boilers import load_boiler
from rig_emulator.cli_support import Parser, UsageError, report
from rig_emulator.instruments import ProfileError, load_profile
from rig_emulator.model.params import ParameterError


def _build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="hil-client", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    run = sub.add_parser(
        "run",
        help="play a test method on a rig and write the lab log",
        description="Play a test method (stationary, load_cycle or a PROTOCOL.yaml) on a rig "
        "and write the lab log (CSV) and its meta file.",
    )
    run.add_argument("protocol", help="stationary | load_cycle | PROTOCOL.yaml")
    run.add_argument("--boiler", required=True, help="boiler NAME or parameter file PATH")
    run.add_argument(
        "--rig", default="local", help="local (in-process) or modbus://HOST:PORT [local]"
    )
    run.add_argument("--profile", default="clean", help="instrument and plant profile [clean]")
    run.add_argument("--seed", type=int, default=0, help="random seed of the profile [0]")
    run.add_argument("--out", required=True, type=Path, help="lab log to write (CSV)")
    run.add_argument("--quiet", action="store_true", help="no progress line, no summary")
    return parser


def _cmd_run(args: argparse.Namespace) -> int:
    # validate everything before any file is written
    try:
        params = load_boiler(args.boiler)
    except ParameterError as exc:
        raise UsageError(str(exc)) from None
    try:
        protocol = load_protocol(args.protocol)
    except ProtocolError as exc:
        raise UsageError(str(exc)) from None
    if args.rig != "local":
        raise UsageError(f"--rig: unsupported rig '{args.rig}' (available: local)")
    try:
        profile = load_profile(args.profile)
    except ProfileError as exc:
        raise UsageError(f"--profile: {exc}") from None
    out: Path = args.out
    if out.suffix.lower() != ".csv":
        raise UsageError(f"--out: '{out}' must name a .csv file")
    if out.exists() and out.is_dir():
        raise UsageError(f"--out: '{out}' is a directory")

    rig = LocalRig(params, profile, seed=args.seed)
    summary = RunSummary()
    expected = protocol.test_duration_s + protocol.cooling_2_until_after_t2_s + 2 * 3600
    show = not args.quiet and sys.stderr.isatty()
    progress = ProgressLine(expected) if show else None
    started = time.monotonic()
    with LabLogWriter(out) as writer:

        def sink(row: tuple[object, ...]) -> None:
            writer(row)
            summary(row)

        result = run_protocol(protocol, params.p_nom_kW, rig, sink, progress)
    rig.close()
    if progress is not None:
        progress.done()
    wall = time.monotonic() - started
    meta = {
        "boiler": params.name,
        "boiler_source": str(args.boiler),
        "test": protocol.test,
        "protocol": protocol.name,
        "rig": args.rig,
        "profile": args.profile,
        "seed": args.seed,
        "acquisition_period_s": protocol.acquisition_period_s,
        **{key: result.times.get(key) for key in ("t0_s", "t1_s", "t2_s", "t3_s", "t4_s")},
        "notes": result.notes,
    }
    meta_file = write_meta(out, meta)
    if not args.quiet:
        times = "  ".join(f"{k[:2]}={v / 3600:.3f} h" for k, v in result.times.items())
        print(f"{protocol.name} on {params.name} ({args.rig}, {args.profile}): {result.rows} rows")
        print(times)
        print(summary.table())
        for note in result.notes:
            print(f"note: {note}")
        print(
            f"simulated {result.duration_s / 3600:.2f} h in {wall:.2f} s "
            f"({result.duration_s / max(wall, 1e-9):,.0f} x real time)"
        )
        print(f"log: {out}\nmeta: {meta_file}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``hil-client``; returns the exit code."""
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command == "run":
            return _cmd_run(args)
        raise UsageError(f"unknown command {args.command}")
    except UsageError as exc:
        return report(exc, "hil-client")
    except KeyboardInterrupt:
        print("hil-client: interrupted; the log keeps every row acquired", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
