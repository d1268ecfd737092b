"""A bare pymodbus SimDevice server with static values and the register map's layout.

The reference of ``make bench``: the same devices, tables and addresses as the emulator, but
no physics, no tick, no action callback. Usage: python bench/bare_server.py PORT
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import sys

from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import SimDevice

from rig_emulator.modbus.server import device_layout
from rig_emulator.registers import load_map


async def serve(port: int) -> None:
    devices = [SimDevice(d.unit_id, simdata=device_layout(d)) for d in load_map().devices]
    server = ModbusTcpServer(devices, address=("127.0.0.1", port))
    await server.serve_forever()


if __name__ == "__main__":
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    with contextlib.suppress(KeyboardInterrupt):  # the terminal's Ctrl-C: the bench says it
        asyncio.run(serve(int(sys.argv[1])))
