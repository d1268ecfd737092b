"""Data layout of the compiled model: indices into its constant, state and output arrays.

The step functions are compiled with numba and exchange flat float64 arrays; these names
keep the code readable. ``*_FIELDS`` list the names in index order (for dicts and logs).
"""

# --- constants (derived once from BoilerParams by boiler.pack_constants)
K_HHV = 0  # gross calorific value, dry [kJ/kg]
K_LHV = 1  # net calorific value, dry [kJ/kg]
K_CAP = 2  # node capacity, structure plus water [kJ/K]
K_UA_ON = 3  # loss coefficient while firing [kW/K]
K_UA_OFF = 4  # loss coefficient when idle [kW/K]
K_A0 = 5  # dry flue-gas mass = A0 + A1 lambda [kg/kg dry fuel]
K_A1 = 6
K_B0 = 7  # dry flue-gas heat capacity = B0 + B1 lambda [kJ/(K kg dry fuel)]
K_B1 = 8
K_MH2O_CP = 9  # vapour mass times cp_vap [kJ/(K kg dry fuel)]
K_LATENT = 10  # latent heat of the vapour [kJ/kg dry fuel]
K_VDRY0 = 11  # dry flue-gas volume = VDRY0 + VDRY1 lambda [m3(N)/kg dry fuel]
K_VDRY1 = 12
K_VH2O = 13  # vapour volume [m3(N)/kg dry fuel]
K_VO2_PER_LAMBDA = 14  # O2 volume = VO2_PER_LAMBDA (lambda - 1) [m3(N)/kg]
K_VCO2 = 15  # [m3(N)/kg]
K_VSO2 = 16  # [m3(N)/kg]
K_FUEL_NOM = 17  # dry fuel flow at Pmax [kg/h]
K_FLOW_NOM = 18  # nominal water flow [kg/h]
K_AS_RECEIVED = 19  # as-received fuel per kg dry fuel [-]
K_IGNITION = 20  # Wel spread over the start-up [kW]
K_CHEM_PER_PPM = 21  # chemical loss per ppm CO per m3(N) dry gas [kJ]
K_INV_SPAN = 22  # 1 / (Pmax - Pmin) [1/kW]
K_PEL_SLOPE = 23  # (Pel,MAX - Pel,MIN) / (Pmax - Pmin) [W/kW]
K_P_MAX = 24  # [kW]
K_P_MIN = 25  # [kW]
K_P_START = 26  # [kW]
K_DT_NOM = 27  # [K]
K_DT_HX_FG = 28  # [K]
K_DT_HX_WAT = 29  # [K]
K_FAC_A = 30  # [-]
K_FAC_B = 31  # [h/kg]
K_PEL_MIN = 32  # [W]
K_PEL_OFF = 33  # [W]
K_SET = 34  # [C]
K_SHUTOFF = 35  # [C]
K_RESTART = 36  # [C]
K_STARTUP_S = 37  # [s]
K_CO_PMIN = 38  # [ppm]
K_CO_PMAX = 39  # [ppm]
K_CO_START = 40  # [ppm]
K_CO_STOP = 41  # [ppm]
K_CO_TAU = 42  # [s]
N_CONSTANTS = 43

# --- boiler state
S_T = 0  # node temperature [C]
S_MODE = 1  # controller mode (OFF, STARTUP, MODULATING, CUTOUT)
S_MODE_TIME = 2  # time in the current mode [s]
S_FIRING = 3  # firing power of the last step, net basis [kW]
S_SINCE_START = 4  # time since the last ignition [s]
S_SINCE_STOP = 5  # time since the last stop [s]
S_FUEL = 6  # dry fuel burnt so far [kg]
S_ELECTRIC = 7  # electricity drawn so far [Wh]
S_STARTS = 8  # ignitions so far
S_RESTART = 9  # 1 while the start-up is a restart after a cut-out, else 0
N_STATE = 10
STATE_FIELDS = (
    "t_boiler_C",
    "mode",
    "mode_time_s",
    "firing_kW",
    "since_start_s",
    "since_stop_s",
    "fuel_dry_kg",
    "electric_Wh",
    "starts",
    "restart",
)

# --- boiler outputs of one step (temperatures at the end, heat flows as step means)
Y_T_BOILER = 0  # [C]
Y_T_OUT = 1  # [C] (= T_boiler, Type 869 assumption)
Y_T_FG = 2  # flue-gas temperature [C]
Y_MODE = 3
Y_FIRING = 4  # [kW, net]
Y_FUEL = 5  # dry fuel flow [kg/h]
Y_LAMBDA = 6  # excess-air ratio [-] (inf when idle)
Y_O2 = 7  # [vol-%, dry]
Y_CO2 = 8  # [vol-%, dry]
Y_SO2 = 9  # [ppm, dry]
Y_CO = 10  # [ppm, dry]
Y_FG_DRY = 11  # dry flue-gas mass flow [kg/h]
Y_FG_WET = 12  # wet flue-gas volume flow [m3(N)/h]
Y_Q_FUEL = 13  # [kW]
Y_Q_IGN = 14  # [kW]
Y_Q_ASH = 15  # [kW]
Y_Q_SENS = 16  # [kW]
Y_Q_LAT = 17  # [kW]
Y_Q_CHEM = 18  # [kW]
Y_Q_HX = 19  # [kW]
Y_Q_WATER = 20  # [kW]
Y_Q_AMB = 21  # [kW]
Y_Q_STORED = 22  # [kW]
Y_P_EL = 23  # [W]
N_OUTPUTS = 24
OUTPUT_FIELDS = (
    "t_boiler_C",
    "t_out_C",
    "t_flue_gas_C",
    "mode",
    "firing_kW",
    "fuel_dry_kg_h",
    "lambda",
    "o2_pct",
    "co2_pct",
    "so2_ppm",
    "co_ppm",
    "flue_gas_dry_kg_h",
    "flue_gas_wet_m3n_h",
    "q_fuel_kW",
    "q_el_ign_kW",
    "q_ash_kW",
    "q_fg_sens_kW",
    "q_fg_lat_kW",
    "q_fg_chem_kW",
    "q_hx_kW",
    "q_water_kW",
    "q_amb_kW",
    "q_stored_kW",
    "p_el_W",
)

# Controller modes.
OFF = 0  #: switched off by the external command
STARTUP = 1  #: firing at Pstart after a start
MODULATING = 2  #: firing between Pmin and Pmax to hold the set temperature
CUTOUT = 3  #: stopped above the shut-off temperature, waiting for the restart temperature
MODE_NAMES = {OFF: "off", STARTUP: "start_up", MODULATING: "modulating", CUTOUT: "cut_out"}
