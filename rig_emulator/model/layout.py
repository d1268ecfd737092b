"""Data layout of the compiled model: the names of its constant, state and output arrays.

The step functions are compiled with numba and exchange flat float64 arrays. Each array
family is declared once here, as a tuple of names in index order; the indices (``K_*``,
``S_*``, ``Y_*``) and the sizes are generated from that tuple, so no second list can fall
out of step with it. Code outside the kernels reads arrays by name (:func:`named`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def index_of(fields: Sequence[str]) -> dict[str, int]:
    """Name -> index of a declared array family (the names must be unique)."""
    index = {name: i for i, name in enumerate(fields)}
    if len(index) != len(fields):
        raise ValueError(f"duplicate names in {fields!r}")
    return index


def named(fields: Sequence[str], array: np.ndarray) -> dict:
    """The last axis of ``array`` by name: floats for a 1-D array, columns for a 2-D one."""
    if array.shape[-1] != len(fields):
        raise ValueError(f"array has {array.shape[-1]} fields, the layout {len(fields)}")
    if array.ndim == 1:
        return {name: float(array[i]) for i, name in enumerate(fields)}
    return {name: array[..., i] for i, name in enumerate(fields)}


# --- constants (derived once from BoilerParams by boiler.pack_constants)
CONSTANT_FIELDS = (
    "hhv",  # gross calorific value, dry [kJ/kg]
    "lhv",  # net calorific value, dry [kJ/kg]
    "cap",  # node capacity, structure plus water [kJ/K]
    "ua_on",  # loss coefficient while firing [kW/K]
    "ua_off",  # loss coefficient when idle [kW/K]
    "a0",  # dry flue-gas mass = A0 + A1 lambda [kg/kg dry fuel]
    "a1",
    "b0",  # dry flue-gas heat capacity = B0 + B1 lambda [kJ/(K kg dry fuel)]
    "b1",
    "mh2o_cp",  # vapour mass times cp_vap [kJ/(K kg dry fuel)]
    "latent",  # latent heat of the vapour [kJ/kg dry fuel]
    "vdry0",  # dry flue-gas volume = VDRY0 + VDRY1 lambda [m3(N)/kg dry fuel]
    "vdry1",
    "vh2o",  # vapour volume [m3(N)/kg dry fuel]
    "vo2_per_lambda",  # O2 volume = VO2_PER_LAMBDA (lambda - 1) [m3(N)/kg]
    "vco2",  # [m3(N)/kg]
    "vso2",  # [m3(N)/kg]
    "fuel_nom",  # dry fuel flow at Pmax [kg/h]
    "flow_nom",  # nominal water flow [kg/h]
    "as_received",  # as-received fuel per kg dry fuel [-]
    "ignition",  # Wel spread over the start-up [kW]
    "chem_per_ppm",  # chemical loss per ppm CO per m3(N) dry gas [kJ]
    "inv_span",  # 1 / (Pmax - Pmin) [1/kW]
    "pel_slope",  # (Pel,MAX - Pel,MIN) / (Pmax - Pmin) [W/kW]
    "p_max",  # [kW]
    "p_min",  # [kW]
    "p_start",  # [kW]
    "dt_nom",  # [K]
    "dt_hx_fg",  # [K]
    "dt_hx_wat",  # [K]
    "fac_a",  # [-]
    "fac_b",  # [h/kg]
    "pel_min",  # [W]
    "pel_off",  # [W]
    "set",  # [C]
    "shutoff",  # [C]
    "handover_limit",  # [C] below which Pmin must hold the water for a start-up to hand over
    "restart",  # [C]
    "startup_s",  # [s]
    "co_pmin",  # [ppm]
    "co_pmax",  # [ppm]
    "co_start",  # [ppm]
    "co_stop",  # [ppm]
    "co_tau",  # [s]
)
K = index_of(CONSTANT_FIELDS)
K_HHV = K["hhv"]
K_LHV = K["lhv"]
K_CAP = K["cap"]
K_UA_ON = K["ua_on"]
K_UA_OFF = K["ua_off"]
K_A0 = K["a0"]
K_A1 = K["a1"]
K_B0 = K["b0"]
K_B1 = K["b1"]
K_MH2O_CP = K["mh2o_cp"]
K_LATENT = K["latent"]
K_VDRY0 = K["vdry0"]
K_VDRY1 = K["vdry1"]
K_VH2O = K["vh2o"]
K_VO2_PER_LAMBDA = K["vo2_per_lambda"]
K_VCO2 = K["vco2"]
K_VSO2 = K["vso2"]
K_FUEL_NOM = K["fuel_nom"]
K_FLOW_NOM = K["flow_nom"]
K_AS_RECEIVED = K["as_received"]
K_IGNITION = K["ignition"]
K_CHEM_PER_PPM = K["chem_per_ppm"]
K_INV_SPAN = K["inv_span"]
K_PEL_SLOPE = K["pel_slope"]
K_P_MAX = K["p_max"]
K_P_MIN = K["p_min"]
K_P_START = K["p_start"]
K_DT_NOM = K["dt_nom"]
K_DT_HX_FG = K["dt_hx_fg"]
K_DT_HX_WAT = K["dt_hx_wat"]
K_FAC_A = K["fac_a"]
K_FAC_B = K["fac_b"]
K_PEL_MIN = K["pel_min"]
K_PEL_OFF = K["pel_off"]
K_SET = K["set"]
K_SHUTOFF = K["shutoff"]
K_HANDOVER_LIMIT = K["handover_limit"]
K_RESTART = K["restart"]
K_STARTUP_S = K["startup_s"]
K_CO_PMIN = K["co_pmin"]
K_CO_PMAX = K["co_pmax"]
K_CO_START = K["co_start"]
K_CO_STOP = K["co_stop"]
K_CO_TAU = K["co_tau"]
N_CONSTANTS = len(CONSTANT_FIELDS)

# --- boiler state
STATE_FIELDS = (
    "t_boiler_C",  # node temperature [C]
    "mode",  # controller mode (OFF, STARTUP, MODULATING, CUTOUT)
    "mode_time_s",  # time in the current mode [s]
    "firing_kW",  # firing power of the last step, net basis [kW]
    "since_start_s",  # time since the last ignition [s]
    "since_stop_s",  # time since the last stop [s]
    "fuel_dry_kg",  # dry fuel burnt so far [kg]
    "electric_Wh",  # electricity drawn so far [Wh]
    "starts",  # ignitions so far
    "no_demand",  # 1: stopped for no demand (switched on at or above the set temperature)
)
S = index_of(STATE_FIELDS)
S_T = S["t_boiler_C"]
S_MODE = S["mode"]
S_MODE_TIME = S["mode_time_s"]
S_FIRING = S["firing_kW"]
S_SINCE_START = S["since_start_s"]
S_SINCE_STOP = S["since_stop_s"]
S_FUEL = S["fuel_dry_kg"]
S_ELECTRIC = S["electric_Wh"]
S_STARTS = S["starts"]
S_NO_DEMAND = S["no_demand"]
N_STATE = len(STATE_FIELDS)

# --- boiler outputs of one step (temperatures at the end, heat flows as step means)
OUTPUT_FIELDS = (
    "t_boiler_C",  # [C]
    "t_out_C",  # [C] (= T_boiler, Type 869 assumption)
    "t_flue_gas_C",  # flue-gas temperature [C]
    "mode",
    "firing_kW",  # [kW, net]
    "fuel_dry_kg_h",  # dry fuel flow [kg/h]
    "lambda",  # excess-air ratio [-] (inf when idle)
    "o2_pct",  # [vol-%, dry]
    "co2_pct",  # [vol-%, dry]
    "so2_ppm",  # [ppm, dry]
    "co_ppm",  # [ppm, dry]
    "flue_gas_dry_kg_h",  # dry flue-gas mass flow [kg/h]
    "flue_gas_wet_m3n_h",  # wet flue-gas volume flow [m3(N)/h]
    "q_fuel_kW",  # [kW]
    "q_el_ign_kW",  # [kW]
    "q_ash_kW",  # [kW]
    "q_fg_sens_kW",  # [kW]
    "q_fg_lat_kW",  # [kW]
    "q_fg_chem_kW",  # [kW]
    "q_hx_kW",  # [kW]
    "q_water_kW",  # [kW]
    "q_amb_kW",  # [kW]
    "q_stored_kW",  # [kW]
    "p_el_W",  # [W]
)
Y = index_of(OUTPUT_FIELDS)
Y_T_BOILER = Y["t_boiler_C"]
Y_T_OUT = Y["t_out_C"]
Y_T_FG = Y["t_flue_gas_C"]
Y_MODE = Y["mode"]
Y_FIRING = Y["firing_kW"]
Y_FUEL = Y["fuel_dry_kg_h"]
Y_LAMBDA = Y["lambda"]
Y_O2 = Y["o2_pct"]
Y_CO2 = Y["co2_pct"]
Y_SO2 = Y["so2_ppm"]
Y_CO = Y["co_ppm"]
Y_FG_DRY = Y["flue_gas_dry_kg_h"]
Y_FG_WET = Y["flue_gas_wet_m3n_h"]
Y_Q_FUEL = Y["q_fuel_kW"]
Y_Q_IGN = Y["q_el_ign_kW"]
Y_Q_ASH = Y["q_ash_kW"]
Y_Q_SENS = Y["q_fg_sens_kW"]
Y_Q_LAT = Y["q_fg_lat_kW"]
Y_Q_CHEM = Y["q_fg_chem_kW"]
Y_Q_HX = Y["q_hx_kW"]
Y_Q_WATER = Y["q_water_kW"]
Y_Q_AMB = Y["q_amb_kW"]
Y_Q_STORED = Y["q_stored_kW"]
Y_P_EL = Y["p_el_W"]
N_OUTPUTS = len(OUTPUT_FIELDS)

# Controller modes.
OFF = 0  #: switched off by the external command
STARTUP = 1  #: firing at Pstart after a start
MODULATING = 2  #: firing between Pmin and Pmax to hold the set temperature
#: stopped, waiting to start: after a cut-out at the shut-off temperature, for the restart
#: temperature; switched on with the water at or above the set temperature, for the water
#: to fall to it
CUTOUT = 3
MODE_NAMES = {OFF: "off", STARTUP: "start_up", MODULATING: "modulating", CUTOUT: "cut_out"}
