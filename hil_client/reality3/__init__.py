"""A third, independently written pellet-boiler test-bench plant ("reality3").

Blind "real lab data" for the sim-to-real gap diagnosis: lab logs (CONTRACT section 3) of
the stationary test and the load cycle of Carlon et al. (2015, Applied Energy 138, 505-516),
from a plant written from the paper's physics but deliberately not the one-node Type 869.

API
---
``EFFECT_FORMS`` (effect -> its two forms), ``draw_background(rng, boiler)``,
``simulate_log(boiler, test, *, background, effect, form, strength, seed, sample_s=1.0,
jitter=False) -> (columns, meta)`` and ``write_log_csv(columns, path)``. ``meta`` holds
``t0_s``..``t4_s`` and ``truth`` (effect, form, strength, the form's physical parameters,
the fuel really burnt, fuel fed/burnt, energy totals of Eq. 1-2, number of starts).

Plant (``_kernel.py``, one numba loop at 1 s, 4 thermal sub-steps, explicit Euler)
--------------------------------------------------------------------------------
* Combustion from the fuel composition (Table 1; digest sections 1-2): a fed pellet bed
  (as-received mass) burns at ``bed / tau_bed``, at most at the rate the air allows
  (lambda >= 1.05); dry flue gas, vapour, O2/CO2 (dry vol-%) and CO from stoichiometry with
  the real air flow (fan + natural draught); lambda therefore swings around the fan's target
  (Eq. 9 times a background factor) when the auger pulses or the pellet density fluctuate.
  Losses as in Eq. 1 and 4-6: flue-gas sensible (dry gas + vapour incl. air humidity, above
  the room), latent (fuel water, HHV basis), chemical (CO), unburnt carbon in the ash and a
  small combustion-chamber loss to the room (Q_bc,amb, which the paper set to zero).
* Exchanger: the gas gives heat to the steel with effectiveness 1 - exp(-NTU), NTU = UA/W,
  UA ~ W^n (n 0.85-1.15, transitional flow); UA is calibrated so that at nominal load
  (70/55 C) the flue gas sits at T_w,in + dTnom (Eq. 8) times a background factor. Away from
  nominal the flue-gas temperature follows the exchanger (it falls with load, unlike Eq. 8
  with the small dThx,wat), so efficiency varies with load.
* Thermal body: NOT one node. Steel (share 0.33-0.45 of Ctherm + water, times 0.92-1.12)
  and water with a steel-water time constant of 20-60 s; casing loss UA_on times 0.75-1.3
  from the water; idle losses add natural draught air through the hot boiler, ~ (T-T_room)^1.5
  (Eq. 14-16 made physical), sized to UA_off - UA_on times 0.7-1.4 at 40 K.
* Electricity: standby, controller, fan ~ air^2.5, auger-motor pulses, igniter (250-420 W,
  on for about W_el per start, its heat enters the chamber and the energy balance).

Controller (own design)
-----------------------
PI on the boiler's own forward sensor (offset +-0.4 K, lag 10-30 s) with conditional-
integration anti-windup, output between Pmin and Pmax (documented firing powers, LHV basis;
the auger really delivers 0.985-1.07 times the believed mass, in pulses of 12-40 s with an
Ornstein-Uhlenbeck pellet-density factor of 4-10 %). Start-up: pre-purge (20-60 s, fan),
ignition (igniter on, a charge of 30-60 g per 12 kW fed, then small top-ups; the bed catches
after 40-110 s, the flame is recognised 10-30 s later), fuel ramp Pmin -> Pstart (60-200 s),
hold at Pstart until the water is 1.5-4 K below the set point or 10-18 min after ignition,
then PI. Shut-off when the own reading exceeds 84-86.5 C after a minimum burn time of
10-20 min; burn-out with post-purge fan (5-15 min) until the bed is empty. Restart when the
true water has fallen to 55-56 C (own reading) after a minimum off time, or after 90-120 min
off below 60 C. At t2 the boiler is switched off the same way.

Bench and test procedures (own scheduler, Section 2.3 / Table 2)
----------------------------------------------------------------
Flow follows the setpoint with a 4-15 s lag and 0.3-1 % ripple; the return is conditioned by
a bench water volume (20-45 L) cooled through a mixing valve (PI, actuator lag and dead band,
capacity 1.5-2.5 Pnom, fluctuating cold side); a heater helps only in preheat. Preheat at
nominal flow holds the mean of supply and return at 45 C until both are within 0.5 K for
60 s (t0, 2-30 min). Start-up at nominal flow, return 55 C, until the flue-gas temperature
rises less than 0.5 K/min over 5 min with the burner firing (t1, 5-120 min). Test: 6 h at
100 % (stationary) or the 8 h load cycle of Table 2 (linear gradients), flow = load * Pnom /
(cp 15 K). t2: boiler off; cooling_1 extracts 20 % of Pnom at 20 % flow (return not below
48-52 C) until the forward reading is 55 C (t3); cooling_2 with the pump off until
t4 = t2 + 8 h. Room 18-28 C with a daily swing and drift, pressure 969-1004 hPa, humidity.

Instruments
-----------
Pt100s with offsets (~0.12 K), drifts, 0.02 K noise, 0.01 K resolution and 3-8 s lags; the
body sensor (15-45 s) also sees a stratification bias +-(0.03-0.12) * (m/m_nom) * (T-T_in);
flue-gas Pt100 class-B offset, lag 15-40 s growing at low gas flow; gas analyser with a
30-90 s sample-line delay and first-order response (O2 8-20 s, CO2 10-25 s, CO 15-30 s),
offset, span and drift errors; vortex velocity (cut-off 0.4 m/s); balance under the hopper
(0.01 or 0.02 kg steps, 2-8 g noise; it loses exactly the fed fuel); flow meter gain error
and noise; power meter. With ``jitter`` the acquisition intervals are uniform in
0.6-1.4 * ``sample_s``; readings are interpolated between internal steps.

Background gap (no effect) vs a one-node Type 869 with the documented parameters (ideal
outlet control, tests/hil_client/reality3/onenode.py), medians (ranges) over 12 backgrounds:
test phase of the stationary test T RMSD 1.4 (0.6-2.2) K, Q RMSD 0.58 (0.25-1.0) kW for
12 kW and 1.3 (0.7-2.2) K, 0.27 (0.12-0.48) kW for 6 kW; load cycle 4.4 (2.6-6.8) K,
0.54 (0.37-0.77) kW for 12 kW and 1.7 (0.9-4.9) K, 0.19 (0.13-0.30) kW for 6 kW (the on/off
timing in the 13 % stage dominates the 12 kW temperature gap). Start-up T RMSD 4-5.5 K (the
real boiler lags: pre-purge, ignition, ramp); stand-by T RMSD 1.5-2.5 K.

Effects and their forms (``_effects.py``; strength s in [0, 1] linear in the parameters)
-------------------------------------------------------------------------------------
* ``body_heat_diffusion``
  - ``radiant_hot_steel``: burner pot / firebox steel (20-70 % of the steel capacity) is
    heated by flame radiation ~ (T_flame^4 - T_steel^4) (10-30 % of the available heat at
    nominal load, falling steeply at part load as the flame cools) and passes it to the water
    through a contact resistance (time constant 3-15 min).
  - ``chamber_jacket_pocket``: a poorly circulated water jacket around the combustion chamber
    (15-45 % of the water) takes 10-30 % of the gas-side surface and gives its heat to the
    main water only by a buoyant plume, exchange ~ dT^(1/3) (1 + m/m_nom), running 8-30 K
    hotter at nominal load.
* ``outlet_sensor_pipe``
  - ``thermowell_bracket``: forward sensor in a thermowell (lag 8-33 s at nominal flow, film
    coefficient ~ flow^0.8, natural convection at zero flow) with a conducting bracket
    (stem error 0.1-0.6 K at 45 K above the room, growing as the flow falls) on a 0.4 L exit
    pipe whose stagnant water relaxes (15 min) towards a point that has lost 4-50 % of
    T_boiler - T_room (pipe loss inside the energy balance).
  - ``laminar_pipe_transit``: the sensor sits at the end of a 0.3-1.5 L exit pipe; the water
    arrives with the laminar (Poiseuille) residence-time distribution in cumulative-volume
    coordinates (transport delay grows as the flow falls), each parcel relaxing for its age
    (time constant 2 h - 20 min) towards a point that has lost 4-50 % of T_boiler - T_room.
* ``ignition_delay``
  - ``failed_first_ignition``: the first attempt of every start never catches; after a
    3-10 min timeout the controller purges (1-2 min) and feeds a second charge (1-2 times the
    normal charge each); the accumulated pile then burns off, air-limited.
  - ``critical_pile_mass``: the bed catches only above a critical mass, 20-220 g per 12 kW
    above the charge, accumulated by ignition top-ups (30 % of the ignition feed); the bed's
    burn-out time constant grows by 30-180 s (the pile after stops burns out longer).
* ``flue_gas_lag``
  - ``turbulator_store``: hot spiral turbulators (20 % of the gas-side surface) store heat
    between gas and tube wall; at nominal load 25-60 % of T_fg - T_steel is due to them and
    their time constant is 3-23 min (longer at part load, convective).
  - ``air_recuperator``: a combustion-air recuperator after the exchanger (gas-side
    effectiveness 0.25-0.60, air side 0.6) with a wall time constant of 3-23 min at nominal
    load; the preheated air returns heat to the flame.
  Both are included when calibrating the exchanger, so the nominal flue-gas temperature
  stays at the background's value; the dynamics (and part-load statics) change.
* ``fuel_energy_bias``
  - ``ash_rich_blend``: a bark-containing blend: 0.8-6 % points more ash, 0.2-1.5 % of the
    organic matter shifted from carbon to oxygen; HHV scaled by the Channiwala-Parikh
    correlation (about -1.3 % to -10 %); stoichiometry, O2/CO2 and CO2 per kg follow.
  - ``load_unburnt_carbon``: char carried into the ash, 1.2-8 % of the fuel energy at the
    maximum burn rate, growing with (burn rate)^1.5; the unburnt carbon takes no oxygen and
    forms no CO2.
  Both make the balance lose more mass per kJ delivered to the water.

Cross-talk that is physical, not a bug: the deeper bed of ``critical_pile_mass`` also burns
out longer after stops (flue gas stays warm, O2 stays below 21 %); the jacket pocket and
the turbulators also absorb heat at start-up; every effect shifts the on/off timing of the
13 % stage a little.

Invariants (tested in tests/hil_client/reality3): every step, fuel heat + igniter = ash +
CO + latent + chamber + flue sensible + casing + pipe + water + storage change (to rounding);
fed = burnt + bed and the balance loses the fed mass; an open-loop run reaches the
algebraic steady state; same seed, same log.
"""

