"""Index constants of the flat parameter vector and of the record array of the kernel.

The numba kernel takes every plant, controller, bench and sensor parameter in one float64
vector ``p`` and writes its per-step results into one 2-D array ``rec``. The names below are
plain module-level integers, so numba folds them into constants at compile time.
"""

from __future__ import annotations

import numpy as np

PARAM_NAMES: tuple[str, ...] = (
    # fuel and combustion (Eq. 3-6, 9; Table 1)
    "HHV",  # HHV of the fuel actually burnt, dry basis [kJ/kg]
    "FC",  # carbon, mass fraction of dry fuel
    "FH",  # hydrogen
    "FO",  # oxygen
    "FN",  # nitrogen
    "FS",  # sulphur
    "FASH",  # ash
    "MOIST",  # moisture, as received
    "FC_BG",  # fraction of the fuel carbon leaving unburnt in the ash (background)
    "FC_NOM",  # extra unburnt carbon fraction at nominal burn rate (fuel form B)
    "FC_EXP",  # exponent of its growth with the burn rate
    "F_BC",  # fraction of the released heat lost from the combustion chamber to the room
    "LHV_AR_DOC",  # controller's nominal net calorific value, as received [kJ/kg]
    "K_AUGER",  # delivered / nominal auger mass per revolution
    "FAC_A",  # Eq. 9 coefficients used by the fan controller
    "FAC_B",
    "K_LAMBDA",  # real / documented excess-air ratio
    "LAMBDA_MIN",
    "AIRMIN_DOC",  # stoichiometric air of the documented fuel [Nm3/kg dry]
    "R_DRY_NOM",  # dry burn rate at nominal load (calibration point) [kg/h]
    # thermal body (Eq. 2, 10)
    "C_M",  # exchanger steel [kJ/K]
    "C_W",  # boiler water, well-mixed part [kJ/K]
    "G_MW",  # steel -> water conductance [kW/K]
    "UA_ENV",  # casing loss to the room [kW/K]
    "K_NAT",  # natural draught through the idle boiler [Nm3/h per sqrt(K)]
    "UA_NOM",  # flue-gas side conductance at W_REF [kW/K]
    "W_REF",  # flue-gas heat-capacity flow at the calibration point [kW/K]
    "N_UA",  # exponent of the convective conductance with gas flow
    # body form A: radiant hot steel
    "C_H",
    "G_C",
    "K_RAD",  # [kW/K^4]
    # body form B: poorly circulated water jacket around the combustion chamber
    "C_D",
    "SIGMA_D",  # share of the gas-side surface that is the jacket pocket's wall
    "G_DB",  # pocket -> main water base conductance [kW/K]
    "DT_REF",  # pocket excess temperature at nominal load [K]
    "K_MIX_FLOW",  # forced-mixing factor 1 + k m/m_nom
    "EPS_MIN",  # conduction share of the exchange without buoyancy
    # flue form A: turbulator store
    "C_SP",
    "A_SP",
    "G_SW",
    # flue form B: air recuperator
    "C_R",
    "UA_RG",  # gas side conductance at W_REF [kW/K]
    "EPS_A",  # air side effectiveness
    # outlet pipe
    "PIPE_MODE",  # 0 none, 1 thermowell with bracket, 2 laminar pipe transit
    "C_P",
    "UA_P",
    "G_AX",  # stagnant pipe water <-> boiler water (natural convection at the connection)
    "V_PIPE",  # laminar pipe: water volume up to the sensor [kg]
    "TAU_LOSS",  # laminar pipe: parcel cooling time constant [s]
    "E_STAG",  # laminar pipe: share of T_boiler - T_room lost at long ages
    "C_S",
    "H_WELL_NOM",
    "H_WELL_0",
    "G_BR",
    "M_NOM",  # water flow at nominal load, 15 K spread [kg/h]
    "CP_W",
    # controller
    "P_MIN",
    "P_MAX",
    "P_START",
    "T_SET",
    "T_OFF",
    "DT_RESTART",
    "KP",
    "TI",
    "CTRL_OFFSET",
    "TAU_CTRL",
    "T_MIN_BURN",
    "T_MIN_OFF",
    "T_OFF_MAX",  # restart after this long off if the water is below T_SET - 10 K
    "T_PREPURGE",
    "T_CATCH",
    "T_DET",
    "T_IGN_ON",
    "P_IGN",  # [kW]
    "M_CHARGE",
    "R_IGN",
    "R_TOP",
    "M_CRIT",
    "T_RAMP",
    "T_HOLD_MIN",
    "DT_HOLD_EXIT",
    "T_POST",
    "TAU_BED",
    "T_AUGER",
    "R_AUGER_MAX",
    "IGN_FAIL",
    "T_FAIL",
    "T_PURGE_RETRY",
    "M_CHARGE2",
    "V_IGN_FRAC",
    "V_PURGE_FRAC",
    "V_POST_FRAC",
    "TAU_FAN",
    "T_IGN_MAX",
    "V_REF",  # fan air at nominal [Nm3/h]
    "CO_BASE",
    # electricity
    "P_EL_BASE",
    "P_EL_CTRL",
    "P_FAN_NOM",
    "P_AUGER_ON",
    # bench
    "C_B",
    "UA_B",
    "Q_CMAX",
    "Q_HMAX",
    "T_COLD",
    "KP_B",
    "TI_B",
    "TAU_VALVE",
    "TAU_FLOW",
    "VALVE_DB",  # dead band of the mixing-valve actuator (fraction of stroke)
    "T_FLOOR_C1",
    "P_NOM",
    # schedule
    "T_PREHEAT",
    "PREHEAT_TOL",
    "PREHEAT_HOLD",
    "PREHEAT_MIN",
    "PREHEAT_MAX",
    "PREHEAT_LOAD",
    "T_RET_SP",
    "SU_WINDOW",
    "SU_RISE",
    "SU_MIN",
    "SU_MAX",
    "C1_LOAD",
    "C1_UNTIL",
    "C1_MAX",
    "C2_AFTER",
    # sensors
    "TAU_TIN",
    "TAU_TOUT",
    "TAU_TBW",
    "TAU_FG0",
    "STRAT_BETA",
    "OFF_TOUT",
    "OFF_TIN",
    "OFF_TFG",
    "N_DELAY",
    "TAU_O2",
    "TAU_CO2",
    "TAU_CO",
    "A_DUCT",
    # forced (open-loop) mode, used by the steady-state test
    "FORCE_P",
    "FORCE_M",
    "FORCE_TIN",
    "FORCE_TROOM",
    # initial state and integration
    "T_INIT",
    "T_INIT_BENCH",
    "DT",
    "N_SUB",
)

