"""Physical constants used by the boiler model.

All values are the usual engineering figures for the temperature range of a hot-water boiler
(20-160 C); sources are given per constant.
"""

#: Specific heat of liquid water [kJ/(kg K)] (EN 14785 uses 4.19 around 50-70 C).
CP_WATER = 4.19
#: Density of water at 70 C [kg/m3] (IAPWS-95), used for the water inside the boiler.
RHO_WATER = 977.8
#: Latent heat of vaporisation of water at 25 C [kJ/kg]; the reference of the gross (HHV) basis.
DH_VAP_WATER = 2442.0
#: Heat of combustion of CO to CO2 [kJ/kg CO] (digest section 1: about 10.1 MJ/kg).
DH_COMB_CO = 10_100.0
#: Ash (unburnt residue) loss as a fraction of Q_fuel: 0.02 percentage points (EN 14785).
ASH_LOSS_FRACTION = 0.0002

# Mean specific heats of the flue-gas components between 20 and 160 C [kJ/(kg K)]
# (ideal-gas tables, e.g. VDI Heat Atlas D3.1, averaged over the range).
CP_CO2 = 0.90
CP_N2 = 1.041
CP_O2 = 0.925
CP_SO2 = 0.64
CP_VAPOUR = 1.89

# Densities at 0 C and 1013.25 hPa [kg/m3(N)] (DIN 1343 normal state).
RHO_N_CO2 = 1.977
RHO_N_N2 = 1.2505
RHO_N_O2 = 1.429
RHO_N_SO2 = 2.926
RHO_N_CO = 1.250
RHO_N_H2O = 0.804

#: Oxygen fraction of dry air [-].
O2_AIR = 0.21
#: Oxygen and CO2 in ambient air as read by the analyser when no flue gas flows [vol-%].
O2_AMBIENT_PCT = 20.95
CO2_AMBIENT_PCT = 0.04
#: Normal molar volume of an ideal gas [m3(N)/kmol].
V_MOLAR_N = 22.414
#: Normal temperature [K].
T_NORMAL_K = 273.15
