"""Sim-to-real gap diagnosis: where the model departs from the lab, which unmodelled effect
causes it, and how far the gap shrinks on held-out data once that effect is added.

1. *Calibrate* the one-node model on the calibration log only (Section 3.1).
2. *Where*: simulate both logs with their measured inputs; per segment (start-up, test,
   stand-by) and signal (water inside the boiler, forward sensor, heat to water, flue gas,
   cumulative fuel) the Table 4 metrics and the residual's structure (Theil bias/variance/
   covariance shares, lag at the cross-correlation peak, autocorrelation at 1 min), ranked
   by RMSD over the signal's noise scale.
3. *Which*: each candidate of :mod:`hil_client.analysis.augment` is fitted on the
   calibration log by maximum likelihood, every signal with its own Gaussian error variance
   and offset (the sensors' fixed errors), on rows 2 min apart (to thin the residuals'
   autocorrelation); the fuel enters as the balance's loss per 10-min block, each with an
   error of 0.01 kg (two readings of 0.02-kg resolution) plus 2 % (the calorific value's
   uncertainty). Candidates
   are compared by
   BIC = sum_s n log(RSS_s / n + floor_s^2) + k log(N), with an error floor per signal
   (:data:`ERROR_FLOOR`).
   Rule: an effect is named when its BIC is lower than the unaugmented model's by more than
   :data:`BIC_THRESHOLD` (10, "very strong" evidence, Kass & Raftery 1995) *and* it lowers
   the RMSD of at least one signal by :data:`MIN_SHRINK` (10 %); otherwise ``none``.
   Confidence: the share of the winner's BIC gain not matched by the runner-up,
   (dBIC_1 - max(dBIC_2, 0)) / dBIC_1; for ``none``, 1 - dBIC_1 / threshold (clipped).
4. *How far*: the chosen augmentation, frozen, predicts the validation log; RMSD before and
   after where the gap lies (the segment and signal it improved most on calibration) and
   over the whole log.

The model predictions include the response times of the bench's sensors
(:data:`SENSOR_TAU_S`, from their data sheets), so a thermowell's lag is not mistaken for
an effect.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import minimize

from hil_client.analysis.augment import EFFECTS, PARAMETERS, first_order_lag, pipe_sensor
from hil_client.analysis.balance import heat_to_water_kW
from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.logio import LabLog, fill_gaps
from hil_client.analysis.metrics import (
    autocorrelation,
    lag_at_peak,
    table4_metrics,
    theil_shares,
)
from hil_client.analysis.phases import Phases
from rig_emulator.model import pack_constants
from rig_emulator.model.layout import Y_FUEL, Y_T_BOILER, Y_T_FG
from rig_emulator.model.params import BoilerParams
from rig_emulator.model.simulate import simulate

SIGNALS = (
    "boiler_water_temp_C",
    "water_out_temp_C",
    "heat_to_water_kW",
    "flue_gas_temp_C",
    "fuel_cum_kg",
)
OFFSET_SIGNALS = ("boiler_water_temp_C", "water_out_temp_C", "flue_gas_temp_C")
#: Response times of the bench's sensors [s] (thermowells, duct probe; data sheets).
SENSOR_TAU_S = {
    "boiler_water_temp_C": 10.0,
    "water_out_temp_C": 4.0,
    "water_in_temp_C": 4.0,
    "flue_gas_temp_C": 8.0,
}
#: Error floors [signal units]: what the lab cannot resolve or trust anyway (sensor accuracy,
#: the fuel's calorific value known to about 2 %); added to each signal's error variance so
#: that a tiny but very regular difference in a quiet signal is not taken as an effect.
ERROR_FLOOR = {
    "boiler_water_temp_C": 0.3,
    "water_out_temp_C": 0.3,
    "heat_to_water_kW": 0.1,
    "flue_gas_temp_C": 1.0,
    "fuel_cum_kg": 1.0,  # per-block residuals are already divided by their own error
}
FUEL_BLOCK_ERROR = (0.01, 0.02)  # [kg], [-]: two readings of 0.02-kg resolution, calorific value
BIC_THRESHOLD = 10.0
MIN_SHRINK = 0.10
THIN_S = 120.0
FUEL_BLOCK_S = 600.0
SEGMENTS = ("start_up", "test", "stand_by")


@dataclass
class Case:
    """One log prepared for the diagnosis: lab signals, inputs and the base model run."""

    log: LabLog
    phases: Phases
    params: BoilerParams
    t: np.ndarray
    dt: np.ndarray
    flow: np.ndarray
    t_in: np.ndarray
    room: np.ndarray
    enabled: np.ndarray
    lab: dict[str, np.ndarray]
    base: np.ndarray
    thin: np.ndarray
    segments: dict[str, np.ndarray]
    blocks: np.ndarray  # row indices of the fuel blocks' edges
    _sims: dict[float, np.ndarray] = field(default_factory=dict)

    def run(self, delay_s: float = 0.0) -> np.ndarray:
        """Model outputs with the heat release delayed after each switch-on (cached)."""
        key = round(delay_s, 1)
        if key not in self._sims:
            t = self.t
            on = self.enabled
            if key > 0:
                on = on & (t > self.phases.t0 + key)
            y = simulate(
                pack_constants(self.params),
                self.lab["boiler_water_temp_C"][0],
                self.dt,
                self.flow,
                self.t_in,
                self.room,
                on,
            )
            self._sims[key] = y
        return self._sims[key]


def prepare(log: LabLog, phases: Phases, params: BoilerParams) -> Case:
    t = log.t
    dt = np.diff(t, prepend=t[0] - (t[1] - t[0] if len(t) > 1 else 1.0))
    flow = np.nan_to_num(fill_gaps(log["water_flow_kg_h"], t))
    t_in = fill_gaps(log["water_in_temp_C"], t)
    room = fill_gaps(log["room_temp_C"], t)
    out_t = fill_gaps(log["water_out_temp_C"], t)
    mass = fill_gaps(log["balance_mass_kg"], t)
    lab = {
        "boiler_water_temp_C": fill_gaps(log["boiler_water_temp_C"], t),
        "water_out_temp_C": out_t,
        "heat_to_water_kW": heat_to_water_kW(flow, t_in, out_t),
        "flue_gas_temp_C": fill_gaps(log["flue_gas_temp_C"], t),
        "fuel_cum_kg": mass[0] - mass,
    }
    enabled = (t > phases.t0) & (t <= phases.t2)
    thin_idx = np.unique(np.searchsorted(t, np.arange(t[0], t[-1], THIN_S)))
    thin = np.zeros(len(t), bool)
    thin[thin_idx] = True
    blocks = np.unique(np.searchsorted(t, np.arange(t[0], t[-1], FUEL_BLOCK_S)))
    segments = {
        "start_up": phases.mask("start_up", t),
        "test": phases.mask("test", t),
        "stand_by": phases.mask("cooling_1", t) | phases.mask("cooling_2", t),
    }
    case = Case(
        log,
        phases,
        params,
        t,
        dt,
        flow,
        t_in,
        room,
        enabled,
        lab,
        np.empty((0, 0)),
        thin,
        segments,
        blocks,
    )
    case.base = case.run(0.0)
    return case


def predict(case: Case, effect: str, theta: dict[str, float]) -> dict[str, np.ndarray]:
    """The augmented model's prediction of every lab signal (sensor lags included)."""
    y = case.run(theta.get("delay_s", 0.0) if effect == "ignition_delay" else 0.0)
    node = y[:, Y_T_BOILER]
    water = node
    if effect == "body_heat_diffusion":
        water = first_order_lag(node, case.dt, theta["tau_body_s"])
    forward = water
    if effect == "outlet_sensor_pipe":
        forward = pipe_sensor(
            water, case.flow, case.room, case.dt, theta["pipe_kg"], theta["tau_loss_s"]
        )
    t_fg = y[:, Y_T_FG]
    if effect == "flue_gas_lag":
        t_fg = first_order_lag(t_fg, case.dt, theta["tau_fg_s"])
    fuel_y = case.base if effect == "ignition_delay" else y  # the auger feeds from switch-on
    per_kg = case.params.fuel.as_received_per_kg_dry - case.params.fuel.ash
    fuel = np.cumsum(fuel_y[:, Y_FUEL] * case.dt) / 3600.0 * per_kg
    fuel -= fuel[0]
    if effect == "fuel_energy_bias":
        fuel = fuel * (1.0 + theta["bias"])
    sensed_water = first_order_lag(water, case.dt, SENSOR_TAU_S["boiler_water_temp_C"])
    sensed_forward = first_order_lag(forward, case.dt, SENSOR_TAU_S["water_out_temp_C"])
    return {
        "boiler_water_temp_C": sensed_water,
        "water_out_temp_C": sensed_forward,
        "heat_to_water_kW": heat_to_water_kW(case.flow, case.t_in, forward),
        "flue_gas_temp_C": first_order_lag(t_fg, case.dt, SENSOR_TAU_S["flue_gas_temp_C"]),
        "fuel_cum_kg": fuel,
    }


