"""Raw-socket Modbus TCP helpers for the framing, conformance and gate tests: the frames are
built here by hand from the Messaging on TCP/IP Implementation Guide V1.0b (MBAP header:
transaction id, protocol id 0, length = unit id + PDU bytes, unit id), not by a library."""

from __future__ import annotations

import socket
import struct


def frame(tid: int, unit: int, pdu: bytes, protocol: int = 0, length: int | None = None) -> bytes:
    """One request ADU (``length`` and ``protocol`` may be forced to wrong values)."""
    return (
        struct.pack(">HHHB", tid, protocol, len(pdu) + 1 if length is None else length, unit) + pdu
    )


def connect(port: int, timeout: float = 10.0) -> socket.socket:
    s = socket.create_connection(("127.0.0.1", port), timeout=timeout)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


class Replies:
    """Reads reply ADUs from a socket, whatever their segmentation."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.data = b""

    def next(self) -> tuple[int, int, bytes]:
        """The next reply as (transaction id, unit id, PDU); AssertionError when closed."""
        while len(self.data) < 6 or len(self.data) < 6 + struct.unpack(">H", self.data[4:6])[0]:
            chunk = self.sock.recv(65536)
            assert chunk, "the server closed the connection"
            self.data += chunk
        tid, protocol, length, unit = struct.unpack(">HHHB", self.data[:7])
        assert protocol == 0
        pdu = self.data[7 : 6 + length]
        self.data = self.data[6 + length :]
        return tid, unit, pdu

    def take(self, n: int) -> list[tuple[int, int, bytes]]:
        return [self.next() for _ in range(n)]


def ask(port: int, unit: int, pdu: bytes, tid: int = 1) -> bytes:
    """Send one request on a fresh connection and return the reply PDU."""
    with connect(port) as s:
        s.sendall(frame(tid, unit, pdu))
        got_tid, got_unit, reply = Replies(s).next()
    assert (got_tid, got_unit) == (tid, unit)
    return reply


def closed_by_server(sock: socket.socket, timeout: float = 10.0) -> bool:
    """Whether the server closes ``sock`` (EOF or reset) within ``timeout``, reading and
    discarding whatever replies come first."""
    sock.settimeout(timeout)
    try:
        while True:
            if not sock.recv(65536):
                return True
    except ConnectionResetError:
        return True
    except TimeoutError:
        return False


def read_pdu(function: int, address: int, count: int) -> bytes:
    return struct.pack(">BHH", function, address, count)


def write_registers_pdu(address: int, registers: list[int], byte_count: int | None = None) -> bytes:
    n = 2 * len(registers) if byte_count is None else byte_count
    return struct.pack(f">BHHB{len(registers)}H", 16, address, len(registers), n, *registers)


def registers_of(pdu: bytes) -> list[int]:
    """The registers of a read (03/04/23) reply."""
    n = pdu[1] // 2
    return list(struct.unpack(f">{n}H", pdu[2 : 2 + 2 * n]))
