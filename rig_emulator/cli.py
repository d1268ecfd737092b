"""``rig-emulator``: the pellet-boiler test-bench emulator.

Exit codes: 0 success, 2 bad usage or bad input (one line naming what is wrong), 1 any
other failure.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import ipaddress
import logging
import math
import os
import re
import signal
import sys
from collections.abc import Sequence
from pathlib import Path

from rig_emulator import cli_transports as transport_options
from rig_emulator.atomic import write_atomically
from rig_emulator.boilers import resolve as resolve_boiler
from rig_emulator.certs import make_lab_certificates, validity_problem
from rig_emulator.cli_support import (
    Parser,
    UsageError,
    bad_input,
    boiler_arg,
    finite_float,
    guarded_streams,
    input_errors,
    int_in,
    listen_host,
    output_file,
    path_arg,
    refuse_overwriting,
    release_outputs,
    report,
    report_os_error,
    text_file,
    text_input,
)
from rig_emulator.dashboard import Dashboard
from rig_emulator.emulator import CommandError, Emulator, check_command
from rig_emulator.faults import FaultError, check_spikes, check_units, load_faults
from rig_emulator.faults.journal import check_writable as check_journal_writable
from rig_emulator.instruments import ProfileError, load_profile
from rig_emulator.instruments.profile import PROFILE_DIR
from rig_emulator.modbus import BenchServer
from rig_emulator.modbus.fault_control import reading_ranges
from rig_emulator.modbus.transports import Transports
from rig_emulator.model import pack_constants, steady_state
from rig_emulator.registers import MapError, RegisterMap, emulator_units, load_map
from rig_emulator.registers.codec import carries_between
from rig_emulator.registers.reference import markdown
from rig_emulator.signals import MEASURED, SIGNALS
from rig_emulator.yamlio import resolve_named


def _build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="rig-emulator", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    serve = sub.add_parser(
        "serve",
        help="run the emulated bench as a Modbus TCP server",
        description="Run the emulated bench as a Modbus TCP server (one unit ID per "
        "instrument, see the register map reference). Stops cleanly on SIGINT, SIGTERM "
        "or SIGHUP.",
    )
    serve.add_argument(
        "--boiler", required=True, type=text_input, help="boiler NAME or parameter file PATH"
    )
    serve.add_argument(
        "--map",
        default=None,
        type=text_input,
        help="register map YAML [register_maps/wieselburg_bench.yaml]",
    )
    serve.add_argument(
        "--host", type=listen_host, default="127.0.0.1", help="address to listen on [127.0.0.1]"
    )
    serve.add_argument(
        "--port",
        type=int_in(0, 65535),
        default=None,
        help="TCP port (0: any free) [5020; 802 with --tls-*]",
    )
    pace = serve.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed",
        type=finite_float(SIGNALS["speed_factor"].minimum, SIGNALS["speed_factor"].maximum),
        default=1.0,
        help="simulated seconds per wall second [1 = real time]",
    )
    pace.add_argument(
        "--lockstep",
        action="store_true",
        help="time moves only when a client writes lockstep_advance",
    )
    serve.add_argument(
        "--profile", default="clean", type=text_input, help="clean | lab | PROFILE.yaml [clean]"
    )
    serve.add_argument(
        "--seed", type=int_in(0, 2**32 - 1), default=0, help="seed of instrument errors [0]"
    )
    serve.add_argument(
        "--tick-hz", type=finite_float(0.1, 1000.0, "Hz"), default=10.0, help="tick rate [10]"
    )
    serve.add_argument(
        "--http",
        type=int,
        default=None,
        metavar="PORT",
        help="also serve a live dashboard on this port, same host (0: any free) [off]",
    )
    serve.add_argument(
        "--http-control",
        action="store_true",
        help="let the dashboard write setpoints, boiler on/off and speed (through the "
        "Modbus write checks) [off]",
    )
    serve.add_argument(
        "--allow-control",
        action="store_true",
        help="let clients change speed/clock mode, reset or advance a real-time server",
    )
    serve.add_argument(
        "--faults",
        default=None,
        type=text_file,
        metavar="FAULTS.yaml",
        help="faults to inject, scheduled in simulated time (CONTRACT section 5) [none]",
    )
    serve.add_argument(
        "--fault-log",
        default=None,
        type=path_arg,
        metavar="JOURNAL.jsonl",
        help="write one JSON line per fault start and end; missing directories are "
        "created, a FIFO needs its reader running [none]",
    )
    serve.add_argument(
        "--idle-timeout",
        type=finite_float(0.0, 1e7, "s"),
        default=300.0,
        metavar="SECONDS",
        help="close client connections that sent no whole request this long, or stalled in "
        "a TLS handshake (0: never) [300]",
    )
    serve.add_argument(
        "--max-connections",
        type=int_in(1, 100_000),
        default=100,
        metavar="N",
        help="client connections open at once; a new one beyond closes the oldest unused "
        "one (all busy: the new one), logged; at most what the process's open-file limit "
        "holds (said at start) [100]",
    )
    certs = sub.add_parser(
        "certs",
        help="make a CA, a server certificate and client certificates per role (TLS)",
        description="Write ca, server (127.0.0.1, localhost), observer, operator, engineer "
        "and norole (no role extension) certificates (.pem) and keys (.key) into DIR, for "
        "Modbus/TCP Security tests and demos.",
    )
    certs.add_argument("--out", required=True, type=path_arg, help="directory to write")
    certs.add_argument(
        "--server-name",
        action="append",
        default=[],
        metavar="NAME",
        help="another host name or IP of the server certificate (repeatable) "
        "[127.0.0.1, localhost]",
    )
    transport_options.add_arguments(serve)
    doc = sub.add_parser("map-doc", help="write the Markdown reference of a register map")
    doc.add_argument(
        "--map", default=None, type=text_input, help="register map YAML [the shipped one]"
    )
    doc.add_argument(
        "--out", default=None, help="file to write, missing directories created [stdout]"
    )
    check = sub.add_parser("check", help="validate a boiler parameter file and print it")
    check.add_argument(
        "--boiler", required=True, type=text_input, help="boiler NAME or parameter file PATH"
    )
    steady = sub.add_parser(
        "steady",
        help="closed-form steady state at a load (energy split of Eq. 1-10)",
        description="Print the steady operating point of the one-node model at a load.",
    )
    steady.add_argument(
        "--boiler", required=True, type=text_input, help="boiler NAME or parameter file PATH"
    )
    steady.add_argument(
        "--load",
        type=finite_float(0.0, 150.0, "%"),
        default=100.0,
        help="load [%% of nominal] [100]",
    )
    # the ranges of the bench: its return conditioning (10-90 C) and a boiler room
    steady.add_argument(
        "--return-temp", type=finite_float(10.0, 90.0, "C"), default=55.0, help="return [C] [55]"
    )
    steady.add_argument(
        "--room-temp", type=finite_float(-30.0, 50.0, "C"), default=22.0, help="room [C] [22]"
    )
    return parser


def _cmd_check(args: argparse.Namespace) -> int:
    params = boiler_arg(args.boiler)
    for key, value in params.to_mapping().items():
        print(f"{key}: {value}")
    return 0


def _cmd_steady(args: argparse.Namespace) -> int:
    params = boiler_arg(args.boiler)
    if not args.load > 0.0:
        raise UsageError(f"--load: must be above 0 % (no flow, no steady state), got {args.load}")
    flow = args.load / 100.0 * params.nominal_flow_kg_h
    try:
        ss = steady_state(pack_constants(params), flow, args.return_temp, args.room_temp)
    except ValueError as exc:  # the root finder found no operating point
        raise UsageError(f"no steady state at these inputs ({exc})") from None
    figures = (ss.t_boiler_C, ss.t_flue_gas_C, ss.q_fuel_kW, ss.q_water_kW, ss.q_amb_kW)
    if not all(math.isfinite(x) for x in figures) or ss.q_fuel_kW <= 0:
        raise UsageError("no finite steady state at these inputs")
    if ss.t_boiler_C >= params.shutoff_temp_C:
        raise UsageError(
            f"no steady state at {args.load:g} % load and return {args.return_temp:g} C: even at "
            f"Pmin ({params.p_min_kW:g} kW) the water would settle at {ss.t_boiler_C:.0f} C, "
            f"above the shut-off temperature ({params.shutoff_temp_C:g} C); the burner cycles"
        )
    share = 100.0 / ss.q_fuel_kW
    print(f"{params.name} at {args.load:g} % load ({flow:.1f} kg/h, return {args.return_temp} C)")
    print(f"  T_boiler   {ss.t_boiler_C:8.2f} C     T_flue_gas {ss.t_flue_gas_C:8.2f} C")
    print(f"  firing     {ss.firing_kW:8.3f} kW    fuel (dry) {ss.fuel_dry_kg_h:8.3f} kg/h")
    print(f"  Q_fuel     {ss.q_fuel_kW:8.3f} kW    100.0 %")
    print(f"  Q_water    {ss.q_water_kW:8.3f} kW    {ss.q_water_kW * share:5.1f} %")
    print(f"  Q_fluegas  {ss.q_flue_gas_kW:8.3f} kW    {ss.q_flue_gas_kW * share:5.1f} %")
    print(f"  Q_amb      {ss.q_amb_kW:8.3f} kW    {ss.q_amb_kW * share:5.1f} %")
    set_c = params.set_temp_C
    if ss.firing_kW >= params.p_max_kW and ss.t_boiler_C < set_c - 0.01:
        print(f"  note: the burner is at Pmax; the water stays below its set point ({set_c:g} C)")
    elif ss.firing_kW <= params.p_min_kW and ss.t_boiler_C > set_c + 0.01:
        print(f"  note: the burner is at Pmin; the water settles above its set point ({set_c:g} C)")
    return 0


def _cmd_certs(args: argparse.Namespace) -> int:
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out: '{args.out}' is a file, not a directory")
    for name in args.server_name:
        if not _host_name_or_address(name):
            raise UsageError(f"--server-name: '{name}' is not a host name or IP address")
    held = sorted(  # (a link counts, a dangling one too: the CA was written through it)
        p.name for p in (args.out / "ca.pem", args.out / "ca.key") if os.path.lexists(p)
    )
    if held:  # a new CA would leave every certificate issued from the old one refused
        raise UsageError(  # (it was replaced without a word: a stranger's probe)
            f"--out: '{args.out}' already holds a CA ({', '.join(held)}); certificates it "
            "issued would stop working with a new one: name another directory, or move "
            "them away first"
        )
    existed = args.out.is_dir()
    before = set(args.out.iterdir()) if existed else set()
    try:
        written = make_lab_certificates(args.out, server_names=tuple(args.server_name))
    except OSError as exc:  # a full disk, a read-only file system: nothing half-made stays
        if args.out.is_dir():  # (an empty ca.pem refused every retry: a re-probe)
            for path in set(args.out.iterdir()) - before:
                with contextlib.suppress(OSError):
                    path.unlink()
            if not existed:
                with contextlib.suppress(OSError):
                    args.out.rmdir()
        raise OSError(exc.errno, exc.strerror, str(args.out)) from None
    for path in written:
        print(f"written: {path} (key {path.with_suffix('.key')})")
    return 0


def _host_name_or_address(name: str) -> bool:
    """An IPv4 or IPv6 address, or a DNS host name (RFC 1123: labels of 1-63 letters,
    digits and hyphens, not starting or ending with one, 253 characters at most; an
    all-numeric name such as 999.1.1.1 is a bad address, not a name)."""
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        pass
    labels = name.rstrip(".").split(".")
    if not name or len(name) > 253 or all(label.isdigit() for label in labels):
        return False
    return all(_HOST_LABEL.fullmatch(label) for label in labels)


_HOST_LABEL = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?")


def _cmd_map_doc(args: argparse.Namespace) -> int:
    with bad_input(MapError):
        register_map = load_map(args.map)
        text = markdown(register_map)
    if args.out is not None:
        if not args.out.strip():
            raise UsageError("--out: empty (a file to write; leave --out out for stdout)")
        out = Path(args.out)  # (the shipped map was replaced without --map: a re-probe)
        refuse_overwriting(out, {"the register map (--map)": Path(register_map.source)})
        write_atomically(output_file(out), text)
    else:
        sys.stdout.write(text)
    return 0


def _warn_unpublished(register_map: RegisterMap) -> None:
    """A warning naming the measured signals ``register_map`` publishes nowhere: a client
    reading them by the shipped map gets exception 02 or, where another point sits at
    their address, that point's value (a map whose humidity point was given the flow's
    signal served the flow as humidity; a stranger's probe)."""
    published = {p.signal for d in register_map.devices for p in d.points}
    missing = [s for s in MEASURED if s not in published]
    if missing:
        logging.warning(
            "warning: %s publishes no point for %s: a client reading %s by another map gets "
            "exception 02, or the value of a point at that address",
            register_map.source,
            ", ".join(missing),
            "it" if len(missing) == 1 else "them",
        )


