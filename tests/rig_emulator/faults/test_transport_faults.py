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


def test_hil_client_rig_over_rtu_survives_a_silent_a_busy_and_a_slow_unit(serve):
    """The Modbus rig on the RTU line: the silent analyser's, the busy balance's and the
    slow bench PLC's fields are empty, the events say why, every step is done once. The
    PLC takes the setpoint writes before the lockstep advance: a delay there longer than
    the rig's timeout used to leave the line answering each request one late, for ever."""
    import math

    from hil_client.protocol.rig import RigCommand
    from hil_client.rigs.modbus import ModbusRig
    from hil_client.rigs.transports import connector

    faults = faults_from_list(
        [
            {"kind": "no_reply", "unit": 2, "at_s": 2, "for_s": 2},
            {"kind": "exception", "unit": 5, "code": 6, "at_s": 5, "for_s": 1},
            {"kind": "delay", "unit": 1, "delay_ms": 1500, "at_s": 7, "for_s": 1},
        ]
    )
    srv = serve(faults=faults)

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", 115200, "E")

    transports, rtu = srv.call(setup())
    url = f"modbus-rtu://{rtu.path}?baud=115200&parity=E"
    rig = ModbusRig(url, srv.map, timeout_s=0.3, connect=connector(url, 0.3))
    rig.apply(RigCommand(600.0, 55.0, True, True))
    rows = {}
    for _ in range(9):
        rig.advance(1.0)
        rows[rig.log_time_s] = rig.read()
    rig.close()
    srv.call(transports.stop())
    assert sorted(rows) == [float(t) for t in range(1, 10)]
    assert rig.gaps == []
    status = srv.values()
    assert status["sim_time_s"] == 9.0 and status["lockstep_counter"] == 9  # none twice
    for t, row in rows.items():
        assert math.isnan(row["flue_gas_O2_pct"]) == (2.0 <= t < 4.0), t
        assert math.isnan(row["balance_mass_kg"]) == (t == 5.0), t
        assert math.isnan(row["water_flow_kg_h"]) == (t == 7.0), t
    events = {(e["event"], e["unit"], e["server_time_s"]) for e in rig.comm_events}
    assert {("timeout", 2, 2.0), ("timeout", 2, 3.0), ("exception", 5, 5.0)} <= events
