"""An independently written "reality" for the gap benchmark: a pellet boiler and its test
bench written from Carlon et al. (2015) and the test procedure, without the emulator's
model, bench or instruments and without the project's analysis.

API used by :mod:`hil_client.analysis.gap_benchmark`:

- :data:`EFFECT_FORMS`: each listed effect's functional forms (:mod:`.effects`);
- :func:`draw_background`: a random real boiler and bench around the documentation
  (:mod:`.background`);
- :func:`simulate_log`: one lab log (CONTRACT section 3 columns) and its meta
  (:mod:`.simulate`);
- :func:`write_log_csv`: the CSV (:mod:`.csvlog`).
"""

from hil_client.reality.background import draw_background
from hil_client.reality.csvlog import write_log_csv
from hil_client.reality.effects import EFFECT_FORMS, STRENGTH_RANGES
from hil_client.reality.simulate import simulate_log

__all__ = ["EFFECT_FORMS", "STRENGTH_RANGES", "draw_background", "simulate_log", "write_log_csv"]
