"""The ``hil-client`` command. Its libraries take a second or two to load (numpy, scipy,
matplotlib); Ctrl-C meanwhile ends it with one line, as Ctrl-C does later, instead of a
traceback from the middle of an import."""

from __future__ import annotations

import sys
from collections.abc import Sequence


def main(argv: Sequence[str] | None = None) -> int:
    try:
        from hil_client.cli import main as cli_main
    except KeyboardInterrupt:
        print("hil-client: interrupted", file=sys.stderr)
        return 1
    return cli_main(argv)


if __name__ == "__main__":
    sys.exit(main())
