"""A minimal blocking Modbus TCP client on a raw socket, for load generation in benchmarks."""

from __future__ import annotations

import socket
import struct


class RawClient:
    def __init__(self, host: str, port: int, timeout: float = 5.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.tid = 0

    def request(self, unit: int, pdu: bytes) -> bytes:
        self.tid = (self.tid + 1) & 0xFFFF
        self.sock.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, unit) + pdu)
        header = self._recv(7)
        _, _, length, _ = struct.unpack(">HHHB", header)
        return self._recv(length - 1)

    def read_input(self, unit: int, address: int, count: int) -> bytes:
        return self.request(unit, struct.pack(">BHH", 4, address, count))

    def write_registers(self, unit: int, address: int, words: list[int]) -> bytes:
        pdu = struct.pack(f">BHHB{len(words)}H", 16, address, len(words), 2 * len(words), *words)
        return self.request(unit, pdu)

    def _recv(self, n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError("closed")
            buf += chunk
        return buf

    def close(self) -> None:
        self.sock.close()
