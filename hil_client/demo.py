"""``make demo``: the load cycle of the 12 kW boiler, played offline on the in-process rig.

Writes ``out/demo/load_cycle.csv`` with its meta file and prints the run summary.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path

from hil_client.cli import main as hil_client_main


def main(argv: Sequence[str] | None = None) -> int:
    """Run the demo; ``argv`` may name another output directory (default ``out/demo``)."""
    args = list(argv) if argv is not None else sys.argv[1:]
    out_dir = Path(args[0]) if args else Path("out/demo")
    log = out_dir / "load_cycle.csv"
    code = hil_client_main(
        ["run", "load_cycle", "--boiler", "windhager_12kw", "--rig", "local", "--out", str(log)]
    )
    if code == 0:
        print(f"\ndemo results in {out_dir.resolve()}/")
    return code


if __name__ == "__main__":
    sys.exit(main())
