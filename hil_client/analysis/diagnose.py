"""Sim-to-real gap diagnosis: where the model departs from the lab, which unmodelled effect
causes it, and how far the gap shrinks on held-out data once that effect is added.

Real lab data never equals the model plus one listed effect: the real boiler's controller,
start-up, exchanger and bench differ from Type 869 in ways nobody listed (CONTRACT
section 4). The diagnosis is built to name an effect *through* that background gap:

1. *Calibrate* the one-node model on the calibration log only (Section 3.1).
2. *Replay* both logs through it with their measured inputs and the combustion the lab
   observed as the on/off command (:mod:`hil_client.analysis.replay`), as the paper
   validated the model: the real controller's timing is then not part of the gap.
3. *Where*: per segment (start-up, test, stand-by) and signal the Table 4 metrics and the
   residual's structure, ranked by RMSD over the signal's spread.
4. *Which*: each candidate (:mod:`hil_client.analysis.candidates`) looks only where its
   physics acts and is scored on rows it was not fitted on (blocked cross-validation in
   time within the calibration log), with an error model that respects autocorrelated
   residuals (:mod:`hil_client.analysis.evidence`). It is named only if the held-out
   evidence exceeds :data:`~hil_client.analysis.candidates.Z_MIN` standard errors, it
   removes a real share of the residual where it acts, and its physical fingerprint stands
   beyond what a real boiler's background reaches without it. Of several, the one whose
   fingerprint stands furthest beyond that floor wins (an ignition delay only where no
   other is named: every start-up leaves some pre-feed, :data:`YIELDING`); with none, the
   answer is ``none``, and ``unexplained_gap`` says whether a gap beyond the bench's
   resolution remains.
5. *Confidence*: the share of :data:`BOOTSTRAP` block-bootstrap draws of the evidence
   (held-out blocks, starts and closure hours drawn again with replacement) that give the
   same answer: a verdict that rests on one block gets a low figure; an effect read in n
   separate events (stops, starts, standstills, the closure's loads) gets at most
   (n + 1) / (n + 2) (one stop cannot show that it was typical), and one that may be the
   plant's normal behaviour (an ignition delay as short as a normal start-up's charge,
   where the burner's documented charge was not given: :func:`caveats`) at most 0.5. A
   ``none`` is discounted
   by how close the closest candidate came to being named (its mark and its evidence), and
   is at most 1 / (1 + k) where the log gives k candidates no evidence at all (absence of
   evidence is not evidence of absence), and at most (n + 1) / (n + 2) where the least
   tested candidate was read in n events (a weak store the one stop did not show may show
   in the next).
6. *How far*: the chosen effect, parameters frozen, predicts the validation log, which is
   used for nothing else; RMSD before and after where the effect acts. A shrinkage of zero
   or less is reported as "not confirmed".
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from hil_client.analysis.calibrate import calibrate
from hil_client.analysis.candidates import CANDIDATES
from hil_client.analysis.candidates.base import Z_MIN, Assessment
from hil_client.analysis.logio import LabLog
from hil_client.analysis.metrics import autocorrelation, lag_at_peak, table4_metrics, theil_shares
from hil_client.analysis.phases import Phases
from hil_client.analysis.replay import SIGNALS, Case, prepare
from hil_client.analysis.sanity import suspicious
from rig_emulator.model.params import BoilerParams

BOOTSTRAP = 400
#: A gap the bench resolves, per signal [signal units]: the lower edge of the paper's
#: Table 4 test-phase RMSDs (T 1 K, Q 0.3 kW) and of its flue-gas figures; fuel: 15 balance
#: steps of 0.02 kg.
GAP_FLOOR = {
    "boiler_water_temp_C": 1.0,
    "water_out_temp_C": 1.0,
    "heat_to_water_kW": 0.3,
    "flue_gas_temp_C": 5.0,
    "fuel_cum_kg": 0.3,
}
SEGMENTS = ("start_up", "test", "stand_by")


def _segments(case: Case) -> dict[str, np.ndarray]:
    ph, t = case.phases, case.t
    return {
        "start_up": ph.mask("start_up", t),
        "test": ph.mask("test", t),
        "stand_by": ph.mask("cooling_1", t) | ph.mask("cooling_2", t),
    }


def where(case: Case, pred: dict[str, np.ndarray]) -> list[dict]:
    """Per segment and signal: Table 4 metrics and residual structure, ranked by RMSD over
    the signal's spread."""
    rows = []
    for seg, mask in _segments(case).items():
        if mask.sum() < 30:
            continue
        for s in SIGNALS:
            model, lab = pred[s][mask], case.lab[s][mask]
            if s == "fuel_cum_kg":  # consumption within the segment
                model, lab = model - model[0], lab - lab[0]
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
                    "beyond_floor": m["rmsd"] / GAP_FLOOR[s],
                    "bias_share": bias,
                    "variance_share": var,
                    "covariance_share": cov,
                    "lag_s": lag_at_peak(model, lab, float(np.median(case.dt)), 600.0),
                    "residual_autocorrelation_60s": autocorrelation(resid, 60),
                }
            )
    rows.sort(key=lambda r: -r["normalised_rmsd"])
    return [
        {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()}
        for r in rows
    ]


