"""``outlet_sensor_pipe``: the forward sensor about 30 cm down the exit pipe, predicted from
the *measured* boiler water through a mixed pipe volume fed by the flow, losing heat to the
room and coupled to the boiler by conduction (:func:`hil_client.analysis.augment.pipe_sensor`);
read on the rows of low flow and stagnation.
"""

from __future__ import annotations

import numpy as np

from hil_client.analysis.augment import first_order_lag, pipe_sensor
from hil_client.analysis.candidates.base import CurveCandidate, straight_line
from hil_client.analysis.candidates.windows import low_flow_blocks
from hil_client.analysis.replay import Case
from rig_emulator.model.water_heat import heat_to_water_kW


def _pipe_water(case: Case, water: np.ndarray, theta: dict[str, float]) -> np.ndarray:
    """The water at the forward sensor, fed by ``water`` through the pipe of ``theta``."""
    return pipe_sensor(
        water,
        case.flow,
        case.room,
        case.dt,
        theta["pipe_kg"],
        theta["tau_loss_s"],
        theta["tau_coupling_s"],
    )


def _pipe_predict(case: Case, theta: dict[str, float] | None) -> np.ndarray:
    water = case.lab["boiler_water_temp_C"]
    if theta is None:
        return water
    pipe = _pipe_water(case, water, theta)
    return first_order_lag(pipe, case.dt, case.sensor_tau_s["water_out_temp_C"])


class PipeCandidate(CurveCandidate):
    """The exit pipe. Its residual is taken relative to a straight line per run of low
    flow (offset and drift of the two sensors over the run, which a lab's Pt100s have and
    which extrapolating the settled rows' drift over an 8-h stagnation gets wrong by tenths
    of a kelvin): only the curvature of a pipe's cooling toward the room, or its transport
    delay, counts as evidence. A real pipe's cooling (time constant 20 min to a few hours,
    Section 2.2's 30 cm of pipe) is far from straight over a stagnation of hours.
    The pipe also moves the heat to water the lab computes from the forward reading
    (Eq. 7)."""

    def residual(self, case: Case, theta: dict[str, float] | None) -> np.ndarray:
        r = super().residual(case, theta)
        runs: dict[int, list[np.ndarray]] = {}
        for _, rows, anchor in case.memo(("blocks", self.effect), lambda: self.blocks(case)):
            runs.setdefault(anchor, []).append(rows)
        for pieces in runs.values():
            rows = np.concatenate(pieces)
            ok = rows[np.isfinite(r[rows])]
            if len(ok) >= 3 and np.ptp(case.t[ok]) > 0:
                slope, intercept = straight_line(case.t[ok] - case.t[ok[0]], r[ok])
                r[rows] = r[rows] - (intercept + slope * (case.t[rows] - case.t[ok[0]]))
        return r

    def prediction(self, case: Case, theta: dict[str, float]) -> dict[str, np.ndarray]:
        pipe = _pipe_water(case, case.model["t_boiler_C"], theta)
        return {
            "water_out_temp_C": first_order_lag(
                pipe, case.dt, case.sensor_tau_s["water_out_temp_C"]
            ),
            "heat_to_water_kW": heat_to_water_kW(case.flow, case.t_in, pipe),
        }


PIPE = PipeCandidate(
    "outlet_sensor_pipe",
    "water_out_temp_C",
    "stand_by",
    {
        # a pipe of 30 cm holds 0.1-0.4 kg of water; up to 3 kg allowed
        "pipe_kg": np.geomspace(0.05, 3.0, 6),
        "tau_loss_s": np.geomspace(120.0, 1e5, 7),
        "tau_coupling_s": np.array([3e3, 1e4, 3e4, 1e9]),
    },
    _pipe_predict,
    low_flow_blocks,
    nuisance_drift=True,
)
