"""Servers with the dashboard for the tests of this folder, each its own process."""

from __future__ import annotations

from contextlib import ExitStack

import pytest

from hil_client.demo import rig_emulator_serve
from hil_client.wait_for_port import free_port, wait_for_port


def _start(stack: ExitStack, options: tuple[str, ...]) -> tuple[int, int]:
    """(modbus port, http port) of ``serve --http`` with ``options``, stopped with ``stack``."""
    http = free_port()
    port, _ = stack.enter_context(
        rig_emulator_serve("windhager_12kw", "--http", str(http), *options)
    )
    assert wait_for_port("127.0.0.1", http, 30.0)
    return port, http


@pytest.fixture
def served():
    """``served(*options)`` -> (modbus port, http port) of ``serve --http`` (real time
    unless ``--lockstep`` is among the options); all stopped after the test."""
    with ExitStack() as stack:
        yield lambda *options: _start(stack, options)


@pytest.fixture(scope="module")
def served_once():
    """As :func:`served`, but one server per module and options, for probes that change
    nothing on it (refused or read-only requests; a server process costs about 1.5 s of
    CPU); all stopped after the module."""
    started: dict[tuple[str, ...], tuple[int, int]] = {}
    with ExitStack() as stack:

        def start(*options: str) -> tuple[int, int]:
            if options not in started:
                started[options] = _start(stack, options)
            return started[options]

        yield start


@pytest.fixture
def dashboard(served):
    """``dashboard(*options)`` -> (modbus port, http port) of a lockstep server."""
    return lambda *options: served("--lockstep", *options)