#: Effects that yield to any other named candidate: fuel the balance loses before the
#: flame is a mark every real start-up leaves to some degree (the ignition charge a burner
#: drops on the grate and lights in its own time: without any listed effect the diagnosis
#: reads up to 145 s of feed per start on the fourth independent plant and 94-229 s on the
#: fifth), so how far it stands beyond a fixed floor says more about the burner's start-up
#: program than about an unmodelled effect; a body, pipe, flue-gas or fuel mark beyond its
#: floor as well is the better answer.
YIELDING = ("ignition_delay",)


#: The most feed before the flame a normal start-up read without any listed effect [s]:
#: the `none` cases of the first eight independent plants (``gap-benchmark --seed 0`` on
#: each, 2026-11-25) read 0-259 s; a burner that drops its ignition charge on the grate and
#: lights it in its own time has an ignition delay that Type 869 lacks, and a normal one.
#: The ninth plant, written after the bound was set, read 76-262 s without a listed
#: ignition effect (27 of its 29 ignition answers fall within the bound).
NORMAL_CHARGE_MAX_S = 260.0


def caveats(effect: str, params: dict[str, float]) -> list[str]:
    """What the answer cannot tell apart, in words for the report: an ignition delay no
    longer than a normal start-up's charge may be the burner's normal ignition sequence
    rather than a fault or a change, unless the burner's documented charge was given
    (``charge_kg``; without it the diagnosis has no reference for what this burner does
    normally)."""
    delay = params.get("delay_s", math.nan)
    documented = params.get("charge_kg", 0.0) > 0.0
    if effect == "ignition_delay" and delay <= NORMAL_CHARGE_MAX_S and not documented:
        return [
            f"The fuel fed before the flame ({delay:.0f} s of feed per start) is within what "
            f"burners' normal start-ups drop as an ignition charge (up to "
            f"{NORMAL_CHARGE_MAX_S:.0f} s on the eight independently written plants this "
            "diagnosis was tested on): Type 869 lacks it either way, but compare it with "
            "this burner's start-up program before reading it as a fault, or give the "
            "charge its manual documents (hil-client diagnose --ignition-charge-kg), and "
            "only the feed beyond it is read (its confidence is held at even odds at most)."
        ]
    return []


def _answer(
    verdicts: dict[str, tuple[bool, float, str]], assessments: dict[str, Assessment]
) -> str:
    """Of the named candidates, the one whose physical mark stands furthest beyond what a
    real boiler's background reaches without it (:attr:`Assessment.margin`), those in
    :data:`YIELDING` only when no other is named: evidence in standard errors says *that*
    a candidate helps, not which of two helps more, and a long record gives any of them a
    large figure."""
    named = [
        (e not in YIELDING, assessments[e].margin, e) for e, (ok, *_) in verdicts.items() if ok
    ]
    return max(named)[2] if named else "none"


def _closest_miss(assessments: dict[str, Assessment], verdicts: dict) -> float:
    """How close the closest candidate not named came to being named (0-1): the share of
    its fingerprint's floor its mark reached (its margin) times the share of the needed
    held-out evidence it reached; 0 when none came near on both."""
    near = [
        min(max(a.margin, 0.0), 1.0) * min(max(verdicts[e][1], 0.0) / Z_MIN, 1.0)
        for e, a in assessments.items()
        if not verdicts[e][0] and math.isfinite(a.margin) and math.isfinite(verdicts[e][1])
    ]
    return max(near, default=0.0)


