"""The ``rig-emulator`` command. Its libraries take a second to load (numpy, numba,
pymodbus); Ctrl-C meanwhile ends it with one line once they are loaded, instead of a
traceback from the middle of an import."""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import TypeVar

T = TypeVar("T")


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
    cli_main = loaded_unless_stopped(_cli)
    if cli_main is None:
        print("rig-emulator: interrupted", file=sys.stderr)
        return 1
    return cli_main(argv)


if __name__ == "__main__":
    sys.exit(main())
