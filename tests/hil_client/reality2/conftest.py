"""Shared runs of the second independent plant (each about 0.5 s once compiled)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import yaml

from hil_client.reality2 import draw_background, simulate_log
from rig_emulator.boilers import BOILER_DIR


@functools.cache
def boiler(name: str) -> dict:
    return yaml.safe_load((BOILER_DIR / f"{name}.yaml").read_text())


@functools.cache
def background(name: str, seed: int) -> dict:
    return draw_background(np.random.default_rng(seed), boiler(name))


@functools.cache
def run(
    name: str = "windhager_12kw",
    test: str = "stationary",
    effect: str | None = None,
    form: str | None = None,
    strength: float = 0.0,
    seed: int = 3,
    sample_s: float = 1.0,
    jitter: bool = False,
):
    """(columns, meta) of one log; the background depends on the boiler and seed only."""
    return simulate_log(
        boiler(name),
        test,
        background=background(name, seed),
        effect=effect,
        form=form,
        strength=strength,
        seed=seed,
        sample_s=sample_s,
        jitter=jitter,
    )


@pytest.fixture(scope="session")
def plant_run():
    return run