def carried_to_next_event(events: int) -> float:
    """How likely an effect read in each of ``events`` separate events (stops, starts) also
    shows in the next one, another log's: Laplace's rule of succession, (n + 1) / (n + 2),
    the posterior mean of a share with a uniform prior after n of n. Resampling blocks
    within one stop cannot say whether that stop was typical; 1 for evidence not read
    event by event."""
    return (events + 1.0) / (events + 2.0) if events > 0 else 1.0


def _confidence(assessments: dict[str, Assessment], answer: str) -> float:
    """Share of block-bootstrap draws that give ``answer`` (see the module docstring), for
    an effect read event by event at most :func:`carried_to_next_event` of its events
    (one stop: 0.67, three: 0.8), and at most 0.5 where a caveat says it may be the plant's
    normal behaviour (:func:`caveats`: two explanations the data cannot tell apart, the
    uniform prior's even odds; over the six held-out plants' seed-0 runs 24 of 88 such
    ignition answers were right); for ``none`` discounted by the closest miss (a candidate
    that shows most of the mark its effect needs and most of the held-out evidence makes
    "nothing listed" a close call, however stable the verdict is under resampling), at
    most 1 / (1 + k) with k candidates the log could not test, and at most what
    :func:`carried_to_next_event` gives the events the least tested candidate was read in
    (a mark absent from one stop is as uncertain to stay absent as one present in one stop
    is to show again)."""
    rng = np.random.default_rng(20150505)
    votes: Counter[str] = Counter()
    for _ in range(BOOTSTRAP):
        verdicts = {}
        for effect, a in assessments.items():
            if a.units:
                idx = rng.integers(0, len(a.units), len(a.units))
                units = [a.units[i] for i in idx]
            else:
                units = a.units
            verdicts[effect] = a.verdict(units)
        votes[_answer(verdicts, assessments)] += 1
    share = votes[answer] / BOOTSTRAP
    if answer != "none":
        # an answer the data cannot tell from a plant's normal behaviour (:func:`caveats`)
        # is one of two explanations with nothing to choose between them: at most even odds
        even = 0.5 if caveats(answer, assessments[answer].params) else 1.0
        return min(share, carried_to_next_event(assessments[answer].events), even)
    verdicts = {effect: a.verdict() for effect, a in assessments.items()}
    share *= 1.0 - _closest_miss(assessments, verdicts)
    # a candidate the log gives no evidence for or against (no start after a quiet balance,
    # no settled stop) is as likely as "nothing listed" (a uniform prior over the answers)
    untested = sum(not a.units for a in assessments.values())
    # a mark absent from n events is no surer to stay absent in the next than one present
    # in n is to show again: the least tested candidate's n limits "nothing listed"
    events = [a.events for a in assessments.values() if a.units and a.events > 0]
    seen_in = carried_to_next_event(min(events)) if events else 1.0
    return min(share, 1.0 / (1.0 + untested), seen_in)


def unexplained(effect: str, shrinkage: dict | None, gap_left: bool) -> bool:
    """Whether a gap beyond the bench's resolution (``gap_left``) remains that no listed
    effect explains out of sample: with ``none``, or with an effect the held-out log does
    not confirm (a shrinkage of zero or less: the stranger's stuck forward sensor made a
    named effect's held-out RMSD 27 times worse, and the answer said no gap was left)."""
    if not gap_left:
        return False
    return effect == "none" or not (shrinkage or {}).get("confirmed", False)


def _finite(x: float) -> float | None:
    return float(x) if x is not None and math.isfinite(x) else None


@dataclass(frozen=True)
class Diagnosis:
    """The result of :func:`diagnose`: what ``diagnosis.json`` holds (:attr:`content`,
    CONTRACT section 4) and the replayed logs the figures draw."""

    content: dict
    calibration: Case
    validation: Case

    @property
    def effect(self) -> str:
        return self.content["effect"]

    @property
    def confidence(self) -> float:
        return self.content["confidence"]

    @property
    def unexplained_gap(self) -> bool:
        return self.content["unexplained_gap"]

    @property
    def where(self) -> list[dict]:
        return self.content["where"]

    @property
    def candidates(self) -> list[dict]:
        return self.content["candidates"]

    @property
    def shrinkage(self) -> dict | None:
        return self.content["shrinkage"]

    @property
    def caveats(self) -> list[str]:
        return self.content["caveats"]


