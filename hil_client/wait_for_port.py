"""Wait until a TCP port accepts connections (for docker-compose and scripts).

``python -m hil_client.wait_for_port HOST PORT [--timeout S]``: exit 0 once HOST:PORT
accepts a connection, 1 after the timeout, 2 on bad usage.
"""

from __future__ import annotations

import argparse
import socket
import sys
import time
from collections.abc import Callable, Sequence

from rig_emulator.names import host_name_problem


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on ``host`` right now (the OS picks it)."""
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def wait_for_port(
    host: str, port: int, timeout_s: float, alive: Callable[[], bool] | None = None
) -> bool:
    """True once ``host:port`` accepts a TCP connection, False after ``timeout_s``.

    With ``alive`` (e.g. "the server process still runs"), False as soon as it returns False.
    """
    deadline = time.monotonic() + timeout_s
    while alive is None or alive():
        try:
            socket.create_connection((host, port), timeout=1.0).close()
            return True
        except OSError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.2)
    return False


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="wait_for_port", description=__doc__.splitlines()[0])
    parser.add_argument("host")
    parser.add_argument("port", type=int)
    parser.add_argument("--timeout", type=float, default=60.0)
    args = parser.parse_args(argv)
    if not 0 <= args.timeout < float("inf"):  # (NaN too) bad usage, as the docstring says
        parser.error(f"--timeout: {args.timeout:g} is not a number of seconds >= 0")
    if not 1 <= args.port <= 65535:
        parser.error(f"port: {args.port} is not a TCP port (1-65535)")
    problem = host_name_problem(args.host)
    if problem is not None:
        parser.error(f"host: '{args.host[:80]}' is no host name ({problem})")
    if wait_for_port(args.host, args.port, args.timeout):
        return 0
    print(
        f"wait_for_port: {args.host}:{args.port} not reachable after {args.timeout:g} s",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())