from __future__ import annotations

import numpy as np

from hil_client.reality3 import _params as _P
from hil_client.reality3._background import draw_background
from hil_client.reality3._effects import EFFECT_FORMS, FORM_RANGES
from hil_client.reality3._log import LOG_COLUMNS, simulate_raw, to_columns, write_log_csv

__all__ = [
    "EFFECT_FORMS",
    "FORM_RANGES",
    "LOG_COLUMNS",
    "draw_background",
    "simulate_log",
    "write_log_csv",
]


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
    """Simulate one lab log of ``test`` ("stationary" or "load_cycle") on this plant.

    Returns the lab-log columns (CONTRACT section 3) and a meta dict with the phase marks
    ``t0_s``..``t4_s`` and the truth (effect, form, strength, its physical parameters,
    fuel fed and burnt, energy totals of Eq. 1-2, number of starts).
    """
    raw = simulate_raw(
        boiler,
        test,
        background=background,
        effect=effect,
        form=form,
        strength=strength,
        seed=seed,
    )
    cols = to_columns(raw, background, sample_s, jitter, seed)
    rec, dt = raw.rec, raw.dt
    t0, t1, t2, t3, t4 = raw.marks

    def mj(col: int) -> float:
        return float(rec[:, col].sum() * dt / 1000.0)

    eff = None if effect in (None, "none") else effect
    truth = {
        "plant": "reality3",
        "effect": eff or "none",
        "form": form if eff else None,
        "strength": float(strength) if eff else 0.0,
        "form_params": raw.info["form_params"],
        "fuel": raw.info["fuel"],
        "p_fire_nominal_kW": raw.info["p_fire_nominal_kW"],
        "t_fg_target_C": raw.info["t_fg_target_C"],
        "fuel_fed_kg": float(rec[-1, _P.R_FED]),
        "fuel_burnt_kg": float(rec[-1, _P.R_BURNT]),
        "fuel_on_bed_kg": float(rec[-1, _P.R_BED]),
        "starts": int(raw.starts),
        "energy_MJ": {
            "fuel_hhv": mj(_P.R_QREL),
            "igniter": mj(_P.R_QIGN),
            "water": mj(_P.R_QW),
            "flue_sensible": mj(_P.R_QFG),
            "flue_latent": mj(_P.R_QLAT),
            "flue_chemical": mj(_P.R_QCHEM),
            "ash": mj(_P.R_QASH),
            "chamber_loss": mj(_P.R_QBC),
            "casing_loss": mj(_P.R_QENV),
            "pipe_loss": mj(_P.R_QPIPE),
            "storage_change": float((rec[-1, _P.R_ESTORE] - rec[0, _P.R_ESTORE]) / 1000.0),
        },
    }
    meta = {
        "boiler": boiler.get("name", "unnamed"),
        "test": test,
        "t0_s": float(t0),
        "t1_s": float(t1),
        "t2_s": float(t2),
        "t3_s": float(t3),
        "t4_s": float(t4),
        "sample_s": float(sample_s),
        "jitter": bool(jitter),
        "seed": int(seed),
        "truth": truth,
        "background": background,
    }
    return cols, meta