def diagnose(
    cal_log: LabLog,
    cal_phases: Phases,
    val_log: LabLog,
    val_phases: Phases,
    doc: BoilerParams,
    ignition_charge_kg: float = 0.0,
) -> Diagnosis:
    """The whole diagnosis (see the module docstring); ``ignition_charge_kg``: the fuel the
    burner's start-up program feeds before the flame by design, as received (its manual;
    0: not documented), which is not read as an ignition delay."""
    calibration = calibrate([(cal_log, cal_phases)], doc)
    # Pstart from the start-up fuel rate presumes the nominal calorific value, the very thing
    # a fuel-energy bias changes: the diagnosis keeps the documented start-up power
    params = replace(calibration.params, p_start_kW=doc.p_start_kW)
    cal = prepare(cal_log, cal_phases, params, ignition_charge_kg)
    # the bench's sensors as the calibration log shows them: VAL stays held out
    val = prepare(val_log, val_phases, params, ignition_charge_kg, cal.sensor_tau_s)
    assessments = {effect: cand.assess(cal) for effect, cand in CANDIDATES.items()}
    verdicts = {effect: a.verdict() for effect, a in assessments.items()}
    effect = _answer(verdicts, assessments)
    candidates = []
    for name, a in assessments.items():
        named, z, reason = verdicts[name]
        val_before, val_after = CANDIDATES[name].held_out(val, a.params)
        candidates.append(
            {
                "effect": name,
                "params": a.params,
                "score": _finite(z),
                "margin": _finite(a.margin),
                "named": named,
                # what stops a candidate, one test at a time: the held-out evidence alone,
                # and its physical mark against the floor the background reaches
                "evidence_named": a.evidence_named(),
                "mark_named": a.margin >= 1.0,
                "reason": reason,
                "signal": a.signal,
                "phase": a.locus,
                "evidence_units": len(a.units),
                "evidence_events": a.events,
                "calibration_rmsd_before": _finite(a.rmsd_before),
                "calibration_rmsd_after": _finite(a.rmsd_after),
                "validation_rmsd_before": _finite(val_before),
                "validation_rmsd_after": _finite(val_after),
            }
        )
    candidates.sort(key=lambda c: -(c["score"] or 0.0))
    shrinkage = None
    if effect != "none":
        chosen = next(c for c in candidates if c["effect"] == effect)
        before, after = chosen["validation_rmsd_before"], chosen["validation_rmsd_after"]
        shrink = 100.0 * (before - after) / before if before and after is not None else None
        shrinkage = {
            "signal": chosen["signal"],
            "phase": chosen["phase"],
            "validation_rmsd_before": before,
            "validation_rmsd_after": after,
            "shrink_pct": shrink,
            "confirmed": shrink is not None and shrink > 0.0,
        }
    base_val, base_cal = val.base_prediction(), cal.base_prediction()
    where_val, where_cal = where(val, base_val), where(cal, base_cal)
    gap_left = any((w["beyond_floor"] or 0.0) > 1.0 for w in where_val + where_cal)
    content = {
        "effect": effect,
        "confidence": _confidence(assessments, effect),
        "unexplained_gap": unexplained(effect, shrinkage, gap_left),
        "rule": (
            "named when its held-out evidence (blocked cross-validation within the "
            "calibration log, AR(1) effective sample size) exceeds 3 standard errors, it "
            "removes at least 20 % of the residual where it acts, and its physical "
            "fingerprint stands beyond what the background reaches; of several, the one "
            "whose fingerprint stands furthest beyond its floor wins"
        ),
        "where": where_val[:12],
        "where_calibration": where_cal[:12],
        "candidates": candidates,
        "shrinkage": shrinkage,
        "caveats": caveats(effect, assessments[effect].params) if effect != "none" else [],
        "ignition_charge_kg": ignition_charge_kg,
        "firing": {"calibration": cal.firing.source, "validation": val.firing.source},
        # where each log's phases came from (the report did not say: a stranger's probe)
        "phases": {"calibration": cal_phases.source, "validation": val_phases.source},
        # the sensors' response times the replay applied, as the calibration log shows them
        "sensor_tau_s": cal.sensor_tau_s,
        "calibrated": {key: f.value for key, f in calibration.fitted.items()},
        "calibration_flags": dict(getattr(calibration, "flags", {})),
        # what in the logs looks like a wrong unit or a broken sensor: read the answer
        # with these in mind
        "log_warnings": [*suspicious(cal_log, doc), *suspicious(val_log, doc)],
        # what the calibration warns of (a log of another boiler size: a stranger's probe)
        "calibration_warnings": list(calibration.warnings),
    }
    return Diagnosis(content, cal, val)
