"""The bench around the boiler: loop, return conditioning, balance, flue duct."""

import math

import numpy as np
import pytest

from rig_emulator.bench import Bench, BenchConfig, RoomConditions
from rig_emulator.bench.bench import BS_T_RETURN, YB_PRESSURE, YB_VELOCITY
from rig_emulator.bench.loop import LoopConfig, condition_return, follow_flow
from rig_emulator.boilers import load_boiler
from rig_emulator.model.constants import CP_WATER
from rig_emulator.model.layout import S_FUEL, Y_Q_WATER, Y_T_BOILER


def test_flow_follows_setpoint_and_pump():
    flow = 0.0
    for _ in range(100):  # 10 time constants
        flow = follow_flow(flow, 500.0, True, 1.0, 10.0)
    assert flow == pytest.approx(500.0, rel=1e-4)
    assert follow_flow(500.0, 500.0, False, 10.0, 10.0) == pytest.approx(500.0 / np.e)


def _loop_args(cfg: LoopConfig):
    return (
        cfg.capacity_kJ_K,
        cfg.loop_ua_W_K / 1000,
        cfg.conditioning_time_constant_s,
        cfg.cooling_capacity_kW,
        cfg.heating_capacity_kW,
    )


def test_return_conditioning_cools_to_setpoint():
    cfg = LoopConfig()
    t, flow, t_fwd = 60.0, 600.0, 70.0
    for _ in range(300):  # 10 conditioning time constants
        t, q = condition_return(t, flow, t_fwd, 55.0, 22.0, False, 1.0, *_loop_args(cfg))
    assert t == pytest.approx(55.0, abs=1e-3)
    # the cooler removes what the flow brings minus the loop's loss
    expected = flow * CP_WATER / 3600 * (t_fwd - 55.0) - cfg.loop_ua_W_K / 1000 * (55.0 - 22.0)
    assert q == pytest.approx(expected, rel=1e-3)


def test_return_cannot_be_heated_without_outside_help():
    cfg = LoopConfig()
    t = 45.0
    for _ in range(600):
        t, q = condition_return(t, 600.0, 50.0, 55.0, 22.0, False, 1.0, *_loop_args(cfg))
        assert q >= 0.0  # never heats
    assert t < 50.0  # follows the colder forward water, less the loop loss
    t_h = 45.0
    for _ in range(600):
        t_h, q = condition_return(t_h, 600.0, 50.0, 55.0, 22.0, True, 1.0, *_loop_args(cfg))
    assert t_h == pytest.approx(55.0, abs=1e-3) and q < 0.0


def test_cooler_capacity_limit_lets_the_circuit_heat_up():
    cfg = LoopConfig(cooling_capacity_kW=2.0)
    t = 55.0
    for _ in range(3600):
        t, q = condition_return(t, 600.0, 80.0, 55.0, 22.0, False, 1.0, *_loop_args(cfg))
    assert q == pytest.approx(2.0)
    assert t > 70.0  # without a buffer tank the return rises


def test_balance_loses_fuel_as_received_less_ash(params_12kw):
    bench = Bench(params_12kw)
    bench.set_inputs(params_12kw.nominal_flow_kg_h, 55.0, True, True, False)
    for _ in range(3600):
        bench.step(1.0)
    fuel_dry = bench.s[S_FUEL]
    fuel = params_12kw.fuel
    expected = fuel_dry * (1 / (1 - fuel.moisture) - fuel.ash)
    mass = bench.yb[7]
    assert BenchConfig().initial_balance_kg - mass == pytest.approx(expected, rel=1e-12)
    assert 2.0 < fuel_dry < 3.0  # about one hour at nominal load (2.5 kg/h dry)


