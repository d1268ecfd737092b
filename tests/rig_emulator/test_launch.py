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
    argv = ["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(out)]
    proc = subprocess.run(
        [sys.executable, "-c", code, *argv], preexec_fn=_closed_streams, timeout=300
    )
    assert proc.returncode == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("time_s,") and len(lines) > 1000
    # every line a row of the log: no message landed in it
    assert {len(line.split(",")) for line in lines} == {len(lines[0].split(","))}


def test_a_check_started_without_standard_streams_exits_as_it_would():
    code = "from rig_emulator.launch import main; import sys; sys.exit(main())"
    argv = ["check", "--boiler", "windhager_12kw"]
    proc = subprocess.run(
        [sys.executable, "-c", code, *argv], preexec_fn=_closed_streams, timeout=120
    )
    assert proc.returncode == 0
