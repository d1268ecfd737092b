"""The boiler as the real bench has it: the Type 869 step with the unmodelled effects.

:mod:`rig_emulator.bench.effects` describes the effects and their parameters; this module
holds their compiled physics. :func:`plant_step` is :func:`rig_emulator.model.boiler.step`
with the effects switched in (it reuses the model's own functions for everything the
effects leave alone), and :func:`pipe_sensor` is the forward sensor down the exit pipe. The
bench calls them only when an effect needs them; with every effect off it calls the pure
model, so the plant is then the model bit for bit.

Numerics (inputs held over a step, as in the model):
- body chain: backward Euler over the metal nodes and the water node (a tridiagonal system,
  L-stable for any conduction time constant). Its step-end temperatures define the heat
  flows, so the balance Q_in = Q_water + Q_amb + sum C_i dT_i/dt closes to rounding. Without
  the body effect the one node is solved exactly as in the model;
- bed and flue-gas nodes: exact solutions of their linear equations over the step;
- exit pipe: a history of the water that entered it (cumulated mass, temperature, time),
  searched forward for the parcel now at the sensor (amortised O(1) per step).

Layouts: constants :data:`FX_CONSTANT_FIELDS` (:func:`pack_effect_constants`), state
:data:`FX_STATE_FIELDS` (:func:`new_effect_state`), pipe history ``PH_*`` rows of
:data:`N_HISTORY` entries.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rig_emulator.bench.effects import MAX_BODY_NODES, EffectSettings
from rig_emulator.model import boiler as bm
from rig_emulator.model import constants as k
from rig_emulator.model.layout import (
    K_CO_START,
    K_LHV,
    S_SINCE_START,
    index_of,
)
from rig_emulator.model.params import BoilerParams

_CP_W_KWH = k.CP_WATER / 3600.0  # kg/h flow to kW/K
_ASH = k.ASH_LOSS_FRACTION
#: Bed content below which a bed without feed counts as burnt out [kg dry].
BED_EMPTY_KG = 1e-4
#: Share of the body's conduction time constant the controller waits out (assumption).
HORIZON_PER_BODY_TAU = 0.8

# --- effect constants and state: one declaration each (see model.layout)
FX_CONSTANT_FIELDS = (
    "body_on",  # 0/1
    "body_metal_nodes",  # [-]
    "body_metal_node_capacity_kJ_K",
    "body_water_capacity_kJ_K",
    "body_link_conductance_kW_K",
    "controller_horizon_s",  # beyond one step
    "ignition_on",  # 0/1
    "ignition_delay_s",
    "burnout_time_constant_s",
    "flue_on",  # 0/1
    "flue_exchanger_time_constant_s",
    "flue_refractory_time_constant_s",
    "pipe_on",  # 0/1
    "pipe_water_kg",
    "pipe_room_rate_1_s",  # relaxation rate toward the room
    "pipe_boiler_rate_1_s",  # relaxation rate toward the boiler water (inf: instant)
)
FC = index_of(FX_CONSTANT_FIELDS)
FC_BODY_ON = FC["body_on"]
FC_BODY_N = FC["body_metal_nodes"]
FC_BODY_CM = FC["body_metal_node_capacity_kJ_K"]
FC_BODY_CW = FC["body_water_capacity_kJ_K"]
FC_BODY_G = FC["body_link_conductance_kW_K"]
FC_HORIZON = FC["controller_horizon_s"]
FC_IGN_ON = FC["ignition_on"]
FC_IGN_DELAY = FC["ignition_delay_s"]
FC_IGN_TAU = FC["burnout_time_constant_s"]
FC_FG_ON = FC["flue_on"]
FC_FG_TAU1 = FC["flue_exchanger_time_constant_s"]
FC_FG_TAU2 = FC["flue_refractory_time_constant_s"]
FC_PIPE_ON = FC["pipe_on"]
FC_PIPE_MASS = FC["pipe_water_kg"]
FC_PIPE_K_ROOM = FC["pipe_room_rate_1_s"]
FC_PIPE_K_BOILER = FC["pipe_boiler_rate_1_s"]
N_FX_CONSTANTS = len(FX_CONSTANT_FIELDS)

FX_STATE_FIELDS = (
    *(f"metal_{i}_C" for i in range(MAX_BODY_NODES)),  # metal node temperatures
    "bed_kg",  # fuel in the bed [kg dry, nominal-energy equivalent]
    "bed_lit",  # 0/1: the bed burns
    "ignition_timer_s",  # time fed since the start while unlit
    "since_ignition_s",
    "lambda_feed_kg_h",  # feed rate that sets the fan (held in the burn-out)
    "flue_exchanger_C",  # exchanger node of the flue-gas lag
    "flue_gas_C",  # refractory node = flue-gas temperature
    "pipe_sensor_C",  # temperature of the parcel at the sensor
    "pipe_cumulated_kg",  # cumulated mass that entered the pipe
    "pipe_parcel",  # history index of the parcel at the sensor (-1: initial water)
    "pipe_head",  # entries written to the history so far
    "time_s",
)
FS = index_of(FX_STATE_FIELDS)
FS_METAL = FS["metal_0_C"]  # the metal nodes follow in order
FS_BED = FS["bed_kg"]
FS_LIT = FS["bed_lit"]
FS_IGN_TIMER = FS["ignition_timer_s"]
FS_SINCE_IGNITION = FS["since_ignition_s"]
FS_LAMBDA_FEED = FS["lambda_feed_kg_h"]
FS_FG1 = FS["flue_exchanger_C"]
FS_FG2 = FS["flue_gas_C"]
FS_PIPE_T = FS["pipe_sensor_C"]
FS_PIPE_MASS = FS["pipe_cumulated_kg"]
FS_PIPE_PARCEL = FS["pipe_parcel"]
FS_PIPE_HEAD = FS["pipe_head"]
FS_TIME = FS["time_s"]
N_FX_STATE = len(FX_STATE_FIELDS)

# --- pipe history: rows of cumulated mass at the end of the entry [kg], temperature [C],
# time at its end [s]
PH_MASS, PH_TEMP, PH_TIME = range(3)
N_HISTORY = 4096


def pack_effect_constants(fx: EffectSettings, params: BoilerParams) -> np.ndarray:
    """The effect constants (layout ``FC_*``) for resolved settings and a boiler."""
    fc = np.zeros(N_FX_CONSTANTS)
    cap = params.capacity_kJ_K
    if fx.body_on:
        n = fx.body_nodes
        c_metal = fx.body_metal_share * cap
        fc[FC_BODY_ON] = 1.0
        fc[FC_BODY_N] = n
        fc[FC_BODY_CM] = c_metal / n
        fc[FC_BODY_CW] = cap - c_metal
        fc[FC_BODY_G] = n * c_metal / fx.body_time_constant_s
        fc[FC_HORIZON] += HORIZON_PER_BODY_TAU * fx.body_time_constant_s
    if fx.ignition_on:
        fc[FC_IGN_ON] = 1.0
        fc[FC_IGN_DELAY] = fx.ignition_delay_s
        fc[FC_IGN_TAU] = fx.burnout_time_constant_s
        fc[FC_HORIZON] += fx.burnout_time_constant_s
    if fx.flue_on:
        fc[FC_FG_ON] = 1.0
        fc[FC_FG_TAU1] = fx.flue_time_constant_s * (1.0 - fx.flue_refractory_share)
        fc[FC_FG_TAU2] = fx.flue_time_constant_s * fx.flue_refractory_share
    if fx.pipe_on:
        fc[FC_PIPE_ON] = 1.0
        fc[FC_PIPE_MASS] = fx.pipe_volume_l * 1e-3 * k.RHO_WATER
        fc[FC_PIPE_K_ROOM] = 1.0 / fx.pipe_cooling_time_constant_s
        tau_b = fx.pipe_coupling_time_constant_s
        fc[FC_PIPE_K_BOILER] = 1.0 / tau_b if tau_b > 0 else math.inf
    return fc


def new_effect_state(t_C: float) -> tuple[np.ndarray, np.ndarray]:
    """(state ``FS_*``, pipe history) of a plant at rest at ``t_C`` with an empty bed."""
    fs = np.zeros(N_FX_STATE)
    fs[FS_METAL : FS_METAL + MAX_BODY_NODES] = t_C
    fs[FS_SINCE_IGNITION] = math.inf
    fs[FS_FG1] = fs[FS_FG2] = fs[FS_PIPE_T] = t_C
    fs[FS_PIPE_PARCEL] = -1.0
    return fs, np.zeros((3, N_HISTORY))


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


@njit(cache=True)
def body_chain(fc, fs, t_w0, q_in_kW, m_cp, water_in_C, ua, room_C, dt_s):
    """Advance metal nodes and water node by backward Euler; metal temperatures in ``fs``.

    C_m dT_1/dt = Q_in - G (T_1 - T_2)
    C_m dT_i/dt = G (T_(i-1) - T_i) - G (T_i - T_(i+1))
    C_w dT_w/dt = G (T_n - T_w) - m cp (T_w - T_in) - UA (T_w - T_room)

    Returns (water temperature at the end [C], heat stored in all nodes [kW]).
    """
    n = int(fc[FC_BODY_N])
    cm = fc[FC_BODY_CM] / dt_s
    cw = fc[FC_BODY_CW] / dt_s
    g = fc[FC_BODY_G]
    # tridiagonal system over nodes 0..n (n = water): sub a, diagonal b, super c, rhs d
    b = np.empty(n + 1)
    d = np.empty(n + 1)
    for i in range(n):
        b[i] = cm + 2.0 * g
        d[i] = cm * fs[FS_METAL + i]
    b[0] = cm + g
    d[0] += q_in_kW
    b[n] = cw + g + m_cp + ua
    d[n] = cw * t_w0 + m_cp * water_in_C + ua * room_C
    # Thomas algorithm, a = c = -g everywhere
    for i in range(1, n + 1):
        w = -g / b[i - 1]
        b[i] += w * g
        d[i] -= w * d[i - 1]
    t_new = d[n] / b[n]
    stored = fc[FC_BODY_CW] * (t_new - t_w0)
    t_next = t_new
    for i in range(n - 1, -1, -1):
        t_i = (d[i] + g * t_next) / b[i]
        stored += fc[FC_BODY_CM] * (t_i - fs[FS_METAL + i])
        fs[FS_METAL + i] = t_i
        t_next = t_i
    return t_new, stored / dt_s


@njit(cache=True, inline="always")
def _flame_clock(c, s, fc, fs, row, started):
    """``flame_clock``: a start resets the ignition timer; the flame's age is the bed's."""
    if started:
        fs[FS_IGN_TIMER] = 0.0
    return fs[FS_SINCE_IGNITION] if fc[FC_IGN_ON] > 0.5 else s[S_SINCE_START]


@njit(cache=True, inline="always")
def _fuel_bed(c, s, fc, fs, row, firing, feed, firing_kW, co_start, dt_s):
    """``fuel_bed``: fuel fed collects, burns once lit, burns out after a stop."""
    if fc[FC_IGN_ON] < 0.5:
        return bm.model_fuel_bed(c, s, fc, fs, row, firing, feed, firing_kW, co_start, dt_s)
    m0 = fs[FS_BED]
    f_s = feed / 3600.0  # [kg/s]
    t_unlit = 0.0  # part of the step before the bed lights [s]
    if fs[FS_LIT] < 0.5:
        t_unlit = dt_s
        if firing:
            wait = max(fc[FC_IGN_DELAY] - fs[FS_IGN_TIMER], 0.0)
            if wait < dt_s:  # the bed lights within this step
                fs[FS_LIT] = 1.0
                fs[FS_SINCE_IGNITION] = -wait
                t_unlit = wait
                co_start = c[K_CO_START]
    if firing:
        fs[FS_LAMBDA_FEED] = feed
        fs[FS_IGN_TIMER] += dt_s
    m1 = m0 + f_s * t_unlit
    t_lit = dt_s - t_unlit
    if fs[FS_LIT] > 0.5 and t_lit > 0.0:
        tau = fc[FC_IGN_TAU]
        m1 = f_s * tau + (m1 - f_s * tau) * math.exp(-t_lit / tau) if tau > 0.0 else 0.0
        if not firing and m1 < BED_EMPTY_KG:
            m1 = 0.0
            fs[FS_LIT] = 0.0
    fs[FS_BED] = m1
    burn = (m0 + f_s * dt_s - m1) * 3600.0 / dt_s  # mean over the step [kg/h]
    fs[FS_SINCE_IGNITION] += dt_s
    return burn, burn * c[K_LHV] / 3600.0, fs[FS_LAMBDA_FEED], co_start, burn > 0.0


@njit(cache=True, inline="always")
def _heat_store(c, fc, fs, row, t0, q_in, m_cp, water_in_C, ua, room_C, dt_s):
    """``heat_store``: the metal chain and the water node, or the model's one node."""
    if fc[FC_BODY_ON] < 0.5:
        return bm.model_heat_store(c, fc, fs, row, t0, q_in, m_cp, water_in_C, ua, room_C, dt_s)
    t1, q_stored = body_chain(fc, fs, t0, q_in, m_cp, water_in_C, ua, room_C, dt_s)
    return t1, t1, q_stored