(
    HHV,
    FC,
    FH,
    FO,
    FN,
    FS,
    FASH,
    MOIST,
    FC_BG,
    FC_NOM,
    FC_EXP,
    F_BC,
    LHV_AR_DOC,
    K_AUGER,
    FAC_A,
    FAC_B,
    K_LAMBDA,
    LAMBDA_MIN,
    AIRMIN_DOC,
    R_DRY_NOM,
    C_M,
    C_W,
    G_MW,
    UA_ENV,
    K_NAT,
    UA_NOM,
    W_REF,
    N_UA,
    C_H,
    G_C,
    K_RAD,
    C_D,
    SIGMA_D,
    G_DB,
    DT_REF,
    K_MIX_FLOW,
    EPS_MIN,
    C_SP,
    A_SP,
    G_SW,
    C_R,
    UA_RG,
    EPS_A,
    PIPE_MODE,
    C_P,
    UA_P,
    G_AX,
    V_PIPE,
    TAU_LOSS,
    E_STAG,
    C_S,
    H_WELL_NOM,
    H_WELL_0,
    G_BR,
    M_NOM,
    CP_W,
    P_MIN,
    P_MAX,
    P_START,
    T_SET,
    T_OFF,
    DT_RESTART,
    KP,
    TI,
    CTRL_OFFSET,
    TAU_CTRL,
    T_MIN_BURN,
    T_MIN_OFF,
    T_OFF_MAX,
    T_PREPURGE,
    T_CATCH,
    T_DET,
    T_IGN_ON,
    P_IGN,
    M_CHARGE,
    R_IGN,
    R_TOP,
    M_CRIT,
    T_RAMP,
    T_HOLD_MIN,
    DT_HOLD_EXIT,
    T_POST,
    TAU_BED,
    T_AUGER,
    R_AUGER_MAX,
    IGN_FAIL,
    T_FAIL,
    T_PURGE_RETRY,
    M_CHARGE2,
    V_IGN_FRAC,
    V_PURGE_FRAC,
    V_POST_FRAC,
    TAU_FAN,
    T_IGN_MAX,
    V_REF,
    CO_BASE,
    P_EL_BASE,
    P_EL_CTRL,
    P_FAN_NOM,
    P_AUGER_ON,
    C_B,
    UA_B,
    Q_CMAX,
    Q_HMAX,
    T_COLD,
    KP_B,
    TI_B,
    TAU_VALVE,
    TAU_FLOW,
    VALVE_DB,
    T_FLOOR_C1,
    P_NOM,
    T_PREHEAT,
    PREHEAT_TOL,
    PREHEAT_HOLD,
    PREHEAT_MIN,
    PREHEAT_MAX,
    PREHEAT_LOAD,
    T_RET_SP,
    SU_WINDOW,
    SU_RISE,
    SU_MIN,
    SU_MAX,
    C1_LOAD,
    C1_UNTIL,
    C1_MAX,
    C2_AFTER,
    TAU_TIN,
    TAU_TOUT,
    TAU_TBW,
    TAU_FG0,
    STRAT_BETA,
    OFF_TOUT,
    OFF_TIN,
    OFF_TFG,
    N_DELAY,
    TAU_O2,
    TAU_CO2,
    TAU_CO,
    A_DUCT,
    FORCE_P,
    FORCE_M,
    FORCE_TIN,
    FORCE_TROOM,
    T_INIT,
    T_INIT_BENCH,
    DT,
    N_SUB,
) = range(len(PARAM_NAMES))

