"""Effect catalogue and the per-case background quirks of the reality7 plant.

Effects (CONTRACT section 4) are structural features a one-node Type 869 model (paper Eq. 1-2)
lacks. Each has two physically different forms here; ``strength`` in [0, 1] scales a form
continuously from "absent" (0) to "strong" (1).

The background is what makes this plant a real boiler rather than Type 869 plus one effect:
its own controller, start-up sequence, exchanger law, bench and instruments, with their
parameters drawn per case.
"""

from __future__ import annotations

import numpy as np

#: effect -> forms. Numbering: the index in the tuple is the form code of the kernel.
EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    # a cast ash/firebox door taking a radiant share of the flame heat and giving it to the
    # water through its water-cooled rim; a heavy burner-pot ring radiating (T^4) to the body
    "body_heat_diffusion": ("cast_door_radiant_share", "burner_pot_ring_store"),
    # the forward sensor in a brass immersion pocket with a fin loss to the cold stub and a
    # flow-dependent film; an uninsulated brass gate valve and union in the 30 cm run
    "outlet_sensor_pipe": ("pocket_contact_fin_loss", "gate_valve_heat_sink"),
    # the ignition air is blown too fast past the igniter so the pellets heat slowly; the bed
    # catches but smoulders before the flame spreads, and burns out slowly as char
    "ignition_delay": ("fan_cooled_igniter", "smoulder_then_flash"),
    # a ceramic-foam flame insert ahead of the tubes; an uncooled steel deflector plate in the
    # turning chamber after the tubes
    "flue_gas_lag": ("ceramic_foam_insert", "uncooled_deflector_plate"),
    # a lot with bark in it (lower HHV, more ash and water); pellets with a vegetable-oil
    # binder (higher HHV, more hydrogen)
    "fuel_energy_bias": ("bark_contaminated_lot", "vegetable_oil_binder"),
}

#: kernel effect codes (0 = none)
EFFECT_CODES: dict[str, int] = {name: i + 1 for i, name in enumerate(EFFECT_FORMS)}


