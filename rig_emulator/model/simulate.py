"""Open-loop simulation of the boiler with measured inputs (as the paper validated it).

Carlon et al. (2015, Section 3.2) simulated the tests with the measured water flow, return
temperature, room conditions and on/off commands as inputs and the calibrated parameters
held constant. :func:`simulate` does the same: it steps the one-node model of
:mod:`rig_emulator.model.boiler` row by row (inputs held over each row's interval) and
returns every output of every step, by name (:data:`~rig_emulator.model.layout.OUTPUT_FIELDS`).

The controller decides once per step (Section 3.1's ideal controller), so a row longer than
:data:`MAX_STEP_S` (a gap in a lab log) is stepped in equal parts no longer than that: in one
900-s step the burner would fire on past the shut-off (110 C at zero flow). Such a row gives
what an instrument reads at its end (temperatures, mode, lambda and the gas composition) and
the flows and powers as means over it, so the balance still closes over the row.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig_emulator.model.boiler import new_state, step
from rig_emulator.model.layout import (
    N_OUTPUTS,
    OUTPUT_FIELDS,
    Y_CO,
    Y_CO2,
    Y_LAMBDA,
    Y_MODE,
    Y_O2,
    Y_SO2,
    Y_T_BOILER,
    Y_T_FG,
    Y_T_OUT,
    named,
)

#: Longest step the controller decides for [s]: at zero flow the 12-kW boiler heats by at
#: most 0.061 K/s at Pstart, so the water passes the shut-off by at most about 4 K.
MAX_STEP_S = 60.0
#: what a long row gives at its end (the rest are means over it)
_AT_END = np.array([Y_T_BOILER, Y_T_OUT, Y_T_FG, Y_MODE, Y_LAMBDA, Y_O2, Y_CO2, Y_SO2, Y_CO])


@njit(cache=True)
def _run(c, s, dt, flow, t_in, room, enabled, out):
    y = np.zeros(N_OUTPUTS)
    mean = np.zeros(N_OUTPUTS)
    for i in range(flow.size):
        parts = max(int(np.ceil(dt[i] / MAX_STEP_S)), 1)
        if parts == 1:
            step(c, s, flow[i], t_in[i], room[i], enabled[i], dt[i], y)
            out[i, :] = y
            continue
        mean[:] = 0.0
        for _ in range(parts):
            step(c, s, flow[i], t_in[i], room[i], enabled[i], dt[i] / parts, y)
            mean += y / parts
        for j in _AT_END:
            mean[j] = y[j]
        out[i, :] = mean


def simulate(
    c: np.ndarray,
    t_boiler0_C: float,
    dt_s: np.ndarray,
    flow_kg_h: np.ndarray,
    water_in_C: np.ndarray,
    room_C: np.ndarray,
    enabled: np.ndarray,
) -> dict[str, np.ndarray]:
    """Outputs of the model driven by measured inputs: one column per output name
    (:data:`~rig_emulator.model.layout.OUTPUT_FIELDS`), one row per step.

    Args:
        c: constants (``pack_constants``); t_boiler0_C: initial node temperature [C].
        dt_s: length of each row's step [s]; flow_kg_h [kg/h], water_in_C [C], room_C [C]:
            inputs held over the step; enabled: the bench's on/off command per step.
    """
    n = len(flow_kg_h)
    out = np.empty((n, N_OUTPUTS))
    _run(
        c,
        new_state(t_boiler0_C),
        np.ascontiguousarray(dt_s, dtype=np.float64),
        np.ascontiguousarray(flow_kg_h, dtype=np.float64),
        np.ascontiguousarray(water_in_C, dtype=np.float64),
        np.ascontiguousarray(room_C, dtype=np.float64),
        np.ascontiguousarray(enabled, dtype=np.bool_),
        out,
    )
    return named(OUTPUT_FIELDS, out)
