"""Running one record and turning it into lab-log columns (CONTRACT section 3)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import lfilter

from hil_client.reality3 import _params as P
from hil_client.reality3._effects import check_effect
from hil_client.reality3._kernel import new_record, run_kernel
from hil_client.reality3._plant import build_params
from hil_client.reality3._schedule import schedule_arrays

LOG_COLUMNS: tuple[str, ...] = (
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

_DECIMALS = {
    "time_s": 3,
    "water_flow_kg_h": 3,
    "water_in_temp_C": 3,
    "water_out_temp_C": 3,
    "boiler_water_temp_C": 3,
    "flue_gas_temp_C": 2,
    "flue_gas_O2_pct": 3,
    "flue_gas_CO2_pct": 3,
    "flue_gas_CO_ppm": 1,
    "flue_gas_velocity_m_s": 3,
    "chimney_draught_Pa": 2,
    "balance_mass_kg": 3,
    "room_temp_C": 2,
    "ambient_pressure_hPa": 2,
    "relative_humidity_pct": 2,
    "electric_power_W": 2,
    "water_flow_setpoint_kg_h": 3,
    "boiler_on": 0,
}


@dataclass
class Raw:
    """One simulated record at the internal step, before the instruments' noise."""

    rec: np.ndarray  # (n, N_REC)
    p: np.ndarray
    info: dict
    marks: tuple[float, float, float, float, float]
    starts: int
    seq_names: list[str]
    rh: np.ndarray
    press: np.ndarray
    dt: float


def _ou(rng: np.random.Generator, n: int, sd: float, tau: float, dt: float) -> np.ndarray:
    """Ornstein-Uhlenbeck series (stationary start) of standard deviation ``sd``."""
    a = math.exp(-dt / tau)
    e = rng.standard_normal(n) * sd * math.sqrt(1.0 - a * a)
    y, _ = lfilter([1.0], [1.0, -a], e, zi=np.array([a * rng.normal(0.0, sd)]))
    return y


def humidity_ratio_np(t_c: np.ndarray, rh_pct: np.ndarray, p_hpa: np.ndarray) -> np.ndarray:
    """Water per kg of dry air (Magnus)."""
    ps = 6.112 * np.exp(17.62 * t_c / (243.12 + t_c))
    pv = np.clip(rh_pct, 0.0, 100.0) / 100.0 * ps
    return 0.622 * pv / np.maximum(p_hpa - pv, 1.0)


