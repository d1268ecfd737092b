"""The query of a ``modbus-rtu://`` URL: each parameter once, with a value, or one line and
exit 2 (``hil-client run`` as its own process)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil_client.rigs.transports import Endpoint, parse_endpoint

REPO = Path(__file__).resolve().parents[3]

#: a stranger's probe: each ran with the defaults (or the last baud given), exit 0
BAD = [
    ("modbus-rtu:///dev/pts/0?baud", "a parameter is empty or has no value"),
    ("modbus-rtu:///dev/pts/0?baud=", "parameter 'baud' has no value"),
    ("modbus-rtu:///dev/pts/0?parity=", "parameter 'parity' has no value"),
    ("modbus-rtu:///dev/pts/0?=&&", "a parameter is empty or has no value"),
    ("modbus-rtu:///dev/pts/0?baud=19200&baud=9600", "parameter 'baud' is given 2 times"),
    ("modbus-rtu:///dev/pts/0?parity=E&parity=N", "parameter 'parity' is given 2 times"),
    ("modbus-rtu:///dev/pts/0?baud=9600&speed=1", "unknown parameter 'speed'"),
]


@pytest.mark.parametrize(("url", "fault"), BAD)
def test_an_empty_valueless_or_repeated_parameter_is_named(url, fault):
    with pytest.raises(ValueError, match=fault) as info:
        parse_endpoint(url)
    assert url in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("url", "endpoint"),
    [
        ("modbus-rtu:///dev/pts/0?", Endpoint("modbus-rtu", path="/dev/pts/0")),  # nothing given
        (
            "modbus-rtu:///dev/pts/0?parity=o&baud=9600",
            Endpoint("modbus-rtu", path="/dev/pts/0", baud=9600, parity="O"),
        ),
        (
            "modbus-rtu:///dev/pts/0?baud=%31200",
            Endpoint("modbus-rtu", path="/dev/pts/0", baud=1200),
        ),
    ],
)
def test_good_queries_still_parse(url, endpoint):
    assert parse_endpoint(url) == endpoint


@pytest.mark.parametrize(("url", "fault"), BAD[:5])
def test_hil_client_run_refuses_them_in_one_line(tmp_path, url, fault):
    done = subprocess.run(
        [
            *(sys.executable, "-m", "hil_client.cli", "run", "stationary"),
            *("--boiler", "windhager_12kw", "--rig", url, "--out", str(tmp_path / "o.csv")),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and fault in done.stderr, done.stderr
    assert not (tmp_path / "o.csv").exists()
