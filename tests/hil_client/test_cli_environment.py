"""``hil-client`` in the environment a shell may give it: standard streams whose encoding
cannot carry a file name, a standard output closed, a working directory deleted, a
directory that takes no new file, a file name too long (strangers' probes of the
environment the commands run in). Each runs the command as its own process, started as
the console script starts it (:mod:`hil_client.launch`)."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import pytest

from tests.environment_helpers import (
    ODD_NAME,
    ODD_NAME_WRITTEN,
    close_stdout,
    launched,
    read_only_mount,
)

SHORT = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"

#: bound of one short run (about 3 s alone; more on a machine the suite loads)
COMMAND_S = 300


def hil_client(*argv: str, **how: object) -> subprocess.CompletedProcess[bytes]:
    """``hil-client ARGV`` as its own process (:func:`launched`)."""
    return launched("hil_client", *argv, timeout_s=COMMAND_S, **how)  # type: ignore[arg-type]


def short_run(out: Path, *options: str, **how: object) -> subprocess.CompletedProcess[bytes]:
    """``hil-client run`` of the short test protocol on the local rig to ``out``."""
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--out", str(out), *options]
    return hil_client(*argv, **how)  # type: ignore[arg-type]


def _complete(log: Path) -> dict:
    """The meta file of ``log``, checked to say a complete run whose rows are all there."""
    meta = json.loads(log.with_name(log.stem + ".meta.json").read_text())
    assert meta["complete"] is True
    assert len(log.read_text().splitlines()) - 1 >= meta["t4_s"]  # a row a second to t4
    return meta


# the stream's handling of each encoding is rig_emulator's test_cli_streams'; here, a run
# and an analysis through it: the stranger's case (utf-8) and one with lone bytes escaped
@pytest.mark.parametrize("encoding", ["utf-8", "ascii:strict"])
def test_a_log_named_with_a_byte_no_stream_encoding_carries(tmp_path, encoding):
    """A stranger's probe: ``PYTHONIOENCODING=utf-8 hil-client run ... --out $'bad\\xff.csv'``
    wrote the log whole, then ended in a UnicodeEncodeError traceback and exit 1 at its
    "log:" line (``balance`` of that log too; ascii and latin-1 the same). The name is
    written readably, on standard output (the run's and the balance's summaries) and on
    standard error (a warning naming the log), exit 0."""
    codec = encoding.split(":")[0]
    name = ODD_NAME_WRITTEN.get(encoding, ODD_NAME_WRITTEN["utf-8:strict"])
    out = tmp_path / f"{ODD_NAME}.csv"
    run = short_run(Path(out.name), cwd=tmp_path, encoding=encoding)
    assert run.returncode == 0, run.stderr
    assert b"Traceback" not in run.stderr
    assert "log: ".encode(codec) + name + ".csv\n".encode(codec) in run.stdout
    assert "meta: ".encode(codec) + name + ".meta.json\n".encode(codec) in run.stdout
    _complete(out)

    # analysed as the other boiler: a warning on standard error names the log
    argv = ["balance", out.name, "--boiler", "windhager_6kw"]
    balance = hil_client(*argv, cwd=tmp_path, encoding=encoding)
    assert balance.returncode == 0, balance.stderr
    warning = "hil-client: warning: ".encode(codec) + name + ".csv was recorded".encode(codec)
    assert balance.stderr.startswith(warning), balance.stderr
    written = "written: ".encode(codec) + name + ".balance.json\n".encode(codec)
    assert balance.stdout.endswith(written), balance.stdout
    assert (tmp_path / f"{ODD_NAME}.balance.json").is_file()


def test_a_missing_log_named_with_such_a_byte_is_one_line(tmp_path):
    """The error line of bad input (said after the command's streams are given back)
    names the file readably under a strict standard error too: one line, exit 2."""
    proc = hil_client("balance", f"{ODD_NAME}.csv", cwd=tmp_path, encoding="ascii:strict")
    assert proc.returncode == 2
    assert proc.stderr == (
        b"hil-client balance: error: argument log: caf\\xe9-bad\xff.csv: no such file\n"
    )


def test_a_run_to_a_closed_standard_output_writes_its_log_and_fails(tmp_path):
    """A stranger's probe: ``rig-emulator map-doc >&-`` exited 0 with its output lost, and
    so did ``hil-client run``'s summary. The run writes its log and meta whole, then says
    in one line that its summary had nowhere to go, exit 1 (as ``cat >&-``)."""
    out = tmp_path / "log.csv"
    proc = short_run(out, preexec_fn=close_stdout)
    assert proc.returncode == 1, proc.stderr
    *marks, last = proc.stderr.decode().splitlines()  # (the phase marks come first)
    assert last == "hil-client: error: standard output: Bad file descriptor"
    assert all(" simulated, " in mark for mark in marks), marks
    _complete(out)


def test_a_quiet_run_to_a_closed_standard_output_succeeds(tmp_path):
    """``--quiet`` writes nothing on standard output: closed, it is no failure (as
    ``cat /dev/null >&-`` exits 0)."""
    out = tmp_path / "log.csv"
    proc = short_run(out, "--quiet", preexec_fn=close_stdout)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == b""
    _complete(out)


@pytest.mark.parametrize("argv", [["balance"], ["--help"]], ids=lambda argv: argv[0])
def test_balance_and_help_to_a_closed_standard_output_fail(tmp_path, argv):
    """The same probe's other commands: ``balance LOG >&-`` writes its JSON file, and
    fails for its table; ``--help >&-`` fails for its text. One line, exit 1."""
    log = tmp_path / "log.csv"
    assert short_run(log, "--quiet").returncode == 0
    argv = [*argv, str(log)] if argv == ["balance"] else argv
    proc = hil_client(*argv, preexec_fn=close_stdout)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == b"hil-client: error: standard output: Bad file descriptor\n"
    if argv[0] == "balance":
        assert json.loads((tmp_path / "log.balance.json").read_text())


def test_a_relative_out_in_a_deleted_working_directory_is_named_so(tmp_path):
    """A stranger's probe: ``hil-client run ... --out x.csv`` in a working directory
    deleted under it said "hil-client: error: None: No such file or directory". One line
    naming --out says the working directory no longer exists, exit 2."""
    gone = tmp_path / "gone"
    gone.mkdir()
    proc = short_run(Path("x.csv"), "--quiet", cwd=gone, preexec_fn=lambda: os.rmdir(gone))
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1, err
    assert "--out" in err and "the working directory no longer exists" in err, err
    assert "None" not in err


def test_an_absolute_out_in_a_deleted_working_directory_is_written(tmp_path):
    """The working directory gone, an absolute --out still names a log: a complete run."""
    gone = tmp_path / "gone"
    gone.mkdir()
    out = tmp_path / "log.csv"
    proc = short_run(out, "--quiet", cwd=gone, preexec_fn=lambda: os.rmdir(gone))
    assert proc.returncode == 0, proc.stderr
    _complete(out)


@pytest.mark.parametrize("stem_length", [250, 300])
def test_a_log_name_too_long_for_the_log_or_its_meta_is_bad_input(tmp_path, stem_length):
    """A stranger's probe: ``--out <250 a>.csv`` was "cannot write <250 a>.meta.json: File
    name too long; no row was acquired", exit 1, where ``<300 a>.csv`` was exit 2. The
    log's name fits the file system's 255 bytes, its meta file's (10 bytes more) does not:
    bad input either way, one line, exit 2, nothing written."""
    out = tmp_path / ("a" * stem_length + ".csv")
    proc = short_run(out, "--quiet")
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1 and "too long" in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_log_in_a_read_only_directory_is_bad_input(tmp_path):
    """A stranger's probe: a relative ``--out`` in a read-only working directory was
    "cannot write x.csv: Permission denied", exit 1, while an absolute one whose missing
    directory could not be created there was exit 2. Both are a path given that cannot be
    written: one line naming --out, exit 2, before any row."""
    prefix = read_only_mount(tmp_path)
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--quiet"]
    for out, said in (
        ("x.csv", "--out: cannot write 'x.csv'"),
        (str(tmp_path / "sub" / "x.csv"), f"--out: cannot create '{tmp_path / 'sub'}'"),
    ):
        proc = hil_client(*argv, "--out", out, cwd=tmp_path, prefix=prefix)
        assert proc.returncode == 2, proc.stderr
        err = proc.stderr.decode()
        assert err.count("\n") == 1 and said in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_fault_report_that_cannot_be_written_is_refused_before_any_row(tmp_path, serve_process):
    """A re-probe: ``run ... --fault-report <305-byte name>`` (or one in a directory that
    takes no file) was judged after the whole run: its log complete, then exit 2 and no
    report. Judged with --out and its meta, before any row: one line, no log."""
    journal = tmp_path / "j.jsonl"
    journal.touch()  # (the server's journal, begun as it serves)
    srv = serve_process("--lockstep", "--fault-log", str(journal))
    out = tmp_path / "x.csv"
    report = tmp_path / ("r" * 300 + ".json")
    proc = short_run(out, "--quiet", "--rig", f"modbus://127.0.0.1:{srv.port}",
                     "--fault-journal", str(journal),
                     "--fault-report", str(report))  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1 and "--fault-report" in err and "too long" in err, err
    assert not out.exists()


def test_a_command_that_needs_a_working_directory_says_so_where_it_was_deleted(tmp_path):
    """A re-probe: ``validate`` with every path absolute, from a deleted working directory,
    said "give every path absolute" (numba's compiler asks for the working directory, not
    the user's paths). It works, or says in one line to run it from a directory that
    exists (exit 2)."""
    log = tmp_path / "log.csv"
    assert short_run(log, "--quiet").returncode == 0
    gone = tmp_path / "gone"
    gone.mkdir()
    proc = hil_client("validate", "--boiler", "windhager_12kw", "--out", str(tmp_path / "v"),
                      str(log), cwd=gone, preexec_fn=lambda: os.rmdir(gone))  # fmt: skip
    err = proc.stderr.decode()
    if proc.returncode == 0:
        assert (tmp_path / "v").is_dir()
    else:
        assert proc.returncode == 2 and err.count("\n") == 1, err
        assert "run it from a directory that exists" in err and "absolute" not in err, err
