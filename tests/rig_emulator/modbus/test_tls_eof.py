"""A TLS client that closes its side as its handshake ends, against a real ``rig-emulator
serve`` with Modbus/TCP Security."""

from __future__ import annotations

import contextlib
import socket
import ssl

from rig_emulator.certs import make_lab_certificates
from tests.rig_emulator.transports.served import serving

HALF_CLOSES = 5  # connections tried: the client's bytes make the race each time


def _handshake_byte_and_close_notify_in_one_segment(port: int, context: ssl.SSLContext) -> bytes:
    """A TLS connection whose client sends the end of its handshake (its Finished), one
    byte of data and its close_notify in one TCP segment, as ``echo | openssl s_client``
    does; what the server sent after (b"" at its close)."""
    incoming, outgoing = ssl.MemoryBIO(), ssl.MemoryBIO()
    tls = context.wrap_bio(incoming, outgoing, server_hostname="127.0.0.1")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        while True:
            try:
                tls.do_handshake()
                break
            except ssl.SSLWantReadError:
                if outgoing.pending:
                    sock.sendall(outgoing.read())
                data = sock.recv(65536)
                assert data, "the server closed the connection in the handshake"
                incoming.write(data)
        tls.write(b"\n")
        with contextlib.suppress(ssl.SSLWantReadError):  # (the server's is not read)
            tls.unwrap()  # the close_notify, into ``outgoing`` with the rest
        sock.sendall(outgoing.read())
        after = b""
        while chunk := sock.recv(65536):  # until the server closes
            after += chunk
        return after


def test_a_tls_client_closing_as_its_handshake_ends_draws_no_asyncio_warning(tmp_path):
    """A stranger's probe: ``echo | openssl s_client -connect`` to the TLS port logged
    asyncio's "returning true from eof_received() has no effect when using ssl" in 13 of 15
    runs: the close_notify came with the handshake's end, before the TLS transport was
    handed to the connection, which took itself for plain TCP and asked to stay open. Now
    no such line, and the connection is closed."""
    make_lab_certificates(tmp_path)
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.load_verify_locations(cafile=str(tmp_path / "ca.pem"))
    context.load_cert_chain(str(tmp_path / "operator.pem"), str(tmp_path / "operator.key"))
    tls = [
        f"--tls-{kind}={tmp_path / name}"
        for kind, name in (("cert", "server.pem"), ("key", "server.key"), ("ca", "ca.pem"))
    ]
    with serving(*tls) as served:
        for _ in range(HALF_CLOSES):
            _handshake_byte_and_close_notify_in_one_segment(served.port, context)
    err = served.stderr
    assert not any("eof_received" in line for line in err), err
    assert sum("TLS, subject CN=operator client" in line for line in err) == HALF_CLOSES, err
    assert not any("Traceback" in line for line in err), err
