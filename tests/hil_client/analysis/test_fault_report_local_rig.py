"""A fault journal is judged against a log a server ran, not one of ``run --rig local``.

A stranger's probe: ``fault-report`` took the log of ``hil-client run --rig local`` (its meta
file says ``"rig": "local"``: the plant stepped in-process, no server) with the fault
journal of a Modbus server's run and reported "faults: 0 detected, 5 missed", exit 0, where
a Modbus log with another server's journal is refused in one line. The log here is a real
local run of the short test method; the journal's lines are as ``serve --fault-log`` writes
them (copied from a real server's journal, its times moved into the short run)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hil_client.cli import main as hil_client_main

SHORT = Path(__file__).resolve().parents[2] / "data" / "short_protocol.yaml"
EPOCH = "7144c4ce"  # the server start of the real journal the lines are copied from


@pytest.fixture(scope="module")
def local_run(tmp_path_factory) -> Path:
    """A real ``run --rig local`` of the short test method (about 1.4 h simulated, 4970
    rows): its log and its meta file with ``"rig": "local"``."""
    out = tmp_path_factory.mktemp("local") / "local.csv"
    argv = ["run", str(SHORT), "--boiler", "windhager_12kw", "--rig", "local", "--quiet"]
    assert hil_client_main([*argv, "--out", str(out)]) == 0
    assert json.loads(out.with_name("local.meta.json").read_text())["rig"] == "local"
    return out


def _journal(path: Path) -> Path:
    """A no_reply of the analyser (unit 2) from 2000 to 2600 s, inside the short run's
    rows, as a server journals it."""
    lines = [
        {"event": "start", "id": 1, "t_sim_s": 2000.0, "t_wall": 1795727502.9011297}
        | {"kind": "no_reply", "unit": 2, "source": "file", "served": {"reply": "none"}}
        | {"at_s": 2000.0, "for_s": 600.0, "epoch_id": EPOCH},
        {"event": "end", "id": 1, "t_sim_s": 2600.0, "t_wall": 1795727504.308646}
        | {"kind": "no_reply", "unit": 2, "source": "file", "served": {"reply": "normal"}}
        | {"reason": "for_s elapsed", "requests": 600, "epoch_id": EPOCH},
    ]
    path.write_text("".join(json.dumps(line) + "\n" for line in lines))
    return path


def _copy_log(local_run: Path, to: Path, meta: dict | None) -> Path:
    """The local run's log under ``to``, with ``meta`` as its meta file (None: none)."""
    to.write_bytes(local_run.read_bytes())
    if meta is not None:
        to.with_name(to.stem + ".meta.json").write_text(json.dumps(meta))
    return to


def test_a_local_runs_log_with_a_servers_journal_is_refused(local_run, tmp_path, capsys):
    journal = _journal(tmp_path / "fj.jsonl")
    out = tmp_path / "report.json"
    argv = ["fault-report", str(local_run), "--journal", str(journal), "--out", str(out)]
    assert hil_client_main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"fj.jsonl: its server (epoch_id {EPOCH}) served none of the rows of " in err
    assert f"{local_run}: its meta file says rig local" in err
    assert not out.exists()


def test_the_same_log_of_another_program_is_still_judged(local_run, tmp_path, capsys):
    """Not over-refused: the same rows without a meta file, or with a meta file that names
    no rig (another acquisition program's), are judged from the log alone, as before: the
    analyser answered throughout, so its silence is missed."""
    journal = _journal(tmp_path / "fj.jsonl")
    for name, meta in (("bare", None), ("lab", {"operator": "jd"})):
        log = _copy_log(local_run, tmp_path / f"{name}.csv", meta)
        out = tmp_path / f"{name}.report.json"
        argv = ["fault-report", str(log), "--journal", str(journal), "--out", str(out)]
        assert hil_client_main(argv) == 0, capsys.readouterr().err
        assert "faults: 0 detected, 1 missed" in capsys.readouterr().out
        assert json.loads(out.read_text())["missed"] == 1
