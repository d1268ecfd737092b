"""Modbus/TCP Security: TLS with mutual authentication and role-based authorisation.

The TLS side (Modbus/TCP Security Protocol Specification): TLS 1.2 or newer, the client
must present a certificate signed by the configured CA (else the handshake fails), and
the client's role is the certificate's extension 1.3.6.1.4.1.50316.802.1 (an ASN.1
UTF8String); without that extension the policy's default role applies
(:mod:`rig_emulator.modbus.roles`).

The authorisation side is a gate of :class:`~rig_emulator.modbus.handler.BenchModbusServer`,
first in its ``gates``: a request the connection's role may not send is answered with
exception 01 (illegal function) before it reaches any datastore, so it changes nothing.
Each refusal is logged with the client certificate's subject, once per connection and
reason and at most :attr:`RefusalLog.burst` lines a minute (a flood does not flood the log);
roles and subjects are shown as :func:`~rig_emulator.names.shown` writes them.

Plain TCP and RTU requests carry no role (``RequestInfo.role`` is None) and pass this gate,
unless ``plain_role`` names a role for them.
"""

from __future__ import annotations

import logging
import ssl
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.exceptions import UnsupportedAlgorithm
from cryptography.hazmat.primitives import serialization

from rig_emulator.certs import role_of
from rig_emulator.modbus.handler import (
    BenchModbusServer,
    GateDecision,
    RequestHandler,
    RequestInfo,
)
from rig_emulator.modbus.roles import (
    DEFAULT_POLICY,
    INVALID_ROLE,
    RefusalLog,
    RolePolicy,
)
from rig_emulator.names import shown

log = logging.getLogger("rig_emulator.serve")

DEFAULT_TLS_PORT = 802  # Modbus/TCP Security's registered port
ILLEGAL_FUNCTION = 1


class TlsConfigError(ValueError):
    """Certificate, key or CA files that cannot be used (the message names the file)."""


def server_context(cert: str | Path, key: str | Path, ca: str | Path) -> ssl.SSLContext:
    """A server ``SSLContext``: TLS 1.2 or newer, client certificates required and verified
    against ``ca``."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    ctx.verify_mode = ssl.CERT_REQUIRED
    _load(ctx, cert, key, ca)
    return ctx


def client_context(cert: str | Path, key: str | Path, ca: str | Path) -> ssl.SSLContext:
    """A client ``SSLContext`` for a Modbus/TCP Security server: TLS 1.2 or newer, the
    server verified against ``ca`` (its name too), ``cert``/``key`` presented."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    _load(ctx, cert, key, ca)
    return ctx


def _load(ctx: ssl.SSLContext, cert: str | Path, key: str | Path, ca: str | Path) -> None:
    for name, path in (("certificate", cert), ("key", key), ("CA", ca)):
        problem = pem_file_problem(path)
        if problem:
            raise TlsConfigError(f"TLS {name} {path}: {problem}")
    try:
        ctx.load_cert_chain(str(cert), str(key), password=_no_passphrase(key))
    except TlsConfigError:
        raise
    except (ssl.SSLError, ValueError) as exc:
        raise TlsConfigError(
            pair_problem(cert, key)
            or f"TLS certificate {cert} / key {key}: cannot be used ({_reason(exc)})"
        ) from None
    try:
        ctx.load_verify_locations(cafile=str(ca))
    except (ssl.SSLError, ValueError) as exc:
        problem = "not a PEM certificate" if not _certificates(ca) else _reason(exc)
        raise TlsConfigError(f"TLS CA {ca}: cannot be used ({problem})") from None


def pem_file_problem(path: str | Path) -> str | None:
    """Why ``path`` cannot be a PEM file, or None: strangers' probes had a directory, a FIFO
    and a device all called "no such file", on the server and the client."""
    path = Path(path)
    if path.is_dir():
        return "is a directory, not a PEM file"
    if not path.exists():
        return "no such file"
    if not path.is_file():  # a FIFO or a device
        return "not a regular file, not a PEM file"
    return None


def _certificates(path: str | Path) -> list[x509.Certificate]:
    """The PEM certificates in ``path`` (none if it holds none, or cannot be read)."""
    try:
        return x509.load_pem_x509_certificates(Path(path).read_bytes())
    except (OSError, ValueError):
        return []


def pair_problem(cert: str | Path, key: str | Path) -> str | None:
    """Why OpenSSL refused ``cert`` and ``key`` in words ("not a PEM certificate", "not a PEM
    private key", "the key does not match the certificate"), where its own reason says only
    "[SSL] PEM lib (_ssl.c:3905)" (a stranger's probe); None if none of these is why."""
    certificates = _certificates(cert)
    if not certificates:
        return f"TLS certificate {cert}: not a PEM certificate"
    try:
        private = serialization.load_pem_private_key(Path(key).read_bytes(), password=None)
    except TypeError:  # protected by a passphrase: the password callback says so
        return None
    except (OSError, ValueError, UnsupportedAlgorithm):
        return f"TLS key {key}: not a PEM private key"
    public = serialization.PublicFormat.SubjectPublicKeyInfo
    if private.public_key().public_bytes(serialization.Encoding.DER, public) != certificates[
        0
    ].public_key().public_bytes(serialization.Encoding.DER, public):
        return f"TLS key {key}: the key does not match the certificate {cert}"
    return None


