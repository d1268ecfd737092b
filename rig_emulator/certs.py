"""Certificates for Modbus/TCP Security tests and demos (``rig-emulator certs --out DIR``).

Makes a certificate authority, a server certificate (subject alternative names 127.0.0.1
and localhost) and client certificates signed by it: one per role, carrying the role in the
X.509 v3 extension of the Modbus/TCP Security specification (OID 1.3.6.1.4.1.50316.802.1,
the value an ASN.1 UTF8String), and one without that extension. EC P-256 keys, valid for
ten years from one day before they are made. They are for a lab, not for production: the
keys are written unencrypted (mode 0600).
"""

from __future__ import annotations

import datetime
import ipaddress
from dataclasses import dataclass
from pathlib import Path

from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import ExtendedKeyUsageOID, NameOID

#: The Modbus/TCP Security role extension.
ROLE_OID = "1.3.6.1.4.1.50316.802.1"
DEFAULT_ROLES = ("observer", "operator", "engineer")
NO_ROLE = "norole"  # file stem of the client certificate without the role extension
VALID_DAYS = 3650
SERVER_NAMES = ("localhost", "127.0.0.1")


@dataclass(frozen=True)
class Issued:
    """A key and the certificate made for it."""

    key: ec.EllipticCurvePrivateKey
    cert: x509.Certificate


def utf8_string_der(text: str) -> bytes:
    """``text`` as a DER-encoded ASN.1 UTF8String (tag 0x0C)."""
    body = text.encode("utf-8")
    if len(body) < 0x80:
        length = bytes([len(body)])
    else:
        size = (len(body).bit_length() + 7) // 8
        length = bytes([0x80 | size]) + len(body).to_bytes(size, "big")
    return b"\x0c" + length + body


def parse_utf8_string_der(der: bytes) -> str:
    """The text of a DER ASN.1 UTF8String; ValueError if ``der`` is not exactly one."""
    if len(der) < 2 or der[0] != 0x0C:
        raise ValueError("not an ASN.1 UTF8String")
    first = der[1]
    if first < 0x80:
        length, start = first, 2
    else:
        size = first & 0x7F
        if size == 0 or size > 4 or len(der) < 2 + size:
            raise ValueError("bad ASN.1 length")
        length, start = int.from_bytes(der[2 : 2 + size], "big"), 2 + size
        if length < 0x80 or der[2] == 0:  # DER: the shortest form only (X.690 10.1)
            raise ValueError("ASN.1 length not in its shortest form (not DER)")
    if len(der) != start + length:
        raise ValueError("ASN.1 length does not match the extension")
    return der[start:].decode("utf-8")


def role_of(cert: x509.Certificate) -> str | None:
    """The role in ``cert``'s Modbus role extension, None without one; ValueError if the
    extension is there but not a UTF8String."""
    try:
        ext = cert.extensions.get_extension_for_oid(x509.ObjectIdentifier(ROLE_OID))
    except x509.ExtensionNotFound:
        return None
    value = ext.value
    if not isinstance(value, x509.UnrecognizedExtension):
        raise ValueError("role extension not understood")
    return parse_utf8_string_der(value.value)


def _name(common_name: str) -> x509.Name:
    return x509.Name(
        [
            x509.NameAttribute(NameOID.ORGANIZATION_NAME, "rig-emulator lab"),
            x509.NameAttribute(NameOID.COMMON_NAME, common_name),
        ]
    )


def _builder(subject: x509.Name, issuer: x509.Name, key: ec.EllipticCurvePrivateKey):
    now = datetime.datetime.now(datetime.UTC)
    return (
        x509.CertificateBuilder()
        .subject_name(subject)
        .issuer_name(issuer)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(days=1))
        .not_valid_after(now + datetime.timedelta(days=VALID_DAYS))
    )


