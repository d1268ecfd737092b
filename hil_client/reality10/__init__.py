"""reality10: an independent simulated pellet-boiler test bench ("a real boiler").

A Windhager-type pellet boiler after Carlon et al. (2015) (TRNSYS Type 869 balance: fuel
power on HHV basis, linear excess-air law, flue-gas sensible/latent/CO losses, UA on/off
losses, igniter energy) run through the stationary or load-cycle protocol of the Wieselburg
bench, with a random real-boiler background (own controller, start/stop sequence, exchanger,
bench, sensors; see background.py) and optionally one of five listed effects in one of two
forms. It writes lab logs in the CONTRACT section 3 format and is used as held-out truth.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import yaml

from .background import draw_background
from .plant import EFFECT_FORMS, effect_params, run_plant

__all__ = [
    "COLUMNS",
    "EFFECT_FORMS",
    "draw_background",
    "effect_params",
    "read_log_csv",
    "simulate_log",
    "write_log_csv",
]

COLUMNS: tuple[str, ...] = (
    "time_s",
    "phase",
    "sequence",
    "water_flow_kg_h",
    "water_in_temp_C",
    "water_out_temp_C",
    "boiler_water_temp_C",
    "flue_gas_temp_C",
    "flue_gas_O2_pct",
    "flue_gas_CO2_pct",
    "flue_gas_CO_ppm",
    "flue_gas_velocity_m_s",
    "chimney_draught_Pa",
    "balance_mass_kg",
    "room_temp_C",
    "ambient_pressure_hPa",
    "relative_humidity_pct",
    "electric_power_W",
    "water_flow_setpoint_kg_h",
    "boiler_on",
)
TEXT_COLUMNS = ("phase", "sequence")
PROTOCOL_DIR = Path(__file__).parents[1] / "protocol" / "definitions"
TESTS = ("stationary", "load_cycle")
VORTEX_CUTOFF_M_S = 0.5  # the vortex meter reads nothing below this


def _validate(test, effect, form, strength, sample_s, background) -> None:
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    if effect is None:
        if form is not None:
            raise ValueError(f"form {form!r} given without an effect; form must be None")
    elif effect not in EFFECT_FORMS:
        raise ValueError(
            f"unknown effect {effect!r}; expected None or one of {tuple(EFFECT_FORMS)}"
        )
    elif form not in EFFECT_FORMS[effect]:
        raise ValueError(f"unknown form {form!r} for {effect!r}; expected {EFFECT_FORMS[effect]}")
    try:
        s_ok = 0.0 <= float(strength) <= 1.0
    except (TypeError, ValueError):
        s_ok = False
    if not s_ok:
        raise ValueError(f"strength {strength!r} outside [0, 1]")
    try:
        dt_ok = 1.0 <= float(sample_s) <= 10.0
    except (TypeError, ValueError):
        dt_ok = False
    if not dt_ok:
        raise ValueError(f"sample_s {sample_s!r} outside [1, 10] s")
    if not isinstance(background, dict):
        raise ValueError("background must be the dict returned by draw_background")
    missing = set(draw_background(np.random.default_rng(0), {"p_nom_kW": 1.0})) - set(background)
    if missing:
        raise ValueError(f"background lacks keys {sorted(missing)}")


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
) -> tuple[dict[str, np.ndarray], dict]:
    """Run ``test`` on the boiler and return (lab-log columns, meta)."""
    _validate(test, effect, form, strength, sample_s, background)
    proto = yaml.safe_load((PROTOCOL_DIR / f"{test}.yaml").read_text())
    bg = {k: float(v) for k, v in background.items()}
    out = run_plant(boiler, proto, bg, effect, form, float(strength), int(seed))
    tr, pm, rng = out["traces"], out["meta"], out["noise_rng"]
    tg = np.asarray(tr["t"])
    t_end = float(tg[-1])
    dt_s = float(sample_s)
    if jitter:
        steps = dt_s * rng.uniform(0.7, 1.3, size=int(t_end / (0.7 * dt_s)) + 2)
        ts = np.concatenate(([0.0], np.cumsum(steps)))
    else:
        ts = np.arange(0.0, t_end + 1e-9, dt_s)
    ts = ts[ts <= t_end]
    n = ts.size
    idx = np.clip(np.searchsorted(tg, ts, side="right") - 1, 0, tg.size - 1)

    def ip(key: str, shift: float = 0.0) -> np.ndarray:
        return np.interp(ts - shift, tg, np.asarray(tr[key], dtype=float))

    def nz(sd: float) -> np.ndarray:
        return sd * rng.standard_normal(n)

    th = ts / 3600.0
    sd_t = bg["t_noise_K"]
    flow = ip("flow")
    vel = ip("vel") + nz(0.05)
    cols: dict[str, np.ndarray] = {
        "time_s": np.round(ts, 3),
        "phase": np.asarray(tr["phase"], dtype=object)[idx],
        "sequence": np.asarray(tr["seq"], dtype=object)[idx],
        "water_flow_kg_h": np.clip(flow * (1 + nz(bg["flow_noise_frac"])) + nz(0.5), 0, None),
        "water_in_temp_C": ip("t_in") + nz(sd_t),
        "water_out_temp_C": ip("t_out") + nz(sd_t),
        "boiler_water_temp_C": ip("t_boil") + nz(sd_t),
        "flue_gas_temp_C": ip("t_fg") + nz(bg["t_fg_noise_K"]),
        "flue_gas_O2_pct": np.clip(ip("o2", bg["o2_delay_s"]) + bg["o2_offset"] + nz(0.05), 0, 21),
        "flue_gas_CO2_pct": np.clip(ip("co2", bg["o2_delay_s"]) * bg["co2_gain"] + nz(0.05), 0, 25),
        "flue_gas_CO_ppm": np.clip(ip("co", bg["o2_delay_s"]) * bg["co_gain"] + nz(3.0), 0, None),
        "flue_gas_velocity_m_s": np.where(vel < VORTEX_CUTOFF_M_S, np.nan, vel),
        "chimney_draught_Pa": bg["draught_Pa"] + nz(0.6),
        "balance_mass_kg": np.round(
            (ip("hopper") + nz(bg["balance_noise_kg"])) / bg["balance_res_kg"]
        )
        * bg["balance_res_kg"],
        "room_temp_C": ip("room") + bg["room_sensor_offset_K"] + nz(0.05),
        "ambient_pressure_hPa": bg["pressure_hPa"] + bg["pressure_drift_hPa_h"] * th + nz(0.1),
        "relative_humidity_pct": np.clip(
            bg["humidity_pct"] + bg["humidity_drift_pct_h"] * th + nz(0.5), 0, 100
        ),
        "electric_power_W": np.asarray(tr["pel"], dtype=float)[idx] + nz(0.5),
        "water_flow_setpoint_kg_h": np.asarray(tr["flow_sp"], dtype=float)[idx],
        "boiler_on": np.asarray(tr["on"], dtype=float)[idx],
    }
    cols = {c: cols[c] for c in COLUMNS}
    led = pm["ledger_kJ"]
    e_in = led["fuel"] + led["igniter"]
    e_out = sum(led[k] for k in ("water", "amb", "fg_sens", "fg_lat", "fg_co", "ash_char"))
    e_out += led["storage"] + led["bed"]
    meta = {
        "boiler": boiler.get("name"),
        "test": test,
        "effect": effect,
        "form": form,
        "strength": float(strength),
        "effect_params": pm["effect_params"],
        "seed": int(seed),
        "sample_s": dt_s,
        "jitter": bool(jitter),
        **pm["marks"],
        "n_starts": pm["n_starts"],
        "ledger_kJ": led,
        "energy_residual_rel": (e_in - e_out) / e_in if e_in else math.nan,
        "fuel_fed_kg": pm["fuel_fed_kg"],
        "hopper_start_kg": pm["hopper_start_kg"],
        "fuel_moisture": pm["fuel_moisture"],
        "nominal_flow_kg_h": pm["nominal_flow_kg_h"],
        "internal_step_s": pm["internal_step_s"],
        "background": dict(bg),
        "truth": {
            "balance_kg": ip("hopper"),
            "fuel_fed_kg": ip("fed"),
            "heat_to_water_kW": ip("q_water"),
            "fuel_power_kW": ip("q_fuel"),
            "boiler_water_C": ip("tw_true"),
            "water_out_C": ip("tout_true"),
            "water_in_C": ip("tin_true"),
            "flue_gas_C": ip("tfg_true"),
        },
    }
    return cols, meta


def write_log_csv(columns: dict, path) -> None:
    """Write a lab log: header row of names, one row per sample, NaN as an empty field."""
    names = list(columns)
    arrays = [np.asarray(columns[c]) for c in names]
    n = len(arrays[0]) if arrays else 0

    def fmt(v) -> str:
        if isinstance(v, str):
            return v
        if v is None:
            return ""
        f = float(v)
        return "" if math.isnan(f) else repr(f)

    with open(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(names)
        for i in range(n):
            wr.writerow([fmt(a[i]) for a in arrays])


def read_log_csv(path) -> dict[str, np.ndarray]:
    """Read a lab log; numeric columns as float arrays (empty -> NaN), text as object arrays."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    names, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(names):
        vals = [r[j] if j < len(r) else "" for r in body]
        if name in TEXT_COLUMNS:
            out[name] = np.asarray(vals, dtype=object)
            continue
        try:
            out[name] = np.asarray([float(v) if v != "" else math.nan for v in vals], dtype=float)
        except ValueError:
            out[name] = np.asarray(vals, dtype=object)
    return out
