"""The balance's readings that the physics cannot produce, and gaps in time, against a
stationary log of known heat and fuel flow built here (a stranger's probe: a balance stuck
for part of the test gave 512 %, a 60-s dropout to 0 kg was 242 kg of fuel, a clock
stepped forward 1 h gave 99.7 % for 85.4 %)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil_client.analysis.balance import energy_balance
from hil_client.analysis.calibrate import Interval, _fuel_rate_dry
from hil_client.analysis.logio import LabLog
from hil_client.analysis.phases import Phases
from rig_emulator.model import constants as k

STEP_S = 5.0  # sampling period [s]
HOURS = 4.0
Q_WATER_KW = 12.0  # heat to the water [kW]
LOSS_KG_H = 3.0  # what the balance loses [kg/h]
RES_KG = 0.02  # the balance's resolution [kg]
# the balance's resolution at both ends of 12 kg lost in 4 h (0.04 / 12 = 0.3 %) and the
# rectangles of Eq. 7's sum at a constant heat (exact): within 1 %
REL = 0.01


def _log(t=None, mass=None) -> LabLog:
    """A stationary log: the burner firing throughout (O2 9 %), the water taking
    :data:`Q_WATER_KW` (15 K across a constant flow), the balance falling at
    :data:`LOSS_KG_H` from 250 kg in steps of :data:`RES_KG`; ``t`` and ``mass`` replace
    the time and the balance's readings."""
    n = int(HOURS * 3600 / STEP_S)
    true_t = np.arange(1, n + 1) * STEP_S
    t = true_t if t is None else t
    if mass is None:
        mass = np.round((250.0 - LOSS_KG_H * true_t / 3600.0) / RES_KG) * RES_KG
    flow = Q_WATER_KW * 3600.0 / (k.CP_WATER * 15.0)
    cols = {
        "time_s": np.asarray(t, float),
        "water_flow_kg_h": np.full(n, flow),
        "water_in_temp_C": np.full(n, 55.0),
        "water_out_temp_C": np.full(n, 70.0),
        "boiler_water_temp_C": np.full(n, 70.0),
        "flue_gas_temp_C": np.full(n, 150.0),
        "flue_gas_O2_pct": np.full(n, 9.0),
        "balance_mass_kg": np.asarray(mass, float),
        "room_temp_C": np.full(n, 22.0),
    }
    return LabLog(path=None, columns=cols, text={})  # type: ignore[arg-type]


def _test(log: LabLog, params):
    t = log.t
    phases = Phases(0.0, 0.5, float(t[-1]), float(t[-1]) + 1, float(t[-1]) + 2, "test")
    return next(r for r in energy_balance(log, params, phases) if r.phase == "test")


def _truth(params) -> tuple[float, float]:
    """(Q_fuel [kW], direct efficiency) by hand: the dry fuel is the balance's loss over
    what one kg of dry fuel leaves it (the fuel less its ash), times the dry HHV."""
    q_fuel = LOSS_KG_H / params.fuel.balance_loss_per_kg_dry * params.fuel.hhv_dry_kJ_kg / 3600
    return q_fuel, Q_WATER_KW / q_fuel


