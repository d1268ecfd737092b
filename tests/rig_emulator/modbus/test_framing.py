"""Modbus TCP framing over real sockets (Messaging on TCP/IP Implementation Guide V1.0b):
any segmentation, pipelining, bad headers, in-order answers behind a slow request, and the
connection hygiene (idle timeout, connection limit).

The guide's MBAP header (its section 3.1.3, as quoted by e.g. the promo package's README):
"Length - The length field is a byte count of the following fields, including the Unit
Identifier and data fields"; "Protocol Identifier - It is used for intra-system
multiplexing. The MODBUS protocol is identified by the value 0". Its Transaction Identifier
"is used for transaction pairing" and lets a client have several transactions outstanding,
which is what pipelining is. The largest ADU, 260 bytes, is 7 header bytes and the 253-byte
PDU of the Application Protocol Specification 4.1. On a bad header its 4.4.2.2 says: "If
an error is detected on the MBAP, the indication is discarded"; a length over 254 leaves no
trustworthy way to find the next frame, and the connection is closed (see the README).
Connection management, its 4.2.1.2: "If the number of client and server connections is
greater than the number of authorized connections the oldest unused connection is closed."
"""

from __future__ import annotations

import logging
import random
import select
import struct
import threading
import time

import pytest

from rig_emulator.modbus.handler import GateDecision
from rig_emulator.registers import decode, encode
from tests.modbus_helpers import ADVANCE, point
from tests.rig_emulator.modbus.raw import (
    Replies,
    closed_by_server,
    connect,
    frame,
    read_pdu,
    registers_of,
    write_registers_pdu,
)

PLC, SIM = 1, 100


def _reads(n: int, first_tid: int = 1) -> tuple[bytes, list[int]]:
    """``n`` reads of 1..14 input registers of the PLC, as one byte string, and the
    register count of each."""
    counts = [1 + i % 14 for i in range(n)]
    stream = b"".join(frame(first_tid + i, PLC, read_pdu(4, 0, c)) for i, c in enumerate(counts))
    return stream, counts


def _check_read_replies(replies, counts, first_tid: int = 1) -> None:
    assert [tid for tid, _, _ in replies] == list(range(first_tid, first_tid + len(counts)))
    for (_, unit, pdu), count in zip(replies, counts, strict=True):
        assert unit == PLC and pdu[0] == 4 and pdu[1] == 2 * count


def test_frames_sent_one_byte_at_a_time_are_answered(serve):
    srv = serve()
    stream, counts = _reads(3)
    with connect(srv.port) as s:
        for i in range(len(stream)):
            s.sendall(stream[i : i + 1])
            time.sleep(0.001)  # one segment per byte (TCP_NODELAY)
        _check_read_replies(Replies(s).take(3), counts)


def test_150_pipelined_requests_in_one_segment_are_all_answered_in_order(serve):
    """1,800 bytes in one send: far over the 264-byte buffer that lost whole segments."""
    srv = serve()
    stream, counts = _reads(150)
    with connect(srv.port) as s:
        s.sendall(stream)
        _check_read_replies(Replies(s).take(150), counts)


def test_a_stream_cut_at_random_places_is_answered_frame_by_frame(serve):
    """Reads and writes of varied sizes, the byte stream cut at seeded random places into
    segments of 1 to 600 bytes; every answer matches its request."""
    srv = serve()
    _, flow = point(srv, "bench_plc", "flow_setpoint")
    rng = random.Random(11)
    frames, expect = [], []
    for tid in range(1, 301):
        if tid % 3 == 0:
            value = float(rng.randrange(100, 1500))
            frames.append(frame(tid, PLC, write_registers_pdu(flow.address, encode(flow, value))))
            expect.append(("write", value))
        else:
            frames.append(frame(tid, PLC, read_pdu(3, flow.address, 2)))
            expect.append(("read", expect[-1][1] if expect else None))
    stream = b"".join(frames)
    with connect(srv.port) as s:
        at = 0
        while at < len(stream):
            size = rng.randint(1, 600)
            s.sendall(stream[at : at + size])
            at += size
            if rng.random() < 0.3:
                time.sleep(0.002)
        replies = Replies(s).take(len(frames))
    last_written = None
    for (tid, _, pdu), (kind, value) in zip(replies, expect, strict=True):
        if kind == "write":
            assert pdu == struct.pack(">BHH", 16, flow.address, 2), tid
            last_written = value
        elif last_written is not None:
            assert decode(flow, registers_of(pdu)) == last_written, tid
    assert [tid for tid, _, _ in replies] == list(range(1, 301))


