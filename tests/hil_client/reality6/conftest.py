"""Shared fixtures of the reality-6 tests: the two boilers' YAML and a cached log runner."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality6 import draw_background, simulate_log

BOILER_DIR = Path(__file__).resolve().parents[3] / "rig_emulator" / "boilers"
BOILER_NAMES = ("windhager_6kw", "windhager_12kw")
TESTS = ("stationary", "load_cycle")


@functools.cache
def boiler(name: str) -> dict:
    with open(BOILER_DIR / f"{name}.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


@functools.cache
def background(name: str, draw: int) -> dict:
    return draw_background(np.random.default_rng(1000 + draw), boiler(name))


def log(name, test, draw=0, effect=None, form=None, strength=0.0, seed=7, **kw):
    return simulate_log(
        boiler(name),
        test,
        background=background(name, draw),
        effect=effect,
        form=form,
        strength=strength,
        seed=seed,
        **kw,
    )


@pytest.fixture(params=BOILER_NAMES)
def boiler_name(request):
    return request.param


@pytest.fixture(params=TESTS)
def test_name(request):
    return request.param
