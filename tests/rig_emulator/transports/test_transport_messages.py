"""What ``rig-emulator serve`` says of a transport it cannot use or that is not what it seems:
one line and exit 2 for bad input, a warning for a server certificate clients refuse, and
log lines that read as what happened (``serve`` as its own process, real files, real TLS)."""

from __future__ import annotations

import os
import ssl
import struct
import time

import pytest

from rig_emulator.certs import make_ca, make_client, make_server, write_pair
from tests.rig_emulator.transports.served import (
    run_serve,
    serving,
    tcp_exchange,
    tls_connect,
    with_role_extension,
)


@pytest.fixture
def lab(tmp_path):
    """A CA, a server and an engineer certificate in ``tmp_path``; (CA, its directory)."""
    ca = make_ca()
    write_pair(ca, tmp_path, "ca")
    write_pair(make_server(ca), tmp_path, "server")
    write_pair(make_client(ca, "engineer", "engineer"), tmp_path, "engineer")
    return ca, tmp_path


def _tls(d, cert: str = "server.pem", key: str = "server.key", ca: str = "ca.pem") -> list[str]:
    return ["--tls-cert", str(d / cert), "--tls-key", str(d / key), "--tls-ca", str(d / ca)]


def _refused(*args: str) -> str:
    """The one line of a ``serve`` that exits 2."""
    done = run_serve("--port", "0", *args)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    return done.stderr.strip()


@pytest.mark.parametrize(
    ("path", "fault"),
    [
        # a line served there answered nobody, without a word (a stranger's probe)
        ("/dev/ptmx", "the pseudo-terminal multiplexer opens a new pty"),
        ("/dev/pts/ptmx", "the pseudo-terminal multiplexer opens a new pty"),
        # "not a serial line (a terminal)" read as if /dev/null were a terminal
        ("/dev/null", "--serial /dev/null: is not a terminal (a serial line or pty)"),
    ],
)
def test_a_serial_path_that_is_no_line_is_one_line(path, fault):
    line = _refused("--serial", path)
    assert fault in line, line
    if "multiplexer" in line:
        assert line.endswith("use --serial pty"), line


def test_tls_files_that_are_not_what_they_should_be_are_named(lab):
    """Strangers' probes: a directory and a FIFO were "no such file", and garbage PEM or a
    certificate and key swapped said only "([SSL] PEM lib (_ssl.c:3905))"."""
    ca, d = lab
    (d / "garbage.pem").write_text("garbage\n")
    if not (d / "fifo.pem").exists():
        os.mkfifo(d / "fifo.pem")
    write_pair(make_client(ca, "other", None), d, "other")
    for files, fault in (
        (_tls(d, cert="."), "TLS certificate " + str(d / ".") + ": is a directory"),
        (_tls(d, ca="."), ": is a directory, not a PEM file"),
        (_tls(d, cert="fifo.pem"), "fifo.pem: not a regular file, not a PEM file"),
        (_tls(d, cert="garbage.pem"), "garbage.pem: not a PEM certificate"),
        (_tls(d, cert="server.key", key="server.pem"), "server.key: not a PEM certificate"),
        (_tls(d, key="garbage.pem"), "garbage.pem: not a PEM private key"),
        (_tls(d, key="other.key"), "other.key: the key does not match the certificate"),
        (_tls(d, ca="garbage.pem"), "TLS CA " + str(d / "garbage.pem") + ": cannot be used "),
    ):
        line = _refused(*files)
        assert fault in line and "PEM lib" not in line, (files, line)


def test_a_server_certificate_for_clients_only_is_warned_of(lab):
    """A server certificate whose extended key usage is clientAuth only was served without a
    word (as an expired one is warned of); TLS clients refuse it, as this one does."""
    ca, d = lab
    write_pair(make_client(ca, "127.0.0.1", None), d, "client_only")
    unsuitable = pytest.raises(ssl.SSLCertVerificationError, match="unsuitable certificate purpose")
    with serving(*_tls(d, cert="client_only.pem", key="client_only.key")) as served, unsuitable:
        tls_connect(served.port, d, "engineer")
    warned = [line for line in served.stderr if "client_only.pem" in line]
    assert len(warned) == 1, served.stderr
    assert "is not for a TLS server: its extended key usage is clientAuth" in warned[0]
    assert warned[0].endswith("clients refuse it")


def test_a_client_speaking_after_the_idle_close_is_an_ordinary_close(lab):
    """A client that sent a request after the server had closed its idle connection was
    logged as "disconnected ([SSL: APPLICATION_DATA_AFTER_CLOSE_NOTIFY] application data
    after close notify (_ssl.c:2706))" (a stranger's probe)."""
    _, d = lab
    with serving(*_tls(d), "--idle-timeout", "1") as served:
        sock = tls_connect(served.port, d, "engineer")
        try:
            assert tcp_exchange(sock, 1, struct.pack(">BHH", 4, 0, 2))[:2] == bytes([4, 4])
            time.sleep(2.0)  # the idle timeout (1 s) closes it, a second to spare
            request = struct.pack(">HHHB", 2, 0, 6, 1) + struct.pack(">BHH", 4, 0, 2)
            try:
                sock.sendall(request)
                sock.recv(64)
            except (ssl.SSLError, OSError):
                pass  # the server has gone: either way is an ordinary end
        finally:
            sock.close()
        time.sleep(0.3)
    peer = next(
        line.split("client ")[1].split(":")[0:2] for line in served.stderr if "TLS, " in line
    )
    closed = [line for line in served.stderr if f"{peer[0]}:{peer[1]} disconnected" in line]
    assert closed and not any("SSL" in line for line in closed), served.stderr
    assert not any("APPLICATION_DATA_AFTER_CLOSE_NOTIFY" in line for line in served.stderr)


def test_a_critical_role_extension_is_refused_and_the_log_says_why(lab):
    """Python's ssl module has no certificate-verification callback, so OpenSSL refuses a
    role extension marked critical ("unhandled critical extension") before the server sees
    it (README, transports: a known limitation). The log line used to leave the reader to
    guess which extension and what to do; now it names the role extension and the cure."""
    ca, d = lab
    client = make_client(ca, "critical engineer", None)
    role = b"\x0c\x08engineer"  # the right UTF8String, marked critical
    write_pair(with_role_extension(ca, client, role, True), d, "critical")
    with serving(*_tls(d)) as served:
        with pytest.raises((ssl.SSLError, ConnectionError, OSError)):
            sock = tls_connect(served.port, d, "critical")
            try:  # TLS 1.3: the client learns of the refusal on its first read
                tcp_exchange(sock, 1, struct.pack(">BHH", 4, 0, 2))
            finally:
                sock.close()
        engineer = tls_connect(served.port, d, "engineer")  # the server goes on
        try:
            assert tcp_exchange(engineer, 1, struct.pack(">BHH", 4, 0, 2))[:2] == bytes([4, 4])
        finally:
            engineer.close()
        time.sleep(0.3)
    failed = [line for line in served.stderr if "critical" in line]
    assert len(failed) == 1 and "TLS handshake failed" in failed[0], served.stderr
    assert "unhandled critical extension" in failed[0]
    assert "a Modbus role extension marked critical is one" in failed[0], failed[0]
