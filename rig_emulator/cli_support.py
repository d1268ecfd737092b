"""What both command-line tools share: one-line errors with exit code 2 for bad input."""

from __future__ import annotations

import argparse
import sys


class UsageError(Exception):
    """Bad usage or input: reported as one line on stderr, exit code 2."""

    def __init__(self, message: str, prog: str | None = None) -> None:
        super().__init__(message)
        self.prog = prog


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors raise :class:`UsageError` instead of exiting."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message, self.prog)


def report(exc: UsageError, default_prog: str) -> int:
    """Print ``PROG: error: MESSAGE`` on stderr and return exit code 2."""
    print(f"{exc.prog or default_prog}: error: {exc}", file=sys.stderr)
    return 2