def _cmd_serve(args: argparse.Namespace) -> int:
    params = boiler_arg(args.boiler)
    with bad_input(MapError, ProfileError):
        register_map = load_map(args.map)
        profile = load_profile(args.profile)
    with bad_input(CommandError, prefix="--speed: "):
        check_command("speed_factor", args.speed)
    with bad_input(FaultError, prefix="--faults: "):
        faults = load_faults(args.faults) if args.faults is not None else []
        units = {d.unit_id for d in register_map.devices}
        check_units(faults, units, f"{args.faults}: faults", emulator_units(register_map))
        check_spikes(faults, reading_ranges(register_map), f"{args.faults}: faults")
    with bad_input(FaultError, prefix="--profile: "):
        check_units(profile.faults, units, f"{args.profile}: faults", emulator_units(register_map))
        check_spikes(profile.faults, reading_ranges(register_map), f"{args.profile}: faults")
    if args.fault_log is not None:
        output_file(args.fault_log, "--fault-log")  # (before any port: a FIFO unread)
        named = {  # (the journal replaced the fault, boiler, map or key file: probes)
            "the --faults file": args.faults,
            "the boiler file (--boiler)": resolve_boiler(args.boiler),
            "the register map (--map)": register_map.source,
            "the profile file (--profile)": resolve_named(
                args.profile, PROFILE_DIR, "profile", ProfileError
            ),
            "the --roles file": getattr(args, "roles", None),
            "the --tls-cert file": getattr(args, "tls_cert", None),
            "the --tls-key file": getattr(args, "tls_key", None),
            "the --tls-ca file": getattr(args, "tls_ca", None),
        }
        refuse_overwriting(
            args.fault_log,
            {what: Path(v) for what, v in named.items() if v is not None},
            "--fault-log",
        )
        try:  # (it was a warning, and a whole session served without a journal: a probe)
            check_journal_writable(args.fault_log)
        except OSError as exc:
            why = exc.strerror or str(exc)
            raise UsageError(f"--fault-log: cannot write '{args.fault_log}' ({why})") from None
    advances = [
        p for d in register_map.devices for p in d.points if p.signal == "lockstep_advance_s"
    ]
    # (a plant that could never move: a stranger's probe; read-only, or no positive step
    # its encoding carries: served all the same, re-probes)
    if args.lockstep and not any(
        p.writable and carries_between(p, 1e-9, math.inf) for p in advances
    ):
        why = "is read-only or carries no positive step" if advances else "has no point for it"
        raise UsageError(
            f"--lockstep: the map {register_map.source}'s lockstep_advance_s {why}, so "
            "nothing could advance this server"
        )
    if args.http is not None and not 0 <= args.http <= 65535:
        raise UsageError(f"--http: {args.http} is not a TCP port")
    if args.http and args.http == args.port:  # (it said "serving", then failed: a probe)
        raise UsageError(f"--http: port {args.http} is the Modbus port (--port) too")
    if args.http_control and args.http is None:
        raise UsageError("--http-control needs --http PORT")
    args.transport_plan = transport_options.plan(args)
    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s rig-emulator: %(message)s", stream=sys.stderr
    )
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    _warn_unpublished(register_map)
    if args.tls_cert is not None and (problem := validity_problem(args.tls_cert)):
        logging.warning("warning: --tls-cert %s %s: clients refuse it", args.tls_cert, problem)
    emulator = Emulator(params, profile, seed=args.seed)
    server = BenchServer(
        emulator,
        register_map,
        args.host,
        args.transport_plan.port,
        args.speed,
        args.lockstep,
        args.tick_hz,
        allow_control=args.allow_control,
        faults=faults,
        fault_log=args.fault_log,
        idle_timeout_s=args.idle_timeout,
        max_connections=args.max_connections,
        ssl_context=args.transport_plan.ssl_context,
        dashboard=args.http is not None,  # (its connections' share of the descriptors)
    )
    try:
        asyncio.run(_serve(server, args))
    except OSError as exc:  # busy port, address not local, no permission: bad input
        if exc.strerror is None:
            raise UsageError(str(exc)) from None
        if "attempting to bind" in str(exc):  # asyncio names the address: the HTTP port's
            option = "--http: " if args.http is not None and f", {args.http})" in str(exc) else ""
            why = exc.strerror.split(": ")[-1] if exc.strerror else str(exc)
            raise UsageError(f"{option}cannot serve on {args.host}:{args.http}: {why}") from None
        raise UsageError(
            f"cannot serve on {args.host}:{args.transport_plan.port}: {exc.strerror}"
        ) from None
    # lines of the fault journal lost (a full disk; its warning said how many): exit 1, as
    # for any OS failure (it exited 0, the loss silent in CI: a stranger's probe)
    return 1 if server.faults.journal_lines_lost else 0


