"""Unmodelled effects of the plant (CONTRACT section 4): off is the model, on conserves
energy, each shows its signature, profiles are validated, the lab defaults give the
paper's gaps (Carlon et al. 2015, Section 3.2; digest section 7)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hil_client.cli import main as hil_client_main
from hil_client.protocol.definition import load_protocol
from hil_client.protocol.runner import LOG_COLUMNS, run_protocol
from hil_client.rigs.local import LocalRig
from rig_emulator.bench import (
    EFFECT_NAMES,
    Bench,
    BenchConfig,
    EffectSettings,
    effects_at,
    lab_parameters,
    resolve_effects,
    strength_ranges,
)
from rig_emulator.bench.bench import YB_BALANCE, YB_T_OUT, YB_VELOCITY
from rig_emulator.bench.effects import SPECS, STRENGTH_LIMITS, EffectError, check_effects
from rig_emulator.bench.effects.flue_gas_lag import lag2
from rig_emulator.bench.effects.ignition_delay import BED_EMPTY_KG
from rig_emulator.emulator import Emulator
from rig_emulator.instruments import ProfileError, load_profile, profile_from_mapping
from rig_emulator.model.boiler import balance_residual_kW
from rig_emulator.model.constants import CP_WATER
from rig_emulator.model.layout import (
    S_FUEL,
    Y_FIRING,
    Y_MODE,
    Y_O2,
    Y_Q_AMB,
    Y_Q_ASH,
    Y_Q_CHEM,
    Y_Q_FUEL,
    Y_Q_IGN,
    Y_Q_LAT,
    Y_Q_SENS,
    Y_Q_STORED,
    Y_Q_WATER,
    Y_T_BOILER,
    Y_T_FG,
    Y_T_OUT,
)
from tests.conftest import read_log
from tests.modbus_helpers import client, point, read_point, start_boiler

DYNAMIC = ("body_heat_diffusion", "outlet_sensor_pipe", "ignition_delay", "flue_gas_lag")

# (duration [s], flow setpoint [share of nominal], return setpoint [C], pump, boiler on):
# start-up from 45 C, nominal load, a load step down, stop with circulation, circulation off
SCENARIO = (
    (2400, 1.0, 55.0, True, True),
    (1200, 0.3, 55.0, True, True),
    (900, 0.2, 55.0, True, False),
    (3600, 0.0, 55.0, False, False),
)


def _bench(params, effects=None) -> Bench:
    return Bench(params, BenchConfig(initial_water_temp_C=45.0), effects)


def drive(bench: Bench, scenario=SCENARIO, dt_s: float = 1.0) -> dict[str, np.ndarray]:
    """Play ``scenario`` on ``bench``; per step: time, boiler outputs y, bench outputs yb."""
    flow_nom = bench.params.nominal_flow_kg_h
    ys, ybs, fuel = [], [], []
    for duration, load, ret, pump, on in scenario:
        bench.set_inputs(load * flow_nom, ret, pump, on, False)
        for _ in range(round(duration / dt_s)):
            bench.step(dt_s)
            ys.append(bench.y.copy())
            ybs.append(bench.yb.copy())
            fuel.append(bench.s[S_FUEL])
    y = np.array(ys)
    return {
        "t": dt_s * np.arange(1, len(ys) + 1),
        "y": y,
        "yb": np.array(ybs),
        "fuel": np.array(fuel),
    }


@pytest.fixture(scope="module")
def clean_run(params_12kw):
    return drive(_bench(params_12kw))


# ---------------------------------------------------------------------------- off = model


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_each_effect_at_strength_zero_is_the_model_bit_for_bit(params_12kw, clean_run, name):
    bench = _bench(params_12kw, {name: {"strength": 0.0}})
    assert bench.effects == EffectSettings()
    run = drive(bench)
    assert np.array_equal(run["y"], clean_run["y"], equal_nan=True)
    assert np.array_equal(run["yb"], clean_run["yb"], equal_nan=True)


def test_weak_effects_approach_the_model(params_12kw, clean_run):
    """The effects' plant step, with every effect nearly off, is the model (continuity)."""
    bench = _bench(params_12kw, {name: {"strength": 1e-4} for name in EFFECT_NAMES})
    assert set(bench.effects.active) == set(EFFECT_NAMES)
    run = drive(bench)
    y, yc = run["y"], clean_run["y"]
    assert np.max(np.abs(y[:, Y_T_BOILER] - yc[:, Y_T_BOILER])) < 0.05
    assert np.max(np.abs(run["yb"][:, YB_T_OUT] - clean_run["yb"][:, YB_T_OUT])) < 0.05
    assert np.max(np.abs(y[:, Y_Q_WATER] - yc[:, Y_Q_WATER])) < 0.05
    firing = yc[:, Y_Q_FUEL] > 0
    assert np.max(np.abs(y[firing, Y_T_FG] - yc[firing, Y_T_FG])[30:]) < 0.05
    assert run["fuel"][-1] == pytest.approx(clean_run["fuel"][-1], rel=1e-3)


