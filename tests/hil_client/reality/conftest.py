"""Shared runs of the independent plant (module-cached: each log takes about half a second)."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import yaml

from hil_client.reality import draw_background, simulate_log
from rig_emulator.boilers import BOILER_DIR


def boiler(name: str = "windhager_12kw") -> dict:
    return yaml.safe_load((BOILER_DIR / f"{name}.yaml").read_text())


def background(name: str = "windhager_12kw", seed: int = 11, **override) -> dict:
    bg = draw_background(np.random.default_rng(seed), boiler(name))
    return bg | override


@functools.lru_cache(maxsize=64)
def run(
    test: str = "stationary",
    effect: str | None = None,
    form: str | None = None,
    strength: float = 0.5,
    name: str = "windhager_12kw",
    sample_s: float = 5.0,
    jitter: bool = False,
    seed: int = 7,
    bg_items: tuple = (),
):
    bg = background(name) | dict(bg_items)
    return simulate_log(
        boiler(name),
        test,
        background=bg,
        effect=effect,
        form=form,
        strength=strength,
        seed=seed,
        sample_s=sample_s,
        jitter=jitter,
    )


@pytest.fixture
def plant_run():
    return run
