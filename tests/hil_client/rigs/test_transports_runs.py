"""``hil-client run`` over Modbus/TCP Security and over Modbus RTU on a real pty: in
lockstep each run equals the in-process run of the same protocol."""

from __future__ import annotations

import contextlib
import math
import os
import select
import shutil
import subprocess
import threading
import time
import tty
from pathlib import Path

import pytest

from hil_client.analysis.logio import read_log
from hil_client.cli import main
from hil_client.protocol.rig import RigCommand
from hil_client.rigs.modbus import ModbusRig
from hil_client.rigs.transports import connector
from rig_emulator.certs import make_lab_certificates
from rig_emulator.modbus.roles import DEFAULT_POLICY
from rig_emulator.modbus.tls import server_context
from rig_emulator.modbus.transports import Transports
from rig_emulator.registers import load_map
from tests.hil_client.test_modbus_rig import SHORT, assert_logs_equal

# a protocol of about 20 simulated minutes at 10 s per row (about 150 rows), so a run over
# a serial line (one request at a time, ten per row) takes seconds, not minutes
TINY = """\
name: tiny
test: tiny
acquisition_period_s: 10
flow_spread_K: 15
preheat: {temperature_C: 30, tolerance_K: 1, hold_s: 20, load_pct: 100, max_duration_s: 900}
start_up: {return_setpoint_C: 30, t1_window_s: 60, t1_max_rise_K_min: 5, min_duration_s: 60,
           max_duration_s: 300}
test_sequence:
  return_setpoint_C: 30
  sequences:
    - {name: peak, load_pct: 100, duration: "00:03:00"}
    - {name: stationary_50, load_pct: 50, duration: "00:03:00"}
cooling_1: {load_pct: 20, return_setpoint_C: 30, until_forward_C: 90, max_duration_s: 120}
cooling_2: {until_after_t2_s: 240}
"""


def _run(protocol: str, *args: str) -> int:
    return main(["run", protocol, "--boiler", "windhager_12kw", "--quiet", *args])


@pytest.fixture(scope="module")
def certs(tmp_path_factory):
    out = tmp_path_factory.mktemp("certs")
    make_lab_certificates(out)
    return out


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("protocol") / "tiny.yaml"
    path.write_text(TINY)
    return path


def _local(protocol: str, out: Path):
    assert _run(protocol, "--rig", "local", "--out", str(out)) == 0
    return read_log(out)


@pytest.fixture
def tls_server(serve, certs):
    srv = serve(
        ssl_context=server_context(certs / "server.pem", certs / "server.key", certs / "ca.pem")
    )

    async def setup():
        transports = Transports(srv.server.modbus_server)
        transports.authorise(DEFAULT_POLICY)
        return transports

    srv.transports = srv.call(setup())
    yield srv
    srv.call(srv.transports.stop())


def _tls_args(certs: Path, stem: str) -> list[str]:
    return [
        "--tls-cert",
        str(certs / f"{stem}.pem"),
        "--tls-key",
        str(certs / f"{stem}.key"),
        "--tls-ca",
        str(certs / "ca.pem"),
    ]


def test_run_over_tls_equals_the_local_run(tls_server, certs, tmp_path):
    local = _local(SHORT, tmp_path / "local.csv")
    out = tmp_path / "tls.csv"
    rig = f"modbus+tls://127.0.0.1:{tls_server.port}"
    assert _run(SHORT, "--rig", rig, *_tls_args(certs, "engineer"), "--out", str(out)) == 0
    remote = read_log(out)
    assert remote.meta["clock"] == "lockstep" and remote.meta["complete"] is True
    assert_logs_equal(local, remote)
    assert tls_server.transports.authorisation.refusals == 0


def test_operator_cannot_drive_the_clock(tls_server, certs, tmp_path, capsys):
    # a lockstep run advances the simulation control (unit 100): an operator is refused
    rig = f"modbus+tls://127.0.0.1:{tls_server.port}"
    out = tmp_path / "op.csv"
    assert _run(SHORT, "--rig", rig, *_tls_args(certs, "operator"), "--out", str(out)) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert "exception 01" in err[-1], err
    # what the role lacks, said (a stranger's probe: only "function 16 refused")
    assert "role may not write it" in err[-1] and "engineer" in err[-1], err
    assert tls_server.values()["sim_time_s"] == 0.0


