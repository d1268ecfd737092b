"""The role gate asks for every right a request needs, and a malformed role extension may do
nothing whatever a roles file says: ``rig-emulator serve`` as its own process, over real TLS
sockets and a real pty (requests built byte by byte)."""

from __future__ import annotations

import struct

import pytest

from rig_emulator.certs import Issued, make_ca, make_client, make_server, write_pair
from rig_emulator.modbus.roles import INVALID_ROLE, Role, RolePolicy
from tests.rig_emulator.transports.served import (
    RtuClient,
    run_serve,
    serving,
    tcp_exchange,
    tls_connect,
    with_role_extension,
)

#: the stranger's roles file: the operator reads only unit 7, writes units 1 and 7
ROLES_FC23 = """\
roles:
  observer:
    read: all
  operator:
    read: [7]
    write: [1, 7]
  engineer:
    read: all
    write: all
default_role: observer
"""
FLOW_400 = struct.pack(">f", 400.0)  # unit 1's flow setpoint, holding 0-1


def _fc23(read_address: int, read_count: int, write_address: int, values: bytes) -> bytes:
    count = len(values) // 2
    return struct.pack(">BHHHHB", 23, read_address, read_count, write_address, count, len(values))


def _lab(tmp_path, *clients: tuple[str, str]) -> tuple[Issued, list[str]]:
    """A CA, a server certificate and ``(stem, role)`` client certificates in ``tmp_path``;
    the TLS options of ``serve``."""
    ca = make_ca()
    write_pair(ca, tmp_path, "ca")
    write_pair(make_server(ca), tmp_path, "server")
    for stem, role in clients:
        write_pair(make_client(ca, stem, role), tmp_path, stem)
    options = ["--tls-cert", str(tmp_path / "server.pem"), "--tls-key"]
    options += [str(tmp_path / "server.key"), "--tls-ca", str(tmp_path / "ca.pem")]
    return ca, options


def test_fc23_needs_read_and_write_over_tls_and_rtu(tmp_path):
    """A stranger's probe: an operator that writes unit 1 but may not read it got 01 for an
    FC3 to unit 1, while an FC23 to unit 1 wrote the flow setpoint AND returned unit 1's
    holding registers, over TLS and over RTU with ``--plain-role operator``. Now it gets 01
    and nothing is written; to unit 7, which it reads and writes, FC23 is answered."""
    _, tls = _lab(tmp_path, ("operator", "operator"), ("engineer", "engineer"))
    roles = tmp_path / "roles.yaml"
    roles.write_text(ROLES_FC23)
    options = [*tls, "--roles", str(roles), "--serial", "pty", "--plain-role", "operator"]
    with serving(*options, serial=True) as served:
        engineer = tls_connect(served.port, tmp_path, "engineer")
        operator = tls_connect(served.port, tmp_path, "operator")
        line = RtuClient(served.serial)
        try:
            holding_of_unit_1 = struct.pack(">BHH", 3, 0, 4)
            before = tcp_exchange(engineer, 1, holding_of_unit_1)
            assert before[:2] == bytes([3, 8])
            for exchange in (
                lambda pdu: tcp_exchange(operator, 1, pdu),
                lambda pdu: line.exchange(1, pdu),
            ):
                assert exchange(holding_of_unit_1) == bytes([0x83, 0x01])
                assert exchange(_fc23(0, 4, 0, FLOW_400) + FLOW_400) == bytes([0x97, 0x01])
                assert tcp_exchange(engineer, 1, holding_of_unit_1) == before  # nothing written
            # unit 7, which the operator reads and writes: set temperature 60.0 (raw 600)
            answer = tcp_exchange(operator, 7, _fc23(0, 1, 0, b"\x02\x58") + b"\x02\x58")
            assert answer == bytes([23, 2, 0x02, 0x58])
            answer = line.exchange(7, _fc23(0, 1, 0, b"\x02\x62") + b"\x02\x62")
            assert answer == bytes([23, 2, 0x02, 0x62])
        finally:
            line.close()
            engineer.close()
            operator.close()
    summary = next(line for line in served.stderr if "roles:" in line)
    # it said "operator writes units 1, 7": what the role reads is said too
    assert "operator reads unit 7, writes units 1, 7" in summary, summary
    assert "observer reads every unit, writes no unit" in summary, summary


