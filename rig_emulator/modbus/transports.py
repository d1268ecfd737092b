"""Several transports from one plant: plain TCP, Modbus/TCP Security (TLS) and RTU lines.

They all share one :class:`~rig_emulator.modbus.handler.BenchModbusServer` (its datastore,
its gates and its connection count): extra TCP listeners hand their connections to the
server's own handler; an RTU line calls its ``execute``. So a value written over any of
them is read over every other, and the fault and authorisation gates apply to all.

How the guards combine: the TLS role gate comes first (exception 01 for what the
connection's role may not do); a request it lets through still meets the server's own
checks, among them the clock guard (``--allow-control``: exception 01 for clock commands
to a real-time server). An engineer may therefore change the speed of a real-time server
only where ``--allow-control`` is given; plain TCP and RTU clients meet the clock guard
only (or the role of ``plain_role``).
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import ssl
from dataclasses import dataclass, field

from rig_emulator.modbus.handler import BenchModbusServer
from rig_emulator.modbus.roles import RolePolicy
from rig_emulator.modbus.rtu import RtuLine
from rig_emulator.modbus.tls import Authorisation


@dataclass
class Transports:
    """The listeners and lines added to a running server; :meth:`stop` closes them."""

    server: BenchModbusServer
    authorisation: Authorisation | None = None
    listeners: list[asyncio.Server] = field(default_factory=list)
    lines: list[RtuLine] = field(default_factory=list)

    async def add_tcp(
        self, host: str, port: int, context: ssl.SSLContext | None = None
    ) -> tuple[str, int]:
        """Listen for plain TCP (``context`` None) or TLS connections on ``host:port``
        (0: any free port); the address listened on. OSError when it cannot."""
        listener = await self.server.listen(host, port, context)
        self.listeners.append(listener)
        sock: socket.socket = listener.sockets[0]
        return sock.getsockname()[0], sock.getsockname()[1]

    def authorise(self, policy: RolePolicy, plain_role: str | None = None) -> Authorisation:
        """Install the role gate first in the server's gates (once)."""
        if self.authorisation is None:
            self.authorisation = Authorisation(policy, plain_role)
            self.authorisation.install(self.server)
        return self.authorisation

    async def add_rtu(self, path: str, baud: int, parity: str) -> RtuLine:
        """Serve the server's units on a serial line (``pty``: a new pseudo-terminal)."""
        line = RtuLine(self.server, path, baud, parity)
        await line.start()
        self.lines.append(line)
        return line

    async def stop(self) -> None:
        for listener in self.listeners:
            listener.close()
        for line in self.lines:
            await line.stop()
        for listener in self.listeners:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(listener.wait_closed(), 2.0)
