"""The blind benchmark's case design (the cases themselves are scored by
``hil-client gap-benchmark``; these tests check only that its design covers what the issue
asks for)."""

import importlib
import subprocess
import sys
import textwrap
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
import yaml

from hil_client.analysis.gap_benchmark import (
    BOILERS,
    DROPPED_COLUMNS,
    EFFECTS,
    HELD_OUT_PLANTS,
    INDEPENDENT_PLANTS,
    PAIRS,
    _write_csv_without,
    is_right,
    make_cases,
    miss_reason,
    score,
)
from hil_client.analysis.logio import REQUIRED, read_log
from hil_client.analysis.phases import find_phases
from hil_client.cli import main
from rig_emulator.boilers import BOILER_DIR


@pytest.mark.parametrize(
    "plants",
    [None, *((p,) for p in HELD_OUT_PLANTS)],
    ids=["default", *(p.rsplit(".", 1)[1] for p in HELD_OUT_PLANTS)],
)
def test_every_plant_meets_both_boilers_and_both_log_pairs_for_every_effect(plants):
    cases = make_cases(48, 0, "independent", plants)
    assert {c["plant"] for c in cases} >= set(plants or ())
    effects = [c for c in cases if c["effect"] != "none"]
    assert sum(c["effect"] == "none" for c in cases) == 8
    for effect in {c["effect"] for c in effects}:
        mine = [c for c in effects if c["effect"] == effect]
        for plant in {c["plant"] for c in cases}:
            theirs = [c for c in mine if c["plant"] == plant]
            assert {c["boiler"] for c in theirs} == set(BOILERS), (effect, plant)
            assert {tuple(c["pair"]) for c in theirs} == set(PAIRS), (effect, plant)
            forms = Counter(c["form"] for c in theirs)
            assert len(forms) >= 2, (effect, plant, forms)  # both forms of the plant
            # no form is tied to one boiler
            for form in forms:
                assert len({c["boiler"] for c in theirs if c["form"] == form}) == 2


def test_strengths_span_weak_to_strong_and_cases_are_reproducible():
    a, b = make_cases(48, 3, "independent"), make_cases(48, 3, "independent")
    assert a == b
    strengths = sorted(c["strength"] for c in a if c["effect"] != "none")
    assert strengths[0] < 0.1 and strengths[-1] > 0.9


def test_an_effect_named_without_held_out_shrinkage_is_not_a_success():
    cases = [{"case": 0, "effect": "flue_gas_lag"}, {"case": 1, "effect": "none"}]
    unconfirmed = {"case": 0, "found": "flue_gas_lag", "confirmed": False, "confidence": 0.9}
    right_none = {"case": 1, "found": "none", "confirmed": None, "confidence": 0.9}
    assert not is_right("flue_gas_lag", unconfirmed)
    base = {"shrink_pct": -5.0, "diagnosis_s": 1.0}
    scores = score(cases, [unconfirmed | base, right_none | base | {"shrink_pct": None}])
    assert scores["accuracy"] == 0.5 and scores["not_confirmed"] == 1
    assert scores["negative_shrinks_on_right_effect"] == 1
    # 0.9 on a miss and 0.9 on a right answer: (0.81 + 0.01) / 2
    assert scores["brier_score"] == pytest.approx(0.41)


def test_each_miss_says_which_of_the_diagnosis_tests_stopped_the_true_effect():
    """The breakdown of the misses reads what the true effect's candidate passed: named
    and outranked, its evidence without its mark, its mark without its evidence, neither;
    a ``none`` missed names the false alarm."""

    def result(case, found, named, evidence, mark, confirmed=None):
        cand = {"named": named, "evidence_named": evidence, "mark_named": mark, "reason": ""}
        return {
            "case": case,
            "found": found,
            "confirmed": confirmed,
            "confidence": 0.6,
            "shrink_pct": None,
            "diagnosis_s": 1.0,
            "true_candidate": cand,
        }

    results = [
        result(0, "flue_gas_lag", True, True, True, confirmed=True),
        result(1, "ignition_delay", True, True, True),
        result(2, "none", False, True, False),
        result(3, "none", False, False, True),
        result(4, "none", False, False, False),
        result(5, "flue_gas_lag", True, True, True, confirmed=False),
        result(6, "ignition_delay", False, False, False),
        result(7, "error", False, False, False) | {"true_candidate": None},
    ]
    truths = [
        "flue_gas_lag",
        "body_heat_diffusion",
        "flue_gas_lag",
        "fuel_energy_bias",
        "outlet_sensor_pipe",
        "flue_gas_lag",
        "none",
        "none",
    ]
    cases = [{"case": i, "effect": t} for i, t in enumerate(truths)]
    reasons = [miss_reason(t, r) for t, r in zip(truths, results, strict=True)]
    assert reasons == [
        "right",
        "named, outranked by ignition_delay",
        "evidence enough, mark below its floor",
        "mark beyond its floor, evidence short",
        "neither evidence nor mark",
        "named, not confirmed on held-out data",
        "false alarm: ignition_delay",
        "error",
    ]
    misses = score(cases, results)["misses"]
    assert "flue_gas_lag" in misses and sum(misses["flue_gas_lag"].values()) == 2
    assert misses["none"] == {"false alarm: ignition_delay": 1, "error": 1}


