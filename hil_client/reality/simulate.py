"""One lab log of the independent plant: the boiler file, a background, maybe one effect.

:func:`plant_values` turns the documented parameters (CONTRACT section 2), the drawn
background and the effect into the kernel's named values; :func:`simulate_log` runs the
test and returns the CONTRACT section 3 columns plus a meta mapping (phase marks, the
effect's physical parameters, the energy ledger and true signals for the tests).
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np

from hil_client.reality import kernel as kn
from hil_client.reality.combustion import (
    CP_WATER_KJ_KG_K,
    RHO_WATER_KG_M3,
    fuel_constants,
    humidity_ratio,
)
from hil_client.reality.effects import effect_fields
from hil_client.reality.params import NAMES, pack
from hil_client.reality.protocol import load_test

PHASE_NAMES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
#: (log column, kernel column) in CONTRACT section 3 order after time_s, phase, sequence.
READINGS = (
    ("water_flow_kg_h", kn.C_FLOW),
    ("water_in_temp_C", kn.C_TIN),
    ("water_out_temp_C", kn.C_TOUT),
    ("boiler_water_temp_C", kn.C_TBW),
    ("flue_gas_temp_C", kn.C_TFG),
    ("flue_gas_O2_pct", kn.C_O2),
    ("flue_gas_CO2_pct", kn.C_CO2),
    ("flue_gas_CO_ppm", kn.C_CO),
    ("flue_gas_velocity_m_s", kn.C_VEL),
    ("chimney_draught_Pa", kn.C_DRAUGHT),
    ("balance_mass_kg", kn.C_BAL),
    ("room_temp_C", kn.C_ROOM),
    ("ambient_pressure_hPa", kn.C_P),
    ("relative_humidity_pct", kn.C_RH),
    ("electric_power_W", kn.C_PEL),
    ("water_flow_setpoint_kg_h", kn.C_SET),
    ("boiler_on", kn.C_ON),
)
LEDGER = {
    "fuel_fed_kJ": kn.L_FED,
    "igniter_kJ": kn.L_IGN,
    "heat_to_water_kJ": kn.L_WATER,
    "flue_gas_and_ash_kJ": kn.L_FLUE,
    "room_kJ": kn.L_ROOM,
    "storage_change_kJ": kn.L_STORE,
    "boiler_water_true_C": kn.L_TW,
    "forward_water_true_C": kn.L_TFWD,
    "return_true_C": kn.L_TIN,
    "flow_true_kg_h": kn.L_FLOW,
    "flue_gas_sensor_true_C": kn.L_TFG,
    "fuel_fed_as_received_kg": kn.L_FEED_AR,
    "bed_kg": kn.L_BED,
    "firing_power_cmd_kW": kn.L_FIRE,
    "heat_to_water_true_kW": kn.L_QW,
    "metal_fire_side_C": kn.L_TMETAL,
    "fuel_burnt_dry_kg": kn.L_BURNT,
    "room_true_C": kn.L_TROOM,
    "o2_true_pct": kn.L_O2,
}
DUCT_AREA_M2 = math.pi * 0.10**2 / 4.0  # DN100 flue duct of the bench


def _nominal_gas(values: dict[str, float], firing_kW: float) -> tuple[float, float, float]:
    """(W [kW/K], chamber temperature [C], dry fuel flow [kg/h]) at ``firing_kW`` in a
    22 C, 45 % RH, 985 hPa room (used to place the exchanger's NTU)."""
    ns = SimpleNamespace(**values)
    dry = firing_kW * 3600.0 / values["lhv_ar_nom"] * (1.0 - values["moist_ar_nom"])
    lam = max(values["lam_a"] + values["lam_b"] * dry, values["lam_floor"])
    v_air = lam * values["air_min"] * dry
    x = humidity_ratio(22.0, 45.0, 985.0)
    _, _, _, w, q_lat, q_chem, _ = kn._gas.py_func(ns, dry, v_air, x, values["co_at_max"])
    q_rel = dry * values["hhv_true"] / 3600.0
    h_gas = q_rel * (1.0 - 0.0002 - values["bc_share"]) - q_lat - q_chem
    return w, 22.0 + h_gas / w, dry


def _fire_ntu_exponent(boiler: dict, v: dict[str, float], bg: dict, t_fg_nom: float) -> float:
    """Exponent m of the exchanger's fire term, NTU = NTU_nom (W / W_nom)^(-n) (Q_rel /
    Q_rel,nom)^m, that puts the flue gas at Pmin where the boiler's documented part-load
    line puts it (Eq. 8, Fig. 4: T_fg - T_in = dTnom + dThx,wat (1 - m/m_nom), the lab's
    regression over the load cycle's stationary intervals), off by the background's
    ``fg_part_load_dev_K``.

    Why: the paper's boilers are thermo-controlled (the fan holds the temperature at the
    exit of the combustion chamber, Section 2.1) and their flue gas leaves at nearly the same
    temperature at every load (dThx,wat = -0.5 / -1.07 K over 30-100 % load). A bare
    convective exchanger would leave the leaner, cooler part-load gas tens of kelvin colder
    than measured (the gas flow W hardly changes with load, the chamber temperature does),
    making the plant's part load far more efficient than the boiler documented and its
    cut-outs at 13 % load far earlier than any Type 869 calibration could follow. The
    exchange in the firebox is largely radiative and so rises with the flame temperature
    and size; m > 0 lumps that."""
    p_min = v["p_min"]
    firing_nom = float(boiler["p_nom_kW"]) / 0.9
    share = min(0.9 * p_min / float(boiler["p_nom_kW"]), 0.95)  # water-flow share at Pmin
    w_low, t_ch_low, _ = _nominal_gas(v, p_min)
    t_sink_low = 70.0 - v["sink_kappa"] * 15.0 * share / (share + 0.05)
    t_fg_low = (
        t_fg_nom
        + float(boiler["dt_hx_wat_K"]) * (1.0 - share)
        + float(bg.get("fg_part_load_dev_K", 0.0))
    )
    t_fg_low = min(max(t_fg_low, t_sink_low + 3.0), t_ch_low - 5.0)
    ntu_low = math.log((t_ch_low - t_sink_low) / (t_fg_low - t_sink_low))
    conv = (w_low / v["w_nom_kW_K"]) ** (-v["ntu_exp"])
    return math.log(ntu_low / (v["ntu_nom"] * conv)) / math.log(p_min / firing_nom)


def plant_values(
    boiler: dict,
    test: str,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
    sample_s: float,
    jitter: bool,
) -> tuple[dict[str, float], dict[str, Any], dict[str, float]]:
    """(kernel values by name, protocol sequences, the effect's physical parameters)."""
    bg = background
    fc = fuel_constants(boiler["fuel"])
    settings, seqs = load_test(test)
    p_max = float(boiler["p_max_kW"]) * bg["p_max_factor"]
    p_min = float(boiler["p_min_kW"]) * bg["p_min_factor"]
    ua_on = float(boiler["ua_amb_on_W_K"]) / 1000.0
    ua_off = float(boiler["ua_amb_off_W_K"]) / 1000.0
    v: dict[str, float] = {
        "hhv_true": fc["hhv_dry_kJ_kg"] * bg["hhv_factor"],
        "moist_ar_nom": fc["moisture_ar"],
        "moist_ar_true": fc["moisture_ar"],
        "moist_true": fc["moisture_kg_kg_dry"],
        "lhv_ar_nom": fc["lhv_ar_kJ_kg"],
        "o_min": fc["o_min_nm3_kg"],
        "air_min": fc["air_min_nm3_kg"],
        "v_co2": fc["v_co2_nm3_kg"],
        "v_so2": fc["v_so2_nm3_kg"],
        "v_n2f": fc["v_n2_fuel_nm3_kg"],
        "water_h": fc["water_from_h_kg_kg"],
        "p_nom": float(boiler["p_nom_kW"]),
        "p_min": p_min,
        "p_max": p_max,
        "p_start": min(float(boiler["p_start_kW"]) * bg["p_start_factor"], p_max),
        "c_metal": float(boiler["c_therm_kJ_K"]) * bg["c_metal_factor"],
        "c_water": float(boiler["vol_water_m3"])
        * RHO_WATER_KG_M3
        * CP_WATER_KJ_KG_K
        * bg["c_water_factor"],
        "tau_mw": bg["tau_mw"],
        "ua_shell_kW_K": ua_on * bg["ua_shell_factor"],
        "draught_kW_K": max(ua_off - ua_on, 0.2e-3) * bg["draught_factor"],
        "bc_share": bg["bc_share"],
        "ntu_exp": bg["ntu_exp"],
        "sink_kappa": bg["sink_kappa"],
        "lam_a": float(boiler["fac_a_lambda"]) * bg["lam_a_factor"],
        "lam_b": float(boiler["fac_b_lambda_h_kg"]) * bg["lam_b_factor"],
        "lam_floor": 1.3,
        "duct_area_m2": DUCT_AREA_M2,
        "pel_min": float(boiler["p_el_min_W"]) * bg["pel_min_factor"],
        "pel_max": float(boiler["p_el_max_W"]) * bg["pel_max_factor"],
        "pel_off": float(boiler["p_el_off_W"]) * bg["pel_off_factor"],
        "p_ign_W": float(boiler["w_el_Wh"]) * 3600.0 / bg["t_igniter_s"] * bg["p_ign_factor"],
        "q_cool_max_kW": bg["q_cool_factor"] * p_max,
        "q_heat_max_kW": bg["q_heat_factor"] * float(boiler["p_nom_kW"]),
    }
    for name in NAMES:  # the background's values that the kernel takes as they are
        if name in bg and name not in v:
            v[name] = float(bg[name])
    # exchanger: NTU placing the nominal flue-gas temperature near the documented dTnom
    firing_nom = float(boiler["p_nom_kW"]) / 0.9
    w_nom, t_ch, dry_nom = _nominal_gas(v, firing_nom)
    t_sink = 70.0 - v["sink_kappa"] * 15.0 * 0.95
    t_fg = max(55.0 + float(boiler["dt_nom_K"]) + bg["fg_dev_K"], t_sink + 5.0)
    v["w_nom_kW_K"] = w_nom
    v["ntu_nom"] = math.log((t_ch - t_sink) / (t_fg - t_sink))
    v["q_rel_nom_kW"] = dry_nom * v["hhv_true"] / 3600.0
    v["fire_share_min"] = p_min / firing_nom
    v["ntu_fire_exp"] = _fire_ntu_exponent(boiler, v, bg, t_fg)
    dry_max = p_max * 3600.0 / v["lhv_ar_nom"] * (1.0 - v["moist_ar_nom"])
    lam_max = max(v["lam_a"] + v["lam_b"] * dry_max, v["lam_floor"])
    v["fan_min_nm3_h"] = 0.5 * lam_max * v["air_min"] * dry_max
    # effect
    fields, info = effect_fields(
        effect, form, strength, bg, w_nom, float(boiler["fuel"]["moisture"]), seed
    )
    v |= fields
    if "hhv_bias" in info:
        v["hhv_true"] *= 1.0 + info["hhv_bias"]
    if "moisture_ar" in info:
        m = info["moisture_ar"]
        v["moist_ar_true"] = m
        v["moist_true"] = m / (1.0 - m)
    v |= settings
    v |= {"sample_s": float(sample_s), "jitter": 1.0 if jitter else 0.0, "seed": float(seed)}
    return v, seqs, info


def simulate_log(
    boiler: dict,
    test: str,
    *,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
    sample_s: float,
    jitter: bool,
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The lab log of ``test`` ("stationary" | "load_cycle") on this plant.

    Returns (columns by CONTRACT section 3 name, one row per acquisition, NaN where a
    reading dropped out; meta with ``t0_s``..``t4_s``, ``timed_out``, the effect and its
    physical parameters, ``ledger`` and ``truth`` arrays per row)."""
    if not 1.0 <= sample_s <= 10.0:
        raise ValueError(f"sample_s must lie in [1, 10] s, not {sample_s}")
    values, seqs, info = plant_values(
        boiler, test, background, effect, form, strength, seed, sample_s, jitter
    )
    p = pack(values)
    total = (
        values["pre_max"]
        + values["su_max"]
        + float(np.sum(seqs["dur"]))
        + values["c1_max"]
        + values["c2_after"]
    )
    max_rows = int(total / (0.7 * sample_s)) + 16
    out, led, n, marks, timeouts = kn.run_test(
        p, seqs["load0"], seqs["load1"], seqs["dur"], max_rows
    )
    out, led = out[:n], led[:n]
    phase_codes = out[:, kn.C_PHASE].astype(int)
    seq_codes = out[:, kn.C_SEQ].astype(int)
    names = np.array([*seqs["names"], ""], dtype=object)
    columns: dict[str, np.ndarray] = {
        "time_s": out[:, kn.C_TIME].copy(),
        "phase": np.array(PHASE_NAMES, dtype=object)[phase_codes],
        "sequence": names[np.where(seq_codes >= 0, seq_codes, len(names) - 1)],
    }
    for name, col in READINGS:
        columns[name] = out[:, col].copy()
    meta: dict[str, Any] = {
        "boiler": boiler.get("name"),
        "test": test,
        **{f"t{i}_s": (None if math.isnan(m) else float(m)) for i, m in enumerate(marks)},
        "timed_out": [PHASE_NAMES[i] for i in range(5) if timeouts[i] > 0],
        "effect": effect,
        "form": form,
        "strength": strength,
        "effect_params": info,
        "ledger": {name: led[:, i].copy() for name, i in LEDGER.items()},
    }
    return columns, meta
