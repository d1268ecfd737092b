"""A request a delay fault holds is answered at once when that fault ends, over real sockets:
cleared by the command block, its ``for_s`` elapsed under a lockstep advance, the plant
reset; the later requests of its connection follow in order. A stranger's probe: a cleared
20 s delay still held the read it had taken, answered 19 s after the clear."""

from __future__ import annotations

import time

import pytest

from rig_emulator.faults.wire import KIND_CODES
from rig_emulator.registers import encode
from tests.modbus_helpers import point
from tests.rig_emulator.modbus.raw import (
    Replies,
    connect,
    frame,
    read_pdu,
    registers_of,
    write_registers_pdu,
)

DELAY_MS = 20000.0  # held this long if the fault's end did not let it go
#: how soon after the fault's end the held read must be answered: a loop turn and a local
#: round trip take milliseconds; 2 s leaves room for a busy 2-core machine, and is a tenth
#: of the delay the request would otherwise wait
PROMPT_S = 2.0


def _set_delay(srv, for_s: float) -> list[int]:
    """The command block's registers setting a 20 s delay on unit 1 now (command 1)."""
    words: list[int] = []
    for name, value in (
        ("fault_kind", KIND_CODES["delay"]),
        ("fault_target", 1),
        ("fault_parameter", DELAY_MS),
        ("fault_duration", for_s),
        ("fault_at", 0.0),
        ("fault_command", 1),
    ):
        words += encode(point(srv, "sim_control", name)[1], value)
    return words


def _write(sock, srv, name: str, value: float, tid: int) -> None:
    """Write one sim_control point on ``sock`` and check it was taken."""
    dev, p = point(srv, "sim_control", name)
    sock.sendall(frame(tid, dev.unit_id, write_registers_pdu(p.address, encode(p, value))))
    got_tid, _, pdu = Replies(sock).next()
    assert got_tid == tid and pdu[0] == 16, pdu.hex()


def _held_read(srv, for_s: float):
    """Set the delay (on its own connection), then two reads pipelined on connection A,
    the first to the delayed unit 1, the second to unit 2; neither answered yet."""
    control = connect(srv.port)
    dev, _ = point(srv, "sim_control", "fault_kind")
    control.sendall(frame(1, dev.unit_id, write_registers_pdu(10, _set_delay(srv, for_s))))
    assert Replies(control).next()[2][0] == 16
    held = connect(srv.port)
    held.sendall(frame(7, 1, read_pdu(4, 0, 2)) + frame(8, 2, read_pdu(4, 0, 2)))
    held.settimeout(0.5)
    with pytest.raises(TimeoutError):  # the delay holds the read (and the one behind it)
        held.recv(1)
    held.settimeout(DELAY_MS / 1000.0 + 10.0)
    return control, held


def _answered_in_order(held) -> float:
    """Seconds until both held reads are answered; they come in the order sent."""
    t0 = time.monotonic()
    replies = Replies(held).take(2)
    elapsed_s = time.monotonic() - t0
    assert [(tid, unit, pdu[0]) for tid, unit, pdu in replies] == [(7, 1, 4), (8, 2, 4)]
    assert all(len(registers_of(pdu)) == 2 for _, _, pdu in replies)
    return elapsed_s


def test_a_cleared_delay_lets_the_request_it_holds_go(serve):
    srv = serve()
    control, held = _held_read(srv, 0.0)  # until cleared
    _write(control, srv, "fault_command", 2, tid=2)  # clear every fault
    assert _answered_in_order(held) < PROMPT_S
    # and the next request is not delayed
    held.sendall(frame(9, 1, read_pdu(4, 0, 2)))
    t0 = time.monotonic()
    assert Replies(held).next()[0] == 9 and time.monotonic() - t0 < PROMPT_S
    control.close()
    held.close()


def test_a_delay_whose_for_s_elapses_lets_the_request_it_holds_go(serve):
    srv = serve()
    control, held = _held_read(srv, 5.0)
    _write(control, srv, "lockstep_advance", 6.0, tid=2)  # past its 5 s
    assert _answered_in_order(held) < PROMPT_S
    control.close()
    held.close()


def test_a_reset_lets_the_request_a_delay_holds_go(serve):
    srv = serve(allow_control=True)
    control = connect(srv.port)
    _write(control, srv, "lockstep_advance", 2.0, tid=1)  # a reset goes back in time
    control.close()
    control, held = _held_read(srv, 0.0)
    _write(control, srv, "reset", 1, tid=2)
    assert _answered_in_order(held) < PROMPT_S
    control.close()
    held.close()


def test_an_uncleared_delay_still_holds_the_request(serve):
    """The delay itself still acts (the release does not answer early on its own)."""
    srv = serve()
    faults = srv.server.faults.engine
    control, held = _held_read(srv, 0.0)
    held.settimeout(1.5)
    with pytest.raises(TimeoutError):
        held.recv(1)
    assert [f.spec.kind for f in faults.active.values()] == ["delay"]
    held.settimeout(DELAY_MS / 1000.0 + 10.0)
    _write(control, srv, "fault_command", 2, tid=2)
    assert _answered_in_order(held) < PROMPT_S
    control.close()
    held.close()
