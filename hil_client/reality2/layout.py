"""Names of the packed arrays the kernel exchanges (parameters, outputs, noise channels).

Data crosses the Python/numba boundary as flat float arrays; these constants name each slot.
The Python side builds and reads the arrays only through :data:`PARAM_NAMES`,
:data:`OUTPUT_NAMES` and :data:`NOISE_NAMES`.
"""

from __future__ import annotations

#: Water nodes of the stratified body (0 = top, outlet; last = bottom, return inlet).
N_WATER = 4
#: Segments of the delayed wall (body form ``delayed_wall``).
N_WALL = 5
#: Most cells of the exit pipe.
N_PIPE_MAX = 48
#: Longest transit delay of the delayed wall [s].
TRANSIT_MAX = 600

#: Specific heat of water [kJ/(kg K)] (at 60-80 C, IAPWS).
CP_WATER = 4.187
#: Specific heat of air [kJ/(kg K)].
CP_AIR = 1.007
#: Heat of vaporisation of water at 25 C [kJ/kg] (reference of the gross basis).
DH_VAP = 2442.3
#: Stefan-Boltzmann constant [W/(m2 K4)].
SIGMA = 5.670e-8

PARAM_NAMES: tuple[str, ...] = (
    "air_burnout",
    "air_ignition",
    "air_min",
    "air_purge",
    "an_delay_s",
    "an_tau_s",
    "auger_ar_kg_s",
    "auger_period_s",
    "auger_w",
    "bal_drift",
    "bal_m0",
    "bal_noise",
    "bal_res",
    "bal_vib",
    "bench_kp",
    "bench_ti_s",
    "body_form",
    "burnout_s",
    "bw_frac",
    "bw_node",
    "charge_ar_kg",
    "cool1_load",
    "cool1_max_s",
    "cool1_return",
    "cool1_until",
    "cool2_after_t2_s",
    "co_pmax",
    "co_pmin",
    "co_start",
    "ctrl_offset",
    "c_loop",
    "c_ref",
    "c_steel_node",
    "c_water_node",
    "draught_air_kg_s",
    "draught_eff",
    "draught_sig",
    "drift_o2",
    "drift_tbw",
    "drift_tin",
    "drift_tout",
    "dt_x0",
    "dt_x_exp",
    "duct_area",
    "fan_w0",
    "fan_w1",
    "fg_c",
    "fg_form",
    "fg_g_steel",
    "fg_ntu0",
    "fines_frac",
    "flow_bias",
    "flow_noise_rel",
    "flow_nom",
    "flow_per_pct",
    "flow_ripple",
    "gas_a0",
    "gas_a1",
    "g_mix_stable",
    "g_mix_unstable",
    "heater_kw",
    "hhv",
    "igniter_s",
    "igniter_w",
    "ign_bed_c0",
    "ign_bed_cp",
    "ign_bed_dt",
    "ign_bed_eta",
    "ign_bed_tau_loss",
    "ign_delay_bg_s",
    "ign_form",
    "ign_program_s",
    "kp",
    "lam_a",
    "lam_b",
    "lam_curv",
    "lam_xmid",
    "lhv_doc",
    "mcp_gas_nom",
    "min_burn_s",
    "min_off_s",
    "moisture",
    "noise_tbw",
    "noise_tw",
    "n_stages",
    "off_o2",
    "off_room",
    "off_tbw",
    "off_tfg",
    "off_tin",
    "off_tout",
    "pel_off",
    "pipe_cells",
    "pipe_c_cell",
    "pipe_c_wall",
    "pipe_g_back",
    "pipe_h_wall",
    "pipe_ua_cell",
    "pipe_ua_wall",
    "preheat_hold_s",
    "preheat_load",
    "preheat_max_s",
    "preheat_t",
    "preheat_tol",
    "prepurge_s",
    "pressure",
    "p_auger_cap",
    "p_max",
    "p_min",
    "p_start",
    "q_tbw",
    "ramp_handover_k",
    "ramp_s",
    "ref_ea",
    "ref_frac",
    "rel_co2",
    "rel_tfg",
    "restart_t",
    "return_set",
    "rh",
    "room_amp",
    "room_base",
    "room_ou_sig",
    "room_ou_tau",
    "room_phase_s",
    "sensor_wall_w",
    "set_t",
    "shutoff_t",
    "smoulder_start",
    "smoulder_stop",
    "start_hold_s",
    "stop_hyst_k",
    "t1_max_rise",
    "t1_max_s",
    "t1_min_s",
    "t1_window_s",
    "tau_bed",
    "tau_bw",
    "tau_fan",
    "tau_fg",
    "tau_flow",
    "tau_return",
    "tau_tw",
    "ti_s",
    "t_cold",
    "t_init",
    "ua_jacket_node",
    "ua_loop",
    "ua_sw_node",
    "valve_max",
    "valve_stroke_s",
    "vapour_per_kg",
    "vco2",
    "vdry0",
    "vdry1",
    "wall_c_seg",
    "wall_delay_s",
    "wall_g",
    "feed_sig",
    "valve_deadband",
    "heat_w0",
    "heat_w1",
    "heat_w2",
    "heat_w3",
)
OUTPUT_NAMES: tuple[str, ...] = (
    "r_time",
    "r_phase",
    "r_sequence",
    "r_flow",
    "r_tin",
    "r_tout",
    "r_tbw",
    "r_tfg",
    "r_o2",
    "r_co2",
    "r_co",
    "r_vel",
    "r_draught",
    "r_mass",
    "r_room",
    "r_press",
    "r_rh",
    "r_pel",
    "r_flowset",
    "r_on",
    "x_bed_dry",
    "x_burnt_dry",
    "x_fed_ar",
    "x_fed_dry",
    "x_fines_dry",
    "x_flow",
    "x_heater",
    "x_ignited",
    "x_lambda",
    "x_mode",
    "x_p_cmd",
    "x_q_ash",
    "x_q_chem",
    "x_q_draught",
    "x_q_flue",
    "x_q_fuel",
    "x_q_ign",
    "x_q_jacket",
    "x_q_lat",
    "x_q_pipe",
    "x_q_store",
    "x_q_water",
    "x_residual",
    "x_starts",
    "x_t_bottom",
    "x_t_bw",
    "x_t_fg",
    "x_t_in",
    "x_t_out",
    "x_t_room",
    "x_t_steel",
    "x_t_top",
    "x_valve",
)
NOISE_NAMES: tuple[str, ...] = (
    "flow",
    "tin",
    "tout",
    "tbw",
    "tfg",
    "o2",
    "co2",
    "co",
    "vel",
    "draught",
    "mass",
    "vib",
    "room",
    "room2",
    "press",
    "rh",
    "pel",
    "ripple",
    "feed",
)

