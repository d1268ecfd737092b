"""Pure physics of the Type 869 pellet boiler: functions and small dataclasses, no I/O.

The step functions are compiled with numba and exchange flat arrays laid out as
:mod:`rig_emulator.model.layout` names them.
"""

from rig_emulator.model.boiler import (
    balance_residual_kW,
    new_outputs,
    new_state,
    pack_constants,
    step,
)
from rig_emulator.model.fuel import Fuel, Stoichiometry, stoichiometry
from rig_emulator.model.layout import (
    CUTOUT,
    MODE_NAMES,
    MODULATING,
    OFF,
    OUTPUT_FIELDS,
    STARTUP,
    STATE_FIELDS,
)
from rig_emulator.model.params import BoilerParams, ParameterError, params_from_mapping
from rig_emulator.model.steady_state import SteadyState, steady_state

__all__ = [
    "CUTOUT",
    "MODE_NAMES",
    "MODULATING",
    "OFF",
    "OUTPUT_FIELDS",
    "STARTUP",
    "STATE_FIELDS",
    "BoilerParams",
    "Fuel",
    "ParameterError",
    "SteadyState",
    "Stoichiometry",
    "balance_residual_kW",
    "new_outputs",
    "new_state",
    "pack_constants",
    "params_from_mapping",
    "steady_state",
    "step",
    "stoichiometry",
]
