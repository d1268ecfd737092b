"""``hil-client`` outputs that are no regular file: a FIFO, read or not, and a socket.

A stranger's probe: ``hil-client balance LOG --out FIFO`` with no process reading the FIFO
blocked forever in its open (SIGINT stopped it). Every output of both CLIs goes through
:func:`rig_emulator.cli_support.output_file`: a FIFO nobody reads is one line and exit 2
at once, one a process reads gets the output, a socket is refused.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

from tests.fifo_helpers import FifoReader

#: bound of a balance of the stationary log (about 3 s here) on a loaded machine
BALANCE_S = 120.0


def _balance(log: Path, out: Path) -> tuple[int | None, str]:
    """``hil-client balance LOG --out OUT`` in its own process: its exit code (None: still
    running after BALANCE_S, then killed) and standard error."""
    try:
        proc = subprocess.run(
            [sys.executable, "-m", "hil_client.cli", "balance", str(log), "--out", str(out)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=BALANCE_S,
        )  # fmt: skip
    except subprocess.TimeoutExpired as exc:  # (killed by subprocess.run)
        return None, str(exc.stderr or "")
    return proc.returncode, proc.stderr


def test_balance_out_to_a_fifo_nobody_reads_is_one_line_at_once(run_log, tmp_path):
    fifo = tmp_path / "balance.fifo"
    os.mkfifo(fifo)
    code, err = _balance(run_log("stationary", "windhager_12kw").path, fifo)
    assert code == 2, err
    refused = f"--out: no process reads the FIFO '{fifo}'; start its reader first"
    assert err == f"hil-client: error: {refused}\n"


def test_balance_out_to_a_fifo_read_gets_the_json_of_a_file(run_log, tmp_path):
    """The fix refuses only a FIFO nobody reads: one a process reads gets the same JSON
    as a file, and its reader the end of the stream."""
    log = run_log("stationary", "windhager_12kw").path
    fifo = tmp_path / "balance.fifo"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    code, err = _balance(log, fifo)
    assert code == 0, err
    assert reader.ended(BALANCE_S)
    code, err = _balance(log, tmp_path / "balance.json")
    assert code == 0, err
    expected = json.loads((tmp_path / "balance.json").read_text())
    assert json.loads("".join(reader.lines)) == expected


def test_balance_out_to_a_socket_is_refused(run_log, tmp_path):
    """A socket's open failed (ENXIO) after the analysis: exit 1, "No such device or
    address"; it is no file to write: exit 2, said before anything is written."""
    path = tmp_path / "b.sock"
    with socket.socket(socket.AF_UNIX) as listening:
        listening.bind(str(path))
        code, err = _balance(run_log("stationary", "windhager_12kw").path, path)
    assert code == 2, err
    assert err == f"hil-client: error: --out: '{path}' is a socket; name a file\n"


def test_run_out_to_a_fifo_is_refused_and_the_fifo_kept(tmp_path):
    """A probe: ``run --out FIFO.csv`` with a reader set the FIFO aside as an earlier run's
    log, wrote a regular file in its place and then deleted the FIFO, its reader getting
    nothing. A lab log is a file (it is set aside, locked and renamed): refused, kept."""
    fifo = tmp_path / "log.csv"
    os.mkfifo(fifo)
    reader = FifoReader(fifo)
    proc = subprocess.run(
        [sys.executable, "-m", "hil_client.cli", "run", "stationary", "--boiler",
         "windhager_12kw", "--rig", "local", "--quiet", "--out", str(fifo)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=BALANCE_S,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    refused = f"--out: '{fifo}' is not a regular file; a lab log and its meta and events files"
    assert proc.stderr == f"hil-client: error: {refused} are files\n"
    assert fifo.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["log.csv"]
    reader.ended(1.0)  # (released: nothing was written to it)
    assert not reader.lines
    # (a re-probe: a FIFO at the log's meta file was set aside as an earlier run's, deleted)
    fifo.unlink()
    os.mkfifo(tmp_path / "log.meta.json")
    proc = subprocess.run(
        [sys.executable, "-m", "hil_client.cli", "run", "stationary", "--boiler",
         "windhager_12kw", "--rig", "local", "--quiet", "--out", str(fifo)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=BALANCE_S,
    )  # fmt: skip
    assert proc.returncode == 2 and "log.meta.json' is not a regular file" in proc.stderr
    assert (tmp_path / "log.meta.json").is_fifo() and not fifo.exists()


def test_a_fifo_nobody_reads_beside_the_out_is_one_line_at_once(run_log, tmp_path):
    """A re-probe: the FIFO refusal covered ``--out`` only, and calibrate still waited for
    good on a FIFO at ``OUT.uncertainty.json``, validate on one at ``DIR/validation.json``.
    Every file written goes through :func:`rig_emulator.atomic.replacing`: one line at once."""
    log = run_log("stationary", "windhager_12kw").path
    fifo = tmp_path / "cal.uncertainty.json"
    os.mkfifo(fifo)
    proc = subprocess.run(
        [sys.executable, "-m", "hil_client.cli", "calibrate", str(log), "--boiler",
         "windhager_12kw", "--out", str(tmp_path / "cal.yaml")],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=BALANCE_S,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f"hil-client: error: {fifo}: no process reads the FIFO\n"
    assert fifo.is_fifo()
