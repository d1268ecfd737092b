"""reality7: an independent simulated pellet-boiler test-bench plant.

A held-out "real boiler" for measuring the sim-to-real gap diagnosis (CONTRACT section 4):
a Windhager-type pellet boiler on the Wieselburg bench (Carlon et al. 2015), written from the
paper's balances (Eq. 1-10) but with its own controller, start-up, exchanger, bench and
instruments, plus optional structural effects.
"""

from __future__ import annotations

from .plant import COLUMNS, simulate_log, write_log_csv
from .quirks import EFFECT_FORMS, draw_background

__all__ = ["COLUMNS", "EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]
