"""The query of a ``modbus-rtu://`` URL: each parameter once, with a value, or one line and
exit 2 (``hil-client run`` as its own process); a line on the pty multiplexer, refused as the
server refuses it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil_client.rigs.transports import Endpoint, connector, parse_endpoint

REPO = Path(__file__).resolve().parents[3]

#: a stranger's probe: each ran with the defaults (or the last baud given), exit 0
BAD = [
    ("modbus-rtu:///dev/pts/0?baud", "parameter 'baud' has no value"),
    ("modbus-rtu:///dev/pts/0?baud=", "parameter 'baud' has no value"),
    ("modbus-rtu:///dev/pts/0?parity=", "parameter 'parity' has no value"),
    ("modbus-rtu:///dev/pts/0?=&&", "'=' names no parameter"),
    ("modbus-rtu:///dev/pts/0?baud=19200&baud=9600", "parameter 'baud' is given 2 times"),
    ("modbus-rtu:///dev/pts/0?parity=E&parity=N", "parameter 'parity' is given 2 times"),
    ("modbus-rtu:///dev/pts/0?baud=9600&speed=1", "unknown parameter 'speed'"),
]
#: a re-probe: the strict parse said "a parameter is empty or has no value" of a name
#: without "=", naming nothing, and "²" (isdigit() is true of it) ended in int()'s own words
NAMED = [
    ("modbus-rtu:///dev/pts/0?baud=9600&foo", "unknown parameter 'foo'"),
    ("modbus-rtu:///dev/pts/0?baud=9600&BAUD", "unknown parameter 'BAUD'"),
    ("modbus-rtu:///dev/pts/0?baud=\u00b2", "baud '\u00b2' is not a line speed"),
    ("modbus-rtu:///dev/pts/0?baud=%C2%B2", "baud '\u00b2' is not a line speed"),
    ("modbus-rtu:///dev/pts/0?baud=\u0661\u0669\u0662\u0660\u0660", "is not a line speed"),
    ("modbus-rtu:///dev/pts/0?baud=9600&&parity=E&baud=9600", "parameter 'baud' is given 2"),
    # a speed the line cannot be set to was passed over, the line left at its own speed
    ("modbus-rtu:///dev/pts/0?baud=19201", r"baud 19201 is not a serial line speed \(1200, "),
]


@pytest.mark.parametrize(("url", "fault"), BAD + NAMED)
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
        # a re-probe: a stray "&" was refused as "a parameter is empty or has no value";
        # browsers and urllib pass it over, as before
        *(
            (f"modbus-rtu:///dev/pts/0?{query}", Endpoint("modbus-rtu", "", 0, "/dev/pts/0", 9600))
            for query in ("baud=9600&", "&baud=9600&parity=E", "baud=9600&&parity=E", "&&baud=9600")
        ),
    ],
)
def test_good_queries_still_parse(url, endpoint):
    assert parse_endpoint(url) == endpoint


def _run(tmp_path: Path, url: str) -> subprocess.CompletedProcess:
    """``hil-client run stationary --rig URL`` as its own process, to its end."""
    return subprocess.run(
        [
            *(sys.executable, "-m", "hil_client.cli", "run", "stationary"),
            *("--boiler", "windhager_12kw", "--rig", url, "--out", str(tmp_path / "o.csv")),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )


@pytest.mark.parametrize(("url", "fault"), BAD[:5] + NAMED[:3])
def test_hil_client_run_refuses_them_in_one_line(tmp_path, url, fault):
    done = _run(tmp_path, url)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and fault in done.stderr, done.stderr
    assert not (tmp_path / "o.csv").exists()


def _is_multiplexer_node(path: str) -> bool:
    try:
        rdev = os.stat(path).st_rdev
    except OSError:
        return False
    return (os.major(rdev), os.minor(rdev)) == (5, 2)


@pytest.mark.parametrize("path", ["/dev/ptmx", "/dev/pts/ptmx"])
def test_the_pty_multiplexer_is_refused_before_it_is_opened(tmp_path, path):
    """A re-probe: ``rig-emulator serve --serial /dev/ptmx`` is refused in one line, but
    ``hil-client run --rig modbus-rtu:///dev/ptmx`` opened it (a new pty nobody serves),
    waited and said "cannot reach ...: no reply within 5 s", exit 1 after 7 s. Now: the
    server's words in one line, exit 2, and the connector refuses it before opening it."""
    if not _is_multiplexer_node(path):
        pytest.skip(f"{path} is not Linux's pty multiplexer here")
    url = f"modbus-rtu://{path}?baud=9600"
    with pytest.raises(ValueError, match="the pseudo-terminal multiplexer opens a new pty"):
        connector(url, 1.0)  # it returned a function that opened the multiplexer
    done = _run(tmp_path, url)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
    assert f"--rig: '{url}': {path}: the pseudo-terminal multiplexer opens a new pty" in (
        done.stderr
    )
    assert not (tmp_path / "o.csv").exists()