def check_effect(effect: str | None, form: str | None, strength: float) -> tuple[int, int, float]:
    """Validate an effect request; return (effect code, form code, strength).

    Raises ValueError with the allowed names when the request is not understood.
    """
    try:
        s = float(strength)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"strength must be a number in [0, 1], got {strength!r}") from exc
    if not np.isfinite(s) or s < 0.0 or s > 1.0:
        raise ValueError(f"strength must be in [0, 1], got {strength!r}")
    if effect is None or effect == "none":
        if form not in (None, "none", ""):
            raise ValueError(f"form {form!r} given without an effect")
        return 0, 0, 0.0
    if effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}; expected one of {[*EFFECT_FORMS, 'none']}")
    forms = EFFECT_FORMS[effect]
    if form is None:
        raise ValueError(f"effect {effect!r} needs a form, one of {list(forms)}")
    if form not in forms:
        raise ValueError(f"unknown form {form!r} of effect {effect!r}; expected one of {forms}")
    return EFFECT_CODES[effect], forms.index(form), s


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def draw_background(rng: np.random.Generator, boiler: dict) -> dict[str, float]:
    """Draw one case's real-boiler quirks (plain floats, deterministic in ``rng``).

    Ranges are chosen so that the plant differs from the paper's plain Type 869 model by about
    the paper's Table 4 (test phase: water temperature RMSD 1-3 K, heat to water 0.3-0.7 kW).
    """
    p_nom = float(boiler["p_nom_kW"])
    b: dict[str, float] = {}
    # --- body (paper Eq. 2: C dT/dt; here two nodes: steel around the fire, water) -------
    b["cap_water_scale"] = _u(rng, 0.92, 1.08)  # water content of the jacket vs Volwat
    b["cap_steel_scale"] = _u(rng, 0.85, 1.20)  # steel vs documented Ctherm
    b["ua_sw_kW_K"] = p_nom / _u(rng, 9.0, 16.0)  # steel->water, 9-16 K at nominal load
    b["ua_env_scale"] = _u(rng, 0.85, 1.2)  # cladding vs UAamb,ON (Eq. 10)
    b["ua_idle_scale"] = _u(rng, 0.85, 1.2)  # idle draught air vs UAamb,OFF - UAamb,ON
    b["ua_nc_W_K"] = _u(rng, 0.6, 1.5)  # conduction/back-mixing boiler <-> exit pipe, no flow
    # --- burner controller ----------------------------------------------------------------
    b["t_set_offset_K"] = _u(rng, -0.6, 0.6)  # 1 K at the outlet is 0.8 kW at 12 kW
    b["t_off_offset_K"] = _u(rng, -1.0, 1.0)
    b["t_on_offset_K"] = _u(rng, -1.5, 1.5)
    b["ctrl_sensor_offset_K"] = _u(rng, -0.4, 0.4)
    b["ctrl_sensor_tau_s"] = _u(rng, 10.0, 30.0)
    b["kp_scale"] = _u(rng, 0.5, 1.2)
    b["ti_s"] = _u(rng, 300.0, 900.0)
    b["p_max_real_frac"] = _u(rng, 1.03, 1.08)  # firing limit vs the nameplate Pmax
    b["slew_pct_min"] = _u(rng, 6.0, 20.0)  # modulation slew, % of Pmax per minute
    b["min_off_s"] = _u(rng, 180.0, 600.0)
    # --- start-up and burn-out ------------------------------------------------------------
    b["prepurge_s"] = _u(rng, 40.0, 100.0)
    b["igniter_W"] = _u(rng, 260.0, 380.0)
    b["ign_ref_C"] = _u(rng, 320.0, 370.0)  # pellet surface temperature of quick ignition
    b["charge_kg"] = _u(rng, 0.10, 0.18) * p_nom / 12.0 + 0.03
    b["tau_bed_s"] = _u(rng, 80.0, 160.0)  # bed burn time constant
    b["spread_s"] = _u(rng, 8.0, 20.0)  # flame spread over the bed after ignition
    b["ramp_s"] = _u(rng, 90.0, 240.0)
    b["start_hold_s"] = _u(rng, 600.0, 1000.0)  # the paper's ~15 min at Pstart
    b["postpurge_s"] = _u(rng, 240.0, 420.0)
    # --- combustion ------------------------------------------------------------------------
    b["lam_a_scale"] = _u(rng, 0.95, 1.05)
    b["lam_b_scale"] = _u(rng, 0.9, 1.1)
    b["fan_sigma"] = _u(rng, 0.01, 0.04)
    b["fan_tau_s"] = _u(rng, 120.0, 600.0)
    b["o2_trim_tau_s"] = _u(rng, 300.0, 900.0)
    b["burn_sigma"] = _u(rng, 0.02, 0.05)  # bed burn-rate fluctuation (paper: Q fluctuates)
    b["burn_tau_s"] = _u(rng, 30.0, 120.0)
    b["auger_period_s"] = _u(rng, 8.0, 20.0)
    b["grate_pause_period_s"] = _u(rng, 1800.0, 4800.0)  # grate shaking in modulation
    b["grate_pause_s"] = _u(rng, 30.0, 90.0)  # feed paused meanwhile
    b["co_base_ppm"] = _u(rng, 30.0, 150.0)
    # --- exchanger -------------------------------------------------------------------------
    b["dt_fg_scale"] = _u(rng, 0.9, 1.1)  # flue-gas temperature at nominal vs dTnom (Eq. 8)
    b["ntu_exponent"] = _u(rng, 0.25, 0.45)  # NTU ~ W^-exponent (convective film)
    b["fouling0"] = _u(rng, 0.0, 0.05)
    b["fouling_per_kg"] = _u(rng, 0.001, 0.004)  # NTU loss per kg dry fuel burnt
    b["clean_eff"] = _u(rng, 0.4, 0.8)  # share of the fouling the spiral cleaner removes
    # --- fuel lot (normal spread of an ENplus lot) ----------------------------------------
    b["hhv_scale"] = _u(rng, 0.99, 1.01)
    b["moisture"] = _u(rng, 0.05, 0.08)
    b["bulk_density_ratio"] = _u(rng, 0.95, 1.05)  # auger delivers volume, not mass
    # --- bench -----------------------------------------------------------------------------
    b["bench_cool_max_frac"] = _u(rng, 1.3, 1.8)  # cooler capacity / Pnom
    b["bench_heat_max_frac"] = _u(rng, 0.5, 1.0)  # preheat heater / Pnom
    b["bench_kp_frac"] = _u(rng, 0.15, 0.4)  # kW per K, as fraction of Pnom
    b["bench_ti_s"] = _u(rng, 60.0, 240.0)
    b["bench_valve_tau_s"] = _u(rng, 10.0, 40.0)
    b["bench_loop_kg"] = _u(rng, 15.0, 40.0)
    b["bench_dist_frac"] = _u(rng, 0.01, 0.04)  # cooling-water disturbance, fraction of Pnom
    b["flow_tau_s"] = _u(rng, 3.0, 12.0)
    b["flow_offset_frac"] = _u(rng, -0.01, 0.01)
    b["flow_noise_frac"] = _u(rng, 0.002, 0.008)
    b["init_dev_K"] = _u(rng, -3.0, 1.0)
    # --- instruments -----------------------------------------------------------------------
    for name, lo, hi in (
        ("t_in", 3.0, 8.0),
        ("t_out", 3.0, 8.0),
        ("t_boiler", 8.0, 25.0),
        ("t_fg", 15.0, 45.0),
    ):
        b[f"tau_{name}_s"] = _u(rng, lo, hi)
        # a matched, calibrated Pt100 set: +-0.1 K (fg: class B on top, below)
        b[f"off_{name}_K"] = _u(rng, -0.1, 0.1)
    b["fg_class_b_frac"] = _u(rng, -0.6, 0.6)  # share of the class-B tolerance used
    b["o2_delay_s"] = _u(rng, 8.0, 25.0)
    b["o2_tau_s"] = _u(rng, 6.0, 15.0)
    b["o2_offset_pct"] = _u(rng, -0.15, 0.15)
    b["o2_drift_pct"] = _u(rng, -0.2, 0.2)  # over the whole log
    b["balance_tare_kg"] = _u(rng, 20.0, 30.0)  # hopper and auger housing
    b["hopper_kg"] = _u(rng, 30.0, 45.0)
    b["balance_drift_kg"] = _u(rng, -0.04, 0.04)
    b["duct_diam_m"] = _u(rng, 0.055, 0.07) * (p_nom / 12.0) ** 0.5  # ~2-3 m/s at nominal
    # --- room ------------------------------------------------------------------------------
    b["room_mean_C"] = _u(rng, 19.0, 27.0)
    b["room_amp_C"] = _u(rng, 0.3, 2.0)
    b["room_period_h"] = _u(rng, 10.0, 30.0)
    b["room_phase"] = _u(rng, 0.0, 6.283185307179586)
    b["pressure_hPa"] = _u(rng, 970.0, 1003.0)
    b["humidity_pct"] = _u(rng, 30.0, 60.0)
    return {k: float(v) for k, v in b.items()}


