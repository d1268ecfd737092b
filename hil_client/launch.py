"""The ``hil-client`` command. Its libraries take a second or two to load (numpy, scipy,
numba; matplotlib only when a figure is drawn); Ctrl-C meanwhile ends it with one line once
they are loaded, as Ctrl-C does later, instead of a traceback from the middle of an import
(:func:`rig_emulator.launch.loaded_unless_stopped`)."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence

from rig_emulator.launch import (
    interrupts_not_swallowed,
    loaded_unless_stopped,
    standard_streams,
    stopping_from_here,
)


def _cli() -> Callable[[Sequence[str] | None], int]:
    from hil_client.cli import main as cli_main

    return cli_main


def main(argv: Sequence[str] | None = None) -> int:
    standard_streams()
    interrupts_not_swallowed()
    cli_main = loaded_unless_stopped(_cli)
    if cli_main is None:
        print("hil-client: interrupted", file=sys.stderr)
        return 1
    code = cli_main(argv)
    stopping_from_here()
    return code


if __name__ == "__main__":
    sys.exit(main())
