"""A re-run to the ``--out`` of an earlier log, with real processes and files: only a run
that completes replaces the earlier log; one stopped by Ctrl-C or by a failing write keeps
it beside its own partial log, as ``NAME.previous.csv`` with its meta and events files."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hil_client.cli import main
from hil_client.demo import rig_emulator_serve
from hil_client.run_lock import lock_path, run_lock
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


def _rerun_on(out: Path, port: int, **popen) -> subprocess.Popen:
    """``hil-client run`` to ``out`` on the real-time server at ``port``, in its own
    process (``popen``: how its stderr is taken)."""
    argv = [sys.executable, "-m", "hil_client.cli"]
    return subprocess.Popen(
        [*argv, *_run_argv(out, "--rig", f"modbus://127.0.0.1:{port}")], **popen
    )


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
        rerun = _rerun_on(out, port, stderr=subprocess.PIPE, text=True)
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
        rerun = _rerun_on(out, port, stderr=subprocess.PIPE)
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


def _hooked_run(hook: str, out: Path, *options: str) -> subprocess.CompletedProcess:
    """``hil-client run`` to ``out`` in its own process, ``hook`` run first in it (it
    sends that process a real SIGINT at a chosen moment, which no outside timing hits)."""
    code = f"{hook}\nfrom hil_client.cli import main\nsys.exit(main(sys.argv[1:]))"
    return subprocess.run(
        [sys.executable, "-c", f"import os, signal, sys\n{code}", *_run_argv(out, *options)],
        stderr=subprocess.PIPE, text=True, timeout=120,
    )  # fmt: skip


def _hil_client(out: Path, *options: str, **kwargs) -> subprocess.CompletedProcess:
    """``hil-client run`` to ``out`` in its own process, its stderr captured."""
    return subprocess.run(
        [sys.executable, "-m", "hil_client.cli", *_run_argv(out, *options)],
        stderr=subprocess.PIPE, text=True, timeout=120, **kwargs,
    )  # fmt: skip


def _snapshot(directory: Path) -> dict[str, bytes]:
    """Every file in ``directory`` (lock files included), by name."""
    return {p.name: p.read_bytes() for p in directory.iterdir() if p.is_file()}


def test_an_earlier_log_whose_meta_cannot_be_moved_stays_whole_at_out(tmp_path):
    """A stranger's probe: the earlier a.meta.json made immutable (chattr +i, as another
    user's file in a sticky directory is), a re-run said only "a.meta.json: Operation not
    permitted" (exit 2) and left a.previous.csv and a.meta.json, no a.csv; the next run
    took the orphaned meta for an earlier run's, "kept as a.previous2.meta.json", and
    deleted it on completing: the earlier log lost its meta for good. The set-aside is now
    all or none: the log moved is moved back, and the run refused in one line naming the
    file and the reason; a later run, the meta movable again, replaces both as one log."""
    out = tmp_path / "a.csv"
    earlier = _earlier_run(out)
    meta = tmp_path / "a.meta.json"
    chattr = shutil.which("chattr")
    made = chattr and subprocess.run([chattr, "+i", str(meta)], capture_output=True, text=True)
    if not made or made.returncode != 0:
        pytest.skip(f"chattr +i {meta} failed: {made.stderr.strip() if made else 'no chattr'}")
    try:
        rerun = _hil_client(out)
    finally:
        subprocess.run([chattr, "-i", str(meta)], check=True)
    assert rerun.returncode == 2, rerun.stderr
    assert rerun.stderr.count("\n") == 1, rerun.stderr
    assert f"'{meta}' cannot be set aside as 'a.previous.meta.json'" in rerun.stderr
    assert f"({os.strerror(errno.EPERM)})" in rerun.stderr and "nothing was moved" in rerun.stderr
    assert _snapshot(tmp_path) == earlier, rerun.stderr  # no a.previous*, no lock file

    assert main(_run_argv(out)) == 0  # movable again: the earlier log and meta are replaced
    assert json.loads(meta.read_text())["complete"] is True
    assert sorted(_snapshot(tmp_path)) == ["a.csv", "a.meta.json"]


def test_an_earlier_log_whose_aside_names_are_too_long_stays_whole_at_out(tmp_path):
    """A stranger's probe: --out with a 236-character stem; a re-run that did not complete
    kept the earlier log as N.previous.csv; the next re-run found N.previous2.meta.json
    free (a name too long to exist), moved the log, failed on the meta with "N.meta.json:
    File name too long" (the wrong file named) and every later run failed so. A name too
    long to be made is now no name to keep files under: the run is refused in one line
    before it moves anything."""
    name_max = os.pathconf(tmp_path, "PC_NAME_MAX")
    stem = "x" * (name_max - len(".previous.meta.json"))  # .previous fits, .previous2 not
    out = tmp_path / f"{stem}.csv"
    earlier = _earlier_run(out)
    stopped = _hil_client(out, "--seed", "7", preexec_fn=_with_file_size_limit(FILE_SIZE_LIMIT))
    assert stopped.returncode == 1, stopped.stderr  # its log kept the earlier one beside it
    kept = [f"{stem}.previous.csv", f"{stem}.previous.meta.json"]
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True))
    before = _snapshot(tmp_path)

    rerun = _hil_client(out)
    assert rerun.returncode == 2, rerun.stderr
    assert rerun.stderr.count("\n") == 1, rerun.stderr
    assert f"'{stem}.previous2.meta.json', is too long" in rerun.stderr, rerun.stderr
    assert _snapshot(tmp_path) == before  # nothing moved, nothing lost


#: Run first in a re-run: a real SIGINT to itself just after its first rename of an
#: earlier run's file to a kept name (between the log's rename and its meta's).
SIGINT_AFTER_FIRST_SET_ASIDE = """
_replace = os.replace
def _then_sigint(src, dst, *args, **kwargs):
    _replace(src, dst, *args, **kwargs)
    if ".previous" in os.fsdecode(dst) and not _then_sigint.sent:
        _then_sigint.sent = True
        os.kill(os.getpid(), signal.SIGINT)
