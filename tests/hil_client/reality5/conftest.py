"""Shared fixtures for plant 5: the two boiler files (read as data) and cached runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.reality5 import draw_background, simulate_log

BOILER_DIR = Path(__file__).resolve().parents[3] / "rig_emulator" / "boilers"
BOILERS = ("windhager_12kw", "windhager_6kw")
TESTS = ("stationary", "load_cycle")


@pytest.fixture(scope="session")
def boilers() -> dict[str, dict]:
    return {n: yaml.safe_load((BOILER_DIR / f"{n}.yaml").read_text()) for n in BOILERS}


@pytest.fixture(scope="session")
def backgrounds(boilers) -> dict[str, dict]:
    return {n: draw_background(np.random.default_rng(11), b) for n, b in boilers.items()}


def sim(boiler, test, bg, effect=None, form=None, s=0.0, seed=3, **kw):
    """simulate_log with short keywords."""
    return simulate_log(boiler, test, background=bg, effect=effect, form=form, strength=s,
                        seed=seed, **kw)  # fmt: skip


@pytest.fixture(scope="session")
def baselines(boilers, backgrounds) -> dict[tuple[str, str], tuple[dict, dict]]:
    """No-effect runs (5 s sampling) for every boiler and test, seed 3."""
    return {
        (n, t): sim(boilers[n], t, backgrounds[n], sample_s=5.0) for n in BOILERS for t in TESTS
    }
