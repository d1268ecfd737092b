"""Role policies: the defaults of CONTRACT section 6 and the validation of ROLES.yaml."""

from __future__ import annotations

import pytest

from rig_emulator.modbus.roles import (
    DEFAULT_POLICY,
    RefusalLog,
    RolesError,
    load_policy,
)

READS = (1, 2, 3, 4)
WRITES = (5, 6, 15, 16, 23)


@pytest.mark.parametrize(
    ("role", "writable_units"),
    [("observer", set()), ("operator", set(range(1, 8))), ("engineer", {*range(1, 8), 100})],
)
def test_default_roles(role, writable_units):
    for unit in (*range(0, 9), 99, 100, 247):
        for fc in READS:
            assert DEFAULT_POLICY.refusal(role, unit, fc) is None
        for fc in WRITES:
            refused = DEFAULT_POLICY.refusal(role, unit, fc)
            assert (refused is None) == (unit in writable_units), (role, unit, fc)
    assert DEFAULT_POLICY.default_role == "observer"


def test_unknown_role_may_do_nothing():
    assert DEFAULT_POLICY.refusal("admin", 1, 4) == "unknown role 'admin', which may send nothing"


def test_unlisted_function_codes_need_write():
    assert DEFAULT_POLICY.refusal("observer", 1, 8) is not None  # diagnostics
    assert DEFAULT_POLICY.refusal("observer", 1, 43) is None  # device identification


def test_file_redefines_roles(tmp_path):
    path = tmp_path / "roles.yaml"
    path.write_text(
        "default_role: guest\nroles:\n  guest: {read: [5], write: []}\n"
        "  balance_tech: {read: all, write: [5]}\n"
    )
    policy = load_policy(path)
    assert policy.default_role == "guest"
    assert policy.refusal("guest", 5, 4) is None
    assert policy.refusal("guest", 1, 4) == "may not read unit 1"
    assert policy.refusal("balance_tech", 5, 16) is None
    assert policy.refusal("balance_tech", 1, 16) == "may not write unit 1"
    assert policy.refusal("operator", 1, 4) is not None  # the defaults are gone


@pytest.mark.parametrize(
    ("text", "fault"),
    [
        ("[1, 2]", "expected a mapping"),
        ("roles: {}\n", "non-empty mapping"),
        ("roles: {a: {read: all}}\nextra: 1\n", "unknown key 'extra'"),
        ("roles: {a: {read: all, wrte: []}}\n", "roles.a: unknown key 'wrte'"),
        ("roles: {a: {read: [1, 300]}}\n", "roles.a.read: '300' is not a unit ID"),
        ("roles: {a: {read: some}}\n", "roles.a.read: 'some' is neither"),
        ("roles: {a: {write: [true]}}\n", "roles.a.write: 'True' is not a unit ID"),
        ("roles: {a: {read: all}}\ndefault_role: b\n", "default_role 'b' is not one"),
        ("roles: {a: 3}\n", "roles.a: expected a mapping"),
        ("roles: [\n", "not valid YAML"),
    ],
)
def test_bad_file_is_named(tmp_path, text, fault):
    path = tmp_path / "roles.yaml"
    path.write_text(text)
    with pytest.raises(RolesError) as info:
        load_policy(path)
    message = str(info.value)
    assert fault in message and str(path) in message and "\n" not in message


def test_refusal_log_once_per_connection_and_reason_and_bounded():
    limiter = RefusalLog(burst=3, window_s=60.0)
    assert limiter.admit("a:1", "write unit 1", now=0.0) == 0
    assert limiter.admit("a:1", "write unit 1", now=0.1) is None  # same again
    assert limiter.admit("a:1", "write unit 2", now=0.2) == 1  # a new reason; 1 suppressed
    assert limiter.admit("b:2", "write unit 1", now=0.3) == 0
    assert limiter.admit("c:3", "write unit 1", now=0.4) is None  # over the burst
    assert limiter.admit("d:4", "write unit 1", now=61.0) == 1  # next window: reported
    limiter.forget("a:1")
    assert limiter.admit("a:1", "write unit 1", now=61.1) == 0
