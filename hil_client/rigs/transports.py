"""How the Modbus rig reaches its server: plain TCP, Modbus/TCP Security (TLS) or RTU.

``--rig`` URLs (CONTRACT sections 1 and 6):

- ``modbus://HOST:PORT``: plain Modbus TCP (:class:`~hil_client.modbus_client.Connection`);
- ``modbus+tls://HOST:PORT``: Modbus/TCP Security (default port 802), TLS 1.2 or newer,
  the client certificate and key presented and the server verified against the CA
  (:class:`TlsFiles`);
- ``modbus-rtu:///dev/ttyX?baud=19200&parity=E``: Modbus RTU on a serial line.

Every connection offers the same three calls (``send`` requests, ``receive`` their
replies in order, ``close``), so the rig does not know which one it drives. RTU has no
pipelining: its ``send`` queues, and each ``receive`` is one transaction on the line.
"""

from __future__ import annotations

import contextlib
import functools
import os
import select
import ssl
import termios
import time
import tty
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import unquote_plus, urlparse

from hil_client.modbus_client import (
    BadReply,
    Connection,
    ConnectionLost,
    ModbusExceptionResponse,
    NoReply,
    Reply,
    ReplyTimeout,
    reply_problem,
)
from rig_emulator.modbus.rtu import PTY_MULTIPLEXER, is_pty_multiplexer
from rig_emulator.modbus.rtu_wire import PARITIES, frame, reply_length, silence_s, unframe
from rig_emulator.modbus.tls import pem_file_problem
from rig_emulator.names import host_name_problem

DEFAULT_TLS_PORT = 802
DEFAULT_BAUD = 19200
DEFAULT_PARITY = "E"
SCHEMES = ("modbus", "modbus+tls", "modbus-rtu")
RTU_PARAMETERS = ("baud", "parity")  # of a modbus-rtu:// URL's query
#: The usual speeds of a Modbus serial line, named when a URL asks for another
STANDARD_BAUDS = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)
RIG_TIMEOUT_S = 5.0  # one request, as ModbusRig's default


@dataclass(frozen=True)
class TlsFiles:
    """The client certificate, its key and the CA that signed the server's certificate."""

    cert: Path
    key: Path
    ca: Path


def tls_files(options: Any, url: str | None = None) -> TlsFiles | None:
    """The :class:`TlsFiles` of parsed ``--tls-cert``/``--tls-key``/``--tls-ca`` options
    (None if none is given; ValueError if only some are, or any for a ``url`` that is no
    Modbus/TCP Security rig: a plain rig's --tls-cert was told to add --tls-key)."""
    given = {name: getattr(options, name, None) for name in ("tls_cert", "tls_key", "tls_ca")}
    if not any(given.values()):
        return None
    if url is not None and not url.startswith("modbus+tls://"):
        raise ValueError(f"--tls-* options need a modbus+tls:// rig, not {url}")
    missing = [f"--{k.replace('_', '-')}" for k, v in given.items() if not v]
    if missing:
        raise ValueError(f"TLS needs {', '.join(missing)} too")
    return TlsFiles(Path(given["tls_cert"]), Path(given["tls_key"]), Path(given["tls_ca"]))


@dataclass(frozen=True)
class Endpoint:
    """A parsed ``--rig`` URL."""

    scheme: str
    host: str = ""
    port: int = 0
    path: str = ""
    baud: int = DEFAULT_BAUD
    parity: str = DEFAULT_PARITY