def test_clean_and_lab_instruments_profiles_have_no_effects_and_lab_has_all():
    lab = load_profile("lab")
    assert set(lab.effects) == set(EFFECT_NAMES)
    assert set(resolve_effects(lab.effects).active) == set(EFFECT_NAMES)
    assert load_profile("clean").effects == {}
    lab_instruments = load_profile("lab_instruments")
    assert lab_instruments.effects == {}
    assert lab_instruments.instruments == lab.instruments


# ---------------------------------------------------------------------------- energy


def _energy_flows(y: np.ndarray) -> np.ndarray:
    """Inputs less outputs of every step's balance [kW]."""
    return np.array([balance_residual_kW(row) for row in y])


@pytest.mark.parametrize("name", DYNAMIC)
def test_plant_energy_balance_closes_every_step(params_12kw, name):
    run = drive(_bench(params_12kw, {name: {"strength": 1.0}}))
    assert np.max(np.abs(_energy_flows(run["y"]))) < 1e-9


def test_body_diffusion_conserves_energy_over_a_run(params_12kw):
    """Fuel in = losses + water + ambient + stored (metal and water nodes), to rounding."""
    bench = _bench(params_12kw, {"body_heat_diffusion": {"strength": 1.0}})
    body = bench.effects["body_heat_diffusion"]
    n = int(body["nodes"])
    c_metal = body["metal_share"] * params_12kw.capacity_kJ_K

    def content() -> float:  # heat in the nodes above 0 C [kJ]
        state = bench.effect_state("body_heat_diffusion")
        metal = sum(state[f"metal_{i}_C"] for i in range(n)) * c_metal / n
        return metal + (params_12kw.capacity_kJ_K - c_metal) * bench.s[0]

    e0 = content()
    run = drive(bench)
    y = run["y"]
    assert "body_heat_diffusion" in bench.effects.active  # the chain is on
    fuel_in = np.sum(y[:, Y_Q_FUEL] + y[:, Y_Q_IGN])  # kJ over 1 s steps
    losses = np.sum(y[:, [Y_Q_ASH, Y_Q_SENS, Y_Q_LAT, Y_Q_CHEM]])
    water, ambient = np.sum(y[:, Y_Q_WATER]), np.sum(y[:, Y_Q_AMB])
    stored = content() - e0
    assert np.sum(y[:, Y_Q_STORED]) == pytest.approx(stored, rel=1e-9, abs=1e-6)
    assert fuel_in == pytest.approx(losses + water + ambient + stored, rel=1e-12, abs=1e-6)
    # and the fuel fed is the fuel burnt (no bed without the ignition effect)
    hhv = params_12kw.fuel.hhv_dry_kJ_kg
    assert bench.s[S_FUEL] * hhv == pytest.approx(np.sum(y[:, Y_Q_FUEL]), rel=1e-12)


