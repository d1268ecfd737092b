"""Modbus/TCP Security over real TLS sockets with the certificates of ``rig-emulator certs``,
driven by pymodbus's TLS client and Python's ``ssl`` (clients the project did not write)."""

from __future__ import annotations

import logging
import socket
import ssl
import struct
import time

import pytest
from pymodbus.client import ModbusTcpClient, ModbusTlsClient

from rig_emulator.certs import make_ca, make_client, make_lab_certificates, write_pair
from rig_emulator.modbus.roles import DEFAULT_POLICY
from rig_emulator.modbus.tls import server_context
from rig_emulator.modbus.transports import Transports
from rig_emulator.registers import decode, encode
from tests.modbus_helpers import encrypted_copy
from tests.rig_emulator.modbus.raw import closed_by_server

ROLES = ("observer", "operator", "engineer", "norole")


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    out = tmp_path_factory.mktemp("certs")
    make_lab_certificates(out)
    return out


@pytest.fixture
def tls_server(serve, certs):
    """A lockstep server speaking TLS on its port, with the default roles and a plain TCP
    listener beside it."""
    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem")
    )

    async def setup():
        transports = Transports(srv.server.modbus_server)
        transports.authorise(DEFAULT_POLICY)
        return transports, await transports.add_tcp("127.0.0.1", 0)

    srv.transports, (_, srv.plain_port) = srv.call(setup())
    yield srv
    srv.call(srv.transports.stop())


def client_context(certs, stem: str | None, ca: str = "ca.pem", **versions) -> ssl.SSLContext:
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.load_verify_locations(cafile=str(certs / ca))
    if stem is not None:
        ctx.load_cert_chain(str(certs / f"{stem}.pem"), str(certs / f"{stem}.key"))
    for name, value in versions.items():
        setattr(ctx, name, value)
    return ctx


def tls_client(port: int, certs, stem: str) -> ModbusTlsClient:
    ctx = client_context(certs, stem)
    ctx.check_hostname = False  # pymodbus's sync TLS client passes no server name; the
    # chain is still verified against the CA
    c = ModbusTlsClient("127.0.0.1", port=port, sslctx=ctx, timeout=5, retries=0)
    assert c.connect()
    return c


def _point(srv, device: str, name: str):
    dev = srv.map.device(device)
    return dev, next(p for p in dev.points if p.name == name)


def _read_holding(c, srv, device: str, name: str) -> float:
    dev, p = _point(srv, device, name)
    r = c.read_holding_registers(p.address, count=p.width, device_id=dev.unit_id)
    assert not r.isError(), r
    return decode(p, r.registers)


def _write(c, srv, device: str, name: str, value: float):
    dev, p = _point(srv, device, name)
    return c.write_registers(p.address, encode(p, value), device_id=dev.unit_id)


def _only_the_engineer_moves_the_clock(c, srv, stem: str, also_reset: bool = False) -> None:
    """An advance of 5 s on the simulation control: done for the engineer, refused with 01
    and the time unchanged for every other role (and a reset refused too, ``also_reset``)."""
    time_before = srv.values()["sim_time_s"]
    r = _write(c, srv, "sim_control", "lockstep_advance", 5)
    if stem == "engineer":
        assert not r.isError(), r
        assert srv.values()["sim_time_s"] == pytest.approx(time_before + 5.0)
        return
    assert r.isError() and r.exception_code == 1, r
    if also_reset:
        r = _write(c, srv, "sim_control", "reset", 1)
        assert r.isError() and r.exception_code == 1, r
    assert srv.values()["sim_time_s"] == time_before


