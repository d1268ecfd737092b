"""reality4: pellet boiler on a test bench (Carlon et al. 2015 procedures), own physics.

Nodes: steel body + water (+ optional cast-iron section), a pellet bed fed in auger pulses and
burning with a time constant, stoichiometric flue gas, a bench with a lagging mixing valve,
a burner controller (pre-purge, igniter, ramp, hold, PI modulation with quantised steps,
overheat stop / restart, post-purge) and instruments (offsets, noise, lags, O2 line delay).
"""

from __future__ import annotations

import csv
import math

import numpy as np

from hil_client.reality4._loop import PNAMES, run

EFFECT_FORMS: dict[str, tuple[str, ...]] = {
    "body_heat_diffusion": ("limescale_layer", "cast_iron_section"),
    "outlet_sensor_pipe": ("clamp_on_sensor", "long_riser"),
    "ignition_delay": ("clogged_igniter", "cold_retort"),
    "flue_gas_lag": ("soot_fouled_hx", "ceramic_afterburner"),
    "fuel_energy_bias": ("resin_softwood", "worn_auger_co"),
}

# protocol definitions (hil_client/protocol/definitions/*.yaml): durations in s, load fraction
_LOAD_CYCLE = (
    ("peak", 292, 1.00, 1.00),
    ("gradient_100_48", 1560, 1.00, 0.48),
    ("stationary_48", 3015, 0.48, 0.48),
    ("gradient_48_39", 540, 0.48, 0.39),
    ("stationary_39", 4424, 0.39, 0.39),
    ("gradient_39_63", 720, 0.39, 0.63),
    ("stationary_63", 1478, 0.63, 0.63),
    ("gradient_63_30", 1320, 0.63, 0.30),
    ("stationary_30", 3194, 0.30, 0.30),
    ("gradient_30_13", 2040, 0.30, 0.13),
    ("stationary_13", 10217, 0.13, 0.13),
)
_STATIONARY = (("stationary_100", 21600, 1.0, 1.0),)
_PHASES = np.array(["preheat", "start_up", "test", "cooling_1", "cooling_2"])

COLUMNS = [
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
]


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def _fuel_numbers(fuel: dict) -> dict:
    c, h, o, n, s = (float(fuel[k]) for k in ("c", "h", "o", "n", "s"))
    w = float(fuel["moisture"])
    w_dry = w / (1.0 - w)
    return {
        "air_min": (1.866 * c + 5.56 * h + 0.7 * s - 0.7 * o) / 0.21,
        "v_co2": 1.866 * c,
        "v_h2o": 11.1 * h + 1.244 * w_dry,
        "v_n2": 0.8 * n,
        "v_so2": 0.7 * s,
    }


