"""The transport options of ``rig-emulator serve`` (CONTRACT section 6).

- ``--tls-cert CERT --tls-key KEY --tls-ca CA [--roles ROLES.yaml]``: ``--port`` (default
  802, Modbus/TCP Security's port) serves TLS with client certificates and roles instead of
  plain TCP; ``--tcp-port PORT`` adds a plain TCP listener beside it (on the same host).
  Without ``--roles`` the roles are the defaults derived from the served map's devices
  (:func:`~rig_emulator.modbus.roles.default_policy`); a ROLES.yaml's unit IDs are taken as
  written;
- ``--serial PATH|pty [--baud 19200] [--parity E|N|O]``: also serve the units on an RTU
  line; ``pty`` creates a pseudo-terminal and prints ``serial: /dev/pts/N`` on stdout;
- ``--plain-role ROLE``: hold plain TCP and RTU clients to a role too (default: they pass
  the role gate and meet only the server's own checks, among them ``--allow-control``).

Bad files and values are one line and exit 2 (:class:`UsageError`).
"""

from __future__ import annotations

import argparse
import logging
import ssl
from dataclasses import dataclass

from rig_emulator.certs import purpose_problem
from rig_emulator.cli_support import UsageError, int_in, text_file
from rig_emulator.modbus import BenchServer
from rig_emulator.modbus.roles import (
    DEFAULT_POLICY,
    RolePolicy,
    RolesError,
    default_policy,
    load_policy,
)
from rig_emulator.modbus.rtu import SerialConfigError, check_line_options
from rig_emulator.modbus.rtu_wire import PARITIES
from rig_emulator.modbus.tls import DEFAULT_TLS_PORT, TlsConfigError, server_context
from rig_emulator.modbus.transports import Transports
from rig_emulator.names import shown

PLAIN_PORT = 5020
log = logging.getLogger("rig_emulator.serve")


def add_arguments(serve: argparse.ArgumentParser) -> None:
    """Add the transport options to the ``serve`` parser."""
    tls = serve.add_argument_group("Modbus/TCP Security (TLS)")
    tls.add_argument("--tls-cert", default=None, help="server certificate (PEM)")
    tls.add_argument("--tls-key", default=None, help="its private key (PEM)")
    tls.add_argument("--tls-ca", default=None, help="CA certificate (PEM) of the clients")
    tls.add_argument(
        "--roles",
        default=None,
        type=text_file,
        help="ROLES.yaml redefining the roles [observer; operator writes the instruments; "
        "engineer also the simulation control: units from what the --map devices publish]",
    )
    tls.add_argument(
        "--tcp-port",
        type=int_in(0, 65535),
        default=None,
        help="with --tls-*: also serve plain TCP on this port (0: any free) [off]",
    )
    tls.add_argument(
        "--plain-role",
        default=None,
        help="hold plain TCP and RTU clients to this role [no role check]",
    )
    rtu = serve.add_argument_group("Modbus RTU")
    rtu.add_argument(
        "--serial",
        default=None,
        type=serial_line,
        metavar="PATH|pty",
        help="also serve RTU on this line [off]",
    )
    rtu.add_argument("--baud", type=int_in(50, 4_000_000), default=None, help="line speed [19200]")
    rtu.add_argument("--parity", default=None, type=str.upper, choices=PARITIES, help="parity [E]")


