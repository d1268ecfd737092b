"""``hil-client`` as users call it: logs written, bad input refused with exit code 2."""

import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from hil_client.cli import main


@pytest.mark.parametrize("script", ["hil-client", "rig-emulator"])
def test_console_scripts_answer_help(script):
    exe = shutil.which(script) or str(__import__("pathlib").Path(sys.executable).with_name(script))
    result = subprocess.run([exe, "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0
    assert "usage:" in result.stdout


def test_run_writes_log_and_meta(run_log):
    rec = run_log("load_cycle", "windhager_6kw")
    meta = rec.meta
    assert meta["boiler"] == "windhager_6kw" and meta["test"] == "load_cycle"
    assert all(isinstance(meta[f"t{i}_s"], float) for i in range(5))
    assert meta["t0_s"] < meta["t1_s"] < meta["t2_s"] < meta["t3_s"] < meta["t4_s"]
    # every column has a value in every row for a clean local run; the sequence only
    # exists during the test phase
    for name, values in rec.columns.items():
        if name != "sequence":
            assert None not in values, name
    in_test = [s for s, ph in zip(rec["sequence"], rec["phase"], strict=True) if ph == "test"]
    assert None not in in_test and in_test[0] == "peak" and in_test[-1] == "stationary_13"


def test_a_run_with_a_boiler_file_of_ones_own_records_its_parameters(tmp_path, capsys):
    """A stranger's probe: a parameter file of the user's own that keeps a shipped
    boiler's name (moisture 0.15) was recorded in the meta file by that name, and
    ``balance`` without --boiler read the log with the shipped fuel: a direct efficiency of
    75.9 % for 84.0 %, no word. Its parameters now go into the meta file inline (CONTRACT
    section 3), and the balance reads them."""
    import json

    import yaml

    from rig_emulator.boilers import BOILER_DIR

    own = yaml.safe_load((BOILER_DIR / "windhager_12kw.yaml").read_text())
    own["fuel"]["moisture"] = 0.15
    boiler = tmp_path / "moist.yaml"
    boiler.write_text(yaml.safe_dump(own))
    protocol = Path(__file__).parents[1] / "data" / "short_protocol.yaml"  # (1.7 h)
    log = tmp_path / "st.csv"
    argv = ["run", str(protocol), "--boiler", str(boiler), "--rig", "local", "--quiet"]
    assert main([*argv, "--out", str(log)]) == 0
    recorded = json.loads(log.with_name("st.meta.json").read_text())["boiler"]
    assert isinstance(recorded, dict) and recorded["fuel"]["moisture"] == 0.15
    outs = []
    capsys.readouterr()
    for extra in ([], ["--boiler", str(boiler)]):
        out = tmp_path / f"b{len(extra)}.json"
        assert main(["balance", str(log), "--out", str(out), *extra]) == 0
        outs.append(json.loads(out.read_text())["balance"])
        assert "recorded with" not in capsys.readouterr().err
    assert outs[0] == outs[1]
    # the shipped file of that name given: other parameters, said (a re-probe: by the
    # name alone, nothing was)
    assert (
        main(["balance", str(log), "--out", str(tmp_path / "b.json"), "--boiler", "windhager_12kw"])
        == 0
    )
    assert "recorded with the parameters its meta file holds" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run", "load_cycle", "--boiler", "nope"], "unknown boiler 'nope'"),
        (["run", "nope", "--boiler", "windhager_12kw"], "unknown protocol 'nope'"),
        (["run", "load_cycle", "--boiler", "windhager_12kw", "--profile", "x"], "--profile"),
        (["run", "load_cycle", "--boiler", "windhager_12kw", "--rig", "tcp:1"], "--rig"),
        (["bogus"], "invalid choice"),
    ],
)
def test_bad_input_exit_2_one_line_nothing_written(tmp_path, capsys, args, message):
    out = tmp_path / "x.csv"
    code = main([*args, "--out", str(out)] if args[0] == "run" else args)
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_broken_parameter_file_is_refused_before_any_work(tmp_path, capsys):
    bad = tmp_path / "boiler.yaml"
    bad.write_text("name: x\np_nom_kW: 12\n")
    out = tmp_path / "log.csv"
    assert main(["run", "stationary", "--boiler", str(bad), "--out", str(out)]) == 2
    assert "missing required key 'p_max_kW'" in capsys.readouterr().err
    assert not out.exists()


