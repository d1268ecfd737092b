"""``rig-emulator serve`` exits 1 when its fault journal lost lines (CONTRACT: exit 1 for an
OS failure such as a full disk). A stranger's probe: ``--fault-log /dev/full`` logged "N
line(s) lost" and exited 0 after SIGTERM, the loss silent in CI."""

from __future__ import annotations

import signal
import subprocess
from pathlib import Path

import pytest

from hil_client.demo import rig_emulator_serve
from rig_emulator.registers import encode, load_map
from tests.modbus_helpers import client, read_point


def _serve_and_stop(tmp_path: Path, journal: str) -> tuple[int, str]:
    """A lockstep server with a fault from 1 s to 3 s, advanced 4 s, stopped by SIGTERM:
    its exit code and standard error."""
    faults = tmp_path / "faults.yaml"
    faults.write_text("faults:\n  - {kind: exception, unit: 5, code: 6, at_s: 1, for_s: 2}\n")
    options = ("--lockstep", "--faults", str(faults), "--fault-log", journal)
    with rig_emulator_serve("windhager_12kw", *options, stderr=subprocess.PIPE) as (port, proc):
        sim = load_map().device("sim_control")
        sim_time = next(p for p in sim.points if p.name == "sim_time")
        advance = next(p for p in sim.points if p.name == "lockstep_advance")
        c = client(port, timeout_s=60)
        for step in range(1, 5):
            assert not c.write_registers(
                advance.address, encode(advance, 1), device_id=100
            ).isError()
            assert read_point(c, sim, sim_time) == step
        c.close()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=60)
        return code, proc.stderr.read().decode()


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_serve_exits_1_after_a_clean_stop_when_journal_lines_were_lost(tmp_path):
    code, err = _serve_and_stop(tmp_path, "/dev/full")
    assert code == 1, err
    assert err.count("fault journal /dev/full: 2 line(s) lost") == 1, err  # start and end
    assert "stopping at simulated time 4.0 s" in err  # the normal stop, then the exit code
    assert "Traceback" not in err, err
    # the same run with a journal it can write: exit 0, both lines there
    code, err = _serve_and_stop(tmp_path, str(tmp_path / "j.jsonl"))
    assert code == 0, err
    assert (tmp_path / "j.jsonl").read_text().count("\n") == 2