def quiet_background(boiler: dict) -> dict[str, float]:
    """A background with every random disturbance, offset and drift switched off.

    Used by the tests to compare the kernel's steady state with a closed form.
    """
    b = draw_background(np.random.default_rng(0), boiler)
    p_nom = float(boiler["p_nom_kW"])
    for k in list(b):
        if k.startswith("off_") or k.endswith("_offset_K") or k.endswith("_pct"):
            b[k] = 0.0
    b.update(
        cap_water_scale=1.0,
        cap_steel_scale=1.0,
        ua_sw_kW_K=p_nom / 12.0,
        ua_env_scale=1.0,
        ua_idle_scale=1.0,
        fan_sigma=0.0,
        burn_sigma=0.0,
        bench_dist_frac=0.0,
        fouling0=0.0,
        fouling_per_kg=0.0,
        grate_pause_s=0.0,
        hhv_scale=1.0,
        moisture=float(boiler["fuel"]["moisture"]),
        bulk_density_ratio=1.0,
        lam_a_scale=1.0,
        lam_b_scale=1.0,
        dt_fg_scale=1.0,
        flow_offset_frac=0.0,
        flow_noise_frac=0.0,
        fg_class_b_frac=0.0,
        o2_offset_pct=0.0,
        o2_drift_pct=0.0,
        balance_drift_kg=0.0,
        room_amp_C=0.0,
        room_mean_C=22.0,
        humidity_pct=45.0,
        pressure_hPa=990.0,
    )
    return {k: float(v) for k, v in b.items()}
