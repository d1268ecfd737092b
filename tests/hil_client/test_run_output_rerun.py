"""A re-run to the ``--out`` of an earlier log, with real processes and files: only a run
that completes replaces the earlier log; one stopped by Ctrl-C or by a failing write keeps
it beside its own partial log, as ``NAME.previous.csv`` with its meta and events files."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from hil_client.cli import main
from hil_client.demo import rig_emulator_serve
from tests.hil_client.test_run_lock import SHORT, _rows
from tests.hil_client.test_run_refusals import _with_file_size_limit


def _run_argv(out: Path, *rig: str) -> list[str]:
    return ["run", str(SHORT), "--boiler", "windhager_12kw", *rig, "--quiet", "--out", str(out)]


def _earlier_run(out: Path) -> dict[str, bytes]:
    """A complete run's files at ``out`` (the in-process rig), by name."""
    assert main(_run_argv(out)) == 0
    meta = out.with_name(out.stem + ".meta.json")
    assert json.loads(meta.read_text())["complete"] is True
    return {path.name: path.read_bytes() for path in (out, meta)}


def _wait_rerun_rows(out: Path, rows: int, proc: subprocess.Popen) -> None:
    """Wait until the re-run ``proc`` wrote ``rows`` rows of its own at ``out`` (a new
    file there: the earlier log was set aside)."""
    earlier = out.stat().st_ino
    end = time.monotonic() + 60  # (a row a second from a real-time server; its start: ~2 s)
    while not (out.exists() and out.stat().st_ino != earlier and _rows(out) >= rows):
        assert proc.poll() is None, f"the re-run ended with {proc.returncode}"
        assert time.monotonic() < end, f"{out}: the re-run wrote fewer than {rows} rows in 60 s"
        time.sleep(0.2)


def _still_there(directory: Path, log: bytes) -> bool:
    """Whether a file in ``directory`` holds the bytes of the earlier log, by any name."""
    return any(p.read_bytes() == log for p in directory.iterdir() if p.is_file())


def _files(directory: Path, names: list[str]) -> dict[str, bytes]:
    return {name: (directory / name).read_bytes() for name in names}


def test_a_rerun_stopped_with_ctrl_c_keeps_the_complete_earlier_log(tmp_path, capsys):
    """A stranger's probe: a complete 18-h log at r.csv, a re-run to the same --out stopped
    with Ctrl-C 2 s later: "interrupted; the log keeps the 10264 rows written", and the
    complete log was gone (deleted at the re-run's first row). It is now kept, whole, as
    r.previous.csv (and its meta), said on stderr; the partial log stays at r.csv. A
    further re-run sets that partial log aside under the next free name and, completing,
    replaces only it: the kept log is never touched."""
    out = tmp_path / "r.csv"
    earlier = _earlier_run(out)
    capsys.readouterr()
    with rig_emulator_serve("windhager_12kw") as (port, _server):  # real time: a row a second
        rerun = subprocess.Popen(
            [sys.executable, "-m", "hil_client.cli",
             *_run_argv(out, "--rig", f"modbus://127.0.0.1:{port}")],
            stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            _wait_rerun_rows(out, 3, rerun)
            rerun.send_signal(signal.SIGINT)
            _, err = rerun.communicate(timeout=60)
        finally:
            if rerun.poll() is None:
                rerun.kill()
                rerun.wait(timeout=30)
    assert rerun.returncode == 1, err
    assert _still_there(tmp_path, earlier["r.csv"]), err
    kept = ["r.previous.csv", "r.previous.meta.json"]
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True)), err
    assert f"it is kept as {tmp_path / 'r.previous.csv'}" in err, err
    assert f"and the earlier run's log is kept as {tmp_path / 'r.previous.csv'}" in err, err
    partial = _rows(out)
    assert 3 <= partial < 100, err  # SHORT's first rows at a row a second, not its ~5000
    meta = json.loads((tmp_path / "r.meta.json").read_text())
    assert meta["complete"] is False and meta["interrupted"] is True
    assert (tmp_path / "r.modbus_events.jsonl").exists()  # the Modbus run's own, beside it

    assert main(_run_argv(out)) == 0  # completes: replaces the partial log at --out only
    err = capsys.readouterr().err
    assert f"{out} holds an earlier run's log ({partial} rows, not complete)" in err, err
    assert f"it is kept as {tmp_path / 'r.previous2.csv'}" in err, err
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True))
    assert json.loads((tmp_path / "r.meta.json").read_text())["complete"] is True
    assert not list(tmp_path.glob("r.previous2*"))
    assert not (tmp_path / "r.modbus_events.jsonl").exists()  # the local rig writes none


#: The re-run's log is stopped at this size: about 570 of SHORT's ~5000 rows (the rows
#: are about 180 bytes each), so the write fails as on a full disk, after the first row.
FILE_SIZE_LIMIT = 100_000


def test_a_rerun_whose_writes_fail_keeps_the_complete_earlier_log(tmp_path):
    """A stranger's probe: a second run to the --out of a complete lab log died of a full
    disk, and left its fragment in place of the complete log (deleted at its first row).
    A write that fails (here at the process's file-size limit) now stops the run with the
    earlier log kept as NAME.previous.csv beside the fragment, and said."""
    out = tmp_path / "lab.csv"
    earlier = _earlier_run(out)
    rerun = subprocess.run(
        [sys.executable, "-m", "hil_client.cli", *_run_argv(out, "--seed", "7")],
        stderr=subprocess.PIPE, text=True, timeout=120,
        preexec_fn=_with_file_size_limit(FILE_SIZE_LIMIT),
    )  # fmt: skip
    assert rerun.returncode == 1, rerun.stderr
    assert f"cannot write {out}" in rerun.stderr, rerun.stderr
    assert _still_there(tmp_path, earlier["lab.csv"]), rerun.stderr
    kept = ["lab.previous.csv", "lab.previous.meta.json"]
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True))
    assert f"the earlier run's log is kept as {tmp_path / 'lab.previous.csv'}" in rerun.stderr
    assert _rows(out) > 0 and out.stat().st_size <= FILE_SIZE_LIMIT


def test_the_name_an_earlier_log_is_kept_under_is_held_while_the_run_writes(tmp_path):
    """Where a re-run keeps the earlier log (r.previous.csv) no other run writes until it
    ends: a run given that --out would set the kept log aside in turn, and delete it when
    it completed. It is refused in one line naming the pid and what that run keeps."""
    out = tmp_path / "r.csv"
    earlier = _earlier_run(out)
    kept = tmp_path / "r.previous.csv"
    with rig_emulator_serve("windhager_12kw") as (port, _server):  # real time: a row a second
        rerun = subprocess.Popen(
            [sys.executable, "-m", "hil_client.cli",
             *_run_argv(out, "--rig", f"modbus://127.0.0.1:{port}")],
            stderr=subprocess.PIPE,
        )  # fmt: skip
        try:
            _wait_rerun_rows(out, 2, rerun)
            other = subprocess.run(
                [sys.executable, "-m", "hil_client.cli", *_run_argv(kept, "--rig", "local")],
                stderr=subprocess.PIPE, text=True, timeout=120,
            )  # fmt: skip
            assert rerun.poll() is None
        finally:
            rerun.kill()
            rerun.wait(timeout=30)
    assert other.returncode == 2, other.stderr
    assert f"is being written by another run (pid {rerun.pid})" in other.stderr, other.stderr
    assert f"it keeps the earlier run's files of its --out '{out}' there" in other.stderr
    assert other.stderr.count("\n") == 1, other.stderr
    assert kept.read_bytes() == earlier["r.csv"]
