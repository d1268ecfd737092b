"""Shared fixtures: the shipped boilers, whole protocol runs on the in-process rig, and real
emulator servers on free ports of 127.0.0.1.

Whole runs are computed once per session (about 1 s each) and shared read-only.
"""

from __future__ import annotations

import asyncio
import csv
import json
import logging
import signal
import threading
from collections.abc import Iterator
from concurrent.futures import Future
from pathlib import Path

import pytest

from hil_client.cli import main as hil_client_main
from rig_emulator.boilers import load_boiler
from rig_emulator.emulator import Emulator
from rig_emulator.instruments import load_profile
from rig_emulator.modbus import BenchServer
from rig_emulator.registers import load_map

logging.getLogger("pymodbus").setLevel(logging.CRITICAL)


@pytest.fixture(autouse=True)
def _ctrl_c_as_a_terminal_gives_it() -> None:
    """Each test starts with Ctrl-C as a terminal gives it to a command: SIGINT handled
    (Python's default handler). An ignored SIGINT is inherited by every process a test
    starts, which then cannot be interrupted: a test of Ctrl-C failed in a CI run whose
    worker an earlier test had left ignoring it (code that ends a command ignores SIGINT
    from there on: serve's stop, the launchers' exit); the same test passes alone."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


BOILERS = ("windhager_12kw", "windhager_6kw")


@pytest.fixture(scope="session", params=BOILERS)
def params(request):
    return load_boiler(request.param)


@pytest.fixture(scope="session")
def params_12kw():
    return load_boiler("windhager_12kw")


def read_log(path: Path) -> tuple[list[str], dict[str, list]]:
    """Header and columns of a lab log (numbers as float, text as str, empty as None)."""
    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader)
        columns: dict[str, list] = {name: [] for name in header}
        for row in reader:
            for name, value in zip(header, row, strict=True):
                if value == "":
                    columns[name].append(None)
                elif name in ("phase", "sequence"):
                    columns[name].append(value)
                else:
                    columns[name].append(float(value))
    return header, columns


class RunRecord:
    """A finished ``hil-client run``: its log columns and meta."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.header, self.columns = read_log(path)
        self.meta = json.loads(path.with_name(path.stem + ".meta.json").read_text())

    def __getitem__(self, name: str) -> list:
        return self.columns[name]


@pytest.fixture(scope="session")
def run_log(tmp_path_factory):
    """``run_log(protocol, boiler)``: a clean local run through the CLI, cached per session."""
    cache: dict[tuple[str, str], RunRecord] = {}

    def get(protocol: str, boiler: str) -> RunRecord:
        key = (protocol, boiler)
        if key not in cache:
            out = tmp_path_factory.mktemp("runs") / f"{protocol}_{boiler}.csv"
            code = hil_client_main(
                [
                    "run",
                    protocol,
                    "--boiler",
                    boiler,
                    "--rig",
                    "local",
                    "--out",
                    str(out),
                    "--quiet",
                ]
            )
            assert code == 0
            cache[key] = RunRecord(out)
        return cache[key]

    return get


class RunningServer:
    """A :class:`BenchServer` serving from its own event-loop thread."""

    def __init__(self, **kwargs) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        profile = load_profile(kwargs.pop("profile", "clean"))
        emulator = kwargs.pop("emulator", None) or Emulator(
            load_boiler(kwargs.pop("boiler", "windhager_12kw")), profile, kwargs.pop("seed", 0)
        )
        self.map = kwargs.pop("register_map", None) or load_map()
        self.server = BenchServer(emulator, self.map, port=0, **kwargs)
        self.call(self.server.start())
        self.port = self.server.port

    def call(self, coro):
        """Run a coroutine in the server's loop and return its result."""
        future: Future = asyncio.run_coroutine_threadsafe(coro, self.loop)
        return future.result(timeout=30)

    def values(self) -> dict[str, float]:
        async def get():
            return self.server.values()

        return self.call(get())

    def stop(self) -> None:
        self.call(self.server.stop())
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(timeout=10)
        self.loop.close()


@pytest.fixture
def serve() -> Iterator:
    """``serve(**kwargs)`` starts a server (lockstep by default); all are stopped after."""
    servers: list[RunningServer] = []

    def start(**kwargs) -> RunningServer:
        kwargs.setdefault("lockstep", True)
        server = RunningServer(**kwargs)
        servers.append(server)
        return server

    yield start
    for server in servers:
        server.stop()


@pytest.fixture
def serve_process() -> Iterator:
    """``serve_process(*serve_args)`` starts ``rig-emulator serve`` as its own process on a
    free port (:class:`tests.hil_client.test_restarts.ServerProcess`); all killed after."""
    from hil_client.wait_for_port import free_port
    from tests.hil_client.test_restarts import ServerProcess

    started: list[ServerProcess] = []

    def start(*args: str) -> ServerProcess:
        process = ServerProcess(free_port(), *args)
        started.append(process)
        return process

    yield start
    for process in started:
        process.kill()
