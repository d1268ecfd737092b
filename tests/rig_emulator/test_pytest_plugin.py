"""The pytest plugin, as a user's suite uses it: a real pytest subprocess that finds the
plugin through the ``pytest11`` entry point of pyproject.toml (published to it as a
distribution's metadata on its path, since the shared venv is not reinstalled here)."""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

USER_SUITE = """
import math
import pytest

PORTS = []


@pytest.mark.rig_emulator(profile="lab", seed=2)
def test_api(rig_emulator):
    PORTS.append(rig_emulator.port)
    rig_emulator.advance(120)
    assert rig_emulator.read("sim_time_s") == 120.0
    true_room = rig_emulator.truth("room_temp_C")
    rig_emulator.inject({"kind": "offset", "signal": "room_temp_C", "value": 5.0})
    rig_emulator.advance(1)
    assert rig_emulator.read("room_temp_C") - rig_emulator.truth("room_temp_C") > 4.0
    assert abs(rig_emulator.truth("room_temp_C") - true_room) < 0.5
    rig_emulator.inject({"kind": "dropout", "signal": "flue_gas_O2_pct", "for_s": 5})
    rig_emulator.advance(1)
    assert math.isnan(rig_emulator.read("flue_gas_O2_pct"))
    assert rig_emulator.active_fault_count() == 2
    rig_emulator.clear_faults()
    assert rig_emulator.active_fault_count() == 0
    with open(PORTS_FILE, "a") as fh:
        fh.write(f"{rig_emulator.port} {rig_emulator.process.pid}\\n")


def test_the_fixture_leaves_tmp_path_to_the_test(rig_emulator, tmp_path):
    rig_emulator.inject({"kind": "no_reply", "unit": 2, "for_s": 1})
    rig_emulator.advance(2)
    assert list(tmp_path.iterdir()) == []
    assert rig_emulator.journal.read_text().count("\\n") == 2  # the start and the end


def test_failing_test_still_stops_the_server(rig_emulator):
    with open(PORTS_FILE, "a") as fh:
        fh.write(f"{rig_emulator.port} {rig_emulator.process.pid}\\n")
    assert rig_emulator.truth("water_flow_kg_h") == 12345.0  # fails on purpose
"""


def _entry_points() -> dict[str, str]:
    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["entry-points"][
        "pytest11"
    ]


def test_entry_point_is_declared():
    assert _entry_points() == {"rig_emulator.pytest_plugin": "rig_emulator.pytest_plugin"}


def _env_with_entry_point(tmp_path: Path) -> dict[str, str]:
    """PYTHONPATH with this worktree and a distribution whose metadata carries the
    pyproject's entry points (what ``pip install`` writes)."""
    site = tmp_path / "site"
    dist = site / "rig_plugin_probe-0.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: rig-plugin-probe\nVersion: 0.0\n")
    lines = "".join(f"{name} = {target}\n" for name, target in _entry_points().items())
    (dist / "entry_points.txt").write_text("[pytest11]\n" + lines)
    return {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{site}"}


def test_user_suite_runs_and_servers_stop_even_on_failure(tmp_path):
    ports = tmp_path / "ports.txt"
    (tmp_path / "test_user.py").write_text(f"PORTS_FILE = {str(ports)!r}\n" + USER_SUITE)
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "rig_emulator.pytest_plugin",
            "-p",
            "no:cacheprovider",
            "--strict-markers",
            str(tmp_path / "test_user.py"),
        ],
        cwd=tmp_path,
        env=_env_with_entry_point(tmp_path),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert "1 failed, 2 passed" in proc.stdout, proc.stdout + proc.stderr
    assert "12345" in proc.stdout  # the failure is the user's assertion, not the fixture's
    started = [line.split() for line in ports.read_text().splitlines()]
    assert len(started) == 2
    for port, pid in started:
        assert (
            not Path(f"/proc/{pid}").exists() or "zombie" in Path(f"/proc/{pid}/status").read_text()
        )
        with pytest.raises(OSError), socket.create_connection(("127.0.0.1", int(port)), 1):
            pass