def make_ca(common_name: str = "rig-emulator lab CA") -> Issued:
    """A self-signed certificate authority."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = _name(common_name)
    cert = (
        _builder(name, name, key)
        .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
        .add_extension(
            x509.KeyUsage(
                digital_signature=True,
                content_commitment=False,
                key_encipherment=False,
                data_encipherment=False,
                key_agreement=False,
                key_cert_sign=True,
                crl_sign=True,
                encipher_only=False,
                decipher_only=False,
            ),
            critical=True,
        )
        .add_extension(x509.SubjectKeyIdentifier.from_public_key(key.public_key()), False)
        .sign(key, hashes.SHA256())
    )
    return Issued(key, cert)


def _leaf(
    ca: Issued, common_name: str, server: bool, role: str | None, names: tuple[str, ...] = ()
) -> Issued:
    key = ec.generate_private_key(ec.SECP256R1())
    builder = (
        _builder(_name(common_name), ca.cert.subject, key)
        .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
        .add_extension(
            x509.ExtendedKeyUsage(
                [ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH]
            ),
            critical=False,
        )
        .add_extension(
            x509.AuthorityKeyIdentifier.from_issuer_public_key(ca.key.public_key()), False
        )
    )
    if server:
        builder = builder.add_extension(
            x509.SubjectAlternativeName([_general_name(n) for n in SERVER_NAMES + names]),
            critical=False,
        )
    if role is not None:
        builder = builder.add_extension(
            x509.UnrecognizedExtension(x509.ObjectIdentifier(ROLE_OID), utf8_string_der(role)),
            critical=False,
        )
    return Issued(key, builder.sign(ca.key, hashes.SHA256()))


def _general_name(name: str) -> x509.GeneralName:
    try:
        return x509.IPAddress(ipaddress.ip_address(name))
    except ValueError:
        return x509.DNSName(name)


def make_server(
    ca: Issued, common_name: str = "rig-emulator", names: tuple[str, ...] = ()
) -> Issued:
    """A server certificate for 127.0.0.1, localhost and ``names`` (host names or IPs)."""
    return _leaf(ca, common_name, server=True, role=None, names=names)


def make_client(ca: Issued, common_name: str, role: str | None) -> Issued:
    """A client certificate, with the Modbus role extension unless ``role`` is None."""
    return _leaf(ca, common_name, server=False, role=role)


def write_pair(issued: Issued, out: Path, stem: str) -> tuple[Path, Path]:
    """Write ``STEM.pem`` (certificate) and ``STEM.key`` (unencrypted key, mode 0600)."""
    cert_path, key_path = out / f"{stem}.pem", out / f"{stem}.key"
    cert_path.write_bytes(issued.cert.public_bytes(serialization.Encoding.PEM))
    key_path.touch(mode=0o600)
    key_path.chmod(0o600)
    key_path.write_bytes(
        issued.key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return cert_path, key_path


def make_lab_certificates(
    out: Path, roles: tuple[str, ...] = DEFAULT_ROLES, server_names: tuple[str, ...] = ()
) -> list[Path]:
    """Write ``ca``, ``server`` (also valid for ``server_names``), one client pair per role
    (``observer.pem``/``.key`` ...) and ``norole`` (a client certificate without the role
    extension) into ``out``; the certificate files written."""
    out.mkdir(parents=True, exist_ok=True)
    ca = make_ca()
    server = make_server(ca, names=server_names)
    written = [write_pair(ca, out, "ca")[0], write_pair(server, out, "server")[0]]
    for role in roles:
        written.append(write_pair(make_client(ca, f"{role} client", role), out, role)[0])
    written.append(write_pair(make_client(ca, "client without role", None), out, NO_ROLE)[0])
    return written


def validity_problem(path: str | Path, now: datetime.datetime | None = None) -> str | None:
    """What makes the certificate in ``path`` (PEM) invalid today: "expired on DATE" or
    "not valid before DATE"; None if it is valid, or cannot be read (whoever loads it
    says why)."""
    try:
        cert = x509.load_pem_x509_certificate(Path(path).read_bytes())
    except (OSError, ValueError):
        return None
    now = now or datetime.datetime.now(datetime.UTC)
    if now > cert.not_valid_after_utc:
        return f"expired on {cert.not_valid_after_utc:%Y-%m-%d %H:%M} UTC"
    if now < cert.not_valid_before_utc:
        return f"not valid before {cert.not_valid_before_utc:%Y-%m-%d %H:%M} UTC"
    return None


_USAGE_NAMES = {
    ExtendedKeyUsageOID.SERVER_AUTH: "serverAuth",
    ExtendedKeyUsageOID.CLIENT_AUTH: "clientAuth",
    ExtendedKeyUsageOID.CODE_SIGNING: "codeSigning",
    ExtendedKeyUsageOID.EMAIL_PROTECTION: "emailProtection",
    ExtendedKeyUsageOID.TIME_STAMPING: "timeStamping",
    ExtendedKeyUsageOID.OCSP_SIGNING: "OCSPSigning",
}


def purpose_problem(path: str | Path, server: bool) -> str | None:
    """Why the certificate in ``path`` (PEM) is not for its side of TLS: a server's (or a
    client's, ``server`` False) whose extended key usage leaves out serverAuth (clientAuth),
    which the other side's OpenSSL refuses ("unsuitable certificate purpose"); a server
    certificate made for clients was taken without a word (a stranger's probe). None if it
    is fit, has no extended key usage (any purpose), or cannot be read."""
    try:
        cert = x509.load_pem_x509_certificate(Path(path).read_bytes())
        usage = cert.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value
    except (OSError, ValueError, x509.ExtensionNotFound):
        return None
    needed = ExtendedKeyUsageOID.SERVER_AUTH if server else ExtendedKeyUsageOID.CLIENT_AUTH
    if needed in usage or ExtendedKeyUsageOID.ANY_EXTENDED_KEY_USAGE in usage:
        return None
    names = ", ".join(_USAGE_NAMES.get(oid, oid.dotted_string) for oid in usage) or "empty"
    side = "a TLS server" if server else "a TLS client"
    return f"is not for {side}: its extended key usage is {names}"
