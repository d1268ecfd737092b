"""Role policies: the defaults of CONTRACT section 6 and the validation of ROLES.yaml."""

from __future__ import annotations

import pytest

from rig_emulator.modbus.roles import (
    ALL_UNITS,
    DEFAULT_POLICY,
    RefusalLog,
    RolesError,
    default_policy,
    load_policy,
    policy_from_mapping,
)
from rig_emulator.registers import load_map, map_from_mapping
from tests.rig_emulator.transports.remapped import shipped_map_with_units

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


def test_default_policy_of_the_shipped_map_is_the_default_policy():
    assert default_policy(load_map()) == DEFAULT_POLICY
    assert DEFAULT_POLICY.summary() == (
        "observer reads every unit, writes no unit; operator reads every unit, writes units "
        "1-7; engineer reads every unit, writes units 1-7, 100"
    )


@pytest.mark.parametrize(
    ("units", "instruments", "control"),
    [
        # a stranger's probe: the simulation control and the boiler controller swapped
        ({"sim_control": 7, "boiler_controller": 100}, {*range(1, 7), 100}, {7}),
        # instruments at the edges of the unit range
        ({"bench_plc": 31, "boiler_controller": 247}, {*range(2, 7), 31, 247}, {100}),
    ],
)
def test_default_policy_follows_the_devices_not_their_unit_ids(units, instruments, control):
    """The operator writes the units of the instruments and the engineer also those of the
    simulation control, wherever the map puts them; the truth unit (101) stays read only."""
    policy = default_policy(shipped_map_with_units(**units))
    assert policy.roles["observer"].write_units == frozenset()
    assert policy.roles["operator"].write_units == instruments
    assert policy.roles["engineer"].write_units == instruments | control
    assert all(role.read_units == ALL_UNITS for role in policy.roles.values())
    assert policy.default_role == "observer"


def test_a_unit_sharing_instrument_and_clock_points_is_simulation_control():
    """Roles go per unit: a unit with a clock command is the engineer's, even with a pump
    on it (else the operator resets the plant through it); status-only units are read only."""
    register_map = map_from_mapping(
        {
            "devices": [
                {
                    "name": "plc",
                    "unit_id": 1,
                    "points": [
                        {"signal": "pump_on", "table": "coil", "address": 0,
                         "datatype": "bool", "access": "rw"},
                        {"signal": "reset", "table": "holding", "address": 0,
                         "datatype": "uint16", "access": "rw"},
                    ],
                },
                {
                    "name": "truth",
                    "unit_id": 2,
                    "points": [{"signal": "true_water_flow_kg_h", "table": "input",
                                "address": 0, "datatype": "float64"}],
                },
                {
                    "name": "clock_status",
                    "unit_id": 3,
                    "points": [{"signal": "sim_time_s", "table": "input", "address": 0,
                                "datatype": "float64"}],
                },
                {
                    "name": "balance",
                    "unit_id": 4,
                    "points": [{"signal": "balance_mass_kg", "table": "input", "address": 0,
                                "datatype": "float32"}],
                },
            ]
        }
    )  # fmt: skip
    policy = default_policy(register_map)
    assert policy.roles["operator"].write_units == {4}
    assert policy.roles["engineer"].write_units == {1, 4}


def test_unknown_role_may_do_nothing():
    assert DEFAULT_POLICY.refusal("admin", 1, 4) == "unknown role 'admin', which may send nothing"


def test_unlisted_function_codes_need_read_and_write():
    assert DEFAULT_POLICY.refusal("observer", 1, 8) is not None  # diagnostics
    assert DEFAULT_POLICY.refusal("observer", 1, 43, 14) is None  # device identification
    assert DEFAULT_POLICY.refusal("observer", 1, 43, 13) is not None  # CANopen may write
    assert DEFAULT_POLICY.refusal("observer", 1, 200) is not None  # nobody knows what it does


@pytest.mark.parametrize(
    ("function_code", "mei_type", "needs"),
    [
        *((fc, None, {"read"}) for fc in (1, 2, 3, 4, 7, 11, 12, 17, 20, 24)),
        (43, 14, {"read"}),
        *((fc, None, {"write"}) for fc in (5, 6, 15, 16, 21, 22)),
        (23, None, {"read", "write"}),  # writes, then returns the registers it reads
        (8, None, {"read", "write"}),
        (43, 13, {"read", "write"}),
        (43, None, {"read", "write"}),  # no MEI type: not the read it claims
        (99, None, {"read", "write"}),
    ],
)
def test_a_request_needs_every_right_of_what_it_does(function_code, mei_type, needs):
    """A stranger's probe: a role that writes unit 1 but may not read it read unit 1's
    holding registers through FC23 (its read half was never checked)."""
    policy = policy_from_mapping(
        {
            "roles": {
                "reader": {"read": [1]},
                "writer": {"write": [1]},
                "both": {"read": [1], "write": [1]},
            },
            "default_role": "reader",
        },
        "test",
    )
    for role, granted in (("reader", {"read"}), ("writer", {"write"}), ("both", {"read", "write"})):
        refused = policy.refusal(role, 1, function_code, mei_type)
        assert (refused is None) == (needs <= granted), (role, function_code, mei_type, refused)


def test_the_summary_says_what_a_role_reads():
    """``write: all`` without ``read`` reads nothing; the start-up line said only
    "engineer writes every unit" (a stranger's probe)."""
    policy = policy_from_mapping(
        {
            "roles": {"engineer": {"write": "all"}, "operator": {"read": [7], "write": [1, 7]}},
            "default_role": "operator",
        },
        "test",
    )
    assert policy.summary() == (
        "engineer reads no unit, writes every unit; operator reads unit 7, writes units 1, 7"
    )


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
        # the broadcast address and the reserved ones were taken (a stranger's probe)
        ("roles: {a: {write: [0]}}\n", "roles.a.write: '0' is not a unit ID (1-247; 0 is"),
        ("roles: {a: {write: [248]}}\n", "roles.a.write: '248' is not a unit ID (1-247;"),
        ("roles: {a: {read: [255]}}\n", "roles.a.read: '255' is not a unit ID (1-247;"),
        # a file gave the rights of its '<invalid role extension>' to every malformed role
        # extension (a stranger's probe); a name no log line shows as it is, likewise
        ("roles: {'<invalid role extension>': {read: all}}\n", "is in angle brackets"),
        ('roles: {"eng\\nineer": {read: all}}\n', "'eng\\nineer' holds U+000A: a control"),
        ('roles: {"eng\\tineer": {read: all}}\n', "holds U+0009: a control character"),
        ('roles: {"\\n": {read: all}}\n', "role name '\\n' is not a non-empty text"),
        ("roles: {a: {read: some}}\n", "roles.a.read: 'some' is neither"),
        ("roles: {a: {write: [true]}}\n", "roles.a.write: 'true' is not a unit ID"),
        # a quoted 1 was "'1' is not a unit ID (1-247 ...)" (a stranger's probe)
        ("roles: {a: {write: ['1', 2]}}\n", "roles.a.write: '1' is text: a unit ID is a number"),
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
