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
temperature it stops, and it restarts when the water has cooled to the restart temperature.

Assumptions (ours, where the paper is silent):
- firing powers are on the net (LHV, dry) basis; Q_fuel = P HHV/LHV (see params.py);
- m_fuel,nom of Eq. 8 is the dry fuel flow at Pmax;
- the ignition energy Wel is spread evenly over the start-up and heats the node;
- when the burner is off the flue-gas probe sees draught air leaving the exchanger at the
  node temperature, and the analyser sees ambient air (plus the decaying burn-out CO);
- electric power is linear in firing power between Pel,MIN at Pmin and Pel,MAX at Pmax.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rig_emulator.model import constants as k
from rig_emulator.model.emissions import co_ppm
from rig_emulator.model.fuel import stoichiometry
from rig_emulator.model.params import BoilerParams

# Controller modes.
OFF = 0  #: switched off by the external command
STARTUP = 1  #: firing at Pstart after a start
MODULATING = 2  #: firing between Pmin and Pmax to hold the set temperature
CUTOUT = 3  #: stopped above the shut-off temperature, waiting for the restart temperature
MODE_NAMES = {OFF: "off", STARTUP: "start_up", MODULATING: "modulating", CUTOUT: "cut_out"}

_INF = math.inf


@dataclass(frozen=True, slots=True)
class BoilerCoefficients:
    """Per-boiler constants derived once from :class:`BoilerParams` (no state)."""

    hhv: float  # [kJ/kg dry]
    lhv: float  # [kJ/kg dry]
    capacity: float  # node capacity [kJ/K]
    ua_on: float  # [kW/K]
    ua_off: float  # [kW/K]
    a0: float  # dry flue-gas mass = a0 + a1 lambda [kg/kg]
    a1: float
    b0: float  # dry flue-gas heat capacity = b0 + b1 lambda [kJ/(K kg)]
    b1: float
    m_h2o: float  # vapour [kg/kg]
    latent: float  # m_h2o dH_vap [kJ/kg]
    v_dry0: float  # dry volume = v_dry0 + v_dry1 lambda [m3(N)/kg]
    v_dry1: float
    v_h2o: float  # vapour volume [m3(N)/kg]
    v_o2_per_lambda: float  # O2 volume = v_o2_per_lambda (lambda - 1)
    v_co2: float
    v_so2: float
    fuel_nom_kg_h: float  # dry fuel flow at Pmax [kg/h]
    flow_nom_kg_h: float  # nominal water flow [kg/h]
    as_received_factor: float  # as-received fuel per kg dry
    ignition_kW: float  # Wel spread over the start-up [kW]


def coefficients(p: BoilerParams) -> BoilerCoefficients:
    """Derive the per-boiler constants of :func:`step` from the parameter set."""
    st = stoichiometry(p.fuel)
    a0, a1 = st.dry_mass_coeffs()
    b0, b1 = st.dry_heat_capacity_coeffs()
    v_dry0 = st.dry_volume_m3(0.0)
    v_dry1 = st.dry_volume_m3(1.0) - v_dry0
    lhv = p.fuel.lhv_dry_kJ_kg
    return BoilerCoefficients(
        hhv=p.fuel.hhv_dry_kJ_kg,
        lhv=lhv,
        capacity=p.capacity_kJ_K,
        ua_on=p.ua_amb_on_W_K / 1000.0,
        ua_off=p.ua_amb_off_W_K / 1000.0,
        a0=a0,
        a1=a1,
        b0=b0,
        b1=b1,
        m_h2o=st.m_h2o_kg,
        latent=st.m_h2o_kg * k.DH_VAP_WATER,
        v_dry0=v_dry0,
        v_dry1=v_dry1,
        v_h2o=st.m_h2o_kg / k.RHO_N_H2O,
        v_o2_per_lambda=k.O2_AIR * st.air_min_m3,
        v_co2=st.v_co2_m3,
        v_so2=st.v_so2_m3,
        fuel_nom_kg_h=p.p_max_kW * 3600.0 / lhv,
        flow_nom_kg_h=p.nominal_flow_kg_h,
        as_received_factor=p.fuel.as_received_per_kg_dry,
        ignition_kW=p.w_el_Wh * 3.6 / p.startup_duration_s,
    )


