"""Fuzz of both CLIs' inputs (issue 11): numbers and files.

Every outcome must be exit 0 with output, or exit 2 with one line on stderr naming what is
wrong: never a traceback, never exit 1 for bad input. Bounded: 200 seeded cases in-process
(``main(argv)``) plus a few subprocesses that prove no traceback reaches stderr. Only
commands that cannot run long are fuzzed: ``serve`` always against a busy port, ``run``
always with an ``--out`` it refuses before simulating.
"""

from __future__ import annotations

import random
import socket
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from hil_client.cli import main as hil_main
from rig_emulator.cli import main as rig_main

ROOT = Path(__file__).resolve().parents[1]
BOILER_YAML = ROOT / "rig_emulator" / "boilers" / "windhager_12kw.yaml"
MAP_YAML = ROOT / "register_maps" / "wieselburg_bench.yaml"
CASES = 200

NUMBERS = [
    "nan", "NaN", "inf", "-inf", "Infinity", "-0", "0", "1e308", "-1e308", "1e-320", "-1",
    "-300", "99999999999999999999999999", "-99999999999999999999", "abc", "", " ", "0x10",
    "1e", "5,5", "1_000", "\u0661\u0662", "55", "22", "100", "7",
]  # fmt: skip
LOG_HEADER = (
    "time_s,phase,sequence,water_flow_kg_h,water_in_temp_C,water_out_temp_C,"
    "boiler_water_temp_C,flue_gas_temp_C,flue_gas_O2_pct\n"
)


@pytest.fixture(scope="module")
def busy_port() -> Iterator[int]:
    """A port on 127.0.0.1 something already listens on: ``serve`` exits at once."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen()
        yield sock.getsockname()[1]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory) -> list[Path]:
    """Files no command should accept silently (and one directory)."""
    d = tmp_path_factory.mktemp("fuzz")
    rng = random.Random(11)
    boiler = BOILER_YAML.read_text(encoding="utf-8")
    files = {
        "binary.yaml": bytes(rng.randrange(256) for _ in range(512)),
        "latin1.yaml": "name: k\u00e9ssel\n".encode("latin-1"),
        "empty.csv": b"",
        "empty.yaml": b"",
        "truncated.yaml": boiler[: len(boiler) // 3].encode(),
        "list.yaml": b"- 1\n- 2\n",
        "scalar.yaml": b"42\n",
        "unclosed.yaml": b"name: [1, 2\n",
        "header_only.csv": LOG_HEADER.encode(),
        "truncated.csv": (LOG_HEADER + "1.0,preheat,,600,55,6").encode(),
        "missing_columns.csv": b"time_s,phase\n1,preheat\n2,preheat\n",
        "inf.csv": (LOG_HEADER + "1.0,preheat,,inf,55,-inf,60,100,10\n").encode(),
        "binary.csv": bytes(rng.randrange(256) for _ in range(512)),
        "nul.csv": b"time_s\x00,phase\n\x00\x00\n",
    }
    paths = []
    for name, data in files.items():
        path = d / name
        path.write_bytes(data)
        paths.append(path)
    (d / "a_directory").mkdir()
    paths.append(d / "a_directory")
    return paths


def _cases(
    rng: random.Random, files: list[Path], port: int, out: Path
) -> Iterator[tuple[str, Callable[[list[str]], int], list[str]]]:
    """(cli name, main, argv) for one fuzz case each."""
    n = lambda: rng.choice(NUMBERS)  # noqa: E731
    f = lambda: str(rng.choice(files))  # noqa: E731
    serve = ["serve", "--port", str(port)]
    makers = [
        lambda: ["steady", "--boiler", "windhager_12kw", rng.choice(
            ["--load", "--return-temp", "--room-temp"]), n()],
        lambda: ["steady", "--boiler", "windhager_12kw", "--load", n(), "--return-temp", n(),
                 "--room-temp", n()],
        lambda: ["steady", "--boiler", f()],
        lambda: ["check", "--boiler", f()],
        lambda: ["map-doc", "--map", f(), "--out", str(out / "doc.md")],
        lambda: [*serve, "--boiler", "windhager_12kw", rng.choice(
            ["--speed", "--seed", "--tick-hz", "--port"]), n()],
        lambda: [*serve, "--boiler", f()],
        lambda: [*serve, "--boiler", "windhager_12kw", "--profile", f()],
        lambda: [*serve, "--boiler", "windhager_12kw", "--map", f()],
    ]  # fmt: skip
    hil_makers = [
        lambda: ["balance", f(), "--out", str(out / "b" / "x.json")],
        lambda: ["balance", f(), "--boiler", f()],
        lambda: ["validate", f(), "--boiler", "windhager_12kw", "--out", str(out / "v")],
        lambda: ["calibrate", f(), "--boiler", "windhager_12kw", "--out", str(out / "c.yaml")],
        lambda: ["diagnose", "--calibration", f(), "--validation", f(), "--boiler",
                 "windhager_12kw", "--out", str(out / "d")],
        lambda: ["run", rng.choice(["stationary", f()]), "--boiler", "windhager_12kw",
                 rng.choice(["--seed", "--reconnect-timeout"]), n(), "--out",
                 str(out / "never.txt")],  # .txt: refused before any simulation
        lambda: ["run", "stationary", "--boiler", f(), "--profile", f(), "--out",
                 str(out / "never.txt")],
    ]  # fmt: skip
    while True:
        if rng.random() < 0.55:
            yield "rig-emulator", rig_main, rng.choice(makers)()
        else:
            yield "hil-client", hil_main, rng.choice(hil_makers)()


def test_cli_inputs_fuzz(bad_files, busy_port, tmp_path, capsys):
    rng = random.Random(20261122)
    cases = _cases(rng, bad_files, busy_port, tmp_path)
    seen = {0: 0, 2: 0}
    for _ in range(CASES):
        name, main, argv = next(cases)
        try:
            code = main(argv)
        except SystemExit as exc:  # --help and the like only
            code = exc.code
        out, err = capsys.readouterr()
        where = f"{name} {argv}: exit {code}, stderr {err!r}"
        assert code in (0, 2), where
        seen[code] += 1
        if code == 2:
            lines = err.strip().splitlines()
            assert len(lines) == 1 and "error:" in lines[0], where
        else:
            assert out.strip(), where
            for word in ("nan", "inf"):  # a figure printed as nan/inf is nonsense
                assert word not in out.lower().replace("info", ""), where
    assert seen[2] > 0 and seen[0] > 0  # both outcomes are exercised


@pytest.mark.parametrize(
    "argv",
    [
        ["rig_emulator.cli", "steady", "--boiler", "windhager_12kw", "--return-temp", "nan"],
        ["rig_emulator.cli", "check", "--boiler", "BINARY"],
        ["rig_emulator.cli", "serve", "--boiler", "windhager_12kw", "--port", "BUSY"],
        ["hil_client.cli", "balance", "BINARY"],
    ],
)
def test_no_traceback_reaches_stderr(argv, bad_files, busy_port):
    binary = next(p for p in bad_files if p.name == "binary.csv")
    argv = [str(binary) if a == "BINARY" else str(busy_port) if a == "BUSY" else a for a in argv]
    proc = subprocess.run(
        [sys.executable, "-m", *argv], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