def test_an_undecodable_frame_does_not_discard_the_frames_after_it(serve):
    srv = serve()
    good, counts = _reads(2)
    stream = (
        good[: len(good) // 2]
        + frame(50, PLC, bytes([0x99, 1, 2, 3]))  # unknown function: 01
        + frame(51, PLC, bytes([3, 0]))  # truncated read: 03
        + frame(52, 42, bytes([0x42]))  # unknown unit: 0B
        + good[len(good) // 2 :]
    )
    with connect(srv.port) as s:
        s.sendall(stream)
        replies = Replies(s).take(5)
    assert replies[1:4] == [
        (50, PLC, bytes([0x99, 0x01])),
        (51, PLC, bytes([0x83, 0x03])),
        (52, 42, bytes([0xC2, 0x0B])),
    ]
    _check_read_replies([replies[0], replies[4]], counts)


@pytest.mark.parametrize(
    ("label", "bad"),
    [
        ("protocol id 1", struct.pack(">HHHB", 9, 1, 6, PLC) + read_pdu(4, 0, 1)),
        ("protocol id 0xFFFF", struct.pack(">HHHB", 9, 0xFFFF, 6, PLC) + read_pdu(4, 0, 1)),
        ("protocol id 5, 2-byte PDU", struct.pack(">HHHB", 9, 5, 3, PLC) + bytes([4, 0])),
    ],
)
def test_a_frame_with_a_wrong_mbap_header_is_discarded_and_the_rest_answered(
    serve, caplog, label, bad
):
    """The guide's 4.4.2.2: "If an error is detected on the MBAP, the indication is
    discarded"; "The Protocol Identifier field has to be checked: If it is different from
    MODBUS protocol type, the indication is simply discarded." Its length (2 to 254) still
    says where the next frame starts: no answer to it, the frames before and after it are
    answered on the same connection, one warning names it (two in a row are still
    discarded: three end the stream, see below)."""
    srv = serve()
    good, counts = _reads(2)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    with connect(srv.port) as s:
        s.sendall(good + bad + bad + good)
        replies = Replies(s).take(4)
        _check_read_replies(replies[:2], counts)
        _check_read_replies(replies[2:], counts)
        s.sendall(bad)  # alone in its segment: decided on its own bytes, nothing waits
        s.sendall(good)
        _check_read_replies(Replies(s).take(2), counts)
    assert sum("discarded a frame" in r.getMessage() for r in caplog.records) == 1, label


@pytest.mark.parametrize(
    ("label", "header"),
    [
        ("length 255", struct.pack(">HHHB", 9, 0, 255, PLC) + read_pdu(4, 0, 1)),
        ("length 0xFFFF", struct.pack(">HHHB", 9, 0, 0xFFFF, PLC) + read_pdu(4, 0, 1)),
        ("length 0xFFFF, 6 bytes only", struct.pack(">HHH", 9, 0, 0xFFFF)),
        ("length 0", struct.pack(">HHH", 9, 0, 0)),
        ("length 1", struct.pack(">HHHB", 9, 0, 1, PLC)),
        ("length 1, 6 bytes only", struct.pack(">HHH", 9, 0, 1)),
    ],
)
def test_a_length_over_254_or_below_2_answers_what_came_before_then_closes_with_a_log_line(
    serve, caplog, label, header
):
    """A frame longer than any Modbus TCP ADU (260 bytes), or a length that no frame has
    (the guide's 3.1.3: it counts the unit identifier and the PDU, so 1 leaves no function
    code and 0 not even the unit): the stream is out of step, its length cannot be trusted
    to find the next frame. Never a silent stall: the requests before it are answered, then
    the connection is closed (one warning naming the header), and the server serves
    others. Six bytes of header are enough to decide."""
    srv = serve()
    good, counts = _reads(2)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    with connect(srv.port) as s:
        s.sendall(good + header)
        _check_read_replies(Replies(s).take(2), counts)
        assert closed_by_server(s), label
    assert sum("bad MBAP header" in r.getMessage() for r in caplog.records) == 1
    with connect(srv.port) as s:
        s.sendall(good)
        _check_read_replies(Replies(s).take(2), counts)


def test_a_client_whose_length_leaves_out_a_byte_is_closed_not_left_hanging(serve, caplog):
    """A stranger's probe: a request whose MBAP length is one byte short (a client that
    leaves out the unit identifier) put every later header a byte off; each 6 bytes then
    read as a "frame" with protocol id not 0 and length 0, discarded one by one, and the
    well-formed requests after it got no answer until the 300 s idle timeout, the log
    saying "the frames after it are answered". Now the short frame gets its 03 (its PDU is
    cut), the out-of-step header after it closes the connection at once, and the log line
    says so."""
    srv = serve()
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    short = read_pdu(3, 0, 2)
    with connect(srv.port) as s:
        s.sendall(frame(7, PLC, short, length=len(short)))  # unit id + 4 of its 5 bytes
        assert Replies(s).next() == (7, PLC, bytes([0x83, 0x03]))
        s.sendall(frame(8, PLC, short))  # well formed, read from a byte off
        # 5 s: the old server held the connection open and silent for its idle timeout
        assert closed_by_server(s, timeout=5.0)
    messages = [r.getMessage() for r in caplog.records]
    closes = [m for m in messages if m.startswith("closing the connection")]
    assert len(closes) == 1 and "length field 0" in closes[0] and "out of step" in closes[0]
    assert not any("the frames after it are answered" in m for m in messages)
    good, counts = _reads(2)
    with connect(srv.port) as s:  # the server serves others as before
        s.sendall(good)
        _check_read_replies(Replies(s).take(2), counts)


@pytest.mark.parametrize("segments", ["one", "each alone"])
def test_three_frames_of_another_protocol_in_a_row_close_the_stream(serve, caplog, segments):
    """A stranger's probe showed a stream out of step yielding wrong frames one after the
    other, each discarded and none answered. Two in a row are discarded as the guide's
    4.4.2.2 says (the test above); a third with no valid frame between them shows the
    stream out of step, whether they come in one segment or one by one: the requests
    before them are answered, the connection is closed with one line saying why, the
    request after them is not answered."""
    srv = serve()
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    good, counts = _reads(2)
    bad = [struct.pack(">HHHB", 9 + i, 7, 6, PLC) + read_pdu(4, 0, 1) for i in range(3)]
    with connect(srv.port) as s:
        if segments == "one":
            s.sendall(good + b"".join(bad) + good)
        else:
            s.sendall(good)
            for piece in bad:
                time.sleep(0.05)  # each its own segment, parsed on its own (TCP_NODELAY)
                s.sendall(piece)
            s.sendall(good)
        replies = Replies(s)
        _check_read_replies(replies.take(2), counts)
        assert closed_by_server(s, timeout=5.0)  # (the 5 s a bound only: closed at once)
        assert replies.data == b"", "the request after the run was answered"
    messages = [r.getMessage() for r in caplog.records]
    closes = [m for m in messages if m.startswith("closing the connection")]
    assert len(closes) == 1 and "3 frames in a row" in closes[0], closes
    assert "transaction 11: protocol identifier 7" in closes[0]
    assert not any("the frames after it are answered" in m for m in messages)


def test_truncated_frames_then_close_leave_the_server_serving(serve):
    srv = serve()
    good, counts = _reads(1)
    for cut in (1, 5, 7, len(good) - 1):
        s = connect(srv.port)
        s.sendall(good[:cut])
        s.close()
    with connect(srv.port) as s:
        s.sendall(good)
        _check_read_replies(Replies(s).take(1), counts)


def test_answers_wait_in_order_behind_a_one_day_advance_while_others_are_served(serve):
    """A lockstep advance of 86,400 s (lab profile: runs in slices that await) holds the
    later requests of its own connection, which are then answered in order; another
    connection is answered meanwhile. Ordering and completion are asserted, not timings."""
    srv = serve(profile="lab")
    sim_dev, sim_time = point(srv, "sim_control", "sim_time")
    _, advance = point(srv, *ADVANCE)
    reads, counts = _reads(20, first_tid=3)
    batch = (
        frame(1, SIM, write_registers_pdu(advance.address, encode(advance, 86_400)))
        + frame(2, SIM, read_pdu(4, sim_time.address, 4))
        + reads
    )
    slow, other = connect(srv.port, timeout=60), connect(srv.port)
    slow.sendall(batch)
    deadline = time.monotonic() + 30
    while srv.server.emulator.sim_time_s == 0 and time.monotonic() < deadline:
        time.sleep(0.001)  # the advance is under way
    other_replies = Replies(other)
    answered_meanwhile = 0
    while not select.select([slow], [], [], 0)[0] and answered_meanwhile < 50:
        other.sendall(frame(answered_meanwhile, SIM, read_pdu(4, sim_time.address, 4)))
        _, _, pdu = other_replies.next()
        if not select.select([slow], [], [], 0)[0]:
            assert decode(sim_time, registers_of(pdu)) == 0.0  # the old state meanwhile
            answered_meanwhile += 1
    replies = Replies(slow).take(22)
    assert answered_meanwhile > 0, "no other client was answered during the advance"
    assert [tid for tid, _, _ in replies] == list(range(1, 23))
    assert replies[0][2] == struct.pack(">BHH", 16, advance.address, 2)
    assert decode(sim_time, registers_of(replies[1][2])) == 86_400.0
    _check_read_replies(replies[2:], counts, first_tid=3)
    slow.close()
    other.close()
    assert sim_dev.unit_id == SIM


def test_a_client_that_half_closes_gets_every_answer_then_the_close(serve):
    """Requests sent, then the client's side shut (FIN): the answers still come, all of
    them, behind a one-day advance, and then the server closes too."""
    import socket

    srv = serve(profile="lab")
    _, advance = point(srv, *ADVANCE)
    reads, counts = _reads(30, first_tid=2)
    with connect(srv.port, timeout=60) as s:
        s.sendall(frame(1, SIM, write_registers_pdu(advance.address, encode(advance, 86_400))))
        s.sendall(reads)
        s.shutdown(socket.SHUT_WR)
        replies = Replies(s).take(31)
        assert closed_by_server(s)
    assert replies[0][0] == 1
    _check_read_replies(replies[1:], counts, first_tid=2)


def test_100_kib_pipelined_behind_an_advance_are_all_answered_in_order(serve):
    """More than the 64 KiB a connection may queue: reading it stops (TCP flow control)
    until the queue drains, nothing is dropped."""
    srv = serve(profile="lab")
    _, advance = point(srv, *ADVANCE)
    n = 9000  # 108,000 bytes of 12-byte reads
    reads, counts = _reads(n, first_tid=2)
    stream = frame(1, SIM, write_registers_pdu(advance.address, encode(advance, 86_400))) + reads
    with connect(srv.port, timeout=60) as s:
        sender = threading.Thread(target=s.sendall, args=(stream,))
        sender.start()
        replies = Replies(s).take(n + 1)
        sender.join(timeout=60)
    assert replies[0][0] == 1
    _check_read_replies(replies[1:], counts, first_tid=2)


def test_idle_connections_are_closed_with_a_log_line_and_busy_ones_are_not(serve, caplog):
    srv = serve(idle_timeout_s=0.5)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    good, counts = _reads(1)
    idle, busy = connect(srv.port), connect(srv.port)
    replies = Replies(busy)
    for _ in range(15):  # 1.5 s of a request every 0.1 s: never idle for 0.5 s
        busy.sendall(good)
        _check_read_replies([replies.next()], counts)
        time.sleep(0.1)
    assert closed_by_server(idle, timeout=10)
    busy.sendall(good)
    _check_read_replies([replies.next()], counts)
    assert any("idle for" in r.getMessage() for r in caplog.records)
    busy.close()


def test_many_connections_closed_at_once_are_logged_in_a_line_with_a_count(
    serve, caplog, monkeypatch
):
    """30 silent connections timing out together wrote 30 lines (120 on TLS: 98 lines in
    2 s; a stranger's probe). One line per kind of close a 10 s, saying how many more; the
    burst's count is said when its interval ends (it waited for the next close; a re-probe).
    The interval is 2 s here, not 10, to keep the test short."""
    from rig_emulator.modbus import handler

    monkeypatch.setattr(handler, "_LIMIT_LOG_INTERVAL_S", 2.0)
    srv = serve(idle_timeout_s=0.5)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    silent = [connect(srv.port) for _ in range(30)]
    assert all(closed_by_server(s, timeout=10) for s in silent)
    lines = [r.getMessage() for r in caplog.records if "idle for" in r.getMessage()]
    assert len(lines) == 1, lines
    for s in silent:
        s.close()
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and not any(
        "29 more connection(s) closed (idle)" in r.getMessage() for r in caplog.records
    ):
        time.sleep(0.1)
    assert any("29 more connection(s) closed (idle)" in r.getMessage() for r in caplog.records)
    # the next, 10 s on, says how many the interval left out
    srv.server._server._closes["idle"] = (time.monotonic() - 11.0, 29)
    last = connect(srv.port)
    assert closed_by_server(last, timeout=10)
    lines = [r.getMessage() for r in caplog.records if "idle for" in r.getMessage()]
    assert len(lines) == 2 and "(29 more closed so since the last such line)" in lines[1]
    last.close()


def test_at_the_limit_a_new_connection_closes_the_oldest_unused_one(serve, caplog):
    """The guide's 4.2.1.2: "If the number of client and server connections is greater
    than the number of authorized connections the oldest unused connection is closed." The
    one that sent or was answered longest ago goes; the others and the new one are served;
    one log line says so."""
    srv = serve(max_connections=3)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    good, counts = _reads(1)
    kept = [connect(srv.port) for _ in range(3)]
    for s in (kept[1], kept[0], kept[2]):  # kept[1] is now the oldest unused
        s.sendall(good)
        _check_read_replies(Replies(s).take(1), counts)
        time.sleep(0.02)
    with connect(srv.port) as extra:
        extra.sendall(good)
        _check_read_replies(Replies(extra).take(1), counts)
        assert closed_by_server(kept[1])
        for s in (kept[0], kept[2]):
            s.sendall(good)
            _check_read_replies(Replies(s).take(1), counts)
    assert sum("closed the oldest unused" in r.getMessage() for r in caplog.records) == 1
    for s in kept:
        s.close()


def test_at_the_limit_silent_connections_go_before_a_client_that_polls(serve):
    """A stranger's probe: a client polling every second, answered 0.1 s before a burst of
    connections that never send a word, was the one closed at the limit (its last answer
    was older than their connects), again and again while the burst stayed open. A
    connection that never sent a request is the one left unused: those go first."""
    srv = serve(max_connections=10)
    poller = connect(srv.port)
    replies = Replies(poller)
    for tid in (1, 2):
        good, counts = _reads(1, first_tid=tid)
        poller.sendall(good)
        _check_read_replies(replies.take(1), counts, first_tid=tid)
        if tid == 1:
            time.sleep(0.1)
            silent = [connect(srv.port) for _ in range(30)]
            time.sleep(0.2)  # the server has accepted them all
    assert sum(closed_by_server(s, timeout=0.5) for s in silent) >= 20
    for s in [poller, *silent]:
        s.close()


def test_at_the_limit_half_sent_frames_go_before_a_client_that_polls(serve):
    """A stranger's probe: connections that sent 3 bytes of a header, or trickled a frame
    a byte at a time, counted as used from their last byte, so the poller (answered
    longest ago) was the one closed at the limit. Bytes that never make a request are not
    a use: those connections go first."""
    srv = serve(max_connections=5)
    poller = connect(srv.port)
    replies = Replies(poller)
    good, counts = _reads(1)
    poller.sendall(good)
    _check_read_replies(replies.take(1), counts)
    time.sleep(0.1)
    stalled = [connect(srv.port) for _ in range(4)]  # the limit is reached
    for i, s in enumerate(stalled):
        s.sendall(good[: 3 + i])  # part of a header, never the rest
    time.sleep(0.2)
    for s in stalled[:2]:  # still "sending": one more byte each, later than the poll
        s.sendall(good[5:6])
    time.sleep(0.2)
    newcomers = [connect(srv.port) for _ in range(4)]
    time.sleep(0.3)  # the server has accepted them all
    assert all(closed_by_server(s, timeout=5) for s in stalled)
    assert not closed_by_server(poller, timeout=0.3)
    good, counts = _reads(1, first_tid=2)
    poller.sendall(good)
    _check_read_replies(replies.take(1), counts, first_tid=2)
    for s in [poller, *stalled, *newcomers]:
        s.close()


def test_a_frame_trickled_in_for_ever_is_closed_at_the_idle_timeout(serve, caplog):
    """A stranger's probe: a byte a second kept a connection open past --idle-timeout for
    good (a slowloris holding a place). What counts is a whole request; the log says the
    request was left incomplete."""
    srv = serve(idle_timeout_s=1.0)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    slow = connect(srv.port)
    # a header announcing the longest frame, then a byte every 0.2 s: 40 bytes never make it
    trickle = [struct.pack(">HHHB", 1, 0, 254, 1)] + [b"\x03"] * 40
    closed = False
    for chunk in trickle:
        try:
            slow.sendall(chunk)
        except OSError:
            closed = True
            break
        if closed_by_server(slow, timeout=0.2):
            closed = True
            break
    assert closed
    assert any("a request left incomplete for" in r.getMessage() for r in caplog.records)
    slow.close()


def test_at_the_limit_with_every_connection_waiting_the_new_one_is_refused(serve, caplog):
    """No connection is unused (each has a request waiting behind a 2-s gate): the new one
    is closed with a log line, and the waiting ones get their answers."""
    srv = serve(max_connections=2)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")

    async def slow_gate() -> None:
        srv.server._server.gates[:] = [lambda info: GateDecision(delay_s=2.0)]

    srv.call(slow_gate())
    good, counts = _reads(1)
    waiting = [connect(srv.port, timeout=30) for _ in range(2)]
    for s in waiting:
        s.sendall(good)
    time.sleep(0.2)  # both requests are held by the gate
    extra = connect(srv.port)
    assert closed_by_server(extra)
    assert sum("refused the connection" in r.getMessage() for r in caplog.records) == 1
    for s in waiting:
        _check_read_replies(Replies(s).take(1), counts)
        s.close()


def test_connections_left_without_a_word_do_not_lock_out_a_real_client(serve):
    """A burst of connects that close at once (their ends not yet read when the next comes)
    filled the limit and refused the client after them; now they are the oldest unused
    connections and make room."""
    srv = serve(max_connections=10)
    good, counts = _reads(1)
    for _ in range(100):
        connect(srv.port).close()
    with connect(srv.port) as s:
        s.sendall(good)
        _check_read_replies(Replies(s).take(1), counts)