def test_the_generator_itself(params_12kw):
    q_fuel, eta = _truth(params_12kw)
    row = _test(_log(), params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    assert not row.warnings


def test_a_balance_stuck_to_the_end_of_the_test_leaves_its_fuel_unknown(params_12kw):
    log = _log()
    mass = log["balance_mass_kg"]
    at = np.searchsorted(log.t, 3600.0)
    mass[at:] = mass[at]  # stuck from 1 h on
    row = _test(log, params_12kw)
    assert math.isnan(row.fuel_as_received_kg) and math.isnan(row.eta_direct)
    assert math.isnan(row.eta_indirect) and math.isnan(row.q_fuel_kW)
    assert row.q_water_kW == pytest.approx(Q_WATER_KW, rel=1e-9)
    (line,) = row.warnings  # one line, naming the stretch
    # (from the last reading of the level it stuck at: a step of 0.02 kg lasts 24 s)
    assert "stuck" in line and f"to {log.t[-1]:g}, through 180 min of firing" in line


def test_a_balance_stuck_for_an_hour_between_readings_is_read_across(params_12kw):
    q_fuel, eta = _truth(params_12kw)
    log = _log()
    mass = log["balance_mass_kg"]
    a, b = np.searchsorted(log.t, [3600.0, 7200.0])
    mass[a:b] = mass[a]  # stuck 1 h to 2 h, then reading again (falls 3 kg at once)
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    (line,) = row.warnings
    assert "stuck" in line and "read across" in line


def test_a_dropout_to_zero_is_no_fuel_and_no_refill(params_12kw):
    q_fuel, eta = _truth(params_12kw)
    log = _log()
    a, b = np.searchsorted(log.t, [7200.0, 7260.0])
    log["balance_mass_kg"][a:b] = 0.0  # 60 s of 0 kg, then the level again
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    (line,) = row.warnings
    assert "faster than any small boiler burns" in line and f"time_s {log.t[a]:g}" in line
    from hil_client.analysis.logio import refills

    assert refills(log.balance_readings()[0], log.t) == []  # its return is no refill


def test_a_fall_that_never_comes_back_leaves_the_fuel_unknown(params_12kw):
    log = _log()
    a = np.searchsorted(log.t, 7200.0)
    rng = np.random.default_rng(0)  # a failed balance reading a few hundredths around 0
    log["balance_mass_kg"][a:] = rng.uniform(0.0, 0.06, len(log) - a).round(2)
    row = _test(log, params_12kw)
    assert math.isnan(row.fuel_as_received_kg) and math.isnan(row.eta_direct)
    (line,) = row.warnings
    assert "never comes back" in line


def test_a_clock_stepped_forward_and_a_gap_read_heat_and_fuel_alike(params_12kw):
    q_fuel, eta = _truth(params_12kw)
    log = _log()
    t = log.t.copy()
    t[t >= 7200.0] += 3600.0  # the clock steps 1 h forward at 2 h; no row is missing
    row = _test(_log(t=t), params_12kw)
    assert row.duration_s == pytest.approx(HOURS * 3600.0, abs=STEP_S)  # the time recorded
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    (line,) = row.warnings
    assert "gaps of 60 min" in line and f"cover the {HOURS * 60:.0f} min recorded" in line
    # the same hour truly missing: the heat and the balance's loss over it both left out
    keep = (log.t < 7200.0) | (log.t >= 10800.0)
    gapped = LabLog(None, {n: v[keep] for n, v in log.columns.items()}, {})  # type: ignore[arg-type]
    row = _test(gapped, params_12kw)
    assert row.duration_s == pytest.approx((HOURS - 1) * 3600.0, abs=STEP_S)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    assert "cover the 180 min recorded" in row.warnings[0]


def test_calibrate_reads_the_fuel_flow_over_the_time_recorded_only(params_12kw):
    """The stationary interval's fuel flow (whence Pel,MAX/MIN): across a clock step as
    without it; none from a balance stuck over most of it."""
    true_rate = LOSS_KG_H / params_12kw.fuel.balance_loss_per_kg_dry  # dry [kg/h]
    log = _log()
    t = log.t.copy()
    t[t >= 7200.0] += 3600.0
    jumped = _log(t=t)
    rate, _ = _fuel_rate_dry(Interval(jumped, 0, len(jumped), "x"), params_12kw)
    assert rate == pytest.approx(true_rate, rel=REL)
    stuck = _log()
    mass = stuck["balance_mass_kg"]
    at = np.searchsorted(stuck.t, 3600.0)
    mass[at:] = mass[at]
    rate, _ = _fuel_rate_dry(Interval(stuck, 0, len(stuck), "x"), params_12kw)
    assert math.isnan(rate)


def test_a_coarse_balance_at_a_low_load_is_no_stuck_one(params_12kw):
    """A balance of 0.1-kg steps at 0.35 kg/h (a 13 % load: 1.6 kW to the water) holds
    each reading 17 min, beyond STUCK_FIRING_S: the heat the water took over it is less
    than three of its steps of fuel could give, so no reading is taken for stuck, and the
    fuel is the balance's own (the heat criterion; without it each hold was "stuck")."""
    low_loss, coarse, low_heat = 0.35, 0.1, 1.6  # [kg/h], [kg], [kW]
    log = _log()
    t = log.t
    log["balance_mass_kg"][:] = np.round((250.0 - low_loss * t / 3600.0) / coarse) * coarse
    log["water_in_temp_C"][:] = 70.0 - low_heat / Q_WATER_KW * 15.0  # 2 K across the flow
    readings, unread = log.balance_readings()
    assert unread == [] and np.isfinite(readings).all()
    row = _test(log, params_12kw)
    # the loss over the run, to the balance's steps at both ends (0.2 kg of 1.4 kg)
    assert row.fuel_dry_kg * params_12kw.fuel.balance_loss_per_kg_dry == pytest.approx(
        low_loss * HOURS, abs=2 * coarse
    )


@pytest.mark.parametrize(
    ("taken_kg", "readings"),
    [(1.0, 1), (0.6, 1), (6.0, 12)],  # a sample in one step; the hopper emptied in a minute
)
def test_fuel_taken_off_by_hand_is_no_fuel_and_the_rest_is_read(params_12kw, taken_kg, readings):
    """A re-probe: a fuel sample of 0.6-1 kg scooped from the hopper mid-test was taken for
    a balance that never came back, every later phase's fuel unknown (and ``validate``
    gave half the fuel); 6 kg taken out over 12 readings, each under 0.5 kg, was counted
    as fuel burnt (59 % for 81 %). Both are fuel taken off by hand: not counted, the rest
    read as the fuel left."""
    q_fuel, eta = _truth(params_12kw)
    log = _log()
    a = int(np.searchsorted(log.t, 7200.0))
    mass = log["balance_mass_kg"]
    for i in range(readings):  # taken off in equal parts, a reading at a time
        mass[a + i :] -= taken_kg / readings
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)
    assert any("fuel taken off by hand" in note for note in log.notes), log.notes