def test_all_effects_conserve_fuel_and_energy(params_12kw):
    """Fuel fed = fuel burnt + the bed; the plant's balance closes with all effects on."""
    bench = _bench(params_12kw, {name: {"strength": 1.5} for name in EFFECT_NAMES})
    run = drive(bench, (*SCENARIO[:2], (300, 0.2, 55.0, True, False)))
    hhv = params_12kw.fuel.hhv_dry_kJ_kg
    burnt = np.sum(run["y"][:, Y_Q_FUEL]) / hhv
    bed = bench.effect_state("ignition_delay")["bed_kg"]
    assert bench.s[S_FUEL] == pytest.approx(burnt + bed, rel=1e-12)
    assert np.max(np.abs(_energy_flows(run["y"]))) < 1e-9


# ---------------------------------------------------------------------------- signatures


def test_body_diffusion_water_lags_and_gets_less_heat_at_start_up(params_12kw, clean_run):
    bench = _bench(params_12kw, {"body_heat_diffusion": {"strength": 1.0}})
    run = drive(bench)
    y, yc = run["y"], clean_run["y"]
    t = run["t"]
    early = t <= 900  # first 15 min
    assert np.all(y[early, Y_T_BOILER][60:] < yc[early, Y_T_BOILER][60:])
    # heat to water at start-up below the one-node model's
    assert np.sum(y[early, Y_Q_WATER]) < 0.8 * np.sum(yc[early, Y_Q_WATER])
    i10 = int(np.searchsorted(t, 600))
    assert yc[i10, Y_Q_WATER] / y[i10, Y_Q_WATER] > 1.2
    # steady firing: same heat to water, the metal hotter than the water by about Q tau / C_m
    i = int(np.searchsorted(t, 2399))
    assert y[i, Y_Q_WATER] == pytest.approx(yc[i, Y_Q_WATER], rel=0.02)
    # after the stop the metal's excess heats the water: it stays warmer than the model's
    stop = int(np.searchsorted(t, 3600 + 600))
    assert y[stop, Y_T_BOILER] > yc[stop, Y_T_BOILER] + 1.0


def test_body_metal_gradient_in_steady_firing(params_12kw):
    bench = _bench(params_12kw, {"body_heat_diffusion": {"strength": 1.0}})
    drive(bench, (*SCENARIO[:1], (3600, 1.0, 55.0, True, True)))
    body = bench.effects["body_heat_diffusion"]
    c_metal = body["metal_share"] * params_12kw.capacity_kJ_K
    q_in = bench.y[Y_Q_WATER] + bench.y[Y_Q_AMB]  # steady: what reaches the water
    expected = q_in * body["time_constant_s"] / c_metal
    metal_0 = bench.effect_state("body_heat_diffusion")["metal_0_C"]
    assert metal_0 - bench.y[Y_T_BOILER] == pytest.approx(expected, rel=0.02)


def test_outlet_pipe_reads_below_the_boiler_once_circulation_stops(params_12kw, clean_run):
    run = drive(_bench(params_12kw, {"outlet_sensor_pipe": {"strength": 1.0}}))
    y, yb, t = run["y"], run["yb"], run["t"]
    # the boiler water is untouched
    assert np.array_equal(y[:, Y_T_BOILER], clean_run["y"][:, Y_T_BOILER])
    flowing = (t > 1800) & (t <= 3600)
    gap = y[:, Y_T_OUT] - yb[:, YB_T_OUT]
    assert np.all(np.abs(gap[flowing]) < 0.2)  # while water flows: close to the boiler's
    stop = 3600 + 900  # circulation off
    assert gap[int(np.searchsorted(t, stop + 600))] > 3.0
    assert gap[-1] > 8.0  # an hour later: well below, on its way toward the room
    assert np.all(np.diff(gap[t > stop + 60]) > -1e-9)  # diverging


