"""Shared fixtures: the two boilers and cached plant runs (each run ~0.1 s after compile)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality8 import draw_background
from hil_client.reality8.kernel import SIGNAL_NAMES
from hil_client.reality8.simulate import run_plant

BOILERS = Path(__file__).resolve().parents[3] / "rig_emulator" / "boilers"


@cache
def boiler(name: str) -> dict:
    return yaml.safe_load((BOILERS / f"windhager_{name}.yaml").read_text())


@cache
def background(name: str, case: int) -> dict:
    return draw_background(np.random.default_rng(case), boiler(name))


@cache
def plant(name: str, test: str, effect=None, form=None, strength=0.0, case=0):
    """(signals dict name -> 1 s array, events t0..t4, params) of one run."""
    sig, ev, p = run_plant(
        boiler(name), test, background=background(name, case), effect=effect, form=form,
        strength=strength, seed=case,
    )  # fmt: skip
    return {n: sig[:, i] for i, n in enumerate(SIGNAL_NAMES)}, ev, p


@pytest.fixture(scope="session")
def b12() -> dict:
    return boiler("12kw")


@pytest.fixture(scope="session")
def bg12() -> dict:
    return background("12kw", 0)
