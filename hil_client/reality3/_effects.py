"""The unmodelled effects, two functional forms each, and their strength mapping.

``strength`` s in [0, 1] maps linearly onto the physical parameters below (s = 0 barely
detectable above the background, s = 1 strong). ``size`` is p_nom / 12 kW, so masses and heat
capacities scale with the boiler. Every form is physical: it adds nodes or mass to the plant,
and the plant's energy and mass balances include them.
"""

from __future__ import annotations

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("radiant_hot_steel", "chamber_jacket_pocket"),
    "outlet_sensor_pipe": ("thermowell_bracket", "laminar_pipe_transit"),
    "ignition_delay": ("failed_first_ignition", "critical_pile_mass"),
    "flue_gas_lag": ("turbulator_store", "air_recuperator"),
    "fuel_energy_bias": ("ash_rich_blend", "load_unburnt_carbon"),
}

#: Parameter ranges at s = 0 and s = 1 (linear in between), per effect form.
FORM_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    # burner pot / firebox steel heated by flame radiation, contact resistance to the water
    "radiant_hot_steel": {
        "steel_share": (0.20, 0.70),  # share of the exchanger steel capacity that is hot steel
        "tau_contact_s": (180.0, 900.0),  # C_hot / G_contact
        "radiant_share": (0.10, 0.30),  # share of the available heat radiated at nominal load
    },
    # poorly circulated water jacket around the combustion chamber: it takes a share of the
    # gas-side heat through the chamber wall and passes it to the main water only by a buoyant
    # plume (exchange ~ dT^(1/3)) and flow-driven mixing, so it runs hotter and stores heat
    "chamber_jacket_pocket": {
        "pocket_share": (0.15, 0.45),  # share of the water capacity
        "surface_share": (0.10, 0.30),  # share of the gas-side surface
        "dt_nom_K": (8.0, 30.0),  # pocket excess over the main water at nominal load
        "flow_mixing": (1.0, 1.0),  # exchange factor 1 + k m/m_nom
        "conduction_share": (0.05, 0.05),  # exchange without buoyancy, relative
    },
    # forward sensor in a thermowell with a conducting bracket; stagnant pipe water cools
    "thermowell_bracket": {
        "pipe_volume_l": (0.4, 0.4),
        "tau_pipe_s": (900.0, 900.0),  # stagnant pipe water -> boiler water and room
        "stagnant_error": (0.04, 0.50),  # share of T_boiler - T_room lost by stagnant pipe
        "tau_well_nom_s": (8.0, 33.0),  # thermowell at nominal flow
        "bracket_error_nom_K": (0.10, 0.60),  # stem-conduction error at 45 K above the room
        "natural_share": (0.08, 0.08),  # film coefficient at zero flow / at nominal flow
    },
    # forward sensor at the end of a longer exit pipe; at the low Reynolds numbers of part
    # load the water arrives with the laminar (Poiseuille) residence-time distribution, in
    # cumulative-volume coordinates; each parcel relaxes, for its age, towards a temperature
    # between the room's and the boiler's (conduction along the pipe from the boiler)
    "laminar_pipe_transit": {
        "pipe_volume_l": (0.3, 1.5),
        "tau_loss_s": (7200.0, 1200.0),  # parcel relaxation time constant
        "stagnant_error": (0.04, 0.50),  # share of T_boiler - T_room a parcel finally loses
    },
    # first ignition attempt never catches: timeout, purge, second charge, pile burns off
    "failed_first_ignition": {
        "t_fail_s": (180.0, 600.0),
        "t_purge_s": (60.0, 120.0),
        "charge_factor": (1.0, 2.0),  # charge of each attempt / background charge
    },
    # bed catches only above a critical mass (controller tops up); deeper standing bed
    "critical_pile_mass": {
        "extra_mass_kg": (0.02, 0.22),  # critical mass above the charge (x size)
        "extra_tau_bed_s": (30.0, 180.0),  # longer bed burn-out time constant
        "topup_factor": (0.30, 0.30),  # top-up feed / ignition feed while waiting
    },
    # hot spiral turbulators in the exchanger tubes (gas -> spirals -> tube wall)
    "turbulator_store": {
        "area_share": (0.20, 0.20),
        "flue_share": (0.25, 0.60),  # share of T_fg - T_steel due to the spirals (nominal)
        "tau_s": (180.0, 1380.0),  # spirals' time constant at nominal load
    },
    # combustion-air recuperator after the exchanger with a heat-storing wall
    "air_recuperator": {
        "gas_effectiveness": (0.25, 0.60),
        "air_effectiveness": (0.60, 0.60),
        "tau_s": (180.0, 1380.0),  # wall time constant at nominal load
    },
    # bark-containing blend: more ash, carbon shifted to oxygen (lower HHV)
    "ash_rich_blend": {
        "extra_ash": (0.008, 0.060),  # mass fraction of dry fuel
        "carbon_to_oxygen": (0.002, 0.015),  # of the organic matter
    },
    # char carried over into the ash, growing with the burn rate
    "load_unburnt_carbon": {
        "energy_share_nom": (0.012, 0.080),  # fuel energy left in char at nominal burn rate
        "exponent": (1.5, 1.5),
    },
}


def form_params(form: str, strength: float) -> dict[str, float]:
    """Physical parameters of ``form`` at ``strength`` (linear between the two ends)."""
    s = min(max(float(strength), 0.0), 1.0)
    return {k: lo + (hi - lo) * s for k, (lo, hi) in FORM_RANGES[form].items()}


def check_effect(effect: str | None, form: str | None) -> None:
    """Raise ValueError for an unknown effect or form."""
    if effect is None or effect == "none":
        return
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; known: {sorted(EFFECT_FORMS)}")
    if form not in EFFECT_FORMS[effect]:
        raise ValueError(f"unknown form {form!r} of {effect}; known: {EFFECT_FORMS[effect]}")