@pytest.mark.parametrize("stem", ROLES)
def test_each_role_allowed_or_refused_with_01_and_no_change(tls_server, certs, stem):
    srv = tls_server
    c = tls_client(srv.port, certs, stem)
    try:
        # every role reads every unit
        flow_before = _read_holding(c, srv, "bench_plc", "flow_setpoint")
        r = c.read_input_registers(0, count=7, device_id=100)
        assert not r.isError()
        counter_before = srv.values()["lockstep_counter"]

        # instruments (unit 1): operator and engineer write, observer and no role do not
        r = _write(c, srv, "bench_plc", "flow_setpoint", 321.5)
        if stem in ("operator", "engineer"):
            assert not r.isError(), r
            assert _read_holding(c, srv, "bench_plc", "flow_setpoint") == 321.5
            assert srv.values()["water_flow_setpoint_kg_h"] == 321.5
        else:
            assert r.isError() and r.exception_code == 1, r
            assert _read_holding(c, srv, "bench_plc", "flow_setpoint") == flow_before
            assert srv.values()["water_flow_setpoint_kg_h"] == flow_before
        # coil write (FC5) of the boiler command on unit 7
        before = srv.values()["boiler_command"]
        r = c.write_coil(0, not bool(before), device_id=7)
        assert r.isError() == (stem in ("observer", "norole")), r
        if r.isError():
            assert r.exception_code == 1
            assert srv.values()["boiler_command"] == before

        # simulation control (unit 100): only the engineer advances the plant
        _only_the_engineer_moves_the_clock(c, srv, stem)
        if stem != "engineer":
            assert srv.values()["lockstep_counter"] == counter_before
    finally:
        c.close()


@pytest.mark.parametrize("stem", ROLES)
def test_a_unit_the_bench_lacks_is_0b_whatever_the_role(tls_server, certs, stem):
    """A stranger's probe: over TLS a write to a unit the bench does not have got 01 ("not
    allowed"), even for the engineer, while plain TCP gave 0B: a client told its role is
    at fault looks for a certificate problem, not for a wrong unit id. The unit is checked
    first, for every role and every function."""
    c = tls_client(tls_server.port, certs, stem)
    try:
        for request in (
            lambda: c.write_register(0, 1, device_id=9),
            lambda: c.write_registers(0, [1], device_id=200),
            lambda: c.read_holding_registers(0, count=1, device_id=9),
        ):
            r = request()
            assert r.isError() and r.exception_code == 0x0B, r
    finally:
        c.close()


def test_plain_tcp_beside_tls_sees_the_same_plant(tls_server, certs):
    srv = tls_server
    c = tls_client(srv.port, certs, "operator")
    plain = ModbusTcpClient("127.0.0.1", port=srv.plain_port, timeout=5, retries=0)
    assert plain.connect()
    try:
        assert not _write(c, srv, "bench_plc", "return_setpoint", 61.0).isError()
        assert _read_holding(plain, srv, "bench_plc", "return_setpoint") == 61.0
        assert not _write(plain, srv, "bench_plc", "return_setpoint", 48.0).isError()
        assert _read_holding(c, srv, "bench_plc", "return_setpoint") == 48.0
    finally:
        c.close()
        plain.close()


def _raw_exchange(ctx: ssl.SSLContext, port: int) -> bytes:
    """Handshake and one FC4 request; the reply bytes (raises if TLS refuses)."""
    with (
        socket.create_connection(("127.0.0.1", port), timeout=5) as raw,
        ctx.wrap_socket(raw, server_hostname="127.0.0.1") as tls,
    ):
        tls.sendall(struct.pack(">HHHB", 1, 0, 6, 1) + struct.pack(">BHH", 4, 0, 2))
        reply = tls.recv(256)
        if not reply:
            raise ConnectionError("closed")
        return reply


def test_good_client_gets_an_answer(tls_server, certs, caplog):
    # the control for the refusals below: the same raw exchange with a valid certificate
    caplog.set_level(logging.WARNING, logger="asyncio")
    reply = _raw_exchange(client_context(certs, "observer"), tls_server.port)
    assert reply[7] == 4 and reply[8] == 4
    for _ in range(20):  # the server sees the close within a few ms
        if not tls_server.server.modbus_server.connections:
            break
        time.sleep(0.05)
    # every TLS close logged asyncio's "returning true from eof_received() has no effect"
    assert not [r for r in caplog.records if "eof_received" in r.getMessage()]