def test_stagnant_outlet_pipe_settles_between_room_and_boiler(params_12kw):
    """T_room + (T_boiler - T_room) / (1 + tau_r / tau_b) once settled (tau_r 1800 s)."""
    effect = {"outlet_sensor_pipe": {"strength": 1.0, "coupling_time_constant_s": 1800.0}}
    run = drive(_bench(params_12kw, effect), (*SCENARIO[:3], (4 * 3600, 0.0, 55.0, False, False)))
    boiler, sensor = run["y"][-1, Y_T_BOILER], run["yb"][-1, YB_T_OUT]
    room = BenchConfig().room.temp_C
    assert (sensor - room) / (boiler - room) == pytest.approx(0.5, abs=0.02)


def _best_lag(sensor: np.ndarray, outlet: np.ndarray, max_lag: int = 40) -> int:
    errors = [
        np.mean((sensor[max_lag:] - outlet[max_lag - k : len(outlet) - k]) ** 2)
        for k in range(max_lag)
    ]
    return int(np.argmin(errors))


@pytest.mark.parametrize("share", [0.15, 0.6])
def test_outlet_pipe_delay_is_pipe_content_over_flow(params_12kw, share):
    # the lab pipe without its heat exchange, to see the transport delay alone
    no_loss = {"cooling_time_constant_s": 1e6, "coupling_time_constant_s": 1e6}
    bench = _bench(params_12kw, {"outlet_sensor_pipe": {"strength": 1.0, **no_loss}})
    flow = share * params_12kw.nominal_flow_kg_h
    run = drive(bench, ((600, share, 55.0, True, True),))
    # the boiler outlet over the step (what enters the pipe) against the sensor
    outlet = run["yb"][:, 2] + run["y"][:, Y_Q_WATER] / (flow * CP_WATER / 3600.0)
    delay = 0.25 * 0.9778 / (flow / 3600.0)  # rho V / m [s]
    lag = _best_lag(run["yb"][60:, YB_T_OUT], outlet[60:])
    assert abs(lag - delay) <= 1.0


def test_ignition_delay_balance_drops_before_heat_is_released(params_12kw, clean_run):
    bench = _bench(params_12kw, {"ignition_delay": {"strength": 1.0}})
    run = drive(bench)
    y, yb, t = run["y"], run["yb"], run["t"]
    delay = bench.effects["ignition_delay"]["delay_s"]
    before = t < delay
    balance0 = BenchConfig().initial_balance_kg
    assert np.all(y[before, Y_Q_FUEL] == 0.0)
    assert np.all(y[before, Y_O2] > 20.9)  # the analyser sees air
    assert balance0 - yb[int(delay) - 2, YB_BALANCE] > 0.05  # kg of pellets already fed
    assert np.all(y[(t > delay + 1) & (t < 1800), Y_Q_FUEL] > 0.0)
    # the clean boiler heats from the first second
    assert clean_run["y"][0, Y_Q_FUEL] > 10.0
    # after the stop (t = 3600 s) the bed burns out without feed
    stop = int(np.searchsorted(t, 3600.0))
    after = y[stop + 1 : stop + 200]
    assert np.all(after[:, Y_FIRING] == 0.0)
    assert after[0, Y_Q_FUEL] > 1.0
    burn_out = np.sum(y[stop:, Y_Q_FUEL]) / params_12kw.fuel.hhv_dry_kJ_kg
    assert burn_out == pytest.approx(
        y[stop - 1, 5] / 3600 * bench.effects["ignition_delay"]["burnout_time_constant_s"],
        rel=0.05,
    )
    state = bench.effect_state("ignition_delay")  # out, its last 0.1 g left for the next start
    assert state["bed_lit"] == 0.0 and 0.0 < state["bed_kg"] < BED_EMPTY_KG
    assert np.sum(y[stop + 600 :, Y_Q_FUEL]) == 0.0