@pytest.mark.parametrize("also_p", [False, True])
def test_marker_is_registered_once(tmp_path, also_p):
    """Through the entry point, with or without ``-p rig_emulator.pytest_plugin`` on top."""
    extra = ["-p", "rig_emulator.pytest_plugin"] if also_p else []
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "--markers", *extra],
        env=_env_with_entry_point(tmp_path),
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("@pytest.mark.rig_emulator(boiler=") == 1


def test_a_server_that_does_not_start_says_why(tmp_path):
    """An unknown boiler: the fixture's own error with the server's message, not an
    AttributeError from its clean-up."""
    from rig_emulator.pytest_plugin import RigEmulator, RigEmulatorError

    with pytest.raises(RigEmulatorError, match=r"did not start.*no_such_boiler"):
        RigEmulator(boiler="no_such_boiler", workdir=tmp_path)


def test_a_server_that_hangs_without_a_word_is_given_up_after_the_start_timeout(
    tmp_path, monkeypatch
):
    """A review: the start's bound never applied while the fixture waited on a line of
    the server's standard error, so a server hung before its first line hung the test.
    Here its interpreter sleeps before it runs (a ``sitecustomize`` on its path): the
    fixture gives up after START_TIMEOUT_S, saying so, and the process is gone."""
    from rig_emulator import pytest_plugin
    from rig_emulator.pytest_plugin import RigEmulator, RigEmulatorError

    hang = tmp_path / "hang"
    hang.mkdir()
    (hang / "sitecustomize.py").write_text("import time\ntime.sleep(600)\n")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(hang), *sys.path]))
    monkeypatch.setattr(pytest_plugin, "START_TIMEOUT_S", 2.0)
    workdir = tmp_path / "w"
    with pytest.raises(RigEmulatorError, match=r"said nothing of serving in 2 s"):
        RigEmulator(workdir=workdir)
    # no process left whose command line names its folder (stopped: SIGTERM, else KILL)
    left = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        with contextlib.suppress(OSError):
            if str(workdir).encode() in cmdline.read_bytes():
                left.append(cmdline.parent.name)
    assert left == []


SLOW_SUITE = """
import time


def test_waits(rig_emulator):
    with open(PORTS_FILE, "w") as fh:
        fh.write(f"{rig_emulator.port} {rig_emulator.process.pid}\\n")
    time.sleep(600)
"""


def _server_outlives_pytest(tmp_path: Path, how: str, *pytest_args: str) -> bool:
    """Start a user's suite whose test holds a server for ten minutes, kill pytest with
    ``how`` once the server listens, and say whether the server outlived it by 30 s (a
    bound, not a target) or kept its port."""
    import signal
    import time

    ports = tmp_path / "ports.txt"
    (tmp_path / "test_slow.py").write_text(f"PORTS_FILE = {str(ports)!r}\n" + SLOW_SUITE)
    proc = subprocess.Popen(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *pytest_args,
         "test_slow.py"],
        cwd=tmp_path,
        env=_env_with_entry_point(tmp_path),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 180
        while not (ports.exists() and ports.read_text().endswith("\n")):
            assert time.monotonic() < deadline and proc.poll() is None, "no server started"
            time.sleep(0.1)
        port, pid = (int(x) for x in ports.read_text().split())
        proc.send_signal(getattr(signal, how))
        proc.wait(timeout=30)
        deadline = time.monotonic() + 30
        while _alive(pid) and time.monotonic() < deadline:
            time.sleep(0.1)
        if _alive(pid):
            return True
        try:
            socket.create_connection(("127.0.0.1", port), 1).close()
        except OSError:
            return False
        return True
    finally:
        if proc.poll() is None:
            proc.kill()


