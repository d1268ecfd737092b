"""FAULTS.yaml as data: every kind parses; every bad entry is one error naming entry and field."""

from __future__ import annotations

import datetime

import pytest

from rig_emulator.faults import FaultError, FaultSpec, RandomSpec, faults_from_list, load_faults
from rig_emulator.instruments import ProfileError, load_profile, profile_from_mapping

GOOD = [
    {"kind": "delay", "unit": 1, "delay_ms": 800, "at_s": 10, "for_s": 5},
    {"kind": "no_reply", "unit": 2, "at_s": 20},
    {"kind": "exception", "unit": 0, "code": 11},
    {"kind": "disconnect", "at_s": 30},
    {"kind": "stuck", "signal": "flue_gas_temp_C", "at_s": 40, "for_s": 60},
    {"kind": "drift", "signal": "water_out_temp_C", "rate_per_h": -2.5},
    {"kind": "spike", "signal": "flue_gas_O2_pct", "value": 25},
    {"kind": "dropout", "signal": "flue_gas_CO_ppm"},
    {"kind": "offset", "signal": "balance_mass_kg", "value": 15.0},
    {"kind": "random", "rate_per_h": 2, "kinds": ["no_reply", "spike"], "seed": 7},
]


def test_every_kind_parses_with_its_parameter():
    entries = faults_from_list(GOOD, "f.yaml")
    assert [e.kind for e in entries] == [g["kind"] for g in GOOD]
    delay, no_reply, exc, disc, stuck, drift, spike, dropout, offset, rnd = entries
    assert delay == FaultSpec("delay", 10.0, 5.0, 1, None, 800.0)
    assert no_reply.unit == 2 and no_reply.for_s is None
    assert exc.parameter == 11.0 and disc.unit == 0
    assert stuck.signal == "flue_gas_temp_C" and drift.parameter == -2.5
    assert spike.parameter == 25.0 and dropout.parameter is None and offset.parameter == 15.0
    assert isinstance(rnd, RandomSpec) and rnd.seed == 7 and rnd.kinds == ("no_reply", "spike")
    # the dict form round-trips
    assert faults_from_list([e.as_dict() for e in entries[:9]]) == entries[:9]


@pytest.mark.parametrize(
    ("entry", "where"),
    [
        ({"kind": "lightning", "unit": 1}, "faults[0].kind"),
        ({"kind": "delay", "unit": 1}, "faults[0].delay_ms"),
        ({"kind": "delay", "unit": 1, "delay_ms": -5}, "faults[0].delay_ms"),
        ({"kind": "delay", "unit": 1, "delay_ms": 10**400}, "faults[0].delay_ms"),  # traceback
        ({"kind": "exception", "unit": 1, "code": 0}, "faults[0].code"),
        ({"kind": "exception", "unit": 1, "code": 4.5}, "faults[0].code"),
        ({"kind": "no_reply", "unit": 300}, "faults[0].unit"),
        ({"kind": "no_reply"}, "faults[0].unit: missing (a whole number"),  # (was "not None")
        ({"kind": "stuck", "signal": "nonsense"}, "faults[0].signal"),
        ({"kind": "stuck"}, "faults[0].signal"),
        ({"kind": "stuck", "signal": "room_temp_C", "unit": 1}, "faults[0].unit"),
        ({"kind": "drift", "signal": "room_temp_C", "rate_per_h": "fast"}, "faults[0].rate_per_h"),
        ({"kind": "spike", "signal": "room_temp_C", "value": float("nan")}, "faults[0].value"),
        ({"kind": "no_reply", "unit": 1, "at_s": -1}, "faults[0].at_s"),
        ({"kind": "no_reply", "unit": 1, "for_s": 0}, "faults[0].for_s"),
        ({"kind": "random", "kinds": ["spike"]}, "faults[0].rate_per_h"),
        ({"kind": "random", "rate_per_h": 1, "kinds": []}, "faults[0].kinds"),
        ({"kind": "random", "rate_per_h": 1, "kinds": ["spike", "x"]}, "faults[0].kinds[1]"),
        (
            {"kind": "random", "rate_per_h": 1, "kinds": ["delay"], "params": {"delay": {"x": 1}}},
            "faults[0].params.delay",
        ),
        # a stranger's probe: a parameter of a kind never drawn was ignored without a word
        (
            {
                "kind": "random",
                "rate_per_h": 1,
                "kinds": ["no_reply", "delay"],
                "params": {"spike": {"value": 50}},
            },
            "faults[0].params.spike: 'spike' is not among the kinds drawn (no_reply, delay)",
        ),
        ("no_reply", "faults[0]"),
        # said as "kind: None is not one of", and a date as datetime.date(...): a probe
        ({"unit": 1}, "faults[0]: missing 'kind'"),
        (
            {"kind": "no_reply", "unit": 1, "at_s": datetime.date(2026, 1, 1)},
            "faults[0].at_s: must be a number, not '2026-01-01'",
        ),
    ],
)
def test_a_bad_entry_names_the_entry_and_field(entry, where):
    with pytest.raises(FaultError) as err:
        faults_from_list([GOOD[0], entry][1:], "f.yaml")
    message = str(err.value)
    assert message.startswith("f.yaml: ") and where in message, message
    assert "\n" not in message