def test_a_bed_burning_out_is_fanned_by_the_air_of_the_last_feed(params_12kw):
    """A physics review: in the burn-out the analyser read the full-load O2 to the last gram
    and then air at once, the duct velocity fell to a hundredth of the idle draught's, and
    the gas left as hot as at full load. The fan holds the last feed's air: O2 rises to air
    as the bed burns down, the velocity stays the fan's until the bed is out, and the gas
    cools towards the water (module docstring of boiler.burnout_gas)."""
    bench = _bench(params_12kw, {"ignition_delay": {"strength": 1.0}})
    run = drive(bench)
    y, yb, t = run["y"], run["yb"], run["t"]
    stop = int(np.searchsorted(t, 3600.0))
    out = stop + int(np.argmax(y[stop:, Y_Q_FUEL] == 0.0))  # the first row the bed is out
    burning = slice(stop + 1, out)
    assert out - stop > 100  # (a bed of some minutes' burning)
    o2 = y[burning, Y_O2]
    assert y[stop - 1, Y_O2] < o2[0] < 17.0 and o2[-1] > 20.0  # the fire's, then air's
    assert np.all(np.diff(o2) >= -1e-9)  # as the bed burns down, never back
    velocity = yb[burning, YB_VELOCITY]
    idle = yb[out + 5, YB_VELOCITY]  # the bed out: the idle draught's
    assert velocity.min() > idle  # the fan's air, not the fuel's gas alone
    assert y[out - 1, Y_Q_FUEL] < 0.05  # its last second no flare (2 kW: the review)
    water, gas = y[burning, Y_T_BOILER], y[burning, Y_T_FG]
    assert np.all(gas >= water - 1e-9) and gas[-1] - water[-1] < 0.2 * (gas[0] - water[0])


def test_a_restart_onto_a_bed_still_burning_keeps_the_fans_air(params_12kw):
    """A re-probe: switched on again 3 min after a stop, the bed still burning, the duct
    velocity fell from 0.93 to 0.12 m/s (below the idle draught's) and O2 from 19.3 to
    6.05 % in one second, the gas of the burning bed alone taken for the flow. The fan's
    air carries on: no step in the readings, the velocity above the idle draught's."""
    bench = _bench(params_12kw, {"ignition_delay": {"strength": 0.5}})
    scenario = ((2400, 1.0, 55.0, True, True), (180, 1.0, 55.0, True, False))
    run = drive(bench, (*scenario, (900, 1.0, 55.0, True, True)))
    y, yb = run["y"][2300:], run["yb"][2300:]
    assert y[2579 - 2300, Y_Q_FUEL] > 0.0  # the bed burns as the boiler comes back on
    assert np.abs(np.diff(y[:, Y_O2])).max() < 2.0  # vol-%, a second apart
    idle = drive(_bench(params_12kw), ((600, 1.0, 55.0, True, False),))["yb"][-1, YB_VELOCITY]
    assert yb[:, YB_VELOCITY].min() > idle


def test_flue_gas_lag_rises_slower_after_ignition(params_12kw, clean_run):
    bench = _bench(params_12kw, {"flue_gas_lag": {"strength": 1.0}})
    run = drive(bench)
    t = run["t"]
    fg, fg_clean = run["y"][:, Y_T_FG], clean_run["y"][:, Y_T_FG]
    i60 = int(np.searchsorted(t, 60))
    assert fg_clean[0] > 135.0  # Eq. 8 at once
    assert fg[0] < 50.0 and fg[i60] < 90.0  # S-shaped: slow start
    rise = fg_clean[i60] - 45.0
    assert fg[i60] - 45.0 < 0.5 * rise
    i = int(np.searchsorted(t, 1800))
    assert fg[i] == pytest.approx(fg_clean[i], abs=0.5)  # then the same level
    # and after the stop it falls slowly instead of jumping to the water temperature
    stop = int(np.searchsorted(t, 3600.0))
    assert fg[stop + 30] > clean_run["y"][stop + 30, Y_T_FG] + 30.0


