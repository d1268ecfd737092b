"""The five listed effects, each in two physically different forms, as parameter changes.

``strength`` in [0, 1] interpolates each form's parameters linearly between the weakest
noticeable and the strong-but-realistic end given in ``FORM_RANGES`` (documented in the
package docstring). The background plant has none of these mechanisms (or only far weaker
versions: metal-water time constant 40-100 s, flue sensor 20-45 s, ignition 1-2.5 min after
the preload, insulated exit pipe, HHV of the lot within +-1.2 %).
"""

from __future__ import annotations

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("layered_wall_conduction", "heavy_base_plate"),
    "outlet_sensor_pipe": ("bare_outlet_run", "stratified_horizontal_run"),
    "ignition_delay": ("oversized_start_charge", "drying_zone_holdup"),
    "flue_gas_lag": ("finned_economiser_mass", "lined_flue_connector"),
    "fuel_energy_bias": ("flyash_char_entrainment", "tar_slip_low_load"),
}

# form -> {parameter: (value at strength 0, value at strength 1)}
FORM_RANGES: dict[str, dict[str, tuple[float, float]]] = {
    "layered_wall_conduction": {"f_rad": (0.5, 0.8), "tau_link_s": (240.0, 840.0)},
    "heavy_base_plate": {"share": (0.4, 0.7), "f_pl": (0.3, 0.5), "tau_pl_s": (900.0, 2400.0)},
    "bare_outlet_run": {"length_m": (0.3, 0.9)},
    "stratified_horizontal_run": {"ua_bot_W_K": (0.15, 0.5), "k_mix": (0.02, 0.01)},
    "oversized_start_charge": {"t_preload_s": (120.0, 300.0), "t_wait_s": (180.0, 600.0)},
    "drying_zone_holdup": {"tau_dry_s": (120.0, 480.0)},
    "finned_economiser_mass": {"eps": (0.35, 0.6), "tau_s": (180.0, 720.0)},
    "lined_flue_connector": {"eps": (0.3, 0.6), "tau_s": (180.0, 900.0)},
    "flyash_char_entrainment": {"deficit": (0.07, 0.18)},
    "tar_slip_low_load": {"deficit": (0.04, 0.12)},
}


def validate(effect: str | None, form: str | None, strength: float) -> None:
    """Raise ValueError for an unknown effect/form pair or a strength outside [0, 1]."""
    if not (isinstance(strength, int | float) and 0.0 <= float(strength) <= 1.0):
        raise ValueError(f"strength must be a float in [0, 1], got {strength!r}")
    if effect is None:
        if form is not None:
            raise ValueError(f"form {form!r} given without an effect")
        return
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; expected one of {sorted(EFFECT_FORMS)}")
    if form not in EFFECT_FORMS[effect]:
        raise ValueError(
            f"unknown form {form!r} for effect {effect!r}; expected one of {EFFECT_FORMS[effect]}"
        )


def _lerp(form: str, key: str, s: float) -> float:
    a, b = FORM_RANGES[form][key]
    return a + (b - a) * s


def apply_effect(p: dict[str, float], effect: str | None, form: str | None, s: float) -> None:
    """Change the plant parameters ``p`` in place for ``form`` at strength ``s``."""
    validate(effect, form, s)
    if effect is None:
        return
    c_m_tot = p["c_m"]
    w_g = p["w_g_nom"]
    if form == "layered_wall_conduction":
        # firebox wall as two conduction nodes in series ahead of the water-side metal:
        # C_a dT_a/dt = f_rad Q_hx - G_ab (T_a - T_b)
        # C_b dT_b/dt = G_ab (T_a - T_b) - G_bm (T_b - T_m)
        tau = _lerp(form, "tau_link_s", s)
        p["c_a"] = p["c_b"] = 0.4 * c_m_tot
        p["c_m"] = 0.2 * c_m_tot
        p["g_ab"] = p["c_a"] / tau
        p["g_bm"] = p["c_b"] / tau
        p["f_rad"] = _lerp(form, "f_rad", s)
    elif form == "heavy_base_plate":
        # massive burner base plate takes f_pl of Q_hx by radiation, gives it to the water
        # through a weld seam: C_pl dT_pl/dt = f_pl Q_hx - G_pw (T_pl - T_w), G_pw = C_pl / tau
        share = _lerp(form, "share", s)
        p["c_pl"] = share * c_m_tot
        p["c_m"] = (1.0 - share) * c_m_tot
        p["f_pl"] = _lerp(form, "f_pl", s)
        p["g_pw"] = p["c_pl"] / _lerp(form, "tau_pl_s", s)
    elif form == "bare_outlet_run":
        # sensor at the end of L m of bare DN25 steel pipe with fittings, 4 plug-flow cells:
        # per metre 0.58 l water + 2.5 kg steel = 3.6 kJ/K; loss 1.5 W/(m K); wall conduction
        length = _lerp(form, "length_m", s)
        dx = length / 4.0
        p["n_pipe"] = 4.0
        p["c_cell"] = 3.6 * dx
        p["ua_cell"] = 1.5e-3 * dx
        p["g_ax"] = 50.0 * 2.4e-4 / dx / 1000.0
    elif form == "stratified_horizontal_run":
        # horizontal run, sensor boss at the pipe bottom: the bottom layer mixes with the core
        # by turbulence (G = G0 + k W_w) and loses heat through the bare boss (UA_bot)
        p["n_pipe"] = 3.0
        p["c_cell"] = 0.5
        p["strat"] = 1.0
        p["c_bot"] = 0.15
        p["ua_bot"] = _lerp(form, "ua_bot_W_K", s) / 1000.0
        p["g_mix0"] = 0.03e-3
        p["k_mix"] = _lerp(form, "k_mix", s)
    elif form == "oversized_start_charge":
        # controller pre-loads minutes of fuel; the igniter needs longer to light the big pile
        p["t_preload"] = _lerp(form, "t_preload_s", s)
        p["t_ign_need"] = p["t_preload"] + _lerp(form, "t_wait_s", s)
    elif form == "drying_zone_holdup":
        # fed pellets first sit in a drying/pyrolysis zone: dm_hold/dt = feed - m_hold/tau_dry
        p["tau_dry"] = _lerp(form, "tau_dry_s", s)
    elif form == "finned_economiser_mass":
        # finned economiser after the tube bank:
        # C_e dT_e/dt = eps W_g (T_g1 - T_e) - G_ew (T_e - T_w)
        eps = _lerp(form, "eps", s)
        p["eps_e"] = eps
        p["g_ew"] = eps * w_g
        p["c_e"] = _lerp(form, "tau_s", s) * (eps * w_g + p["g_ew"])
    elif form == "lined_flue_connector":
        # ceramic-lined flue connector before the probe, jacket loss UA_l to the room
        eps = _lerp(form, "eps", s)
        p["eps_l"] = eps
        p["ua_l"] = 0.3 * eps * w_g
        p["c_l"] = _lerp(form, "tau_s", s) * (eps * w_g + p["ua_l"])
    elif form == "flyash_char_entrainment":
        # char fines carried out by the fan: deficit = d (P/P_full)^1.5 (entrainment ~ velocity)
        p["def_mode"] = 1.0
        p["def_a"] = _lerp(form, "deficit", s)
    elif form == "tar_slip_low_load":
        # unburnt tars/OGC from a cool bed: deficit = d (0.4 + 0.6 P_full / P)
        p["def_mode"] = 2.0
        p["def_a"] = _lerp(form, "deficit", s)
