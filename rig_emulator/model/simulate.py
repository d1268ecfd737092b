"""Open-loop simulation of the boiler with measured inputs (as the paper validated it).

Carlon et al. (2015, Section 3.2) simulated the tests with the measured water flow, return
temperature, room conditions and on/off commands as inputs and the calibrated parameters
held constant. :func:`simulate` does the same: it steps the one-node model of
:mod:`rig_emulator.model.boiler` row by row (inputs held over each row's interval) and
returns every output of every step, by name (:data:`~rig_emulator.model.layout.OUTPUT_FIELDS`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rig_emulator.model.boiler import new_state, step
from rig_emulator.model.layout import N_OUTPUTS, OUTPUT_FIELDS, named


@njit(cache=True)
def _run(c, s, dt, flow, t_in, room, enabled, out):
    y = np.zeros(N_OUTPUTS)
    for i in range(flow.size):
        step(c, s, flow[i], t_in[i], room[i], enabled[i], dt[i], y)
        out[i, :] = y


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
