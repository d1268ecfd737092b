"""``make demo`` run twice: at once on one out_dir, and after one interrupted. Real demo
processes (``python -m hil_client.demo``, each with its own ``rig-emulator serve``) on the
short protocol."""

from __future__ import annotations

import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHORT = str(REPO / "tests" / "data" / "short_protocol.yaml")
#: A short demo takes 10 s on a quiet 2-core machine; bounds are several times that.
DEMO_TIMEOUT_S = 180


class _Demo:
    """A demo process on ``out_dir``; its stdout and stderr lines are read as they come."""

    def __init__(self, out_dir: Path) -> None:
        self.process = subprocess.Popen(
            [sys.executable, "-m", "hil_client.demo", str(out_dir), "--protocol", SHORT],
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.lines: queue.Queue[str] = queue.Queue()
        self.text: list[str] = []
        self.readers = [
            threading.Thread(target=self._read, args=(stream,), daemon=True)
            for stream in (self.process.stdout, self.process.stderr)
        ]
        for reader in self.readers:
            reader.start()

    def _read(self, stream) -> None:
        for line in stream:
            self.lines.put(line)

    def wait_for(self, pattern: str) -> re.Match:
        """The first line matching ``pattern``, waiting at most :data:`DEMO_TIMEOUT_S`."""
        while True:
            try:
                line = self.lines.get(timeout=DEMO_TIMEOUT_S)
            except queue.Empty:
                self.process.kill()
                pytest.fail(f"no line matching {pattern!r}: {''.join(self.text)}")
            self.text.append(line)
            found = re.search(pattern, line)
            if found:
                return found

    def finish(self) -> tuple[int, str]:
        """Its exit code and everything it printed."""
        code = self.process.wait(timeout=DEMO_TIMEOUT_S)
        for reader in self.readers:  # (the pipes end with the process)
            reader.join(timeout=10)
        while not self.lines.empty():
            self.text.append(self.lines.get())
        return code, "".join(self.text)


def test_a_second_demo_on_the_same_out_dir_changes_nothing(tmp_path):
    """A stranger's probe: two ``make demo`` 4 s apart in one clone; the second was
    refused, but it had started its own server, whose log truncated and rewrote the first
    run's server.log (the other server's lines, NUL bytes, then the first's last lines;
    report.md named one port, the log beside it another). The second is now refused
    before it starts a server or opens a file."""
    first = _Demo(tmp_path)
    port = first.wait_for(r"started on 127\.0\.0\.1:(\d+)").group(1)
    second = _Demo(tmp_path)
    code, said = second.finish()
    assert code == 2 and "is being written by another run" in said, said
    assert "started on" not in said and "Traceback" not in said
    code, said = first.finish()
    assert code == 0, said
    server_log = (tmp_path / "server.log").read_bytes()
    assert b"\0" not in server_log
    served = set(re.findall(rb"serving \S+ on 127\.0\.0\.1:(\d+)", server_log))
    assert served == {port.encode()}, server_log[:300]
    assert f"modbus://127.0.0.1:{port}`" in (tmp_path / "report.md").read_text()


@pytest.fixture(scope="module")
def complete_demo(tmp_path_factory) -> tuple[Path, str]:
    """One demo run to completion (its out_dir and everything it printed), shared by the
    tests that read it or copy it: each demo costs about 10 s of CPU."""
    out = tmp_path_factory.mktemp("complete_demo")
    code, said = _Demo(out).finish()
    assert code == 0, said
    return out, said


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_demo_leaves_the_complete_one_whole(complete_demo, tmp_path, signum):
    """A stranger's probe: a demo interrupted after a complete one left out/demo mixed
    (report.md and the figure of the complete run beside the interrupted run's log and
    server.log), the complete log set aside as NAME.previousN.csv, one more copy per
    interrupted demo. Now the complete demo stays whole, and the interrupted one is kept
    in incomplete/, which holds the last one only."""
    out = tmp_path / "demo"
    shutil.copytree(complete_demo[0], out)
    complete = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert {"short_protocol.csv", "report.md", "server.log"} <= set(complete)
    for attempt in range(2):
        demo = _Demo(out)
        demo.wait_for(r"hil-client: t0 at")  # rows are being written
        os.kill(demo.process.pid, signum)
        code, said = demo.finish()
        assert code != 0 and "Traceback" not in said, said
        assert f"kept in {out / 'incomplete'}/" in said, said
        now = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        assert now == complete, attempt  # nothing replaced, nothing set aside beside it
        kept = sorted(p.name for p in (out / "incomplete").iterdir())
        assert "short_protocol.csv" in kept and "server.log" in kept, kept
        rows = (out / "incomplete" / "short_protocol.csv").read_text().count("\n")
        assert 1 < rows < complete["short_protocol.csv"].count(b"\n")
    assert sorted(p.name for p in out.iterdir() if p.is_dir()) == ["incomplete"]


def test_the_demo_says_what_each_fuel_figure_is(complete_demo):
    """A stranger's probe: the demo's summary gave the test phase's fuel as 7.44 kg and
    report.md 7.47 kg, both called fuel. The summary's is the balance's loss, the report's
    the fuel as received (the ash left in the boiler added back): each now says so."""
    out, said = complete_demo
    note = "'fuel kg (a.r.)' is the fuel as received, that loss with the ash"
    assert note in said and note in (out / "report.md").read_text()
