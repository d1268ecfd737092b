"""The gap diagnosis: a small blind benchmark, one case end to end over Modbus, a real lab's
CSV without phase columns or meta files, bad input."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.analysis.candidates.ignition import PRE_FEED_MIN_S
from hil_client.analysis.diagnose import NORMAL_CHARGE_MAX_S
from hil_client.analysis.gap_benchmark import ANSWERS, _independent_logs, run_benchmark
from hil_client.cli import main
from hil_client.protocol.definition import DEFINITION_DIR
from hil_client.reality9 import draw_background
from rig_emulator.boilers import BOILER_DIR
from rig_emulator.instruments.profile import PROFILE_DIR

#: The small benchmark (six cases, each two emulated tests and a diagnosis) takes one to
#: three minutes on two cores; on a shared, loaded machine it can pass the suite's 300-s
#: hang guard without hanging.
pytestmark = pytest.mark.timeout(1200)


@pytest.fixture(scope="module")
def small_benchmark(tmp_path_factory):
    """Six blind cases on the emulator's own plant, one per answer."""
    out = tmp_path_factory.mktemp("gap")
    scores = run_benchmark(6, seed=2, out=out, workers=2, reality="emulator")
    return out, scores


def _diagnose(calibration, validation, boiler, out) -> int:
    """Exit code of `hil-client diagnose` on two logs."""
    return main(
        [
            "diagnose",
            "--calibration",
            str(calibration),
            "--validation",
            str(validation),
            "--boiler",
            str(boiler),
            "--out",
            str(out),
        ]
    )


def test_small_benchmark_is_blind_and_scored(small_benchmark):
    out, scores = small_benchmark
    truth = json.loads((out / "sealed" / "truth.json").read_text())
    assert sorted(c["effect"] for c in truth) == sorted(ANSWERS)  # one case per answer
    for case in (out / "cases").iterdir():
        names = {p.name for p in case.rglob("*")}
        assert not any(n.endswith(".meta.json") for n in names)  # nothing names the profile
        assert "stationary.csv" in names and "diagnosis.json" in names
        header = (case / "stationary.csv").read_text().split("\n", 1)[0].split(",")
        assert "phase" not in header and "sequence" not in header
    assert sum(sum(row.values()) for row in scores["confusion"].values()) == 6
    on_disk = json.loads((out / "scores.json").read_text())
    assert on_disk["accuracy"] == scores["accuracy"]
    assert sum(row["answers"] for row in on_disk["reliability"]) == 6
    report = (out / "report.md").read_text()
    assert "Reliability of the confidence" in report and (out / "benchmark.png").exists()
    # each case's report says where its phases came from: the signals (no phase column)
    case_report = next((out / "cases").iterdir()) / "diagnosis" / "report.md"
    assert "Phases from the signals (calibration log) and the signals" in case_report.read_text()
    # the target is >= 90 % on 48 cases (`hil-client gap-benchmark --reality emulator`); one
    # miss in six is allowed here, and a right effect always shrinks the held-out gap
    assert round((1.0 - scores["accuracy"]) * 6) <= 1
    assert scores["negative_shrinks_on_right_effect"] == 0
    # each candidate says which test stopped it: named means both its evidence and its mark
    for case in (out / "cases").iterdir():
        for c in json.loads((case / "diagnosis" / "diagnosis.json").read_text())["candidates"]:
            assert isinstance(c["evidence_named"], bool) and isinstance(c["mark_named"], bool)
            assert not c["named"] or (c["evidence_named"] and c["mark_named"])
    missed = sum(sum(row.values()) for row in scores["misses"].values())
    assert missed == round((1.0 - scores["accuracy"]) * 6) and "Why the misses" in report