def draw_background(rng: np.random.Generator, boiler: dict) -> dict:
    """A random real boiler and bench around the documentation values (kW, kJ, kg, s)."""
    fuel = boiler["fuel"]
    p_nom = float(boiler["p_nom_kW"])
    hhv_doc = float(fuel["hhv_dry_kJ_kg"])
    w_doc = float(fuel["moisture"])
    lhv_ar = (hhv_doc - 2442.0 * 8.94 * float(fuel["h"])) * (1 - w_doc) - 2442.0 * w_doc
    w = float(np.clip(w_doc + rng.normal(0, 0.005), 0.03, 0.12))
    ign_on_s = _u(rng, 240, 420)
    c_s = float(boiler["c_therm_kJ_K"]) * _u(rng, 0.85, 1.15)
    bg = {
        "p_nom": p_nom,
        "p_max": float(boiler["p_max_kW"]) * _u(rng, 0.96, 1.03),
        "p_min": float(boiler["p_min_kW"]) * _u(rng, 0.95, 1.08),
        "p_start": float(boiler["p_start_kW"]) * _u(rng, 0.93, 1.0),
        "hhv": hhv_doc * (1 + rng.normal(0, 0.006)),
        "lhv_bel": lhv_ar,
        "w": w,
        "ash_ar": float(fuel["ash"]) * _u(rng, 0.8, 1.3) * (1 - w),
        **_fuel_numbers({**fuel, "moisture": w}),
        "lam_a": float(boiler["fac_a_lambda"]) * _u(rng, 0.94, 1.06),
        "lam_b": float(boiler["fac_b_lambda_h_kg"]) * _u(rng, 0.9, 1.1),
        "c_w": float(boiler["vol_water_m3"]) * 977.0 * 4.186 * _u(rng, 0.92, 1.08),
        "c_s": c_s,
        "ua_sw": c_s / _u(rng, 20, 45),
        "ua_on": float(boiler["ua_amb_on_W_K"]) * _u(rng, 0.85, 1.2) / 1000.0,
        "ua_off": float(boiler["ua_amb_off_W_K"]) * _u(rng, 0.85, 1.2) / 1000.0,
        "c_ci": 1.0,
        "ua_ci": 0.0,
        "ci_frac": 0.0,
        "c_fg": (float(boiler["dt_nom_K"]) - 15.0) * _u(rng, 0.92, 1.08),
        "n_fg": _u(rng, 0.55, 0.85),
        "dthx": float(boiler["dt_hx_wat_K"]) * _u(rng, 0.5, 1.5),
        "eff_off": _u(rng, 0.6, 0.85),
        "tau_fg_bg": _u(rng, 12, 25),
        "fg_mode": 0.0,
        "fg_a": 0.0,
        "fg_tau": 1.0,
        "tau_burn": _u(rng, 35, 80),
        "burn_sig": _u(rng, 0.04, 0.09),
        "burn_tau": _u(rng, 200, 900),
        "pulse_kg": _u(rng, 0.003, 0.006),
        "auger_over": 0.0,
        "t_light": _u(rng, 25, 50),
        "retort_tau": 0.0,
        "retort_g0": 1.0,
        "burnout_fac": 1.0,
        "ign_kg": _u(rng, 0.03, 0.06) * p_nom / 6.0,
        "ign_feed_s": _u(rng, 40, 90),
        "p_ign": float(boiler["w_el_Wh"]) * 3.6 / ign_on_s,
        "ign_on_s": ign_on_s,
        "ign_heat": _u(rng, 0.3, 0.6),
        "prepurge_s": _u(rng, 30, 90),
        "ramp_s": _u(rng, 120, 300),
        "hold_s": _u(rng, 600, 900),
        "post_s": _u(rng, 300, 900),
        "t_set": 70.0 + float(rng.choice([-1.0, 1.0])) * _u(rng, 0.8, 2.5),
        "kp": p_nom * _u(rng, 0.06, 0.12),
        "ti": _u(rng, 300, 900),
        "q_step": p_nom * _u(rng, 0.03, 0.08),
        "t_stop": _u(rng, 84, 87),
        "t_restart": _u(rng, 55.5, 60),
        "co0": _u(rng, 40, 150),
        "co_frac": 0.0,
        "pipe_mode": 0.0,
        "pipe_ua": 0.0,
        "pipe_c": 1.5,
        "clamp_beta": 0.0,
        "clamp_tau": 1.0,
        "riser_kg": 0.0,
        "riser_g": 0.0,
        "tau_flow": _u(rng, 5, 15),
        "flow_gain": _u(rng, 0.985, 1.015),
        "tau_valve": _u(rng, 60, 150),
        "valve_sig": _u(rng, 0.1, 0.3),
        "tau_stag": _u(rng, 3000, 8000),
        "room0": _u(rng, 19, 25),
        "room_amp": _u(rng, 0.5, 2.0),
        "room_ph": _u(rng, 0, 1),
        "p_amb0": _u(rng, 970, 1000),
        "rh0": _u(rng, 30, 60),
        "m_bal0": _u(rng, 150, 300),
        "area": math.pi / 4 * (0.08 * math.sqrt(p_nom / 6.0)) ** 2,
        "tau_s_in": _u(rng, 3, 8),
        "tau_s_out": _u(rng, 3, 8),
        "tau_s_bw": _u(rng, 15, 35),
        "tau_s_fg": _u(rng, 8, 15),
        "o2_delay": _u(rng, 20, 60),
        "tau_o2": _u(rng, 6, 12),
        "n_pre": float(int(_u(rng, 900, 1800))),
        "test_total": 0.0,
        "t_w0": 45.0 + float(rng.normal(0, 0.2)),
        "p_el_min": float(boiler["p_el_min_W"]),
        "p_el_max": float(boiler["p_el_max_W"]),
        "p_el_off": float(boiler["p_el_off_W"]),
        # instruments (applied outside the loop)
        "off_in": float(rng.normal(0, 0.1)),
        "off_out": float(rng.normal(0, 0.1)),
        "off_bw": float(rng.normal(0, 0.15)),
        "off_fg": float(rng.normal(0, 0.6)),
        "off_room": float(rng.normal(0, 0.2)),
        "off_o2": float(rng.normal(0, 0.1)),
        "gain_co2": _u(rng, 0.98, 1.02),
        "gain_flow": _u(rng, 0.995, 1.005),
        "bal_step": float(rng.choice([0.01, 0.02])),
        "analyser_gap": bool(rng.random() < 0.5),
    }
    return bg


