"""Shared fixtures: the shipped boilers and whole protocol runs on the in-process rig.

Whole runs are computed once per session (about 1 s each) and shared read-only.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from hil_client.cli import main as hil_client_main
from rig_emulator.boilers import load_boiler

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
