"""The lowest value an instrument can show (``reading_min``): the vortex meter reads no
negative flue-gas velocity, on the real CLI and through a real server."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.cli import main as hil_client_main
from rig_emulator.emulator import ANALYSER_SIGNALS
from rig_emulator.instruments import InstrumentBank, load_profile, profile_from_mapping
from rig_emulator.instruments.profile import PROFILE_DIR
from rig_emulator.pytest_plugin import RigEmulator
from rig_emulator.signals import MEASURED
from tests.conftest import read_log

VELOCITY = "flue_gas_velocity_m_s"
#: The gas analysers' signals (the analyser and the FID): a small negative reading of theirs
#: is a real analyser's zero drift, so no shipped profile gives them a floor.
ANALYSERS = (*ANALYSER_SIGNALS, "flue_gas_OGC_ppm")
#: A seed whose vortex meter draws a fixed error of -0.15 m/s, the whole of the paper's
#: accuracy band: the stand-by draught (0.18-0.19 m/s) then reads about 0.03 +- 0.05 m/s
SEED_LOW_VORTEX = 145


def _run(tmp_path: Path, profile: str, name: str) -> dict[str, list]:
    """The columns of ``hil-client run stationary`` (12 kW, seed 1) on the local rig."""
    out = tmp_path / f"{name}.csv"
    argv = ["run", "stationary", "--boiler", "windhager_12kw", "--rig", "local"]
    argv += ["--profile", profile, "--seed", "1", "--out", str(out), "--quiet"]
    assert hil_client_main(argv) == 0
    return read_log(out)[1]


def test_the_vortex_meter_reads_no_negative_velocity_in_a_lab_run(tmp_path):
    """A stranger's probe: `hil-client run stationary --profile lab --seed 1` logged 266
    negative flue-gas velocities in the first cooling (down to -0.18 m/s), 59 in the second
    and 13 in the preheat; a vortex meter counts a shedding frequency and reads no velocity
    below 0. The floor changes nothing else: the same run without it differs only where it
    read below 0, which now reads 0."""
    floored = _run(tmp_path, "lab", "floored")
    velocity = [v for v in floored[VELOCITY] if v is not None]
    assert min(velocity) >= 0.0
    data = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    del data["instruments"][VELOCITY]["reading_min"]
    unfloored_profile = tmp_path / "lab_without_floor.yaml"
    unfloored_profile.write_text(yaml.safe_dump(data))
    unfloored = _run(tmp_path, str(unfloored_profile), "unfloored")
    assert floored.keys() == unfloored.keys()
    for name in floored:
        if name != VELOCITY:
            assert floored[name] == unfloored[name], name
    raw = np.array(unfloored[VELOCITY], dtype=float)
    # rows below 0 without the floor, each now read as 0: the probe counted 338; 77 since
    # the bed's burn-out keeps the fan's air (its velocity no longer falls to 0)
    assert (raw < 0.0).sum() > 20
    assert np.array_equal(np.array(floored[VELOCITY], dtype=float), np.maximum(raw, 0.0))


def _velocity_and_truth(rig: RigEmulator, seconds: int) -> tuple[np.ndarray, np.ndarray]:
    """The vortex meter's register and the plant's true velocity, each second."""
    readings, truths = [], []
    for _ in range(seconds):
        rig.advance(1)
        readings.append(rig.read(VELOCITY))
        truths.append(rig.truth(VELOCITY))
    return np.array(readings), np.array(truths)


def test_a_server_serves_the_floor_and_the_clean_profile_the_plant_values():
    """The stranger's negative velocities through a real ``serve --lockstep`` of the idle
    boiler's draught: with the lab profile at a seed whose meter reads 0.15 m/s low (the
    paper's accuracy) the register never goes below 0 though the plant's draught is near
    it; the clean profile's register is the plant's value, the floor being no part of it."""
    with RigEmulator(profile="clean") as rig:
        reading, truth = _velocity_and_truth(rig, 120)
    # the register is an int16 of 0.001 m/s: equal to half a step
    assert np.all(np.abs(reading - truth) <= 0.0005 + 1e-12)
    assert truth.min() > 0.0  # a draught through the idle boiler, never reversed
    with RigEmulator(profile="lab", seed=SEED_LOW_VORTEX) as rig:
        reading, truth = _velocity_and_truth(rig, 300)
    assert reading.min() >= 0.0
    # the floor is what held it: the draught lies within the meter's error of 0, so about a
    # quarter of its readings (0.03 / 0.05 sd below the mean) sit on the floor
    assert truth.max() < 0.2 and (reading == 0.0).sum() > 30


def test_the_floor_is_applied_after_error_noise_and_rounding():
    """A reading below the floor shows the floor; one above is what the instrument reads
    without it (the same seed draws the same errors), so only the tail below is cut."""
    spec = {"accuracy_abs": 0.15, "noise_sd": 0.05, "resolution": 0.01}
    banks = [
        InstrumentBank(
            (VELOCITY,),
            profile_from_mapping({"name": "t", "instruments": {VELOCITY: extra | spec}}),
            SEED_LOW_VORTEX,
        )
        for extra in ({"reading_min": 0.0}, {})
    ]
    values = np.full(2000, 0.05)
    floored, raw = (
        np.array([b.read(np.array([v]), i + 1.0, 1.0)[0] for i, v in enumerate(values)])
        for b in banks
    )
    assert (raw < 0.0).any() and floored.min() == 0.0
    assert np.array_equal(floored, np.maximum(raw, 0.0))


def test_a_floor_alone_is_no_ideal_instrument_and_nan_stays_nan():
    """An instrument whose only property is a floor changes a plant value below it, so it is
    not ideal (the ideal path returns the plant values as they are); a missing value stays
    missing."""
    profile = profile_from_mapping({"name": "t", "instruments": {VELOCITY: {"reading_min": 0}}})
    bank = InstrumentBank((VELOCITY,), profile, 1)
    assert not bank.ideal
    assert bank.read(np.array([-0.3]), 1.0, 1.0)[0] == 0.0
    assert bank.read(np.array([0.123456789]), 2.0, 1.0)[0] == 0.123456789
    assert math.isnan(bank.read(np.array([math.nan]), 3.0, 1.0)[0])
    assert InstrumentBank(MEASURED, load_profile("clean"), 1).ideal


@pytest.mark.parametrize("path", sorted(PROFILE_DIR.glob("*.yaml")), ids=lambda p: p.stem)
def test_every_shipped_vortex_meter_has_its_floor_and_no_analyser_one(path):
    """Every shipped profile with a vortex meter declares that it shows no velocity below 0;
    no analyser gets a floor (its small negative reading is real zero drift); the clean
    profile stays ideal."""
    profile = load_profile(str(path))
    if VELOCITY in profile.instruments:
        assert profile.spec(VELOCITY).reading_min == 0.0
    assert all(profile.spec(name).reading_min is None for name in ANALYSERS)
    if profile.name == "clean":
        assert all(profile.spec(name).ideal for name in MEASURED)
