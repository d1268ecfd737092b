"""Test methods as data (Table 2) and the runner's phase rules on the in-process rig."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.protocol.definition import (
    DEFINITION_DIR,
    ProtocolError,
    load_protocol,
    parse_duration,
)
from hil_client.protocol.runner import LOG_COLUMNS, flow_for_load

# Table 2 of Carlon et al. (2015): (sequence, load %, duration)
TABLE_2 = [
    ("peak", (100, 100), "00:04:52"),
    ("gradient_100_48", (100, 48), "00:26:00"),
    ("stationary_48", (48, 48), "00:50:15"),
    ("gradient_48_39", (48, 39), "00:09:00"),
    ("stationary_39", (39, 39), "01:13:44"),
    ("gradient_39_63", (39, 63), "00:12:00"),
    ("stationary_63", (63, 63), "00:24:38"),
    ("gradient_63_30", (63, 30), "00:22:00"),
    ("stationary_30", (30, 30), "00:53:14"),
    ("gradient_30_13", (30, 13), "00:34:00"),
    ("stationary_13", (13, 13), "02:50:17"),
]

# CONTRACT.md section 3, written out on purpose: the pin must not be derived from
# READING_KEYS/LOG_COLUMNS, the code it checks.
CONTRACT_COLUMNS = [
    "time_s",
    "phase",
    "sequence",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "balance_mass_kg",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "water_flow_setpoint_kg_h",
    "boiler_on",
]


def test_load_cycle_is_table_2_exactly():
    proto = load_protocol("load_cycle")
    got = [(s.name, (s.load_start_pct, s.load_end_pct), s.duration_s) for s in proto.sequences]
    want = [(n, load, parse_duration(d, "d", "t")) for n, load, d in TABLE_2]
    assert got == want
    assert proto.test_duration_s == 8 * 3600  # "the duration of the load cycle ... is 8 h"
    ramp = proto.sequences[1]
    assert ramp.load_at(ramp.duration_s / 2) == pytest.approx(74.0)  # linear 100 -> 48


def test_stationary_is_six_hours_at_nominal_load():
    proto = load_protocol("stationary")
    assert [(s.load_start_pct, s.duration_s) for s in proto.sequences] == [(100, 6 * 3600)]


def test_load_to_flow():
    # load * Pnom / (cp_w * 15 K): 12 kW -> 687.35 kg/h
    assert flow_for_load(100, 12.0, 15.0) == pytest.approx(12 * 3600 / (4.19 * 15))


def test_log_columns_are_the_contract_columns_then_optional_ones():
    assert list(LOG_COLUMNS[: len(CONTRACT_COLUMNS)]) == CONTRACT_COLUMNS
    assert LOG_COLUMNS[len(CONTRACT_COLUMNS) :] == (
        "flue_gas_NOx_ppm",
        "flue_gas_SO2_ppm",
        "flue_gas_OGC_ppm",
        "rig_epoch",
    )


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.pop("cooling_1"), "missing required key 'cooling_1'"),
        (lambda d: d["test_sequence"]["sequences"][0].update(duration="4:52"), "HH:MM:SS"),
        (lambda d: d["test_sequence"]["sequences"][1].update(load_pct=[100]), "[from, to]"),
        (lambda d: d["test_sequence"]["sequences"][2].update(load_pct=500), "0..120 %"),
        (lambda d: d["start_up"].pop("t1_window_s"), "'start_up.t1_window_s'"),
        (lambda d: d.update(acquisition_period_s=0), "must be > 0"),
        (lambda d: d.update(extra=1), "unknown key 'extra'"),
        # a stranger wrote a protocol from the errors, which did not say the keys there are
        (
            lambda d: d["cooling_1"].update(duration_s=60),
            "unknown key 'cooling_1.duration_s' (the keys of 'cooling_1': load_pct, "
            "max_duration_s, return_setpoint_C, until_forward_C)",
        ),
        # a stranger's probes: a repeated or blank name, a step shorter than a period (never
        # logged, its setpoint never written), a time of 99 minutes
        (
            lambda d: d["test_sequence"]["sequences"].append(
                dict(d["test_sequence"]["sequences"][0])
            ),
            "names an earlier sequence",
        ),
        (lambda d: d["test_sequence"]["sequences"][0].update(name=" "), ".name'"),
        (
            lambda d: (
                d.update(acquisition_period_s=10)
                or d["test_sequence"]["sequences"][0].update(duration=3)
            ),
            "less than one acquisition period",
        ),
        (lambda d: d["test_sequence"]["sequences"][0].update(duration="00:99:99"), "HH:MM:SS"),
        # an integer of 400 digits has no float: OverflowError, a traceback (a probe)
        (lambda d: d["start_up"].update(max_duration_s=10**400), "must be a finite number"),
    ],
)
def test_broken_protocol_files_name_the_key(tmp_path: Path, mutate, message):
    data = yaml.safe_load((DEFINITION_DIR / "load_cycle.yaml").read_text())
    mutate(data)
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ProtocolError) as info:
        load_protocol(str(path))
    assert message in str(info.value) and str(path) in str(info.value)


def _arr(record, name):
    return np.array([np.nan if v is None else v for v in record[name]], dtype=float)


@pytest.mark.parametrize("protocol", ["stationary", "load_cycle"])
@pytest.mark.parametrize("boiler", ["windhager_12kw", "windhager_6kw"])
def test_phase_rules(run_log, protocol, boiler):
    rec = run_log(protocol, boiler)
    meta = rec.meta
    t = _arr(rec, "time_s")
    phase = np.array(rec["phase"])
    t0, t1, t2, t3, t4 = (meta[f"t{i}_s"] for i in range(5))
    assert meta["notes"] == []  # every rule was met, none timed out
    assert rec.header == list(LOG_COLUMNS)
    assert t[-1] == t4 and len(t) == t4  # one row per second, nothing lost
    # preheat: both temperatures within 0.5 K of 45 C at t0
    i0 = np.searchsorted(t, t0)
    assert abs(_arr(rec, "water_out_temp_C")[i0] - 45) <= 0.5
    assert abs(_arr(rec, "water_in_temp_C")[i0] - 45) <= 0.5
    # t1: flue-gas rise below 0.5 K/min over the 5-min window ending at t1, not before
    fg = _arr(rec, "flue_gas_temp_C")
    i1 = np.searchsorted(t, t1)
    rise = np.polyfit(t[i1 - 300 : i1 + 1], fg[i1 - 300 : i1 + 1], 1)[0] * 60
    assert rise < 0.5
    rise_before = np.polyfit(t[i1 - 301 : i1], fg[i1 - 301 : i1], 1)[0] * 60
    assert rise_before >= 0.5 or t1 - t0 <= 300
    # t2 - t1 is the test sequence; t4 = t2 + 8 h
    expected = {"stationary": 6 * 3600, "load_cycle": 8 * 3600}[protocol]
    assert t2 - t1 == expected
    assert t4 - t2 == 8 * 3600
    # t3: the forward temperature has fallen to 55 C, and not earlier
    fwd = _arr(rec, "water_out_temp_C")
    i2, i3 = np.searchsorted(t, t2), np.searchsorted(t, t3)
    assert fwd[i3] <= 55.0 < fwd[i2:i3].min()
    # phases in order and contiguous
    order = ["preheat", "start_up", "test", "cooling_1", "cooling_2"]
    changes = [phase[0]] + [phase[i] for i in range(1, len(phase)) if phase[i] != phase[i - 1]]
    assert changes == order
    # circulation stops at t3
    assert np.all(_arr(rec, "water_flow_setpoint_kg_h")[i3 + 1 :] == 0.0)


def test_load_cycle_cuts_out_at_85_and_restarts_at_55(run_log):
    """Section 3.2.2-3.2.3 and Fig. 7: below the modulation range (13 % step) the boiler
    stops at 85 C, restarts at 55 C, "maintains the maximum power output during the
    start-up phase" and so reaches 85 C and stops a second time.

    Against the paper (12 kW, clean load cycle, measured here): the water is at 69.8 C at
    t2 (paper: 57 C) and the first cooling takes 67 min (paper: about 5 min), because our
    water cools back from the first stop in 1.84 h where the paper's took about 1.5 h, so
    the second stop comes later in the step."""
    rec = run_log("load_cycle", "windhager_12kw")
    seq = np.array(rec["sequence"])
    on = _arr(rec, "boiler_on")[seq == "stationary_13"]
    temp = _arr(rec, "boiler_water_temp_C")[seq == "stationary_13"]
    stops = np.flatnonzero((on[1:] == 0) & (on[:-1] == 1)) + 1
    starts = np.flatnonzero((on[1:] == 1) & (on[:-1] == 0)) + 1
    assert len(stops) >= 1 and len(starts) >= 1
    for i in stops:  # the controller decides on the temperature at the start of the step
        assert temp[i - 1] >= 85.0
    assert temp[starts[0] - 1] <= 55.0
    assert temp.max() < 85.1
    # cool-back from the cut-out to the restart: the paper's 1.5 h as the floor (ours is
    # slower, never faster), 2 h as the ceiling of "about" (measured 1.84 h)
    t = _arr(rec, "time_s")[seq == "stationary_13"]
    restart = starts[starts > stops[0]][0]
    assert 1.5 <= (t[restart] - t[stops[0]]) / 3600 <= 2.0
    # the restart fires at Pstart through the start-up into the second cut-out
    assert len(stops) >= 2 and stops[1] > restart
    assert temp[stops[1] - 1] >= 85.0


def test_second_cooling_loses_about_10_K(run_log):
    """Digest section 6 / Fig. 6: the second cooling loses about 10 K in 8 h (12 kW)."""
    rec = run_log("stationary", "windhager_12kw")
    temp = _arr(rec, "boiler_water_temp_C")
    t = _arr(rec, "time_s")
    meta = rec.meta
    i3, i4 = np.searchsorted(t, meta["t3_s"]), np.searchsorted(t, meta["t4_s"])
    drop = temp[i3] - temp[i4]
    # "about 10 K": read as 10 +- 2.5 K; our t3..t4 is 6.9 h of the 8 h after t2
    assert drop == pytest.approx(10.0, abs=2.5)


def test_stationary_fuel_near_the_paper(run_log, params_12kw):
    """Section 3.2.1: simulated fuel of the 12 kW stationary test 15.0 kg (measured 16.3)."""
    rec = run_log("stationary", "windhager_12kw")
    t = _arr(rec, "time_s")
    mass = _arr(rec, "balance_mass_kg")
    i1, i2 = np.searchsorted(t, rec.meta["t1_s"]), np.searchsorted(t, rec.meta["t2_s"])
    fuel = params_12kw.fuel
    dry = (mass[i1] - mass[i2]) / (1 / (1 - fuel.moisture) - fuel.ash)
    # the model's fuel is dry (Eq. 3 on HHV dry); 5 % covers the paper's rounding and our
    # room temperature (22 C) against the lab's 18-30 C
    assert dry == pytest.approx(15.0, rel=0.05)


def test_first_cooling_after_stationary_takes_about_an_hour(run_log):
    """Digest section 6: after the stationary test the first cooling 70 -> 55 C takes ~1 h."""
    meta = run_log("stationary", "windhager_12kw").meta
    assert (meta["t3_s"] - meta["t2_s"]) / 3600 == pytest.approx(1.0, abs=0.3)


class _ByNameOnly:
    """A rig that offers only the mapping ``read()`` (as the Modbus rig does)."""

    def __init__(self, rig) -> None:
        self.rig = rig
        self.epoch, self.gaps = rig.epoch, rig.gaps

    def apply(self, command) -> None:
        self.rig.apply(command)

    def advance(self, dt_s: float) -> float:
        return self.rig.advance(dt_s)

    def read(self):
        return self.rig.read()


@pytest.mark.parametrize("profile", ["clean", "lab"])
def test_readings_in_order_are_the_readings_by_name(params_12kw, profile):
    """The local rig's ``read_values`` (the runner's path) is ``read()`` in READING_KEYS
    order, with ideal and with noisy instruments, and a run through either gives the same
    rows to the last bit."""
    from hil_client.protocol.rig import READING_KEYS, RigCommand
    from hil_client.protocol.runner import run_protocol
    from hil_client.rigs.local import LocalRig
    from rig_emulator.instruments import load_profile

    rig = LocalRig(params_12kw, load_profile(profile), seed=4)
    rig.apply(RigCommand(600.0, 45.0, True, True, False))
    for _ in range(30):
        rig.advance(1.0)
        by_name = rig.read()
        assert tuple(by_name[k] for k in READING_KEYS) == rig.read_values()
    assert by_name["boiler_on"] == 1.0

    protocol = load_protocol("stationary")
    rows: dict[str, list] = {"values": [], "by_name": []}
    for path, make in (("values", lambda r: r), ("by_name", _ByNameOnly)):
        rig = make(LocalRig(params_12kw, load_profile(profile), seed=4))
        run_protocol(protocol, params_12kw.p_nom_kW, rig, rows[path].append)
    assert len(rows["values"]) > 40_000
    assert rows["values"] == rows["by_name"]  # no NaN in these readings: == is exact


def test_the_schemas_own_example_is_a_protocol(tmp_path):
    """The example in the schema's docstring (which the README points to) loads as written:
    it once used the key 'test' twice and was refused."""
    import hil_client.protocol.definition as definition

    doc = definition.__doc__ or ""
    block = doc[doc.index("    name: load_cycle") : doc.index("A sequence whose")]
    path = tmp_path / "example.yaml"
    path.write_text("\n".join(line[4:] for line in block.splitlines()))
    assert definition.load_protocol(str(path)).name == "load_cycle"


def test_the_documented_example_protocol_is_one(tmp_path):
    """docs/protocols.md's example loads as written, its loads and ramp as it says (the
    form was written for a stranger who had built a file from the error messages)."""
    import re

    text = (Path(__file__).parents[2] / "docs" / "protocols.md").read_text()
    path = tmp_path / "mine.yaml"
    path.write_text(re.search(r"```yaml\n(.*?)```", text, re.S).group(1))
    protocol = load_protocol(str(path))
    assert [(s.name, s.load_start_pct, s.load_end_pct) for s in protocol.sequences] == [
        ("full", 100.0, 100.0),
        ("ramp_100_30", 100.0, 30.0),
        ("part_30", 30.0, 30.0),
    ]
    assert protocol.test_duration_s == 3600.0 + 1800.0 + 7200.0
