"""The plant-side effect registry is complete: every module of rig_emulator/bench/effects is
registered, and every registered effect has validated parameters with units, a documented
strength range, and stages that leave the plant bit-identical to the model at strength 0 and
change the plant's output at their point when its strength is above 0."""

from __future__ import annotations

import math
import pkgutil

import numpy as np
import pytest

from hil_client.analysis.candidates import CANDIDATES
from rig_emulator.bench import Bench, BenchConfig, EffectSettings
from rig_emulator.bench import effects as effects_pkg
from rig_emulator.bench.bench import YB_BALANCE, YB_T_OUT
from rig_emulator.bench.effects import (
    EFFECT_NAMES,
    POINTS,
    REGISTRY,
    STRENGTH_LIMITS,
    EffectError,
    check_effects,
    resolve_effects,
)
from rig_emulator.model.boiler import STAGE_POINTS
from rig_emulator.model.layout import Y_Q_FUEL, Y_T_BOILER, Y_T_FG

# start-up from 45 C at nominal flow, a load step down, stop with circulation, pump off:
# every point of the skeleton acts in it (duration [s], flow share, pump, boiler on)
SCENARIO = ((1200, 1.0, True, True), (600, 0.3, True, True), (600, 0.2, True, False))
SCENARIO += ((1800, 0.0, False, False),)

# where a stage at each point shows: (array, column) of the plant's output
SIGNAL_OF_POINT = {
    "flame_clock": ("y", Y_Q_FUEL),
    "fuel_bed": ("y", Y_Q_FUEL),
    "flue_gas": ("y", Y_T_FG),
    "heat_store": ("y", Y_T_BOILER),
    "forward_sensor": ("yb", YB_T_OUT),
    "balance": ("yb", YB_BALANCE),
}


def _run(params, effects) -> dict[str, np.ndarray]:
    bench = Bench(params, BenchConfig(initial_water_temp_C=45.0), effects)
    ys, ybs = [], []
    for duration, load, pump, on in SCENARIO:
        bench.set_inputs(load * params.nominal_flow_kg_h, 55.0, pump, on, False)
        for _ in range(duration):
            bench.step(1.0)
            ys.append(bench.y.copy())
            ybs.append(bench.yb.copy())
    return {"y": np.array(ys), "yb": np.array(ybs)}


@pytest.fixture(scope="module")
def model_run(params_12kw):
    return _run(params_12kw, None)


def test_every_effect_module_is_registered_and_named_as_its_file():
    modules = sorted(
        m.name for m in pkgutil.iter_modules(effects_pkg.__path__) if not m.name.startswith("_")
    )
    assert list(REGISTRY) == modules
    assert tuple(modules) == EFFECT_NAMES


def test_plant_and_diagnosis_share_the_effect_names():
    """CONTRACT section 4: the two registries share only the names, and all of them."""
    assert set(EFFECT_NAMES) == set(CANDIDATES)


def test_stage_points_are_the_skeletons_and_each_has_one_owner():
    assert POINTS[: len(STAGE_POINTS)] == STAGE_POINTS
    assert set(SIGNAL_OF_POINT) == set(POINTS)  # this test knows where every point shows
    compiled = [p for spec in REGISTRY.values() for p in spec.stages]
    assert len(compiled) == len(set(compiled))


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_parameters_have_units_and_are_validated(name):
    spec = REGISTRY[name]
    assert spec.params
    for p in spec.params:
        assert p.unit and p.doc, p.name
        key = f"effects.{name}.{p.name}"
        assert check_effects({name: {p.name: p.lab}}) == {name: {p.name: p.lab}}
        span = p.hi - p.lo
        for outside in (p.lo - 0.01 * span, p.hi + 0.01 * span, math.nan, math.inf):
            with pytest.raises(EffectError, match=rf"'{key}' must be finite and within"):
                check_effects({name: {p.name: outside}})
        with pytest.raises(EffectError, match=rf"'{key}' must be a number"):
            check_effects({name: {p.name: "1"}})
        if p.integer:
            with pytest.raises(EffectError, match="whole number"):
                check_effects({name: {p.name: p.lab + 0.5}})
    with pytest.raises(EffectError, match=rf"'effects.{name}.nope' is not a parameter"):
        check_effects({name: {"nope": 1.0}})
    # blanked (null) to switch it off, it was on at full strength (a stranger's probe)
    with pytest.raises(EffectError, match=rf"'effects.{name}' is empty: write"):
        check_effects({name: None})
    for strength in (STRENGTH_LIMITS[0] - 0.1, STRENGTH_LIMITS[1] + 0.1):
        with pytest.raises(EffectError, match=rf"'effects.{name}.strength' must be finite"):
            check_effects({name: {"strength": strength}})


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_strength_range_is_documented_and_acts_at_both_ends(name):
    lo, hi = REGISTRY[name].strength_range
    assert STRENGTH_LIMITS[0] < lo < 1.0 < hi <= STRENGTH_LIMITS[1]
    for strength in (lo, hi):
        assert resolve_effects({name: {"strength": strength}}).active == (name,)
    assert resolve_effects({name: {"strength": 0.0}}) == EffectSettings()


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_strength_zero_is_the_model_bit_for_bit(params_12kw, model_run, name):
    run = _run(params_12kw, {name: {"strength": 0.0}})
    for part in ("y", "yb"):
        assert np.array_equal(run[part], model_run[part], equal_nan=True), part


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_each_stage_changes_the_plant_at_its_point(params_12kw, model_run, name):
    """At the lowest documented strength every stage of the effect moves the signal of its
    point by more than rounding (1e-6 in that signal's unit: far below any stage's effect
    in this scenario, far above the 1e-12 relative noise of float64 sums)."""
    lo = REGISTRY[name].strength_range[0]
    run = _run(params_12kw, {name: {"strength": lo}})
    assert REGISTRY[name].points
    for point in REGISTRY[name].points:
        part, column = SIGNAL_OF_POINT[point]
        change = np.nanmax(np.abs(run[part][:, column] - model_run[part][:, column]))
        assert change > 1e-6, (point, change)