def test_lag2_is_the_exact_two_node_response():
    y1 = y2 = 0.0
    for _ in range(100):
        y1, y2 = lag2(y1, y2, 1.0, 20.0, 30.0, 1.0)
    # step response of two lags in series: 1 - (t1 e1 - t2 e2) / (t1 - t2)
    expected = 1.0 - (20.0 * math.exp(-100 / 20) - 30.0 * math.exp(-100 / 30)) / (20.0 - 30.0)
    assert y2 == pytest.approx(expected, rel=1e-12)
    y1 = y2 = 0.0
    for _ in range(100):
        y1, y2 = lag2(y1, y2, 1.0, 25.0, 25.0, 1.0)
    assert y2 == pytest.approx(1.0 - (1.0 + 100 / 25) * math.exp(-100 / 25), rel=1e-12)


@pytest.mark.parametrize("extra", [{}, {"flue_gas_lag": {"strength": 1.0}}])
def test_fuel_bias_more_mass_for_the_same_heat(params_12kw, extra):
    base = drive(_bench(params_12kw, extra))
    biased = drive(_bench(params_12kw, {**extra, "fuel_energy_bias": {"strength": 1.0}}))
    assert np.array_equal(biased["y"], base["y"])  # the same heat flows and temperatures
    lost = BenchConfig().initial_balance_kg - biased["yb"][-1, YB_BALANCE]
    lost_base = BenchConfig().initial_balance_kg - base["yb"][-1, YB_BALANCE]
    assert lost / lost_base == pytest.approx(1.0 / (1.0 - 0.08), rel=1e-12)


# ---------------------------------------------------------------------------- profiles


def test_strength_scales_parameters_and_explicit_values_override():
    fx = resolve_effects(
        {
            "body_heat_diffusion": {"strength": 2.0},
            "outlet_sensor_pipe": {"strength": 0.5, "volume_l": 1.0},
            "ignition_delay": {},
            "fuel_energy_bias": {"relative_bias": 0.05},
        }
    )
    lab = lab_parameters()
    body, pipe = fx["body_heat_diffusion"], fx["outlet_sensor_pipe"]
    assert body["time_constant_s"] == 2 * lab["body_heat_diffusion"]["time_constant_s"]
    assert body["metal_share"] == lab["body_heat_diffusion"]["metal_share"]  # shape
    assert pipe["volume_l"] == 1.0
    assert pipe["cooling_time_constant_s"] == 2 * 1800.0  # inverse: a weaker loss
    assert pipe["coupling_time_constant_s"] == 0.5 * 18000.0
    # strength 1 by default
    assert fx["ignition_delay"]["delay_s"] == lab["ignition_delay"]["delay_s"]
    assert fx["fuel_energy_bias"]["relative_bias"] == 0.05
    assert "flue_gas_lag" not in fx
    assert resolve_effects({"flue_gas_lag": {"strength": 0.0}}) == EffectSettings()


def test_strength_ranges_are_documented_for_every_effect():
    ranges = strength_ranges()
    assert set(ranges) == set(EFFECT_NAMES) == set(SPECS)
    for lo, hi in ranges.values():
        assert STRENGTH_LIMITS[0] < lo < 1.0 < hi <= STRENGTH_LIMITS[1]
        for s in (lo, hi):  # accepted by validation, and every effect is then on
            for name in EFFECT_NAMES:
                fx = resolve_effects(check_effects({name: {"strength": s}}))
                assert fx.active == (name,)


def test_effects_at_builds_a_profile_for_drawn_strengths(params_12kw):
    drawn = {name: hi for name, (lo, hi) in strength_ranges().items()}
    profile = profile_from_mapping({"name": "drawn", "effects": effects_at(drawn)})
    fx = Emulator(params_12kw, profile).bench.effects
    assert fx.active == EFFECT_NAMES
    bias = fx["fuel_energy_bias"]["relative_bias"]
    assert bias == pytest.approx(-0.08 * drawn["fuel_energy_bias"])
    with pytest.raises(EffectError, match=r"'effects\.nope'"):
        effects_at({"nope": 1.0})


