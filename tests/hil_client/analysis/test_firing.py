"""The firing the diagnosis replays, read from the flue gas (hil_client.analysis.firing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hil_client.analysis.firing import O2_BURNING_PCT, _join_flicker, observe_firing
from hil_client.analysis.logio import LabLog


def _log(t, o2, t_fg) -> LabLog:
    water = np.full_like(t, 60.0)
    return LabLog(
        Path("synthetic.csv"),
        {"time_s": t, "flue_gas_O2_pct": o2, "flue_gas_temp_C": t_fg, "boiler_water_temp_C": water},
        {},
    )


def test_start_and_stop_follow_the_flue_gas_not_the_delayed_analyser():
    """A burn from 600 s to 3600 s: the probe's flue gas answers at once, the analyser's
    O2 40 s later (its sample line); the replayed firing starts and stops with the flame."""
    t = np.arange(0.0, 5400.0, 2.0)
    flame = (t >= 600.0) & (t < 3600.0)
    t_fg = np.where(flame, 150.0, 60.0) + 0.5 * np.sin(t / 30.0)  # a few tenths of modulation
    delayed = (t >= 640.0) & (t < 3640.0)
    o2 = np.where(delayed, 8.0, 20.9)
    firing = observe_firing(_log(t, o2, t_fg))
    assert o2[firing.starts[0]] > O2_BURNING_PCT  # earlier than the O2 crossing ...
    assert abs(t[firing.starts[0]] - 600.0) <= 2.0  # ... at the flame's start
    assert abs(t[firing.stops[0]] - 3600.0) <= 2.0  # and at its end, not 40 s later
    assert firing.burning[(t > 610) & (t < 3590)].all()
    assert not firing.burning[(t > 3602) & (t < 3700)].any()


def _with_balance(log: LabLog, mass) -> LabLog:
    return LabLog(log.path, {**log.columns, "balance_mass_kg": mass}, {})


def test_a_bed_burning_out_without_feed_is_not_a_start():
    """A burn from 600 s to 3600 s, then the bed smoulders on the draught for 12 min
    (O2 low again, the flue gas falling, the balance still): the burner started once. A
    second burn with feed from 6000 s is a start."""
    t = np.arange(0.0, 9000.0, 2.0)
    flame = (t >= 600.0) & (t < 3600.0) | (t >= 6000.0) & (t < 8000.0)
    smoulder = (t >= 3800.0) & (t < 4520.0)
    t_fg = np.where(flame, 150.0, 60.0)
    t_fg = np.where(smoulder, 110.0 - (t - 3800.0) / 30.0, t_fg)
    o2 = np.where(flame, 8.0, np.where(smoulder, 0.5, 20.9))
    fed = np.clip(t - 600.0, 0.0, 3000.0) + np.clip(t - 6000.0, 0.0, 2000.0)  # [s of feed]
    mass = np.round((300.0 - fed * 0.001) / 0.02) * 0.02  # 3.6 kg/h on a 0.02-kg balance
    firing = observe_firing(_with_balance(_log(t, o2, t_fg), mass))
    assert [t[i] for i in firing.starts] == [600.0, 6000.0]
    assert [t[i] for i in firing.stops] == [3600.0, 8000.0]
    assert not firing.burning[smoulder].any()
    without_balance = observe_firing(_log(t, o2, t_fg))  # no balance: cannot tell, kept
    assert len(without_balance.starts) == 3
    refilled = mass + np.where(t >= 4000.0, 10.0, 0.0)  # a refill during the smoulder
    assert len(observe_firing(_with_balance(_log(t, o2, t_fg), refilled)).starts) == 3


def test_a_stop_and_a_start_closer_than_a_run_are_one_burn():
    """Refining a stop and the next start by the flue gas can leave them 20 s apart (a bed
    burning out on the fan's air dips the flue gas and the O2 in turn): one burn."""
    t = np.arange(0.0, 6000.0, 2.0)
    burning = (t >= 600.0) & (t < 5000.0)
    burning[(t >= 3000.0) & (t < 3020.0)] = False
    starts = np.flatnonzero(t == 600.0).tolist() + np.flatnonzero(t == 3020.0).tolist()
    stops = np.flatnonzero(t == 3000.0).tolist() + np.flatnonzero(t == 5000.0).tolist()
    starts, stops = _join_flicker(burning, t, np.array(starts), np.array(stops))
    assert [t[i] for i in starts] == [600.0] and [t[i] for i in stops] == [5000.0]
    assert burning[(t >= 600.0) & (t < 5000.0)].all()
