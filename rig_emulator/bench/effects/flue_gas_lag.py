"""``flue_gas_lag``: heat exchanger and refractory store heat, so the flue-gas temperature
follows load changes with a time constant instead of at once.

The flue-gas temperature follows its Eq. 8 value (while the bed burns; the water
temperature otherwise) through two first-order nodes in series, the exchanger surface
(tau (1 - r)) and the refractory (tau r): an S-shaped response of mean delay tau. The losses
(Eq. 4) use the lagged temperature and the heat to the exchanger is the remainder (Eq. 1),
so what the cold exchanger takes from the gas goes to the body: energy is conserved.

Numerics: the two nodes are solved exactly over the step (:func:`lag2`).

Stage: ``flue_gas``.
"""

from __future__ import annotations

import math

from numba import njit

from rig_emulator.bench.effects._spec import EffectSpec, ParamSpec
from rig_emulator.model.layout import index_of

CONSTANTS = ("on", "exchanger_time_constant_s", "refractory_time_constant_s")
C = index_of(CONSTANTS)
C_ON, C_TAU1, C_TAU2 = (
    C["on"], C["exchanger_time_constant_s"], C["refractory_time_constant_s"]
)  # fmt: skip

STATE = ("exchanger_C", "flue_gas_C")  # exchanger node; refractory node = flue gas
S = index_of(STATE)
S_FG1, S_FG2 = S["exchanger_C"], S["flue_gas_C"]


@njit(cache=True)
def lag2(y1, y2, u, tau1, tau2, dt_s):
    """Two first-order nodes in series, y1 -> u (tau1), y2 -> y1 (tau2), input held.

    Exact: y1(t) = u + (y1_0 - u) e1, y2(t) = u + (y2_0 - u) e2 + (y1_0 - u) K with
    e_i = exp(-t/tau_i) and K = tau1 (e1 - e2) / (tau1 - tau2), or (t/tau) e for equal
    time constants. A zero time constant makes its node follow its input at once.
    Returns (y1, y2) at the end of the step.
    """
    if tau1 <= 0.0:
        y1n = u
        if tau2 <= 0.0:
            return u, u
        return y1n, u + (y2 - u) * math.exp(-dt_s / tau2)
    e1 = math.exp(-dt_s / tau1)
    y1n = u + (y1 - u) * e1
    if tau2 <= 0.0:
        return y1n, y1n
    e2 = math.exp(-dt_s / tau2)
    equal = abs(tau1 - tau2) <= 1e-9 * tau1
    kk = dt_s / tau1 * e1 if equal else tau1 * (e1 - e2) / (tau1 - tau2)
    return y1n, u + (y2 - u) * e2 + (y1 - u) * kk


@njit(cache=True, inline="always")
def flue_gas(fc, fs, row, t_target_C, dt_s):
    """``flue_gas``: flue-gas temperature [C], the target through the two-node lag if on."""
    if fc[row, C_ON] < 0.5:
        return t_target_C
    fs[row, S_FG1], fs[row, S_FG2] = lag2(
        fs[row, S_FG1], fs[row, S_FG2], t_target_C, fc[row, C_TAU1], fc[row, C_TAU2], dt_s
    )
    return fs[row, S_FG2]


EFFECT = EffectSpec(
    name="flue_gas_lag",
    params=(
        ParamSpec(
            "time_constant_s",
            "s",
            150.0,
            "linear",
            0.0,
            3600.0,
            doc="tau, the mean delay of the flue-gas temperature",
        ),
        ParamSpec(
            "refractory_share",
            "-",
            0.5,
            "shape",
            0.0,
            1.0,
            doc="r, the refractory's share of tau (0 or 1: a single first-order lag)",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: v["time_constant_s"] > 0.0,
    stages={"flue_gas": flue_gas},
    constants=CONSTANTS,
    state=STATE,
    pack=lambda v, params: {
        "exchanger_time_constant_s": v["time_constant_s"] * (1.0 - v["refractory_share"]),
        "refractory_time_constant_s": v["time_constant_s"] * v["refractory_share"],
    },
    initial_state=lambda t_C: dict.fromkeys(STATE, t_C),
)
