"""``rig-emulator serve``'s start-up, as its own process: the "serving" line comes once every
listener is up, and an output or listener that cannot be had is one line and exit 2 before it.

A stranger's probes: ``serve --http PORT`` with the HTTP port taken logged "serving
windhager_12kw on 127.0.0.1:PORT (lockstep, ...)", then exited 2 ("--http: cannot serve on
...: address already in use"): the serving line is the only readiness signal scripts and the
pytest plugin have, and how ``--port 0`` reports its port. And ``--fault-log`` in a directory
the server's user may not write (run as nobody, the journal under root's directory) was a
warning: the server served a whole session without a journal.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: bound of a server's start-up on a loaded machine (rig_emulator_serve waits 60 s)
START_S = 60.0
SERVING = re.compile(r"rig-emulator: serving \S+ on 127\.0\.0\.1:(\d+) ")


@dataclass
class Started:
    """A ``serve`` process and its standard error up to its "serving" line (all of it if
    it exited first)."""

    process: subprocess.Popen
    lines: list[str] = field(default_factory=list)

    @property
    def serving(self) -> re.Match[str] | None:
        return SERVING.search(self.lines[-1]) if self.lines else None


@contextlib.contextmanager
def _started(*options: str, user: Sequence[str] = ()) -> Iterator[Started]:
    """``serve --boiler windhager_12kw OPTIONS`` (run through ``user``, e.g. setpriv, as a
    service account without a home), read until it says "serving" or exits; stopped
    (SIGTERM) when the block ends."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if user:  # (numba's cache of this process's user is no other user's to write)
        env.pop("NUMBA_CACHE_DIR", None)
        env["HOME"] = "/nonexistent"
    process = subprocess.Popen(
        [*user, sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw",
         *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )  # fmt: skip
    watchdog = threading.Timer(START_S, process.kill)  # (neither line nor exit: a failure)
    watchdog.start()
    started = Started(process)
    try:
        assert process.stderr is not None
        for line in process.stderr:
            started.lines.append(line.rstrip("\n"))
            if SERVING.search(line):
                break
        yield started
    finally:
        watchdog.cancel()
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
        process.communicate(timeout=START_S)


def _refusal(*options: str, user: Sequence[str] = ()) -> tuple[int | None, list[str], str]:
    """The exit code (None: it said "serving"), standard error and standard output of a
    ``serve`` expected to refuse to start."""
    with _started(*options, user=user) as started:
        if started.serving:
            return None, started.lines, ""
        code = started.process.wait(timeout=START_S)
        assert started.process.stdout is not None
        return code, started.lines, started.process.stdout.read()


@pytest.fixture(scope="module")
def certs(tmp_path_factory) -> Path:
    from rig_emulator.certs import make_lab_certificates

    out = tmp_path_factory.mktemp("certs")
    make_lab_certificates(out)
    return out


@pytest.fixture
def busy_port() -> Iterator[int]:
    """A port of 127.0.0.1 another process's socket listens on."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        yield taken.getsockname()[1]


def _tls(certs: Path) -> list[str]:
    return ["--tls-cert", str(certs / "server.pem"), "--tls-key", str(certs / "server.key"),
            "--tls-ca", str(certs / "ca.pem")]  # fmt: skip


NOT_A_TERMINAL = "not_a_terminal"

#: (options, the one line's text): BUSY is the busy port, TLS the certificate options
LISTENERS_THAT_CANNOT_START = {
    "http": (["--port", "0", "--http", "BUSY"], "--http: cannot serve on 127.0.0.1:BUSY: "),
    "http after tls, tcp and serial": (
        ["TLS", "--port", "0", "--tcp-port", "0", "--serial", "pty", "--http", "BUSY"],
        "--http: cannot serve on 127.0.0.1:BUSY: ",
    ),
    "tcp-port": (
        ["TLS", "--port", "0", "--tcp-port", "BUSY"],
        "--tcp-port: cannot serve plain TCP on 127.0.0.1:BUSY: ",
    ),
    "tls port": (["TLS", "--port", "BUSY"], "cannot listen on 127.0.0.1:BUSY: "),
    "serial path": (
        ["--port", "0", "--serial", "/nonexistent/tty"],
        "--serial /nonexistent/tty: No such file or directory",
    ),
    "serial not a terminal": (
        ["--port", "0", "--serial", NOT_A_TERMINAL],
        "is not a terminal (a serial line or pty)",
    ),
}


@pytest.mark.parametrize("case", list(LISTENERS_THAT_CANNOT_START))
def test_a_listener_that_cannot_start_is_one_line_and_no_serving_line(
    case, certs, busy_port, tmp_path
):
    """A stranger's probe: ``--http`` on a busy port logged "serving ... on
    127.0.0.1:PORT", then exited 2. Every listener (Modbus TCP, TLS, plain TCP beside it,
    the serial line, HTTP) is up before that line; one that cannot start is the one line
    of an exit 2, with no line before it announcing another (the plain TCP port, the TLS
    port, ``serial: /dev/pts/N`` on stdout, which a client of the pty waits for)."""
    options, said = LISTENERS_THAT_CANNOT_START[case]
    not_a_terminal = tmp_path / "plain_file"
    not_a_terminal.write_text("")
    given = {"BUSY": str(busy_port), NOT_A_TERMINAL: str(not_a_terminal)}
    expanded = [o for option in options for o in (_tls(certs) if option == "TLS" else [option])]
    code, lines, stdout = _refusal("--lockstep", *(given.get(o, o) for o in expanded))
    assert code == 2, lines
    assert len(lines) == 1, lines
    assert lines[0].startswith("rig-emulator: error: "), lines
    assert said.replace("BUSY", str(busy_port)) in lines[0], lines
    assert stdout == ""


def test_when_serving_is_said_every_listener_answers(certs):
    """The "serving" line is the last of the start-up's announcements: once a script reads
    it, the TLS port it names, the plain TCP port, the dashboard (``--http 0``: the port it
    chose is said before) and the pty (its path on stdout) all take a connection at once,
    without a retry."""
    options = ["--lockstep", "--port", "0", "--tcp-port", "0", "--serial", "pty", "--http", "0"]
    with _started(*_tls(certs), *options) as started:
        assert started.serving, started.lines
        text = "\n".join(started.lines)
        tls_port = int(started.serving.group(1))
        plain_port = int(re.search(r"plain Modbus TCP also on 127\.0\.0\.1:(\d+)", text)[1])
        http_port = int(re.search(r"dashboard on http://127\.0\.0\.1:(\d+)/", text)[1])
        for port in (tls_port, plain_port, http_port):
            socket.create_connection(("127.0.0.1", port), timeout=5).close()
        assert started.process.stdout is not None
        line = started.process.stdout.readline()
        assert line.startswith("serial: /dev/pts/"), line
        os.close(os.open(line.split(": ", 1)[1].strip(), os.O_RDWR | os.O_NOCTTY))


NOBODY = 65534  # the unprivileged user of Debian and most Linux systems


@dataclass
class JournalCase:
    """A journal path the server's user cannot open for writing, made in a folder of the
    test's by ``make(folder, as_root)``, and what the refusal's line says of it."""

    make: Callable[[Path, bool], Path]
    said: str


def _new_in_a_folder_not_its_own(folder: Path, as_root: bool) -> Path:
    """The stranger's case: root's directory, the server run as nobody."""
    if not as_root:
        folder.chmod(0o555)
    return folder / "j.jsonl"


def _earlier_journal_in_a_folder_not_its_own(folder: Path, as_root: bool) -> Path:
    """A journal of an earlier run the server's user may write, which it cannot set aside
    (a rename in the directory): it opened, and every line of the new one was lost."""
    journal = folder / "j.jsonl"
    journal.write_text('{"event": "start", "epoch_id": "0000abcd"}\n')
    if as_root:
        os.chown(journal, NOBODY, NOBODY)
    else:
        folder.chmod(0o555)
    return journal


def _a_file_it_may_not_write(folder: Path, as_root: bool) -> Path:
    """An empty file (nothing to set aside) in a directory it may write."""
    journal = folder / "j.jsonl"
    journal.write_text("")
    journal.chmod(0o444)
    if as_root:
        os.chown(folder, NOBODY, NOBODY)
    return journal


JOURNALS = {
    "new, folder not its own": JournalCase(_new_in_a_folder_not_its_own, ""),
    "earlier journal, folder not its own": JournalCase(
        _earlier_journal_in_a_folder_not_its_own, "cannot be set aside"
    ),
    "a file it may not write": JournalCase(_a_file_it_may_not_write, "Permission denied"),
}


@pytest.fixture
def unprivileged() -> tuple[list[str], bool]:
    """How to run the server as a user file permissions hold (root passes them all): as
    nobody through setpriv when the tests run as root, else as the tests' own user."""
    if os.geteuid() != 0:
        return [], False
    setpriv = shutil.which("setpriv")
    if setpriv is None:
        pytest.skip("running as root without setpriv: no user the permissions hold")
    return [setpriv, f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups"], True


@pytest.mark.skipif(sys.platform != "linux", reason="setpriv and the permissions are Linux's")
@pytest.mark.parametrize("case", list(JOURNALS))
def test_a_fault_log_that_cannot_be_opened_is_refused_before_any_port(case, unprivileged):
    """A stranger's probe: run as nobody with ``--fault-log`` in root's directory, serve
    said "serving", then "fault journal .../j.jsonl: cannot write (Permission denied)", and
    served on without a journal. Now, as for a FIFO nobody reads: one line naming it, exit
    2, before any port opens, and the path's directory as it was (an earlier journal kept
    as it is, no file made)."""
    user, as_root = unprivileged
    # (a directory of the tests' tmp_path lies under one only root may enter)
    folder = Path(tempfile.mkdtemp(prefix="rig_journal_", dir="/tmp" if as_root else None))
    try:
        folder.chmod(0o755)
        journal = JOURNALS[case].make(folder, as_root)
        before = {p.name: p.read_bytes() for p in folder.iterdir()}
        code, lines, _ = _refusal("--lockstep", "--port", "0", "--fault-log", str(journal),
                                  user=user)  # fmt: skip
        assert code == 2, lines
        assert len(lines) == 1, lines
        assert f"rig-emulator: error: --fault-log: cannot write '{journal}'" in lines[0], lines
        assert JOURNALS[case].said in lines[0], lines
        assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    finally:
        folder.chmod(0o755)
        shutil.rmtree(folder)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full on this system")
def test_a_fault_log_that_opens_but_cannot_be_written_still_serves():
    """``/dev/full`` opens as any device: it is accepted at the start (its lost lines are
    said, and exit 1, after the stop: test_serve_journal_lost.py)."""
    with _started("--lockstep", "--port", "0", "--fault-log", "/dev/full") as started:
        assert started.serving, started.lines


def test_a_fault_log_to_a_pipe_still_serves():
    """A re-probe: ``--fault-log /dev/stdout`` with standard output a pipe (docker's logs, a
    shell's ``>(...)``) served before the start-up check, then was refused as "No such file
    or directory": the check followed the link to the pipe's /proc name and tried to
    create it. A pipe is opened as it is; its lines come through."""
    with _started("--lockstep", "--port", "0", "--fault-log", "/dev/stdout") as started:
        assert started.serving, started.lines


@pytest.mark.skipif(sys.platform != "linux", reason="setpriv and the permissions are Linux's")
def test_a_read_only_earlier_journal_is_set_aside_as_before(unprivileged):
    """A re-probe: a non-empty earlier journal the server's user may read but not write, in
    a directory it may write, was set aside before the start-up check and then refused
    ("Permission denied"): the journal renames it and writes a new file, it never writes
    into it. It is kept, and the server serves."""
    user, as_root = unprivileged
    folder = Path(tempfile.mkdtemp(prefix="rig_journal_", dir="/tmp" if as_root else None))
    try:
        folder.chmod(0o777 if as_root else 0o755)
        journal = folder / "j.jsonl"
        journal.write_text('{"event": "start", "epoch_id": "0000abcd"}\n')
        journal.chmod(0o444)  # (root's, read-only, when the server runs as nobody)
        with _started("--lockstep", "--port", "0", "--fault-log", str(journal),
                      user=user) as started:  # fmt: skip
            assert started.serving, started.lines
        # (set aside as the journal begins, right after "serving"; the server stopped since)
        assert (folder / "j.0000abcd.jsonl").read_text().startswith('{"event": "start"')
    finally:
        folder.chmod(0o755)
        shutil.rmtree(folder)


def test_a_fault_log_to_standard_output_appended_to_a_file_is_added_to(tmp_path):
    """A re-probe: ``--fault-log /dev/stdout`` with standard output appended to a file
    that holds lines (``>> out.txt``) was taken for an earlier journal: the link was set
    aside (as root, /dev/stdout itself renamed) and a new file written in its place, the
    stream never reached. The stream is written to as it is, after what it holds. (The
    test names standard output through a link of its own, to /proc/self/fd/1 as
    /dev/stdout is: a build with the defect, run as root, renamed the machine's
    /dev/stdout.)"""
    stdout_link = tmp_path / "stdout"
    stdout_link.symlink_to("/proc/self/fd/1")
    out = tmp_path / "out.txt"
    out.write_text("earlier line\n")
    faults = tmp_path / "faults.yaml"  # a fault a second in: its start and end journalled
    faults.write_text("faults:\n  - {kind: spike, signal: flue_gas_O2_pct, value: 25, at_s: 1}\n")
    with out.open("a") as stdout:
        server = subprocess.Popen(
            [sys.executable, "-m", "rig_emulator.cli", "serve", "--boiler", "windhager_12kw",
             "--speed", "100", "--port", "0", "--faults", str(faults),
             "--fault-log", str(stdout_link)],
            stdout=stdout, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and out.read_text().count("\n") < 2:
            time.sleep(0.1)
    finally:
        server.send_signal(signal.SIGTERM)
        _, err = server.communicate(timeout=30)
    lines = out.read_text().splitlines()
    assert lines[0] == "earlier line" and len(lines) >= 2, (lines, err)
    assert json.loads(lines[1])["kind"] == "spike", lines
    assert "kept as" not in err, err