def test_no_client_certificate_refused(tls_server, certs):
    with pytest.raises((ssl.SSLError, ConnectionError, OSError)):
        _raw_exchange(client_context(certs, None), tls_server.port)


def test_certificate_of_another_ca_refused(tls_server, certs, tmp_path):
    other = make_ca("another lab CA")
    write_pair(make_client(other, "stranger", "engineer"), tmp_path, "stranger")
    (tmp_path / "ca.pem").write_bytes((certs / "ca.pem").read_bytes())
    with pytest.raises((ssl.SSLError, ConnectionError, OSError)):
        _raw_exchange(client_context(tmp_path, "stranger"), tls_server.port)


@pytest.mark.parametrize(
    "hello",
    [b"", bytes.fromhex("16030102000100 01fc0303")],  # nothing; half a ClientHello
    ids=["silent", "half-hello"],
)
def test_a_stalled_handshake_is_closed_at_the_idle_timeout(serve, certs, hello):
    """A client that opens the TLS port and stalls its handshake is closed after
    --idle-timeout (here 1 s), as any silent connection is, not after asyncio's own 60 s;
    a good client is served meanwhile."""
    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem"),
        idle_timeout_s=1.0,
    )
    with socket.create_connection(("127.0.0.1", srv.port), timeout=5) as stalled:
        stalled.sendall(hello)
        assert _raw_exchange(client_context(certs, "observer"), srv.port)[7] == 4
        assert closed_by_server(stalled, timeout=20)  # 60 s without the bound


def test_a_peer_that_never_answers_close_notify_is_let_go(serve, certs):
    """A TLS connection the server closes (here at the idle timeout) waits for the peer's
    close_notify; a peer that never sends it held the server's socket for asyncio's 30 s.
    Now the TCP connection ends a few seconds after the server's close_notify."""
    import os
    import select

    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem"),
        idle_timeout_s=1.0,
    )
    ctx = client_context(certs, "observer")
    with (
        socket.create_connection(("127.0.0.1", srv.port), timeout=10) as raw,
        ctx.wrap_socket(raw, server_hostname="127.0.0.1") as tls,
    ):
        assert tls.recv(1) == b""  # the server's close_notify, at the idle timeout
        # never answered: read the TCP stream underneath until the server lets it go
        fd = tls.fileno()
        ended = False
        for _ in range(150):  # 15 s at most; it used to take 30 s
            if select.select([fd], [], [], 0.1)[0]:
                try:
                    ended = os.read(fd, 4096) == b""
                except ConnectionResetError:
                    ended = True
                if ended:
                    break
        assert ended


def test_stalled_handshakes_hold_places_of_the_connection_limit(serve, certs, caplog):
    """A connection counts from its first byte, not from the end of its handshake: 200
    stalled handshakes stayed open beside a limit of 10 (each until the idle timeout, 300 s
    by default), every one a file descriptor an unauthenticated peer held. Now the limit
    closes the oldest unused ones, so at most 10 stay open, and a good client is served."""
    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem"),
        max_connections=10,
    )
    stalled = [socket.create_connection(("127.0.0.1", srv.port), timeout=5) for _ in range(30)]
    try:
        for sock in stalled:
            sock.sendall(bytes.fromhex("16030102000100 01fc0303"))  # half a ClientHello
        assert _raw_exchange(client_context(certs, "observer"), srv.port)[7] == 4
        closed = sum(closed_by_server(sock, timeout=0.5) for sock in stalled)
        assert closed >= 21, closed  # 30 stalled + 1 good, 10 places
        assert srv.server.modbus_server.connections <= 10
    finally:
        for sock in stalled:
            sock.close()
    import gc

    gc.collect()  # a task's unretrieved exception is logged when the task goes
    # each handshake the limit closed ended its task in an AttributeError, logged unlimited
    assert not [r for r in caplog.records if "never retrieved" in r.getMessage()]


