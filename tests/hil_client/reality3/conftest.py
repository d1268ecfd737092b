"""Fixtures of the reality3 tests: the documented boilers as plain dicts."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

BOILER_DIR = Path(__file__).resolve().parents[3] / "rig_emulator" / "boilers"
BOILER_NAMES = ("windhager_12kw", "windhager_6kw")


def load(name: str) -> dict:
    """The boiler documentation file as a plain dict."""
    with open(BOILER_DIR / f"{name}.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


@pytest.fixture(scope="session")
def boilers() -> dict[str, dict]:
    return {name: load(name) for name in BOILER_NAMES}