@pytest.mark.parametrize(("taken_kg", "readings", "refill_kg"), [(1.0, 1, 15.0), (6.0, 12, 8.0)])
def test_fuel_taken_off_then_a_refill_is_read_as_both(params_12kw, taken_kg, readings, refill_kg):
    """A re-probe: a refill half an hour after fuel taken off was taken for the balance
    coming back (570 % efficiency), or counted against its loss (a "failed balance"):
    the balance comes back only to where it fell from, never above it."""
    q_fuel, eta = _truth(params_12kw)
    log = _log()
    a, r = (int(i) for i in np.searchsorted(log.t, [7200.0, 9000.0]))
    mass = log["balance_mass_kg"]
    for i in range(readings):
        mass[a + i :] -= taken_kg / readings
    mass[r:] += refill_kg
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert row.eta_direct == pytest.approx(eta, rel=REL)


def test_scoops_a_reading_apart_are_one_fall_and_a_noisy_balance_none(params_12kw):
    """Re-probes: ten scoops with a reading between each (0.06 kg/s over all) were fuel,
    each under 0.5 kg; joined across the pauses, a noisy balance's falls a few seconds
    apart made one fall of the whole log. Scoops join while the fall over all is faster
    than any boiler burns; noise never is."""
    q_fuel, _ = _truth(params_12kw)
    log = _log()
    a = int(np.searchsorted(log.t, 7200.0))
    for i in range(10):
        log["balance_mass_kg"][a + 2 * i :] -= 0.6
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    noisy = _log()
    rng = np.random.default_rng(1)  # 0.07 kg of scatter, read to 0.01 kg, with dropouts
    mass = noisy["balance_mass_kg"]
    mass[:] = np.round(mass + rng.normal(0.0, 0.07, len(mass)), 2)
    mass[rng.choice(len(mass), 8, replace=False)] = 0.0
    row = _test(noisy, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)
    assert not any("by hand" in note for note in noisy.notes), noisy.notes


def test_a_sample_minutes_before_the_end_is_no_failed_balance(params_12kw):
    """A re-probe: a 1.5-kg sample taken minutes before firing ended was called a failed
    balance (the water's heat after it, from the body as much as from fuel, needed more
    than the balance lost), the test's fuel unknown."""
    q_fuel, _ = _truth(params_12kw)
    log = _log()
    a = int(np.searchsorted(log.t, log.t[-1] - 240.0))  # 4 min before the end
    log["balance_mass_kg"][a:] -= 1.5
    row = _test(log, params_12kw)
    assert row.q_fuel_kW == pytest.approx(q_fuel, rel=REL)


def test_with_no_water_readings_a_balance_failed_to_zero_is_unknown(params_12kw):
    """A re-probe: with the water's columns empty, the heat was taken as 0, not unknown,
    and a balance failed to 0 for the last two hours of firing passed as fuel taken off
    by hand: half the fuel, no warning."""
    log = _log()
    for name in ("water_flow_kg_h", "water_in_temp_C", "water_out_temp_C"):
        log[name][:] = np.nan
    a = int(np.searchsorted(log.t, 7200.0))
    log["balance_mass_kg"][a:] = 0.0
    row = _test(log, params_12kw)
    assert math.isnan(row.fuel_as_received_kg), row


def _noisy(sigma_kg: float, seed: int, taken_kg: float = 0.0) -> LabLog:
    """The stationary log on a balance of ``sigma_kg`` Gaussian scatter read to 0.01 kg
    (seeded), ``taken_kg`` taken off by hand at 2 h (the same scatter with or without)."""
    log = _log()
    rng = np.random.default_rng(seed)
    mass = log["balance_mass_kg"]
    clean = 250.0 - LOSS_KG_H * log.t / 3600.0
    mass[:] = np.round(clean + rng.normal(0.0, sigma_kg, len(mass)), 2)
    mass[log.t >= 7200.0] -= taken_kg
    return log


