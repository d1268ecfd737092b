"""The ``hil-client`` command. Its libraries take a second or two to load (numpy, scipy,
matplotlib); Ctrl-C meanwhile ends it with one line once they are loaded, as Ctrl-C does
later, instead of a traceback from the middle of an import."""

from __future__ import annotations

import signal
import sys
import threading
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    # Ctrl-C and SIGTERM are held until the imports are done: raised inside one, it can land in
    # importlib's own callbacks, which print it as an ignored exception with a traceback
    held: list[int] = []
    main_thread = threading.current_thread() is threading.main_thread()
    stopping: tuple[int, ...] = ()  # (SIGTERM ended it silently, exit 143: a re-probe)
    if main_thread:  # a signal the process was started ignoring stays ignored
        ignored = signal.SIG_IGN
        stopping = tuple(
            n for n in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(n) is not ignored
        )
        previous = [signal.signal(n, lambda signum, frame: held.append(signum)) for n in stopping]
    try:
        from hil_client.cli import main as cli_main
    finally:
        if main_thread:
            for signum, handler in zip(stopping, previous, strict=True):
                signal.signal(signum, signal.SIG_DFL if handler is None else handler)
    if held:
        print("hil-client: interrupted", file=sys.stderr)
        return 1
    return cli_main(argv)


if __name__ == "__main__":
    sys.exit(main())
