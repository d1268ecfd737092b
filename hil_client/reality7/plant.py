"""simulate_log: the reality7 plant on the Wieselburg bench, and its lab-log CSV.

Python side: parameters from the boiler file (CONTRACT section 2) and the background, the test
schedule (protocol YAML), the numba kernel, then the instruments' offsets, noise, quantisation
and gaps, and the acquisition times.
"""

from __future__ import annotations

import csv
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from . import kernel as K
from .fuel import RHO_H2O, RHO_N2, RHO_O2, Fuel, fuel_from_boiler
from .quirks import check_effect

#: Lab-log columns of CONTRACT section 3 ("Lab log (CSV)"), in its order, up to boiler_on.
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
PHASES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
STRING_COLUMNS = ("phase", "sequence")
CP_W = K.CP_W

_DEFINITIONS = Path(__file__).resolve().parents[1] / "protocol" / "definitions"


def _hms(text: str) -> int:
    h, m, s = (int(x) for x in str(text).split(":"))
    return 3600 * h + 60 * m + s


def load_schedule(test: str) -> dict:
    """The test schedule (hil_client/protocol/definitions/<test>.yaml, read as a data file)."""
    if test not in ("stationary", "load_cycle"):
        raise ValueError(f"unknown test {test!r}; expected 'stationary' or 'load_cycle'")
    with open(_DEFINITIONS / f"{test}.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


def effect_fuel(fuel: Fuel, effect: int, form: int, s: float) -> Fuel:
    """The fuel_energy_bias forms: change the lot's composition and HHV (paper Table 1)."""
    if effect != 5 or s == 0.0:
        return fuel
    if form == 0:  # bark_contaminated_lot: bark is ash- and water-rich, lower HHV (dry)
        ash = fuel.ash + 0.03 * s
        k = (1.0 - ash) / (1.0 - fuel.ash)
        return replace(
            fuel,
            hhv_dry=fuel.hhv_dry * (1.0 - 0.09 * s),
            c=fuel.c * k,
            h=fuel.h * k,
            o=fuel.o * k,
            n=fuel.n * k,
            s=fuel.s * k,
            ash=ash,
            moisture=fuel.moisture + 0.025 * s,
        )
    # vegetable_oil_binder: oil is C- and H-rich, O-poor: more energy per kg
    return replace(
        fuel,
        hhv_dry=fuel.hhv_dry * (1.0 + 0.08 * s),
        c=fuel.c + 0.04 * s,
        h=fuel.h + 0.012 * s,
        o=fuel.o - 0.052 * s,
    )


def _gas_wcp(fuel: Fuel, md: float, v_air: float) -> float:
    """Heat-capacity flow of the flue gas [kW/K] (same formulas as the kernel)."""
    v_co2 = 1.866 * fuel.c * md
    v_n2 = 0.79 * v_air + 0.8 * fuel.n * md
    v_o2 = max(0.21 * v_air - 0.21 * fuel.air_min * md, 0.0)
    m_dry = K.RHO_CO2 * v_co2 + RHO_N2 * v_n2 + RHO_O2 * v_o2 + K.RHO_SO2 * 0.7 * fuel.s * md
    m_vap = RHO_H2O * fuel.v_h2o * md
    return (m_dry * K.CP_G + m_vap * K.CP_V) / 3600.0


def build_params(
    boiler: dict, schedule: dict, bg: dict, effect: int, form: int, s: float
) -> K.KParams:
    """All kernel parameters of one case."""
    fuel0 = fuel_from_boiler(boiler)
    fuel = replace(fuel0, hhv_dry=fuel0.hhv_dry * bg["hhv_scale"], moisture=bg["moisture"])
    fuel = effect_fuel(fuel, effect, form, s)
    p_nom = float(boiler["p_nom_kW"])
    p_max = float(boiler["p_max_kW"])
    p_min = float(boiler["p_min_kW"])
    sc = p_nom / 12.0
    lhv_ctrl = fuel0.lhv_dry
    md_ref = p_max * 3600.0 / lhv_ctrl
    lam_a = float(boiler["fac_a_lambda"]) * bg["lam_a_scale"]
    lam_b = float(boiler["fac_b_lambda_h_kg"]) * bg["lam_b_scale"]
    lam_ref = min(max(lam_a + lam_b * md_ref, 1.25), 6.0)
    air_ref = lam_ref * fuel.air_min * md_ref
    w_ref = _gas_wcp(fuel, md_ref, air_ref)
    # exchanger: NTU such that the flue gas leaves at T_in + dTnom at the reference firing
    # (the paper's Eq. 8 at nominal flow fixes the level; the law off that point is ours)
    t_set = 70.0 + bg["t_set_offset_K"]
    ua_sw = bg["ua_sw_kW_K"]
    t_s_ref = t_set + p_nom / ua_sw
    q_rel = md_ref * fuel.hhv_dry / 3600.0
    q_lat = RHO_H2O * fuel.v_h2o * md_ref * 2442.0 / 3600.0
    t_ad = 22.0 + (q_rel * 0.9998 - q_lat) / w_ref
    t_fg_ref = max(55.0 + float(boiler["dt_nom_K"]) * bg["dt_fg_scale"], t_s_ref + 5.0)
    ntu_ref = math.log((t_ad - t_s_ref) / (t_fg_ref - t_s_ref))
    ua_diff = max(float(boiler["ua_amb_off_W_K"]) - float(boiler["ua_amb_on_W_K"]), 0.1)
    v_idle = ua_diff * 1e-3 * bg["ua_idle_scale"] * 3600.0 / (1.288 * K.CP_G)
    su = schedule["start_up"]
    pre = schedule["preheat"]
    c1 = schedule["cooling_1"]
    seqs = schedule["test_sequence"]["sequences"]
    first = seqs[0]["load_pct"]
    su_load = float(first[0] if isinstance(first, list) else first)
    flow_nom = p_nom * 3600.0 / (CP_W * float(schedule.get("flow_spread_K", 15)))
    pel_min = float(boiler["p_el_min_W"])
    e_fields = {
        "pocket_tau": 40.0,
        "pocket_beta": 0.25,
        "m_extra": 0.3 if (effect == 2 and form == 0) else 0.8,
    }
    vals = dict(
        c_w=float(boiler["vol_water_m3"]) * 985.0 * CP_W * bg["cap_water_scale"],
        c_s=float(boiler["c_therm_kJ_K"]) * bg["cap_steel_scale"],
        ua_sw=ua_sw,
        ua_env=float(boiler["ua_amb_on_W_K"]) * 1e-3 * bg["ua_env_scale"],
        v_idle=v_idle,
        ua_nc=bg["ua_nc_W_K"] * 1e-3,
        m_pipe=0.25,
        ua_pipe=0.1e-3,
        t_set=t_set,
        t_off=85.0 + bg["t_off_offset_K"],
        t_on=55.0 + bg["t_on_offset_K"],
        ctrl_off=bg["ctrl_sensor_offset_K"],
        ctrl_tau=bg["ctrl_sensor_tau_s"],
        kp=bg["kp_scale"] * (p_max - p_min) / 8.0,
        ti=bg["ti_s"],
        slew=bg["slew_pct_min"] / 100.0 * p_max / 60.0,
        min_off=bg["min_off_s"],
        p_min=p_min,
        p_max=p_max * bg["p_max_real_frac"],
        p_start=float(boiler["p_start_kW"]),
        lhv_ctrl=lhv_ctrl,
        w_ctrl=fuel0.moisture,
        lam_a=lam_a,
        lam_b=lam_b,
        trim_tau=bg["o2_trim_tau_s"],
        prepurge=bg["prepurge_s"],
        ign_kw=bg["igniter_W"] * 1e-3,
        ign_ref=bg["ign_ref_C"],
        ign_rise=620.0 * bg["igniter_W"] / 320.0,
        charge=bg["charge_kg"],
        tau_bed=bg["tau_bed_s"],
        spread=bg["spread_s"],
        ramp=bg["ramp_s"],
        start_hold=bg["start_hold_s"],
        postpurge=bg["postpurge_s"],
        air_purge=0.8 * air_ref,
        air_ign=0.3 * air_ref,
        air_post=0.5 * air_ref,
        aug_max=1.6 * p_max * 3600.0 / fuel0.lhv_ar,
        bulk_ratio=bg["bulk_density_ratio"],
        aug_period=float(round(bg["auger_period_s"])),
        ign_timeout=360.0,
        pause_period=bg["grate_pause_period_s"],
        pause_s=bg["grate_pause_s"],
        pel_min=pel_min,
        pel_max=float(boiler["p_el_max_W"]),
        pel_off=float(boiler["p_el_off_W"]),
        hhv=fuel.hhv_dry,
        fc=fuel.c,
        fh=fuel.h,
        fo=fuel.o,
        fn=fuel.n,
        fs=fuel.s,
        fash=fuel.ash,
        fw=fuel.moisture,
        fan_sigma=bg["fan_sigma"],
        fan_tau=bg["fan_tau_s"],
        burn_sigma=bg["burn_sigma"],
        burn_tau=bg["burn_tau_s"],
        co_base=bg["co_base_ppm"],
        md_ref=md_ref,
        ntu_ref=ntu_ref,
        w_ref=w_ref,
        ntu_exp=bg["ntu_exponent"],
        fouling0=bg["fouling0"],
        fouling_per_kg=bg["fouling_per_kg"],
        clean_eff=bg["clean_eff"],
        cool_max=bg["bench_cool_max_frac"] * p_nom,
        heat_max=bg["bench_heat_max_frac"] * p_nom,
        bench_kp=bg["bench_kp_frac"] * p_nom,
        bench_ti=bg["bench_ti_s"],
        valve_tau=bg["bench_valve_tau_s"],
        c_loop=bg["bench_loop_kg"] * CP_W,
        dist=bg["bench_dist_frac"] * p_nom,
        flow_tau=bg["flow_tau_s"],
        m_rp=1.0,
        ua_loop=0.02,
        ua_rp=0.5e-3,
        tau_t_in=bg["tau_t_in_s"],
        tau_t_out=bg["tau_t_out_s"],
        tau_t_boiler=bg["tau_t_boiler_s"],
        tau_t_fg=bg["tau_t_fg_s"],
        tau_ch=15.0,
        o2_delay=float(round(bg["o2_delay_s"])),
        o2_tau=bg["o2_tau_s"],
        duct_area=math.pi / 4.0 * bg["duct_diam_m"] ** 2,
        p_amb=bg["pressure_hPa"],
        flow_nom=flow_nom,
        pre_t=float(pre["temperature_C"]),
        pre_tol=float(pre["tolerance_K"]),
        pre_hold=float(pre["hold_s"]),
        pre_load=float(pre["load_pct"]),
        pre_max=float(pre["max_duration_s"]),
        init_dev=bg["init_dev_K"],
        su_ret=float(su["return_setpoint_C"]),
        su_window=float(su["t1_window_s"]),
        su_rise=float(su["t1_max_rise_K_min"]),
        su_min=float(su["min_duration_s"]),
        su_max=float(su["max_duration_s"]),
        su_load=su_load,
        test_ret=float(schedule["test_sequence"]["return_setpoint_C"]),
        c1_load=float(c1["load_pct"]),
        c1_ret=float(c1["return_setpoint_C"]),
        c1_until=float(c1["until_forward_C"]),
        c1_max=float(c1["max_duration_s"]),
        c2_after=float(schedule["cooling_2"]["until_after_t2_s"]),
        eff=float(effect),
        form=float(form),
        s=float(s),
        cap_door=35.0 * sc,
        door_share=0.3,
        door_tau=900.0,
        cap_ring=6.0 * sc,
        ring_share=0.25,
        ring_k=6.0e-12 * sc,
        cap_valve=1.0,
        ua_valve_w=0.03,
        ua_valve_r=0.002,
        ign_fan_factor=2.6,
        spread_extra=150.0,
        burnout_factor=1.5,
        cap_ins=8.0 * sc,
        ntu_ins=1.0,
        k_ins=1.5e-11 * sc,
        cap_pl=8.0 * sc,
        ntu_pl=1.2,
        ua_pl_s=0.002 * sc,
        **e_fields,
    )
    return K.KParams(**{f: float(vals[f]) for f in K.KP_FIELDS})


def _sequences(schedule: dict) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    names, dur, l0, l1 = [], [], [], []
    for seq in schedule["test_sequence"]["sequences"]:
        load = seq["load_pct"]
        a, b = (load[0], load[1]) if isinstance(load, list) else (load, load)
        names.append(str(seq["name"]))
        dur.append(_hms(seq["duration"]))
        l0.append(float(a))
        l1.append(float(b))
    return names, np.array(dur, np.int64), np.array(l0), np.array(l1)


def run_case(
    boiler: dict,
    test: str,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
) -> tuple[np.ndarray, tuple[int, ...], K.KParams, list[str]]:
    """Run the kernel; return the per-second table, (t0..t4) in s, params and sequence names."""
    code, fcode, s = check_effect(effect, form, strength)
    schedule = load_schedule(test)
    kp = build_params(boiler, schedule, background, code, fcode, s)
    names, dur, l0, l1 = _sequences(schedule)
    n_max = int(kp.pre_max + kp.su_max + dur.sum() + kp.c1_max + kp.c2_after + 10)
    rng = np.random.default_rng([int(seed), 7])
    noise = rng.standard_normal((n_max, 3))
    t = np.arange(n_max, dtype=float)
    bg = background
    room = bg["room_mean_C"] + bg["room_amp_C"] * np.sin(
        2.0 * math.pi * t / (3600.0 * bg["room_period_h"]) + bg["room_phase"]
    )
    out = np.zeros((n_max, K.NCOL))
    n, t0, t1, t2, t3, t4 = K.run_kernel(kp, dur, l0, l1, noise, room, out)
    return out[:n], (t0, t1, t2, t3, t4), kp, names


def _quant(x: np.ndarray, q: float) -> np.ndarray:
    return np.round(x / q) * q


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
    """One lab log of the reality7 plant: columns of CONTRACT section 3 and a meta dict."""
    if not (1.0 <= float(sample_s) <= 10.0):
        raise ValueError(f"sample_s must be within 1..10 s, got {sample_s!r}")
    table, times, kp, names = run_case(boiler, test, background, effect, form, strength, seed)
    n = table.shape[0]
    bg = background
    rng = np.random.default_rng([int(seed), 11])
    # acquisition times
    t_end = float(n - 1)
    if jitter:
        steps = sample_s * (1.0 + rng.uniform(-0.2, 0.2, int(t_end / sample_s / 0.8) + 2))
        ts = np.concatenate(([0.0], np.cumsum(steps)))
        ts = np.round(ts[ts <= t_end], 3)
    else:
        ts = np.arange(0.0, t_end + 1e-9, float(sample_s))
    m = ts.size
    i0 = np.floor(ts).astype(int)
    i1 = np.minimum(i0 + 1, n - 1)
    fr = ts - i0

    def col(c: int) -> np.ndarray:
        return table[i0, c] * (1.0 - fr) + table[i1, c] * fr

    def nz(sigma: float) -> np.ndarray:
        return rng.normal(0.0, sigma, m)

    cols: dict[str, np.ndarray] = {"time_s": ts}
    ph = table[i0, K.O_PHASE].astype(int)
    seq = table[i0, K.O_SEQ].astype(int)
    cols["phase"] = np.array([PHASES[p] for p in ph], dtype=str)
    cols["sequence"] = np.array(
        [names[q] if q >= 0 else PHASES[p] for p, q in zip(ph, seq, strict=True)], dtype=str
    )
    flow = col(K.O_FLOW) * (1.0 + bg["flow_offset_frac"])
    flow = flow + rng.normal(0.0, 1.0, m) * (bg["flow_noise_frac"] * flow + 1e-3 * kp.flow_nom)
    flow[np.abs(flow) < 0.005 * kp.flow_nom] = 0.0  # low-flow cut-off of the inductive meter
    cols["water_flow_kg_h"] = _quant(flow, 0.1)
    for name, c, key in (
        ("water_in_temp_C", K.O_TIN, "t_in"),
        ("water_out_temp_C", K.O_TOUT, "t_out"),
        ("boiler_water_temp_C", K.O_TB, "t_boiler"),
    ):
        cols[name] = _quant(col(c) + bg[f"off_{key}_K"] + nz(0.02), 0.01)
    tfg = col(K.O_TFG)
    tfg = tfg + bg["off_t_fg_K"] + bg["fg_class_b_frac"] * (0.3 + 0.005 * np.abs(tfg))
    cols["flue_gas_temp_C"] = _quant(tfg + nz(0.08), 0.1)
    drift = ts / max(t_end, 1.0)
    o2 = col(K.O_O2) + bg["o2_offset_pct"] + bg["o2_drift_pct"] * drift + nz(0.03)
    co2 = col(K.O_CO2) * (1.0 + 0.01 * rng.uniform(-1, 1)) + nz(0.03)
    co = np.maximum(col(K.O_CO) * (1.0 + nz(0.02)) + nz(3.0), 0.0)
    gaps = np.zeros(m, bool)
    for _ in range(int(rng.integers(1, 4))):  # analyser calibration: 3-7 min without data
        a = rng.uniform(0.0, t_end)
        gaps |= (ts >= a) & (ts < a + rng.uniform(180.0, 420.0))
    cols["flue_gas_O2_pct"] = np.where(gaps, np.nan, _quant(np.clip(o2, 0.0, 21.0), 0.01))
    cols["flue_gas_CO2_pct"] = np.where(gaps, np.nan, _quant(np.clip(co2, 0.0, 25.0), 0.01))
    cols["flue_gas_CO_ppm"] = np.where(gaps, np.nan, np.round(co))
    vel = col(K.O_VEL) + nz(0.04)
    cols["flue_gas_velocity_m_s"] = _quant(np.where(vel < 0.75, 0.0, vel), 0.01)  # vortex cut-off
    dr = np.convolve(rng.normal(0.0, 1.0, m + 30), np.ones(30) / 30**0.5 / 6.0, "valid")[:m]
    cols["chimney_draught_Pa"] = _quant(-12.0 + dr, 0.1)
    bal = bg["balance_tare_kg"] + bg["hopper_kg"] + col(K.O_HOPPER)
    bal = bal + bg["balance_drift_kg"] * drift + nz(0.005)
    cols["balance_mass_kg"] = _quant(bal, 0.02)  # 0.02 kg precision (paper Section 2.2)
    cols["room_temp_C"] = _quant(col(K.O_TROOM) + nz(0.05), 0.1)
    cols["ambient_pressure_hPa"] = _quant(
        bg["pressure_hPa"] + 1.5 * np.sin(ts / 20000.0 + bg["room_phase"]) + nz(0.05), 0.1
    )
    cols["relative_humidity_pct"] = _quant(
        bg["humidity_pct"] - 0.8 * (col(K.O_TROOM) - bg["room_mean_C"]) + nz(0.3), 0.1
    )
    cols["electric_power_W"] = _quant(col(K.O_PEL) + nz(0.3), 0.1)
    cols["water_flow_setpoint_kg_h"] = np.round(table[i0, K.O_FLOW_SP], 2)
    cols["boiler_on"] = table[i0, K.O_ON].astype(np.int64)
    code, _fcode, s = check_effect(effect, form, strength)
    t0, t1, t2, t3, t4 = (float(x) for x in times)
    meta = {
        "boiler": str(boiler.get("name", "")),
        "test": test,
        "effect": "none" if code == 0 else effect,
        "form": None if code == 0 else form,
        "strength": float(s),
        "background": dict(background),
        "seed": int(seed),
        "sample_s": float(sample_s),
        "jitter": bool(jitter),
        "t0_s": t0,
        "t1_s": t1,
        "t2_s": t2,
        "t3_s": t3,
        "t4_s": t4,
    }
    return {c: cols[c] for c in COLUMNS}, meta


def write_log_csv(columns: dict[str, np.ndarray], path: str | Path) -> None:
    """Write a lab log as CONTRACT section 3 says: header row, one row per step, a missing
    value as an empty field."""
    names = [c for c in COLUMNS if c in columns] + [c for c in columns if c not in COLUMNS]
    n = len(columns[names[0]])

    def fmt(v: object) -> str:
        if isinstance(v, str | np.str_):
            return str(v)
        if isinstance(v, int | np.integer):
            return str(int(v))
        x = float(v)  # type: ignore[arg-type]
        if not math.isfinite(x):
            return ""
        return f"{x:.10g}"

    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(names)
        arrays = [columns[c] for c in names]
        for i in range(n):
            w.writerow([fmt(a[i]) for a in arrays])