def parse_endpoint(url: str) -> Endpoint:
    """The endpoint of a ``modbus://``, ``modbus+tls://`` or ``modbus-rtu://`` URL;
    ValueError (one line naming the fault) if it is none of them."""
    parsed = urlparse(url)
    if parsed.scheme not in SCHEMES:
        raise ValueError(
            f"'{url}' is not modbus://HOST:PORT, modbus+tls://HOST:PORT or "
            "modbus-rtu:///DEVICE?baud=N"
        )
    if parsed.scheme == "modbus-rtu":
        if not parsed.path or parsed.netloc:
            raise ValueError(f"'{url}' names no device (modbus-rtu:///dev/ttyX?baud=N)")
        query = rtu_query(url, parsed.query)
        baud_text = query.get("baud", str(DEFAULT_BAUD))
        # ASCII digits only: "²" passes isdigit() and ended in int()'s own words (a probe)
        if not (baud_text.isascii() and baud_text.isdigit()) or not (
            50 <= int(baud_text) <= 4_000_000
        ):
            raise ValueError(f"'{url}': baud '{baud_text}' is not a line speed")
        # a speed the line cannot be set to left it at its own, silently (a re-probe)
        if getattr(termios, f"B{int(baud_text)}", None) is None:
            known = ", ".join(str(b) for b in STANDARD_BAUDS)
            raise ValueError(f"'{url}': baud {int(baud_text)} is not a serial line speed ({known})")
        parity = query.get("parity", DEFAULT_PARITY).upper()
        if parity not in PARITIES:
            raise ValueError(f"'{url}': parity '{parity}' is not one of {', '.join(PARITIES)}")
        return Endpoint("modbus-rtu", path=parsed.path, baud=int(baud_text), parity=parity)
    if not parsed.hostname:
        raise ValueError(f"'{url}' names no host ({parsed.scheme}://HOST:PORT)")
    problem = host_name_problem(parsed.hostname)
    if problem is not None:
        raise ValueError(f"'{url[:100]}': '{parsed.hostname[:80]}' is no host name ({problem})")
    port = url_port(url, DEFAULT_TLS_PORT if parsed.scheme == "modbus+tls" else 502)
    return Endpoint(parsed.scheme, host=parsed.hostname, port=port)


def rtu_query(url: str, query: str) -> dict[str, str]:
    """The parameters of the ``query`` of a ``modbus-rtu://`` ``url``, each known, once and
    with a value; ValueError naming the one at fault. An empty piece between ``&`` is
    nothing (``?baud=9600&``, ``?&baud=9600``: a stray ``&`` is harmless, as to browsers
    and urllib); a name without a value (``?baud``, ``?baud=``), an unknown name and a
    name given twice are refused: each ran with the defaults or the last one without a
    word, and then a strict parse refused them all, stray ``&`` included, as "a parameter
    is empty" without naming it (stranger's probes)."""
    given: dict[str, list[str]] = {}
    for piece in query.split("&"):
        if not piece:
            continue
        name, _, value = (unquote_plus(part) for part in piece.partition("="))
        if not name:
            raise ValueError(f"'{url}': '{piece}' names no parameter (baud=N&parity=E)")
        if name not in RTU_PARAMETERS:
            raise ValueError(f"'{url}': unknown parameter '{name}' (baud=N, parity=E|N|O)")
        given.setdefault(name, []).append(value)
    for name, values in given.items():
        if len(values) > 1:
            raise ValueError(f"'{url}': parameter '{name}' is given {len(values)} times")
        if not values[0]:
            raise ValueError(f"'{url}': parameter '{name}' has no value ({name}=...)")
    return {name: values[0] for name, values in given.items()}


def url_port(url: str, default: int) -> int:
    """The port of a ``SCHEME://HOST:PORT`` URL, ``default`` if it names none; ValueError
    for one outside 1..65535 (port 0 is no port to connect to)."""
    try:
        port = urlparse(url).port
    except ValueError:
        port = 0
    if port is None:
        return default
    if not 1 <= port <= 65535:
        raise ValueError(f"'{url}' has a bad port (1..65535)")
    return port


def tls_client_context(files: TlsFiles) -> ssl.SSLContext:
    """TLS 1.2 or newer; the server verified against ``files.ca`` (its name or address
    too); ``files.cert``/``files.key`` presented. ValueError naming a file that cannot be
    used."""
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    for name, path in (
        ("--tls-cert", files.cert),
        ("--tls-key", files.key),
        ("--tls-ca", files.ca),
    ):
        problem = pem_file_problem(path)
        if problem:
            raise ValueError(f"{name} {path}: {problem}")
    try:
        ctx.load_cert_chain(str(files.cert), str(files.key), password=_no_passphrase)
    except _Encrypted:
        raise ValueError(
            f"--tls-key {files.key} is protected by a passphrase; give one without "
            "(openssl pkey -in KEY -out KEY.pem)"
        ) from None
    except (ssl.SSLError, ValueError) as exc:
        raise ValueError(f"--tls-cert/--tls-key {files.cert}: cannot be used ({exc})") from None
    try:
        ctx.load_verify_locations(cafile=str(files.ca))
    except (ssl.SSLError, ValueError) as exc:
        raise ValueError(f"--tls-ca {files.ca}: cannot be used ({exc})") from None
    return ctx


