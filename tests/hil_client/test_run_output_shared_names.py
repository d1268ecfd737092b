"""Logs whose names differ only in the case of ``.csv`` (``s.csv``, ``s.CSV``) share one
meta file and one Modbus events file (``s.meta.json``, ``s.modbus_events.jsonl``): with
real processes, a run to one while another writes the other is refused as a run to the
same log is, and a run beside the other's log is refused before it writes anything."""

from __future__ import annotations

import json
import subprocess
import sys

from hil_client.demo import rig_emulator_serve
from hil_client.run_lock import lock_path
from tests.hil_client.test_run_lock import SHORT, _wait_rows


def _hil_client_run(out, boiler: str, rig: str) -> list[str]:
    return [sys.executable, "-m", "hil_client.cli", "run", str(SHORT), "--boiler", boiler,
            "--rig", rig, "--quiet", "--out", str(out)]  # fmt: skip


def test_a_run_to_the_same_name_in_another_case_of_csv_is_refused(tmp_path):
    """A stranger's probe: run A writing s.csv (a 12-kW boiler), run B given s.CSV (a 6-kW
    one, its lock guarding only the exact name) replaced A's s.meta.json and truncated
    its s.modbus_events.jsonl; ``balance s.csv`` then analysed A's log as B's boiler with
    B's phase marks, exit 0. B is now refused while A runs (one line naming A's pid and
    log), and after A ends (killed with -9) too, as s.csv beside it owns the meta file;
    A's files are as A wrote them, and B wrote nothing."""
    a_out, b_out = tmp_path / "s.csv", tmp_path / "s.CSV"
    meta, events = tmp_path / "s.meta.json", tmp_path / "s.modbus_events.jsonl"
    with rig_emulator_serve("windhager_12kw") as (port, _server):  # real time: a row a second
        run_a = subprocess.Popen(
            _hil_client_run(a_out, "windhager_12kw", f"modbus://127.0.0.1:{port}"),
            stderr=subprocess.DEVNULL,
        )
        try:
            _wait_rows(a_out, 2, run_a)
            a_meta, a_events = meta.read_bytes(), events.stat().st_size
            run_b = subprocess.run(
                _hil_client_run(b_out, "windhager_6kw", "local"),
                stderr=subprocess.PIPE, text=True, timeout=120,
            )  # fmt: skip
            assert run_a.poll() is None  # A was live all along
            assert meta.read_bytes() == a_meta and events.stat().st_size >= a_events
        finally:
            run_a.kill()
            run_a.wait(timeout=30)
    assert run_b.returncode == 2, run_b.stderr
    assert f"is being written by another run (pid {run_a.pid})" in run_b.stderr, run_b.stderr
    assert f"it writes '{a_out}'" in run_b.stderr and run_b.stderr.count("\n") == 1
    assert not b_out.exists()
    assert lock_path(a_out) == lock_path(b_out)  # one lock for both names

    after = subprocess.run(  # A's lock is gone with A: the meta file is still A's
        _hil_client_run(b_out, "windhager_6kw", "local"),
        stderr=subprocess.PIPE, text=True, timeout=120,
    )  # fmt: skip
    assert after.returncode == 2, after.stderr
    assert (
        f"--out: '{b_out}' would share its meta and events files ('s.meta.json', "
        f"'s.modbus_events.jsonl') with the log '{a_out}' beside it"
    ) in after.stderr, after.stderr
    assert after.stderr.count("\n") == 1
    assert not b_out.exists() and json.loads(meta.read_text())["boiler"] == "windhager_12kw"
    assert not list(tmp_path.glob("s.previous*"))  # nothing was set aside either
