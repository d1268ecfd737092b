"""``ignition_delay``: after a start the auger feeds while the bed is not yet burning.

The fuel fed (the balance loses it) collects in the bed of mass M [kg dry, nominal-energy
equivalent]: dM/dt = m_feed - m_burn. For ``delay_s`` after a start from an unlit bed
nothing burns; then the bed burns at m_burn = M / tau_b, also after a stop (without feed)
until it is empty (burn-out; below :data:`BED_EMPTY_KG` the bed goes out, the rest staying
in it for the next start). The bed holds m_feed tau_b in steady firing, so the heat release
follows the feed with the lag tau_b; at ignition it holds m_feed delay_s, which flares up
if the delay exceeds tau_b (equal at the lab values and under any strength: at constant feed
the heat is the feed delayed). The excess-air ratio is the controller's (Eq. 9 at the
feed rate); in the burn-out the fan holds the air of the last feed, so lambda rises as the
bed burns down and the gas leaves cooler (:func:`rig_emulator.model.boiler.burnout_gas`);
flue-gas temperature (Eq. 8), composition and losses (Eq. 3-6) follow the fuel that burns.
The fan runs (UA_amb,ON) while the controller fires or the bed burns; the start CO peak
decays from the ignition of the bed.

Numerics: the bed's linear equation is solved exactly over the lit part of the step.

Stages: ``flame_clock`` (a start resets the ignition timer; the flame's age is the bed's)
and ``fuel_bed``. The controller waits out tau_b (assumption, as for the body).
"""

from __future__ import annotations

import math

from numba import njit

from rig_emulator.bench.effects._spec import EffectSpec, ParamSpec
from rig_emulator.model import boiler as bm
from rig_emulator.model.layout import K_CO_START, K_LHV, S_SINCE_START, index_of

#: Bed content below which a bed without feed counts as burnt out [kg dry].
BED_EMPTY_KG = 1e-4

CONSTANTS = ("on", "delay_s", "burnout_time_constant_s")
C = index_of(CONSTANTS)
C_ON, C_DELAY, C_TAU = C["on"], C["delay_s"], C["burnout_time_constant_s"]

STATE = (
    "bed_kg",  # fuel in the bed [kg dry, nominal-energy equivalent]
    "bed_lit",  # 0/1: the bed burns
    "ignition_timer_s",  # time fed since the start while unlit
    "since_ignition_s",
    "lambda_feed_kg_h",  # feed rate that sets the fan (held in the burn-out)
)
S = index_of(STATE)
S_BED, S_LIT, S_TIMER = S["bed_kg"], S["bed_lit"], S["ignition_timer_s"]
S_SINCE_IGNITION, S_FAN_FEED = S["since_ignition_s"], S["lambda_feed_kg_h"]


@njit(cache=True, inline="always")
def flame_clock(c, s, fc, fs, row, started):
    """``flame_clock``: time since the flame lit [s] (the bed's ignition if on)."""
    if started:
        fs[row, S_TIMER] = 0.0
    return fs[row, S_SINCE_IGNITION] if fc[row, C_ON] > 0.5 else s[S_SINCE_START]


@njit(cache=True, inline="always")
def fuel_bed(c, s, fc, fs, row, firing, feed_kg_h, firing_kW, co_start, dt_s):
    """``fuel_bed``: fuel fed collects, burns once lit, burns out after a stop (module
    docstring); off, the model's bed (the feed burns at once)."""
    if fc[row, C_ON] < 0.5:
        return bm.model_fuel_bed(c, s, fc, fs, row, firing, feed_kg_h, firing_kW, co_start, dt_s)
    m0 = fs[row, S_BED]
    f_s = feed_kg_h / 3600.0  # [kg/s]
    t_unlit = 0.0  # part of the step before the bed lights [s]
    if fs[row, S_LIT] < 0.5:
        t_unlit = dt_s
        if firing:
            wait = max(fc[row, C_DELAY] - fs[row, S_TIMER], 0.0)
            if wait < dt_s:  # the bed lights within this step
                fs[row, S_LIT] = 1.0
                fs[row, S_SINCE_IGNITION] = -wait
                t_unlit = wait
                co_start = c[K_CO_START]
    if firing:
        fs[row, S_FAN_FEED] = feed_kg_h
        fs[row, S_TIMER] += dt_s
    m1 = m0 + f_s * t_unlit
    t_lit = dt_s - t_unlit
    if fs[row, S_LIT] > 0.5 and t_lit > 0.0:
        tau = fc[row, C_TAU]
        m1 = f_s * tau + (m1 - f_s * tau) * math.exp(-t_lit / tau) if tau > 0.0 else 0.0
        if not firing and m1 < BED_EMPTY_KG:
            # out: the rest stays in the bed, unlit, for the next start (burnt in this
            # step, it flared to 2 kW in the burn-out's last second: a physics review)
            fs[row, S_LIT] = 0.0
    fs[row, S_BED] = m1
    burn = (m0 + f_s * dt_s - m1) * 3600.0 / dt_s  # mean over the step [kg/h]
    fs[row, S_SINCE_IGNITION] += dt_s
    return burn, burn * c[K_LHV] / 3600.0, fs[row, S_FAN_FEED], co_start, burn > 0.0


EFFECT = EffectSpec(
    name="ignition_delay",
    params=(
        ParamSpec(
            "delay_s",
            "s",
            90.0,
            "linear",
            0.0,
            900.0,
            doc="time fed before an unlit bed ignites",
        ),
        ParamSpec(
            "burnout_time_constant_s",
            "s",
            90.0,
            "linear",
            0.0,
            900.0,
            doc="tau_b, the bed's burning time constant (its content over the burn rate)",
        ),
    ),
    strength_range=(0.5, 2.0),
    is_on=lambda v: v["delay_s"] > 0.0 or v["burnout_time_constant_s"] > 0.0,
    stages={"flame_clock": flame_clock, "fuel_bed": fuel_bed},
    constants=CONSTANTS,
    state=STATE,
    pack=lambda v, params: {
        "delay_s": v["delay_s"],
        "burnout_time_constant_s": v["burnout_time_constant_s"],
    },
    initial_state=lambda t_C: {"since_ignition_s": math.inf},
    horizon_s=lambda v: v["burnout_time_constant_s"],
)