def effect_params(effect: str | None, form: str | None, s: float, bg: dict) -> dict:
    """Parameter changes of one effect form at strength s in [0, 1]."""
    s = float(np.clip(s, 0.0, 1.0))
    if effect is None or effect == "none":
        return {}
    if form not in EFFECT_FORMS[effect]:
        raise ValueError(f"unknown form {form!r} for {effect!r}")
    if form == "limescale_layer":  # water-side scale: contact resistance, steel runs hot
        return {"ua_sw": bg["c_s"] / (180.0 + 1020.0 * s)}
    if form == "cast_iron_section":  # heavy section heated by the flame, slow conduction
        c_ci = 30.0 + 120.0 * s
        return {"c_ci": c_ci, "ci_frac": 0.25 + 0.35 * s, "ua_ci": c_ci / (400.0 + 2000.0 * s)}
    if form == "clamp_on_sensor":  # sensor clamped on an uninsulated pipe
        return {
            "pipe_mode": 1.0,
            "clamp_beta": 0.01 + 0.03 * s,
            "clamp_tau": 20.0 + 70.0 * s,
            "pipe_ua": (0.15 + 1.2 * s) / 1000.0,
        }
    if form == "long_riser":  # transport delay, heat loss, thermosiphon at zero flow
        return {
            "pipe_mode": 2.0,
            "riser_kg": 0.4 + 1.6 * s,
            "pipe_ua": (0.5 + 1.5 * s) / 1000.0,
            "riser_g": (1.5 - 1.2 * s) / 1000.0,
        }
    if form == "clogged_igniter":  # charge fed on a timer, lights late, burns as a burst
        return {"t_light": bg["t_light"] + 90.0 + 510.0 * s}
    if form == "cold_retort":  # fed fuel smoulders in a cold retort, long burn-out
        return {"retort_tau": 240.0 + 1260.0 * s, "retort_g0": 0.15, "burnout_fac": 1.5 + 2.5 * s}
    if form == "soot_fouled_hx":  # part of the flue-gas excess goes through a slow sooty wall
        return {"fg_mode": 1.0, "fg_a": 0.35 + 0.4 * s, "fg_tau": 180.0 + 900.0 * s}
    if form == "ceramic_afterburner":  # ceramic insert, lag grows as the gas flow falls
        return {"fg_mode": 2.0, "fg_tau": 90.0 + 600.0 * s}
    if form == "resin_softwood":  # resin-rich softwood: more energy per kg than nominal
        return {"hhv": bg["hhv"] * (1.025 + 0.06 * s)}
    if form == "worn_auger_co":  # more mass per pulse, overfed bed, CO losses
        return {"auger_over": 0.05 + 0.2 * s, "co_frac": 0.02 + 0.06 * s}
    raise ValueError(form)


