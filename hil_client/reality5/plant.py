"""Plant 5 front end: parameters, protocol, ``simulate_log`` and ``write_log_csv``.

Protocol (hil_client/protocol/definitions/<test>.yaml, Carlon et al. Sec. 2.3, Fig. 3): preheat to
45 C with outside heat and nominal flow; t0 boiler on, return set to 55 C; t1 once the measured
flue-gas temperature (1 min means) rose less than 0.5 K/min over 5 min (armed once the boiler has
reported its burner on for 10 min and the gas has warmed by 0.3 dTn + 5 K); t1..t2 the load
sequence imposed through the flow (m_w = load Pnom / (cp_w 15 K)); t2 boiler off, cooling 1 at
20 % flow until the measured forward temperature reaches 55 C (t3); cooling 2 without flow until
t4 = t2 + 8 h.

Fuel basis: the boiler file gives firing powers on the net basis, so the auger is calibrated as
m_ar,max = k_auger Pmax / LHV_ar with LHV_ar = HHV_dry (1 - w) - dH_vap (8.937 H (1 - w) + w).

Bench (assumptions): the flow follows its set point with a lag and pump ripple; the return is
conditioned from the loop water (which lost heat in the bench piping): a heater (preheat and
start-up only) and a cooler whose valve the load programme pre-positions, so the extraction stays
within [q_min load, q_cool load + q_base] Pnom. Below minimum modulation (13 %) the circuit
therefore heats up and, once the boiler stops, cools in finite time, as in the paper. During the
preheat the operator trims the return until the forward sensor reads 45 C.

Controller (assumptions): stepped PI on its own flow sensor, quantised modulation between
x_min and 1; start: pre-purge, charge fed at full auger rate, igniter until the chamber
thermocouple rises by dT_flame plus a dwell, ramp to Pstart, hold, hand over near 70 C; stops on
overheat (T_stop) or after t_lowstop at minimum above 70 + dT_lowstop (once min_burn is over);
post-purge; restart below 70 - dT_restart or after a demand timer below 60 C.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from .background import EFFECT_FORMS, effect_params, effective_fuel
from .core import COLS, CP_FG, CP_W, DH_VAP, H2O_H, N_NOISE, RHO_AIR, TRUTH, J, Params, run

PROTOCOL_DIR = Path(__file__).resolve().parent.parent / "protocol" / "definitions"
PHASES = ("preheat", "start_up", "test", "cooling_1", "cooling_2")
COLUMNS = ("time_s", "phase", "sequence", *COLS[1:])  # CONTRACT section 3 order
STEP_COLUMNS = ("balance_mass_kg", "water_flow_setpoint_kg_h", "boiler_on")


def lhv_ar(f: dict) -> float:
    """Net calorific value as received [kJ/kg]."""
    w = f["moisture"]
    return f["hhv_dry_kJ_kg"] * (1 - w) - DH_VAP * (H2O_H * f["h"] * (1 - w) + w)


def _hms(s) -> float:
    h, m, sec = (float(v) for v in str(s).split(":"))
    return 3600 * h + 60 * m + sec


def load_protocol(test: str) -> tuple[dict, list[tuple[str, float, float, float]]]:
    if test not in ("stationary", "load_cycle"):
        raise ValueError(f"unknown test {test!r}")
    d = yaml.safe_load((PROTOCOL_DIR / f"{test}.yaml").read_text())
    segs = []
    for sq in d["test_sequence"]["sequences"]:
        lp = sq["load_pct"]
        l0, l1 = (lp, lp) if not isinstance(lp, list) else lp
        segs.append((sq["name"], l0 / 100, l1 / 100, _hms(sq["duration"])))
    return d, segs


# parameter field = background key (same units)
_FROM_BACKGROUND = """
ash_loss=ash_loss duty_max=duty_max t_aug=t_auger_s purge_frac=purge_air_frac
ign_air_frac=ign_air_frac eps_idle=eps_idle tau_bed=tau_bed_s burnout_slow=burnout_slow
flicker=flicker flicker_tau=flicker_tau_s t_light=t_light_s m_charge=m_charge_kg
dT_cc_max=dT_cc_max_K tau_cc=tau_cc_s dT_flame=dT_flame_K co_nom=co_nom_ppm c_s=c_steel_kJ_K
a_x=dT_fg_low foul_amp=foul_amp t_clean=clean_interval_s c_p=pipe_c_kJ_K ctrl_off=ctrl_offset_K
tau_ctrl=tau_ctrl_s t_ctrl=ctrl_period_s db=deadband_K kp=kp ki=ki q_step=mod_step
t_stop=t_stop_C t_demand=t_demand_s dT_lowstop=dT_lowstop_K t_lowstop=t_lowstop_s
min_burn=min_burn_s min_off=min_off_s t_pre=t_prepurge_s t_dwell=t_dwell_s t_ramp=t_ramp_s
t_hold=t_hold_s dT_handover=dT_handover_K t_post=t_postpurge_s p_clean_el=p_clean_W
t_clean_run=t_clean_run_s tau_flow=tau_flow_s flow_ripple=flow_ripple m_loop=loop_mass_kg
tau_cond=tau_cond_s hunt_amp=hunt_amp_K hunt_per=hunt_period_s tau_stag=tau_stagnant_s
hopper=hopper_kg t_room0=t_room_C room_amp=room_amp_K room_phase=room_phase p0=p_amb_hPa
p_amp=p_amp_hPa rh0=rh_pct off_in=off_in_K off_out=off_out_K off_bw=off_bw_K
drift_in=drift_in_K_h drift_out=drift_out_K_h tau_in=tau_in_s tau_out=tau_out_s
tau_bw=tau_bw_s n_wt=noise_wt_K k_pos=k_pos tau_prof=tau_prof_s fg_err=fg_err tau_fg=tau_fg_s
n_fg=noise_fg_K fg_turb=fg_turb_K o2_delay=o2_delay_s o2_tau=o2_tau_s o2_off=o2_off
o2_span=o2_span n_o2=noise_o2 co2_delay=co2_extra_delay_s co2_off=co2_off co2_span=co2_span
co_off=co_off_ppm v_off=v_off v_noise=v_noise v_cut=v_cut draught=draught_Pa bal_off=bal_off_kg
bal_drift=bal_drift_kg_h bal_noise=bal_noise_kg bal_vib=bal_vib_kg room_off=room_off_K
flow_off=flow_off flow_noise=flow_noise pel_noise=pel_noise_W az_period=autozero_period_s
az_len=autozero_len_s az_phase=autozero_phase
"""
_FROM_FUEL = """hhv=hhv_dry_kJ_kg fc=c fh=h fo=o fn=n fs=s residue=residue w_ar=moisture
co2_extra=co2_extra"""
_W_TO_KW = """p_ig=p_ig_W ua_env=ua_env_W_K ua_pl=pipe_ua_loss_W_K ua_pc=pipe_ua_cond_W_K
ua_loop=ua_loop_W_K"""


def build_params(boiler, bg, proto, segs, effect, form, s) -> tuple[Params, dict, dict]:
    """All plant parameters in SI-like units (kW, kJ, kg/s, s, C) for the numba loop."""
    nom = boiler["fuel"]
    fuel = effective_fuel(nom, effect, form, s)
    eff, fcode, e, edesc = effect_params(effect, form, s, boiler, bg)
    pnom, pmax, pmin = boiler["p_nom_kW"], boiler["p_max_kW"], boiler["p_min_kW"]
    w_nom = nom["moisture"]
    r_design = pmax / lhv_ar(nom) * (1 - w_nom)  # kg/s dry, design feed at full load
    feed_ar_max = bg["k_auger"] * pmax / lhv_ar(nom)
    r_max_d = feed_ar_max * (1 - fuel["moisture"])
    air_min = (1.866 * nom["c"] + 5.56 * nom["h"] + 0.7 * nom["s"] - 0.7 * nom["o"]) / 0.21
    x0 = pmin / pmax
    fa, fb = boiler["fac_a_lambda"], boiler["fac_b_lambda_h_kg"]
    lam1 = max((fa + fb * r_design * 3600) * bg["lam_scale_hi"], 1.25)
    lam0 = max((fa + fb * x0 * r_design * 3600) * bg["lam_scale_lo"], lam1)
    lam_b = (lam0 - lam1) / (1 / x0 - 1)
    v1 = air_min * r_design * lam1
    c_w = bg["vol_water_m3"] * 980.0 * CP_W
    ua_sw = bg["c_steel_kJ_K"] / bg["tau_sw_s"]
    ts_nom = 70.0 + pnom / ua_sw
    tr = bg["t_room_C"]
    dtn = (55 + boiler["dt_nom_K"] - (tr + bg["eps_idle"] * (ts_nom - tr))) * bg["dT_fg_scale"]
    pel_max = boiler["p_el_max_W"] * bg["p_el_scale"]
    pel_min = boiler["p_el_min_W"] * bg["p_el_scale"]
    pel_off = boiler["p_el_off_W"]
    p_aug = bg["p_auger_frac"] * (pel_max - pel_off)
    tsq, pre, su, c1 = (proto[k] for k in ("test_sequence", "preheat", "start_up", "cooling_1"))
    v = {f: bg[k] for f, k in (pair.split("=") for pair in _FROM_BACKGROUND.split())}
    v.update({f: fuel[k] for f, k in (pair.split("=") for pair in _FROM_FUEL.split())})
    v.update({f: bg[k] / 1000 for f, k in (pair.split("=") for pair in _W_TO_KW.split())})
    v.update(
        r_aug_ar=feed_ar_max / bg["duty_max"], r_max_d=r_max_d, air_unit=air_min * r_design,
        lam_a=lam1 - lam_b, lam_b=lam_b, m_glow=0.002 * pnom / 12, c_w=c_w, ua_sw=ua_sw,
        v_idle_ref=bg["ua_draught_W_K"] / 1000 / (RHO_AIR * CP_FG * bg["eps_idle"]),
        dTn=max(dtn, 10.0), m_nom=pnom / (CP_W * 15), m_fg_nom=v1 * RHO_AIR + r_max_d * 0.45,
        t_set=tsq["return_setpoint_C"] + proto["flow_spread_K"],
        x_min=x0 * bg["x_min_scale"] / bg["k_auger"], x_start=boiler["p_start_kW"] / pmax,
        t_restart=70.0 - bg["dT_restart_K"], pel_off=pel_off, p_aug_el=p_aug,
        pel_fan0=max(pel_min - pel_off - p_aug * x0 * bg["duty_max"], 2.0),
        pel_fan1=max(pel_max - pel_off - p_aug * bg["duty_max"], 3.0),
        qh_max=bg["q_heat_frac"] * pnom, qc_a=bg["q_cool_load"] * pnom,
        qc_b=bg["q_cool_base"] * pnom, qc_lo=bg["q_cool_min"] * pnom,
        t_init=bg["t_room_C"] + bg["t_init_offset_K"], flue_area=math.pi * bg["flue_d_m"] ** 2 / 4,
        pre_T=pre["temperature_C"], pre_tol=pre["tolerance_K"], pre_hold=pre["hold_s"],
        pre_max=pre["max_duration_s"], pre_load=pre["load_pct"] / 100, su_load=segs[0][1],
        su_ret=su["return_setpoint_C"], su_min=su["min_duration_s"], su_max=su["max_duration_s"],
        su_win=su["t1_window_s"], su_rise=su["t1_max_rise_K_min"],
        test_ret=tsq["return_setpoint_C"], test_len=sum(sg[3] for sg in segs),
        c1_load=c1["load_pct"] / 100, c1_ret=c1["return_setpoint_C"],
        c1_until=c1["until_forward_C"], c1_max=c1["max_duration_s"],
        c2_after=proto["cooling_2"]["until_after_t2_s"], eff=eff, form=fcode,
        e1=e[0], e2=e[1], e3=e[2], e4=e[3], e5=e[4], e6=e[5],
    )  # fmt: skip
    return Params(**{k: float(val) for k, val in v.items()}), fuel, edesc


def _check(test, effect, form, strength):
    if test not in ("stationary", "load_cycle"):
        raise ValueError(f"unknown test {test!r}")
    if effect is not None and effect not in EFFECT_FORMS:
        raise ValueError(f"unknown effect {effect!r}")
    if effect is None and form is not None:
        raise ValueError("a form needs an effect")
    if effect is not None and form is not None and form not in EFFECT_FORMS[effect]:
        raise ValueError(f"unknown form {form!r} for {effect!r}")
    if not 0.0 <= float(strength) <= 1.0:
        raise ValueError("strength must lie in [0, 1]")


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
    """Run one lab test on plant 5; returns (lab-log columns, meta with truth)."""
    if effect == "none":
        effect = None
    _check(test, effect, form, strength)
    if sample_s <= 0:
        raise ValueError("sample_s must be positive")
    if effect is not None and form is None:
        form = EFFECT_FORMS[effect][0]
    proto, segs = load_protocol(test)
    p, fuel, edesc = build_params(boiler, background, proto, segs, effect, form, strength)
    n_max = int(p.pre_max + p.su_max + p.test_len + p.c2_after + 10)
    rng = np.random.default_rng(seed)
    nz = rng.standard_normal((N_NOISE, n_max))
    seg = np.array([[0.0, 0.0, 0.0, 0.0]] * len(segs))
    seg[:, 1:] = [[sg[3], sg[1], sg[2]] for sg in segs]
    seg[1:, 0] = np.cumsum(seg[:-1, 1])
    out, pha, sq, ev = run(
        p, seg[:, 0].copy(), seg[:, 1].copy(), seg[:, 2].copy(), seg[:, 3].copy(), nz, n_max
    )
    cols = _resample(out, pha, sq, [sg[0] for sg in segs], sample_s, jitter, seed)
    truth = {k: out[:, J[k]].copy() for k in TRUTH}
    truth["time_s"] = out[:, 0].copy()
    tq = truth
    i1, i2 = int(ev[1]), int(ev[2])
    meta = {
        "boiler": boiler.get("name", "inline"),
        "test": test,
        "effect": effect,
        "form": form,
        "strength": float(strength),
        "effect_params": edesc,
        "seed": seed,
        "sample_s": sample_s,
        "jitter": jitter,
        "background": dict(background),
        "fuel": fuel,
        "params": p._asdict(),
        **{f"t{k}_s": float(ev[k]) for k in range(5)},
        "totals": {
            "fuel_fed_test_kg": float(out[i1, J["balance_kg"]] - out[i2, J["balance_kg"]]),
            "heat_to_water_test_kWh": float(tq["Q_w_kW"][i1:i2].sum() / 3600),
            "fuel_energy_test_kWh": float(tq["q_in_kW"][i1:i2].sum() / 3600),
            "starts": int(np.sum(np.diff((tq["state"] == 1).astype(int)) == 1)),
        },
        "truth": truth,
    }
    return cols, meta


def _resample(out, pha, sq, seg_names, sample_s, jitter, seed):
    t_end = out[-1, 0]
    tk = np.arange(0.0, t_end + 1e-9, sample_s)
    if jitter:
        rng = np.random.default_rng([seed, 5])
        tk = tk + rng.uniform(-0.15, 0.15, tk.size) * min(sample_s, 1.0)
        keep = rng.random(tk.size) > 0.006
        for start in rng.integers(0, tk.size, max(tk.size // 4000, 1)):  # logger hiccups
            keep[start : start + int(rng.integers(2, 6))] = False
        tk = np.round(np.clip(tk[keep], 0.0, t_end), 3)
    idx = np.clip(np.floor(tk + 1e-9).astype(int), 0, len(out) - 1)
    grid = out[:, 0]
    cols: dict[str, np.ndarray] = {"time_s": tk}
    names = np.array([*seg_names])
    ph = pha[idx]
    cols["phase"] = np.array(PHASES, dtype=object)[ph]
    seqs = np.where(sq[idx] >= 0, names[np.maximum(sq[idx], 0)], cols["phase"].astype(str))
    cols["sequence"] = seqs.astype(object)
    for name in COLUMNS:
        if name in ("time_s", "phase", "sequence"):
            continue
        src = out[:, J[name]]
        cols[name] = src[idx].copy() if name in STEP_COLUMNS else np.interp(tk, grid, src)
    return {k: cols[k] for k in COLUMNS}


def write_log_csv(columns: dict[str, np.ndarray], path) -> None:
    """CSV with a header row, ``time_s`` first, NaN as an empty field."""
    names = ["time_s"] + [k for k in columns if k != "time_s"]
    parts = []
    for k in names:
        a = np.asarray(columns[k])
        if a.dtype.kind in "fc":
            s = np.char.mod("%.6g" if k != "time_s" else "%.3f", a.astype(float)).astype(object)
            s[np.isnan(a.astype(float))] = ""
        elif a.dtype.kind in "iub":
            s = a.astype(int).astype(str).astype(object)
        else:
            s = a.astype(str).astype(object)
        parts.append(s)
    lines = [",".join(names)]
    lines += [",".join(row) for row in zip(*parts, strict=True)]
    Path(path).write_text("\n".join(lines) + "\n")