def _stop_signals() -> list[int]:
    """SIGINT, SIGTERM and SIGHUP (the terminal closed: it ended the server at once, with
    no clean stop: a probe), SIGHUP not where the server was started ignoring it (nohup)."""
    stopping = [signal.SIGINT, signal.SIGTERM]
    hangup = getattr(signal, "SIGHUP", None)
    if hangup is not None and signal.getsignal(hangup) is not signal.SIG_IGN:
        stopping.append(hangup)
    return stopping


async def _start_listeners(
    server: BenchServer, args: argparse.Namespace
) -> tuple[Transports, Dashboard | None]:
    """Open the listeners beside the started ``server``'s own port: the plain TCP port and
    serial line of the transport options, then the dashboard's HTTP port. All of them are up
    before the "serving" line, the one readiness signal scripts and the pytest plugin have
    (and the port ``--port 0`` chose): it was logged before the HTTP port was tried, so a
    busy ``--http`` port said "serving", then exited 2 (a stranger's probe). One that cannot
    open closes those already open and the server; its error is serve's one line, exit 2."""
    transports = None
    try:
        transports = await transport_options.start(server, args.transport_plan)
        if args.http is None:
            return transports, None
        dashboard = Dashboard(server, server.host, args.http, control=args.http_control)
        await dashboard.start()
    except (UsageError, OSError):
        if transports is not None:
            await transports.stop()
        await server.stop()
        raise
    return transports, dashboard