def test_a_failed_handshake_is_logged_with_its_reason(tls_server, certs, tmp_path, caplog):
    """A client certificate of another CA, and plain Modbus on the TLS port, were refused
    without a line in the log: no audit trail of failed authentications."""
    other = tmp_path / "other"
    make_lab_certificates(other)
    caplog.set_level(logging.WARNING, logger="rig_emulator.serve")
    ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    ctx.load_verify_locations(cafile=str(certs / "ca.pem"))
    ctx.load_cert_chain(str(other / "engineer.pem"), str(other / "engineer.key"))
    with pytest.raises((ssl.SSLError, ConnectionError, OSError)):
        _raw_exchange(ctx, tls_server.port)
    with socket.create_connection(("127.0.0.1", tls_server.port), timeout=5) as plain:
        plain.sendall(struct.pack(">HHHB", 1, 0, 6, 1) + struct.pack(">BHH", 4, 0, 2))
        assert closed_by_server(plain, timeout=5)
    for _ in range(40):
        failed = [
            r.getMessage() for r in caplog.records if "TLS handshake failed" in r.getMessage()
        ]
        if len(failed) >= 2:
            break
        time.sleep(0.05)
    assert len(failed) == 2, failed
    assert "CERTIFICATE_VERIFY_FAILED" in failed[0].upper().replace(" ", "_"), failed[0]
    # and why OpenSSL refused it (the log said only CERTIFICATE_VERIFY_FAILED for an expired
    # certificate and one of another CA alike; a stranger's probe)
    assert "the client's certificate: unable to get local issuer certificate" in failed[0]


def test_a_certificate_out_of_its_dates_is_named(certs):
    """``validity_problem``: what serve and hil-client warn of at start (an expired server
    certificate was taken without a word, and an expired client certificate gave only
    "connection closed by the server")."""
    import datetime

    from rig_emulator.certs import validity_problem

    assert validity_problem(certs / "engineer.pem") is None
    later = datetime.datetime.now(datetime.UTC) + datetime.timedelta(days=3700)
    assert validity_problem(certs / "engineer.pem", now=later).startswith("expired on ")
    earlier = datetime.datetime.now(datetime.UTC) - datetime.timedelta(days=2)
    assert validity_problem(certs / "server.pem", now=earlier).startswith("not valid before ")
    assert validity_problem(certs / "engineer.key") is None  # no certificate: its loader says


@pytest.mark.filterwarnings("ignore:ssl.TLSVersion.TLSv1:DeprecationWarning")
def test_tls_below_1_2_refused(tls_server, certs):
    legacy = dict(minimum_version=ssl.TLSVersion.TLSv1, maximum_version=ssl.TLSVersion.TLSv1_1)
    ctx = client_context(certs, "engineer", **legacy)
    try:
        ctx.set_ciphers("DEFAULT:@SECLEVEL=0")  # let this OpenSSL offer TLS 1.0/1.1 at all
    except ssl.SSLError:
        pytest.skip("this OpenSSL cannot offer TLS below 1.2")
    with pytest.raises((ssl.SSLError, ConnectionError, OSError)) as info:
        _raw_exchange(ctx, tls_server.port)
    print(f"TLS 1.0/1.1 client: {info.value}")
    assert "NO_PROTOCOLS_AVAILABLE" not in str(info.value)  # it did offer 1.0/1.1
    # the same client allowed TLS 1.2 gets through: the version was the reason
    ctx = client_context(certs, "engineer", maximum_version=ssl.TLSVersion.TLSv1_2)
    assert _raw_exchange(ctx, tls_server.port)[7] == 4


