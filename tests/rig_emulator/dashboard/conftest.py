"""Servers with the dashboard for the tests of this folder, each its own process."""

from __future__ import annotations

import pytest

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port


@pytest.fixture
def served():
    """``served(*options)`` -> (modbus port, http port) of ``serve --http`` (real time
    unless ``--lockstep`` is among the options); all stopped after the test."""
    stack = []

    def start(*options: str) -> tuple[int, int]:
        http = free_port()
        ctx = rig_emulator_serve("windhager_12kw", "--http", str(http), *options)
        port, _ = ctx.__enter__()
        stack.append(ctx)
        assert wait_for_port("127.0.0.1", http, 30.0)
        return port, http

    yield start
    for ctx in stack:
        ctx.__exit__(None, None, None)


@pytest.fixture
def dashboard(served):
    """``dashboard(*options)`` -> (modbus port, http port) of a lockstep server."""
    return lambda *options: served("--lockstep", *options)
