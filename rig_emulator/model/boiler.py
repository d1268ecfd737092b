"""The Type 869 one-node pellet boiler (Carlon et al. 2015, Section 3) and its controller.

Energy balance of the combustion chamber (Eq. 1) with Q_bc,amb = 0 (validation choice):

    Q_fuel + Q_el,ign = Q_ash + Q_fg,sens + Q_fg,lat + Q_fg,chem + Q_hx
    Q_fuel    = m_fuel,dry HHV / 3600                                    (Eq. 3)
    Q_fg,sens = (m_fg,dry cp_fg + m_H2O cp_vap) (T_fg - T_room) / 3600   (Eq. 4)
    Q_fg,lat  = m_H2O dH_vap / 3600                                      (Eq. 5)
    Q_fg,chem = m_CO dH_CO / 3600                                        (Eq. 6)
    Q_ash     = 0.0002 Q_fuel                                            (EN 14785)

and of the one thermal node, water plus structure at T_boiler (Eq. 2, 7, 10):

    Q_hx = Q_w,out + Q_amb + C dT_boiler/dt
    Q_w,out = m_w cp_w (T_boiler - T_w,in) / 3600,   Q_amb = UA (T_boiler - T_room)

with the flue-gas temperature of the reduced empirical delta-T approach (Eq. 8)

    T_fg = T_w,in + dTnom + dThx,fg (1 - m_fuel/m_fuel,nom) + dThx,wat (1 - m_w/m_w,nom)

and the excess-air ratio of Eq. 9, lambda = facA + facB m_fuel,dry.

Integration: inputs and firing power are held over a step; the node equation is then linear
and is solved exactly, so any step length is stable, and the step-mean heat flows close the
balance to rounding. The controller is the ideal one of the paper's simulations: it fires at
Pstart for the start-up time after each start, then chooses the firing power in [Pmin, Pmax]
that brings the outlet to the set temperature by the end of the step; above the shut-off
temperature it stops, and it restarts once the water has cooled to the restart temperature.

Assumptions (ours, where the paper is silent):
- firing powers are on the net (LHV, dry) basis; Q_fuel = P HHV/LHV (see params.py);
- m_fuel,nom of Eq. 8 is the dry fuel flow at Pmax;
- the ignition energy Wel is spread evenly over ``startup_duration_s`` after each start
  (also when the start-up at Pstart ends early at the set temperature) and heats the node;
- when the burner is off the flue-gas probe sees draught air leaving the exchanger at the
  node temperature, and the analyser sees ambient air (plus the decaying burn-out CO);
- electric power is linear in firing power between Pel,MIN at Pmin and Pel,MAX at Pmax;
- CO (for Eq. 6 and the analyser): see :func:`co_stationary_ppm`.

The functions are compiled with numba (``cache=True``); they exchange flat float64 arrays
whose layout :mod:`rig_emulator.model.layout` names. Set ``NUMBA_DISABLE_JIT=1`` to run them
as plain Python.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from rig_emulator.model import constants as k
from rig_emulator.model.fuel import stoichiometry
from rig_emulator.model.layout import (
    CUTOUT,
    K_A0,
    K_A1,
    K_AS_RECEIVED,
    K_B0,
    K_B1,
    K_CAP,
    K_CHEM_PER_PPM,
    K_CO_PMAX,
    K_CO_PMIN,
    K_CO_START,
    K_CO_STOP,
    K_CO_TAU,
    K_DT_HX_FG,
    K_DT_HX_WAT,
    K_DT_NOM,
    K_FAC_A,
    K_FAC_B,
    K_FLOW_NOM,
    K_FUEL_NOM,
    K_HANDOVER_LIMIT,
    K_HHV,
    K_IGNITION,
    K_INV_SPAN,
    K_LATENT,
    K_LHV,
    K_MH2O_CP,
    K_P_MAX,
    K_P_MIN,
    K_P_START,
    K_PEL_MIN,
    K_PEL_OFF,
    K_PEL_SLOPE,
    K_RESTART,
    K_SET,
    K_SHUTOFF,
    K_STARTUP_S,
    K_UA_OFF,
    K_UA_ON,
    K_VCO2,
    K_VDRY0,
    K_VDRY1,
    K_VH2O,
    K_VO2_PER_LAMBDA,
    K_VSO2,
    MODULATING,
    N_CONSTANTS,
    N_OUTPUTS,
    N_STATE,
    OFF,
    S_ELECTRIC,
    S_FIRING,
    S_FUEL,
    S_MODE,
    S_MODE_TIME,
    S_NO_DEMAND,
    S_SINCE_START,
    S_SINCE_STOP,
    S_STARTS,
    S_T,
    STARTUP,
    Y_CO,
    Y_CO2,
    Y_FG_DRY,
    Y_FG_WET,
    Y_FIRING,
    Y_FUEL,
    Y_LAMBDA,
    Y_MODE,
    Y_O2,
    Y_P_EL,
    Y_Q_AMB,
    Y_Q_ASH,
    Y_Q_CHEM,
    Y_Q_FUEL,
    Y_Q_HX,
    Y_Q_IGN,
    Y_Q_LAT,
    Y_Q_SENS,
    Y_Q_STORED,
    Y_Q_WATER,
    Y_SO2,
    Y_T_BOILER,
    Y_T_FG,
    Y_T_OUT,
)

if TYPE_CHECKING:  # (params checks a parameter set against this model's steady state)
    from rig_emulator.model.params import BoilerParams

_CP_W_KWH = k.CP_WATER / 3600.0  # [kJ/(kg K)] per [h/s]: kg/h flow to kW/K
_ASH = k.ASH_LOSS_FRACTION


def pack_constants(p: BoilerParams) -> np.ndarray:
    """The constant array of the compiled model (layout ``K_*``) for a parameter set."""
    st = stoichiometry(p.fuel)
    a0, a1 = st.dry_mass_coeffs()
    b0, b1 = st.dry_heat_capacity_coeffs()
    v_dry0 = st.dry_volume_m3(0.0)
    lhv = p.fuel.lhv_dry_kJ_kg
    span = p.p_max_kW - p.p_min_kW
    c = np.zeros(N_CONSTANTS)
    c[K_HHV] = p.fuel.hhv_dry_kJ_kg
    c[K_LHV] = lhv
    c[K_CAP] = p.capacity_kJ_K
    c[K_UA_ON] = p.ua_amb_on_W_K / 1000.0
    c[K_UA_OFF] = p.ua_amb_off_W_K / 1000.0
    c[K_A0], c[K_A1], c[K_B0], c[K_B1] = a0, a1, b0, b1
    c[K_MH2O_CP] = st.m_h2o_kg * k.CP_VAPOUR
    c[K_LATENT] = st.m_h2o_kg * k.DH_VAP_WATER
    c[K_VDRY0] = v_dry0
    c[K_VDRY1] = st.dry_volume_m3(1.0) - v_dry0
    c[K_VH2O] = st.m_h2o_kg / k.RHO_N_H2O
    c[K_VO2_PER_LAMBDA] = k.O2_AIR * st.air_min_m3
    c[K_VCO2] = st.v_co2_m3
    c[K_VSO2] = st.v_so2_m3
    c[K_FUEL_NOM] = p.p_max_kW * 3600.0 / lhv
    c[K_FLOW_NOM] = p.nominal_flow_kg_h
    c[K_AS_RECEIVED] = p.fuel.as_received_per_kg_dry
    c[K_IGNITION] = p.w_el_Wh * 3.6 / p.startup_duration_s
    c[K_CHEM_PER_PPM] = 1e-6 * k.RHO_N_CO * k.DH_COMB_CO
    c[K_INV_SPAN] = 1.0 / span if span > 0 else 0.0
    c[K_PEL_SLOPE] = (p.p_el_max_W - p.p_el_min_W) / span if span > 0 else 0.0
    c[K_P_MAX], c[K_P_MIN], c[K_P_START] = p.p_max_kW, p.p_min_kW, p.p_start_kW
    c[K_DT_NOM], c[K_DT_HX_FG], c[K_DT_HX_WAT] = p.dt_nom_K, p.dt_hx_fg_K, p.dt_hx_wat_K
    c[K_FAC_A], c[K_FAC_B] = p.fac_a_lambda, p.fac_b_lambda_h_kg
    c[K_PEL_MIN], c[K_PEL_OFF] = p.p_el_min_W, p.p_el_off_W
    c[K_SET], c[K_SHUTOFF], c[K_RESTART] = p.set_temp_C, p.shutoff_temp_C, p.restart_temp_C
    c[K_HANDOVER_LIMIT] = p.shutoff_temp_C  # a replay may move the shut-off, not this
    c[K_STARTUP_S] = p.startup_duration_s
    c[K_CO_PMIN], c[K_CO_PMAX] = p.co_ppm_at_p_min, p.co_ppm_at_p_max
    c[K_CO_START], c[K_CO_STOP] = p.co_start_peak_ppm, p.co_stop_peak_ppm
    c[K_CO_TAU] = p.co_transient_s
    return c


def new_state(t_boiler_C: float) -> np.ndarray:
    """Boiler state array (layout ``S_*``): node at ``t_boiler_C``, switched off, no history."""
    s = np.zeros(N_STATE)
    s[S_T] = t_boiler_C
    s[S_MODE] = OFF
    s[S_SINCE_START] = math.inf
    s[S_SINCE_STOP] = math.inf
    return s


def new_outputs() -> np.ndarray:
    """An output array (layout ``Y_*``) to be filled by :func:`step`."""
    return np.zeros(N_OUTPUTS)


@njit(cache=True)
def flue_gas_temperature(c, water_in_C, water_flow_kg_h, fuel_dry_kg_h):
    """Flue-gas temperature while firing [C], Eq. 8 (empirical delta-T approach).

    Args:
        c: constants array; water_in_C: return temperature [C];
        water_flow_kg_h: water flow [kg/h]; fuel_dry_kg_h: dry fuel flow [kg/h].
    """
    return (
        water_in_C
        + c[K_DT_NOM]
        + c[K_DT_HX_FG] * (1.0 - fuel_dry_kg_h / c[K_FUEL_NOM])
        + c[K_DT_HX_WAT] * (1.0 - water_flow_kg_h / c[K_FLOW_NOM])
    )


@njit(cache=True)
def excess_air(c, fuel_dry_kg_h):
    """Excess-air ratio [-], Eq. 9: lambda = facA + facB m_fuel,dry [kg/h]."""
    return c[K_FAC_A] + c[K_FAC_B] * fuel_dry_kg_h


@njit(cache=True)
def co_stationary_ppm(c, firing_kW):
    """CO in the dry flue gas in stationary firing [ppm].

    Not part of Type 869; the chemical loss (Eq. 6) needs a CO level and the analyser shows
    one. Assumption (ours, typical of small pellet boilers): linear from ``co_ppm_at_p_min``
    at Pmin to ``co_ppm_at_p_max`` at Pmax. Each ignition adds ``co_start_peak_ppm`` and each
    stop leaves a burn-out peak ``co_stop_peak_ppm``, both decaying with ``co_transient_s``
    (in :func:`step`).
    """
    x = (firing_kW - c[K_P_MIN]) * c[K_INV_SPAN]
    x = min(max(x, 0.0), 1.0)
    return c[K_CO_PMIN] + (c[K_CO_PMAX] - c[K_CO_PMIN]) * x


@njit(cache=True)
def flue_gas_loss_per_kg(c, lam, t_fg_C, room_C, co_ppm):
    """Flue-gas losses per kg of dry fuel [kJ/kg]: (sensible, latent, chemical), Eq. 4-6."""
    sens = (c[K_B0] + c[K_B1] * lam + c[K_MH2O_CP]) * (t_fg_C - room_C)
    chem = co_ppm * (c[K_VDRY0] + c[K_VDRY1] * lam) * c[K_CHEM_PER_PPM]
    return sens, c[K_LATENT], chem


@njit(cache=True)
def fuel_for_heat(c, q_hx_kW, dt_fg_K, chem_per_kg):
    """Dry fuel flow [kg/h] whose combustion delivers ``q_hx_kW`` to the exchanger.

    With lambda linear in the fuel flow x (Eq. 9) the balance Eq. 1 is quadratic in x:
    Q_hx 3600 = x (HHV (1 - ash) - (b0 + b1 facA + m_H2O cp_v) dT - latent - chem)
    - b1 facB dT x^2; the root that tends to Q_hx 3600 / beta is taken.
    """
    beta = (
        c[K_HHV] * (1.0 - _ASH)
        - (c[K_B0] + c[K_B1] * c[K_FAC_A] + c[K_MH2O_CP]) * dt_fg_K
        - c[K_LATENT]
        - chem_per_kg
    )
    gamma = c[K_B1] * c[K_FAC_B] * dt_fg_K
    q = q_hx_kW * 3600.0
    disc = beta * beta - 4.0 * gamma * q
    if disc <= 0.0 or beta <= 0.0:
        return c[K_FUEL_NOM]
    return 2.0 * q / (beta + math.sqrt(disc))


@njit(cache=True)
def node_exact(t0_C, q_in_kW, m_cp_kW_K, water_in_C, ua_kW_K, room_C, cap_kJ_K, dt_s):
    """Exact solution of the node equation (Eq. 2, 7, 10) over a step with held inputs.

    C dT/dt = Q_in - m cp (T - T_in) - UA (T - T_room)  is linear in T, so
    T(dt) = T_eq + (T0 - T_eq) exp(-b dt / C), b = m cp + UA, T_eq = (Q_in + m cp T_in +
    UA T_room) / b. Returns (T at the end [C], mean T over the step [C]).
    """
    b = m_cp_kW_K + ua_kW_K
    decay = math.exp(-b * dt_s / cap_kJ_K)
    t_eq = (q_in_kW + m_cp_kW_K * water_in_C + ua_kW_K * room_C) / b
    t1 = t_eq + (t0_C - t_eq) * decay
    t_mean = t_eq + (t0_C - t_eq) * (1.0 - decay) * cap_kJ_K / (b * dt_s)
    return t1, t_mean


@njit(cache=True)
def controller_mode(c, mode, mode_time_s, t_boiler_C, enabled, no_demand):
    """Next controller mode from the current one and the node temperature.

    Off when not enabled; on enabling it starts unless the water is already at the set
    temperature (it then waits, as after a cut-out, for the water to fall to the set
    temperature as it is now where ``no_demand``, else to the restart temperature:
    :func:`update_mode`); firing stops at or above the shut-off
    temperature (cut-out) and starts again at or below the restart temperature. The
    start-up at Pstart lasts
    ``startup_duration_s`` unless the shut-off ends it, or the set temperature where the
    load lies in the modulation range (:func:`startup_hands_over`, decided in the step,
    which knows the load).
    """
    if not enabled:
        return OFF
    if mode == OFF:
        return STARTUP if t_boiler_C < c[K_SET] else CUTOUT
    if mode == CUTOUT:
        return STARTUP if t_boiler_C <= (c[K_SET] if no_demand else c[K_RESTART]) else CUTOUT
    if t_boiler_C >= c[K_SHUTOFF]:
        return CUTOUT
    if mode == STARTUP and mode_time_s >= c[K_STARTUP_S]:
        return MODULATING
    return mode


@njit(cache=True, inline="always")
def update_mode(c, s, enabled):
    """Switch the controller (:func:`controller_mode`) and keep its clocks in ``s``.

    A stop waits for the restart temperature after a cut-out (the paper: off above 85 C,
    on again at 55 C), and for the set temperature where the boiler was switched on with
    the water at or above it, below the shut-off: there is no demand, not an overheated
    boiler (it waited for 55 C, and a boiler switched on at 71.3 C with a full load on the
    loop stayed cold for hours: a stranger's physics probe).

    Returns (mode for this step, True if the burner starts with this step).
    """
    mode = int(s[S_MODE])
    new_mode = controller_mode(c, mode, s[S_MODE_TIME], s[S_T], enabled, s[S_NO_DEMAND] > 0.5)
    started = False
    if new_mode != mode:
        s[S_MODE_TIME] = 0.0
        if new_mode == CUTOUT:  # (the set temperature as it is then: it may be written)
            s[S_NO_DEMAND] = 1.0 if mode == OFF and s[S_T] < c[K_SHUTOFF] else 0.0
        if new_mode == STARTUP:
            s[S_SINCE_START] = 0.0
            s[S_STARTS] += 1.0
            started = True
        elif mode == STARTUP or mode == MODULATING:
            s[S_SINCE_STOP] = 0.0
    return new_mode, started


@njit(cache=True, inline="always")
def igniter_kW(c, s):
    """Ignition power [kW]: the igniter runs for the start-up time after each start,
    whatever the mode (Wel spread over ``startup_duration_s``)."""
    return c[K_IGNITION] if s[S_SINCE_START] < c[K_STARTUP_S] else 0.0


@njit(cache=True, inline="always")
def firing_power_kW(
    c, s, mode, m_cp, water_flow_kg_h, water_in_C, room_C, q_ign, co_start, horizon_s
):
    """Firing power the controller commands while firing [kW, net basis].

    Pstart in the start-up; otherwise the heat to the exchanger that brings the node to
    the set point at the end of ``horizon_s`` (the step, for the paper's ideal controller),
    with the flue-gas losses evaluated at the previous firing power (one fixed-point
    pass), turned into fuel (:func:`fuel_for_heat`) and clipped to [Pmin, Pmax].
    """
    if mode == STARTUP:
        return c[K_P_START]
    ua = c[K_UA_ON]
    b = m_cp + ua
    decay = math.exp(-b * horizon_s / c[K_CAP])
    t_eq = (c[K_SET] - s[S_T] * decay) / (1.0 - decay)
    q_req = max(b * t_eq - m_cp * water_in_C - ua * room_C - q_ign, 0.0)
    x_prev = s[S_FIRING] * 3600.0 / c[K_LHV]
    lam_prev = excess_air(c, x_prev)
    co_prev = co_stationary_ppm(c, s[S_FIRING]) + co_start
    t_fg_prev = flue_gas_temperature(c, water_in_C, water_flow_kg_h, x_prev)
    chem_prev = flue_gas_loss_per_kg(c, lam_prev, t_fg_prev, room_C, co_prev)[2]
    x = fuel_for_heat(c, q_req, t_fg_prev - room_C, chem_prev)
    return min(max(x * c[K_LHV] / 3600.0, c[K_P_MIN]), c[K_P_MAX])


@njit(cache=True, inline="always")
def startup_hands_over(c, s, mode, m_cp, water_flow_kg_h, water_in_C, room_C, co_start):
    """Whether the start-up at Pstart ends now, at the set temperature: when modulation can
    keep the water below the shut-off, i.e. the node's equilibrium at Pmin with this
    step's flow, return and room lies below it (the load is in, or not far below, the
    modulation range). Otherwise the start-up runs its time at Pstart: in Fig. 7 (Carlon et
    al. 2015, 3.2.2) the boiler restarted at 13 % load "maintained the maximum power output
    during the start-up phase" and reached 85 C again, as Pmin alone would have too.
    Assumption (the paper is silent): one rule for every start, so the physics does not
    depend on how the boiler got to its start (the bench switching it on, a cut-out, a
    replay switching the model on where the lab's burner restarted). Run on whatever the
    load, the start-up took the 12-kW boiler from 55 C to 85 C within its 900 s at 28-39 %
    load, and it cut out and restarted for ever."""
    if mode != STARTUP or s[S_T] < c[K_SET]:
        return False
    x_min = c[K_P_MIN] * 3600.0 / c[K_LHV]  # dry fuel at Pmin [kg/h]
    lam = excess_air(c, x_min)
    t_fg = flue_gas_temperature(c, water_in_C, water_flow_kg_h, x_min)
    co = co_stationary_ppm(c, c[K_P_MIN]) + co_start
    sens, lat, chem = flue_gas_loss_per_kg(c, lam, t_fg, room_C, co)
    q_hx = x_min / 3600.0 * (c[K_HHV] * (1.0 - _ASH) - sens - lat - chem)
    ua = c[K_UA_ON]
    t_eq = (q_hx + m_cp * water_in_C + ua * room_C) / (m_cp + ua)
    return t_eq < c[K_HANDOVER_LIMIT]


@njit(cache=True, inline="always")
def burnout_co_ppm(c, s):
    """CO after a stop [ppm]: the burn-out peak decaying since the stop."""
    return c[K_CO_STOP] * math.exp(-s[S_SINCE_STOP] / c[K_CO_TAU])


@njit(cache=True, inline="always")
def combustion(c, fuel_kg_h, lam, t_fg_C, room_C, co_ppm, y):
    """Burn ``fuel_kg_h`` of dry fuel at ``lam``: the heat flows of Eq. 1, 3-6 (ash per
    EN 14785) and the flue gas (analyser, volume and mass flows) into ``y``.

    Returns the heat to the exchanger Q_hx [kW].
    """
    sens, lat, chem = flue_gas_loss_per_kg(c, lam, t_fg_C, room_C, co_ppm)
    per_s = fuel_kg_h / 3600.0
    q_fuel = per_s * c[K_HHV]
    q_ash = _ASH * q_fuel
    q_sens = per_s * sens
    q_lat = per_s * lat
    q_chem = per_s * chem
    q_hx = q_fuel - q_ash - q_sens - q_lat - q_chem
    v_dry = c[K_VDRY0] + c[K_VDRY1] * lam
    # the stoichiometry's air holds 21 % O2 (the digest's set), the room's 20.95 %: a bed's
    # last grams burning in the held air (lambda in the hundreds) read above the room's
    y[Y_O2] = min(100.0 * c[K_VO2_PER_LAMBDA] * (lam - 1.0) / v_dry, k.O2_AMBIENT_PCT)
    y[Y_CO2] = max(100.0 * c[K_VCO2] / v_dry, k.CO2_AMBIENT_PCT)
    y[Y_SO2] = 1e6 * c[K_VSO2] / v_dry
    y[Y_FG_DRY] = fuel_kg_h * (c[K_A0] + c[K_A1] * lam)
    y[Y_FG_WET] = fuel_kg_h * (v_dry + c[K_VH2O])
    y[Y_Q_FUEL] = q_fuel
    y[Y_Q_ASH] = q_ash
    y[Y_Q_SENS] = q_sens
    y[Y_Q_LAT] = q_lat
    y[Y_Q_CHEM] = q_chem
    y[Y_Q_HX] = q_hx
    return q_hx


@njit(cache=True, inline="always")
def no_combustion(y):
    """Nothing burns: no combustion heat, the analyser sees ambient air."""
    y[Y_O2] = k.O2_AMBIENT_PCT
    y[Y_CO2] = k.CO2_AMBIENT_PCT
    y[Y_SO2] = 0.0
    y[Y_FG_DRY] = 0.0
    y[Y_FG_WET] = 0.0
    y[Y_Q_FUEL] = y[Y_Q_ASH] = y[Y_Q_SENS] = y[Y_Q_LAT] = y[Y_Q_CHEM] = y[Y_Q_HX] = 0.0


@njit(cache=True, inline="always")
def electric_power_W(c, firing, firing_kW, q_ign):
    """Electric power [W]: linear in firing power between Pel,MIN and Pel,MAX plus the
    igniter while firing; Pel,OFF otherwise."""
    if firing:
        return c[K_PEL_MIN] + c[K_PEL_SLOPE] * (firing_kW - c[K_P_MIN]) + q_ign * 1000.0
    return c[K_PEL_OFF]


@njit(cache=True, inline="always")
def close_step(
    s, y, dt_s, mode, firing_kW, fuel_kg_h, p_el, t1, t_mean, t_fg, lam, co, q_ign, m_cp,
    water_in_C, ua, room_C, q_stored,
):  # fmt: skip
    """Advance the state's clocks and counters and write the remaining outputs.

    ``fuel_kg_h`` is the feed (what the balance loses); ``t1``/``t_mean`` the node
    temperature at the end of and over the step; ``q_stored`` the heat stored [kW].
    """
    s[S_T] = t1
    s[S_MODE] = mode
    s[S_MODE_TIME] += dt_s
    s[S_FIRING] = firing_kW
    s[S_SINCE_START] += dt_s
    s[S_SINCE_STOP] += dt_s
    s[S_FUEL] += fuel_kg_h * dt_s / 3600.0
    s[S_ELECTRIC] += p_el * dt_s / 3600.0
    y[Y_T_BOILER] = t1
    y[Y_T_OUT] = t1
    y[Y_T_FG] = t_fg
    y[Y_MODE] = mode
    y[Y_FIRING] = firing_kW
    y[Y_FUEL] = fuel_kg_h
    y[Y_LAMBDA] = lam
    y[Y_CO] = co
    y[Y_Q_IGN] = q_ign
    y[Y_Q_WATER] = m_cp * (t_mean - water_in_C)
    y[Y_Q_AMB] = ua * (t_mean - room_C)
    y[Y_Q_STORED] = q_stored
    y[Y_P_EL] = p_el


# --- the step skeleton -------------------------------------------------------------------
# One step is a fixed sequence of stages; the model's step is the skeleton with the neutral
# stage at each of the named points below, the bench plant's step
# (:func:`rig_emulator.bench.plant.plant_step`) the same skeleton with the unmodelled
# effects' stages there. A hook gets the effect constants ``fc`` and state ``fs`` (2-D,
# one row per effect) and ``row``, the row of the effect that owns the point.

#: Named points of the skeleton where an effect may put its own stage, in step order.
STAGE_POINTS = ("flame_clock", "fuel_bed", "flue_gas", "heat_store")
P_FLAME_CLOCK, P_FUEL_BED, P_FLUE_GAS, P_HEAT_STORE = range(len(STAGE_POINTS))


@njit(cache=True, inline="always")
def burnout_gas(t_water_C, t_fg_C, lam_fan, share):
    """Flue-gas temperature [C] and excess-air ratio [-] while a fuel bed burns less than
    the feed that sets the fan: its burn-out after a stop, a restart onto a bed still
    burning, a bed lighting (the model's burns its feed at once: never; ``share``: the
    burning rate over that feed, in (0, 1)).

    Not part of Type 869. Assumptions (ours): the fan blows the air of that feed (after a
    stop, the last feed's: post-purge), so lambda = lambda_fan / share and the gas flow
    stays that of the air (a restart onto the burn-out's bed collapsed the duct velocity
    from 0.93 to 0.12 m/s in one second while the bed burnt on: a re-probe);
    with that gas flow the exchanger's effectiveness stays, so the exit gas's excess over
    the water scales with the adiabatic rise of the gas, which is proportional to the fuel
    burnt: T_fg = T_w + (T_fg,Eq.8 - T_w) share, T_w the boiler water. This neglects the air's
    own excess over the room (under 4 % of a flame's rise of some 1300 K). Held at Eq. 9's
    value with the gas flow falling with the fuel, the analyser read the full-load O2 to
    the last gram and then air at once, the duct velocity fell to a hundredth of the idle
    draught's, and the gas left as hot as at full load (a physics review).
    """
    return t_water_C + (t_fg_C - t_water_C) * share, lam_fan / share


@njit(cache=True, inline="always")
def model_flame_clock(c, s, fc, fs, row, started):
    """``flame_clock``: time since the flame lit [s]; the model's flame lights at the start."""
    return s[S_SINCE_START]


@njit(cache=True, inline="always")
def model_fuel_bed(c, s, fc, fs, row, firing, feed_kg_h, firing_kW, co_start, dt_s):
    """``fuel_bed``: what burns of the fuel fed. The model burns the feed at once.

    Returns (dry fuel burnt [kg/h], its firing power [kW, net], fuel flow that sets the
    fan for Eq. 9 [kg/h], start CO peak [ppm], True if anything burns).
    """
    return feed_kg_h, firing_kW, feed_kg_h, co_start, firing


@njit(cache=True, inline="always")
def model_flue_gas(fc, fs, row, t_target_C, dt_s):
    """``flue_gas``: flue-gas temperature [C] from its Eq. 8 (or idle) value; the model's
    follows at once."""
    return t_target_C


@njit(cache=True, inline="always")
def model_heat_store(c, fc, fs, row, t0_C, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s):
    """``heat_store``: the one node (Eq. 2, 7, 10) solved exactly over the step.

    Returns (node temperature at the end [C], mean over the step [C], heat stored [kW]).
    """
    cap = c[K_CAP]
    t1, t_mean = node_exact(t0_C, q_in_kW, m_cp, water_in_C, ua, room_C, cap, dt_s)
    return t1, t_mean, cap * (t1 - t0_C) / dt_s


@njit(cache=True, inline="always")
def step_skeleton(
    c, s, fc, fs, rows, water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y, horizon_s,
    flame_clock, fuel_bed, flue_gas, heat_store,
):  # fmt: skip
    """The step every boiler takes; :func:`step` documents the arguments.

    Stages: controller (:func:`update_mode`, :func:`firing_power_kW` over ``dt_s +
    horizon_s``), feed, ``fuel_bed``, combustion (Eq. 1, 3-6, 8, 9) with ``flue_gas``,
    electric power, ``heat_store`` (Eq. 2, 7, 10), :func:`close_step`. ``rows`` maps each
    point (``P_*``) to the row of ``fc``/``fs`` its stage reads; the hooks are the stage
    functions of the points of :data:`STAGE_POINTS`. Inlined into its callers (numba IR),
    so the hooks are resolved at compile time and the kernels stay cacheable.
    """
    t0 = s[S_T]
    mode, started = update_mode(c, s, enabled)
    firing = mode == STARTUP or mode == MODULATING
    m_cp = water_flow_kg_h * _CP_W_KWH
    since_flame = flame_clock(c, s, fc, fs, rows[P_FLAME_CLOCK], started)
    co_start = c[K_CO_START] * math.exp(-since_flame / c[K_CO_TAU])
    if startup_hands_over(c, s, mode, m_cp, water_flow_kg_h, water_in_C, room_C, co_start):
        mode = MODULATING
        s[S_MODE_TIME] = 0.0

    # what the controller commands: firing power (net basis) and the feed it implies
    q_ign = 0.0
    firing_kW = 0.0
    if firing:
        q_ign = igniter_kW(c, s)
        firing_kW = firing_power_kW(
            c, s, mode, m_cp, water_flow_kg_h, water_in_C, room_C, q_ign, co_start,
            dt_s + horizon_s,
        )  # fmt: skip
    feed = firing_kW * 3600.0 / c[K_LHV]  # [kg/h dry]
    burn, burn_kW, fan_feed, co_start, burning = fuel_bed(
        c, s, fc, fs, rows[P_FUEL_BED], firing, feed, firing_kW, co_start, dt_s
    )
    ua = c[K_UA_ON] if firing or burning else c[K_UA_OFF]  # the fan runs

    if burning:
        t_fg_target = flue_gas_temperature(c, water_in_C, water_flow_kg_h, burn)
        lam = excess_air(c, fan_feed)
        if 0.0 < burn < fan_feed:  # (the model's bed burns its feed: never)
            t_fg_target, lam = burnout_gas(t0, t_fg_target, lam, burn / fan_feed)
        t_fg = flue_gas(fc, fs, rows[P_FLUE_GAS], t_fg_target, dt_s)
        # while firing the start peak adds; in a burn-out the stop peak, as when off
        co = co_stationary_ppm(c, burn_kW) + co_start if firing else burnout_co_ppm(c, s)
        q_hx = combustion(c, burn, lam, t_fg, room_C, co, y)
    else:
        q_hx = 0.0
        lam = math.inf
        co = burnout_co_ppm(c, s)
        no_combustion(y)
        t_fg = 0.0  # set below: the probe sees draught air leaving at the node temperature
    p_el = electric_power_W(c, firing, firing_kW, q_ign)

    t1, t_mean, q_stored = heat_store(
        c, fc, fs, rows[P_HEAT_STORE], t0, q_hx + q_ign, m_cp, water_in_C, ua, room_C, dt_s
    )
    if not burning:
        t_fg = flue_gas(fc, fs, rows[P_FLUE_GAS], t1, dt_s)
    close_step(
        s, y, dt_s, mode, firing_kW, feed, p_el, t1, t_mean, t_fg, lam, co, q_ign, m_cp,
        water_in_C, ua, room_C, q_stored,
    )  # fmt: skip


@njit(cache=True)
def step(c, s, water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y):
    """Advance the boiler by ``dt_s`` seconds with inputs held over the step.

    The skeleton (:func:`step_skeleton`) with the model's stages at every point; they read
    no effect arrays (None) and no rows.

    Args:
        c: constants (:func:`pack_constants`); s: state (layout ``S_*``), updated in place.
        water_flow_kg_h: water flow through the boiler [kg/h].
        water_in_C: return (inlet) temperature [C]; room_C: room temperature [C].
        enabled: external on/off command of the bench; dt_s: step length [s].
        y: output array (layout ``Y_*``), filled in place.
    """
    step_skeleton(
        c, s, None, None, (0, 0, 0, 0), water_flow_kg_h, water_in_C, room_C,
        enabled, dt_s, y, 0.0, model_flame_clock, model_fuel_bed, model_flue_gas,
        model_heat_store,
    )  # fmt: skip


def balance_residual_kW(y: np.ndarray) -> float:
    """Inputs less outputs of the energy balance of one step's outputs [kW]."""
    return float(
        y[Y_Q_FUEL]
        + y[Y_Q_IGN]
        - y[Y_Q_ASH]
        - y[Y_Q_SENS]
        - y[Y_Q_LAT]
        - y[Y_Q_CHEM]
        - y[Y_Q_WATER]
        - y[Y_Q_AMB]
        - y[Y_Q_STORED]
    )