@njit(cache=True, inline="always")
def _flue_gas(fc, fs, row, t_target_C, dt_s):
    """``flue_gas``: flue-gas temperature [C], the target through the two-node lag if on."""
    if fc[FC_FG_ON] < 0.5:
        return t_target_C
    fs[FS_FG1], fs[FS_FG2] = lag2(
        fs[FS_FG1], fs[FS_FG2], t_target_C, fc[FC_FG_TAU1], fc[FC_FG_TAU2], dt_s
    )
    return fs[FS_FG2]


@njit(cache=True)
def plant_step(c, s, fc, fs, water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y):
    """The model's step skeleton (:func:`~rig_emulator.model.boiler.step_skeleton`) with
    the effects' stages.

    Same arguments, state and outputs as the model, plus the effect constants ``fc`` and
    state ``fs`` (updated in place). Differences from the model (each only if its effect
    is on): the controller's horizon; the feed (what the balance loses: ``s[S_FUEL]``,
    ``y[Y_FUEL]``) and the fuel that burns (``y[Y_Q_FUEL]``, the flue gas) differ by the
    bed; the flue-gas temperature is lagged; the heat goes through the metal chain.
    Fuel masses here are in kg of nominal energy (HHV); the fuel-energy bias is applied by
    the balance (:class:`~rig_emulator.bench.bench.Bench`). Electric power follows the
    controller, as in the model (the fan's share during a burn-out is neglected).
    """
    bm.step_skeleton(
        c, s, fc, fs, (0, 0, 0, 0), water_flow_kg_h, water_in_C, room_C, enabled, dt_s, y,
        fc[FC_HORIZON], _flame_clock, _fuel_bed, _flue_gas, _heat_store,
    )  # fmt: skip


