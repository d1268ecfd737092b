"""Flue-gas CO published by the analyser: a simple documented model.

Not part of Type 869; the paper's chemical loss (Eq. 6) needs a CO level and the bench's
analyser shows one. Assumptions (ours, typical of small pellet boilers under EN 303-5):

- in stationary firing the CO level falls linearly from ``co_ppm_at_p_min`` at Pmin to
  ``co_ppm_at_p_max`` at Pmax (poorer burn-out at low load and high excess air);
- each ignition adds a peak ``co_start_peak_ppm`` decaying with ``co_transient_s``;
- each stop leaves a burn-out peak ``co_stop_peak_ppm`` decaying with the same time constant,
  diluted in the draught air that then flows through the idle boiler.
"""

from __future__ import annotations

import math


def co_ppm(
    firing_kW: float,
    p_min_kW: float,
    p_max_kW: float,
    co_at_p_min: float,
    co_at_p_max: float,
    start_peak: float,
    stop_peak: float,
    transient_s: float,
    since_start_s: float,
    since_stop_s: float,
) -> float:
    """CO concentration in the dry flue gas [ppm].

    Args:
        firing_kW: current firing power [kW], 0 when the burner is off.
        since_start_s / since_stop_s: time since the last ignition / stop [s] (inf if never).
    """
    if firing_kW > 0.0:
        span = p_max_kW - p_min_kW
        x = (firing_kW - p_min_kW) / span if span > 0 else 1.0
        x = min(max(x, 0.0), 1.0)
        base = co_at_p_min + (co_at_p_max - co_at_p_min) * x
        return base + start_peak * math.exp(-since_start_s / transient_s)
    return stop_peak * math.exp(-since_stop_s / transient_s)