def test_an_unknown_plant_is_named_in_one_line(tmp_path, capsys):
    code = main(["gap-benchmark", "--plant", "reality11", "--out", str(tmp_path / "gap")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "reality11" in err and "reality3" in err
    assert not (tmp_path / "gap").exists()


def test_every_plant_builds_its_effects_in_forms_of_its_own():
    """No two independently written plants share a form name (each form is one writer's own
    idea of the effect; the emulator's is ``lab``), and every plant gives every listed
    effect at least two forms."""
    seen: dict[str, str] = {}
    for name in INDEPENDENT_PLANTS + HELD_OUT_PLANTS:
        plant = importlib.import_module(name)
        assert set(plant.EFFECT_FORMS) == set(EFFECTS), name
        for forms in plant.EFFECT_FORMS.values():
            assert len(forms) >= 2, name
            for form in forms:
                assert form not in seen, f"{form} of {name} is {seen.get(form)}'s too"
                seen[form] = name


@pytest.mark.parametrize("plant", [*INDEPENDENT_PLANTS, *HELD_OUT_PLANTS])
def test_the_projects_reader_reads_every_plants_log_as_the_benchmark_writes_it(plant, tmp_path):
    """Each plant's load cycle, written as the benchmark writes it (phase columns dropped,
    10-s jittered sampling), is read by the project's own reader with every required
    column unchanged (NaN gaps included), and its phases are found from the signals."""
    module = importlib.import_module(plant)
    boiler = yaml.safe_load((BOILER_DIR / "windhager_12kw.yaml").read_text())
    background = module.draw_background(np.random.default_rng(5), boiler)
    columns, _ = module.simulate_log(
        boiler, "load_cycle", background=background, effect=None, form=None,
        strength=0.0, seed=5, sample_s=10.0, jitter=True,
    )  # fmt: skip
    path = tmp_path / "load_cycle.csv"
    _write_csv_without(columns, path, module.write_log_csv)
    read = read_log(path)
    assert not any(read.has(name) for name in DROPPED_COLUMNS)
    for name in REQUIRED:
        # half a unit of the 6th significant digit, the coarsest any plant writes (%.6g)
        np.testing.assert_allclose(read[name], columns[name], rtol=5e-6, atol=1e-6)
    phases = find_phases(read)
    assert read.t[0] < phases.t0 < phases.t1 < phases.t2 < phases.t3 <= read.t[-1]


@pytest.mark.parametrize("plant", HELD_OUT_PLANTS)
def test_a_held_out_plant_imports_nothing_of_the_project_or_the_other_plants(plant):
    """A held-out plant stays independent: simulating every effect loads no module of the
    emulator's model, bench or instruments, of the analysis, or of any other plant."""
    others = [p for p in INDEPENDENT_PLANTS + HELD_OUT_PLANTS if p != plant]
    boiler = Path(__file__).parents[3] / "rig_emulator" / "boilers" / "windhager_6kw.yaml"
    code = textwrap.dedent(
        f"""
        import sys, yaml, numpy as np
        from pathlib import Path
        import {plant} as plant
        boiler = yaml.safe_load(Path({str(boiler)!r}).read_text())
        bg = plant.draw_background(np.random.default_rng(1), boiler)
        for effect, forms in plant.EFFECT_FORMS.items():
            plant.simulate_log(boiler, "load_cycle", background=bg, effect=effect,
                               form=forms[-1], strength=0.5, seed=1, sample_s=10.0, jitter=True)
        banned = ("rig_emulator.model", "rig_emulator.bench", "rig_emulator.instruments",
                  "hil_client.analysis")
        others = {others!r}
        bad = [m for m in sys.modules if m.startswith(banned)
               or any(m == o or m.startswith(o + ".") for o in others)]
        print("BAD", bad)
        """
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=True
    )
    assert "BAD []" in out.stdout, out.stdout + out.stderr
