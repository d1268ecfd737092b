"""reality4: an independently written pellet-boiler test-bench plant producing blind lab logs."""

from hil_client.reality4.plant import EFFECT_FORMS, draw_background, simulate_log, write_log_csv

__all__ = ["EFFECT_FORMS", "draw_background", "simulate_log", "write_log_csv"]
