"""Role names and how the log shows them: a name is text of any script, refused only for a
character that displays as something else or as nothing, or for the form of the server's
own stand-ins; a role reads the same in every log line; the start-up summary says whom the
roles judge (``rig-emulator serve`` as its own process, real files, real TLS sockets)."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

from hil_client.wait_for_port import free_port
from rig_emulator.certs import make_ca, make_client, make_server, write_pair
from rig_emulator.modbus.roles import INVALID_ROLE, RolesError, policy_from_mapping
from tests.rig_emulator.transports.served import run_serve, serving, tcp_exchange, tls_connect

#: names a stranger's probe saw refused ("holds '>'", "not printable") that display as
#: themselves: a no-break space and an em space are spaces, a combining accent is text; and
#: names a re-probe saw refused that worked before, spelt with a zero-width non-joiner
#: (Persian) or joiner (Devanagari, an emoji sequence)
NAMES_TAKEN = [
    "a->b",
    "op<1>",
    "lab\u00a0tech",
    "lab\u2003tech",
    "e\u0301ng",
    "运维",
    "😀",
    "\u06a9\u0627\u0631\u0634\u0646\u0627\u0633\u200c\u0627\u0631\u0634\u062f",
    "\u0915\u094d\u200d\u0937",
    "\U0001f469\u200d\U0001f52c",
]
#: names holding a character that displays as another or as nothing, and the code point
#: the refusal names
NAMES_REFUSED = [
    ("lab\ttech", "U+0009: a control character"),
    ("eng\u200b", "U+200B ZERO WIDTH SPACE: a format character"),
    ("\u202eeng", "U+202E RIGHT-TO-LEFT OVERRIDE: a format character"),
    ("\u00ad", "U+00AD SOFT HYPHEN: a format character"),
    ("x\u2028y", "U+2028 LINE SEPARATOR: a line separator"),
    ("x\u2029y", "U+2029 PARAGRAPH SEPARATOR: a paragraph separator"),
    ("eng\ud800", "U+D800: a surrogate"),
    ("eng\ue000", "U+E000: a private-use character"),
    ("eng\u0378", "U+0378: an unassigned code point"),
    (INVALID_ROLE, "is in angle brackets, the form of the server's own stand-ins"),
    ("<operator>", "is in angle brackets, the form of the server's own stand-ins"),
]
WRITE_UNIT_7 = struct.pack(">BHH", 6, 0, 630)  # the boiler controller's first holding register
REFUSED_01 = bytes([0x86, 0x01])


def _policy_of(name: str):
    return policy_from_mapping({"roles": {name: {"read": "all"}, "observer": {}}}, "r.yaml")


@pytest.mark.parametrize("name", NAMES_TAKEN)
def test_a_name_that_displays_as_itself_is_a_role(name):
    """A stranger's probe: ``a->b`` and ``op<1>`` were refused as "names in angle brackets",
    a no-break space as "not printable"."""
    assert name in _policy_of(name).roles


@pytest.mark.parametrize(("name", "fault"), NAMES_REFUSED)
def test_a_name_that_displays_as_another_is_refused_naming_the_character(name, fault):
    """Refused only for what the name's reader cannot see (the message names the character
    by its code point, and is printable itself) or for the stand-ins' ``<...>``."""
    with pytest.raises(RolesError, match=r"r\.yaml: role name '") as info:
        _policy_of(name)
    message = str(info.value)
    assert fault in message and message.isprintable(), message


def _lab(directory: Path, clients: dict[str, str]) -> list[str]:
    """A CA, a server certificate and one client certificate per ``stem: role`` in
    ``directory``; the TLS options of ``serve``."""
    ca = make_ca()
    write_pair(ca, directory, "ca")
    write_pair(make_server(ca), directory, "server")
    for stem, role in clients.items():
        write_pair(make_client(ca, stem, role), directory, stem)
    return [
        *("--tls-cert", str(directory / "server.pem"), "--tls-key"),
        *(str(directory / "server.key"), "--tls-ca", str(directory / "ca.pem")),
    ]


def _roles(directory: Path, roles: dict[str, dict]) -> list[str]:
    """A roles file (UTF-8 JSON, which YAML reads) in ``directory``; its ``serve`` option."""
    path = directory / "roles.yaml"
    path.write_text(json.dumps({"roles": roles}, ensure_ascii=False), encoding="utf-8")
    return ["--roles", str(path)]


def _write_unit_7(port: int, directory: Path, stem: str) -> bytes:
    sock = tls_connect(port, directory, stem)
    try:
        return tcp_exchange(sock, 7, WRITE_UNIT_7)
    finally:
        sock.close()