@dataclass(slots=True)
class BoilerState:
    """State of the boiler between steps.

    Attributes:
        t_boiler_C: temperature of the node (water and structure) [C].
        mode: controller mode (OFF, STARTUP, MODULATING, CUTOUT).
        mode_time_s: time spent in the current mode [s].
        firing_kW: firing power of the last step (net basis) [kW].
        since_start_s / since_stop_s: time since the last ignition / stop [s].
        fuel_dry_kg: dry fuel burnt so far [kg].
        electric_Wh: electricity drawn so far [Wh].
        starts: number of ignitions so far.
    """

    t_boiler_C: float
    mode: int = OFF
    mode_time_s: float = 0.0
    firing_kW: float = 0.0
    since_start_s: float = _INF
    since_stop_s: float = _INF
    fuel_dry_kg: float = 0.0
    electric_Wh: float = 0.0
    starts: int = 0

    def copy(self) -> BoilerState:
        return BoilerState(
            self.t_boiler_C,
            self.mode,
            self.mode_time_s,
            self.firing_kW,
            self.since_start_s,
            self.since_stop_s,
            self.fuel_dry_kg,
            self.electric_Wh,
            self.starts,
        )


@dataclass(slots=True)
class BoilerOutputs:
    """Everything the instruments and the analysis need from one step.

    Temperatures are end-of-step values [C]; heat flows are step means [kW].
    """

    t_boiler_C: float
    t_out_C: float
    t_flue_gas_C: float
    mode: int
    firing_kW: float
    fuel_dry_kg_h: float
    lambda_: float
    o2_pct: float
    co2_pct: float
    so2_ppm: float
    co_ppm: float
    flue_gas_dry_kg_h: float
    flue_gas_wet_m3n_h: float
    q_fuel_kW: float
    q_el_ign_kW: float
    q_ash_kW: float
    q_fg_sens_kW: float
    q_fg_lat_kW: float
    q_fg_chem_kW: float
    q_hx_kW: float
    q_water_kW: float
    q_amb_kW: float
    q_stored_kW: float
    p_el_W: float

    @property
    def balance_residual_kW(self) -> float:
        """Inputs less outputs of the energy balance [kW]; zero to rounding."""
        return (
            self.q_fuel_kW
            + self.q_el_ign_kW
            - self.q_ash_kW
            - self.q_fg_sens_kW
            - self.q_fg_lat_kW
            - self.q_fg_chem_kW
            - self.q_water_kW
            - self.q_amb_kW
            - self.q_stored_kW
        )


def flue_gas_temperature(
    p: BoilerParams, c: BoilerCoefficients, water_in_C: float, water_flow_kg_h: float,
    fuel_dry_kg_h: float,
) -> float:
    """Flue-gas temperature while firing [C], Eq. 8 (empirical delta-T approach)."""
    return (
        water_in_C
        + p.dt_nom_K
        + p.dt_hx_fg_K * (1.0 - fuel_dry_kg_h / c.fuel_nom_kg_h)
        + p.dt_hx_wat_K * (1.0 - water_flow_kg_h / c.flow_nom_kg_h)
    )


def _fuel_for_heat(
    p: BoilerParams, c: BoilerCoefficients, q_hx_kW: float, dt_fg_K: float, chem_per_kg: float
) -> float:
    """Dry fuel flow [kg/h] whose combustion delivers ``q_hx_kW`` to the exchanger.

    Q_hx 3600 = x (HHV (1 - ash) - (b0 + b1 facA + m_H2O cp_v) dT - latent - chem)
                - b1 facB dT x^2, solved for x (the root that tends to q/beta).
    """
    beta = (
        c.hhv * (1.0 - k.ASH_LOSS_FRACTION)
        - (c.b0 + c.b1 * p.fac_a_lambda + c.m_h2o * k.CP_VAPOUR) * dt_fg_K
        - c.latent
        - chem_per_kg
    )
    gamma = c.b1 * p.fac_b_lambda_h_kg * dt_fg_K
    q = q_hx_kW * 3600.0
    disc = beta * beta - 4.0 * gamma * q
    if disc <= 0.0 or beta <= 0.0:
        return c.fuel_nom_kg_h
    return 2.0 * q / (beta + math.sqrt(disc))


