"""The ``rig-emulator`` command. Its libraries take a second to load (numpy, numba,
pymodbus); Ctrl-C meanwhile ends it with one line once they are loaded, instead of a
traceback from the middle of an import."""

from __future__ import annotations

import _thread
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

T = TypeVar("T")


def standard_streams() -> None:
    """Standard input, output and error opened on /dev/null where the command was started
    without them (``>&- 2>&-``, a daemon): Python sets them to None, and ``hil-client run``
    ended in an AttributeError; worse, the log file opened next would take descriptor 1 or
    2 and anything written there would land in the log (a probe)."""
    for fd, name, mode in ((0, "stdin", "r"), (1, "stdout", "w"), (2, "stderr", "w")):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:  # (the lowest free descriptor is this one, unless it is not)
                os.dup2(null, fd)
                os.close(null)
            if getattr(sys, name) is None:
                setattr(sys, name, open(fd, mode, closefd=False))  # noqa: SIM115


#: an interrupt a C callback swallowed is raised again this much later, in the main thread,
#: through its SIGINT handler [s] (one landing in a callback again is raised again)
RAISED_AGAIN_AFTER_S = 0.01


def interrupts_not_swallowed() -> None:
    """Ctrl-C (or SIGTERM, taken as Ctrl-C) that lands in Python code C called back (numba's
    compiler calls back through ctypes, many times a compilation) cannot leave the callback:
    Python printed "Exception ignored on calling ctypes callback function" with a
    traceback, and the command went on as if it had never come (a CI run with a cold numba
    cache, ``hil-client run`` interrupted 0.9 s in). Such an interrupt is raised again in
    the main thread, where it lands once the callback has returned, and nothing is printed
    of it; any other exception a callback could not raise is printed as before."""
    previous = sys.unraisablehook

    def hook(unraisable: Any) -> None:
        if unraisable.exc_type is not None and issubclass(unraisable.exc_type, KeyboardInterrupt):
            # from another thread, a moment on: raised here, in the hook, it was swallowed too
            timer = threading.Timer(RAISED_AGAIN_AFTER_S, _thread.interrupt_main)
            timer.daemon = True
            timer.start()
            return
        previous(unraisable)

    sys.unraisablehook = hook


def stopping_from_here() -> None:
    """The command has its exit code: a stop signal that comes while the interpreter
    shuts down (a second SIGTERM from ``timeout``, a repeated Ctrl-C) is ignored, not
    taken as the process's end with 128 + N (after "interrupted; the log keeps ..." the
    exit code was 129 or 143, not 1: a re-probe)."""
    if threading.current_thread() is not threading.main_thread():
        return
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        signum = getattr(signal, name, None)
        if signum is not None:
            signal.signal(signum, signal.SIG_IGN)


def loaded_unless_stopped(load: Callable[[], T]) -> T | None:
    """``load()`` (a command's imports) with Ctrl-C and SIGTERM held until it is done;
    None if one came meanwhile. Raised inside an import, Ctrl-C can land in importlib's own
    callbacks, which print it as an ignored exception with a traceback; SIGTERM ended the
    command silently, exit 143 (a re-probe). A signal the process was started ignoring
    stays ignored; off the main thread nothing is held."""
    if threading.current_thread() is not threading.main_thread():
        return load()
    held: list[int] = []
    stopping = [
        n for n in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(n) is not signal.SIG_IGN
    ]
    previous = [signal.signal(n, lambda signum, frame: held.append(signum)) for n in stopping]
    try:
        loaded = load()
    finally:
        for signum, handler in zip(stopping, previous, strict=True):
            signal.signal(signum, signal.SIG_DFL if handler is None else handler)
    return None if held else loaded


def _cli() -> Callable[[Sequence[str] | None], int]:
    from rig_emulator.cli import main as cli_main

    return cli_main


def main(argv: Sequence[str] | None = None) -> int:
    standard_streams()
    interrupts_not_swallowed()
    cli_main = loaded_unless_stopped(_cli)
    if cli_main is None:
        print("rig-emulator: interrupted", file=sys.stderr)
        return 1
    code = cli_main(argv)
    stopping_from_here()
    return code


if __name__ == "__main__":
    sys.exit(main())