def _lag(x, tau):
    y = np.empty_like(x)
    a = 1.0 / tau
    acc = x[0]
    for i in range(len(x)):
        acc += (x[i] - acc) * a
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
    sample_s: float = 1.0,
    jitter: bool = False,
) -> tuple[dict[str, np.ndarray], dict]:
    if test not in ("stationary", "load_cycle"):
        raise ValueError(test)
    rng = np.random.default_rng(seed)
    sched = _STATIONARY if test == "stationary" else _LOAD_CYCLE
    durs = np.array([d for _, d, _, _ in sched], float)
    par = dict(background)
    par.update(effect_params(effect, form, strength, background))
    par["test_total"] = float(durs.sum())
    n_max = int(par["n_pre"] + 7200 + par["test_total"] + 28800 + 10)
    z = rng.standard_normal((20, n_max))
    p = tuple(float(par[k]) for k in PNAMES)
    out, en, marks = run(
        p,
        np.cumsum(durs),
        np.array([a for _, _, a, _ in sched], float),
        np.array([b for _, _, _, b in sched], float),
        z,
        n_max,
    )
    n = out.shape[1]
    nz = rng.standard_normal((16, n))

    def q(x, res=0.01):
        return np.round(x / res) * res

    flow_h = out[3] * 3600.0
    meas = {
        "water_flow_kg_h": np.where(
            flow_h > 0, flow_h * par["gain_flow"] * (1 + 0.004 * nz[0]), 0.0
        ),
        "water_in_temp_C": q(out[21] + par["off_in"] + 0.02 * nz[1]),
        "water_out_temp_C": q(out[19] + par["off_out"] + 0.02 * nz[2]),
        "boiler_water_temp_C": q(out[20] + par["off_bw"] + 0.03 * nz[3]),
        "flue_gas_temp_C": q(out[18] + par["off_fg"] + 0.1 * nz[4]),
        "flue_gas_O2_pct": np.clip(out[22] + par["off_o2"] + 0.03 * nz[5], 0, 21.5),
        "flue_gas_CO2_pct": np.clip(out[23] * par["gain_co2"] + 0.03 * nz[6], 0, 25),
        "flue_gas_CO_ppm": np.clip(
            _lag(np.roll(out[7], int(par["o2_delay"])), par["tau_o2"]) * (1 + 0.03 * nz[7])
            + 2.0 * nz[8],
            0,
            None,
        ),
        "flue_gas_velocity_m_s": out[8] * (1 + 0.03 * nz[9]) + 0.03 * nz[10],
        "chimney_draught_Pa": -12.0 + 0.4 * nz[11] + 0.5 * (out[13] - 0.5),
        "balance_mass_kg": q(out[9] + 0.003 * nz[12], par["bal_step"]),
        "room_temp_C": q(out[10] + par["off_room"] + 0.03 * nz[13]),
        "ambient_pressure_hPa": out[25] + 0.05 * nz[14],
        "relative_humidity_pct": np.clip(out[26] + 0.3 * nz[15], 5, 95),
        "electric_power_W": out[11] + 0.3 * nz[0],
        "water_flow_setpoint_kg_h": out[12] * 3600.0,
        "boiler_on": out[13],
    }
    v = meas["flue_gas_velocity_m_s"]
    meas["flue_gas_velocity_m_s"] = np.where(v < 0.5, np.nan, v)  # vortex meter drop-out
    if par["analyser_gap"]:  # analyser zero check: CO2 and CO missing for a few minutes
        g0 = int(rng.uniform(0.3, 0.8) * n)
        g1 = g0 + int(rng.uniform(120, 300))
        for k in ("flue_gas_CO2_pct", "flue_gas_CO_ppm"):
            meas[k][g0:g1] = np.nan
    # sampling
    sample_s = float(np.clip(sample_s, 1.0, 10.0))
    if jitter:
        dt = sample_s * rng.uniform(0.6, 1.4, size=int(n / sample_s * 1.2) + 10)
        t = np.concatenate([[0.0], np.cumsum(dt)])
    else:
        t = np.arange(0.0, n, sample_s)
    t = t[t <= n - 1]
    grid = np.arange(n, dtype=float)
    idx = np.floor(t).astype(int)
    cols: dict[str, np.ndarray] = {"time_s": np.round(t, 3)}
    cols["phase"] = _PHASES[out[14, idx].astype(int)]
    names = np.array([s for s, _, _, _ in sched] + ["cooling_1", "cooling_2"])
    seqi = out[15, idx].astype(int)
    ph = out[14, idx].astype(int)
    seq = np.where(ph == 0, "preheat", np.where(ph == 1, "start_up", names[np.clip(seqi, 0, None)]))
    seq = np.where(ph == 3, "cooling_1", np.where(ph == 4, "cooling_2", seq))
    cols["sequence"] = seq.astype(str)
    for k in COLUMNS[3:]:
        x = meas[k]
        if k in ("boiler_on", "water_flow_setpoint_kg_h", "balance_mass_kg"):
            cols[k] = x[idx].astype(float)
        elif np.isnan(x).any():
            y = np.interp(t, grid, np.nan_to_num(x))
            y[np.isnan(x[idx]) | np.isnan(x[np.minimum(idx + 1, n - 1)])] = np.nan
            cols[k] = y
        else:
            cols[k] = np.interp(t, grid, x)
    for k in ("water_in_temp_C", "water_out_temp_C", "boiler_water_temp_C", "flue_gas_temp_C"):
        cols[k] = q(cols[k])
    cols["water_flow_kg_h"] = np.where(
        cols["water_flow_setpoint_kg_h"] == 0, 0.0, cols["water_flow_kg_h"]
    )
    meta = {
        "boiler": boiler.get("name", "inline"),
        "test": test,
        "sample_s": sample_s,
        "jitter": jitter,
        "effect": effect,
        "form": form,
        "strength": float(strength),
        **{f"t{k}_s": float(marks[k]) for k in range(5)},
        "truth": {
            "E_fuel_kJ": float(en[0]),
            "E_igniter_kJ": float(en[1]),
            "E_water_kJ": float(en[2]),
            "E_room_kJ": float(en[3]),
            "E_flue_kJ": float(en[4]),
            "E_storage_kJ": float(en[5]),
            "fed_kg": float(en[6]),
            "burnt_kg": float(en[7]),
            "bed_end_kg": float(en[8]),
            "ash_ar": float(par["ash_ar"]),
            "balance_start_kg": float(out[9, 0]),
            "balance_end_kg": float(out[9, -1]),
            "hhv_dry_true_kJ_kg": float(par["hhv"]),
            "params": {k: float(par[k]) for k in PNAMES},
        },
    }
    return cols, meta


def write_log_csv(columns: dict[str, np.ndarray], path) -> None:
    keys = ["time_s"] + [k for k in columns if k != "time_s"]
    n = len(columns["time_s"])
    with open(path, "w", newline="") as fh:
        wr = csv.writer(fh)
        wr.writerow(keys)
        arrs = [np.asarray(columns[k]) for k in keys]
        for i in range(n):
            row = []
            for a in arrs:
                x = a[i]
                if isinstance(x, (str, np.str_)):
                    row.append(str(x))
                elif x is None or not np.isfinite(x):
                    row.append("")
                else:
                    row.append(f"{float(x):.6g}")
            wr.writerow(row)