def test_serve_takes_names_of_any_script_and_their_certificates_act_by_them(tmp_path):
    """A stranger's probe: a roles file naming ``a->b``, ``op<1>`` or ``lab tech`` with a
    no-break space was refused in one line ("holds '>'", "not printable"). Now the server
    starts, and a certificate of each role writes unit 7 as its role allows."""
    clients = {f"c{k}": name for k, name in enumerate(NAMES_TAKEN)}
    options = _lab(tmp_path, clients)
    roles = {name: {"read": "all", "write": [7]} for name in NAMES_TAKEN}
    options += _roles(tmp_path, {"observer": {"read": "all"}, **roles})
    with serving(*options) as served:
        for stem in clients:
            assert _write_unit_7(served.port, tmp_path, stem) == WRITE_UNIT_7, stem


def test_serve_refuses_a_name_that_displays_as_another_in_one_line(tmp_path):
    """A bidi override makes ``\\u202eeng`` display as ``gne``: refused, exit 2, naming it."""
    options = _lab(tmp_path, {}) + _roles(tmp_path, {"observer": {}, "\u202eeng": {}})
    done = run_serve("--port", "0", *options)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
    assert "role name '\\u202eeng' holds U+202E RIGHT-TO-LEFT OVERRIDE" in done.stderr


def test_a_role_reads_the_same_in_every_log_line(tmp_path):
    """A stranger's probe: the role ``Ingenieur Ä`` read so in the start-up summary but as
    ``Ingenieur \\xc4`` in its connection line, and ``😀`` as ``\\U0001f600`` in the
    connection and refusal lines. Only what displays as another is escaped: a certificate's
    role holding a bidi override or a newline still cannot write lines of its own."""
    clients = {"uni": "Ingenieur Ä", "emoji": "😀", "forger": "eng\u202e\n2026 FAKE"}
    options = _lab(tmp_path, clients)
    roles = {"observer": {"read": "all"}, "Ingenieur Ä": {"read": "all", "write": [7]}}
    options += _roles(tmp_path, {**roles, "😀": {"read": [7]}})
    with serving(*options) as served:
        assert _write_unit_7(served.port, tmp_path, "uni") == WRITE_UNIT_7
        assert _write_unit_7(served.port, tmp_path, "emoji") == REFUSED_01
        assert _write_unit_7(served.port, tmp_path, "forger") == REFUSED_01  # unknown role
    log = served.stderr
    summary = next(line for line in log if "roles: " in line)
    assert "; Ingenieur Ä reads every unit, writes unit 7; 😀 reads unit 7" in summary, summary
    for shown in ("Ingenieur Ä", "😀"):
        assert any(line.endswith(f", role {shown}") for line in log), (shown, log)
    assert any("role 😀): may not write unit 7" in line for line in log), log
    forged = "eng\\u202e\\n2026 FAKE"
    assert any(line.endswith(f"role {forged}") for line in log), log
    assert any(f"unknown role '{forged}'" in line for line in log), log
    assert not any(line.startswith("2026 FAKE") for line in log), log
    roles = [line for line in log if "role" in line]
    assert not any("\\x" in line or "\\U" in line for line in roles), roles


CERTIFICATE_DEFAULT = "a certificate without a role is observer"
PLAIN_HELD = "plain TCP and RTU clients are held to operator"
PLAIN_FREE = f"{CERTIFICATE_DEFAULT}; plain TCP clients carry no role and pass the role gate"
NOBODY_PLAIN = (
    f"{CERTIFICATE_DEFAULT}; --plain-role operator holds nobody (no plain TCP or RTU here)"
)


@pytest.mark.parametrize(
    ("tls", "options", "serial", "whom"),
    [
        (False, ["--plain-role", "operator"], True, PLAIN_HELD),
        (True, ["--tcp-port", "FREE"], False, PLAIN_FREE),
        (True, ["--plain-role", "operator"], False, NOBODY_PLAIN),
    ],
)
def test_the_summary_says_whom_the_roles_judge(tmp_path, tls, options, serial, whom):
    """A stranger's probe: with ``--plain-role operator`` and no TLS, the start-up summary
    ended "a certificate without a role is observer" (that server has no certificates) and
    never said that its plain TCP and RTU clients were held to operator."""
    given = [str(free_port()) if option == "FREE" else option for option in options]
    tls_options = _lab(tmp_path, {}) if tls else []
    line = ["--serial", "pty"] if serial else []
    with serving(*tls_options, *given, *line, serial=serial) as served:
        pass
    summary = next(
        line for line in served.stderr if "roles (defaults of the map's devices)" in line
    )
    assert summary.endswith(f"; {whom}"), summary
    assert tls or "certificate" not in summary, summary
