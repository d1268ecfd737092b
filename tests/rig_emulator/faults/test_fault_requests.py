"""What the fault journal counts (``requests`` on a communication fault's end line) and how
long an RTU delay holds a reply, over real sockets and a real pseudo-terminal: a request
counts once, for the faults whose effect it got; an exception-04 fault does not count the
illegal requests the spec's checks answered first; a held request counts for the delay it
waited out; an RTU read answered ahead whose frame went on counts for nothing, and an RTU
broadcast for no delay; a delay cleared mid-request lets the RTU reply go at once, as on
TCP."""

from __future__ import annotations

import contextlib
import struct
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

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


@contextlib.contextmanager
def _rtu_line(srv, baud: int = BAUD) -> Iterator[Line]:
    """A client on a new RTU pty of ``srv`` at ``baud`` (parity E); the line stops after."""

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", baud, "E")

    transports, rtu = srv.call(setup())
    line = Line(rtu.path)
    try:
        yield line
    finally:
        line.close()
        srv.call(transports.stop())


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
    with _rtu_line(srv) as line:
        _advance(srv, 1)
        yield srv, line


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


#: The line speed of the read-ahead test [baud], and when a stray byte follows a read [s]:
#: at 1,200 baud a read's 8 characters take 73 ms and its silence 32 ms more, so a byte
#: 10 ms after the read belongs to its frame even on a loaded machine, while the server has
#: seen the read whole first and answered it ahead (a byte read with the frame, had the
#: server's thread come late, makes no read-ahead: the count is right either way)
READ_AHEAD_BAUD, STRAY_AFTER_S = 1200, 0.01
#: How long a reply that does not come is waited for [s]: a read, its silence and a 5-byte
#: reply take 160 ms at 1,200 baud; the rest is room for a loaded machine
NO_REPLY_S = 0.6


def test_an_rtu_read_answered_ahead_whose_frame_went_on_counts_for_nothing(serve, tmp_path):
    """A re-probe: the line answers a read as soon as its bytes form a frame and drops that
    answer when more bytes follow, but the fault's count stayed. Under an exception 06 on
    the analyser, three reads each followed by a stray 0x55 (a frame with a bad CRC: no
    reply), three followed by 0x00 (a valid 9-byte frame, answered once) and a plain read
    (4 replies on the line) were journalled as 10 requests. They are 4."""
    journal = tmp_path / "journal.jsonl"
    srv = serve(
        faults=faults_from_list([{"kind": "exception", "unit": ANALYSER, "code": 6, "at_s": 1}]),
        fault_log=journal,
    )
    _advance(srv, 1)
    read = rtu_frame(ANALYSER, read_pdu(4, 0, 2))
    busy = rtu_frame(ANALYSER, bytes([0x84, 6]))
    with _rtu_line(srv, READ_AHEAD_BAUD) as line:
        for stray, reply in ((b"\x55", b""), (b"\x00", busy)):
            for _ in range(3):
                line.send(read)
                time.sleep(STRAY_AFTER_S)
                line.send(stray)
                assert line.read(len(busy), timeout_s=NO_REPLY_S) == reply
        line.send(read)
        assert line.read(len(busy), timeout_s=NO_REPLY_S) == busy
    ask(srv.port, SIM, CLEAR)
    assert _requests(journal) == {("exception", ANALYSER, 6): 4}


#: The RTU broadcast test's delay [ms]: short, the read waits it out
BROADCAST_TEST_DELAY_MS = 300.0
#: The pause after a broadcast [s]: its wire time and silence (7 ms at 19,200 baud), with
#: room for a loaded machine (as test_rtu's LOADED_MACHINE_GAP_S)
AFTER_BROADCAST_S = 0.25


def test_an_rtu_broadcast_counts_for_no_delay_and_once_for_another_fault(serve, tmp_path):
    """A re-probe: a delay fault on unit 1 counted RTU broadcasts, which get no reply and so
    no delay: three broadcasts and one read were journalled as 4 requests. An exception 06
    on every unit counted each broadcast once per instrument unit it reached (7). A
    broadcast is one request: no delay fault counts it, and a fault that kept the units
    from carrying it out counts it once."""
    journal = tmp_path / "journal.jsonl"
    delay = {"kind": "delay", "unit": 1, "delay_ms": BROADCAST_TEST_DELAY_MS, "at_s": 1}
    busy = {"kind": "exception", "unit": 0, "code": 6, "at_s": 1}
    srv = serve(faults=faults_from_list([delay, busy]), fault_log=journal)
    _advance(srv, 1)
    setpoint = struct.pack(">BHHBf", 16, 0, 2, 4, 500.0)  # flow setpoint of unit 1
    with _rtu_line(srv) as line:
        for _ in range(3):
            line.send(rtu_frame(0, setpoint))
            assert line.read(64, timeout_s=AFTER_BROADCAST_S) == b""
        # the line answers frames in order: this reply comes after every broadcast was done
        line.send(rtu_frame(1, read_pdu(3, 0, 2)))
        assert line.read(5, timeout_s=2.0) == rtu_frame(1, bytes([0x83, 6]))
    ask(srv.port, SIM, CLEAR)
    assert _requests(journal) == {
        ("delay", 1, BROADCAST_TEST_DELAY_MS): 1,
        ("exception", 0, 6): 4,
    }


