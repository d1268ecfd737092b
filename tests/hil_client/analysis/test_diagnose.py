"""The gap diagnosis: a small blind benchmark, one case end to end over Modbus, a real lab's
CSV without phase columns or meta files, bad input."""

from __future__ import annotations

import json

import pytest
import yaml

from hil_client.analysis.gap_benchmark import ANSWERS, run_benchmark
from hil_client.cli import main
from hil_client.protocol.definition import DEFINITION_DIR
from rig_emulator.instruments.profile import PROFILE_DIR


@pytest.fixture(scope="module")
def small_benchmark(tmp_path_factory):
    out = tmp_path_factory.mktemp("gap")
    scores = run_benchmark(6, seed=2, out=out, workers=2)
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
        assert "calibration.csv" in names and "diagnosis.json" in names
    assert sum(sum(row.values()) for row in scores["confusion"].values()) == 6
    on_disk = json.loads((out / "scores.json").read_text())
    assert on_disk["accuracy"] == scores["accuracy"]
    # seed 2 scores 6 of 6 here; one miss is allowed (the target is >= 90 % on 24 cases,
    # `hil-client gap-benchmark`), and only a missed effect may lack a shrinkage figure
    misses = round((1.0 - scores["accuracy"]) * 6)
    assert misses <= 1
    shrinks = scores["median_validation_shrink_pct"]
    assert sum(v is None for v in shrinks.values()) <= misses
    for effect, shrink in shrinks.items():
        assert shrink is None or shrink > 0, effect


def test_diagnosis_works_on_a_real_labs_csv(small_benchmark, tmp_path):
    """No phase, sequence or setpoint columns and no meta file: phases from the signals."""
    out, scores = small_benchmark
    truth = {
        c["case"]: c["effect"] for c in json.loads((out / "sealed" / "truth.json").read_text())
    }
    # a case the full logs diagnose right: the bare logs must find the same true effect
    result = next(r for r in scores["results"] if r["found"] == truth[r["case"]] != "none")
    case = out / "cases" / f"case_{result['case']:02d}"
    bare = {}
    for name in ("calibration", "validation"):
        lines = (case / f"{name}.csv").read_text().splitlines()
        header = lines[0].split(",")
        keep = [
            i
            for i, h in enumerate(header)
            if h not in ("phase", "sequence", "water_flow_setpoint_kg_h")
        ]
        path = tmp_path / f"{name}.csv"
        path.write_text(
            "\n".join(",".join(line.split(",")[i] for i in keep) for line in lines) + "\n"
        )
        bare[name] = path
    assert (
        _diagnose(bare["calibration"], bare["validation"], case / "boiler.yaml", tmp_path / "d")
        == 0
    )
    diagnosis = json.loads((tmp_path / "d" / "diagnosis.json").read_text())
    assert diagnosis["effect"] == truth[result["case"]]
    for key in ("confidence", "where", "candidates", "shrinkage"):
        assert key in diagnosis
    assert {"phase", "signal", "rmsd", "max_dev", "r"} <= set(diagnosis["where"][0])
    assert (tmp_path / "d" / "report.md").read_text().count("![") >= 2


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
        proto["acquisition_period_s"] = 2  # halves the wire time of the test suite
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
    bad = tmp_path / "bad.csv"
    bad.write_text("time_s,water_flow_kg_h\n1,2\n")
    assert _diagnose(bad, bad, "windhager_12kw", tmp_path / "d") == 2
    err = capsys.readouterr().err
    assert "missing required column" in err and err.count("\n") == 1
    assert not (tmp_path / "d").exists()
