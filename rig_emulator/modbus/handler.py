"""The per-connection request handler of the emulator's pymodbus server.

pymodbus 3.16's ``ServerRequestHandler`` decodes one frame per ``data_received`` and
answers it later, from a task; sending the answer clears the receive buffer. Several
requests that arrive in one TCP segment (a client with more than one transaction
outstanding, which Modbus TCP allows: that is what the transaction ID is for) are
therefore answered wrongly or not at all (cf. pymodbus issue #1949). This handler keeps
pymodbus's framer, PDU classes and ``SimDevice`` datastore but

- decodes every complete frame of a segment, in order, and answers each at once (the
  datastore and the emulator's write callback never wait, so a request needs no task);
- sends the answers to one segment in one write;
- logs one line per client connect and disconnect.

A request whose handling does wait after all is finished as a task, as pymodbus would.
"""

from __future__ import annotations

import asyncio
import logging
import types
from collections.abc import Coroutine, Generator
from typing import Any

from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusIOException
from pymodbus.pdu import ExceptionResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.transaction import TransactionManager

log = logging.getLogger("rig_emulator.serve")
_PENDING: set[asyncio.Task] = set()  # strong references to requests that had to wait


def run_now(coro: Coroutine[Any, Any, None]) -> None:
    """Run ``coro`` to completion at once; if it waits on a future, finish it as a task."""
    try:
        future = coro.send(None)
    except StopIteration:
        return
    task = asyncio.get_running_loop().create_task(_resume(coro, future))
    _PENDING.add(task)
    task.add_done_callback(_PENDING.discard)


@types.coroutine
def _resume(coro: Coroutine[Any, Any, None], future: Any) -> Generator[Any, None, None]:
    """Hand the futures ``coro`` waits on to the task running this, until it returns."""
    while True:
        yield future
        try:
            future = coro.send(None)
        except StopIteration:
            return


class RequestHandler(ServerRequestHandler):
    """One client connection (see the module docstring)."""

    server: BenchModbusServer
    _out: list[bytes] | None = None

    def datagram_received(self, data: bytes, addr: tuple | None) -> None:
        buffer = self.recv_buffer + data
        if len(buffer) > self.max_buffer_size:
            self.recv_buffer = b""
            return
        self._out = []
        try:
            while buffer:
                used = self.callback_data(buffer, addr)
                if not used:
                    break
                buffer = buffer[used:]
        finally:
            self.recv_buffer = buffer
            out, self._out = self._out, None
            if out and self.transport:
                self.transport.write(b"".join(out))

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        try:
            used = TransactionManager.callback_data(self, data, addr)
        except ModbusIOException as exc:  # undecodable request: pymodbus's answer
            response = ExceptionResponse(
                0 if exc.fcode is None else exc.fcode,
                exception_code=ExcCodes.ILLEGAL_FUNCTION,
                device_id=exc.dev_id,
                transaction=exc.transaction_id,
            )
            self.server_send(response, addr)
            return len(data)
        if self.last_pdu:
            run_now(self.handle_request())
        return used

    def send(self, data: bytes, addr: tuple | None = None) -> None:
        if self._out is not None:
            self._out.append(data)
        elif self.transport:
            self.transport.write(data)

    def callback_connected(self) -> None:
        super().callback_connected()
        peer = self.transport.get_extra_info("peername") if self.transport else None
        self.peer = f"{peer[0]}:{peer[1]}" if peer else "?"
        self.server.connections += 1
        log.info("client %s connected (%d open)", self.peer, self.server.connections)

    def callback_disconnected(self, exc: Exception | None) -> None:
        super().callback_disconnected(exc)
        self.server.connections -= 1
        reason = f" ({exc})" if exc else ""
        log.info(
            "client %s disconnected%s (%d open)",
            getattr(self, "peer", "?"),
            reason,
            self.server.connections,
        )


class BenchModbusServer(ModbusTcpServer):
    """``ModbusTcpServer`` whose connections use :class:`RequestHandler`."""

    connections = 0

    def callback_new_connection(self) -> RequestHandler:
        return RequestHandler(self, self.trace_packet, self.trace_pdu, self.trace_connect)
