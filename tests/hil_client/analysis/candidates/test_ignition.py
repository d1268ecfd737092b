"""Single rules of the ignition candidate (hil_client.analysis.candidates.ignition) on
small hand-made inputs whose right answer is known by construction: what the balance's
resolution allows an ignition pre-feed to claim, a log that begins just before its first
start, and the fuel a slowly lit bed holds where the flue gas counts the flame's fuel."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from hil_client.analysis.candidates.base import BALANCE_STEP_KG, Z_MIN
from hil_client.analysis.candidates.ignition import (
    PRE_FEED_MIN_S,
    _analyser_delay_max_s,
    _decide_ignition,
    _delay_s,
    _ignition_evidence,
    _pre_feed,
    _start_feed_rate_kg_h,
)
from hil_client.analysis.logio import LabLog
from rig_emulator.boilers import load_boiler


def _start_case(
    mass: np.ndarray, t: np.ndarray, starts: list[int], charge_kg: float = 0.0
) -> SimpleNamespace:
    """A log of the balance alone around its starts (no flue-gas velocity: the flame's fuel
    is not counted); ``charge_kg``: the burner's documented ignition charge."""
    firing = SimpleNamespace(starts=np.array(starts), stops=np.array([], dtype=int))
    return SimpleNamespace(
        t=t,
        balance=mass,
        firing=firing,
        params=load_boiler("windhager_6kw"),
        log=LabLog(Path("x.csv"), {"time_s": t}, {}),
        memo=lambda key, compute: compute(),
        ignition_charge_kg=charge_kg,
    )


def test_one_balance_step_at_one_start_is_not_evidence_of_a_pre_feed():
    """A balance that reads 0.02 kg less from 5 min before the onset on (one step of its
    resolution, Section 2.2: the true mass may have moved by anything from 0 to 0.04 kg)
    is no evidence, however many readings before and after average it: they all round
    the same way. Twenty starts each losing a sixth of a kilogram before the onset are."""
    t = np.arange(0.0, 3600.0, 1.0)
    onset = 2400
    mass = np.where(t < t[onset] - 300.0, 286.08, 286.06)
    units = _pre_feed(_start_case(mass, t, [onset]))
    assert len(units) == 1
    assert abs(units[0][0] - BALANCE_STEP_KG) < 1e-9
    named, z, _ = _decide_ignition(units)
    assert not named and z < Z_MIN
    fed = np.where(t < t[onset] - 240.0, 286.08, 285.92)  # 0.16 kg, 4 min of Pstart feed
    named, z, why = _decide_ignition(_pre_feed(_start_case(fed, t, [onset])) * 20)
    assert named, why


def test_a_documented_ignition_charge_is_taken_off_the_pre_feed():
    """A burner that drops its documented 0.10-kg charge and then feeds 0.06 kg more before
    the flame (a bed late to light): given the charge, only the 0.06 kg beyond it is read,
    as seconds of feed at Pstart; without it, all 0.16 kg is."""
    t = np.arange(0.0, 3600.0, 1.0)
    onset = 2400
    fed = np.where(t < t[onset] - 240.0, 286.08, 285.92)
    rate_kg_h = _start_feed_rate_kg_h(_start_case(fed, t, [onset]))
    [(beyond, _, _)] = _pre_feed(_start_case(fed, t, [onset], charge_kg=0.10))
    [(whole, _, _)] = _pre_feed(_start_case(fed, t, [onset]))
    assert beyond == pytest.approx(0.06, abs=1e-9) and whole == pytest.approx(0.16, abs=1e-9)
    assert _delay_s([(beyond, 0.005, rate_kg_h)]) == pytest.approx(0.06 / rate_kg_h * 3600.0)


def test_the_pre_feeds_evidence_and_its_floor_are_told_apart():
    """Twenty starts each losing 10 g before the flame at 3 kg/h of feed (12 s: a burner's
    own charge) are strong evidence of a pre-feed that stays below its floor; one start
    that loses 0.2 kg +- 0.2 kg (240 s of feed at 3 kg/h) is beyond the floor on too little
    evidence. Neither is named; the assessment tells which test stopped it."""
    many_small = [(0.010, 0.001, 3.0)] * 20
    named, z, why = _decide_ignition(many_small)
    assert not named and z > 10 * Z_MIN and "s of feed" in why
    assert _ignition_evidence(many_small)
    one_large = [(0.2, 0.2, 3.0)]
    assert not _decide_ignition(one_large)[0] and not _ignition_evidence(one_large)
    assert _delay_s(one_large) > PRE_FEED_MIN_S
    assert not _ignition_evidence([])


def test_a_log_that_begins_minutes_before_its_first_start_still_reads_the_pre_feed():
    """A logger started 13.5 min before the first onset (the auger may feed for up to 12 of
    them) leaves 1.5 min of quiet balance: the start is read, with the wider standard error
    of fewer readings; 12.5 min leaves half a minute, too little to read a mass from."""
    onset_s = 810.0
    t = np.arange(0.0, onset_s + 1800.0, 5.0)
    mass = np.where(t < onset_s - 240.0, 286.08, 285.92)  # 0.16 kg fed from 4 min before
    onset = int(np.searchsorted(t, onset_s))
    [(pre_feed, se, _)] = _pre_feed(_start_case(mass, t, [onset]))
    assert abs(pre_feed - 0.16) < 1e-9 and se > 0.0
    late = t >= 60.0
    assert _pre_feed(_start_case(mass[late], t[late] - 60.0, [onset - 12])) == []