class _Encrypted(Exception):
    """The key asks for a passphrase."""


def _no_passphrase() -> bytes:
    # OpenSSL would prompt on the terminal (or fail on a closed stdin with a traceback)
    raise _Encrypted


class TlsConnection(Connection):
    """A Modbus/TCP Security connection: :class:`Connection` inside TLS."""

    def __init__(self, host: str, port: int, timeout_s: float, context: ssl.SSLContext):
        super().__init__(host, port, timeout_s)
        try:
            self.sock = context.wrap_socket(self.sock, server_hostname=host)
        except (ssl.SSLError, OSError) as exc:
            self.close()
            raise ConnectionLost(f"TLS handshake with {host}:{port} failed ({exc})") from None


class GarbledReply(ConnectionLost):
    """A frame whose CRC fails: noise on the line took a reply, from a server that was
    there to answer."""


class RtuConnection:
    """A Modbus RTU client on a serial line: one transaction at a time, frames with CRC,
    a silence of 3.5 characters before each request."""

    def __init__(self, path: str, baud: int, parity: str, timeout_s: float) -> None:
        self.path = path
        self.timeout_s = timeout_s
        self.silence_s = silence_s(baud)
        self._pending: deque[tuple[int, bytes]] = deque()
        self._line_free = 0.0
        self._rest = b""  # bytes read past the last whole frame
        try:
            self._fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        except OSError as exc:
            raise ConnectionLost(f"cannot open {path}: {exc.strerror}") from None
        try:
            tty.setraw(self._fd)
        except termios.error:
            os.close(self._fd)
            raise ConnectionLost(f"{path} is not a serial line") from None
        attrs = termios.tcgetattr(self._fd)
        attrs[2] &= ~(termios.PARENB | termios.PARODD | termios.CSTOPB)
        if parity != "N":
            attrs[2] |= termios.PARENB | (termios.PARODD if parity == "O" else 0)
        else:
            attrs[2] |= termios.CSTOPB
        speed = getattr(termios, f"B{baud}", None)
        if speed is not None:
            attrs[4] = attrs[5] = speed
        # a pseudo-terminal has no line: some kernels refuse parity settings on one; raw
        # mode is what matters there
        with contextlib.suppress(termios.error):
            termios.tcsetattr(self._fd, termios.TCSANOW, attrs)

    def send(self, requests: Sequence[tuple[int, bytes]]) -> None:
        """Queue ``(unit, pdu)`` requests; each :meth:`receive` carries out the oldest."""
        self._pending.extend(requests)

    def receive(
        self,
        timeout_s: float | None = None,
        still_coming: Callable[[], bool] | None = None,
        patience_s: float = 0.0,
    ) -> bytes:
        """The reply PDU to the oldest queued request (sent now, on a quiet line), waited
        for ``timeout_s`` (None: the connection's timeout); with ``still_coming``, for the
        connection's timeout at a time, as long as it says the reply is still coming, up to
        ``patience_s`` in all (a request lost on the line to a bad CRC was waited for 60 s,
        --reconnect-timeout, where the server was idle at once: a stranger's probe).
        :class:`BadReply` for a frame
        whose CRC holds but that does not answer the request (another slave address or
        function, an exception without its code, another size than asked for): never
        decoded (a stranger's probe on TCP: such replies were decoded as the request's
        registers, or ended the run with a traceback; a line had the same holes)."""
        unit, pdu = self._pending.popleft()
        wait = self._line_free - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        with contextlib.suppress(termios.error):
            termios.tcflush(self._fd, termios.TCIFLUSH)  # stale bytes of a timed-out reply
        self._rest = b""
        try:
            os.write(self._fd, frame(unit, pdu))
        except OSError as exc:
            raise ConnectionLost(f"{self.path}: write failed ({exc.strerror})") from None
        wait_s = self.timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + wait_s
        last = time.monotonic() + patience_s  # (still_coming: the longest wait in all)
        while True:
            try:
                reply = self._read_reply(deadline, wait_s)
            except ReplyTimeout:
                if still_coming is None or time.monotonic() >= last or not still_coming():
                    raise
                deadline = min(time.monotonic() + wait_s, last)
                continue
            self._line_free = time.monotonic() + self.silence_s
            decoded = unframe(reply)
            if decoded is None:
                raise GarbledReply(f"{self.path}: garbled reply from unit {unit} ({reply.hex()})")
            if decoded[0] == unit or not unit:
                break
            # another slave's whole frame: a late reply to a request given up on (a slow
            # unit answers after the master moved on), not this one's: read on (it was
            # taken as this reply and refused, the run's own request with it: a flaky CI)
        body = decoded[1]
        problem = reply_problem(unit, pdu, decoded[0], body)
        if problem is not None:
            raise BadReply(
                f"{self.path}: unit {unit}: function {pdu[0]}: reply not used: {problem} "
                f"({reply.hex()})"
            )
        if body[0] == pdu[0] | 0x80:
            raise ModbusExceptionResponse(unit, pdu[0], body[1])
        return body

    def receive_all(
        self,
        count: int,
        own: range = range(0),
        patience_s: float = 0.0,
        still_coming: Callable[[int, int], bool] | None = None,
    ) -> tuple[list[Reply], list[float]]:
        """The outcome of each of the ``count`` oldest queued requests (the reply, the
        exception, or :class:`NoReply` after the timeout, a silent unit, or after a reply
        that does not answer the request, counted as a timeout) and when each was known;
        as :meth:`Connection.receive_all`, one transaction at a time: only the requests at
        the indices ``own`` are waited for up to ``patience_s`` in all (on a line a slow
        unit's late reply is dropped once the master speaks again, so it holds up nothing
        after it), ``still_coming`` asked after each of the connection's timeouts whether
        to wait on."""
        out: list[Reply] = []
        times: list[float] = []
        deadline = time.monotonic() + patience_s
        for k in range(count):
            unit, pdu = self._pending[0]
            patient = max(deadline - time.monotonic(), self.timeout_s)
            try:
                if k in own and still_coming is not None:
                    coming = functools.partial(still_coming, unit, pdu[0])
                    out.append(self.receive(None, coming, patient))
                else:
                    out.append(self.receive(patient if k in own else None))
            except ModbusExceptionResponse as exc:
                out.append(exc)
            except ReplyTimeout:
                self._line_free = time.monotonic() + self.silence_s
                out.append(NoReply(unit, pdu[0], "timeout"))
            except BadReply as exc:
                out.append(NoReply(unit, pdu[0], "timeout", str(exc)))
            times.append(time.monotonic())
        return out, times

    def _read_reply(self, deadline: float, wait_s: float) -> bytes:
        reply, self._rest = self._rest, b""
        while True:
            needed = reply_length(reply)
            if needed is not None and len(reply) >= needed:
                self._rest = reply[needed:]  # (a reply right behind a late one)
                return reply[:needed]
            left = deadline - time.monotonic()
            ready = select.select([self._fd], [], [], max(left, 0.0))[0] if left > 0 else []
            if not ready:
                raise ReplyTimeout(f"{self.path}: no reply within {wait_s:g} s")
            try:
                reply += os.read(self._fd, 512)
            except OSError as exc:
                raise ConnectionLost(f"{self.path}: read failed ({exc.strerror})") from None

    def close(self, abort: bool = False) -> None:
        """Close the line (``abort``: as :meth:`Connection.close`; a line has no reset)."""
        with contextlib.suppress(OSError):
            os.close(self._fd)


Connector = Callable[[], Connection | RtuConnection]


def connector(url: str, timeout_s: float, tls: TlsFiles | None = None) -> Connector:
    """A function that opens a connection to ``url`` (ValueError for a bad URL, or TLS
    options that are missing, unneeded or unusable)."""
    endpoint = parse_endpoint(url)
    if endpoint.scheme == "modbus+tls":
        if tls is None:
            raise ValueError(f"{url} needs --tls-cert, --tls-key and --tls-ca")
        context = tls_client_context(tls)
        return lambda: TlsConnection(endpoint.host, endpoint.port, timeout_s, context)
    if tls is not None:
        raise ValueError(f"--tls-* options need a modbus+tls:// rig, not {url}")
    if endpoint.scheme == "modbus-rtu":
        if is_pty_multiplexer(endpoint.path):  # checked before anything opens it
            raise ValueError(
                f"'{url}': {endpoint.path}: {PTY_MULTIPLEXER}; give the line the server "
                "printed (serial: /dev/pts/N)"
            )
        return lambda: RtuConnection(endpoint.path, endpoint.baud, endpoint.parity, timeout_s)
    return lambda: Connection(endpoint.host, endpoint.port, timeout_s)
