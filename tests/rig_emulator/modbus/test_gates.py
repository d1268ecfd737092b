"""The server's gates (the interface the TLS and fault-injection layers plug into), over a
real socket: a gate can delay an answer (later requests of the connection wait behind it,
other connections do not), drop it, or force an exception code that changes nothing."""

from __future__ import annotations

from rig_emulator.modbus.handler import GateDecision, RequestInfo
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

SERVER_BUSY = 0x06  # an exception code the server never answers by itself


def _install(srv, *gates) -> list[RequestInfo]:
    """Put ``gates`` on the running server; returns the list of requests the first saw."""
    seen: list[RequestInfo] = []

    def recorder(info: RequestInfo) -> None:
        seen.append(info)

    async def put() -> None:
        srv.server._server.gates[:] = [recorder, *gates]

    srv.call(put())
    return seen


def test_a_gate_sees_every_decoded_request_with_its_unit_function_and_peer(serve):
    srv = serve()
    seen = _install(srv)
    with connect(srv.port) as s:
        s.sendall(frame(1, 1, read_pdu(4, 0, 2)) + frame(2, 42, read_pdu(3, 0, 1)))
        Replies(s).take(2)
        host, port = s.getsockname()[:2]
        local = f"{host}:{port}"
    assert [(i.unit_id, i.function_code, i.peer, i.role) for i in seen] == [
        (1, 4, local, None),
        (42, 3, local, None),
    ]


def test_a_delayed_answer_holds_later_answers_of_its_connection_but_not_others(serve):
    srv = serve()
    _install(srv, lambda info: GateDecision(delay_s=2.0) if info.unit_id == 2 else None)
    slow = connect(srv.port)
    other = connect(srv.port)
    slow.sendall(frame(1, 2, read_pdu(4, 0, 2)) + frame(2, 1, read_pdu(4, 0, 2)))
    other.sendall(frame(7, 1, read_pdu(4, 0, 2)))
    assert Replies(other).next()[0] == 7  # answered while the slow connection waits
    slow.setblocking(False)
    try:
        early = slow.recv(4096)
    except BlockingIOError:
        early = b""
    assert early == b""  # not even the undelayed second request jumped the queue
    slow.setblocking(True)
    slow.settimeout(10)
    assert [tid for tid, _, _ in Replies(slow).take(2)] == [1, 2]
    slow.close()
    other.close()


def test_a_dropped_request_gets_no_reply_and_the_next_one_is_answered(serve):
    srv = serve()
    _install(srv, lambda info: GateDecision(drop=True) if info.function_code == 3 else None)
    with connect(srv.port) as s:
        s.sendall(frame(1, 1, read_pdu(3, 0, 2)) + frame(2, 1, read_pdu(4, 0, 2)))
        tid, unit, pdu = Replies(s).next()
        assert (tid, unit, pdu[0]) == (2, 1, 4)
        s.settimeout(0.5)
        try:
            extra = s.recv(4096)
        except TimeoutError:
            extra = b""
    assert extra == b""  # the dropped one never comes


def test_a_forced_exception_is_answered_and_changes_nothing(serve):
    srv = serve()
    dev, flow = point(srv, "bench_plc", "flow_setpoint")
    before = srv.values()["water_flow_setpoint_kg_h"]
    _install(
        srv,
        lambda info: GateDecision(exception_code=SERVER_BUSY) if info.function_code == 16 else None,
    )
    with connect(srv.port) as s:
        s.sendall(frame(1, dev.unit_id, write_registers_pdu(flow.address, encode(flow, 432.0))))
        s.sendall(frame(2, dev.unit_id, read_pdu(3, flow.address, 2)))
        (_, _, refused), (_, _, readback) = Replies(s).take(2)
    assert refused == bytes([0x90, SERVER_BUSY])
    assert srv.values()["water_flow_setpoint_kg_h"] == before != 432.0
    assert registers_of(readback) == encode(flow, before)


def test_the_first_decision_wins(serve):
    srv = serve()
    _install(
        srv,
        lambda info: None,
        lambda info: GateDecision(exception_code=0x0A),
        lambda info: GateDecision(drop=True),
    )
    with connect(srv.port) as s:
        s.sendall(frame(3, 1, read_pdu(4, 0, 2)))
        assert Replies(s).next() == (3, 1, bytes([0x84, 0x0A]))


def test_close_all_connections_closes_them_and_the_server_accepts_new_ones(serve):
    srv = serve()
    socks = [connect(srv.port) for _ in range(3)]
    for s in socks:  # each is open and served
        s.sendall(frame(1, 1, read_pdu(4, 0, 1)))
        Replies(s).next()

    async def close_all() -> int:
        return srv.server._server.close_all_connections("test")

    assert srv.call(close_all()) == 3
    for s in socks:
        s.settimeout(10)
        assert s.recv(1) == b""
        s.close()
    with connect(srv.port) as s:
        s.sendall(frame(9, 1, read_pdu(4, 0, 1)))
        assert Replies(s).next()[0] == 9