@njit(cache=True)
def pipe_sensor(fc, fs, ph, flow_kg_h, t_outlet_C, t_boiler_C, room_C, dt_s):
    """Advance the exit pipe by a step; returns the forward sensor's temperature [C].

    ``t_outlet_C`` is the mean temperature of the water leaving the boiler over the step
    (it enters the pipe); the sensor's parcel is the water that entered one pipe content
    (FC_PIPE_MASS) of flow ago. Parcels relax toward T_c = (k_b T_boiler + k_r T_room) /
    (k_b + k_r) at the rate k_b + k_r: a parcel newly at the sensor has done so for its
    residence time (with the present T_c, exact while T_boiler changes little over a
    residence), the same parcel is advanced by ``dt_s``. Entries smaller than
    1/256 of the pipe content (the trickle after the pump stops) are merged into the last
    one, so the history always spans many pipe contents.
    """
    k_r = fc[FC_PIPE_K_ROOM]
    k_b = fc[FC_PIPE_K_BOILER]
    if math.isinf(k_b):  # instant coupling: the pipe's water is the boiler's
        return t_boiler_C
    rate = k_b + k_r
    t_c = (k_b * t_boiler_C + k_r * room_C) / rate if rate > 0.0 else t_boiler_C
    fs[FS_TIME] += dt_s
    now = fs[FS_TIME]  # the end of this step
    head = int(fs[FS_PIPE_HEAD])
    inc = flow_kg_h * dt_s / 3600.0
    if inc > 0.0:
        mass = fs[FS_PIPE_MASS] + inc
        eps = max(fc[FC_PIPE_MASS] / 256.0, 1e-6)
        last_start = ph[PH_MASS, (head - 2) % N_HISTORY] if head >= 2 else 0.0
        if head >= 1 and mass - last_start < eps:  # merge into the last entry
            row = (head - 1) % N_HISTORY
            size = ph[PH_MASS, row] - last_start
            ph[PH_TEMP, row] = (ph[PH_TEMP, row] * size + t_outlet_C * inc) / (size + inc)
        else:
            row = head % N_HISTORY
            ph[PH_TEMP, row] = t_outlet_C
            head += 1
            fs[FS_PIPE_HEAD] = head
        ph[PH_MASS, row] = mass
        ph[PH_TIME, row] = now
        fs[FS_PIPE_MASS] = mass
    target = fs[FS_PIPE_MASS] - fc[FC_PIPE_MASS]  # cumulated mass when the parcel entered
    parcel = int(fs[FS_PIPE_PARCEL])
    new = parcel
    if target > 0.0 and head > 0:
        new = max(parcel, head - N_HISTORY, 0)
        while new < head - 1 and ph[PH_MASS, new % N_HISTORY] < target:
            new += 1
    if new != parcel:
        fs[FS_PIPE_PARCEL] = new
        row = new % N_HISTORY
        end_mass = ph[PH_MASS, row]
        end_time = ph[PH_TIME, row]
        if new >= 1 and new - 1 >= head - N_HISTORY:
            prev = (new - 1) % N_HISTORY
            start_mass, start_time = ph[PH_MASS, prev], ph[PH_TIME, prev]
        else:  # the first entry: it started with the cumulated mass 0 one step earlier
            start_mass, start_time = 0.0, end_time - dt_s
        # entry time of the parcel, interpolated within its history entry
        w = (target - start_mass) / (end_mass - start_mass) if end_mass > start_mass else 1.0
        w = min(max(w, 0.0), 1.0)
        residence = max(now - (start_time + w * (end_time - start_time)), 0.0)
        t_s = t_c + (ph[PH_TEMP, row] - t_c) * math.exp(-rate * residence)
    else:
        t_s = t_c + (fs[FS_PIPE_T] - t_c) * math.exp(-rate * dt_s)
    fs[FS_PIPE_T] = t_s
    return t_s