def _slow_bed_case(
    o2_floor_pct: float, hold_s: float = 150.0, analyser_s: float = 30.0, trail_s: float = 0.0
) -> SimpleNamespace:
    """A 6-kW start at Pstart whose bed lights at once but lets its fuel wait ``hold_s`` (a
    pure lag of the feed) and burns out after the stop; the analyser sees the flame
    ``analyser_s`` late, its O2 falling from air to ``o2_floor_pct`` at full burn, and the
    flue-gas probe's onset trails the first feed by ``trail_s``; velocity and flue gas
    constant; the balance in 0.02-kg steps."""
    t = np.arange(0.0, 6000.0, 2.0)
    onset, stop = 2400.0, 3600.0
    rate = _start_feed_rate_kg_h(SimpleNamespace(params=load_boiler("windhager_6kw"))) / 3600.0
    fed = rate * np.clip(t - onset, 0.0, stop - onset)
    burning = rate * ((t > onset + hold_s) & (t < stop + hold_s))  # [kg/s]
    o2_true = 20.95 - (20.95 - o2_floor_pct) * burning / rate
    o2 = np.interp(t - analyser_s, t, o2_true)
    mass = np.round((286.0 - fed) / BALANCE_STEP_KG) * BALANCE_STEP_KG
    columns = {
        "time_s": t,
        "flue_gas_O2_pct": o2,
        "flue_gas_velocity_m_s": np.full(len(t), 1.2),
    }
    i_on = int(np.searchsorted(t, onset + trail_s))
    i_off = int(np.searchsorted(t, stop + hold_s))
    firing = SimpleNamespace(
        starts=np.array([i_on]),
        stops=np.array([i_off]),
        burning=(t >= onset + trail_s) & (t < stop + hold_s),
    )
    return SimpleNamespace(
        t=t,
        balance=mass,
        firing=firing,
        params=load_boiler("windhager_6kw"),
        log=LabLog(Path("x.csv"), columns, {}),
        lab={"flue_gas_temp_C": np.full(len(t), 110.0)},
        memo=lambda key, compute: compute(),
        ignition_charge_kg=0.0,
    )


def test_fuel_that_waits_in_a_lit_bed_is_counted_where_the_flue_gas_counts_the_flame():
    """A bed that lights at once shows no pre-feed before the onset, but 150 s of feed
    still wait in it five minutes later, which the flue gas's O2 and velocity against the
    balance read (the analyser's delay counted at the longest the log allows: its O2
    falls no sooner than 180 s after the onset, which shows no delay, so 45 s; 15 s of
    the 150 are credited to the flame: about 135 s). An air-starved flame (O2 down to
    1 %: fuel leaves unburnt as CO and tar) is not read that way: its start gives the
    pre-feed alone."""
    case = _slow_bed_case(o2_floor_pct=10.0)
    [(held, se, rate)] = _pre_feed(case)
    assert abs(held - 135.0 * rate / 3600.0) < 2.0 * se  # within its own two standard errors
    named, _, why = _decide_ignition([(held, se, rate)])
    assert named, why
    starved = _slow_bed_case(o2_floor_pct=1.0)
    [(pre_feed, _, _)] = _pre_feed(starved)
    assert abs(pre_feed) <= BALANCE_STEP_KG
    assert not _decide_ignition(_pre_feed(starved))[0]


def test_a_slow_analyser_is_not_taken_for_a_slow_bed():
    """A bed that burns what it is fed at once, seen through a 90-s sample line (twice the
    longest of a usual line): the O2 falls 90 s after the flue gas's onset, which the
    delay is read from (90 + 45 s at the longest), so no fuel is left waiting; read with a
    usual line's 45 s, 45 s of feed would have been."""
    units = _pre_feed(_slow_bed_case(o2_floor_pct=10.0, hold_s=0.0, analyser_s=90.0))
    [(held, se, rate)] = units
    assert abs(held) < 2.0 * se, held / rate * 3600.0
    assert not _decide_ignition(units)[0]


@pytest.mark.parametrize(
    ("line_s", "trail_s"), [(15.0, 0.0), (30.0, 45.0), (45.0, 10.0), (90.0, 30.0), (150.0, 45.0)]
)
def test_the_o2_is_advanced_by_no_less_than_the_lines_delay(line_s, trail_s):
    """Whatever the sample line (15-150 s) and however far the probe's onset trails the
    first feed (up to 45 s, where the O2 may fall before the onset), the flame's fuel is
    read with the O2 advanced by at least the line's delay: read any later, fuel the flame
    burnt is left in the bed (with a 90-s line and a 30-s trail, the log shows 60 s)."""
    case = _slow_bed_case(o2_floor_pct=10.0, hold_s=0.0, analyser_s=line_s, trail_s=trail_s)
    assert _analyser_delay_max_s(case) >= line_s
