"""A lean blocking Modbus TCP client: one socket per unit, scatter-gather polling.

Acquisition systems poll each instrument over its own connection; sending one request on
every connection before reading any reply lets the instruments (here: the emulator) work
while the others' replies travel. Only one request is ever outstanding per connection.

Errors: :class:`ModbusExceptionResponse` for an exception reply (with its code),
:class:`ConnectionLost` for a closed, reset or timed-out connection.
"""

from __future__ import annotations

import contextlib
import socket
import struct
from collections.abc import Sequence


class ConnectionLost(ConnectionError):
    """The connection to a unit failed (refused, reset, closed or timed out)."""


class ModbusExceptionResponse(RuntimeError):
    """The server answered with a Modbus exception."""

    def __init__(self, unit: int, function: int, code: int) -> None:
        super().__init__(f"unit {unit}: function {function} refused with exception {code:02X}")
        self.unit = unit
        self.function = function
        self.code = code


_HEADER = struct.Struct(">HHHB")


class UnitConnection:
    """A TCP connection to one unit ID."""

    def __init__(self, host: str, port: int, unit: int, timeout_s: float) -> None:
        self.unit = unit
        self._tid = 0
        self._expect: tuple[int, int] | None = None
        self._buffer = b""
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout_s)
        except OSError as exc:
            raise ConnectionLost(
                f"cannot connect to {host}:{port}: {exc.strerror or exc}"
            ) from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def send(self, pdu: bytes) -> None:
        """Send a request; its reply is collected by :meth:`receive`."""
        self._tid = (self._tid + 1) & 0xFFFF
        self._expect = (self._tid, pdu[0])
        try:
            self.sock.sendall(_HEADER.pack(self._tid, 0, len(pdu) + 1, self.unit) + pdu)
        except OSError as exc:
            raise ConnectionLost(f"unit {self.unit}: send failed ({exc})") from None

    def receive(self) -> bytes:
        """The reply PDU (function code first) of the outstanding request."""
        assert self._expect is not None
        tid, function = self._expect
        while True:
            header = self._recv(7)
            got_tid, _, length, _ = _HEADER.unpack(header)
            body = self._recv(length - 1)
            if got_tid == tid:
                break  # a late reply to an earlier, timed-out request is skipped
        self._expect = None
        if body[0] == function | 0x80:
            raise ModbusExceptionResponse(self.unit, function, body[1])
        return body

    def _recv(self, n: int) -> bytes:
        """``n`` bytes; reads whatever has arrived (a whole reply in one call, usually)."""
        buffer = self._buffer
        while len(buffer) < n:
            try:
                chunk = self.sock.recv(4096)
            except OSError as exc:
                raise ConnectionLost(f"unit {self.unit}: receive failed ({exc})") from None
            if not chunk:
                raise ConnectionLost(f"unit {self.unit}: connection closed by the server")
            buffer += chunk
        self._buffer = buffer[n:]
        return buffer[:n]

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def read_pdu(function: int, address: int, count: int) -> bytes:
    """Request of a read function (1 coils, 2 discrete, 3 holding, 4 input)."""
    return struct.pack(">BHH", function, address, count)


def write_registers_pdu(address: int, words: Sequence[int]) -> bytes:
    """FC16 request."""
    n = len(words)
    return struct.pack(f">BHHB{n}H", 16, address, n, 2 * n, *words)


def write_coils_pdu(address: int, bits: Sequence[bool]) -> bytes:
    """FC15 request."""
    data = bytearray((len(bits) + 7) // 8)
    for i, bit in enumerate(bits):
        if bit:
            data[i // 8] |= 1 << (i % 8)
    return struct.pack(">BHHB", 15, address, len(bits), len(data)) + bytes(data)


def registers_of(reply: bytes) -> list[int]:
    """Registers of an FC3/FC4 reply."""
    n = reply[1] // 2
    return list(struct.unpack(f">{n}H", reply[2 : 2 + 2 * n]))


def bits_of(reply: bytes, count: int) -> list[bool]:
    """Bits of an FC1/FC2 reply."""
    data = reply[2 : 2 + reply[1]]
    return [bool(data[i // 8] >> (i % 8) & 1) for i in range(count)]
