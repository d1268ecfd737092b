"""Instrument models: each error term alone, on signals with known answers."""

import numpy as np
import pytest

from rig_emulator.instruments import (
    InstrumentBank,
    ProfileError,
    load_profile,
    profile_from_mapping,
)
from rig_emulator.signals import MEASURED


def bank_for(spec: dict, seed: int = 3) -> InstrumentBank:
    profile = profile_from_mapping({"name": "t", "instruments": {"flue_gas_temp_C": spec}})
    return InstrumentBank(("flue_gas_temp_C",), profile, seed)


def run(bank: InstrumentBank, values, dt=1.0):
    return np.array([bank.read(np.array([v]), (i + 1) * dt, dt)[0] for i, v in enumerate(values)])


def test_ideal_instrument_reads_the_plant_exactly():
    bank = bank_for({})
    x = np.array([123.456789012345])
    assert bank.ideal and bank.read(x, 1.0, 1.0)[0] == x[0]


def test_fixed_error_lies_in_the_tolerance_band_and_depends_on_seed():
    # Pt100 class B: +-(0.30 + 0.005 |t|) -> +-1.05 K at 150 C
    errors = []
    for seed in range(200):
        bank = bank_for({"accuracy_abs": 0.30, "accuracy_rel": 0.005}, seed)
        errors.append(run(bank, [150.0] * 3)[-1] - 150.0)
    errors = np.array(errors)
    assert np.all(np.abs(errors) <= 1.05 + 1e-12)
    # uniform in the band: 200 draws span most of it
    assert errors.min() < -0.9 and errors.max() > 0.9
    # the error is fixed within a run
    bank = bank_for({"accuracy_abs": 0.30}, 7)
    out = run(bank, [100.0] * 50)
    assert np.ptp(out) == 0.0


def test_noise_has_the_specified_standard_deviation():
    bank = bank_for({"noise_sd": 0.5})
    out = run(bank, [80.0] * 20_000)
    # standard error of an sd estimate from 20 000 samples: 0.5 / sqrt(40 000) = 0.0025
    assert out.std() == pytest.approx(0.5, abs=0.015)
    assert out.mean() == pytest.approx(80.0, abs=0.02)


def test_resolution_rounds_the_reading():
    bank = bank_for({"resolution": 0.02})
    out = run(bank, np.linspace(10.0, 11.0, 101))
    assert np.allclose(out / 0.02, np.round(out / 0.02))
    assert np.max(np.abs(out - np.linspace(10.0, 11.0, 101))) <= 0.01 + 1e-12


def test_lag_is_first_order():
    bank = bank_for({"lag_s": 10.0})
    out = run(bank, [0.0] + [1.0] * 60)
    # after one time constant the step has risen to 1 - 1/e
    assert out[10] == pytest.approx(1 - np.exp(-1), rel=1e-9)


def test_delay_shifts_the_signal():
    bank = bank_for({"delay_s": 20.0})
    out = run(bank, [0.0] * 5 + [1.0] * 40)
    first = int(np.argmax(out > 0.5))
    assert first == 5 + 20  # the step at t=6 s appears at t=26 s


def test_update_period_holds_the_reading():
    bank = bank_for({"update_period_s": 5.0})
    out = run(bank, np.arange(20.0))
    # readings change only at multiples of 5 s (t = 5, 10, 15, 20 -> indices 4, 9, 14, 19)
    changes = np.flatnonzero(np.diff(out)) + 1
    assert list(changes) == [4, 9, 14, 19]


def test_lab_profile_covers_every_measured_signal_and_is_reproducible():
    lab = load_profile("lab")
    assert set(lab.instruments) == set(MEASURED)
    a = InstrumentBank(MEASURED, lab, 11)
    b = InstrumentBank(MEASURED, lab, 11)
    x = np.linspace(1, 100, len(MEASURED))
    assert np.array_equal(a.read(x, 1.0, 1.0), b.read(x, 1.0, 1.0))
    c = InstrumentBank(MEASURED, lab, 12)
    assert not np.array_equal(a.read(x, 2.0, 1.0), c.read(x, 2.0, 1.0))
    assert load_profile("clean").instruments == {}


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"instruments": {}}, "missing required key 'name'"),
        ({"name": "x", "instruments": {"nope": {}}}, "'instruments.nope' is not a measured"),
        (
            {"name": "x", "instruments": {"room_temp_C": {"lag": 1}}},
            "'instruments.room_temp_C.lag'",
        ),
        ({"name": "x", "instruments": {"room_temp_C": {"lag_s": -1}}}, "finite, in 0..3600"),
        # beyond any instrument: a noise of 1e300 K, a reading frozen for 30 years
        (
            {"name": "x", "instruments": {"flue_gas_temp_C": {"noise_sd": 1e300}}},
            "noise_sd' must be finite, in 0..10000",
        ),
        (
            {"name": "x", "instruments": {"room_temp_C": {"delay_s": 1e9}}},
            "delay_s' must be finite, in 0..3600",
        ),
        ({"name": "x", "instruments": {"room_temp_C": {"noise_rel": 2}}}, "in 0..1"),
        # an integer of 400 digits has no float (OverflowError, a traceback: a probe)
        ({"name": "x", "instruments": {"room_temp_C": {"lag_s": 10**400}}}, "0..3600"),
        ({"name": "x", "extra": 1}, "unknown key 'extra'"),
        # the lowest reading: a number of the signal's unit, below zero too
        *(
            (
                {"name": "x", "instruments": {"flue_gas_velocity_m_s": {"reading_min": bad}}},
                f"'instruments.flue_gas_velocity_m_s.reading_min' must be {what}",
            )
            for bad, what in (
                (-1e5, "finite, in -10000..10000"),
                (float("nan"), "finite, in -10000..10000"),
                (float("inf"), "finite, in -10000..10000"),
                (1e5, "finite, in -10000..10000"),
                ("0", "a number"),
                (True, "a number"),
                ([0], "a number"),
            )
        ),
    ],
)
def test_broken_profiles_name_the_key(data, message):
    with pytest.raises(ProfileError, match=message.replace("(", r"\(")):
        profile_from_mapping(data, "p.yaml")


@pytest.mark.parametrize("signal", MEASURED)
def test_a_reading_floor_is_the_profile_authors_choice_on_any_signal(signal):
    """A floor is declared per instrument, not kept for velocities and flows: any measured
    signal takes one (0 included: the vortex meter's), and no floor is the default."""
    profile = profile_from_mapping({"name": "x", "instruments": {signal: {"reading_min": 0}}})
    assert profile.spec(signal).reading_min == 0.0 and not profile.spec(signal).ideal
    profile = profile_from_mapping({"name": "x", "instruments": {signal: {"reading_min": 12.5}}})
    assert profile.spec(signal).reading_min == 12.5
    assert profile_from_mapping({"name": "x"}).spec(signal).reading_min is None
    # a re-probe: a draught gauge's range ends below zero, and null is the default written out
    profile = profile_from_mapping({"name": "x", "instruments": {signal: {"reading_min": -100}}})
    assert profile.spec(signal).reading_min == -100.0
    profile = profile_from_mapping({"name": "x", "instruments": {signal: {"reading_min": None}}})
    assert profile.spec(signal).reading_min is None and profile.spec(signal).ideal


def test_unknown_profile_name():
    with pytest.raises(ProfileError, match="unknown profile 'nope'"):
        load_profile("nope")