def step(
    p: BoilerParams,
    c: BoilerCoefficients,
    s: BoilerState,
    water_flow_kg_h: float,
    water_in_C: float,
    room_C: float,
    enabled: bool,
    dt_s: float,
) -> tuple[BoilerState, BoilerOutputs]:
    """Advance the boiler by ``dt_s`` seconds with inputs held constant over the step.

    Args:
        p, c: parameters and their derived coefficients.
        s: state at the start of the step (not modified).
        water_flow_kg_h: water mass flow through the boiler [kg/h].
        water_in_C: return (inlet) water temperature [C].
        room_C: room air temperature [C].
        enabled: external on/off command of the bench.
        dt_s: step length [s].

    Returns:
        The state at the end of the step and the step's outputs.
    """
    t0 = s.t_boiler_C
    mode = s.mode
    mode_time = s.mode_time_s
    since_start = s.since_start_s
    since_stop = s.since_stop_s
    starts = s.starts
    was_firing = mode == STARTUP or mode == MODULATING

    # --- controller: mode transitions on the state at the start of the step
    if not enabled:
        new_mode = OFF
    elif mode == OFF:
        new_mode = STARTUP if t0 < p.set_temp_C else CUTOUT
    elif mode == CUTOUT:
        new_mode = STARTUP if t0 <= p.restart_temp_C else CUTOUT
    elif t0 >= p.shutoff_temp_C:
        new_mode = CUTOUT
    elif mode == STARTUP and mode_time >= p.startup_duration_s:
        new_mode = MODULATING
    else:
        new_mode = mode
    if new_mode != mode:
        mode_time = 0.0
        if new_mode == STARTUP:
            since_start = 0.0
            starts += 1
        elif was_firing and new_mode in (OFF, CUTOUT):
            since_stop = 0.0
    mode = new_mode
    firing = mode == STARTUP or mode == MODULATING

    m_cp = water_flow_kg_h * k.CP_WATER / 3600.0  # [kW/K]
    ua = c.ua_on if firing else c.ua_off
    b = m_cp + ua
    cap = c.capacity
    decay = math.exp(-b * dt_s / cap)
    q_ign = c.ignition_kW if mode == STARTUP else 0.0

    # --- firing power
    if firing:
        dt_fg = flue_gas_temperature(p, c, water_in_C, water_flow_kg_h, s.firing_kW) - room_C
        if mode == STARTUP:
            firing_kW = p.p_start_kW
        else:
            # heat that brings the node to the set temperature by the end of the step
            t_eq = (p.set_temp_C - t0 * decay) / (1.0 - decay)
            q_req = b * t_eq - m_cp * water_in_C - ua * room_C - q_ign
            x_prev = s.firing_kW * 3600.0 / c.lhv
            co_prev = co_ppm(
                s.firing_kW, p.p_min_kW, p.p_max_kW, p.co_ppm_at_p_min, p.co_ppm_at_p_max,
                p.co_start_peak_ppm, p.co_stop_peak_ppm, p.co_transient_s, since_start,
                since_stop,
            )
            lam_prev = p.fac_a_lambda + p.fac_b_lambda_h_kg * x_prev
            chem = co_prev * 1e-6 * (c.v_dry0 + c.v_dry1 * lam_prev) * k.RHO_N_CO * k.DH_COMB_CO
            x = _fuel_for_heat(p, c, max(q_req, 0.0), dt_fg, chem)
            firing_kW = min(max(x * c.lhv / 3600.0, p.p_min_kW), p.p_max_kW)
        fuel_kg_h = firing_kW * 3600.0 / c.lhv
        t_fg = flue_gas_temperature(p, c, water_in_C, water_flow_kg_h, fuel_kg_h)
        lam = p.fac_a_lambda + p.fac_b_lambda_h_kg * fuel_kg_h
        co = co_ppm(
            firing_kW, p.p_min_kW, p.p_max_kW, p.co_ppm_at_p_min, p.co_ppm_at_p_max,
            p.co_start_peak_ppm, p.co_stop_peak_ppm, p.co_transient_s, since_start, since_stop,
        )
        v_dry = c.v_dry0 + c.v_dry1 * lam
        per_h = fuel_kg_h / 3600.0
        q_fuel = per_h * c.hhv
        q_ash = k.ASH_LOSS_FRACTION * q_fuel
        dT = t_fg - room_C
        q_sens = per_h * ((c.b0 + c.b1 * lam) + c.m_h2o * k.CP_VAPOUR) * dT
        q_lat = per_h * c.latent
        q_chem = per_h * co * 1e-6 * v_dry * k.RHO_N_CO * k.DH_COMB_CO
        q_hx = q_fuel - q_ash - q_sens - q_lat - q_chem
        o2 = 100.0 * c.v_o2_per_lambda * (lam - 1.0) / v_dry
        co2 = 100.0 * c.v_co2 / v_dry
        so2 = 1e6 * c.v_so2 / v_dry
        fg_dry = fuel_kg_h * (c.a0 + c.a1 * lam)
        fg_wet = fuel_kg_h * (v_dry + c.v_h2o)
        span = p.p_max_kW - p.p_min_kW
        frac = (firing_kW - p.p_min_kW) / span if span > 0 else 1.0
        p_el = p.p_el_min_W + (p.p_el_max_W - p.p_el_min_W) * frac + q_ign * 1000.0
    else:
        firing_kW = fuel_kg_h = q_fuel = q_ash = q_sens = q_lat = q_chem = q_hx = 0.0
        lam = _INF
        o2, co2, so2 = k.O2_AMBIENT_PCT, k.CO2_AMBIENT_PCT, 0.0
        co = co_ppm(
            0.0, p.p_min_kW, p.p_max_kW, p.co_ppm_at_p_min, p.co_ppm_at_p_max,
            p.co_start_peak_ppm, p.co_stop_peak_ppm, p.co_transient_s, since_start, since_stop,
        )
        fg_dry = fg_wet = 0.0
        p_el = p.p_el_off_W
        t_fg = _INF  # set below from the node temperature

    # --- exact solution of the linear node equation over the step
    a = q_hx + q_ign + m_cp * water_in_C + ua * room_C
    t_eq = a / b
    t1 = t_eq + (t0 - t_eq) * decay
    # step mean of T: integral of the exponential over the step
    t_mean = t_eq + (t0 - t_eq) * (1.0 - decay) * cap / (b * dt_s)
    q_water = m_cp * (t_mean - water_in_C)
    q_amb = ua * (t_mean - room_C)
    q_stored = cap * (t1 - t0) / dt_s
    if not firing:
        t_fg = t1

    new_state = BoilerState(
        t_boiler_C=t1,
        mode=mode,
        mode_time_s=mode_time + dt_s,
        firing_kW=firing_kW,
        since_start_s=since_start + dt_s,
        since_stop_s=since_stop + dt_s,
        fuel_dry_kg=s.fuel_dry_kg + fuel_kg_h * dt_s / 3600.0,
        electric_Wh=s.electric_Wh + p_el * dt_s / 3600.0,
        starts=starts,
    )
    out = BoilerOutputs(
        t_boiler_C=t1,
        t_out_C=t1,
        t_flue_gas_C=t_fg,
        mode=mode,
        firing_kW=firing_kW,
        fuel_dry_kg_h=fuel_kg_h,
        lambda_=lam,
        o2_pct=o2,
        co2_pct=co2,
        so2_ppm=so2,
        co_ppm=co,
        flue_gas_dry_kg_h=fg_dry,
        flue_gas_wet_m3n_h=fg_wet,
        q_fuel_kW=q_fuel,
        q_el_ign_kW=q_ign,
        q_ash_kW=q_ash,
        q_fg_sens_kW=q_sens,
        q_fg_lat_kW=q_lat,
        q_fg_chem_kW=q_chem,
        q_hx_kW=q_hx,
        q_water_kW=q_water,
        q_amb_kW=q_amb,
        q_stored_kW=q_stored,
        p_el_W=p_el,
    )
    return new_state, out
