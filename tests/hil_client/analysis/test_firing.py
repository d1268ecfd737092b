"""The firing the diagnosis replays, read from the flue gas (hil_client.analysis.firing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hil_client.analysis.firing import O2_BURNING_PCT, observe_firing
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
