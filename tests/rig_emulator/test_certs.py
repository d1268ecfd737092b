"""``rig-emulator certs``: the files, the chain (checked by OpenSSL's own ``verify``) and
the role extension (decoded by OpenSSL's ``asn1parse``)."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest
from cryptography import x509

from rig_emulator.certs import (
    ROLE_OID,
    parse_utf8_string_der,
    role_of,
    utf8_string_der,
)
from rig_emulator.cli import main

STEMS = ("ca", "server", "observer", "operator", "engineer", "norole")


@pytest.fixture(scope="module")
def cert_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("certs")
    assert main(["certs", "--out", str(out)]) == 0
    return out


def _cert(cert_dir, stem) -> x509.Certificate:
    return x509.load_pem_x509_certificate((cert_dir / f"{stem}.pem").read_bytes())


def test_every_pair_written_keys_private(cert_dir):
    for stem in STEMS:
        assert (cert_dir / f"{stem}.pem").read_text().startswith("-----BEGIN CERTIFICATE")
        key = cert_dir / f"{stem}.key"
        assert key.read_text().startswith("-----BEGIN PRIVATE KEY")
        assert key.stat().st_mode & 0o077 == 0


@pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl not installed")
def test_openssl_verifies_the_chain(cert_dir):
    leaves = [str(cert_dir / f"{s}.pem") for s in STEMS[1:]]
    done = subprocess.run(
        ["openssl", "verify", "-CAfile", str(cert_dir / "ca.pem"), *leaves],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count(": OK") == len(leaves)


@pytest.mark.skipif(shutil.which("openssl") is None, reason="openssl not installed")
@pytest.mark.parametrize("role", ["observer", "operator", "engineer"])
def test_role_extension_is_a_utf8string(cert_dir, role, tmp_path):
    ext = _cert(cert_dir, role).extensions.get_extension_for_oid(x509.ObjectIdentifier(ROLE_OID))
    assert not ext.critical
    der = tmp_path / "ext.der"
    der.write_bytes(ext.value.value)
    done = subprocess.run(
        ["openssl", "asn1parse", "-inform", "DER", "-in", str(der)],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert done.returncode == 0, done.stderr
    assert f"UTF8STRING        :{role}" in done.stdout
    assert role_of(_cert(cert_dir, role)) == role


def test_server_names_and_no_role_without_extension(cert_dir):
    san = _cert(cert_dir, "server").extensions.get_extension_for_class(x509.SubjectAlternativeName)
    assert san.value.get_values_for_type(x509.DNSName) == ["localhost"]
    assert [str(ip) for ip in san.value.get_values_for_type(x509.IPAddress)] == ["127.0.0.1"]
    assert role_of(_cert(cert_dir, "norole")) is None


def test_utf8string_round_trip_long_and_bad():
    for text in ("", "é-role", "x" * 300):
        assert parse_utf8_string_der(utf8_string_der(text)) == text
    with pytest.raises(ValueError):
        parse_utf8_string_der(b"\x13\x02ab")  # a PrintableString
    with pytest.raises(ValueError):
        parse_utf8_string_der(b"\x0c\x05ab")  # length beyond the value
    # BER's longer length forms are not DER (X.690 10.1; a re-probe's certificate got its
    # role from \x0c\x81\x08operator)
    for ber in (b"\x0c\x81\x08operator", b"\x0c\x82\x00\x08operator"):
        with pytest.raises(ValueError, match="shortest form"):
            parse_utf8_string_der(ber)


def test_more_server_names(tmp_path, capsys):
    assert main(["certs", "--out", str(tmp_path), "--server-name", "emulator"]) == 0
    cert = _cert(tmp_path, "server")
    san = cert.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert set(san.get_values_for_type(x509.DNSName)) == {"localhost", "emulator"}
    assert main(["certs", "--out", str(tmp_path), "--server-name", "bad name"]) == 2
    assert "--server-name: 'bad name'" in capsys.readouterr().err


def test_out_is_a_file_is_one_line(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["certs", "--out", str(target)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "is a file" in err


def test_console_script_help():
    done = subprocess.run(
        [sys.executable, "-m", "rig_emulator.cli", "certs", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0 and "--out" in done.stdout


def test_a_second_run_into_a_ca_s_directory_keeps_the_ca(tmp_path, capsys):
    """A stranger's probe: ``certs --out DIR`` run again replaced the CA and every
    certificate without a word, so those handed out stopped working. Refused, one line,
    nothing changed."""
    assert main(["certs", "--out", str(tmp_path)]) == 0
    before = (tmp_path / "ca.pem").read_bytes()
    capsys.readouterr()
    assert main(["certs", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "already holds a CA (ca.key, ca.pem)" in err, err
    assert (tmp_path / "ca.pem").read_bytes() == before


def _with_file_size_limit(limit_bytes: int):
    import resource
    import signal

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return limit


def test_a_full_disk_leaves_no_half_made_ca_and_exits_1(tmp_path):
    """A re-probe: certs on a full disk left an empty ca.pem (exit 2), which every retry
    then took for a CA and refused. Now nothing it made stays, exit 1 (no bad input), and a
    retry with room succeeds; a dangling ca.pem link counts as a CA (the CA was written
    through it, outside DIR)."""
    import subprocess
    import sys

    out = tmp_path / "certs"
    proc = subprocess.run(
        [sys.executable, "-m", "rig_emulator.cli", "certs", "--out", str(out)],
        preexec_fn=_with_file_size_limit(300),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not out.exists()  # not even the directory it made
    assert main(["certs", "--out", str(out)]) == 0
    linked = tmp_path / "linked"
    linked.mkdir()
    (linked / "ca.pem").symlink_to(tmp_path / "elsewhere.pem")
    assert main(["certs", "--out", str(linked)]) == 2
    assert not (tmp_path / "elsewhere.pem").exists()
