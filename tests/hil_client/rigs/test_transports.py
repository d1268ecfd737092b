"""``--rig`` URLs of the three transports and the TLS options that go with them."""

from __future__ import annotations

import os
import re
from pathlib import Path
from types import SimpleNamespace

import pytest

from hil_client.rigs.transports import Endpoint, connector, parse_endpoint, tls_files


@pytest.mark.parametrize(
    ("url", "endpoint"),
    [
        ("modbus://127.0.0.1:5020", Endpoint("modbus", host="127.0.0.1", port=5020)),
        ("modbus+tls://localhost", Endpoint("modbus+tls", host="localhost", port=802)),
        ("modbus+tls://127.0.0.1:8020", Endpoint("modbus+tls", host="127.0.0.1", port=8020)),
        (
            "modbus-rtu:///dev/pts/7?baud=115200",
            Endpoint("modbus-rtu", path="/dev/pts/7", baud=115200),
        ),
        (
            "modbus-rtu:///dev/ttyUSB0?baud=9600&parity=n",
            Endpoint("modbus-rtu", path="/dev/ttyUSB0", baud=9600, parity="N"),
        ),
        ("modbus-rtu:///dev/ttyS0", Endpoint("modbus-rtu", path="/dev/ttyS0", baud=19200)),
    ],
)
def test_good_urls(url, endpoint):
    assert parse_endpoint(url) == endpoint


@pytest.mark.parametrize(
    ("url", "fault"),
    [
        ("tcp://1.2.3.4:5", "is not modbus://"),
        ("modbus+tls://:802", "names no host"),
        ("modbus+tls://h:99999", "bad port"),
        ("modbus-rtu://host/dev/x", "names no device"),
        ("modbus-rtu:///dev/x?baud=fast", "baud 'fast'"),
        ("modbus-rtu:///dev/x?parity=X", "parity 'X'"),
        ("modbus-rtu:///dev/x?speed=9600", "unknown parameter 'speed'"),
    ],
)
def test_bad_urls_name_the_fault(url, fault):
    with pytest.raises(ValueError, match=fault):
        parse_endpoint(url)


def test_tls_options_all_or_none(tmp_path):
    assert tls_files(SimpleNamespace(tls_cert=None, tls_key=None, tls_ca=None)) is None
    with pytest.raises(ValueError, match="--tls-key, --tls-ca"):
        tls_files(SimpleNamespace(tls_cert=tmp_path / "c", tls_key=None, tls_ca=None))
    files = tls_files(SimpleNamespace(tls_cert="c", tls_key="k", tls_ca="a"))
    with pytest.raises(ValueError, match="need a modbus\\+tls"):
        connector("modbus://127.0.0.1:5020", 1.0, files)
    with pytest.raises(ValueError, match="needs --tls-cert"):
        connector("modbus+tls://127.0.0.1:802", 1.0, None)
    with pytest.raises(ValueError, match="--tls-cert c: no such file"):
        connector("modbus+tls://127.0.0.1:802", 1.0, files)


def test_tls_files_that_are_no_regular_files_are_named_so(tmp_path):
    """A re-probe: the client said "no such file" of a FIFO, a device and a directory."""
    from rig_emulator.certs import make_lab_certificates

    make_lab_certificates(tmp_path)
    os.mkfifo(tmp_path / "fifo.pem")
    good = {"tls_cert": tmp_path / "server.pem", "tls_key": tmp_path / "server.key"}
    good["tls_ca"] = tmp_path / "ca.pem"
    for option, path, said in (
        ("tls_cert", tmp_path / "fifo.pem", "not a regular file, not a PEM file"),
        ("tls_ca", Path("/dev/null"), "not a regular file, not a PEM file"),
        ("tls_key", tmp_path, "is a directory, not a PEM file"),
        ("tls_ca", tmp_path / "none.pem", "no such file"),
    ):
        files = tls_files(SimpleNamespace(**{**good, option: path}))
        flag = "--" + option.replace("_", "-")
        with pytest.raises(ValueError, match=f"{flag} {re.escape(str(path))}: {said}"):
            connector("modbus+tls://127.0.0.1:802", 1.0, files)


def test_a_key_protected_by_a_passphrase_is_one_line(tmp_path):
    """OpenSSL asked for the passphrase on the terminal (or raised OSError through a
    traceback with stdin closed, as under CI)."""
    from hil_client.rigs.transports import TlsFiles
    from rig_emulator.certs import make_lab_certificates
    from tests.modbus_helpers import encrypted_copy

    make_lab_certificates(tmp_path)
    encrypted = encrypted_copy(tmp_path / "engineer.key", tmp_path / "encrypted.key")
    files = TlsFiles(tmp_path / "engineer.pem", encrypted, tmp_path / "ca.pem")
    with pytest.raises(ValueError, match=r"encrypted\.key is protected by a passphrase"):
        connector("modbus+tls://127.0.0.1:802", 1.0, files)