@pytest.mark.skipif(sys.platform != "linux", reason="the parent-death signal is Linux's")
@pytest.mark.parametrize("how", ["SIGTERM", "SIGKILL"])
def test_the_server_stops_when_pytest_is_killed(tmp_path, how):
    """A CI job cancelled (SIGTERM to pytest, which Python does not turn into clean-up) or
    pytest killed outright: the server it started goes too, and frees its port."""
    assert not _server_outlives_pytest(tmp_path, how)


@pytest.mark.skipif(sys.platform != "linux", reason="the parent-death signal is Linux's")
def test_the_server_stops_when_the_xdist_controller_is_killed(tmp_path):
    """A stranger's probe: with ``pytest -n 2``, killing the controlling pytest left the
    worker and its server (and port) behind for a while (6 s here, where the worker ends
    by itself; the probe saw them to the end of the test). The worker's plugin now stops
    its servers once the controller is gone (1 s here)."""
    pytest.importorskip("xdist")
    assert not _server_outlives_pytest(tmp_path, "SIGKILL", "-n", "1")


def _alive(pid: int) -> bool:
    status = Path(f"/proc/{pid}/status")
    try:
        return "zombie" not in status.read_text()
    except OSError:
        return False


def test_advance_and_inject_take_what_a_user_gives_or_say_why(tmp_path):
    """From a user's probe: advance(0) is nothing, more than a day goes in several writes,
    a fraction or a negative is a ValueError before anything moves (0.5 was refused by the
    server with a bare 03, 1.5 rounded to 2); inject of a unit the bench lacks or of no dict
    names what is wrong (a bare 03, a TypeError from dict())."""
    from rig_emulator.faults import FaultError
    from rig_emulator.pytest_plugin import RigEmulator

    with RigEmulator(workdir=tmp_path) as rig:
        assert repr(rig).startswith(f"<RigEmulator 127.0.0.1:{rig.port} boiler=windhager_12kw")
        rig.advance(0)
        assert rig.read("sim_time_s") == 0.0
        for bad in (0.5, 1.5, -1, float("nan"), float("inf"), "10", True):
            with pytest.raises(ValueError, match="advance"):
                rig.advance(bad)
        # a stranger's probe: advance(10**12) (milliseconds as seconds?) ran for days
        for bad in (10**12, 366 * 86_400 + 1):
            with pytest.raises(ValueError, match="more than a year"):
                rig.advance(bad)
        assert rig.read("sim_time_s") == 0.0  # nothing moved
        rig.advance(2 * 86_400 + 5)
        assert rig.read("sim_time_s") == 2 * 86_400 + 5
        import numpy as np

        rig.advance(np.int64(10))  # a duration computed with numpy
        assert rig.read("sim_time_s") == 2 * 86_400 + 15
        with pytest.raises(FaultError, match="99"):
            rig.inject({"kind": "no_reply", "unit": 99})
        with pytest.raises(FaultError, match="expected a dict"):
            rig.inject("no_reply")  # type: ignore[arg-type]
        assert rig.active_fault_count() == 0


