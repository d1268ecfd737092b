"""Pure physics of the Type 869 pellet boiler: functions and small dataclasses, no I/O."""

from rig_emulator.model.boiler import (
    CUTOUT,
    MODE_NAMES,
    MODULATING,
    OFF,
    STARTUP,
    BoilerCoefficients,
    BoilerOutputs,
    BoilerState,
    coefficients,
    step,
)
from rig_emulator.model.fuel import Fuel, Stoichiometry, excess_air_ratio, stoichiometry
from rig_emulator.model.params import BoilerParams, ParameterError, params_from_mapping
from rig_emulator.model.steady_state import SteadyState, steady_state

__all__ = [
    "CUTOUT",
    "MODE_NAMES",
    "MODULATING",
    "OFF",
    "STARTUP",
    "BoilerCoefficients",
    "BoilerOutputs",
    "BoilerParams",
    "BoilerState",
    "Fuel",
    "ParameterError",
    "SteadyState",
    "Stoichiometry",
    "coefficients",
    "excess_air_ratio",
    "params_from_mapping",
    "steady_state",
    "step",
    "stoichiometry",
]
