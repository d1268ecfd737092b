"""What the fault journal counts (``requests`` on a communication fault's end line) and how
long an RTU delay holds a reply, over real sockets and a real pseudo-terminal: a request
counts once, for the faults whose effect it got; an exception-04 fault does not count the
illegal requests the spec's checks answered first; a delay cleared mid-request lets the
RTU reply go at once, as on TCP."""

from __future__ import annotations

import struct
import threading
import time

import pytest

from rig_emulator.faults import faults_from_list, read_journal
from rig_emulator.modbus.transports import Transports
from rig_emulator.registers import encode
from tests.modbus_helpers import ADVANCE, point
from tests.rig_emulator.modbus.raw import ask, read_pdu, write_registers_pdu
from tests.rig_emulator.transports.test_rtu import BAUD, Line, rtu_frame

ANALYSER, FID, SIM = 2, 3, 100
CLEAR = struct.pack(">BHH", 6, 20, 2)  # FC6 fault_command 2: clear every fault


def _advance(srv, seconds: int) -> None:
    _, advance = point(srv, *ADVANCE)
    reply = ask(srv.port, SIM, write_registers_pdu(advance.address, encode(advance, seconds)))
    assert reply[0] == 16, reply


def _requests(journal) -> dict[tuple, int]:
    """Per ended communication fault, (kind, unit, parameter): the requests journalled."""
    return {
        (e["kind"], e["unit"], e.get("code", e.get("delay_ms"))): e["requests"]
        for e in read_journal(journal)
        if e["event"] == "end"
    }


def test_overlapping_faults_of_a_unit_count_a_request_once(serve, tmp_path):
    """A stranger's probe: an exception 06 on the analyser and an 0B on every unit, and two
    delays (50 and 100 ms) on the FID, all at once; five reads of each unit (ten requests)
    were journalled as 25: the 0B fault counted the analyser's reads it never answered
    (they got 06) and the 50-ms delay the FID's, held 100 ms by the other. Now each
    request counts for the faults whose effect it got: the analyser's for the 06, the FID's
    for the 0B and the 100-ms delay."""
    journal = tmp_path / "journal.jsonl"
    faults = faults_from_list(
        [
            {"kind": "exception", "unit": ANALYSER, "code": 6, "at_s": 1},
            {"kind": "exception", "unit": 0, "code": 11, "at_s": 1},
            {"kind": "delay", "unit": FID, "delay_ms": 50, "at_s": 1},
            {"kind": "delay", "unit": FID, "delay_ms": 100, "at_s": 1},
        ]
    )
    srv = serve(faults=faults, fault_log=journal)
    _advance(srv, 1)
    for unit, code in ((ANALYSER, 6), (FID, 11)):
        for _ in range(5):
            assert ask(srv.port, unit, read_pdu(4, 0, 2)) == bytes([0x84, code])
    ask(srv.port, SIM, CLEAR)
    assert _requests(journal) == {
        ("exception", ANALYSER, 6): 5,
        ("exception", 0, 11): 5,
        ("delay", FID, 50.0): 0,
        ("delay", FID, 100.0): 5,
    }


def test_an_exception_04_fault_counts_only_the_requests_it_answered(serve, tmp_path):
    """A stranger's probe: under an exception-04 fault on the analyser one legal read (04)
    and three illegal requests (an unmapped address: 02, a quantity of 0: 03, an
    unsupported function: 01, each checked before the fault) were journalled as four
    requests answered by the fault. It answered one."""
    journal = tmp_path / "journal.jsonl"
    srv = serve(
        faults=faults_from_list([{"kind": "exception", "unit": ANALYSER, "code": 4, "at_s": 1}]),
        fault_log=journal,
    )
    _advance(srv, 1)
    for pdu, code in (
        (read_pdu(4, 0, 2), 0x04),
        (read_pdu(4, 900, 2), 0x02),
        (read_pdu(3, 0, 0), 0x03),
        (bytes([0x41, 0, 0]), 0x01),
    ):
        assert ask(srv.port, ANALYSER, pdu) == bytes([pdu[0] | 0x80, code])
    ask(srv.port, SIM, CLEAR)
    assert _requests(journal) == {("exception", ANALYSER, 4): 1}


#: The delay of the RTU test [s], and when the test clears it into the request [s]
DELAY_S, CLEARED_AFTER_S = 6.0, 1.0
#: How late after the clear the reply may come [s]: the clear's own TCP round trip and the
#: line's wire time and silences (a few ms) on a loaded 2-core machine; far below the 5 s of
#: delay left, which the reply waited before
REPLY_AFTER_CLEAR_S = 2.0


@pytest.fixture
def slow_line(serve):
    """A lockstep server whose analyser replies 6 s late, and a client on its RTU pty."""
    srv = serve(faults=faults_from_list([{"kind": "delay", "unit": ANALYSER, "delay_ms": 6000}]))

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", BAUD, "E")

    transports, rtu = srv.call(setup())
    _advance(srv, 1)
    line = Line(rtu.path)
    yield srv, line
    line.close()
    srv.call(transports.stop())


def test_an_rtu_reply_held_by_a_cleared_delay_goes_at_the_clear(slow_line):
    """A stranger's probe: a 6-s delay fault on the analyser cleared a second into an RTU
    read still held the reply for the whole 6 s (over TCP it came at the clear). The reply
    now comes at the clear, on the line as on TCP."""
    srv, line = slow_line
    clearer = threading.Timer(CLEARED_AFTER_S, ask, (srv.port, SIM, CLEAR))
    started = line.send(rtu_frame(ANALYSER, read_pdu(4, 0, 2)))
    clearer.start()
    try:
        reply = line.read(9, timeout_s=CLEARED_AFTER_S + REPLY_AFTER_CLEAR_S)
        took_s = time.monotonic() - started
    finally:
        clearer.join()
    assert len(reply) == 9 and reply[:3] == bytes([ANALYSER, 4, 4]), reply
    assert CLEARED_AFTER_S <= took_s < CLEARED_AFTER_S + REPLY_AFTER_CLEAR_S < DELAY_S
