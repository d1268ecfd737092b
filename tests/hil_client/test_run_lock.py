"""One run at a time per log (:mod:`hil_client.run_lock`), with real processes: a run
writing a log against a real-time server, a second ``hil-client run`` given the same
``--out``, and the first killed with -9."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil_client.cli import main
from hil_client.demo import rig_emulator_serve
from hil_client.run_lock import lock_path

SHORT = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"


def _rows(path: Path) -> int:
    return max(len(path.read_text().splitlines()) - 1, 0) if path.exists() else 0


def _wait_rows(path: Path, rows: int, proc: subprocess.Popen, timeout_s: float = 60.0) -> None:
    end = time.monotonic() + timeout_s
    while _rows(path) < rows:
        assert proc.poll() is None, f"the first run ended with {proc.returncode}"
        assert time.monotonic() < end, f"{path}: fewer than {rows} rows in {timeout_s} s"
        time.sleep(0.2)


@pytest.mark.parametrize("through_a_link", [False, True])
def test_a_second_run_on_a_log_being_written_is_refused_and_moves_nothing(
    tmp_path, capsys, through_a_link
):
    """A probe: two runs given one ``--out``. The second set the first one's live log
    aside as ``.previous`` and deleted it at its own first row, while the first went on
    writing into the deleted file: both exit 0, one log lost. The second is now refused
    in one line naming the first's pid; a run killed with -9 leaves no lock behind it.
    A re-probe: through a symlinked ``--out`` the first run replaced the link with a
    plain file and the second went unlocked; the log is now the file the link names."""
    out = tmp_path / "log.csv"
    given = out
    if through_a_link:
        given = tmp_path / "link.csv"
        given.symlink_to(out)
    with rig_emulator_serve("windhager_12kw") as (port, _server):  # real time: a row a second
        first = subprocess.Popen(
            [sys.executable, "-m", "hil_client.cli", "run", "--boiler", "windhager_12kw",
             str(SHORT), "--rig", f"modbus://127.0.0.1:{port}", "--out", str(given), "--quiet"],
            stderr=subprocess.PIPE,
        )  # fmt: skip
        try:
            _wait_rows(out, 2, first)
            code = main(["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(given)])
            err = capsys.readouterr().err
            assert code == 2, err
            assert f"is being written by another run (pid {first.pid})" in err, err
            assert err.count("\n") == 1, err
            before = _rows(out)
            _wait_rows(out, before + 2, first)  # the first run's log is the live one still
            assert not list(tmp_path.glob("log.previous*"))  # nothing was set aside
            first.send_signal(signal.SIGKILL)
            first.wait(timeout=30)
        finally:
            if first.poll() is None:
                first.kill()
            first.wait(timeout=30)
    assert lock_path(out).exists()  # what kill -9 leaves: a file nobody holds
    code = main(["run", "--boiler", "windhager_12kw", str(SHORT), "--out", str(given), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "holds an earlier run's log" in err, err
    assert not lock_path(out).exists()  # a run that ends removes its lock
    assert given.is_symlink() == through_a_link and out.is_file()
