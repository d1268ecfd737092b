"""How a ``make bench`` script stops: one Ctrl-C or SIGTERM ends it, and ``make bench``
with it, in one line; a figure is printed only from a run that completed.

A stranger's probe: one Ctrl-C during the load-cycle section did not stop ``make bench``:
``hil-client run`` (called in-process) took the signal, the bench printed a speed figure
from the interrupted run ("exit 1: 5435 steps ... 994 x real time") as a result and went
on with the next section; a Ctrl-C elsewhere stopped it with a KeyboardInterrupt traceback
from the script and from each load generator's process.

- :func:`bench_main` runs a script's ``main``: SIGTERM (make passes it to its child, a CI
  job cancelled) acts as Ctrl-C, so the servers the script started are stopped on the way
  out; an interruption is one line and exit 130, a step that failed (:class:`BenchStopped`)
  one line and exit 1; either way make stops there.
- :func:`require_exit_zero`: a child run's figure needs its exit 0 (``hil-client run``
  interrupted returns 1 and says "interrupted"; the bench stops there).
- :func:`quiet_child` wraps a load generator's process (it gets the terminal's Ctrl-C too):
  exit 130 without a traceback; :func:`result_of` takes its count, or stops the bench if
  it ended without one.
"""

from __future__ import annotations

import argparse
import queue
import signal
import sys
import time
from collections.abc import Callable, Collection
from pathlib import Path
from typing import Any, NoReturn

#: The exit code of a script stopped by Ctrl-C or SIGTERM (the shell's 128 + SIGINT).
INTERRUPTED = 130


class BenchStopped(Exception):
    """A step of the bench did not complete (a child's exit, a load generator gone): no
    figure from it, and the script stops saying why."""


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def bench_main(main: Callable[[], int | None]) -> NoReturn:
    """Run a bench script's ``main`` and exit: its code (0 for None), 130 when Ctrl-C or
    SIGTERM stopped it, 1 when a step did not complete; each stop is one line on stderr
    naming the script."""
    name = Path(sys.argv[0]).stem
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        code = main() or 0
    except KeyboardInterrupt:
        print(
            f"{name}: interrupted (Ctrl-C or SIGTERM); the figures above are of runs that "
            "completed, the one under way gives none",
            file=sys.stderr,
        )
        code = INTERRUPTED
    except BenchStopped as stopped:
        print(f"{name}: stopped: {stopped}; no figure from it", file=sys.stderr)
        code = 1
    sys.exit(code)


def require_exit_zero(what: str, code: int) -> None:
    """:class:`BenchStopped` unless ``what`` (a child run) exited 0: a run that did not
    complete gives no figure."""
    if code != 0:
        raise BenchStopped(f"{what} exited {code}")


def quiet_child(target: Callable[..., None], *args: Any) -> None:
    """The target of a load generator's process: ``target(*args)``, a Ctrl-C ending it with
    exit 130 and no traceback (the script says it once)."""
    try:
        target(*args)
    except KeyboardInterrupt:
        raise SystemExit(INTERRUPTED) from None


def result_of(process: Any, results: Any, timeout_s: float = 120.0) -> Any:
    """What the load generator ``process`` put on ``results``; :class:`BenchStopped` if it
    ended without (it was interrupted, or failed) or gave nothing in ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return results.get(timeout=0.5)
        except queue.Empty:
            pass
        if not process.is_alive():
            try:  # (what it put just before it exited)
                return results.get(timeout=1.0)
            except queue.Empty:
                raise BenchStopped(
                    f"a load generator exited {process.exitcode} without its count"
                ) from None
        if time.monotonic() > deadline:
            process.terminate()
            raise BenchStopped(f"a load generator gave no count in {timeout_s:g} s")


def sections_asked(
    argv: list[str] | None, sections: Collection[str], description: str
) -> list[str]:
    """The sections a bench script's command line names (``python bench/X.py [SECTION ...]``),
    in the script's order; all of them without a name. An unknown name is a usage error."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument(
        "sections", nargs="*", metavar="SECTION", help=f"of {', '.join(sections)} [all]"
    )
    args = parser.parse_args(argv)
    unknown = [name for name in args.sections if name not in sections]
    if unknown:
        parser.error(f"unknown section {unknown[0]!r}: the sections are {', '.join(sections)}")
    return [name for name in sections if not args.sections or name in args.sections]
