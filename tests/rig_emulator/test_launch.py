"""The two commands' launchers (:mod:`rig_emulator.launch`, :mod:`hil_client.launch`) as a
shell starts them: with standard output and error closed (``>&- 2>&-``)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SHORT = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"


def _closed_streams() -> None:
    os.close(1)
    os.close(2)


def test_a_run_started_without_standard_streams_writes_its_log(tmp_path):
    """A probe: ``hil-client run ... >&- 2>&-`` wrote no log and exited 1 (Python sets the
    missing streams to None: an AttributeError nobody saw). The log file opened next
    could also have taken descriptor 1 or 2, where messages are written."""
    out = tmp_path / "log.csv"
    code = "from hil_client.launch import main; import sys; sys.exit(main())"
    # --quiet: it says nothing on standard output (output to a closed one is a failure,
    # as for ``cat >&-``: test_cli_streams)
    argv = ["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(out), "--quiet"]
    proc = subprocess.run(
        [sys.executable, "-c", code, *argv], preexec_fn=_closed_streams, timeout=300
    )
    assert proc.returncode == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time_s,") and len(lines) > 1000
    # every line a row of the log: no message landed in it
    assert {len(line.split(",")) for line in lines} == {len(lines[0].split(","))}


def test_a_check_started_without_standard_streams_exits_as_it_would():
    """It checks the boiler without a traceback; its report had nowhere to go, which is a
    failure (exit 1, as ``cat >&-``), not the 0 that would say the report was read."""
    code = "from rig_emulator.launch import main; import sys; sys.exit(main())"
    argv = ["check", "--boiler", "windhager_12kw"]
    proc = subprocess.run(
        [sys.executable, "-c", code, *argv], preexec_fn=_closed_streams, timeout=120
    )
    assert proc.returncode == 1


def test_a_run_whose_message_readers_go_away_goes_on_to_the_end(tmp_path):
    """A probe: ``hil-client run ... 2>&1 | head -1`` stopped acquiring at its next
    message (1718 of 3518 rows, exit 1, a meta that said nothing), and with only standard
    output cut the complete log came with exit 1. A reader gone ends the messages, not
    the work."""
    import json

    out = tmp_path / "log.csv"
    code = "from hil_client.launch import main; import sys; sys.exit(main())"
    argv = ["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(out)]
    proc = subprocess.Popen(
        [sys.executable, "-c", code, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        first = proc.stderr.readline()  # the first phase mark: then both readers go
        proc.stderr.close()
        proc.stdout.close()
        assert proc.wait(timeout=300) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert first.startswith(b"hil-client: ")
    meta = json.loads(out.with_name("log.meta.json").read_text())
    assert meta["complete"] is True and meta["t4_s"] is not None
    rows = len(out.read_text().splitlines()) - 1
    assert rows >= meta["t4_s"]  # a row a second to t4


def test_a_second_stop_signal_leaves_the_exit_code_of_the_first(serve, tmp_path):
    """A re-probe: a run sent SIGTERM twice 0.1 s apart (a closing terminal, ``timeout``)
    said "interrupted; the log keeps ..." and then exited 143, not 1: the second signal
    came after the handlers were restored, during the interpreter's shutdown."""
    import signal
    import time

    srv = serve(lockstep=False, speed=20.0)
    out = tmp_path / "log.csv"
    code = "from hil_client.launch import main; import sys; sys.exit(main())"
    argv = ["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(out), "--quiet"]
    argv += ["--rig", f"modbus://127.0.0.1:{srv.port}"]
    proc = subprocess.Popen([sys.executable, "-c", code, *argv], stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while not out.exists() or len(out.read_text().splitlines()) < 5:
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        for _ in range(2):
            proc.send_signal(signal.SIGTERM)
            time.sleep(0.1)
        assert proc.wait(timeout=60) == 1, proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=30)


def test_ctrl_c_inside_a_c_callback_interrupts_the_command_without_a_traceback():
    """A CI run with a cold numba cache: Ctrl-C 0.9 s into ``hil-client run`` landed in
    numba's compiler, inside a callback llvmlite's C code made through ctypes, where an
    exception cannot go on: Python printed "Exception ignored on calling ctypes callback
    function" with a traceback, and the command went on as if Ctrl-C had never come. Such
    an interrupt is raised again once the callback has returned (here a ctypes callback
    that raises KeyboardInterrupt, as a signal handler would inside it)."""
    code = (
        "import ctypes\n"
        "from rig_emulator.launch import interrupts_not_swallowed\n"
        "interrupts_not_swallowed()\n"
        "def callback():\n"
        "    raise KeyboardInterrupt\n"
        "c_callback = ctypes.CFUNCTYPE(None)(callback)\n"
        "import time\n"
        "try:\n"
        "    c_callback()\n"
        "    deadline = time.monotonic() + 10\n"
        "    while time.monotonic() < deadline:\n"
        "        pass\n"
        "    print('went on')\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted')\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.stdout == "interrupted\n", (proc.stdout, proc.stderr)
    assert proc.stderr == ""