def test_off_a_terminal_each_phase_mark_is_a_line_and_the_meta_has_the_logs_times(tmp_path, capsys):
    """A run in a CI log or docker compose printed nothing until it ended (17 minutes at
    x50); now each phase mark is a line as it comes. The marks in the meta file are times
    of the log (1285.0, not 1285.0000000000364)."""
    import json
    from pathlib import Path

    from hil_client.analysis.logio import read_log

    short = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"
    out = tmp_path / "log.csv"
    assert main(["run", str(short), "--boiler", "windhager_12kw", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert [line.split()[1] for line in err.splitlines()] == ["t0", "t1", "t2", "t3", "t4"]
    meta = json.loads((tmp_path / "log.meta.json").read_text())
    times = set(read_log(out).t.tolist())
    for key in ("t0_s", "t1_s", "t2_s", "t3_s"):
        assert meta[key] in times and meta[key] == round(meta[key], 3)


def test_a_modbus_option_given_to_a_local_run_is_named(tmp_path, capsys):
    """--reply-timeout with --rig local waits for nothing: it was ignored silently, as
    --profile with a Modbus rig was (that one warns too)."""
    from pathlib import Path

    short = Path(__file__).resolve().parents[1] / "data" / "short_protocol.yaml"
    out = tmp_path / "log.csv"
    argv = ["run", str(short), "--boiler", "windhager_12kw", "--quiet", "--out", str(out)]
    assert main([*argv, "--reply-timeout", "0.5"]) == 0
    assert "--reply-timeout apply to a Modbus rig" in capsys.readouterr().err
    # the other wire options too (a stranger's probe: taken and ignored without a word)
    again = [*argv[:-1], str(tmp_path / "again.csv"), "--on-restart", "continue"]
    assert main([*again, "--reconnect-timeout", "5"]) == 0
    err = capsys.readouterr().err
    assert "--reconnect-timeout, --on-restart apply to a Modbus rig, not to --rig local" in err
    fresh = tmp_path / "fresh.csv"  # (a run to an earlier run's --out says it replaces it)
    assert main([*argv[:-1], str(fresh)]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.parametrize("command", ["hil-client", "rig-emulator"])
def test_ctrl_c_while_the_libraries_load_is_one_line(command, how, tmp_path):
    """Ctrl-C in the first second or two (the imports of numpy, scipy, numba)
    gave a traceback from the middle of an import; now one line, as later. Sent at several
    moments: each lands in Python's start, the imports, or the command itself, and none
    may print a traceback."""
    import shutil
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path

    exe = Path(sys.executable).with_name(command)
    if not exe.exists():
        exe = Path(shutil.which(command) or command)
    argv = {
        "hil-client": ["run", "stationary", "--out", str(tmp_path / "x.csv"), "--quiet"],
        # (Ctrl-C inside numba's first compilation lands in an llvmlite ctypes callback,
        # which swallowed it: raised again after it, test_launch's C-callback test)
        "rig-emulator": ["check", "--boiler", "windhager_12kw"],
    }[command]
    if command == "hil-client":
        argv += ["--boiler", "windhager_12kw"]
    for after_s in (0.2, 0.5, 0.9):
        proc = subprocess.Popen(
            [str(exe), *argv],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            # a pytest-xdist worker ignores SIGINT, and its children would too
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        time.sleep(after_s)
        proc.send_signal(how)  # (SIGTERM ended it silently, exit 143: a re-probe)
        _, err = proc.communicate(timeout=60)
        if "init_import_site" in err:  # a machine so loaded the signal came in Python's own
            continue  # start, before any of this project's code ran: not what is tested
        assert "Traceback" not in err, (after_s, err)
        assert proc.returncode in (0, 1, -how), (after_s, proc.returncode, err)
        if command == "hil-client":  # (rig-emulator's short commands end as SIGTERM says)
            assert proc.returncode == 0 or err.count("\n") >= 1, (after_s, "no word", err)


@pytest.mark.parametrize("timeout", ["-1", "nan"])
def test_wait_for_port_refuses_a_timeout_that_is_no_time(timeout, capsys):
    """--timeout -1 waited no time and exited 1, "not reachable" (a stranger's probe)."""
    from hil_client.wait_for_port import main as wait_main

    with pytest.raises(SystemExit) as info:
        wait_main(["127.0.0.1", "1", "--timeout", timeout])
    assert info.value.code == 2 and "--timeout" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["balance", "LOOP"],
        ["calibrate", "LOOP", "--boiler", "windhager_12kw", "--out", "c.yaml"],
        ["validate", "LOOP", "--boiler", "windhager_12kw", "--out", "v"],
        ["diagnose", "--calibration", "LOOP", "--validation", "LOG", "--out", "d"],
    ],
    ids=["balance", "calibrate", "validate", "diagnose"],
)
def test_a_loop_of_links_as_a_log_is_one_line(tmp_path, capsys, monkeypatch, argv):
    """A stranger's probe: a log path that is a loop of symbolic links gave a traceback in
    diagnose (RuntimeError: Symlink loop) and "no such file" elsewhere."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "LOOP").symlink_to("LOOP")
    (tmp_path / "LOG").write_text("time_s\n1\n")
    if argv[0] == "diagnose":
        argv = [*argv, "--boiler", "windhager_12kw"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "a symbolic link that leads to no file" in err, err