def test_device_identification_needs_read_and_other_mei_types_need_both(tmp_path):
    """Function 43's right depends on its MEI type: 14 (read device identification) only
    reads, so an observer gets its answer; any other type may write (13, CANopen), so a role
    that only reads the unit gets 01, before the server's own 01 for an MEI type it lacks."""
    _, tls = _lab(tmp_path, ("observer", "observer"))
    with serving(*tls) as served:
        observer = tls_connect(served.port, tmp_path, "observer")
        try:
            answer = tcp_exchange(observer, 2, bytes([43, 14, 1, 0]))
            assert answer[:3] == bytes([43, 14, 1]) and b"flue_gas_analyser" in answer
            assert tcp_exchange(observer, 2, bytes([43, 13, 0, 0])) == bytes([0xAB, 0x01])
        finally:
            observer.close()
    assert any("refused function 43 to unit 2" in line for line in served.stderr), served.stderr


def test_a_roles_file_cannot_name_the_invalid_role(tmp_path):
    """A stranger's probe: a roles file defining ``"<invalid role extension>": {read: all,
    write: all}`` gave every certificate with a malformed role extension (a PrintableString,
    the extension twice) the right to write everything. Such a file is refused in one line,
    exit 2, as is a role name with a control character."""
    _, tls = _lab(tmp_path)
    for name, fault in (
        (f'"{INVALID_ROLE}"', "is in angle brackets, the form of the server's own stand-ins"),
        ('"engineer\\u0000"', "holds U+0000: a control character"),
    ):
        roles = tmp_path / "roles.yaml"
        roles.write_text(
            f"roles:\n  observer: {{read: all}}\n  {name}: {{read: all, write: all}}\n"
        )
        done = run_serve("--port", "0", *tls, "--roles", str(roles))
        assert done.returncode == 2, done.stderr
        assert done.stderr.count("\n") == 1 and fault in done.stderr, done.stderr


def test_a_malformed_role_extension_may_do_nothing_whatever_the_policy(serve, tmp_path):
    """Whatever a policy holds (one built in Python, beyond the file's checks), a
    certificate whose role extension is a PrintableString, not a UTF8String, is refused:
    it used to get the policy's role of the marker's name."""
    from rig_emulator.modbus.tls import server_context
    from rig_emulator.modbus.transports import Transports

    ca, _ = _lab(tmp_path)
    client = make_client(ca, "printable", None)
    printable = bytes([0x13, 8]) + b"engineer"  # a PrintableString, not a UTF8String
    write_pair(with_role_extension(ca, client, printable, False), tmp_path, "printable")
    everything = frozenset(range(256))
    policy = RolePolicy(
        {
            "observer": Role("observer", everything, frozenset()),
            INVALID_ROLE: Role(INVALID_ROLE, everything, everything),
        },
        "observer",
    )
    srv = serve(
        ssl_context=server_context(
            tmp_path / "server.pem", tmp_path / "server.key", tmp_path / "ca.pem"
        )
    )

    async def setup():
        transports = Transports(srv.server.modbus_server)
        transports.authorise(policy)
        return transports

    transports = srv.call(setup())
    try:
        sock = tls_connect(srv.port, tmp_path, "printable")
        try:
            before = srv.values()["water_flow_setpoint_kg_h"]
            write = struct.pack(">BHHB", 16, 0, 2, 4) + FLOW_400
            assert tcp_exchange(sock, 1, write) == bytes([0x90, 0x01])
            assert tcp_exchange(sock, 1, struct.pack(">BHH", 4, 0, 2)) == bytes([0x84, 0x01])
            assert srv.values()["water_flow_setpoint_kg_h"] == before
        finally:
            sock.close()
    finally:
        srv.call(transports.stop())


@pytest.mark.parametrize("unit", ["0", "248"])
def test_a_roles_file_naming_broadcast_or_reserved_units_is_refused(tmp_path, unit):
    """``write: [0]`` (the broadcast address) and ``[248]`` (reserved) were taken without a
    word (a stranger's probe): no unit of a map has them."""
    _, tls = _lab(tmp_path)
    roles = tmp_path / "roles.yaml"
    roles.write_text(f"roles:\n  observer: {{read: all, write: [{unit}]}}\n")
    done = run_serve("--port", "0", *tls, "--roles", str(roles))
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
    assert f"'{unit}' is not a unit ID (1-247; 0 is the broadcast address" in done.stderr