_then_sigint.sent = False
os.replace = _then_sigint
"""


def test_ctrl_c_between_the_renames_of_the_set_aside_leaves_no_half_moved_log(tmp_path):
    """A stranger's probe: the set-aside is one rename per file, and a Ctrl-C between two
    of them left the log moved and its meta at --out, which the next run took for an
    earlier run's. The renames now hold the signal; as the run has written nothing, the
    files go back, and it stops as interrupted."""
    out = tmp_path / "a.csv"
    earlier = _earlier_run(out)
    rerun = _hooked_run(SIGINT_AFTER_FIRST_SET_ASIDE, out)
    assert rerun.returncode == 1, rerun.stderr
    assert "interrupted" in rerun.stderr, rerun.stderr
    assert _snapshot(tmp_path) == earlier, rerun.stderr


#: Run first in a re-run: a real SIGINT to itself just after it wrote its final meta
#: file (complete: true), before the earlier log is settled.
SIGINT_AFTER_COMPLETE_META = """
import hil_client.cli as cli
_write_meta = cli.write_meta
def _then_sigint(path, meta):
    written = _write_meta(path, meta)
    if meta.get("complete"):
        os.kill(os.getpid(), signal.SIGINT)
    return written
cli.write_meta = _then_sigint
"""


def test_ctrl_c_just_after_the_complete_meta_still_replaces_the_earlier_log(tmp_path):
    """A stranger's probe: Ctrl-C just after a re-run wrote its final meta (complete:
    true) kept the earlier log as a.previous.csv and said "a run that did not complete
    replaces nothing", beside a log and meta saying complete. The signal now waits until
    the earlier log is replaced, and the run says it completed."""
    out = tmp_path / "a.csv"
    earlier = _earlier_run(out)
    rerun = _hooked_run(SIGINT_AFTER_COMPLETE_META, out)
    assert rerun.returncode == 1, rerun.stderr
    assert "interrupted after the run completed" in rerun.stderr, rerun.stderr
    assert "replaces nothing" not in rerun.stderr, rerun.stderr
    assert json.loads((tmp_path / "a.meta.json").read_text())["complete"] is True
    assert _rows(out) == _rows_of(earlier["a.csv"])  # the same protocol, all its rows
    assert sorted(_snapshot(tmp_path)) == ["a.csv", "a.meta.json"]  # no a.previous*


def _rows_of(log: bytes) -> int:
    return max(len(log.splitlines()) - 1, 0)


def test_a_run_after_a_killed_rerun_says_which_kept_logs_it_leaves(tmp_path):
    """A stranger's probe: after a re-run killed with -9, the next run never mentioned the
    complete earlier log kept as r.previous.csv (it set the partial log aside as
    r.previous2.csv and deleted that on completing, silently), and the killed run's
    .r.previous.csv.lock stayed for good. The next run now says at its start which logs
    are kept beside --out and that it leaves them, never touches them, and removes the
    lock files no live process holds (one a live process holds stays, and is passed
    over)."""
    out = tmp_path / "r.csv"
    earlier = _earlier_run(out)
    with rig_emulator_serve("windhager_12kw") as (port, _server):  # real time: a row a second
        rerun = _rerun_on(out, port, stderr=subprocess.DEVNULL)
        try:
            _wait_rerun_rows(out, 2, rerun)
        finally:
            rerun.kill()  # SIGKILL: nothing of the run's own goes
            rerun.wait(timeout=30)
    kept = ["r.previous.csv", "r.previous.meta.json"]
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True))
    stale = lock_path(tmp_path / "r.previous.csv")
    assert stale.exists()  # the killed run's, no live holder
    live = tmp_path / "r.previous2.csv"
    with run_lock(live, "keeping", tmp_path / "elsewhere.csv"):  # this test's process holds it
        after = _hil_client(out)
        assert lock_path(live).exists()
    assert after.returncode == 0, after.stderr
    rows = _rows_of(earlier["r.csv"])
    assert (
        f"kept beside {out} by earlier re-runs that did not complete: r.previous.csv ({rows} "
        "rows, complete); this run leaves them as they are"
    ) in after.stderr, after.stderr
    assert f"it is kept as {tmp_path / 'r.previous3.csv'}" in after.stderr, after.stderr
    assert _files(tmp_path, kept) == dict(zip(kept, earlier.values(), strict=True))
    assert not stale.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv", "r.meta.json", *kept]


def test_an_earlier_run_with_only_a_meta_file_is_said_as_its_files(tmp_path):
    """A stranger's probe: where only the earlier run's meta file was at --out, the run
    said "the earlier run's log is kept as a.previous.meta.json". It now says the
    earlier run's files, as they are no log."""
    out = tmp_path / "a.csv"
    earlier = _earlier_run(out)
    out.unlink()
    rerun = _hil_client(out, "--seed", "7", preexec_fn=_with_file_size_limit(FILE_SIZE_LIMIT))
    assert rerun.returncode == 1, rerun.stderr
    aside = tmp_path / "a.previous.meta.json"
    assert (
        f"{out} holds an earlier run's files without their log: they are kept as {aside}"
    ) in rerun.stderr, rerun.stderr
    assert f"the earlier run's files are kept as {aside} (a run" in rerun.stderr
    assert "log is kept" not in rerun.stderr and "it is kept" not in rerun.stderr
    assert aside.read_bytes() == earlier["a.meta.json"]