def test_the_hopper_is_topped_up_and_the_balance_keeps_the_fuel_account(params_12kw):
    """A stranger's probe: six simulated days at full load read -142 kg on the balance with
    the burner still firing. The lab tops the hopper up to its first level when less than
    ``refill_below_kg`` is left: the balance rises in one step, never reads below the
    empty boiler, and first reading + what was tipped in - last reading is the fuel fed
    (mass is conserved across the refills)."""
    cfg = BenchConfig()
    bench = Bench(params_12kw, cfg)
    bench.set_inputs(params_12kw.nominal_flow_kg_h, 55.0, True, True, False)
    fuel = params_12kw.fuel
    per_kg_dry = 1 / (1 - fuel.moisture) - fuel.ash
    empty_kg = cfg.initial_balance_kg - cfg.hopper_fuel_kg
    last = cfg.initial_balance_kg
    lowest, tipped_in, refills = last, 0.0, 0
    for _ in range(48 * 3600):  # two days at nominal load: about 130 kg fed
        bench.step(1.0)
        mass = float(bench.yb[7])
        lowest = min(lowest, mass)
        if mass > last:
            refills += 1
            tipped_in += mass - last
        last = mass
    fed = bench.s[S_FUEL] * per_kg_dry
    assert refills == int((fed - cfg.refill_below_kg) // (cfg.hopper_fuel_kg - cfg.refill_below_kg))
    assert refills >= 1
    # the lowest reading: the refill level less one step's feed (2.8 kg/h: under 1 g)
    assert lowest >= empty_kg + cfg.refill_below_kg - 1e-3
    # each refill tips in what was fed since the last one; the rise read over the refill's
    # step nets that step's own feed (under 1 g), so the account closes to that per refill
    assert cfg.initial_balance_kg + tipped_in - last == pytest.approx(fed, abs=1e-3 * refills)


def test_boiler_sees_the_loop_return_and_flue_velocity_is_in_range(params_12kw):
    bench = Bench(params_12kw)
    bench.set_inputs(params_12kw.nominal_flow_kg_h, 55.0, True, True, False)
    for _ in range(3 * 3600):
        t_ret = bench.bs[BS_T_RETURN]
        bench.step(1.0)
    assert bench.yb[2] == pytest.approx(t_ret)
    assert bench.y[Y_Q_WATER] == pytest.approx(12.0, rel=1e-3)
    # digest section 5: the vortex meter measured 0.75-3 m/s
    assert 0.75 < bench.yb[8] < 3.0


def test_room_profile_is_interpolated():
    room = RoomConditions(profile=((0.0, 20.0, 990.0, 40.0), (100.0, 30.0, 970.0, 60.0)))
    assert room.at(50.0) == pytest.approx((25.0, 980.0, 50.0))
    assert room.at(-5.0) == (20.0, 990.0, 40.0)
    assert room.at(500.0) == (30.0, 970.0, 60.0)


@pytest.mark.parametrize("boiler", ["windhager_12kw", "windhager_6kw"])
def test_the_idle_draught_carries_the_heat_of_eq_14_to_16(boiler):
    """A stranger's review: the idle draught read a fixed 0.25 m/s, whose air (2.1 W/K)
    carried more than the model's (UAamb,OFF - UAamb,ON) (Table 3: 1.63 W/K for 12 kW), so
    calibrate found UA_on 37 % low from a noiseless log. The air that leaves the idle
    boiler at its temperature carries exactly that: rho v A cp = UA_off - UA_on, with
    rho = p / (R T) (dry air: R 287.05, cp 1006 J/(kg K); DN100)."""
    params = load_boiler(boiler)
    bench = Bench(params)
    bench.set_inputs(0.0, 50.0, False, False, False)  # idle, no circulation: cooling down
    for _ in range(600):
        bench.step(1.0)
        t_boiler_K = bench.y[Y_T_BOILER] + 273.15
        pressure_Pa = bench.yb[YB_PRESSURE] * 100.0
        rho = pressure_Pa / (287.05 * t_boiler_K)
        carried_W_K = rho * bench.yb[YB_VELOCITY] * math.pi * 0.1**2 / 4.0 * 1006.0
        assert carried_W_K == pytest.approx(params.ua_amb_off_W_K - params.ua_amb_on_W_K)