@pytest.mark.parametrize(
    ("effects", "message"),
    [
        ({"body_diffusion": {}}, "'effects.body_diffusion' is not a known effect"),
        ({"flue_gas_lag": {"tau": 1}}, "'effects.flue_gas_lag.tau' is not a parameter"),
        ({"flue_gas_lag": {"strength": "x"}}, "'effects.flue_gas_lag.strength' must be a number"),
        ({"flue_gas_lag": {"strength": True}}, "'effects.flue_gas_lag.strength' must be a number"),
        ({"ignition_delay": {"strength": -1}}, "'effects.ignition_delay.strength' must be finite"),
        ({"ignition_delay": {"delay_s": math.nan}}, "'effects.ignition_delay.delay_s' must be"),
        (
            {"body_heat_diffusion": {"nodes": 2.5}},
            "'effects.body_heat_diffusion.nodes' must be a whole",
        ),
        (
            {"body_heat_diffusion": {"nodes": 9}},
            "'effects.body_heat_diffusion.nodes' must be finite",
        ),
        ({"fuel_energy_bias": {"relative_bias": 0.5}}, "relative_bias' must be finite and within"),
        # a physics review: 26 MJ/kg (a coal's) and a direct efficiency of 104 % on the HHV;
        # a 30-cm pipe that threw away 28 kW (the forward 20 K under the return, firing)
        ({"fuel_energy_bias": {"relative_bias": 0.3}}, "within -0.3..0.1"),
        (
            {"outlet_sensor_pipe": {"cooling_time_constant_s": 1}},
            "'effects.outlet_sensor_pipe.cooling_time_constant_s' must be finite and within 300",
        ),
        ({"fuel_energy_bias": {"relative_bias": 10**400}}, "relative_bias' must be finite"),
        ({"outlet_sensor_pipe": [1, 2]}, "'effects.outlet_sensor_pipe' must be a mapping"),
        ([1], "'effects' must be a mapping"),
    ],
)
def test_broken_effects_name_the_key(effects, message):
    with pytest.raises(ProfileError, match=message.replace("(", r"\(")) as info:
        profile_from_mapping({"name": "x", "effects": effects}, "p.yaml")
    assert str(info.value).startswith("p.yaml: ")
    with pytest.raises(EffectError):
        check_effects(effects)


# ---------------------------------------------------------------------------- lab gaps


def _stationary(params, profile):
    rig = LocalRig(params, profile)
    rows: list = []
    result = run_protocol(load_protocol("stationary"), params.p_nom_kW, rig, rows.append)
    columns = {
        name: np.array([r[i] for r in rows], dtype=object) for i, name in enumerate(LOG_COLUMNS)
    }
    data = {n: columns[n].astype(float) for n in LOG_COLUMNS if n not in ("phase", "sequence")}
    data["q_water"] = (
        data["water_flow_kg_h"]
        * CP_WATER
        * (data["water_out_temp_C"] - data["water_in_temp_C"])
        / 3600
    )
    return result.times, data


@pytest.fixture(scope="module")
def lab_gap(params_12kw):
    """The 12 kW stationary test on the clean model and on the lab plant (lab effects,
    ideal instruments, so the gap is the plant's)."""
    lab_plant = profile_from_mapping({"name": "lab_plant", "effects": load_profile("lab").effects})
    return _stationary(params_12kw, load_profile("clean")), _stationary(params_12kw, lab_plant)


def test_lab_effects_model_overestimates_heat_to_water_at_t1(lab_gap):
    (tc, clean), (tl, lab) = lab_gap
    since_t0_clean = clean["time_s"] - tc["t0_s"]
    t1 = tl["t1_s"] - tl["t0_s"]
    assert t1 > tc["t1_s"] - tc["t0_s"] + 180  # the lab's t1 comes later (exchanger warms up)
    q_lab = lab["q_water"][int(np.searchsorted(lab["time_s"], tl["t1_s"]))]
    q_model = np.interp(t1, since_t0_clean, clean["q_water"])
    assert 1.1 <= q_model / q_lab <= 1.3