def test_a_bad_file_is_named(tmp_path):
    path = tmp_path / "faults.yaml"
    path.write_text("faults: [{kind: no_reply, unit: 2}\n")
    with pytest.raises(FaultError, match=r"faults.yaml: not valid YAML"):
        load_faults(path)
    path.write_text("fault: []\n")
    with pytest.raises(FaultError, match=r"expected a mapping with a list 'faults:'"):
        load_faults(path)
    path.write_text("faults:\n  - {kind: no_reply, unit: 2}\n  - {kind: spike, signal: x}\n")
    with pytest.raises(FaultError, match=r"faults\[1\]\.value|faults\[1\]\.signal"):
        load_faults(path)


def test_profiles_carry_faults():
    faulty = load_profile("lab_faulty")
    lab = load_profile("lab")
    assert faulty.instruments == lab.instruments and faulty.effects == lab.effects
    assert len(faulty.faults) == 1 and isinstance(faulty.faults[0], RandomSpec)
    assert lab.faults == ()
    with pytest.raises(ProfileError, match=r"p.yaml: faults\[0\].kind"):
        profile_from_mapping({"name": "x", "faults": [{"kind": "hail"}]}, "p.yaml")


@pytest.mark.parametrize(
    ("signal", "value", "ok"),
    [
        ("balance_mass_kg", -2147483.647, True),  # int32 x 0.001: its lowest reading
        ("balance_mass_kg", -2147483.648, False),  # its invalid code (a dropout)
        ("flue_gas_temp_C", 327.67, True),  # int16 x 0.01: its highest reading
        ("flue_gas_temp_C", 327.6700134, True),  # the same as a float32 carries it
        ("flue_gas_temp_C", 327.68, False),
    ],
)
def test_a_spike_is_one_its_register_serves_to_its_step(signal, value, ok):
    """Spikes on 32-bit registers slipped past the range check with a slack of a millionth
    of the range (2.1 kg on the balance: its invalid code was accepted; a re-probe). The
    slack is half the register's step; the message gives the range in full."""
    from rig_emulator.faults import check_spikes
    from rig_emulator.modbus.fault_control import reading_ranges
    from rig_emulator.registers import load_map

    (spike,) = faults_from_list([{"kind": "spike", "signal": signal, "value": value}])
    if ok:
        check_spikes([spike], reading_ranges(load_map()), "faults.yaml")
    else:
        with pytest.raises(FaultError, match=r"outside what .*\(-?[0-9.]+\.\.[0-9.]+: unit"):
            check_spikes([spike], reading_ranges(load_map()), "faults.yaml")


def test_a_signal_on_two_registers_serves_what_both_serve():
    """A re-probe: a map publishing flue_gas_temp_C as a uint16 x0.1 (0..6553.4) and as an
    int16 x0.01 (-327.67..327.67) kept the narrower's range alone: a spike of -100 was
    taken, journalled -100 and served 0 by the uint16. The range is what both serve."""
    from rig_emulator.faults import check_spikes
    from rig_emulator.modbus.fault_control import reading_ranges
    from rig_emulator.registers import MAP_DIR, map_from_mapping
    from rig_emulator.yamlio import read_yaml

    data = read_yaml(MAP_DIR / "wieselburg_bench.yaml", ValueError)
    device = next(
        d for d in data["devices"] if any(p["name"] == "flue_gas_temp" for p in d["points"])
    )
    point = next(p for p in device["points"] if p["name"] == "flue_gas_temp")
    used = {(p["table"], p["address"] + k) for p in device["points"] for k in range(4)}
    address = next(a for a in range(100, 200) if ("input", a) not in used)
    device["points"].insert(  # the wider first: the narrower one came second
        0, dict(point, name="flue_gas_temp_coarse", datatype="uint16", scale=0.1, address=address)
    )
    ranges = reading_ranges(map_from_mapping(data, "two.yaml"))
    assert ranges["flue_gas_temp_C"][:2] == (0.0, pytest.approx(327.67))
    (spike,) = faults_from_list([{"kind": "spike", "signal": "flue_gas_temp_C", "value": -100}])
    with pytest.raises(FaultError, match=r"outside what flue_gas_temp_C's register serves"):
        check_spikes([spike], ranges, "faults.yaml")


@pytest.mark.parametrize(
    "entry",
    [
        {"kind": "no_reply", "unit": 100},
        {"kind": "random", "rate_per_h": 1, "kinds": ["spike"], "units": [100]},
    ],
)
def test_the_maps_own_units_are_never_faulted(entry):
    """The emulator's own units are the map's (a re-probe: a map with the simulation control
    at unit 7 let a fault on every unit silence it); the shipped map's are 100 and 101."""
    from rig_emulator.faults.spec import check_units
    from rig_emulator.registers import emulator_units, load_map

    shipped = load_map()
    assert emulator_units(shipped) == {100, 101}
    units = {d.unit_id for d in shipped.devices}
    with pytest.raises(FaultError, match="unit 100 is the emulator's own"):
        check_units(faults_from_list([entry]), units, "f.yaml", emulator_units(shipped))
