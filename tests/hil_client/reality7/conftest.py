"""Shared fixtures of the reality7 tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality7 import draw_background

BOILERS = Path(__file__).resolve().parents[3] / "rig_emulator" / "boilers"


def load_boiler(name: str) -> dict:
    """A boiler parameter file (CONTRACT section 2), read as data."""
    with open(BOILERS / f"windhager_{name}.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


@pytest.fixture(scope="session", params=["12kw", "6kw"])
def boiler(request: pytest.FixtureRequest) -> dict:
    return load_boiler(request.param)


@pytest.fixture(scope="session")
def boiler12() -> dict:
    return load_boiler("12kw")


@pytest.fixture(scope="session")
def background12(boiler12: dict) -> dict:
    return draw_background(np.random.default_rng(42), boiler12)
