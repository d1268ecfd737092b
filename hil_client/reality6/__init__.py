"""Reality 6: an independently written pellet-boiler test-bench plant ("reality").

A simulated lab test of one pellet boiler on the Wieselburg bench (Carlon et al. 2015,
Applied Energy 138, 505-516), logged the way a real acquisition system would.  The physics
follows the paper's Type 869 balances (Eq. 1-16: combustion and flue-gas losses Eq. 1, 3-6, 9;
heat-exchanger balance Eq. 2, 7; stand-by losses Eq. 10-16), but the plant is a "real" boiler:
its own burner controller, start-up and shut-down sequence, exchanger law, bed dynamics, bench
and instruments, drawn per case by `draw_background` (background.py), so that the gap to the
paper's model is of the size of the paper's Table 4.  One of the five listed effects
(CONTRACT section 4) can be added in one of several forms (effects.py).

Public interface:
* EFFECT_FORMS: effect name -> its form names.
* draw_background(rng, boiler) -> dict of floats.
* simulate_log(boiler, test, *, background, effect, form, strength, seed, sample_s=1.0,
  jitter=False) -> (columns, meta).
* write_log_csv(columns, path).

Modules: combustion (stoichiometry), protocol (the test schedule from the protocol YAML),
kernel (the per-second plant and bench, numba), instruments (the acquisition), background,
effects, simulate.  Imports only numpy, numba, yaml and the standard library.
"""

from .background import draw_background
from .effects import EFFECT_FORMS
from .simulate import simulate_log, write_log_csv

__all__ = ["EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]