N_PARAMS = len(PARAM_NAMES)

REC_NAMES: tuple[str, ...] = (
    "tin_s",  # return temperature at the sensor (after its lag), no offset/noise
    "tout_s",  # forward temperature at the sensor
    "tbw_s",  # boiler-body water sensor
    "tfg_s",  # flue-gas sensor
    "o2_s",  # analyser O2 after sample-line delay and response (dry vol-%)
    "co2_s",
    "co_s",
    "vel",  # flue-gas velocity [m/s]
    "fed",  # cumulative fuel fed, as received [kg]
    "pel",  # electric power [W]
    "m",  # true water flow [kg/h]
    "msp",  # flow setpoint [kg/h]
    "on",  # boiler_on flag
    "phase",
    "seq",
    "troom",
    "tw",  # true boiler water (well-mixed part)
    "texit",  # true water temperature leaving the boiler system
    "tin",  # true return temperature
    "tfg",  # true flue-gas temperature
    "q_rel",  # fuel heat (HHV) of the fuel converted on the bed [kW], step mean
    "q_ign",  # igniter heat into the chamber [kW]
    "q_ash",  # unburnt carbon in the ash
    "q_chem",  # CO
    "q_lat",  # latent heat of the fuel water (HHV basis)
    "q_bc",  # combustion chamber loss to the room
    "q_fg",  # flue-gas sensible loss (dry gas + vapour, above room)
    "q_env",  # casing loss to the room
    "q_pipe",  # outlet pipe loss to the room
    "q_w",  # heat carried away by the water, m cp (T_exit - T_in)
    "e_store",  # heat stored in all plant nodes [kJ]
    "bed",  # fuel on the bed, as received [kg]
    "burnt",  # cumulative fuel converted, as received [kg]
    "state",  # controller state
    "lambda",  # excess-air ratio (NaN without fire)
    "o2_true",
    "tm",  # exchanger steel
    "td",  # jacket pocket water (body form B)
    "th",  # hot steel (body form A)
    "tctrl",  # the boiler's own forward temperature reading
    "fire_cmd",  # commanded firing power [kW, LHV basis]
    "w_g",  # flue-gas heat capacity flow [kW/K]
    "vcum",  # cumulative water volume through the boiler [kg]
)
(
    R_TIN_S,
    R_TOUT_S,
    R_TBW_S,
    R_TFG_S,
    R_O2_S,
    R_CO2_S,
    R_CO_S,
    R_VEL,
    R_FED,
    R_PEL,
    R_M,
    R_MSP,
    R_ON,
    R_PHASE,
    R_SEQ,
    R_TROOM,
    R_TW,
    R_TEXIT,
    R_TIN,
    R_TFG,
    R_QREL,
    R_QIGN,
    R_QASH,
    R_QCHEM,
    R_QLAT,
    R_QBC,
    R_QFG,
    R_QENV,
    R_QPIPE,
    R_QW,
    R_ESTORE,
    R_BED,
    R_BURNT,
    R_STATE,
    R_LAMBDA,
    R_O2_TRUE,
    R_TM,
    R_TD,
    R_TH,
    R_TCTRL,
    R_FIRE,
    R_WG,
    R_VCUM,
) = range(len(REC_NAMES))

N_REC = len(REC_NAMES)

# controller states
ST_OFF, ST_PREPURGE, ST_IGNITE, ST_RETRY_PURGE, ST_RAMP, ST_HOLD, ST_MODULATE, ST_BURNOUT = range(8)
STATE_NAMES = (
    "off",
    "prepurge",
    "ignite",
    "retry_purge",
    "ramp",
    "hold",
    "modulate",
    "burnout",
)

# phases
PH_PREHEAT, PH_START_UP, PH_TEST, PH_COOLING_1, PH_COOLING_2 = range(5)
PHASE_NAMES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")

# exogenous noise streams fed to the kernel, one column each
(
    X_TROOM,
    X_XAIR,
    X_PRESS,
    X_DENS,
    X_LAM,
    X_FLOW,
    X_COLD,
) = range(7)
N_EXO = 7


def new_params() -> np.ndarray:
    """A parameter vector of zeros (every effect inactive)."""
    return np.zeros(N_PARAMS)