async def _serve(server: BenchServer, args: argparse.Namespace) -> None:
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in _stop_signals():
        loop.add_signal_handler(sig, stop.set)
    await server.start(begin_journal=False)  # (begun once every port is open: a re-probe)
    transports, dashboard = await _start_listeners(server, args)
    # every listener is up: what each serves, then "serving", the line scripts wait for
    transport_options.announce(server, args.transport_plan, transports)
    if dashboard is not None:
        logging.getLogger("rig_emulator.serve").info(
            "dashboard on http://%s:%d/ (controls %s)",
            server.host,
            dashboard.port,
            "on" if args.http_control else "off",
        )
    pace = "lockstep" if args.lockstep else f"real time x{args.speed:g}"
    units = ", ".join(f"{d.unit_id}={d.name}" for d in server.map.devices)
    logging.getLogger("rig_emulator.serve").info(
        "serving %s on %s:%d (%s, profile %s, seed %d); units %s",
        server.emulator.params.name,
        server.host,
        server.port,
        pace,
        args.profile,
        args.seed,
        units,
    )
    server.faults.begin_journal()
    await stop.wait()
    # the stop is under way: a second Ctrl-C or SIGTERM (GNU timeout signals the group
    # again) interrupted the shutdown's own clean-up, with a traceback ("Exception ignored
    # in atexit callback"; a re-probe); from here on they are ignored
    for sig in _stop_signals():
        loop.remove_signal_handler(sig)
        signal.signal(sig, signal.SIG_IGN)
    logging.getLogger("rig_emulator.serve").info(
        "stopping at simulated time %.1f s", server.emulator.sim_time_s
    )
    if dashboard is not None:
        await dashboard.stop()
    await transports.stop()
    await server.stop()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``rig-emulator``; returns the exit code."""
    out = None
    try:
        try:
            args = _build_parser().parse_args(argv)
        except OSError as exc:  # --help's text
            return report_os_error(exc, "rig-emulator", "standard output")
        out = getattr(args, "out", None)
        commands = {
            "check": _cmd_check,
            "steady": _cmd_steady,
            "serve": _cmd_serve,
            "map-doc": _cmd_map_doc,
            "certs": _cmd_certs,
        }
        with guarded_streams(), input_errors():
            return commands[args.command](args)
    except UsageError as exc:
        return report(exc, "rig-emulator")
    except OSError as exc:  # a write's error names no file: --out's, or standard output
        return report_os_error(exc, "rig-emulator", f"writing {out}" if out else None)
    except KeyboardInterrupt:  # serve stops on its own; the other commands end here
        print("rig-emulator: interrupted", file=sys.stderr)
        return 1
    finally:
        release_outputs()


if __name__ == "__main__":
    sys.exit(main())
