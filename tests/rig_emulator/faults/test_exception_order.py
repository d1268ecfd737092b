"""An ``exception`` fault over real sockets and raw frames: where its code comes among the
checks of the MODBUS Application Protocol Specification V1.1b3.

Its section 7 defines 04 SERVER DEVICE FAILURE as "An unrecoverable error occurred while the
server was attempting to perform the requested action": a failure at the operation, the last
step of every state diagram of section 6, after the checks that answer 01 (function code),
03 (quantity, structure, value) and 02 (address). A busy device (06) or a gateway that
cannot reach its target (0A, 0B) answers whatever the request (CONTRACT section 5: "the unit
answers every request with that exception")."""

from __future__ import annotations

import struct

import pytest

from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, point
from tests.rig_emulator.modbus.raw import ask, read_pdu, registers_of, write_registers_pdu

PLC, ANALYSER, SIM = 1, 2, 100
DEVICE_FAILURE, BUSY = 0x04, 0x06


def _illegal(srv) -> list[tuple[str, bytes, int]]:
    """Requests to the bench PLC the spec's checks (or the map's write rules) refuse, each
    with its exception code."""
    _, flow = point(srv, "bench_plc", "flow_setpoint")
    return [
        ("unsupported function 0x41", bytes([0x41, 0, 0]), 0x01),
        ("FC3 quantity 0", read_pdu(3, 0, 0), 0x03),
        ("FC3 unmapped address 50", read_pdu(3, 50, 1), 0x02),
        ("FC5 value 0x1234", struct.pack(">BHH", 5, 0, 0x1234), 0x03),
        ("FC16 byte count 3 for 2 registers", write_registers_pdu(0, [0, 0], byte_count=3), 0x03),
        ("FC16 second half of the float flow setpoint", write_registers_pdu(1, [0]), 0x03),
        ("FC16 flow setpoint 5000 (0..2000)", write_registers_pdu(0, encode(flow, 5e3)), 0x03),
        ("FC6 unmapped holding register 9", struct.pack(">BHH", 6, 9, 1), 0x02),
        (
            "FC23 reading unmapped registers",
            struct.pack(">BHHHHB2H", 23, 50, 1, 0, 2, 4, *encode(flow, 600.0)),
            0x02,
        ),
    ]


def _legal(srv) -> list[tuple[str, bytes]]:
    """Requests to the bench PLC every check passes: reads and writes of its points."""
    _, flow = point(srv, "bench_plc", "flow_setpoint")
    _, back = point(srv, "bench_plc", "return_setpoint")
    return [
        ("FC3 flow setpoint", read_pdu(3, flow.address, 2)),
        ("FC4 readings", read_pdu(4, 0, 4)),
        ("FC1 pump and heater", read_pdu(1, 0, 2)),
        ("FC43/14 device identification", bytes([43, 14, 1, 0])),
        ("FC16 flow setpoint 1234", write_registers_pdu(flow.address, encode(flow, 1234.0))),
        ("FC5 pump on", struct.pack(">BHH", 5, 0, 0xFF00)),
        ("FC15 pump and heater on", struct.pack(">BHHBB", 15, 0, 2, 1, 3)),
        (
            "FC23 return setpoint 77, read the flow setpoint",
            struct.pack(">BHHHHB2H", 23, flow.address, 2, back.address, 2, 4, *encode(back, 77)),
        ),
    ]


def _state(port: int) -> tuple[bytes, bytes]:
    """The PLC's setpoints (holding 0-3) and switches (coils 0-1), as read."""
    return ask(port, PLC, read_pdu(3, 0, 4)), ask(port, PLC, read_pdu(1, 0, 2))


async def _inject(server, *faults) -> None:
    for fault in faults:
        server.inject(fault)


@pytest.fixture
def faulty(serve):
    """A lockstep server whose bench PLC fails (04) and whose analyser is busy (06), and
    the PLC's state read before."""
    srv = serve()
    _, advance = point(srv, *ADVANCE)
    ask(srv.port, SIM, write_registers_pdu(advance.address, encode(advance, 1)))
    before = _state(srv.port)
    srv.call(
        _inject(
            srv.server,
            {"kind": "exception", "unit": PLC, "code": DEVICE_FAILURE},
            {"kind": "exception", "unit": ANALYSER, "code": BUSY},
        )
    )
    return srv, before


def test_a_failing_unit_answers_an_illegal_request_its_check_and_a_legal_one_04(faulty):
    """A stranger's probe: under an exception fault of code 04 an unsupported function
    code, a quantity of 0, an unmapped address and an FC5 value of 0x1234 all got 04, ahead
    of the spec's checks. 04 is a failure at the operation: each illegal request gets its
    01/03/02, each legal one 04, and nothing is written (read back once the fault is
    cleared)."""
    srv, before = faulty
    for label, pdu, code in _illegal(srv):
        assert ask(srv.port, PLC, pdu) == bytes([pdu[0] | 0x80, code]), label
    for label, pdu in _legal(srv):
        assert ask(srv.port, PLC, pdu) == bytes([pdu[0] | 0x80, DEVICE_FAILURE]), label
    ask(srv.port, SIM, struct.pack(">BHH", 6, 20, 2))  # fault_command 2: clear every fault
    assert _state(srv.port) == before  # no write of a request answered 04 was made
    _, flow = point(srv, "bench_plc", "flow_setpoint")
    assert registers_of(before[0])[:2] != encode(flow, 1234.0)  # (the test could fail)


def test_a_busy_unit_answers_every_request_its_code_before_any_check(faulty):
    """CONTRACT section 5: "the unit answers every request with that exception": a busy
    device (06) does, the illegal requests included, and changes nothing."""
    srv, _ = faulty
    requests = [(label, pdu) for label, pdu, _ in _illegal(srv)] + _legal(srv)
    for label, pdu in requests:
        assert ask(srv.port, ANALYSER, pdu) == bytes([pdu[0] | 0x80, BUSY]), label
