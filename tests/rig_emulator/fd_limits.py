"""``rig-emulator serve`` as its own process under a low open-file limit (RLIMIT_NOFILE),
and the idle connections and fresh clients the descriptor tests make against it."""

from __future__ import annotations

import contextlib
import functools
import os
import signal
import socket
import struct
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

from hil_client.wait_for_port import free_port, wait_for_port
from rig_emulator.registers import load_map
from tests.modbus_helpers import ADVANCE, client, write
from tests.rig_emulator.transports.served import REPO

#: the open-file limit the servers run under: a server has about 12 descriptors open once
#: it listens, so a few dozen connections exhaust it
NOFILE = 64
#: how long a fresh client may wait for its reply [s]: measured under 0.1 s with the
#: descriptors exhausted; the rest is the margin of a loaded machine
REPLY_BOUND_S = 10.0

#: ``python -c`` of a server whose descriptors something else takes once it serves, as
#: files would: a line on stdin takes every descriptor but ``sys.argv[1]``, and answers
#: "taken N" on stdout; the arguments after it are ``rig-emulator``'s
SERVE_THEN_TAKE_DESCRIPTORS = """
import os, sys, threading
from rig_emulator.cli import main

def take(free):
    sys.stdin.readline()
    held = []
    try:
        while True:
            held.append(os.open(os.devnull, os.O_RDONLY))
    except OSError:
        pass
    for fd in held[:free]:
        os.close(fd)
    print("taken", len(held) - free, flush=True)

threading.Thread(target=take, args=(int(sys.argv[1]),), daemon=True).start()
sys.exit(main(sys.argv[2:]))
"""


@dataclass
class Limited:
    """A running server under an open-file limit: its process, Modbus port and log file."""

    process: subprocess.Popen
    port: int
    log: Path

    def lines(self) -> list[str]:
        return self.log.read_text(errors="replace").splitlines()


def limit_descriptors(nofile: int) -> None:
    import resource

    resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, nofile))


@contextlib.contextmanager
def serving_limited(
    log: Path,
    *options: str,
    take_all_but: int | None = None,
    http: int | None = None,
    nofile: int = NOFILE,
) -> Iterator[Limited]:
    """``rig-emulator serve --lockstep --port FREE OPTIONS`` under an open-file limit of
    ``nofile`` (soft and hard), its stderr to ``log`` (a file: a flood of lines would
    fill a pipe and stop the server); with ``take_all_but``, in a process that takes every
    descriptor but that many when asked (:data:`SERVE_THEN_TAKE_DESCRIPTORS`); with
    ``http``, the dashboard's port is waited for too. SIGTERM at the end."""
    port = free_port()
    serve = ["serve", "--boiler", "windhager_12kw", "--lockstep", "--port", str(port), *options]
    if take_all_but is None:
        command = [sys.executable, "-m", "rig_emulator.cli", *serve]
    else:
        command = [sys.executable, "-c", SERVE_THEN_TAKE_DESCRIPTORS, str(take_all_but), *serve]
    with log.open("w") as err:
        process = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            preexec_fn=functools.partial(limit_descriptors, nofile),
            env={**os.environ, "PYTHONPATH": str(REPO)},
        )
    try:
        alive = lambda: process.poll() is None  # noqa: E731
        assert wait_for_port("127.0.0.1", port, 60.0, alive=alive), log.read_text()
        if http is not None:
            assert wait_for_port("127.0.0.1", http, 30.0, alive=alive), log.read_text()
        yield Limited(process, port, log)
    finally:
        process.send_signal(signal.SIGTERM)
        try:
            process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate(timeout=10)


def kernels_loaded(port: int) -> None:
    """Advance the lockstep server on ``port`` by 1 s: answered once its kernels are loaded
    (the load holds the event loop's thread back, and the accepts with it, for a few
    seconds; and it opens files: load them before the descriptors are taken)."""
    c = client(port)
    try:
        assert not write(c, SimpleNamespace(map=load_map()), *ADVANCE, 1).isError()
    finally:
        c.close()


def take_descriptors(served: Limited) -> int:
    """Have the server's process take every descriptor but the few it was started with;
    how many it took."""
    assert served.process.stdin is not None and served.process.stdout is not None
    served.process.stdin.write("take\n")
    served.process.stdin.flush()
    answer = served.process.stdout.readline().split()
    assert answer[:1] == ["taken"], answer
    return int(answer[1])


def idle_connections(port: int, count: int) -> list[socket.socket]:
    """Up to ``count`` connections to ``port`` that never send a byte; stops at the first
    that cannot connect within 3 s (a server no longer accepting: its backlog full, the
    SYN dropped and sent again 1 s, then 2 s later)."""
    opened = []
    for _ in range(count):
        try:
            opened.append(socket.create_connection(("127.0.0.1", port), timeout=3.0))
        except OSError:
            break
    return opened


def modbus_read(port: int, timeout_s: float = REPLY_BOUND_S) -> bytes:
    """The reply ADU of a fresh client's read of unit 100's first four input registers (the
    simulated time), b"" if none came within ``timeout_s``."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as sock:
            sock.sendall(struct.pack(">HHHBBHH", 7, 0, 6, 100, 4, 0, 4))
            return sock.recv(64)
    except OSError:
        return b""


def http_get(port: int, path: str, timeout_s: float = REPLY_BOUND_S) -> bytes:
    """A fresh client's whole HTTP/1.0 response to GET ``path``, b"" if none came within
    ``timeout_s``."""
    answer = b""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as sock:
            sock.sendall(f"GET {path} HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n".encode())
            while chunk := sock.recv(65536):
                answer += chunk
    except OSError:
        pass
    return answer


def close_all(sockets: list[socket.socket]) -> None:
    for sock in sockets:
        sock.close()
