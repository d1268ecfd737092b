"""Communication faults act on the RTU line too (the gate is the server's, shared by every
transport): exception and no reply on a real pseudo-terminal, the other units unharmed."""

from __future__ import annotations

import struct

import pytest

from rig_emulator.faults import faults_from_list
from rig_emulator.modbus.transports import Transports
from tests.rig_emulator.transports.test_rtu import BAUD, Line, rtu_frame


@pytest.fixture
def faulty_line(serve):
    faults = faults_from_list(
        [
            {"kind": "exception", "unit": 5, "code": 6, "at_s": 0},
            {"kind": "no_reply", "unit": 2, "at_s": 0},
        ]
    )
    srv = serve(faults=faults)

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", BAUD, "E")

    transports, rtu = srv.call(setup())
    line = Line(rtu.path)
    yield line
    line.close()
    srv.call(transports.stop())


def _fc4(address: int, count: int) -> bytes:
    return struct.pack(">BHH", 4, address, count)


def test_faults_on_the_rtu_line(faulty_line):
    faulty_line.send(rtu_frame(5, _fc4(0, 2)))
    reply = faulty_line.read(5)
    assert reply == rtu_frame(5, bytes([0x84, 6]))  # busy, with a valid CRC
    faulty_line.send(rtu_frame(2, _fc4(0, 2)))
    assert faulty_line.read(9, timeout_s=0.5) == b""  # silence, as a dead instrument
    faulty_line.send(rtu_frame(1, _fc4(0, 2)))
    reply = faulty_line.read(9)
    assert len(reply) == 9 and reply[:3] == bytes([1, 4, 4])  # unit 1 answers