def test_the_floor_study_re_decides_every_case_as_the_diagnosis_did(small_benchmark, capsys):
    """bench/gap_floors.py re-decides the cases from diagnosis.json alone: with the floors
    as they are it must give every case the diagnosis's own answer, else the file does not
    carry what the decision used; a directory that is no benchmark's is one line, exit 2."""
    path = Path(__file__).parents[3] / "bench" / "gap_floors.py"
    spec = importlib.util.spec_from_file_location("gap_floors", path)
    gap_floors = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gap_floors)
    out, _ = small_benchmark
    assert gap_floors.main([str(out)]) == 0
    assert "re-decided as diagnosed: 6 of 6" in capsys.readouterr().out
    assert gap_floors.main([str(out / "cases")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_an_ignition_delay_as_short_as_a_normal_charge_is_caveated(small_benchmark, capsys):
    """On every case: caveats exactly where the answer is an ignition delay within a normal
    start-up's charge, and then a confidence of at most 0.5; the command line prints them."""
    out, _ = small_benchmark
    caveated = []
    for case in sorted((out / "cases").iterdir()):
        diagnosis = json.loads((case / "diagnosis" / "diagnosis.json").read_text())
        ignition = next(c for c in diagnosis["candidates"] if c["effect"] == "ignition_delay")
        expected = (
            diagnosis["effect"] == "ignition_delay"
            and ignition["params"]["delay_s"] <= NORMAL_CHARGE_MAX_S
        )
        assert bool(diagnosis["caveats"]) == expected
        if expected:
            assert diagnosis["confidence"] <= 0.5
            caveated.append(case)
    # the emulator's ignition delays (45-180 s) all lie within a normal charge
    assert caveated, "the small benchmark's ignition case was not answered as one"
    case = caveated[0]
    truth = {c["case"]: c for c in json.loads((out / "sealed" / "truth.json").read_text())}
    cal, val = truth[int(case.name.split("_")[1])]["pair"]
    capsys.readouterr()
    assert (
        _diagnose(case / f"{cal}.csv", case / f"{val}.csv", case / "boiler.yaml", case / "again")
        == 0
    )
    assert "caveat: The fuel fed before the flame" in capsys.readouterr().out


def test_a_documented_ignition_charge_is_not_read_as_an_ignition_delay(tmp_path, capsys):
    """A `none` case of the ninth independent plant (the 6-kW boiler, its benchmark seed
    307830): its burner drops an ignition charge on the grate and lights it minutes later,
    a normal start-up Type 869 lacks. Without the charge the diagnosis names an ignition
    delay and says it may be the burner's normal charge; given the charge the plant's
    burner documents (its own figure, drawn from the same seed), only the feed beyond it
    is read, under the floor, and no ignition delay is named."""
    truth = {"plant": "hil_client.reality9", "boiler": "windhager_6kw", "seed": 307830}
    truth |= {"effect": "none", "form": None, "strength": 0.0}
    logs = _independent_logs(truth, tmp_path)
    boiler = yaml.safe_load((tmp_path / "boiler.yaml").read_text())
    charge_kg = draw_background(np.random.default_rng(truth["seed"]), boiler)["charge_kg"]
    argv = ["diagnose", "--calibration", str(logs["stationary"]), "--validation"]
    argv += [str(logs["load_cycle"]), "--boiler", str(tmp_path / "boiler.yaml")]

    assert main([*argv, "--out", str(tmp_path / "plain")]) == 0
    plain = json.loads((tmp_path / "plain" / "diagnosis.json").read_text())
    assert plain["effect"] == "ignition_delay" and plain["caveats"]
    assert "caveat:" in capsys.readouterr().out

    out = tmp_path / "documented"
    assert main([*argv, "--out", str(out), "--ignition-charge-kg", f"{charge_kg:.4f}"]) == 0
    documented = json.loads((out / "diagnosis.json").read_text())
    assert documented["ignition_charge_kg"] == pytest.approx(charge_kg, abs=1e-4)
    ignition = next(c for c in documented["candidates"] if c["effect"] == "ignition_delay")
    assert ignition["params"]["delay_s"] < PRE_FEED_MIN_S and not ignition["named"]
    assert documented["effect"] != "ignition_delay" and not documented["caveats"]
    assert "documented ignition charge" in (out / "report.md").read_text()
    assert "caveat:" not in capsys.readouterr().out


def test_the_charge_study_rediagnoses_a_benchmark_with_each_burners_charge(tmp_path, capsys):
    """bench/gap_charge.py on a one-case run of the ninth plant (an effect): the case
    re-diagnosed with its burner's own charge, both scores printed; a directory that is no
    benchmark of such a plant is one line, exit 2. (One case: the study does the same for
    each, and each costs two simulated tests and two diagnoses.)"""
    path = Path(__file__).parents[3] / "bench" / "gap_charge.py"
    spec = importlib.util.spec_from_file_location("gap_charge", path)
    gap_charge = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gap_charge)
    out = tmp_path / "gap"
    run_benchmark(1, seed=5, out=out, workers=1, reality="independent",
                  plants=["hil_client.reality9"])  # fmt: skip
    capsys.readouterr()
    assert gap_charge.main([str(out), "--workers", "1"]) == 0
    assert "of 1 without the charge" in capsys.readouterr().out
    assert gap_charge.main([str(tmp_path)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.parametrize("value", ["-0.1", "nan", "11", "lots"])
def test_a_bad_ignition_charge_is_one_line_and_exit_2(value, tmp_path, capsys):
    code = main(
        ["diagnose", "--calibration", "a.csv", "--validation", "b.csv", "--boiler",
         "windhager_6kw", "--out", str(tmp_path / "d"), "--ignition-charge-kg", value]
    )  # fmt: skip
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert "--ignition-charge-kg" in err and "\n" not in err and "Traceback" not in err


def test_diagnosis_works_on_a_real_labs_csv(small_benchmark, tmp_path):
    """No phase, sequence, setpoint or boiler_on columns and no meta file: phases and the
    firing from the signals alone."""
    out, scores = small_benchmark
    cases = {c["case"]: c for c in json.loads((out / "sealed" / "truth.json").read_text())}
    result = next(
        r for r in scores["results"] if r["found"] == cases[r["case"]]["effect"] != "none"
    )
    case = out / "cases" / f"case_{result['case']:02d}"
    bare = {}
    for name in ("stationary", "load_cycle"):
        lines = (case / f"{name}.csv").read_text().splitlines()
        header = lines[0].split(",")
        keep = [
            i
            for i, h in enumerate(header)
            if h not in ("water_flow_setpoint_kg_h", "boiler_on", "electric_power_W")
        ]
        path = tmp_path / f"{name}.csv"
        path.write_text(
            "\n".join(",".join(line.split(",")[i] for i in keep) for line in lines) + "\n"
        )
        bare[name] = path
    cal, val = cases[result["case"]]["pair"]
    assert _diagnose(bare[cal], bare[val], case / "boiler.yaml", tmp_path / "d") == 0
    diagnosis = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert diagnosis["effect"] == cases[result["case"]]["effect"]
    for key in ("confidence", "where", "candidates", "shrinkage", "unexplained_gap"):
        assert key in diagnosis
    assert {"phase", "signal", "rmsd", "max_dev", "r"} <= set(diagnosis["where"][0])
    for c in diagnosis["candidates"]:
        assert {
            "effect",
            "params",
            "score",
            "calibration_rmsd_before",
            "calibration_rmsd_after",
            "validation_rmsd_before",
            "validation_rmsd_after",
        } <= set(c)
    assert (tmp_path / "d" / "report.md").read_text().count("![") >= 2


def test_a_gap_outside_the_list_is_none_and_unexplained(tmp_path):
    """The lab's boiler holds 78 C where its documentation (and so the model) says 70 C: a
    controller difference, none of the listed effects. The answer is `none` with
    `unexplained_gap`, and `where` points at the test phase."""
    boiler = yaml.safe_load((BOILER_DIR / "windhager_12kw.yaml").read_text())
    boiler["set_temp_C"] = 78.0
    (tmp_path / "plant.yaml").write_text(yaml.safe_dump(boiler))
    lab = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    lab["effects"] = {}
    (tmp_path / "lab.yaml").write_text(yaml.safe_dump(lab))
    logs = {}
    for test in ("stationary", "load_cycle"):
        logs[test] = tmp_path / f"{test}.csv"
        argv = ["run", test, "--boiler", str(tmp_path / "plant.yaml"), "--rig", "local"]
        argv += ["--profile", str(tmp_path / "lab.yaml"), "--seed", "9", "--quiet"]
        assert main([*argv, "--out", str(logs[test])]) == 0
        logs[test].with_name(f"{test}.meta.json").unlink()
    code = _diagnose(logs["stationary"], logs["load_cycle"], "windhager_12kw", tmp_path / "d")
    assert code == 0
    diagnosis = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert diagnosis["effect"] == "none"
    assert diagnosis["unexplained_gap"] is True
    # `where` shows the 8-K difference of the boiler water in the test phase (beside the
    # fuel it costs); 3 K leaves room for the model's own modulation and the sensors
    test_water = [
        w
        for w in diagnosis["where"]
        if (w["phase"], w["signal"]) == ("test", "boiler_water_temp_C")
    ]
    assert test_water and test_water[0]["rmsd"] > 3.0


def test_one_case_end_to_end_through_modbus(serve, tmp_path):
    """The outlet-sensor pipe, published by `rig-emulator serve`, found by the client."""
    lab = yaml.safe_load((PROFILE_DIR / "lab.yaml").read_text())
    lab["effects"] = {"outlet_sensor_pipe": {"strength": 1.0}}
    profile = tmp_path / "profile.yaml"
    profile.write_text(yaml.safe_dump(lab))
    srv = serve(profile=str(profile), seed=3, boiler="windhager_12kw")
    logs = {}
    for name, test in (("calibration", "stationary"), ("validation", "load_cycle")):
        proto = yaml.safe_load((DEFINITION_DIR / f"{test}.yaml").read_text())
        # a row every 10 s, as some labs log (1 to 10 s are read alike): a tenth of the wire
        # time of 1-s rows
        proto["acquisition_period_s"] = 10
        proto_file = tmp_path / f"{test}.yaml"
        proto_file.write_text(yaml.safe_dump(proto))
        assert not (
            main(
                [
                    "run",
                    str(proto_file),
                    "--boiler",
                    "windhager_12kw",
                    "--rig",
                    f"modbus://127.0.0.1:{srv.port}",
                    "--out",
                    str(tmp_path / f"{name}.csv"),
                    "--quiet",
                ]
            )
        )
        # the next test starts from a reset bench
        from tests.modbus_helpers import client, write

        c = client(srv.port)
        assert not write(c, srv, "sim_control", "reset", 1).isError()
        c.close()
        logs[name] = tmp_path / f"{name}.csv"
    assert _diagnose(logs["calibration"], logs["validation"], "windhager_12kw", tmp_path / "d") == 0
    diagnosis = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert diagnosis["effect"] == "outlet_sensor_pipe"
    assert diagnosis["shrinkage"]["shrink_pct"] > 0


def test_diagnose_refuses_bad_input(tmp_path, capsys):
    bad, other = tmp_path / "bad.csv", tmp_path / "other.csv"
    bad.write_text("time_s,water_flow_kg_h\n1,2\n")
    other.write_text("time_s,water_flow_kg_h\n1,3\n")
    assert _diagnose(bad, other, "windhager_12kw", tmp_path / "d") == 2
    err = capsys.readouterr().err
    assert "missing required column" in err and err.count("\n") == 1
    assert not (tmp_path / "d").exists()


def test_independent_plants_give_every_case_an_answer(tmp_path):
    """Both independently written plants are installed, and the diagnosis answers on their
    logs (no crash, no one-line error) for a case with an effect on each: what it answers
    is scored by `hil-client gap-benchmark`, whose figures the README reports."""
    from hil_client.analysis.gap_benchmark import _run_case, independent_plants, make_cases

    assert independent_plants() == ["hil_client.reality", "hil_client.reality2"]
    cases = make_cases(8, 5, "independent")  # the second case of an effect: second plant
    picked = {}
    for c in cases:
        if c["effect"] != "none":
            picked.setdefault(c["plant"], c)
    assert set(picked) == {"hil_client.reality", "hil_client.reality2"}
    for case in picked.values():
        result = _run_case((case, str(tmp_path)))
        assert result["error"] is None, result
        assert result["found"] in ANSWERS
        assert (tmp_path / "cases" / f"case_{case['case']:02d}" / "diagnosis").is_dir()