def test_a_role_the_server_does_not_know_is_said_not_another_map(
    tls_server, certs, tmp_path, capsys
):
    """A stranger's probe: a certificate with the role "superuser" (no role the server
    knows: it may do nothing) read as "not a rig-emulator with this map?"."""
    from cryptography import x509
    from cryptography.hazmat.primitives import serialization

    from rig_emulator.certs import Issued, make_client, write_pair

    ca = Issued(
        key=serialization.load_pem_private_key((certs / "ca.key").read_bytes(), None),
        cert=x509.load_pem_x509_certificate((certs / "ca.pem").read_bytes()),
    )
    write_pair(make_client(ca, "superuser client", "superuser"), tmp_path, "superuser")
    args = ["--tls-cert", str(tmp_path / "superuser.pem"), "--tls-key"]
    args += [str(tmp_path / "superuser.key"), "--tls-ca", str(certs / "ca.pem")]
    rig = f"modbus+tls://127.0.0.1:{tls_server.port}"
    assert _run(SHORT, "--rig", rig, *args, "--out", str(tmp_path / "su.csv")) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert "role may not read it" in err[-1] and "this map" not in err[-1], err


def test_tls_options_checked_before_connecting(certs, tmp_path, capsys):
    out = tmp_path / "x.csv"
    args = ["--rig", "modbus+tls://127.0.0.1:1", "--out", str(out)]
    assert _run(SHORT, *args) == 2
    assert "needs --tls-cert" in capsys.readouterr().err
    missing = [*_tls_args(certs, "engineer")[:4], "--tls-ca", str(tmp_path / "none.pem")]
    assert _run(SHORT, *args, *missing) == 2
    assert "--tls-ca" in capsys.readouterr().err and not out.exists()
    # a plain rig given one TLS option: not told to add the other two (a stranger's probe)
    plain = ["--rig", "modbus://127.0.0.1:1", "--out", str(out), "--tls-cert", "x.pem"]
    assert _run(SHORT, *plain) == 2
    err = capsys.readouterr().err
    assert "--tls-* options need a modbus+tls:// rig" in err and "needs --tls-key" not in err


@pytest.fixture
def rtu_server(serve):
    srv = serve()

    async def setup():
        transports = Transports(srv.server.modbus_server)
        return transports, await transports.add_rtu("pty", 115200, "E")

    srv.transports, srv.line = srv.call(setup())
    yield srv
    srv.call(srv.transports.stop())


def test_run_over_rtu_equals_the_local_run(rtu_server, tiny, tmp_path):
    local = _local(str(tiny), tmp_path / "local.csv")
    assert len(local) > 50
    out = tmp_path / "rtu.csv"
    rig = f"modbus-rtu://{rtu_server.line.path}?baud=115200&parity=E"
    assert _run(str(tiny), "--rig", rig, "--out", str(out)) == 0
    remote = read_log(out)
    assert remote.meta["complete"] is True and remote.meta["rig"] == rig
    assert_logs_equal(local, remote)
    assert rtu_server.line.transactions >= 8 * len(remote)  # one request at a time
    assert rtu_server.line.crc_errors == 0


def test_a_run_at_another_baud_rate_than_the_lines_is_told_why_nothing_answers(
    rtu_server, tiny, tmp_path, capsys
):
    """A stranger's probe: ?baud=9600 on a 115,200-baud line logged rows as if the lab's
    serial settings were right; a bench would answer nothing. The run stops before its
    first row, saying the device may run at another baud rate or parity."""
    out = tmp_path / "rtu.csv"
    rig = f"modbus-rtu://{rtu_server.line.path}?baud=9600&parity=E"
    assert _run(str(tiny), "--rig", rig, "--reply-timeout", "0.5", "--out", str(out)) == 1
    err = capsys.readouterr().err
    assert "no reply" in err and "another baud rate or parity than the URL's" in err, err
    assert rtu_server.line.transactions == 0


def _step_alike(
    rig: ModbusRig, ref: ModbusRig, command: RigCommand, killer: threading.Thread | None = None
) -> None:
    """A 10-s step of both rigs (``killer`` joined once they are through it); every
    reading of ``rig`` equal to the reference's, bit for bit, NaN where NaN."""
    for r in (rig, ref):
        r.apply(command)
        r.advance(10.0)
    if killer is not None:
        killer.join()
    ours_now, theirs_now = rig.read(), ref.read()
    for key, value in theirs_now.items():
        assert ours_now[key] == value or (math.isnan(value) and math.isnan(ours_now[key]))


