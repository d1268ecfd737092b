"""The low-load sequence of the load cycle (Carlon et al. 2015, Section 3.2.2, Fig. 7).

Below the boiler's modulation range (the 13 % step of Table 2) the bench, having no buffer
tank, cannot take the boiler's minimum output: the water heats to the shut-off temperature
(85 C), the boiler stops, the body gives its heat to the circulating water until the water is
back at the restart temperature (55 C, "after 1.5 h"), the boiler restarts with a full
start-up at Pstart, reaches 85 C again and stops a second time. The paper then reports the
water inside the boiler at 57 C at t2 and a first cooling (t2..t3) of about five minutes.

:func:`low_load_sequence` reads these events from a run's rows (:data:`LOG_COLUMNS` order,
as :func:`~hil_client.protocol.runner.run_protocol` hands them to its sink) so that tests and
``make bench`` measure the same figures.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from hil_client.protocol.runner import LOG_COLUMNS

#: Figures of the paper's 12 kW load cycle (Section 3.2.2, Fig. 7).
PAPER_COOL_BACK_H = 1.5  # first stop to the restart at 55 C: "reached 55 C after 1.5 h"
PAPER_T_AT_T2_C = 57.0  # "the water temperature inside the boiler was 57 C" at t2
PAPER_FIRST_COOLING_MIN = 5.0  # "The 2 K decrease ... took approximately five minutes"

_T = LOG_COLUMNS.index("time_s")
_SEQUENCE = LOG_COLUMNS.index("sequence")
_ON = LOG_COLUMNS.index("boiler_on")
_T_BOILER = LOG_COLUMNS.index("boiler_water_temp_C")


@dataclass(frozen=True, slots=True)
class LowLoadSequence:
    """Burner stops and starts within one step of the measuring cycle, and the figures the
    paper reports for it (times in s since the record start)."""

    stops_s: tuple[float, ...]  #: burner stops within the step
    starts_s: tuple[float, ...]  #: burner starts within the step
    stop_temps_C: tuple[float, ...]  #: water inside the boiler on the row before each stop
    cool_back_h: float  #: first stop to the next start [h] (nan if none)
    t_boiler_at_t2_C: float  #: water inside the boiler at t2 [C]
    first_cooling_min: float  #: t2..t3 [min]


def low_load_sequence(
    rows: Sequence[Sequence[object]], times: Mapping[str, float], step: str = "stationary_13"
) -> LowLoadSequence:
    """Read the low-load sequence of ``step`` from a run's rows and its t0..t4 ``times``."""
    index = [i for i, row in enumerate(rows) if row[_SEQUENCE] == step]
    if not index:
        raise ValueError(f"no rows of the sequence {step!r}")
    stops, starts, stop_temps = [], [], []
    for i in index[1:]:
        was_on, on = float(rows[i - 1][_ON]) >= 0.5, float(rows[i][_ON]) >= 0.5
        if was_on and not on:
            stops.append(float(rows[i][_T]))
            stop_temps.append(float(rows[i - 1][_T_BOILER]))
        elif on and not was_on:
            starts.append(float(rows[i][_T]))
    later = [t for t in starts if stops and t > stops[0]]
    cool_back_h = (later[0] - stops[0]) / 3600.0 if later else float("nan")
    t2, t3 = times["t2_s"], times["t3_s"]
    at_t2 = next(row for row in rows if float(row[_T]) >= t2)
    return LowLoadSequence(
        stops_s=tuple(stops),
        starts_s=tuple(starts),
        stop_temps_C=tuple(stop_temps),
        cool_back_h=cool_back_h,
        t_boiler_at_t2_C=float(at_t2[_T_BOILER]),
        first_cooling_min=(t3 - t2) / 60.0,
    )
