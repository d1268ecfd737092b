"""reality9: an independent simulated pellet-boiler test bench ("a real boiler").

A Windhager-type pellet boiler on the Wieselburg bench of Carlon et al. (2015), run through
the stationary test or the load cycle and logged with the lab-log columns. It differs from
TRNSYS Type 869 by a random per-case background (see background.py) and, optionally, by one
listed effect in one of two forms of its own (EFFECT_FORMS).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from .background import EFFECT_FORMS, draw_background
from .plant import PHASES, room_temp, run_plant

__all__ = ["COLUMNS", "EFFECT_FORMS", "draw_background", "read_log_csv", "simulate_log"]
__all__ += ["write_log_csv"]

COLUMNS = (
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
_TEXT = ("phase", "sequence")


def _lag(x: np.ndarray, tau: float, dt: float) -> np.ndarray:
    a = 1.0 - math.exp(-dt / tau)
    y = np.empty_like(x)
    acc = float(x[0])
    for i, v in enumerate(x.tolist()):
        acc += a * (v - acc)
        y[i] = acc
    return y


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
    """Simulate one lab log; returns (columns, meta)."""
    if test not in ("stationary", "load_cycle"):
        raise ValueError(f"unknown test {test!r}")
    if effect is not None:
        if effect not in EFFECT_FORMS:
            raise ValueError(f"unknown effect {effect!r}")
        if form not in EFFECT_FORMS[effect]:
            raise ValueError(f"unknown form {form!r} for effect {effect!r}")
    elif form is not None:
        raise ValueError("a form needs an effect")
    if not (1.0 <= float(sample_s) <= 10.0):
        raise ValueError("sample_s must lie in [1, 10] s")
    s = float(strength)
    if not (0.0 <= s <= 1.0):
        raise ValueError("strength must lie in [0, 1]")
    bg = background
    res = run_plant(boiler, test, bg, effect, form, s, seed)
    st, meta = res["steps"], dict(res["meta"])
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 17])
    ti = st["t"]
    dt = meta["dt_s"]
    t_end = float(ti[-1])
    n = math.floor(t_end / sample_s) + 1
    ts = np.arange(n) * float(sample_s)
    if jitter:
        ts = ts + rng.uniform(-0.3, 0.3, n) * float(sample_s)
        ts = np.clip(ts, 0.0, t_end)
        ts[0] = 0.0
    idx = np.clip(np.searchsorted(ti, ts, side="right") - 1, 0, len(ti) - 1)

    def lin(x):
        return np.interp(ts, ti, x)

    def noise(sd):
        return sd * rng.standard_normal(n)

    cols: dict[str, np.ndarray] = {"time_s": np.round(ts, 3)}
    names = [*PHASES]
    cols["phase"] = np.array([names[p] for p in st["phase"][idx]], dtype=object)
    seq_names = meta.pop("seq_names")
    seq = st["seq"][idx]
    cols["sequence"] = np.array(
        [seq_names[q] if q >= 0 else names[p] for q, p in zip(seq, st["phase"][idx], strict=True)],
        dtype=object,
    )
    cols["water_flow_kg_h"] = lin(st["m_w"]) * (1.0 + noise(0.003))
    cols["water_in_temp_C"] = lin(st["t_in_m"]) + noise(0.03)
    cols["water_out_temp_C"] = lin(st["t_out_m"]) + noise(0.03)
    cols["boiler_water_temp_C"] = lin(st["t_bw_m"]) + noise(0.04)
    cols["flue_gas_temp_C"] = lin(st["t_fg_m"]) + noise(0.15)
    # gas analyser: heated sample line (transport delay) and analyser response
    tg = np.clip(ts - bg["gas_delay_s"], 0.0, None)
    o2 = np.interp(tg, ti, _lag(st["o2"], bg["gas_tau_s"], dt))
    co2 = np.interp(tg, ti, _lag(st["co2"], bg["gas_tau_s"], dt))
    co = np.interp(tg, ti, _lag(st["co"], bg["gas_tau_s"], dt))
    cols["flue_gas_O2_pct"] = o2 + bg["o2_offset"] + noise(0.05)
    cols["flue_gas_CO2_pct"] = np.clip(co2 * bg["co2_gain"] + noise(0.05), 0.0, None)
    cols["flue_gas_CO_ppm"] = np.clip(co * (1.0 + noise(0.03)) + noise(2.0), 0.0, None)
    vel = lin(_lag(st["vel"], 6.0, dt)) + bg["v_bias_m_s"] + noise(0.05)
    cols["flue_gas_velocity_m_s"] = np.where(vel < 0.5, 0.0, vel)
    cols["chimney_draught_Pa"] = -12.0 + noise(0.3)
    bal = bg["balance_m0_kg"] - lin(st["fed_ar"]) + noise(0.005)
    cols["balance_mass_kg"] = np.round(bal / 0.02) * 0.02
    cols["room_temp_C"] = room_temp(bg, ts) + noise(0.05)
    cols["ambient_pressure_hPa"] = bg["pressure_hPa"] + 2.0 * np.sin(ts / 40000.0) + noise(0.1)
    cols["relative_humidity_pct"] = bg["rh_pct"] + 3.0 * np.sin(ts / 30000.0) + noise(0.5)
    cols["electric_power_W"] = st["p_el"][idx] + noise(0.3)
    cols["water_flow_setpoint_kg_h"] = st["m_set"][idx]
    cols["boiler_on"] = st["on"][idx].astype(int)
    for name in COLUMNS[3:18]:
        if name == "water_flow_setpoint_kg_h":
            continue
        drop = rng.random(n) < bg["p_drop"]
        cols[name] = np.where(drop, np.nan, cols[name])
    meta.update(
        {
            "boiler": boiler.get("name", "inline"),
            "test": test,
            "effect": effect,
            "form": form,
            "strength": s,
            "seed": int(seed),
            "sample_s": float(sample_s),
            "jitter": bool(jitter),
        }
    )
    return cols, meta


def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    f = float(v)
    if math.isnan(f):
        return ""
    return repr(f)


def write_log_csv(columns: dict, path) -> None:
    """Write a log: header row, one row per acquisition, missing values as empty fields."""
    order = [c for c in COLUMNS if c in columns] + [c for c in columns if c not in COLUMNS]
    n = len(columns[order[0]])
    data = [list(columns[c]) for c in order]
    with Path(path).open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(order)
        for i in range(n):
            w.writerow([_fmt(col[i]) for col in data])


def read_log_csv(path) -> dict[str, np.ndarray]:
    """Read a log written by write_log_csv (text columns stay text, empty fields NaN)."""
    with Path(path).open(newline="") as fh:
        rows = list(csv.reader(fh))
    head, body = rows[0], rows[1:]
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(head):
        vals = [r[j] for r in body]
        if name in _TEXT:
            out[name] = np.array(vals, dtype=object)
        else:
            out[name] = np.array([float(v) if v != "" else np.nan for v in vals])
    return out