def test_refusals_logged_with_subject_once_per_connection(tls_server, certs, caplog):
    srv = tls_server
    caplog.set_level(logging.INFO, logger="rig_emulator.serve")
    c = tls_client(srv.port, certs, "observer")
    try:
        for i in range(200):  # a flood of refused writes
            r = _write(c, srv, "bench_plc", "flow_setpoint", 100.0 + i)
            assert r.isError() and r.exception_code == 1
        r = _write(c, srv, "sim_control", "speed_factor", 2.0)  # another reason
        assert r.isError() and r.exception_code == 1
    finally:
        c.close()
    refusals = [r.getMessage() for r in caplog.records if r.getMessage().startswith("refused")]
    assert len(refusals) == 2, refusals
    assert "CN=observer client" in refusals[0] and "role observer" in refusals[0]
    assert "write unit 1" in refusals[0] and "write unit 100" in refusals[1]
    assert srv.transports.authorisation.refusals == 201
    connected = [m.getMessage() for m in caplog.records if "TLS, subject" in m.getMessage()]
    assert any("CN=observer client" in m and "role observer" in m for m in connected)


# ---------------------------------------------------------------------- the real CLI
def _tls_options(certs) -> list[str]:
    return [
        "--tls-cert",
        str(certs / "server.pem"),
        "--tls-key",
        str(certs / "server.key"),
        "--tls-ca",
        str(certs / "ca.pem"),
    ]


def test_tls_port_defaults_to_802(certs):
    from rig_emulator import cli_transports
    from rig_emulator.cli import _build_parser

    parse = _build_parser().parse_args
    tls = cli_transports.plan(parse(["serve", "--boiler", "x", *_tls_options(certs)]))
    assert tls.port == 802 and tls.ssl_context is not None and tls.tcp_port is None
    plain = cli_transports.plan(parse(["serve", "--boiler", "x"]))
    assert plain.port == 5020 and plain.ssl_context is None