def test_inject_takes_numpy_numbers_and_read_gives_nan_for_any_dropout(tmp_path):
    """A stranger's probes: inject refused numpy's numbers (values taken from an array or
    a table); a spike of -999 on an int16 register in hundredths landed on its invalid code
    (read as a dropout) and 400 C clipped to 327.67, both accepted; read() gave a dropout
    on an integer register as -327.68 while a float's was NaN; an unknown unit was named
    'fault[0].unit'."""
    import math

    import numpy as np

    from rig_emulator.faults import FaultError
    from rig_emulator.pytest_plugin import RigEmulator

    with RigEmulator(workdir=tmp_path) as rig:
        rig.inject({"kind": "no_reply", "unit": np.int64(3), "for_s": np.float32(2.0)})
        assert rig.active_fault_count() == 1
        rig.clear_faults()
        for value in (-999.0, 400.0):
            with pytest.raises(FaultError, match=r"fault.value: .* outside .*-327.67..327.67"):
                rig.inject({"kind": "spike", "signal": "flue_gas_temp_C", "value": value})
        rig.inject({"kind": "spike", "signal": "flue_gas_temp_C", "value": -327.0})
        for end in (327.67, -327.67, np.float32(327.67)):  # the register's own ends
            rig.inject({"kind": "spike", "signal": "flue_gas_temp_C", "value": end})
        with pytest.raises(FaultError, match=r"^fault.unit: unit 9 is not on the bench"):
            rig.inject({"kind": "no_reply", "unit": 9})
        with pytest.raises(ValueError, match=r"one of .*flue_gas_temp_C"):
            rig.truth("flue_gas_tmp_C")
        rig.clear_faults()
        for signal in ("flue_gas_temp_C", "balance_mass_kg", "flue_gas_O2_pct"):
            rig.inject({"kind": "dropout", "signal": signal, "for_s": 5})
        rig.advance(1)
        for signal in ("flue_gas_temp_C", "balance_mass_kg", "flue_gas_O2_pct"):
            assert math.isnan(rig.read(signal)), signal
        rig.clear_faults()
        rig.inject({"kind": "offset", "signal": "balance_mass_kg", "value": 3e6})
        rig.advance(1)  # beyond the int32's range: clipped at its end, not its invalid code
        assert rig.read("balance_mass_kg") > 2e6


def test_a_read_under_no_reply_ends_in_one_error_at_the_reply_timeout(tmp_path):
    """A stranger's probe: read() under a no_reply fault waited 60 s (a 30-s timeout, tried
    twice) and raised pymodbus's own ModbusIOException, where an exception fault gave the
    plugin's error at once. Now RigEmulatorError naming the read, after reply_timeout_s;
    the fixture goes on with the other units."""
    import time

    from rig_emulator.pytest_plugin import RigEmulator, RigEmulatorError

    with RigEmulator(workdir=tmp_path) as rig:
        rig.reply_timeout_s = 1.0
        rig.inject({"kind": "no_reply", "unit": 2, "for_s": 60})
        started = time.monotonic()
        with pytest.raises(RigEmulatorError, match=r"read of flue_gas_O2_pct: no reply within 1 s"):
            rig.read("flue_gas_O2_pct")
        # a bound far above the 1-s wait, not a timing target: it was 60 s
        assert time.monotonic() - started < 30.0
        assert rig.read("water_flow_kg_h") >= 0.0
        rig.advance(61)
        assert rig.read("flue_gas_O2_pct") > 0.0  # back once the fault is over
        # a re-probe: a disconnect fault's reset read as "no reply" at first, and a reply
        # late past the timeout answered the calls after it (even to unfaulted units)
        rig.inject({"kind": "disconnect"})
        rig.advance(1)
        assert rig.read("room_temp_C") > 0.0
        rig.inject({"kind": "delay", "unit": 5, "delay_ms": 2500, "for_s": 60})
        with pytest.raises(RigEmulatorError, match="read of balance_mass_kg: no reply"):
            rig.read("balance_mass_kg")
        assert rig.truth("room_temp_C") > 0.0  # unit 101, never faulted
        rig.clear_faults()  # unit 100
        assert rig.read("balance_mass_kg") > 0.0
        # a write that timed out still lands once its delay ends: said (a re-probe)
        rig.inject({"kind": "delay", "unit": 1, "delay_ms": 2500, "for_s": 60})
        with pytest.raises(RigEmulatorError, match="still carried out when its delay ends"):
            rig.write("water_flow_setpoint_kg_h", 700.0)
        rig.clear_faults()


