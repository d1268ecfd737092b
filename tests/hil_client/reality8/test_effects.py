"""Each form moves its own signal with strength, and clearly beyond the background."""

from __future__ import annotations

import numpy as np
import pytest

from hil_client.reality8 import EFFECT_FORMS

from .conftest import plant

TAKEN = set(
    [
        "aged_igniter_element",
        "air_recuperator",
        "ash_crust_grate",
        "ash_rich_blend",
        "bark_contaminated_lot",
        "bed_ignition_temperature",
        "bed_ramp",
        "bimetal_bypass",
        "burner_flange_path",
        "burner_pot_ring_store",
        "calcite_additive",
        "cast_door_radiant_share",
        "cast_iron_section",
        "ceramic_afterburner",
        "ceramic_foam_insert",
        "chamber_jacket_pocket",
        "char_shrinking_core",
        "clamp_on_sensor",
        "clogged_igniter",
        "cold_retort",
        "critical_pile_mass",
        "dead_leg_tee_pocket",
        "dead_time",
        "dead_time_wall",
        "deep_glow_bed",
        "delayed_wall",
        "distributed_wall",
        "dry_back_plate",
        "exit_elbow_plug_segment",
        "failed_first_ignition",
        "fan_cooled_igniter",
        "fines_unburnt",
        "firebox_steel_node",
        "firebrick_lining_store",
        "first_order",
        "flow_dependent_film",
        "flue_collector_mass",
        "gate_valve_heat_sink",
        "grate_siftings_loss",
        "hhv_bias",
        "hopper_humidity_uptake",
        "kiln_dried_hardwood_lot",
        "laminar_pipe_transit",
        "limescale_layer",
        "load_unburnt_carbon",
        "long_riser",
        "low_draught_tube_bank",
        "mixed_volume",
        "moisture",
        "plug_flow",
        "pocket_contact_fin_loss",
        "radiant_hot_steel",
        "random_start_delay",
        "refractory_radiation",
        "regenerative_refractory",
        "resin_softwood",
        "second_order",
        "second_order_store",
        "smoulder_then_flash",
        "soot_fouled_hx",
        "stem_conduction",
        "tank_cascade",
        "thermosiphon_exchange",
        "thermowell_bracket",
        "torrefied_blend",
        "turbulator_store",
        "two_lump_split",
        "uncooled_deflector_plate",
        "vegetable_oil_binder",
        "wet_batch",
        "worn_auger_co",
    ]
)


def test_effect_forms_are_new_and_complete() -> None:
    assert set(EFFECT_FORMS) == {
        "body_heat_diffusion", "outlet_sensor_pipe", "ignition_delay", "flue_gas_lag",
        "fuel_energy_bias",
    }  # fmt: skip
    forms = [f for fs in EFFECT_FORMS.values() for f in fs]
    assert all(len(fs) == 2 for fs in EFFECT_FORMS.values())
    assert len(set(forms)) == 10
    assert not set(forms) & TAKEN
    assert all(f == f.lower() and f.replace("_", "").isalpha() for f in forms)


def _window(s, a, b):
    return (s["time"] >= a) & (s["time"] < b)


def _water_lag(s, ev):  # start-up: boiler water 8 min after the first heat release
    k = int(ev[0])
    fire = k + np.nonzero(s["q_fuel"][k:] > 1.0)[0][0]
    return s["t_w"][fire + 480]


def _pipe_drop(s, ev):  # cooling 2: forward sensor node below the boiler water, 2-4 h in
    sel = _window(s, ev[3] + 7200, ev[3] + 14400)
    return (s["t_w"] - s["t_out_node"])[sel].mean()


def _first_heat_delay(s, ev):  # first fuel fed to 80 % of full firing, at t0
    k = int(ev[0])
    fed = np.nonzero(s["m_fed"][k:] > 0)[0][0]
    heat = np.nonzero(s["q_fuel"][k:] > 0.8 * s["q_fuel"].max())[0][0]
    return float(heat - fed)


def _fg_lag(s, ev):  # flue gas after 10 min of firing (warming of the stores)
    k = int(ev[0])
    fire = k + np.nonzero(s["q_fuel"][k:] > 1.0)[0][0]
    return -s["t_fg"][fire + 600]


def _fuel_per_heat(s, ev):  # kg burnt per MJ to water over the test phase
    sel = _window(s, ev[1], ev[2])
    return s["m_burn"][sel].sum() / s["q_water"][sel].sum() * 1000.0


SIGNAL = {
    "body_heat_diffusion": (_water_lag, -1),  # the water lags: lower temperature
    "outlet_sensor_pipe": (_pipe_drop, +1),
    "ignition_delay": (_first_heat_delay, +1),
    "flue_gas_lag": (_fg_lag, +1),
    "fuel_energy_bias": (_fuel_per_heat, +1),
}
# (name, test) per effect: load cycle where part load matters
RUN = {"fuel_energy_bias": ("6kw", "load_cycle")}
# minimal move at strength 0 vs background and 1 vs 0, in the signal's unit (K, s, kg/MJ)
MARGIN = {
    "body_heat_diffusion": 1.0,  # K: background metal lag is 40-100 s
    "outlet_sensor_pipe": 1.0,  # K
    "ignition_delay": 60.0,  # s: background ignition 30-90 s after a 30-60 s preload
    "flue_gas_lag": 3.0,  # K: Pt100 resolution 0.1 K, class-B tolerance ~1 K
    "fuel_energy_bias": 0.002,  # kg/MJ, ~3 % of ~0.065 kg/MJ (background HHV +-1.2 %)
}


@pytest.mark.parametrize(("effect", "form"), [(e, f) for e, fs in EFFECT_FORMS.items() for f in fs])
def test_strength_moves_own_signal_beyond_background(effect, form) -> None:
    name, test = RUN.get(effect, ("12kw", "stationary"))
    fn, sign = SIGNAL[effect]
    s_bg, ev_bg, _ = plant(name, test)
    s0, ev0, _ = plant(name, test, effect, form, 0.0)
    s1, ev1, _ = plant(name, test, effect, form, 1.0)
    v_bg, v0, v1 = (sign * fn(s, ev) for s, ev in ((s_bg, ev_bg), (s0, ev0), (s1, ev1)))
    assert v0 - v_bg > MARGIN[effect], (v_bg, v0, v1)  # weakest form already noticeable
    assert v1 - v0 > MARGIN[effect], (v_bg, v0, v1)  # stronger with strength


def test_no_effect_is_independent_of_strength() -> None:
    a, _, _ = plant("6kw", "load_cycle", None, None, 0.0)
    b, _, _ = plant("6kw", "load_cycle", None, None, 1.0)
    for k in a:
        assert np.array_equal(a[k], b[k], equal_nan=True), k
