"""The listed effects (CONTRACT section 4), each in at least two functional forms that differ
from the diagnosis's own candidates, and the strength scale of each.

``strength`` in [0, 1] maps log-uniformly (or linearly where stated) onto a realistic range
whose weak end is still physically noticeable:

body_heat_diffusion (heat reaches the water through metal with its own temperature)
    ``distributed_wall``: the body as 4 metal layers in series (fire side first), wall time
    constant C_metal / G_series from 60 s (weak: about 6 K metal-to-water at full firing of
    the 12 kW boiler) to 400 s (strong); ``two_lump_split``: 40 % of the exchanger's heat
    enters a firebox lump (60 % of the metal) that passes it to the water through a
    natural-convection conductance G ~ dT^(1/3), same time-constant range; the rest enters a
    tightly coupled exchanger lump.
outlet_sensor_pipe (forward sensor down the exit pipe)
    ``plug_flow``: plug flow through 0.3-0.8 kg of pipe water (a dead time mass / flow)
    with each slice cooling to the room, time constant 12000 s (insulated) to 1200 s (bare
    DN25 steel); ``mixed_volume``: a mixed volume with a pipe-wall node losing heat by natural
    convection (h ~ dT^(1/4)) and the sensor in a thermowell (20-40 s), same ranges.
ignition_delay (fuel fed before the bed releases heat; burn-out after a stop)
    ``dead_time``: the bed lights 90 s (weak) to 480 s (strong) after the first feed, and
    burns with a time constant of a third of that (the accumulated bed burns out);
    ``bed_ramp``: the bed's burning rate ramps from 0 to full over 120-600 s after the first
    feed, burning time constant the background's plus a quarter of the ramp
    (both weakest forms hold back at least 60 s more of feed than the background's start).
flue_gas_lag (exchanger and refractory store heat)
    a storage node (``first_order``) or two in series (``second_order``) after the
    exchanger, time constant at nominal gas flow 120 s (weak) to 900 s (strong), growing as
    the gas flow falls (C / (W (1 - e^-NTU)), NTU = 2), losing 3 % of W to the room.
fuel_energy_bias (energy per kg differs from the nominal HHV)
    ``hhv_bias``: HHV (dry) off by 4 % (weak, above a lab analysis' 2-3 % uncertainty) to
    15 % (strong), sign drawn from the seed; ``moisture``: pellets as received with 10 %
    (weak) to 20 % (strong) moisture instead of the analysed value, so more mass per kWh
    and more latent heat in the flue gas.
"""

from __future__ import annotations

import math

import numpy as np

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("distributed_wall", "two_lump_split"),
    "outlet_sensor_pipe": ("plug_flow", "mixed_volume"),
    "ignition_delay": ("dead_time", "bed_ramp"),
    "flue_gas_lag": ("first_order", "second_order"),
    "fuel_energy_bias": ("hhv_bias", "moisture"),
}

#: (weak, strong) ends of each effect's strength, for the docs and the meta file.
STRENGTH_RANGES: dict[str, tuple[float, float, str]] = {
    "body_heat_diffusion": (60.0, 400.0, "wall time constant [s]"),
    "outlet_sensor_pipe": (12000.0, 1200.0, "pipe loss time constant [s]"),
    "ignition_delay": (90.0, 480.0, "dead time [s] (ramp: 120-600 s)"),
    "flue_gas_lag": (120.0, 900.0, "storage time constant at nominal gas flow [s]"),
    "fuel_energy_bias": (0.04, 0.15, "relative HHV bias (moisture: 0.10-0.20 as received)"),
}


def _logmap(lo: float, hi: float, s: float) -> float:
    return lo * (hi / lo) ** s


def no_effect(background: dict[str, float]) -> dict[str, float]:
    """Kernel values of the effect fields when no listed effect is present."""
    return {
        "body_form": 0.0,
        "tau_body": 1.0,
        "split_cap": 0.6,
        "split_share": 0.4,
        "pipe_form": 0.0,
        "pipe_kg": 0.3,
        "pipe_tau_loss_s": 1e9,
        "well_tau_s": 0.0,
        "flue_form": 0.0,
        "flue_cap": 1.0,
        "flue_ntu": 2.0,
        "flue_ua_kW_K": 0.0,
        "ign_form": 0.0,
        "light_delay_s": background["light_delay_s"],
        "ign_ramp_s": 1.0,
        "bed_tau_s": background["bed_tau_s"],
    }


def effect_fields(
    effect: str | None,
    form: str | None,
    strength: float,
    background: dict[str, float],
    w_nom_kW_K: float,
    fuel_moisture: float,
    seed: int,
) -> tuple[dict[str, float], dict[str, float]]:
    """(kernel values of the effect fields, the effect's physical parameters for the meta).

    Raises ValueError naming an unknown effect or form, or a strength outside [0, 1]."""
    fields = no_effect(background)
    if effect is None:
        return fields, {}
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; known: {sorted(EFFECT_FORMS)}")
    if form not in EFFECT_FORMS[effect]:
        raise ValueError(f"unknown form {form!r} of {effect}; known: {EFFECT_FORMS[effect]}")
    if not 0.0 <= strength <= 1.0:
        raise ValueError(f"strength must lie in [0, 1], not {strength}")
    s = float(strength)
    info: dict[str, float] = {}
    if effect == "body_heat_diffusion":
        tau = _logmap(60.0, 400.0, s)
        fields["tau_body"] = tau
        fields["body_form"] = 1.0 if form == "distributed_wall" else 2.0
        info["wall_time_constant_s"] = tau
    elif effect == "outlet_sensor_pipe":
        tau = _logmap(12000.0, 1200.0, s)
        fields["pipe_tau_loss_s"] = tau
        fields["pipe_kg"] = 0.3 + 0.5 * s
        if form == "plug_flow":
            fields["pipe_form"] = 1.0
        else:
            fields["pipe_form"] = 2.0
            fields["well_tau_s"] = 20.0 + 20.0 * s
        info |= {"pipe_loss_time_constant_s": tau, "pipe_water_kg": fields["pipe_kg"]}
    elif effect == "ignition_delay":
        if form == "dead_time":
            d = _logmap(90.0, 480.0, s)
            fields["light_delay_s"] = d
            fields["bed_tau_s"] = max(background["bed_tau_s"], d / 3.0)
            info["dead_time_s"] = d
        else:
            ramp = _logmap(120.0, 600.0, s)
            fields["ign_form"] = 2.0
            fields["ign_ramp_s"] = ramp
            fields["bed_tau_s"] = background["bed_tau_s"] + ramp / 4.0
            info["ramp_s"] = ramp
        info["bed_time_constant_s"] = fields["bed_tau_s"]
    elif effect == "flue_gas_lag":
        tau = _logmap(120.0, 900.0, s)
        ntu = 2.0
        fields["flue_form"] = 1.0 if form == "first_order" else 2.0
        fields["flue_ntu"] = ntu
        fields["flue_cap"] = tau * w_nom_kW_K * (1.0 - math.exp(-ntu))
        fields["flue_ua_kW_K"] = 0.03 * w_nom_kW_K
        info["storage_time_constant_nominal_s"] = tau
    else:  # fuel_energy_bias
        if form == "hhv_bias":
            sign = 1.0 if np.random.default_rng([seed, 17]).random() < 0.5 else -1.0
            info["hhv_bias"] = sign * (0.04 + 0.11 * s)
        else:
            info["moisture_ar"] = max(0.10 + 0.10 * s, fuel_moisture + 0.04)
    return fields, info