BAD_MARKERS = """
import pytest


@pytest.mark.rig_emulator(seed="abc")
def test_seed_text(rig_emulator):
    pass


@pytest.mark.rig_emulator(seed=1.7)
def test_seed_fraction(rig_emulator):
    pass


@pytest.mark.rig_emulator(speed=5)
def test_unknown_keyword(rig_emulator):
    pass


@pytest.mark.rig_emulator(boiler="no_such_boiler")
def test_unknown_boiler(rig_emulator):
    pass


@pytest.mark.rig_emulator(faults="faults_here.yaml")
def test_faults_beside_the_test_file(rig_emulator):
    rig_emulator.advance(20)
    assert rig_emulator.active_fault_count() == 1
"""


def test_bad_marker_options_fail_in_one_line_each(tmp_path):
    """Each wrong marker option fails its test with one line naming it, without the
    plugin's insides (45 lines of traceback per test), and a relative faults file is found
    beside the test file when pytest runs from elsewhere."""
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_markers.py").write_text(BAD_MARKERS)
    (suite / "faults_here.yaml").write_text(
        "faults:\n  - {kind: stuck, signal: room_temp_C, at_s: 10}\n"
    )
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(suite)],
        cwd=tmp_path,  # not the suite's folder
        env=_env_with_entry_point(tmp_path),
        capture_output=True,
        text=True,
        timeout=600,
    )
    out = proc.stdout
    assert "4 errors" in out and "1 passed" in out, out + proc.stderr
    assert "seed='abc' is not an integer" in out and "seed=1.7 is not an integer" in out
    assert "takes only the keywords boiler, profile, seed, faults; got speed" in out
    assert "unknown boiler 'no_such_boiler'" in out
    assert "_wait_listening" not in out and "Traceback" not in out
    assert "During handling of the above exception" not in out  # the server's line, once


STRICT_SUITE = """
import pytest


def test_normal_end(rig_emulator):
    rig_emulator.advance(1)


def test_failing_test(rig_emulator):
    assert rig_emulator.read("sim_time_s") == 12345.0  # fails on purpose


@pytest.mark.rig_emulator(seed="abc")
def test_bad_marker(rig_emulator):
    pass


@pytest.mark.rig_emulator(boiler="no_such_boiler")
def test_server_that_fails_to_start(rig_emulator):
    pass


def test_after_them(rig_emulator):
    rig_emulator.advance(1)
"""


@pytest.mark.parametrize("strict", ["ini", "-W"])
def test_the_fixture_closes_what_it_opens_under_filterwarnings_error(tmp_path, strict):
    """A stranger's probe: the fixture left its server's standard-error pipe open, so a
    suite with ``filterwarnings = error`` got "1 passed, 1 error": "ResourceWarning:
    unclosed file <_io.TextIOWrapper name=13 ...>" raised in the next test's set-up, then
    PytestUnraisableExceptionWarning; with PYTHONDEVMODE=1 every test using the fixture
    warned, a server that failed to start (an unknown boiler) too. On every path (a test
    that passes, one that fails, a bad marker, a server that does not start) nothing is
    left open: only the failures the suite asks for."""
    (tmp_path / "test_strict.py").write_text(STRICT_SUITE)
    ini = "[pytest]\nfilterwarnings =\n    error\n" if strict == "ini" else "[pytest]\n"
    (tmp_path / "pytest.ini").write_text(ini)
    options = ["-W", "error"] if strict == "-W" else []
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:randomly",
         *options, "test_strict.py"],
        cwd=tmp_path,
        env={**_env_with_entry_point(tmp_path), "PYTHONDEVMODE": "1"},
        capture_output=True,
        text=True,
        timeout=600,
    )  # fmt: skip
    out = proc.stdout + proc.stderr
    assert "1 failed, 2 passed, 2 errors" in proc.stdout, out
    for sign in ("ResourceWarning", "Unraisable", "unclosed", "INTERNALERROR"):
        assert sign not in out, out
    assert "seed='abc' is not an integer" in out and "unknown boiler 'no_such_boiler'" in out
    assert "12345" in out  # the failure is the test's own assertion