def _sizing_kg(sigma_kg: float) -> float:
    """Three standard errors of a step between lines through LEVEL_MAX_S (300 s, 60
    readings) either side, of one slope: sigma * sqrt(8 / 60) each."""
    return 3 * sigma_kg * math.sqrt(8 / (300.0 / STEP_S))


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("sigma_kg", [0.1, 0.15])
def test_a_sample_on_a_noisy_balance_is_no_fuel_and_no_dropout(params_12kw, sigma_kg, seed):
    """A re-probe: a 0.6-kg sample taken by hand while firing, on a balance of 0.1 kg of
    scatter, was counted as fuel with no warning (the lowest of 120 s of noisy readings
    before it hid the fall); with 0.15 kg it was called a dropout ("is back at", one
    high reading taken for its return) and counted as fuel. The fuel is that of the same
    noisy log without the sample, to the sample's sizing (:func:`_sizing_kg`; the
    sample itself is 5 % of the fuel)."""
    plain = _test(_noisy(sigma_kg, seed), params_12kw)
    log = _noisy(sigma_kg, seed, taken_kg=0.6)
    row = _test(log, params_12kw)
    fuel_kg = plain.q_fuel_kW * HOURS * 3600 / params_12kw.fuel.hhv_dry_kJ_kg
    tolerance = _sizing_kg(sigma_kg) / (fuel_kg * params_12kw.fuel.balance_loss_per_kg_dry)
    assert row.q_fuel_kW == pytest.approx(plain.q_fuel_kW, rel=tolerance)
    assert not any("is back" in w for w in row.warnings), row.warnings
    assert any("fuel taken off by hand" in note for note in log.notes), log.notes


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("sigma_kg", [0.05, 0.15])
def test_a_sample_is_sized_between_the_levels_either_side(params_12kw, sigma_kg, seed):
    """A re-probe: a sample's size was read from two single noisy readings (the last
    before the fall, one near the top of the scatter, to the last of it, near the
    bottom): 0.6 kg logged as 0.78 kg at 0.05 kg of scatter, 1.10 kg at 0.15 kg. It is
    the step between the levels, to :func:`_sizing_kg`."""
    from hil_client.analysis.logio import balance_falls

    log = _noisy(sigma_kg, seed, taken_kg=0.6)
    heat = np.full(len(log), Q_WATER_KW)
    _, removals = balance_falls(log["balance_mass_kg"], log.t, heat)
    (removal,) = removals
    assert removal.kg == pytest.approx(0.6, abs=_sizing_kg(sigma_kg))


def test_a_tared_balance_in_grams_is_told_by_its_unit(params_12kw):
    """A re-probe: a balance logging grams, tared (0 down to -11996 "kg"), was told as
    "falls 11996 kg in 14395 s ... fuel taken off by hand (a sample, a tare), or a failed
    balance": a fall faster than any boiler burns for hours is no hand's, a unit's."""
    log = _log()
    log["balance_mass_kg"][:] = np.round(-1000.0 * LOSS_KG_H * log.t / 3600.0)
    row = _test(log, params_12kw)
    assert math.isnan(row.fuel_as_received_kg)
    assert any("another unit" in w for w in row.warnings), row.warnings
    assert not any("by hand (a sample" in note for note in log.notes), log.notes


@pytest.mark.parametrize(("sigma_kg", "said"), [(0.05, False), (0.1, False), (0.3, True)])
def test_a_balance_whose_noise_hides_a_sample_says_so(params_12kw, sigma_kg, said):
    """A re-probe: a balance scattering 0.3 kg read 2.6 times the fuel (its upward noise
    passed for refills) and one of 0.2 kg counted a 0.6-kg sample as fuel, the phase's
    warnings empty. Beyond a quarter of the 0.5-kg step that tells a refill or a sample
    (four of its deviations), the phase says the balance's noise, measured on the log."""
    from hil_client.analysis.sanity import suspicious

    log = _noisy(sigma_kg, 0)
    row = _test(log, params_12kw)
    noisy = [w for w in row.warnings if "scatters" in w]
    assert bool(noisy) is said, row.warnings
    assert bool([w for w in suspicious(log) if "scatters" in w]) is said
    if said:  # the noise as measured (a robust estimate over the log: to a tenth)
        measured = float(noisy[0].split("scatters ")[1].split(" kg")[0])
        assert measured == pytest.approx(sigma_kg, rel=0.1), noisy
