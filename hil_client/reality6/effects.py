"""The five listed effects (CONTRACT section 4), each in physically distinct forms.

Every form takes a strength s in [0, 1]: 0 leaves the plant unchanged, about 0.06 is barely
detectable, 1 is strong.  A form sets kernel parameters (kernel.py) or instrument settings
(instruments.py):

body_heat_diffusion (Eq. 2 with a metal node of its own temperature)
* firebox_steel_node: all of Q_hx enters a steel node (s * 34 % of the body's capacity,
  time constant 30 + 450 s * s) that passes it to the water; the water lags the fire.
* dry_back_plate: a non-water-backed plate beside the firebox takes s * 35 % of Q_hx into
  s * 25 % of the capacity and passes it on only through its welded edges (time constant
  60 + 1200 s * s), losing a little to the room meanwhile: a slow parallel heat path.

outlet_sensor_pipe (the forward sensor down the exit pipe)
* exit_elbow_plug_segment: plug flow through 0.1-0.25 + 2.2 s kg of pipe water: delay = pipe
  mass / flow, and the parcel loses heat to the room with time constant 1500 s / s while it
  sits there; with the pump off the stagnant water cools towards the room.
* dead_leg_tee_pocket: the sensor sits in a tee branch, coupled to the main flow with time
  constant 60 s * s / (flow / flow_nom)^0.5 and cooled by the room with 3600 s / s: a lag that
  grows as the flow falls, a steady drop, and fast cooling once circulation stops.

ignition_delay (fuel fed before the bed releases heat; the bed burns out after a stop)
* aged_igniter_element: a weak igniter lights the bed s * 540 s later (cold) or s * 300 s later
  (hot bed) than normal, while the controller keeps adding top-up charges: fuel fed, no heat,
  then a flash as the pile lights.
* deep_glow_bed: a deep retort bed, burn-off time + s * 600 s: the heat builds slowly after
  each start and load step, and a large glowing bed burns out after each stop.

flue_gas_lag (heat stored between flame and flue-gas sensor)
* firebrick_lining_store: a refractory lining, constant extra time constant s * 900 s and
  s * 35 kJ/K stored heat.
* low_draught_tube_bank: a heavy tube bank whose gas-side film weakens as the gas flow falls:
  extra time constant s * 300 s * (gas_nom / gas)^0.8 (1-6 x), s * 25 kJ/K.

fuel_energy_bias (energy per kg differs from the documented HHV)
* hopper_humidity_uptake: the pellets took up s * 7 %-points of moisture in the hopper.
* kiln_dried_hardwood_lot: another lot, HHV_dry + 5 % * s, moisture - 60 % * s (less mass).
* grate_siftings_loss: s * 8 % of the fed mass falls through the grate unburnt.
"""

from __future__ import annotations

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("firebox_steel_node", "dry_back_plate"),
    "outlet_sensor_pipe": ("exit_elbow_plug_segment", "dead_leg_tee_pocket"),
    "ignition_delay": ("aged_igniter_element", "deep_glow_bed"),
    "flue_gas_lag": ("firebrick_lining_store", "low_draught_tube_bank"),
    "fuel_energy_bias": (
        "hopper_humidity_uptake",
        "kiln_dried_hardwood_lot",
        "grate_siftings_loss",
    ),
}

# the signal each effect changes first (used by the tests)
EFFECT_SIGNALS: dict[str, str] = {
    "body_heat_diffusion": "boiler_water_temp_C",
    "outlet_sensor_pipe": "water_out_temp_C",
    "ignition_delay": "balance_mass_kg",
    "flue_gas_lag": "flue_gas_temp_C",
    "fuel_energy_bias": "balance_mass_kg",
}


def resolve(effect: str | None, form: str | None, strength: float) -> tuple[str | None, str | None]:
    """Check and normalise (effect, form); raises ValueError on bad names or strength."""
    try:
        s = float(strength)
    except (TypeError, ValueError):
        raise ValueError(f"strength must be a number in [0, 1], got {strength!r}") from None
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"strength must lie in [0, 1], got {strength!r}")
    if effect is None or effect == "none":
        if form not in (None, "none"):
            raise ValueError(f"form {form!r} given without an effect")
        return None, None
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; expected one of {sorted(EFFECT_FORMS)}")
    forms = EFFECT_FORMS[effect]
    if form is None:
        return effect, forms[0]
    if form not in forms:
        raise ValueError(f"unknown form {form!r} of effect {effect!r}; expected one of {forms}")
    return effect, form


def effect_settings(
    effect: str | None, form: str | None, strength: float, c_total_kJ_K: float
) -> dict[str, float]:
    """Named settings of one (effect, form, strength); empty for no effect or s = 0."""
    s = float(strength)
    if effect is None or s <= 0.0:
        return {}
    if form == "firebox_steel_node":
        c_m = s * 0.34 * c_total_kJ_K
        return {"body_mode": 1.0, "c_metal": c_m, "ua_metal": c_m / (30.0 + 450.0 * s)}
    if form == "dry_back_plate":
        c_p = s * 0.25 * c_total_kJ_K
        return {
            "body_mode": 2.0,
            "c_metal": c_p,
            "ua_metal": c_p / (60.0 + 1200.0 * s),
            "plate_frac": 0.35 * s,
            "ua_plate_room": 0.0015 * s,
        }
    if form == "exit_elbow_plug_segment":
        return {"pipe_extra_kg": 2.2 * s, "pipe_tau_loss_s": 1500.0 / s}
    if form == "dead_leg_tee_pocket":
        return {"dead_leg_tau_flow_s": 60.0 * s, "dead_leg_tau_loss_s": 3600.0 / s}
    if form == "aged_igniter_element":
        return {"light_extra_cold_s": 540.0 * s, "light_extra_hot_s": 300.0 * s}
    if form == "deep_glow_bed":
        return {"bed_extra_tau_s": 600.0 * s}
    if form == "firebrick_lining_store":
        return {"fg_mode": 1.0, "fg_tau_eff_s": 900.0 * s, "fg_c_eff": 35.0 * s}
    if form == "low_draught_tube_bank":
        return {"fg_mode": 2.0, "fg_tau_eff_s": 300.0 * s, "fg_c_eff": 25.0 * s}
    if form == "hopper_humidity_uptake":
        return {"moisture_add": 0.07 * s}
    if form == "kiln_dried_hardwood_lot":
        return {"hhv_factor": 1.0 + 0.05 * s, "moisture_factor": 1.0 - 0.6 * s}
    if form == "grate_siftings_loss":
        return {"sift_frac": 0.08 * s}
    raise ValueError(f"unknown form {form!r}")  # pragma: no cover (resolve checks first)