def exogenous(bg: dict, n: int, dt: float, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """Room temperature, humidity ratio, pressure and the plant's random disturbances."""
    t = np.arange(n) * dt
    troom = (
        bg["t_room_C"]
        + bg["room_day_amp_K"] * np.sin(2.0 * np.pi * t / 86400.0 + bg["room_day_phase"])
        + _ou(rng, n, bg["room_noise_sd_K"], 3600.0, dt)
    )
    press = bg["pressure_hPa"] + _ou(rng, n, bg["pressure_sd_hPa"], 4 * 3600.0, dt)
    rh = np.clip(bg["rh_pct"] + _ou(rng, n, bg["rh_sd_pct"], 2 * 3600.0, dt), 5.0, 95.0)
    dens = 1.0 + _ou(rng, n, bg["density_noise_sd"], bg["density_noise_tau_s"], dt)
    lam = 1.0 + _ou(rng, n, bg["lambda_noise_sd"], bg["lambda_noise_tau_s"], dt)
    flow = _ou(rng, n, bg["flow_ripple_sd"], bg["flow_ripple_tau_s"], dt)
    cold = _ou(rng, n, bg["cold_side_sd"], bg["cold_side_tau_s"], dt)
    exo = np.empty((n, P.N_EXO))
    exo[:, P.X_TROOM] = troom
    exo[:, P.X_XAIR] = humidity_ratio_np(troom, rh, press)
    exo[:, P.X_PRESS] = press
    exo[:, P.X_DENS] = np.clip(dens, 0.7, 1.3)
    exo[:, P.X_LAM] = np.clip(lam, 0.8, 1.2)
    exo[:, P.X_FLOW] = flow
    exo[:, P.X_COLD] = np.clip(cold, -0.5, 0.5)
    return exo, rh


def simulate_raw(
    boiler: dict,
    test: str,
    *,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
) -> Raw:
    """Run the kernel for one record (internal step, truth and sensor-side signals)."""
    check_effect(effect, form)
    if effect == "none":
        effect = None
    p, info = build_params(boiler, background, effect, form, strength)
    names, dur, l0, l1 = schedule_arrays(test)
    dt = p[P.DT]
    nmax = int((p[P.PREHEAT_MAX] + p[P.SU_MAX] + dur.sum() + p[P.C2_AFTER]) / dt) + 10
    rng = np.random.default_rng([int(seed), 0x7233])
    exo, rh = exogenous(background, nmax, dt, rng)
    rec = new_record(nmax)
    n, t0, t1, t2, t3, t4, starts = run_kernel(p, dur, l0, l1, exo, rec)
    return Raw(
        rec=rec[:n],
        p=p,
        info=info,
        marks=(t0, t1, t2, t3, t4),
        starts=starts,
        seq_names=names,
        rh=rh[:n],
        press=exo[:n, P.X_PRESS].copy(),
        dt=dt,
    )


def _times(t_end: float, sample_s: float, jitter: bool, rng: np.random.Generator) -> np.ndarray:
    if not jitter:
        return np.arange(0.0, t_end + 1e-9, sample_s)
    n_est = int(t_end / sample_s * 1.6) + 10
    steps = sample_s * rng.uniform(0.6, 1.4, n_est)
    t = np.concatenate([[0.0], np.cumsum(steps)])
    t = np.round(t[t <= t_end], 3)
    return t


def _quant(x: np.ndarray, q: float) -> np.ndarray:
    return np.round(x / q) * q


def to_columns(
    raw: Raw, background: dict, sample_s: float, jitter: bool, seed: int
) -> dict[str, np.ndarray]:
    """Sample the record at the acquisition times and apply the instruments."""
    if not 0.999 <= sample_s <= 10.0 + 1e-9:
        raise ValueError(f"sample_s must be within 1-10 s, got {sample_s}")
    bg = background
    rng = np.random.default_rng([int(seed), 0x10C])
    rec, dt = raw.rec, raw.dt
    n = rec.shape[0]
    t_end = (n - 1) * dt
    t = _times(t_end, sample_s, jitter, rng)
    k = len(t)
    x = t / dt
    i0 = np.minimum(np.floor(x).astype(np.int64), n - 1)
    i1 = np.minimum(i0 + 1, n - 1)
    f = x - i0

    def cont(col: int) -> np.ndarray:
        return rec[i0, col] * (1.0 - f) + rec[i1, col] * f

    def disc(col: int) -> np.ndarray:
        return rec[i0, col]

    hours10 = t / 36000.0
    cols: dict[str, np.ndarray] = {"time_s": t}
    phase_codes = disc(P.R_PHASE).astype(np.int64)
    cols["phase"] = np.array(P.PHASE_NAMES, dtype=object)[phase_codes].astype(str)
    seq_codes = disc(P.R_SEQ).astype(np.int64)
    seq_lookup = np.array([*raw.seq_names, ""], dtype=object)
    seq = seq_lookup[np.where(seq_codes >= 0, seq_codes, len(raw.seq_names))]
    seq = np.where(seq == "", cols["phase"], seq)
    cols["sequence"] = seq.astype(str)
    m = cont(P.R_M)
    flow = m * (1.0 + bg["flow_gain"]) + rng.normal(0.0, 1.0, k) * (0.002 * m + 0.2)
    flow = np.where(np.abs(flow) < 1.5, 0.0, flow)  # low-flow cut-off
    cols["water_flow_kg_h"] = _quant(flow, 0.01)

    def water(col: int, off: str, drift: str) -> np.ndarray:
        v = cont(col) + bg[off] + bg[drift] * hours10 + rng.normal(0.0, 0.02, k)
        return _quant(v, 0.01)

    cols["water_in_temp_C"] = water(P.R_TIN_S, "off_tin_K", "drift_tin_K_10h")
    cols["water_out_temp_C"] = water(P.R_TOUT_S, "off_tout_K", "drift_tout_K_10h")
    cols["boiler_water_temp_C"] = water(P.R_TBW_S, "off_tbw_K", "drift_tbw_K_10h")
    tfg = cont(P.R_TFG_S) + raw.p[P.OFF_TFG] + rng.normal(0.0, 0.15, k)
    cols["flue_gas_temp_C"] = _quant(tfg, 0.1)
    o2 = (
        cont(P.R_O2_S) * bg["span_o2"]
        + bg["off_o2_pct"]
        + bg["drift_o2_pct_10h"] * hours10
        + rng.normal(0.0, 0.03, k)
    )
    cols["flue_gas_O2_pct"] = _quant(np.clip(o2, 0.0, 21.5), 0.01)
    co2 = cont(P.R_CO2_S) * bg["span_co2"] + bg["off_co2_pct"] + rng.normal(0.0, 0.04, k)
    cols["flue_gas_CO2_pct"] = _quant(np.clip(co2, 0.0, 25.0), 0.01)
    co = cont(P.R_CO_S) * (1.0 + rng.normal(0.0, 0.02, k)) + rng.normal(0.0, 3.0, k)
    cols["flue_gas_CO_ppm"] = _quant(np.clip(co, 0.0, None), 1.0)
    vel = cont(P.R_VEL) + rng.normal(0.0, 0.04, k)
    cols["flue_gas_velocity_m_s"] = _quant(np.where(vel < 0.4, 0.0, vel), 0.01)
    v_rel = cont(P.R_VEL) / bg["velocity_nom_m_s"]
    draught = -12.0 - 0.6 * (v_rel - 0.6) + rng.normal(0.0, 0.4, k)
    cols["chimney_draught_Pa"] = _quant(draught, 0.1)
    bal = bg["balance_kg"] - cont(P.R_FED) + rng.normal(0.0, bg["balance_noise_kg"], k)
    cols["balance_mass_kg"] = _quant(bal, bg["balance_step_kg"])
    room = cont(P.R_TROOM) + bg["off_room_K"] + rng.normal(0.0, 0.03, k)
    cols["room_temp_C"] = _quant(room, 0.1)
    ti = np.minimum(np.floor(x).astype(np.int64), n - 1)
    press_true = np.interp(t, np.arange(n) * dt, raw.press)
    cols["ambient_pressure_hPa"] = _quant(
        press_true + bg["off_pressure_hPa"] + rng.normal(0.0, 0.1, k), 0.1
    )
    rh = raw.rh[ti] + bg["off_rh_pct"] + rng.normal(0.0, 0.5, k)
    cols["relative_humidity_pct"] = _quant(np.clip(rh, 0.0, 100.0), 0.1)
    pel = cont(P.R_PEL) + rng.normal(0.0, 0.3, k)
    cols["electric_power_W"] = _quant(np.clip(pel, 0.0, None), 0.1)
    cols["water_flow_setpoint_kg_h"] = np.round(disc(P.R_MSP), 3)
    cols["boiler_on"] = disc(P.R_ON)
    return {name: cols[name] for name in LOG_COLUMNS}


def write_log_csv(columns: dict[str, np.ndarray], path: str | Path) -> None:
    """Write ``columns`` as CSV: header, ``time_s`` first, an empty field for NaN."""
    names = ["time_s", *[c for c in LOG_COLUMNS if c in columns and c != "time_s"]]
    names += [c for c in columns if c not in names]
    n = len(columns["time_s"])
    texts = []
    for name in names:
        v = np.asarray(columns[name])
        if v.dtype.kind in "US O".replace(" ", ""):
            s = v.astype(str)
            s = np.where(s == "nan", "", s)
        else:
            v = v.astype(float)
            d = _DECIMALS.get(name, 6)
            s = np.char.mod(f"%.{d}f", v)
            s = np.where(np.isfinite(v), s, "")
        if len(s) != n:
            raise ValueError(f"column {name} has {len(s)} values, time_s has {n}")
        texts.append(s)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(names) + "\n")
        rows = zip(*texts, strict=True)
        fh.write("".join(",".join(r) + "\n" for r in rows))