@pytest.mark.parametrize(
    ("extra", "fault"),
    [
        (["--tls-cert", "server.pem"], "--tls-cert needs --tls-key, --tls-ca too"),
        (["--tcp-port", "0"], "--tcp-port goes with --tls-*"),
        (["--roles", "ROLES"], "--roles needs --tls-*"),
        (["TLS", "--roles", "ROLES"], "roles.admin.write: 'x' is text: a unit ID is a number"),
        (["TLS", "--plain-role", "root"], "--plain-role: 'root' is not one of"),
        # a certificate as the key: OpenSSL's "[SSL] PEM lib (_ssl.c:3905)" (a stranger's probe)
        (["TLS-BAD-KEY"], "ca.pem: not a PEM private key"),
        (["TLS-ENCRYPTED-KEY"], "is protected by a passphrase"),  # was a traceback or a prompt
        (["TLS", "--roles", "BINARY"], "binary.yaml is not UTF-8 text"),  # named no file
    ],
)
def test_bad_tls_options_are_one_line(certs, tmp_path, capsys, extra, fault):
    from rig_emulator.cli import main

    roles = tmp_path / "roles.yaml"
    roles.write_text("roles:\n  admin: {read: all, write: [x]}\n")
    args = []
    for item in extra:
        if item == "TLS":
            args += _tls_options(certs)
        elif item == "TLS-BAD-KEY":
            args += [*_tls_options(certs)[:2], "--tls-key", str(certs / "ca.pem")]
            args += _tls_options(certs)[4:]
        elif item == "TLS-ENCRYPTED-KEY":
            encrypted = encrypted_copy(certs / "server.key", tmp_path / "encrypted.key")
            args += [*_tls_options(certs)[:2], "--tls-key", str(encrypted)]
            args += _tls_options(certs)[4:]
        elif item == "ROLES":
            args.append(str(roles))
        elif item == "BINARY":
            (tmp_path / "binary.yaml").write_bytes(b"\x00\xff\xfe")
            args.append(str(tmp_path / "binary.yaml"))
        elif item == "server.pem":
            args.append(str(certs / "server.pem"))
        else:
            args.append(item)
    assert main(["serve", "--boiler", "windhager_12kw", "--port", "0", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and fault in err, err


def test_cli_serves_tls_with_a_roles_file_and_plain_tcp(certs, tmp_path):
    import os
    import subprocess
    import sys
    from pathlib import Path

    from hil_client.wait_for_port import free_port, wait_for_port

    roles = tmp_path / "roles.yaml"
    # the balance technician may write nothing but the balance (unit 5); the default
    # operator role no longer exists
    roles.write_text(
        "default_role: observer\nroles:\n  observer: {read: all, write: []}\n"
        "  engineer: {read: all, write: all}\n  balance_tech: {read: all, write: [5]}\n"
    )
    tech = make_client(_ca_of(certs), "balance technician", "balance_tech")  # signed by the lab CA
    write_pair(tech, tmp_path, "tech")
    (tmp_path / "ca.pem").write_bytes((certs / "ca.pem").read_bytes())
    port, plain_port = free_port(), free_port()
    proc = subprocess.Popen(
        [
            *(sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw"),
            *("--lockstep", "--port", str(port), "--tcp-port", str(plain_port)),
            *(*_tls_options(certs), "--roles", str(roles)),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[3])},
    )
    try:
        assert wait_for_port("127.0.0.1", port, 60.0) and wait_for_port(
            "127.0.0.1", plain_port, 60.0
        )
        ctx = client_context(tmp_path, "tech")
        ctx.check_hostname = False
        c = ModbusTlsClient("127.0.0.1", port=port, sslctx=ctx, timeout=5, retries=0)
        assert c.connect()
        try:
            r = c.write_coil(0, True, device_id=1)  # pump: not the balance
            assert r.isError() and r.exception_code == 1
            assert not c.read_input_registers(0, count=2, device_id=5).isError()
        finally:
            c.close()
        op = tls_client(port, certs, "operator")  # a role this file does not define
        try:
            r = op.read_input_registers(0, count=2, device_id=1)
            assert r.isError() and r.exception_code == 1
        finally:
            op.close()
        plain = ModbusTcpClient("127.0.0.1", port=plain_port, timeout=5, retries=0)
        assert plain.connect()
        try:
            assert not plain.write_coil(0, True, device_id=1).isError()
        finally:
            plain.close()
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "CN=balance technician" in err and "may not write unit 1" in err
    assert "unknown role 'operator'" in err


def _serve_remapped(serve, certs, units: dict[str, int], *options: str):
    """A lockstep TLS server of the shipped map with ``units`` moved, its roles set up as
    ``rig-emulator serve`` sets them (``cli_transports.plan`` and ``start``)."""
    from rig_emulator import cli_transports
    from rig_emulator.cli import _build_parser
    from tests.rig_emulator.transports.remapped import shipped_map_with_units

    srv = serve(
        register_map=shipped_map_with_units(**units),
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem"),
    )
    args = _build_parser().parse_args(["serve", "--boiler", "x", *_tls_options(certs), *options])
    srv.transports = srv.call(cli_transports.start(srv.server, cli_transports.plan(args)))
    return srv


@pytest.mark.parametrize(
    "units",
    [{"sim_control": 7, "boiler_controller": 100}, {"bench_plc": 31, "boiler_controller": 247}],
)
def test_serve_gives_the_roles_of_the_devices_not_of_their_unit_ids(serve, certs, units):
    """A stranger's probe: with the simulation control at unit 7 (and the boiler controller
    at 100) a TLS operator advanced and reset the clock, and with the instruments at units
    31 and 247 it was refused its setpoint and boiler writes: the roles went by the shipped
    map's unit IDs. Now the operator writes the instruments wherever they are and gets 01
    from the simulation control; the engineer advances it."""
    srv = _serve_remapped(serve, certs, units)
    try:
        for stem in ("operator", "engineer"):
            c = tls_client(srv.port, certs, stem)
            try:
                r = _write(c, srv, "bench_plc", "flow_setpoint", 321.5)
                assert not r.isError(), (stem, r)
                assert srv.values()["water_flow_setpoint_kg_h"] == 321.5
                set_temp = 55.0 if stem == "operator" else 65.0
                r = _write(c, srv, "boiler_controller", "set_temp", set_temp)
                assert not r.isError(), (stem, r)
                # raw 550 * scale 0.1 is 55.000000000000007: approx's relative 1e-6
                assert srv.values()["boiler_set_temp_C"] == pytest.approx(set_temp)
                on_command, _ = _point(srv, "boiler_controller", "on_command")
                assert not c.write_coil(0, True, device_id=on_command.unit_id).isError()

                _only_the_engineer_moves_the_clock(c, srv, stem, also_reset=True)
            finally:
                c.close()
        observer = tls_client(srv.port, certs, "observer")
        try:
            r = _write(observer, srv, "bench_plc", "flow_setpoint", 100.0)
            assert r.isError() and r.exception_code == 1, r
        finally:
            observer.close()
    finally:
        srv.call(srv.transports.stop())


def test_a_roles_file_keeps_its_unit_ids_whatever_the_map(serve, certs, tmp_path):
    """The unit lists of a ROLES.yaml are the user's: with the simulation control at unit 7,
    a file letting the operator write units 1-7 lets it advance the clock."""
    roles = tmp_path / "roles.yaml"
    roles.write_text("roles:\n  observer: {read: all, write: []}\n"
                     "  operator: {read: all, write: [1, 2, 3, 4, 5, 6, 7]}\n")  # fmt: skip
    srv = _serve_remapped(
        serve, certs, {"sim_control": 7, "boiler_controller": 100}, "--roles", str(roles)
    )
    try:
        c = tls_client(srv.port, certs, "operator")
        try:
            time_before = srv.values()["sim_time_s"]
            assert not _write(c, srv, "sim_control", "lockstep_advance", 5).isError()
            assert srv.values()["sim_time_s"] == pytest.approx(time_before + 5.0)
            r = _write(c, srv, "boiler_controller", "set_temp", 55.0)  # now at unit 100
            assert r.isError() and r.exception_code == 1, r
        finally:
            c.close()
    finally:
        srv.call(srv.transports.stop())


def _ca_of(certs):
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    from rig_emulator.certs import Issued

    key = serialization.load_pem_private_key((certs / "ca.key").read_bytes(), None)
    cert = x509.load_pem_x509_certificate((certs / "ca.pem").read_bytes())
    return Issued(key, cert)


@pytest.mark.parametrize("allow_control", [False, True])
def test_engineer_clock_on_real_time_server_needs_allow_control(serve, certs, allow_control):
    srv = serve(
        lockstep=False,
        allow_control=allow_control,
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem"),
    )

    async def setup():
        transports = Transports(srv.server.modbus_server)
        transports.authorise(DEFAULT_POLICY)
        return transports

    transports = srv.call(setup())
    try:
        for stem, allowed in (("operator", False), ("engineer", allow_control)):
            c = tls_client(srv.port, certs, stem)
            try:
                r = _write(c, srv, "sim_control", "speed_factor", 3.0 if allowed else 1.0)
                assert r.isError() != allowed, (stem, r)
                if not allowed:
                    assert r.exception_code == 1
            finally:
                c.close()
        assert srv.values()["speed_factor"] == (3.0 if allow_control else 1.0)
    finally:
        srv.call(transports.stop())


# ---------------------------------------------------------------------- odd certificates
class _Verified:
    """What a verified TLS connection shows of its client certificate (``peer_of``'s input)."""

    def __init__(self, der: bytes) -> None:
        self.der = der

    def getpeercert(self, binary_form: bool = False) -> bytes:
        return self.der


def _der_with_role_twice() -> bytes:
    """A client certificate whose role extension comes twice (observer, then engineer): the
    builder refuses that, so a second, unknown extension is renamed in the DER (the
    signature no longer matters: OpenSSL verified the chain before ``peer_of`` is asked)."""
    from cryptography.hazmat.primitives import serialization

    from rig_emulator.certs import ROLE_OID, utf8_string_der
    from tests.rig_emulator.transports.served import with_role_extension

    ca = make_ca()
    client = make_client(ca, "twice", "observer")
    other = ROLE_OID[:-1] + "2"
    twice = with_role_extension(ca, client, utf8_string_der("engineer"), False, oid=other)
    der = twice.cert.public_bytes(serialization.Encoding.DER)
    # the OIDs' DER ends: 802 is 0x86 0x22, then the last arc
    tail_other, tail_role = bytes([0x86, 0x22, 0x02]), bytes([0x86, 0x22, 0x01])
    assert der.count(tail_other) == 1
    return der.replace(tail_other, tail_role)


def test_a_role_extension_given_twice_is_an_invalid_role_not_a_crash():
    """It escaped ``peer_of`` as cryptography's DuplicateExtension: two tracebacks a
    connection in the server's log, and the connection dropped."""
    from rig_emulator.modbus.tls import INVALID_ROLE, peer_of

    peer = peer_of(_Verified(_der_with_role_twice()), DEFAULT_POLICY)  # type: ignore[arg-type]
    assert peer.role == INVALID_ROLE and "CN=twice" in peer.subject
    assert DEFAULT_POLICY.refusal(peer.role, 1, 4) is not None  # it may read nothing


def test_a_role_cannot_write_lines_of_its_own_into_the_log(tls_server, certs, tmp_path, caplog):
    """A role holding a newline wrote a forged log line, verbatim, twice."""
    ca = _ca_of(certs)
    forged = "engineer\n2026-01-01 00:00:00,000 rig-emulator: client 10.0.0.9:4444: role engineer"
    # the subject too: RFC 4514 escapes a comma, not a newline
    write_pair(make_client(ca, "forger\n2026-01-01 rig-emulator: FAKE", forged), tmp_path, "forger")
    (tmp_path / "ca.pem").write_bytes((certs / "ca.pem").read_bytes())
    caplog.set_level(logging.INFO, logger="rig_emulator.serve")
    c = tls_client(tls_server.port, tmp_path, "forger")
    try:
        r = _write(c, tls_server, "bench_plc", "flow_setpoint", 100.0)
        assert r.isError() and r.exception_code == 1  # an unknown role may send nothing
    finally:
        c.close()
    lines = [r.getMessage() for r in caplog.records if "forger" in r.getMessage()]
    lines += [r.getMessage() for r in caplog.records if r.getMessage().startswith("refused")]
    assert lines and all("\n" not in m for m in lines), lines
    assert any("engineer\\n2026" in m for m in lines)  # shown, escaped
    assert any("forger\\n2026-01-01 rig-emulator: FAKE" in m for m in lines)


def test_a_tls_connection_the_server_closes_leaves_no_traceback(tls_server, certs, caplog):
    """A frame that cannot be resynchronised closes the connection; on TLS the client's
    end of it then raised inside asyncio (eof_received asked a closed TLS transport for its
    extra info): one traceback per connection (a re-probe)."""
    caplog.set_level(logging.WARNING, logger="asyncio")
    ctx = client_context(certs, "engineer")
    for _ in range(3):
        with (
            socket.create_connection(("127.0.0.1", tls_server.port), timeout=5) as raw,
            ctx.wrap_socket(raw, server_hostname="127.0.0.1") as tls,
        ):
            tls.sendall(struct.pack(">HHHB", 1, 0, 300, 1) + b"\x04" * 20)  # length 300
            with pytest.raises((ssl.SSLError, ConnectionError, OSError, AssertionError)):
                assert tls.recv(256)  # closed by the server: b"" or an error
    time.sleep(0.3)
    assert not [r for r in caplog.records if r.name == "asyncio"], [
        r.getMessage() for r in caplog.records
    ]
