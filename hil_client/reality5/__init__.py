"""Plant 5: an independent pellet-boiler test-bench "reality" for the blind diagnosis benchmark.

Physics after Carlon et al. (2015), Type 869 (paper Eq. 1-16), with a real boiler's differences
drawn per case (see ``background``): a stepped-PI burner controller with quantised modulation and
low-load / overheat stops, pre-purge, igniter lighting time, fuel ramp, post-purge and bed
burn-out, pulsed auger, load-dependent exchanger with fouling and spiral cleaning, natural-draught
stand-by losses, a capacity-limited bench, and instruments with offsets, drifts, lags, noise,
an analyser sample-line delay and auto-zero gaps, and a 0.02 kg balance under the hopper.
"""

from .background import EFFECT_FORMS, draw_background
from .plant import simulate_log, write_log_csv

__all__ = ["EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]
