"""What the phases' messages say about a log that begins mid-run.

A stranger's probe: ``hil-client balance v/midtest.csv`` on a log whose rows begin in its
test phase (a phase column present) warned ``midtest.csv begins with the burner firing``,
where every other message names the file as given (``v/midtest.csv``), and its summary said
``phases from the signals`` as if the log had no phase column: the column is passed over,
it holds no t0 or t1 (the log is a real local run of the short test method, its rows from
the middle of its test on)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from hil_client.cli import main as hil_client_main

SHORT = Path(__file__).resolve().parents[2] / "data" / "short_protocol.yaml"
BOILER = "windhager_12kw"


@pytest.fixture(scope="module")
def whole_run(tmp_path_factory) -> tuple[list[list[str]], dict]:
    """A real ``run --rig local`` of the short test method: its rows (header first) and
    its meta file."""
    out = tmp_path_factory.mktemp("whole") / "whole.csv"
    argv = ["run", str(SHORT), "--boiler", BOILER, "--rig", "local", "--quiet"]
    assert hil_client_main([*argv, "--out", str(out)]) == 0
    with out.open(newline="") as f:
        rows = list(csv.reader(f))
    return rows, json.loads(out.with_name("whole.meta.json").read_text())


def test_a_log_begun_mid_test_is_named_as_given_and_its_phases_source_said(
    whole_run, tmp_path, monkeypatch, capsys
):
    rows, meta = whole_run
    header, body = rows[0], rows[1:]
    t, phase = header.index("time_s"), header.index("phase")
    mid_test = (meta["t1_s"] + meta["t2_s"]) / 2  # (no meta file beside the cut log)
    kept = [row for row in body if float(row[t]) > mid_test]
    assert {row[phase] for row in kept} == {"test", "cooling_1", "cooling_2"}
    (tmp_path / "v").mkdir()
    with (tmp_path / "v" / "midtest.csv").open("w", newline="") as f:
        csv.writer(f).writerows([header, *kept])
    monkeypatch.chdir(tmp_path)

    argv = ["balance", "v/midtest.csv", "--boiler", BOILER, "--out", "midtest.balance.json"]
    assert hil_client_main(argv) == 0
    captured = capsys.readouterr()
    assert "hil-client: warning: v/midtest.csv begins with the burner firing" in captured.err
    source = "signals; the phase column begins mid-run, in its test phase: no t0 or t1 in it"
    assert f"energy balance of v/midtest.csv ({BOILER}; phases from the {source})" in captured.out
    phases = json.loads((tmp_path / "midtest.balance.json").read_text())["phases"]
    assert phases["source"] == source
    # the signals' t2 and t3 are the column's: the test's last row and the first cooling's
    assert (phases["t2_s"], phases["t3_s"]) == (meta["t2_s"], meta["t3_s"])


def test_a_log_begun_mid_test_without_a_phase_column_says_signals(whole_run, tmp_path, capsys):
    """Without the column the signals are the phases' only source, said so alone."""
    rows, meta = whole_run
    header = rows[0]
    t, phase = header.index("time_s"), header.index("phase")
    mid_test = (meta["t1_s"] + meta["t2_s"]) / 2
    log = tmp_path / "midtest_nophase.csv"
    with log.open("w", newline="") as f:
        keep = [i for i in range(len(header)) if i != phase]
        cut = [rows[0]] + [row for row in rows[1:] if float(row[t]) > mid_test]
        csv.writer(f).writerows([[row[i] for i in keep] for row in cut])
    out = tmp_path / "out.json"
    assert hil_client_main(["balance", str(log), "--boiler", BOILER, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert f"hil-client: warning: {log} begins with the burner firing" in captured.err
    assert f"energy balance of {log} ({BOILER}; phases from the signals)" in captured.out
