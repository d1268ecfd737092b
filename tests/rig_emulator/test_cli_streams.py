"""``rig-emulator`` in the environment a shell may give it: standard streams whose encoding
cannot carry a file name, a standard output closed, a working directory deleted, a
directory that takes no new file, a file name too long (strangers' probes of the
environment the commands run in). Each runs the command as its own process, started as
the console script starts it (:mod:`rig_emulator.launch`)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hil_client.wait_for_port import free_port
from tests.environment_helpers import (
    ODD_NAME,
    ODD_NAME_WRITTEN,
    close_stdout,
    launched,
    read_only_mount,
)

#: bound of one command (a second to load, more on a machine the suite loads)
COMMAND_S = 120


def rig_emulator(*argv: str, **how: object) -> subprocess.CompletedProcess[bytes]:
    """``rig-emulator ARGV`` as its own process (:func:`launched`)."""
    return launched("rig_emulator", *argv, timeout_s=COMMAND_S, **how)  # type: ignore[arg-type]


@pytest.mark.parametrize("encoding", sorted(ODD_NAME_WRITTEN))
def test_a_path_no_stream_encoding_carries_is_written_readably(tmp_path, encoding):
    """A stranger's probe: a file name with a byte that is no UTF-8 under
    ``PYTHONIOENCODING=utf-8`` (ascii, latin-1 too) ended in a UnicodeEncodeError traceback
    and exit 1 after the files were written, the rest of the line lost. The name is written
    readably, on standard output (certs' "written:" lines) and on standard error (an
    error naming the file), whatever the encoding."""
    certs = rig_emulator("certs", "--out", str(tmp_path / ODD_NAME), encoding=encoding)
    assert certs.returncode == 0, certs.stderr
    name = ODD_NAME_WRITTEN[encoding]
    newline = "\n".encode(encoding.split(":")[0])
    lines = certs.stdout.split(newline)
    assert len(lines) == 7 and lines[-1] == b""  # six key pairs, each line whole
    assert all(name + "/".encode(encoding.split(":")[0]) in line for line in lines[:-1])
    assert (tmp_path / ODD_NAME / "ca.pem").is_file()

    broken = tmp_path / f"{ODD_NAME}.yaml"
    broken.write_text("name: [\n")
    check = rig_emulator("check", "--boiler", str(broken), encoding=encoding)
    assert check.returncode == 2
    assert check.stderr.count(newline) == 1, check.stderr  # one line, no traceback
    assert name + ".yaml".encode(encoding.split(":")[0]) in check.stderr


def test_a_character_the_encoding_lacks_on_standard_output_is_escaped(tmp_path):
    """``check`` prints a boiler's name, here one with 'é', under an ASCII standard output:
    escaped, not a traceback (the same probe's other case)."""
    boiler = Path(__file__).resolve().parents[2] / "rig_emulator" / "boilers"
    text = (boiler / "windhager_12kw.yaml").read_text(encoding="utf-8")
    renamed = tmp_path / "b.yaml"
    renamed.write_text(text.replace("name: windhager_12kw", "name: kessel_\u00e9"), "utf-8")
    check = rig_emulator("check", "--boiler", str(renamed), encoding="ascii:strict")
    assert check.returncode == 0, check.stderr
    assert b"name: kessel_\\xe9\n" in check.stdout


@pytest.mark.parametrize(
    "argv",
    [
        ["map-doc"],
        ["steady", "--boiler", "windhager_12kw"],
        ["check", "--boiler", "windhager_12kw"],
        ["--help"],
        ["map-doc", "--help"],
    ],
    ids=lambda argv: " ".join(argv),
)
def test_output_to_a_closed_standard_output_is_a_failure(argv):
    """A stranger's probe: ``rig-emulator map-doc >&-`` exited 0 with the whole reference
    lost (``steady``, ``check``, ``--help`` too), while ``> /dev/full`` said so and
    exited 1. A closed standard output is a failure as ``cat >&-`` has it: one line on
    standard error, exit 1."""
    proc = rig_emulator(*argv, preexec_fn=close_stdout)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == b"rig-emulator: error: standard output: Bad file descriptor\n"


def test_a_closed_standard_output_without_the_launcher_is_a_failure_too():
    """``python -m rig_emulator.cli`` started without descriptor 1 has ``sys.stdout`` None
    (no launcher opened /dev/null for it): the same line and exit 1, no AttributeError."""
    proc = subprocess.run(
        [sys.executable, "-m", "rig_emulator.cli", "map-doc"],
        preexec_fn=close_stdout, capture_output=True, timeout=COMMAND_S,
    )  # fmt: skip
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == b"rig-emulator: error: standard output: Bad file descriptor\n"


def test_a_command_that_writes_a_file_and_nothing_on_standard_output_does_not_fail(tmp_path):
    """Only output written to the closed standard output fails: ``map-doc --out FILE >&-``
    writes its file and exits 0, as ``cat /dev/null >&-`` does."""
    out = tmp_path / "map.md"
    proc = rig_emulator("map-doc", "--out", str(out), preexec_fn=close_stdout)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text().startswith("# Register map")


@pytest.mark.parametrize(
    "argv, option",
    [
        (["map-doc", "--out", "m.md"], "--out"),
        (
            ["serve", "--boiler", "windhager_12kw", "--lockstep", "--fault-log", "j.jsonl"],
            "--fault-log",
        ),
    ],
    ids=["map-doc", "serve"],
)
def test_a_relative_output_in_a_deleted_working_directory_is_named_so(tmp_path, argv, option):
    """A stranger's probe: in a working directory deleted under it, ``map-doc --out m.md``
    and ``serve --fault-log j.jsonl`` said "'m.md' is a loop of symbolic links". One line
    naming the option says the working directory no longer exists, exit 2, before any
    port is opened."""
    gone = tmp_path / "gone"
    gone.mkdir()
    argv = [*argv, "--port", str(free_port())] if argv[0] == "serve" else argv
    proc = rig_emulator(*argv, cwd=gone, preexec_fn=lambda: os.rmdir(gone))
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1, err
    assert option in err and "the working directory no longer exists" in err, err
    assert "symbolic links" not in err


def test_an_absolute_output_in_a_deleted_working_directory_is_written(tmp_path):
    """The working directory gone, an absolute path still names a file: written, exit 0."""
    gone = tmp_path / "gone"
    gone.mkdir()
    out = tmp_path / "map.md"
    proc = rig_emulator("map-doc", "--out", str(out), cwd=gone, preexec_fn=lambda: os.rmdir(gone))
    assert proc.returncode == 0, proc.stderr
    assert out.is_file()


def test_an_output_name_too_long_is_bad_input(tmp_path):
    """The file system's limit on a name (255 bytes on Linux file systems) exceeded by
    ``--out``: one line naming the option, exit 2, nothing written."""
    out = tmp_path / ("a" * 300 + ".md")
    proc = rig_emulator("map-doc", "--out", str(out))
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1 and "--out:" in err and "too long" in err, err
    assert list(tmp_path.iterdir()) == []


def test_an_output_in_a_read_only_directory_is_bad_input(tmp_path):
    """A stranger's probe: ``--out`` in a read-only working directory was "cannot write
    x.csv: Permission denied" after the work, exit 1, while a missing directory that
    could not be created there was exit 2. A path given that cannot be written is bad
    input: one line naming the option, exit 2."""
    prefix = read_only_mount(tmp_path)
    proc = rig_emulator("map-doc", "--out", "m.md", cwd=tmp_path, prefix=prefix)
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1, err
    assert "--out: cannot write 'm.md'" in err and "read-only file system" in err, err
    assert list(tmp_path.iterdir()) == []
