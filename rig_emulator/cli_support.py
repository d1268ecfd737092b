"""What both command-line tools share: one-line errors with exit code 2 for bad input."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from contextlib import contextmanager

from rig_emulator.boilers import load_boiler
from rig_emulator.model.params import BoilerParams, ParameterError


class UsageError(Exception):
    """Bad usage or input: reported as one line on stderr, exit code 2."""

    def __init__(self, message: str, prog: str | None = None) -> None:
        super().__init__(message)
        self.prog = prog


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors raise :class:`UsageError` instead of exiting."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message, self.prog)


@contextmanager
def bad_input(*errors: type[Exception], prefix: str = "") -> Iterator[None]:
    """Turn ``errors`` raised in the block into a :class:`UsageError` ``PREFIX + message``."""
    try:
        yield
    except errors as exc:
        raise UsageError(f"{prefix}{exc}") from None


def boiler_arg(name: str) -> BoilerParams:
    """The boiler of a ``--boiler NAME|PATH`` option; a bad one is a :class:`UsageError`."""
    with bad_input(ParameterError):
        return load_boiler(name)


def report(exc: UsageError, default_prog: str) -> int:
    """Print ``PROG: error: MESSAGE`` on stderr and return exit code 2."""
    print(f"{exc.prog or default_prog}: error: {exc}", file=sys.stderr)
    return 2