P_AIR_BURNOUT = 0
P_AIR_IGNITION = 1
P_AIR_MIN = 2
P_AIR_PURGE = 3
P_AN_DELAY_S = 4
P_AN_TAU_S = 5
P_AUGER_AR_KG_S = 6
P_AUGER_PERIOD_S = 7
P_AUGER_W = 8
P_BAL_DRIFT = 9
P_BAL_M0 = 10
P_BAL_NOISE = 11
P_BAL_RES = 12
P_BAL_VIB = 13
P_BENCH_KP = 14
P_BENCH_TI_S = 15
P_BODY_FORM = 16
P_BURNOUT_S = 17
P_BW_FRAC = 18
P_BW_NODE = 19
P_CHARGE_AR_KG = 20
P_COOL1_LOAD = 21
P_COOL1_MAX_S = 22
P_COOL1_RETURN = 23
P_COOL1_UNTIL = 24
P_COOL2_AFTER_T2_S = 25
P_CO_PMAX = 26
P_CO_PMIN = 27
P_CO_START = 28
P_CTRL_OFFSET = 29
P_C_LOOP = 30
P_C_REF = 31
P_C_STEEL_NODE = 32
P_C_WATER_NODE = 33
P_DRAUGHT_AIR_KG_S = 34
P_DRAUGHT_EFF = 35
P_DRAUGHT_SIG = 36
P_DRIFT_O2 = 37
P_DRIFT_TBW = 38
P_DRIFT_TIN = 39
P_DRIFT_TOUT = 40
P_DT_X0 = 41
P_DT_X_EXP = 42
P_DUCT_AREA = 43
P_FAN_W0 = 44
P_FAN_W1 = 45
P_FG_C = 46
P_FG_FORM = 47
P_FG_G_STEEL = 48
P_FG_NTU0 = 49
P_FINES_FRAC = 50
P_FLOW_BIAS = 51
P_FLOW_NOISE_REL = 52
P_FLOW_NOM = 53
P_FLOW_PER_PCT = 54
P_FLOW_RIPPLE = 55
P_GAS_A0 = 56
P_GAS_A1 = 57
P_G_MIX_STABLE = 58
P_G_MIX_UNSTABLE = 59
P_HEATER_KW = 60
P_HHV = 61
P_IGNITER_S = 62
P_IGNITER_W = 63
P_IGN_BED_C0 = 64
P_IGN_BED_CP = 65
P_IGN_BED_DT = 66
P_IGN_BED_ETA = 67
P_IGN_BED_TAU_LOSS = 68
P_IGN_DELAY_BG_S = 69
P_IGN_FORM = 70
P_IGN_PROGRAM_S = 71
P_KP = 72
P_LAM_A = 73
P_LAM_B = 74
P_LAM_CURV = 75
P_LAM_XMID = 76
P_LHV_DOC = 77
P_MCP_GAS_NOM = 78
P_MIN_BURN_S = 79
P_MIN_OFF_S = 80
P_MOISTURE = 81
P_NOISE_TBW = 82
P_NOISE_TW = 83
P_N_STAGES = 84
P_OFF_O2 = 85
P_OFF_ROOM = 86
P_OFF_TBW = 87
P_OFF_TFG = 88
P_OFF_TIN = 89
P_OFF_TOUT = 90
P_PEL_OFF = 91
P_PIPE_CELLS = 92
P_PIPE_C_CELL = 93
P_PIPE_C_WALL = 94
P_PIPE_G_BACK = 95
P_PIPE_H_WALL = 96
P_PIPE_UA_CELL = 97
P_PIPE_UA_WALL = 98
P_PREHEAT_HOLD_S = 99
P_PREHEAT_LOAD = 100
P_PREHEAT_MAX_S = 101
P_PREHEAT_T = 102
P_PREHEAT_TOL = 103
P_PREPURGE_S = 104
P_PRESSURE = 105
P_P_AUGER_CAP = 106
P_P_MAX = 107
P_P_MIN = 108
P_P_START = 109
P_Q_TBW = 110
P_RAMP_HANDOVER_K = 111
P_RAMP_S = 112
P_REF_EA = 113
P_REF_FRAC = 114
P_REL_CO2 = 115
P_REL_TFG = 116
P_RESTART_T = 117
P_RETURN_SET = 118
P_RH = 119
P_ROOM_AMP = 120
P_ROOM_BASE = 121
P_ROOM_OU_SIG = 122
P_ROOM_OU_TAU = 123
P_ROOM_PHASE_S = 124
P_SENSOR_WALL_W = 125
P_SET_T = 126
P_SHUTOFF_T = 127
P_SMOULDER_START = 128
P_SMOULDER_STOP = 129
P_START_HOLD_S = 130
P_STOP_HYST_K = 131
P_T1_MAX_RISE = 132
P_T1_MAX_S = 133
P_T1_MIN_S = 134
P_T1_WINDOW_S = 135
P_TAU_BED = 136
P_TAU_BW = 137
P_TAU_FAN = 138
P_TAU_FG = 139
P_TAU_FLOW = 140
P_TAU_RETURN = 141
P_TAU_TW = 142
P_TI_S = 143
P_T_COLD = 144
P_T_INIT = 145
P_UA_JACKET_NODE = 146
P_UA_LOOP = 147
P_UA_SW_NODE = 148
P_VALVE_MAX = 149
P_VALVE_STROKE_S = 150
P_VAPOUR_PER_KG = 151
P_VCO2 = 152
P_VDRY0 = 153
P_VDRY1 = 154
P_WALL_C_SEG = 155
P_WALL_DELAY_S = 156
P_WALL_G = 157
P_FEED_SIG = 158
P_VALVE_DEADBAND = 159
P_HEAT_W0 = 160
P_HEAT_W1 = 161
P_HEAT_W2 = 162
P_HEAT_W3 = 163
R_TIME = 0
R_PHASE = 1
R_SEQUENCE = 2
R_FLOW = 3
R_TIN = 4
R_TOUT = 5
R_TBW = 6
R_TFG = 7
R_O2 = 8
R_CO2 = 9
R_CO = 10
R_VEL = 11
R_DRAUGHT = 12
R_MASS = 13
R_ROOM = 14
R_PRESS = 15
R_RH = 16
R_PEL = 17
R_FLOWSET = 18
R_ON = 19
X_BED_DRY = 20
X_BURNT_DRY = 21
X_FED_AR = 22
X_FED_DRY = 23
X_FINES_DRY = 24
X_FLOW = 25
X_HEATER = 26
X_IGNITED = 27
X_LAMBDA = 28
X_MODE = 29
X_P_CMD = 30
X_Q_ASH = 31
X_Q_CHEM = 32
X_Q_DRAUGHT = 33
X_Q_FLUE = 34
X_Q_FUEL = 35
X_Q_IGN = 36
X_Q_JACKET = 37
X_Q_LAT = 38
X_Q_PIPE = 39
X_Q_STORE = 40
X_Q_WATER = 41
X_RESIDUAL = 42
X_STARTS = 43
X_T_BOTTOM = 44
X_T_BW = 45
X_T_FG = 46
X_T_IN = 47
X_T_OUT = 48
X_T_ROOM = 49
X_T_STEEL = 50
X_T_TOP = 51
X_VALVE = 52
N_FLOW = 0
N_TIN = 1
N_TOUT = 2
N_TBW = 3
N_TFG = 4
N_O2 = 5
N_CO2 = 6
N_CO = 7
N_VEL = 8
N_DRAUGHT = 9
N_MASS = 10
N_VIB = 11
N_ROOM = 12
N_ROOM2 = 13
N_PRESS = 14
N_RH = 15
N_PEL = 16
N_RIPPLE = 17
N_FEED = 18