#: The delays of the overlap test [ms]: the analyser's long one ends (its for_s, 1 s of
#: simulated time) while the short one on every unit still holds the read
LONG_DELAY_MS, SHORT_DELAY_MS = 6000.0, 2000.0
#: How long to wait for the read to be decided [s] (a few ms unloaded)
DECIDED_WITHIN_S = 10.0


def _when_decided(srv, fault_id: int) -> None:
    """Wait until fault ``fault_id`` holds a request (it counted it)."""
    fault = srv.server.faults.engine.active[fault_id]
    deadline = time.monotonic() + DECIDED_WITHIN_S
    while fault.requests == 0 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert fault.requests == 1


def test_a_held_request_counts_for_the_delay_it_waited_out(serve, tmp_path):
    """A re-probe: a 6000-ms delay of 1 s on the analyser and a 3000-ms delay on every unit;
    a read over TCP and one over RTU each waited out the 3000-ms delay (the 6000-ms one
    ended after a second), yet the journal credited each to the 6000-ms fault and none to
    the 3000-ms one. A request counts for the delay fault whose delay it waited out (as a
    shorter delay another overrides counts nothing): a delay that ends while another still
    holds the request passes the count on."""
    journal = tmp_path / "journal.jsonl"
    faults = faults_from_list(
        [
            {"kind": "delay", "unit": 0, "delay_ms": SHORT_DELAY_MS, "at_s": 1},
            {"kind": "delay", "unit": ANALYSER, "delay_ms": LONG_DELAY_MS, "at_s": 1, "for_s": 1},
            {"kind": "delay", "unit": ANALYSER, "delay_ms": LONG_DELAY_MS, "at_s": 3, "for_s": 1},
        ]
    )
    srv = serve(faults=faults, fault_log=journal)
    _advance(srv, 1)  # the short delay (fault 1) and the first long one (2) start
    with ThreadPoolExecutor(1) as pool:
        reply = pool.submit(ask, srv.port, ANALYSER, read_pdu(4, 0, 2))
        _when_decided(srv, 2)
        _advance(srv, 1)  # the long delay's for_s elapses, the read held
        assert reply.result(timeout=LONG_DELAY_MS / 1000)[:2] == bytes([4, 4])
    _advance(srv, 1)  # the second long delay (3) starts
    with _rtu_line(srv) as line:
        line.send(rtu_frame(ANALYSER, read_pdu(4, 0, 2)))
        _when_decided(srv, 3)
        _advance(srv, 1)
        assert line.read(9, timeout_s=LONG_DELAY_MS / 1000)[:3] == bytes([ANALYSER, 4, 4])
    ask(srv.port, SIM, CLEAR)
    assert [(e["id"], e["requests"]) for e in read_journal(journal) if e["event"] == "end"] == [
        (2, 0),
        (3, 0),
        (1, 2),
    ]


def test_delays_that_end_together_keep_the_count_where_it_was(serve, tmp_path):
    """The other side of the count passed on: delay faults that end together (a clear, or
    one evaluation) pass it to none of them. A read held by a 6000-ms delay on the analyser
    and a 2000-ms delay on every unit, both cleared, got the longer one's effect until the
    clear: it counts for that one, not for the shorter one that happened to end after it."""
    journal = tmp_path / "journal.jsonl"
    faults = faults_from_list(
        [
            {"kind": "delay", "unit": ANALYSER, "delay_ms": LONG_DELAY_MS, "at_s": 1},
            {"kind": "delay", "unit": 0, "delay_ms": SHORT_DELAY_MS, "at_s": 1},
        ]
    )
    srv = serve(faults=faults, fault_log=journal)
    _advance(srv, 1)
    with ThreadPoolExecutor(1) as pool:
        reply = pool.submit(ask, srv.port, ANALYSER, read_pdu(4, 0, 2))
        _when_decided(srv, 1)
        ask(srv.port, SIM, CLEAR)
        assert reply.result(timeout=LONG_DELAY_MS / 1000)[:2] == bytes([4, 4])
    assert [(e["id"], e["requests"]) for e in read_journal(journal) if e["event"] == "end"] == [
        (1, 1),
        (2, 0),
    ]
