"""The listed effects, each in two functional forms of its own (:data:`EFFECT_FORMS`), and
their parameters from a strength in [0, 1] (weak to strong within realistic ranges).

- ``body_heat_diffusion``: ``refractory_radiation`` (a refractory lining takes the radiant
  share of the heat and radiates it, T^4, to the firebox steel) and ``delayed_wall`` (the heat
  reaches the steel after a transit delay through a 5-segment conducting wall);
- ``outlet_sensor_pipe``: ``tank_cascade`` (6 mixed tanks holding water and pipe metal, losing
  heat to the room and fed back by conduction from the boiler) and ``dead_time_wall`` (plug
  flow, 40 cells, through a pipe wall of its own capacity with the sensor in a well that
  reads partly the wall);
- ``ignition_delay``: ``bed_ignition_temperature`` (the igniter must heat the fed bed to its
  ignition temperature; more fuel on the grate, longer heating; the bed then smoulders) and
  ``random_start_delay`` (a gamma-distributed delay per start);
- ``flue_gas_lag``: ``second_order_store`` (two refractory stores in series the gas leaves at
  their temperature) and ``regenerative_refractory`` (one store with a partial exchange whose
  NTU and time constant grow as the gas flow falls, coupled to the steel);
- ``fuel_energy_bias``: ``wet_batch`` (pellets with 9-15 % moisture as received: the auger
  delivers volume, so less dry fuel per pulse and more latent loss) and ``fines_unburnt``
  (2.5-7 % of the fed dry fuel leaves unburnt as fines and carbon in the ash).
"""

from __future__ import annotations

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("refractory_radiation", "delayed_wall"),
    "outlet_sensor_pipe": ("tank_cascade", "dead_time_wall"),
    "ignition_delay": ("bed_ignition_temperature", "random_start_delay"),
    "flue_gas_lag": ("second_order_store", "regenerative_refractory"),
    "fuel_energy_bias": ("wet_batch", "fines_unburnt"),
}


def effect_settings(effect: str | None, form: str | None, strength: float) -> dict:
    """Named settings of ``effect`` in ``form`` at ``strength`` (empty for no effect)."""
    if effect is None:
        return {}
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; known: {sorted(EFFECT_FORMS)}")
    forms = EFFECT_FORMS[effect]
    if form is None:
        form = forms[0]
    if form not in forms:
        raise ValueError(f"effect {effect!r} has forms {forms}, not {form!r}")
    if not 0.0 <= strength <= 1.0:
        raise ValueError(f"strength must be in [0, 1], got {strength}")
    s = float(strength)
    if form == "refractory_radiation":
        # 5-25 kJ/K of chamotte (5-28 kg), taking 30-50 % of the heat as radiation
        return {"body_form": 1, "c_ref_kJ_K": 5.0 + 20.0 * s, "ref_frac": 0.3 + 0.2 * s}
    if form == "delayed_wall":
        return {
            "body_form": 2,
            "wall_delay_s": 20.0 + 70.0 * s,
            "wall_c_kJ_K": 12.0 + 28.0 * s,
            "wall_tau_s": 150.0 + 250.0 * s,
        }
    if form == "tank_cascade":
        # 30 cm to 1.5 m of DN25 pipe with fittings: 0.3-1.5 L, 0.6-2.5 W/K to the room
        return {
            "pipe_form": 1,
            "pipe_volume_L": 0.3 + 1.2 * s,
            "pipe_ua_W_K": 0.6 + 1.9 * s,
            "pipe_metal_kJ_K": 1.0 + 1.5 * s,
        }
    if form == "dead_time_wall":
        return {
            "pipe_form": 2,
            "pipe_volume_L": 0.3 + 1.2 * s,
            "pipe_ua_W_K": 0.6 + 1.9 * s,
            "pipe_metal_kJ_K": 0.5 + 2.0 * s,
        }
    if form == "bed_ignition_temperature":
        return {"ign_form": 1, "extra_delay_s": 120.0 + 480.0 * s, "smoulder": 1.5 + 1.5 * s}
    if form == "random_start_delay":
        return {"ign_form": 2, "extra_delay_s": 120.0 + 480.0 * s, "smoulder": 1.3 + 1.0 * s}
    if form == "second_order_store":
        return {"fg_form": 1, "fg_tau_s": 45.0 + 180.0 * s}
    if form == "regenerative_refractory":
        return {"fg_form": 2, "fg_tau_s": 90.0 + 360.0 * s}
    if form == "wet_batch":
        return {"moisture": 0.09 + 0.06 * s}
    return {"fines_frac": 0.025 + 0.045 * s}  # fines_unburnt