def _residuals(case: Case, pred: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    """Lab minus model per signal on the masked rows; temperatures less their mean (the
    sensor's fixed error); the fuel as per-block losses divided by their error."""
    out = {}
    for s in SIGNALS:
        if s == "fuel_cum_kg":
            edges = case.blocks[mask[case.blocks]]
            lab = np.diff(case.lab[s][edges])
            model = np.diff(pred[s][edges])
            a, r = FUEL_BLOCK_ERROR
            out[s] = (lab - model) / (a + r * np.abs(lab))
            continue
        res = case.lab[s][mask] - pred[s][mask]
        if s in OFFSET_SIGNALS:
            res = res - np.mean(res)
        out[s] = res
    return out


def bic(case: Case, effect: str, theta: dict[str, float]) -> float:
    res = _residuals(case, predict(case, effect, theta), case.thin)
    n_total = sum(len(r) for r in res.values())
    kparams = len(PARAMETERS[effect]) + len(OFFSET_SIGNALS)
    total = kparams * math.log(n_total)
    for name, r in res.items():
        if len(r):
            total += len(r) * math.log(float(np.dot(r, r)) / len(r) + ERROR_FLOOR[name] ** 2)
    return total


@dataclass
class CandidateFit:
    effect: str
    params: dict[str, float]
    bic: float


def fit_candidate(case: Case, effect: str) -> CandidateFit:
    """Maximum-likelihood parameters of one augmentation on the calibration case."""
    spec = PARAMETERS[effect]
    if not spec:
        return CandidateFit(effect, {}, bic(case, effect, {}))
    names = list(spec)
    lo = np.array([spec[n][1] for n in names])
    hi = np.array([spec[n][2] for n in names])
    log_scale = np.array([spec[n][1] > 0 for n in names])

    def to_theta(z: np.ndarray) -> dict[str, float]:
        v = [math.exp(min(zi, 700.0)) if ls else zi for zi, ls in zip(z, log_scale, strict=True)]
        return dict(zip(names, np.clip(v, lo, hi).tolist(), strict=True))

    def objective(z: np.ndarray) -> float:
        return bic(case, effect, to_theta(z))

    best: tuple[float, np.ndarray] | None = None
    # a coarse grid over the parameter box, then a local search from its best point
    grids = [
        np.geomspace(lo[i], hi[i], 7) if log_scale[i] else np.linspace(lo[i], hi[i], 13)
        for i in range(len(names))
    ]
    for point in np.array(np.meshgrid(*grids)).reshape(len(names), -1).T:
        z = np.array([math.log(v) if ls else v for v, ls in zip(point, log_scale, strict=True)])
        value = objective(z)
        if best is None or value < best[0]:
            best = (value, z)
    assert best is not None
    result = minimize(
        objective,
        best[1],
        method="Nelder-Mead",
        options={"xatol": 1e-3, "fatol": 1e-3, "maxiter": 120},
    )
    z = result.x if result.fun < best[0] else best[1]
    theta = to_theta(z)
    return CandidateFit(effect, theta, bic(case, effect, theta))


def where(case: Case, pred: dict[str, np.ndarray]) -> list[dict]:
    """Per segment and signal: Table 4 metrics and residual structure, ranked."""
    rows = []
    for seg, mask in case.segments.items():
        if mask.sum() < 30:
            continue
        for s in SIGNALS:
            model, lab = pred[s][mask], case.lab[s][mask]
            resid = lab - model
            scale = float(np.std(case.lab[s])) or 1.0
            m = table4_metrics(model, lab)
            bias, var, cov = theil_shares(model, lab)
            rows.append(
                {
                    "phase": seg,
                    "signal": s,
                    "rmsd": m["rmsd"],
                    "max_dev": m["max_dev"],
                    "r": m["r"],
                    "normalised_rmsd": m["rmsd"] / scale,
                    "bias_share": bias,
                    "variance_share": var,
                    "covariance_share": cov,
                    "lag_s": lag_at_peak(model, lab, float(np.median(case.dt)), 600.0),
                    "residual_autocorrelation_60s": autocorrelation(resid, 60),
                }
            )
    rows.sort(key=lambda r: -r["normalised_rmsd"])
    return rows


def _rmsd_by(case: Case, pred: dict[str, np.ndarray]) -> dict[tuple[str, str], float]:
    out = {}
    for seg, mask in [*case.segments.items(), ("overall", np.ones(len(case.t), bool))]:
        res = _residuals(case, pred, mask)
        # the fuel in kg: the cumulative consumption's deviation over the segment
        idx = np.flatnonzero(mask)
        fuel = (case.lab["fuel_cum_kg"] - pred["fuel_cum_kg"])[idx]
        res["fuel_cum_kg"] = fuel - fuel[0] if len(fuel) else fuel
        for s, r in res.items():
            out[(seg, s)] = float(np.sqrt(np.mean(r**2))) if len(r) else math.nan
    return out


def diagnose(
    cal_log: LabLog, cal_phases: Phases, val_log: LabLog, val_phases: Phases, doc: BoilerParams
) -> dict:
    """The whole diagnosis (see the module docstring); returns the diagnosis.json content."""
    calibration = calibrate([(cal_log, cal_phases)], doc)
    # Pstart from the start-up fuel rate presumes the nominal calorific value, the very thing
    # a fuel-energy bias changes: the diagnosis keeps the documented start-up power
    params = replace(calibration.params, p_start_kW=doc.p_start_kW)
    cal = prepare(cal_log, cal_phases, params)
    val = prepare(val_log, val_phases, params)
    base_fit = fit_candidate(cal, "none")
    fits = {e: fit_candidate(cal, e) for e in EFFECTS}
    base_cal, base_val = predict(cal, "none", {}), predict(val, "none", {})
    cal_before, val_before = _rmsd_by(cal, base_cal), _rmsd_by(val, base_val)
    candidates = []
    for effect, fit in fits.items():
        cal_after = _rmsd_by(cal, predict(cal, effect, fit.params))
        val_after = _rmsd_by(val, predict(val, effect, fit.params))
        gains = {
            key: (cal_before[key] - cal_after[key]) / cal_before[key]
            for key in cal_before
            if key[0] != "overall" and cal_before[key] > 0
        }
        key = max(gains, key=gains.get)
        candidates.append(
            {
                "effect": effect,
                "params": fit.params,
                "score": base_fit.bic - fit.bic,
                "bic": fit.bic,
                "best_gain": gains[key],
                "phase": key[0],
                "signal": key[1],
                "calibration_rmsd_before": cal_before[key],
                "calibration_rmsd_after": cal_after[key],
                "validation_rmsd_before": val_before[key],
                "validation_rmsd_after": val_after[key],
                "validation_overall_rmsd_before": val_before[("overall", key[1])],
                "validation_overall_rmsd_after": val_after[("overall", key[1])],
            }
        )
    candidates.sort(key=lambda c: -c["score"])
    best = candidates[0]
    second = candidates[1]["score"] if len(candidates) > 1 else 0.0
    clear = best["score"] > BIC_THRESHOLD and best["best_gain"] >= MIN_SHRINK
    if clear:
        effect = best["effect"]
        confidence = (best["score"] - max(second, 0.0)) / best["score"]
    else:
        effect = "none"
        confidence = 1.0 - max(best["score"], 0.0) / BIC_THRESHOLD
    confidence = float(min(max(confidence, 0.0), 1.0))
    chosen = best if clear else None
    shrinkage = None
    if chosen is not None:
        before, after = chosen["validation_rmsd_before"], chosen["validation_rmsd_after"]
        shrinkage = {
            "signal": chosen["signal"],
            "phase": chosen["phase"],
            "validation_rmsd_before": before,
            "validation_rmsd_after": after,
            "shrink_pct": 100.0 * (before - after) / before if before > 0 else 0.0,
            "overall_validation_rmsd_before": chosen["validation_overall_rmsd_before"],
            "overall_validation_rmsd_after": chosen["validation_overall_rmsd_after"],
        }
    return {
        "effect": effect,
        "confidence": confidence,
        "rule": (
            f"BIC gain over the unaugmented model > {BIC_THRESHOLD:g} and RMSD of one "
            f"signal lowered by >= {MIN_SHRINK:.0%} on the calibration log"
        ),
        "where": where(val, base_val)[:12],
        "where_calibration": where(cal, base_cal)[:12],
        "candidates": candidates,
        "shrinkage": shrinkage,
        "calibrated": {key: f.value for key, f in calibration.fitted.items()},
        "_series": {"cal": cal, "val": val, "fits": fits},
    }