def serial_line(text: str) -> str:
    """An argparse ``type`` for ``--serial``: a device path or ``pty``, not empty (``--serial
    ""`` said "--serial : No such file or directory": a stranger's probe)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "the device name is empty; give the line's device (/dev/ttyUSB0) or pty"
        )
    return text


DEFAULT_BAUD = 19200
DEFAULT_PARITY = "E"  # the Modbus serial line guide's default


@dataclass(frozen=True)
class TransportPlan:
    """What the options ask for, checked before anything listens."""

    ssl_context: ssl.SSLContext | None
    policy: RolePolicy | None  # None: the default roles of the served map (see start)
    port: int
    tcp_port: int | None
    plain_role: str | None
    serial: str | None
    baud: int
    parity: str
    #: what is wrong with the server certificate though it loads (logged at start)
    certificate_warnings: tuple[str, ...] = ()


def plan(args: argparse.Namespace) -> TransportPlan:
    """Check the transport options (files included); UsageError naming the fault."""
    files = {"--tls-cert": args.tls_cert, "--tls-key": args.tls_key, "--tls-ca": args.tls_ca}
    given = [k for k, v in files.items() if v]
    context = None
    warnings: tuple[str, ...] = ()
    if given:
        missing = [k for k, v in files.items() if not v]
        if missing:
            raise UsageError(f"{given[0]} needs {', '.join(missing)} too")
        try:
            context = server_context(args.tls_cert, args.tls_key, args.tls_ca)
        except TlsConfigError as exc:
            raise UsageError(str(exc)) from None
        if problem := purpose_problem(args.tls_cert, server=True):
            warnings = (f"warning: --tls-cert {args.tls_cert} {problem}: clients refuse it",)
    elif args.tcp_port is not None:
        raise UsageError("--tcp-port goes with --tls-* (without TLS, --port is plain TCP)")
    if args.roles is not None and context is None and args.plain_role is None:
        raise UsageError("--roles needs --tls-* or --plain-role")
    try:
        policy = load_policy(args.roles) if args.roles is not None else None
    except RolesError as exc:
        raise UsageError(f"--roles: {exc}") from None
    names = (policy or DEFAULT_POLICY).roles  # the default roles' names are every map's
    if args.plain_role is not None and args.plain_role not in names:
        raise UsageError(f"--plain-role: '{args.plain_role}' is not one of {', '.join(names)}")
    if args.serial is None and (args.baud is not None or args.parity is not None):
        given = "--baud" if args.baud is not None else "--parity"
        raise UsageError(f"{given} sets the RTU line: it needs --serial PATH|pty")
    args.baud = DEFAULT_BAUD if args.baud is None else args.baud
    args.parity = DEFAULT_PARITY if args.parity is None else args.parity
    if args.serial is not None:
        try:
            check_line_options(args.baud, args.parity)
        except SerialConfigError as exc:
            raise UsageError(str(exc)) from None
    port = args.port if args.port is not None else (DEFAULT_TLS_PORT if context else PLAIN_PORT)
    return TransportPlan(
        context,
        policy,
        port,
        args.tcp_port,
        args.plain_role,
        args.serial,
        args.baud,
        args.parity,
        warnings,
    )


def who_has_which_role(transport_plan: TransportPlan, default_role: str) -> str:
    """Whose requests the roles judge on this server, for the start-up summary: TLS clients
    by their certificate's role (``default_role`` without one), plain TCP and RTU clients by
    ``--plain-role`` or by none. With ``--plain-role`` and no TLS, the summary spoke only of
    certificates, which that server has none of (a stranger's probe)."""
    p = transport_plan
    said: list[str] = []
    if p.ssl_context is not None:
        said.append(f"a certificate without a role is {shown(default_role)}")
    plain_tcp = p.ssl_context is None or p.tcp_port is not None  # without TLS, --port is plain
    plain = " and ".join(
        kind for kind, served in (("plain TCP", plain_tcp), ("RTU", p.serial is not None)) if served
    )
    if plain and p.plain_role is not None:
        said.append(f"{plain} clients are held to {shown(p.plain_role)}")
    elif plain:
        said.append(f"{plain} clients carry no role and pass the role gate")
    elif p.plain_role is not None:
        said.append(f"--plain-role {shown(p.plain_role)} holds nobody (no plain TCP or RTU here)")
    return "; ".join(said)


async def start(server: BenchServer, transport_plan: TransportPlan) -> Transports:
    """Add the planned listeners, role gate and lines to the started ``server``; without a
    ROLES.yaml, the roles are the defaults of the map it serves (they were those of the
    shipped map's unit IDs, whatever devices a ``--map`` put there: a stranger's probe).
    What they are is said by :func:`announce`, once every listener of the server is up; a
    listener that cannot start closes those this opened and is one :class:`UsageError`."""
    modbus = server.modbus_server
    assert modbus is not None
    transports = Transports(modbus)
    p = transport_plan
    for warning in p.certificate_warnings:  # as serve warns of an expired one
        log.warning("%s", warning)
    if p.ssl_context is not None or p.plain_role is not None:
        transports.authorise(_policy(server, p), p.plain_role)
    try:
        if p.tcp_port is not None:
            await transports.add_tcp(server.host, p.tcp_port)
    except OSError as exc:  # (asyncio's strerror names the address again: its end is why)
        await transports.stop()
        why = exc.strerror.split(": ")[-1] if exc.strerror else str(exc)
        raise UsageError(
            f"--tcp-port: cannot serve plain TCP on {server.host}:{p.tcp_port}: {why}"
        ) from None
    try:
        if p.serial is not None:
            await transports.add_rtu(p.serial, p.baud, p.parity)
    except SerialConfigError as exc:
        await transports.stop()
        raise UsageError(str(exc)) from None
    except OSError as exc:  # (no pty left, say: the line's, not the TCP port's)
        await transports.stop()
        raise UsageError(f"--serial {p.serial}: {exc.strerror or exc}") from None
    return transports


def announce(server: BenchServer, transport_plan: TransportPlan, transports: Transports) -> None:
    """Say what :func:`start` opened: the roles and whom they judge, the TLS port, the plain
    TCP port, and the serial line (``serial: PATH`` on stdout, the line a client of
    ``--serial pty`` waits for). Called with the "serving" line, once every listener of
    the server is up: said as each opened, they announced a server that a later listener's
    failure (a busy ``--http`` port) then ended with exit 2 (a stranger's probe)."""
    p = transport_plan
    if transports.authorisation is not None:
        policy = transports.authorisation.policy
        log.info(
            "roles%s: %s; %s",
            "" if p.policy is not None else " (defaults of the map's devices)",
            policy.summary(),
            who_has_which_role(p, policy.default_role),
        )
    if p.ssl_context is not None:
        log.info(
            "Modbus/TCP Security on %s:%d (TLS 1.2+, client certificates of --tls-ca)",
            server.host,
            server.port,
        )
    for listener in transports.listeners:
        host, port = listener.sockets[0].getsockname()[:2]
        log.info("plain Modbus TCP also on %s:%d", host, port)
    for line in transports.lines:
        print(f"serial: {line.path}", flush=True)
        log.info(
            "Modbus RTU on %s (%s; units %s)",
            line.path,
            line.settings,
            ", ".join(str(u) for u in sorted(transports.server.units)),
        )


def _policy(server: BenchServer, transport_plan: TransportPlan) -> RolePolicy:
    """The roles of ``--roles``, else the defaults of the map ``server`` serves."""
    if transport_plan.policy is not None:
        return transport_plan.policy
    return default_policy(server.map)