def test_lab_effects_fuel_gap_and_forward_sensor(lab_gap):
    (tc, clean), (tl, lab) = lab_gap

    def fuel(times, data, a, b):
        mass = data["balance_mass_kg"]
        return (
            mass[np.searchsorted(data["time_s"], times[a])]
            - mass[np.searchsorted(data["time_s"], times[b])]
        )

    ratio = fuel(tl, lab, "t1_s", "t2_s") / fuel(tc, clean, "t1_s", "t2_s")
    # the paper's 16.3 kg on the balance against the clean model's 15.98 kg (its 15.0 kg
    # simulated is dry fuel): 1.02, within the balance's 0.02-kg steps and its 0.05 kg
    assert 1.01 < ratio <= 1.03
    gap = lab["boiler_water_temp_C"] - lab["water_out_temp_C"]
    t = lab["time_s"]
    assert np.max(np.abs(gap[(t > tl["t1_s"]) & (t < tl["t2_s"])])) < 0.2
    assert np.min(gap[t > tl["t3_s"] + 1800]) > 5.0  # diverges once circulation stops
    assert np.max(np.abs(clean["boiler_water_temp_C"] - clean["water_out_temp_C"])) == 0.0


def test_emulator_publishes_the_effects_of_the_profile(params_12kw):
    emu = Emulator(params_12kw, load_profile("lab"), seed=1)
    assert emu.bench.effects.active == EFFECT_NAMES
    emu.set_commands(
        {"water_flow_setpoint_kg_h": 600.0, "return_setpoint_C": 55.0, "boiler_command": 1}
    )
    emu.advance(30.0)
    values = emu.values()
    assert values["boiler_on"] == 1.0 and emu.bench.y[Y_MODE] == 1
    assert emu.bench.y[Y_Q_FUEL] == 0.0  # the bed has not lit yet
    assert values["balance_mass_kg"] < BenchConfig().initial_balance_kg - 0.01


def test_modbus_server_publishes_the_lab_effects(serve):
    """``rig-emulator serve --profile lab``: 60 s after the start the bed has not lit, so the
    flue-gas probe still reads the idle boiler while the clean model already fires."""
    readings = {}
    for profile in ("clean", "lab"):
        srv = serve(profile=profile, seed=2)
        c = client(srv.port)
        start_boiler(c, srv, 60)
        readings[profile] = read_point(c, *point(srv, "flue_gas_probe", "flue_gas_temp"))
        c.close()
    assert readings["clean"] > 100.0  # Eq. 8: return (22 C) + dTnom
    assert readings["lab"] < 40.0


def test_hil_client_run_with_the_lab_profile_shows_the_outlet_pipe(tmp_path):
    out = tmp_path / "st.csv"
    args = ["run", "stationary", "--boiler", "windhager_12kw", "--profile", "lab"]
    assert hil_client_main([*args, "--rig", "local", "--out", str(out), "--quiet"]) == 0
    _, log = read_log(out)
    t = np.array(log["time_s"])
    t3 = json.loads(out.with_name("st.meta.json").read_text())["t3_s"]
    gap = np.array(log["boiler_water_temp_C"]) - np.array(log["water_out_temp_C"])
    assert np.min(gap[t > t3 + 3600]) > 5.0


def test_plant_step_with_neutral_effects_is_the_model_bit_for_bit(params_12kw, clean_run):
    """One step skeleton: the plant's kernel (every effect constant zero) takes the same
    stages as the model's step, so the two agree to the last bit, not only within noise."""
    bench = _bench(params_12kw)
    assert not np.any(bench.fc)
    bench._dynamic = True  # force the effects kernel with neutral constants
    run = drive(bench)
    assert np.array_equal(run["y"], clean_run["y"], equal_nan=True)
    assert np.array_equal(run["yb"], clean_run["yb"], equal_nan=True)