def test_a_meta_a_killed_set_aside_left_at_out_outlives_a_completing_run(tmp_path):
    """A re-probe: a re-run killed with -9 between the renames of its set-aside left the
    complete log kept as a.previous.csv and its meta at --out; the next run, completing,
    took the meta for an earlier run's files and deleted it, and the kept 18-h log could
    no longer be analysed without --boiler. Files without their log are kept, and said."""
    out = tmp_path / "a.csv"
    earlier = _earlier_run(out)
    out.rename(tmp_path / "a.previous.csv")  # (what the kill left: the log moved, not its meta)
    rerun = _hil_client(out, "--seed", "7")
    assert rerun.returncode == 0, rerun.stderr
    aside = tmp_path / "a.previous2.meta.json"
    assert f"they are kept as {aside}" in rerun.stderr, rerun.stderr
    assert f"the files without a log that were at {out} are kept as {aside}" in rerun.stderr
    assert aside.read_bytes() == earlier["a.meta.json"]
    assert (tmp_path / "a.previous.csv").read_bytes() == earlier["a.csv"]


#: Run first in a run: a real SIGINT to itself once the meta has its first mark, and a
#: second as the meta of the interrupted run is written (Ctrl-C pressed twice; `timeout`
#: signals the child and its process group).
SIGINT_TWICE = """
import hil_client.cli as cli
_write_meta = cli.write_meta
def _hooked(path, meta):
    if meta.get("interrupted"):
        os.kill(os.getpid(), signal.SIGINT)
    written = _write_meta(path, meta)
    if meta.get("t0_s") is not None and not _hooked.sent:
        _hooked.sent = True
        os.kill(os.getpid(), signal.SIGINT)
    return written
_hooked.sent = False
cli.write_meta = _hooked
"""


def test_a_second_ctrl_c_while_the_interrupted_runs_meta_is_written_waits(tmp_path):
    """A stranger's probe: a run under `timeout -s INT` (which signals the child, then its
    process group) said only "hil-client: interrupted", and its meta file kept no note,
    no `interrupted`: the second signal came while that meta was written."""
    out = tmp_path / "a.csv"
    run = _hooked_run(SIGINT_TWICE, out)
    assert run.returncode == 1, run.stderr
    assert "interrupted; the log keeps the" in run.stderr, run.stderr
    meta = json.loads((tmp_path / "a.meta.json").read_text())
    assert meta["interrupted"] is True and meta["complete"] is False, meta
    assert meta["notes"][-1].startswith("interrupted (Ctrl-C, SIGTERM or SIGHUP) after ")
