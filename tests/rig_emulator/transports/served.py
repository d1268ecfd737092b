"""``rig-emulator serve`` as its own process, and raw Modbus exchanges with it over TLS and
RTU (the requests built byte by byte, so a test sends exactly what a stranger sent)."""

from __future__ import annotations

import contextlib
import os
import select
import signal
import socket
import ssl
import struct
import subprocess
import sys
import termios
import time
import tty
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from rig_emulator.certs import ROLE_OID, Issued
from rig_emulator.modbus.rtu_wire import frame, reply_length

REPO = Path(__file__).resolve().parents[3]


def with_role_extension(
    ca: Issued, client: Issued, der: bytes, critical: bool, oid: str = ROLE_OID
) -> Issued:
    """``client`` issued again by ``ca`` with one more extension, the role's (OID
    1.3.6.1.4.1.50316.802.1) unless ``oid`` says another, of the DER value ``der`` (a role
    encoded wrongly, or marked critical: what ``rig-emulator certs`` never makes)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes

    role = x509.UnrecognizedExtension(x509.ObjectIdentifier(oid), der)
    builder = x509.CertificateBuilder(
        client.cert.issuer,
        client.cert.subject,
        client.cert.public_key(),
        client.cert.serial_number,
        client.cert.not_valid_before_utc,
        client.cert.not_valid_after_utc,
        [*client.cert.extensions],
    ).add_extension(role, critical=critical)
    return Issued(client.key, builder.sign(ca.key, hashes.SHA256()))


@dataclass
class Served:
    """A running ``rig-emulator serve``: its TLS (or plain) port, its RTU line and, once
    stopped, what it wrote on stderr."""

    process: subprocess.Popen
    port: int
    serial: str | None
    stderr: list[str] = field(default_factory=list)


def serve_args(*args: str) -> list[str]:
    return [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw", *args]


def run_serve(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess:
    """``rig-emulator serve ARGS`` to its end (a refusal: exit code and one line)."""
    return subprocess.run(
        serve_args(*args),
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )


@contextlib.contextmanager
def serving(*args: str, serial: bool = False) -> Iterator[Served]:
    """``rig-emulator serve --lockstep --port FREE ARGS`` until the block ends (SIGTERM);
    with ``serial``, the path it printed for ``--serial pty``."""
    from hil_client.wait_for_port import free_port, wait_for_port

    port = free_port()
    process = subprocess.Popen(
        serve_args("--lockstep", "--port", str(port), *args),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    served = Served(process, port, None)
    try:
        if serial:
            first = process.stdout.readline() if process.stdout else ""
            assert first.startswith("serial: "), (first, process.poll())
            served.serial = first.split(": ", 1)[1].strip()
        assert wait_for_port("127.0.0.1", port, 60.0, alive=lambda: process.poll() is None)
        yield served
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            _, err = process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            _, err = process.communicate(timeout=10)
        served.stderr[:] = err.splitlines()


def tls_connect(port: int, certs: Path, stem: str) -> ssl.SSLSocket:
    """A TLS connection presenting ``certs/STEM.pem``, the server verified by ``ca.pem``."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.load_verify_locations(cafile=str(certs / "ca.pem"))
    ctx.load_cert_chain(str(certs / f"{stem}.pem"), str(certs / f"{stem}.key"))
    raw = socket.create_connection(("127.0.0.1", port), timeout=5)
    return ctx.wrap_socket(raw, server_hostname="127.0.0.1")


def _recv_exactly(sock: socket.socket, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        if not chunk:
            raise ConnectionError("closed by the server")
        out += chunk
    return out


def tcp_exchange(sock: socket.socket, unit: int, pdu: bytes) -> bytes:
    """The response PDU to ``pdu`` for ``unit`` over Modbus TCP (MBAP framed)."""
    sock.sendall(struct.pack(">HHHB", 1, 0, len(pdu) + 1, unit) + pdu)
    _, _, length, _ = struct.unpack(">HHHB", _recv_exactly(sock, 7))
    return _recv_exactly(sock, length - 1)


class RtuClient:
    """The client side of an RTU pty, raw."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        termios.tcflush(self.fd, termios.TCIOFLUSH)

    def read(self, n: int, timeout_s: float) -> bytes:
        """Up to ``n`` bytes, whatever came within ``timeout_s``."""
        out = b""
        deadline = time.monotonic() + timeout_s
        while len(out) < n:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                break
            out += os.read(self.fd, n - len(out))
        return out

    def exchange(self, unit: int, pdu: bytes, timeout_s: float = 3.0) -> bytes:
        """The response PDU to ``pdu`` for ``unit`` (b"" if none came in ``timeout_s``)."""
        os.write(self.fd, frame(unit, pdu))
        head = self.read(3, timeout_s)
        length = reply_length(head)
        if length is None:
            return b""
        reply = head + self.read(length - len(head), timeout_s)
        assert frame(unit, reply[1:-2]) == reply, reply.hex()  # a whole frame, CRC valid
        return reply[1:-2]

    def close(self) -> None:
        os.close(self.fd)
