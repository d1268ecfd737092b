"""A bench device's Modbus/TCP front of a few lines, in front of a real ``rig-emulator
serve``: a relay on a free port of 127.0.0.1 that passes each request on and each reply
back, with one quirk a device written from the docs may have (a stranger's bench device):

- ``busy``: it takes at most ``limit`` transactions at once and answers exception 06 (server
  busy) to a request that comes while that many are outstanding (the TCP guide lets a
  device handle fewer transactions at once than a client sends);
- ``one_at_a_time``: a request that comes while another is outstanding, or behind another
  in the same segment, is dropped without a reply (a device that reads one request per
  segment; the segment rule makes it drop pipelined requests whatever the timing: by the
  outstanding rule alone, a reply that came back before the relay read on let the next one
  through, and a run seen answering pipelined requests did not fall back);
- ``tid0``: every reply carries transaction ID 0, not its request's;
- ``silent_unit``: requests to the unit ``limit`` get no reply (an absent instrument).

It counts what the quirk did (:attr:`busy_answers`, :attr:`dropped`)."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading

HEADER = struct.Struct(">HHHB")
QUIRKS = ("busy", "one_at_a_time", "tid0", "silent_unit")


class QuirkyDevice:
    """The relay (see the module docstring) to ``rig-emulator serve`` on ``upstream_port``."""

    def __init__(self, upstream_port: int, quirk: str, limit: int = 1) -> None:
        assert quirk in QUIRKS, quirk
        self.upstream_port = upstream_port
        self.quirk = quirk
        self.limit = limit
        self.busy_answers = 0
        self.dropped = 0
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        self._sockets: list[socket.socket] = [self.listener]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            upstream = socket.create_connection(("127.0.0.1", self.upstream_port))
            self._sockets += [client, upstream]
            outstanding: set[int] = set()
            lock = threading.Lock()
            threading.Thread(
                target=self._requests, args=(client, upstream, outstanding, lock), daemon=True
            ).start()
            threading.Thread(
                target=self._replies, args=(upstream, client, outstanding, lock), daemon=True
            ).start()

    def _requests(
        self, client: socket.socket, upstream: socket.socket, outstanding: set[int], lock
    ) -> None:
        """Requests from the client: passed on, answered busy, or dropped."""
        buffer = b""
        with contextlib.suppress(OSError):
            while chunk := client.recv(65536):
                buffer += chunk
                first_of_segment = True
                while len(buffer) >= 7:
                    tid, _, length, unit = HEADER.unpack(buffer[:7])
                    if len(buffer) < 6 + length:
                        break
                    frame, buffer = buffer[: 6 + length], buffer[6 + length :]
                    with lock:
                        if self.quirk == "busy" and len(outstanding) >= self.limit:
                            self.busy_answers += 1
                            client.sendall(
                                HEADER.pack(tid, 0, 3, unit) + bytes([frame[7] | 0x80, 6])
                            )
                            continue
                        if (
                            self.quirk == "one_at_a_time" and (outstanding or not first_of_segment)
                        ) or (self.quirk == "silent_unit" and unit == self.limit):
                            self.dropped += 1
                            continue
                        outstanding.add(tid)
                        first_of_segment = False
                    upstream.sendall(frame)
        self._close(client, upstream)

    def _replies(
        self, upstream: socket.socket, client: socket.socket, outstanding: set[int], lock
    ) -> None:
        """Replies from the server, passed back (with transaction ID 0: ``tid0``)."""
        buffer = b""
        with contextlib.suppress(OSError):
            while chunk := upstream.recv(65536):
                buffer += chunk
                while len(buffer) >= 7:
                    tid, _, length, _ = HEADER.unpack(buffer[:7])
                    if len(buffer) < 6 + length:
                        break
                    frame, buffer = buffer[: 6 + length], buffer[6 + length :]
                    with lock:
                        outstanding.discard(tid)
                    if self.quirk == "tid0":
                        frame = b"\0\0" + frame[2:]
                    client.sendall(frame)
        self._close(client, upstream)

    @staticmethod
    def _close(*sockets: socket.socket) -> None:
        for sock in sockets:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        for sock in self._sockets:
            with contextlib.suppress(OSError):
                sock.close()