def _replayed_over_a_serial_line(
    serve, tmp_path, steps: int, restart_at: int, after_s: float | None, reply_timeout_s: float
) -> None:
    """A lockstep run over a socat pty pair, its server stopped and a new one started on
    the line at step ``restart_at``: before the step (``after_s`` None) or ``after_s`` into
    it, from another thread; every reading must equal an uninterrupted run's over TCP, bit
    for bit, with one break marked ``replayed``."""
    ours, theirs = tmp_path / "emulator", tmp_path / "client"
    socat = subprocess.Popen(
        [shutil.which("socat"), f"pty,raw,echo=0,link={ours}", f"pty,raw,echo=0,link={theirs}"],
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 10
        while not (ours.exists() and theirs.exists()) and time.monotonic() < deadline:
            time.sleep(0.05)

        def start():
            srv = serve()

            async def setup():
                transports = Transports(srv.server.modbus_server)
                await transports.add_rtu(str(ours), 115200, "E")
                return transports

            return srv, srv.call(setup())

        servers = [start()]

        def restart() -> None:
            time.sleep(after_s or 0.0)
            first, transports = servers[-1]
            first.call(transports.stop())  # (the fixture stops its server)
            servers.append(start())

        url = f"modbus-rtu://{theirs}?baud=115200&parity=E"
        # (an advance lost with its server is waited for up to the reconnect timeout)
        rig = ModbusRig(
            url, load_map(), connect=connector(url, reply_timeout_s), reconnect_timeout_s=3
        )
        reference = serve()
        ref = ModbusRig(f"modbus://127.0.0.1:{reference.port}", load_map())
        command = RigCommand(600.0, 50.0, pump_on=True, boiler_on=True)
        for step in range(steps):
            killer = None
            if step == restart_at and after_s is None:
                restart()
            elif step == restart_at:
                killer = threading.Thread(target=restart)
                killer.start()
            _step_alike(rig, ref, command, killer)
        assert [g["action"] for g in rig.gaps] == ["replayed"]
        # (the dead server's timeouts were noted as the replayed row's: "unit 5 gave no
        # reading ... empty there" of a row logged whole, a stranger's probe)
        assert rig.end_notes() == [], rig.end_notes()
        assert rig.log_time_s == ref.log_time_s == 10.0 * steps
        last, transports = servers[-1]
        last.call(transports.stop())
        rig.close()
        ref.close()
    finally:
        socat.terminate()
        socat.wait(timeout=10)


@pytest.mark.skipif(shutil.which("socat") is None, reason="socat not installed (make test-deps)")
def test_a_server_restarted_between_steps_on_a_serial_line_is_replayed(serve, tmp_path):
    """A serial line loses no connection: a lockstep server restarted on it between two
    steps took the next step's advance as a fresh plant before the status showed the new
    epoch, and the run broke where TCP and TLS replay. The new server is now reset to its
    initial state and the journal replayed: every reading equals an uninterrupted run's."""
    _replayed_over_a_serial_line(serve, tmp_path, 12, 6, None, 2.0)


@pytest.mark.skipif(shutil.which("socat") is None, reason="socat not installed (make test-deps)")
@pytest.mark.parametrize("after_s", [0.0, 0.01, 0.03, 0.06])
def test_a_server_restarted_under_a_step_on_a_serial_line_is_replayed(serve, tmp_path, after_s):
    """A serial line loses no connection: a lockstep server stopped while a step's reads
    were on the line (and a new one started on it) left that row's instruments empty, with
    no break marked, before the next step found the new plant. The rig now asks the
    simulation control after instruments that timed out, rebuilds the new server and reads
    the step again: every reading equals an uninterrupted run's, wherever the stop lands
    (``after_s`` into the step; at 115200 baud a step's two dozen transactions take some
    50 ms)."""
    _replayed_over_a_serial_line(serve, tmp_path, 10, 5, after_s, 0.5)


def _garble_one_frame(
    ours: str, theirs: str, stop: threading.Event, after_s: float, head: bytes, to_server: bool
) -> None:
    """A line between two ptys (``theirs`` the client's, ``ours`` the server's) that flips
    a bit in the CRC of the first frame beginning with ``head`` sent after ``after_s`` to
    the server (``to_server``) or from it: a frame lost to noise, as on RS-485."""
    import pty

    c_side, c_end = pty.openpty()
    s_side, s_end = pty.openpty()
    for fd in (c_end, s_end):
        tty.setraw(fd)
    os.symlink(os.ttyname(c_end), theirs)
    os.symlink(os.ttyname(s_end), ours)
    started, done = time.monotonic(), False
    try:
        while not stop.is_set():
            for src in select.select([c_side, s_side], [], [], 0.1)[0]:
                try:
                    data = bytearray(os.read(src, 4096))
                except OSError:
                    continue
                late = time.monotonic() - started > after_s
                way = src == c_side if to_server else src == s_side
                if way and not done and late and data[: len(head)] == head:
                    data[-1] ^= 0x01
                    done = True
                with contextlib.suppress(OSError):
                    os.write(s_side if src == c_side else c_side, bytes(data))
    finally:
        for fd in (c_side, c_end, s_side, s_end):
            os.close(fd)


@contextlib.contextmanager
def _served_through_noise(serve, tmp_path: Path, after_s: float, head: bytes, to_server: bool):
    """A server's RTU line behind :func:`_garble_one_frame`: the client's URL (the line
    stopped at the end)."""
    ours, theirs = str(tmp_path / "emulator"), str(tmp_path / "client")
    stop = threading.Event()
    args = (ours, theirs, stop, after_s, head, to_server)
    line = threading.Thread(target=_garble_one_frame, args=args)
    line.start()
    try:
        while not (os.path.exists(ours) and os.path.exists(theirs)):
            time.sleep(0.01)
        srv = serve()
        transports = Transports(srv.server.modbus_server)
        srv.call(transports.add_rtu(ours, 115200, "E"))
        yield f"modbus-rtu://{theirs}?baud=115200&parity=E"
        srv.call(transports.stop())
    finally:
        stop.set()
        line.join(timeout=10)


def test_an_advance_lost_on_a_serial_line_costs_a_reply_timeout_not_the_reconnect_one(
    serve, tmp_path
):
    """A stranger's probe: one bad CRC on the advance's request (the server never saw it)
    held the run for the whole --reconnect-timeout, 60 s, though the line was free at
    once. The rig now asks the server's counter after each reply timeout: on a line a
    server that answers carries out nothing, so an advance not done was lost, and is sent
    again. The readings equal an uninterrupted run's."""
    advance = b"\x64\x10"  # (unit 100, FC16)
    with _served_through_noise(serve, tmp_path, 1.0, advance, True) as url:
        patience_s = 120.0  # (the wait the lost advance had)
        rig = ModbusRig(
            url, load_map(), connect=connector(url, 0.5), reconnect_timeout_s=patience_s
        )
        reference = serve()
        ref = ModbusRig(f"modbus://127.0.0.1:{reference.port}", load_map())
        command = RigCommand(600.0, 50.0, pump_on=True, boiler_on=True)
        deadline = time.monotonic() + 60.0
        while not rig.gaps and time.monotonic() < deadline:
            _step_alike(rig, ref, command)
        assert [g["action"] for g in rig.gaps] == ["resumed"], rig.gaps
        # a functional bound, not a speed target: the lost frame is not waited out
        assert rig.gaps[0]["outage_wall_s"] < patience_s / 2, rig.gaps
        rig.close()
        ref.close()


def test_a_garbled_first_reply_is_asked_again(serve, tmp_path):
    """A stranger's probe: one bad CRC on the first reply of a serial line (noise, at the
    very start) refused the run: "cannot reach ...: garbled reply from unit 100". It is
    asked again: the run starts, with no break."""
    status = b"\x64\x04"  # (unit 100's reply to the status read, the first exchange)
    with _served_through_noise(serve, tmp_path, 0.0, status, False) as url:
        rig = ModbusRig(url, load_map(), connect=connector(url, 0.5))
        rig.apply(RigCommand(600.0, 50.0, pump_on=True, boiler_on=True))
        rig.advance(10.0)
        assert rig.log_time_s == 10.0 and rig.gaps == []
        rig.close()