def _no_passphrase(key: str | Path):
    """The password callback of a key: a key protected by a passphrase is refused in one
    line (a server started by a service has nobody to type it; OpenSSL would prompt on the
    terminal, or fail on a closed stdin with a traceback)."""

    def refuse() -> bytes:
        raise TlsConfigError(
            f"TLS key {key} is protected by a passphrase; give one without "
            f"(openssl pkey -in {key} -out KEY.pem, kept readable by this user only)"
        )

    return refuse


def _reason(exc: Exception) -> str:
    return getattr(exc, "reason", None) or str(exc) or type(exc).__name__


@dataclass(frozen=True)
class Peer:
    """What the TLS handshake said about a client."""

    subject: str
    role: str


def peer_of(ssl_object: ssl.SSLObject | ssl.SSLSocket, policy: RolePolicy) -> Peer:
    """The subject and role of the verified client certificate of a TLS connection."""
    der = ssl_object.getpeercert(binary_form=True)
    if not der:  # cannot happen with CERT_REQUIRED; refuse everything if it does
        return Peer("<no certificate>", INVALID_ROLE)
    try:
        cert = x509.load_der_x509_certificate(der)
        subject = shown(cert.subject.rfc4514_string())  # RFC 4514 leaves a newline as is
    except ValueError:  # verified by OpenSSL, yet beyond what cryptography parses
        return Peer("<certificate not parsed>", INVALID_ROLE)
    try:
        role = role_of(cert)
    except (ValueError, x509.DuplicateExtension):  # not one UTF8String, or given twice
        return Peer(subject, INVALID_ROLE)
    return Peer(subject, policy.default_role if role is None else role)


class Authorisation:
    """The role gate and the connection hook of a :class:`BenchModbusServer` with TLS
    connections (see the module docstring).

    Args:
        policy: the roles (default: those of the shipped map; a server of another map
            wants :func:`~rig_emulator.modbus.roles.default_policy` of its map, as
            ``rig-emulator serve`` does).
        plain_role: the role of connections without TLS (plain TCP, RTU); None: no check.
    """

    def __init__(self, policy: RolePolicy = DEFAULT_POLICY, plain_role: str | None = None):
        if plain_role is not None and plain_role not in policy.roles:
            raise ValueError(f"role '{plain_role}' is not one of {', '.join(policy.roles)}")
        self.policy = policy
        self.plain_role = plain_role
        self.refusals = 0
        self._refusal_log = RefusalLog()
        self._subjects: dict[str, str] = {}  # peer -> certificate subject
        self._server: BenchModbusServer | None = None

    def install(self, server: BenchModbusServer) -> None:
        """Put the gate first in ``server.gates`` and the role hook on its connections."""
        self._server = server
        server.gates.insert(0, self.gate)
        server.connection_hooks.append(self.on_connection)

    def on_connection(self, handler: RequestHandler) -> None:
        """Set the role of a new TLS connection (plain connections keep None)."""
        transport = handler.transport
        ssl_object = transport.get_extra_info("ssl_object") if transport is not None else None
        if ssl_object is None:
            return
        peer = peer_of(ssl_object, self.policy)
        handler.role = peer.role
        self._forget_closed()
        self._subjects[handler.peer] = peer.subject
        handler.server.log_identity(  # rate-limited as the connects are
            "client %s: TLS, subject %s, role %s", handler.peer, peer.subject, shown(peer.role)
        )

    def _forget_closed(self) -> None:
        if self._server is None:
            return
        open_peers = {h.peer for h in self._server.handlers}
        for gone in [p for p in self._subjects if p not in open_peers]:
            del self._subjects[gone]
            self._refusal_log.forget(gone)

    def gate(self, info: RequestInfo) -> GateDecision | None:
        """Exception 01 for a request the connection's role may not send to a unit of the
        bench; one to a unit the bench does not have is left to the server's 0B, whatever
        the role (a write to unit 9 over TLS was told 01, "not allowed", as if the role
        were at fault, while plain TCP said 0B: a stranger's probe)."""
        role = info.role if info.role is not None else self.plain_role
        if role is None:
            return None
        if self._server is not None and info.unit_id not in self._server.units:
            return None
        reason = self.policy.refusal(role, info.unit_id, info.function_code, info.mei_type)
        if reason is None:
            return None
        self.refusals += 1
        suppressed = self._refusal_log.admit(info.peer, reason)
        if suppressed is not None:
            subject = self._subjects.get(info.peer, "no TLS")
            more = (  # (counted over every connection: they were charged to this one's)
                f"; {suppressed} refusals of any connection not logged since the last such line"
                if suppressed
                else ""
            )
            log.warning(
                "refused function %d to unit %d of %s (subject %s, role %s): %s "
                "(exception 01; further refusals of this kind on this connection not logged%s)",
                info.function_code,
                info.unit_id,
                info.peer,
                subject,
                shown(role),
                shown(reason),
                more,
            )
        return GateDecision(exception_code=ILLEGAL_FUNCTION)
