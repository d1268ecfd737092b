"""The ``rig-emulator`` command. Its libraries take a second to load (numpy, numba,
pymodbus); Ctrl-C meanwhile ends it with one line instead of a traceback from the middle
of an import."""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    try:
        from rig_emulator.cli import main as cli_main
    except KeyboardInterrupt:
        print("rig-emulator: interrupted", file=sys.stderr)
        return 1
    return cli_main(argv)


if __name__ == "__main__":
    sys.exit(main())
