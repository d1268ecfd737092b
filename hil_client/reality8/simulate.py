"""One simulated lab log: background + optional effect -> kernel -> instruments -> columns."""

from __future__ import annotations

import numpy as np

from .effects import apply_effect, validate
from .kernel import SIGNAL_NAMES, run_kernel
from .plant import build_params, to_array
from .protocol import TESTS, max_duration_s, sequence_arrays
from .sensors import measure, sample_times
from .series import density_series, room_series


def run_plant(
    boiler: dict,
    test: str,
    *,
    background: dict,
    effect: str | None,
    form: str | None,
    strength: float,
    seed: int,
) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """The true 1 s signals (columns ``SIGNAL_NAMES``), events t0..t4 and the parameters."""
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    validate(effect, form, strength)
    params = build_params(boiler, background)
    apply_effect(params, effect, form, float(strength))
    n = max_duration_s(test)
    rng = np.random.default_rng([int(seed), 8, 1])
    room = room_series(rng, background, n)
    dens = density_series(rng, background, n)
    _, start, dur, l0, l1 = sequence_arrays(test)
    sig, ev = run_kernel(to_array(params), room, dens, start, dur, l0, l1)
    return sig, ev, params


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
    """Simulate one lab log of ``test`` ("stationary" | "load_cycle"); see the package doc."""
    if test not in TESTS:
        raise ValueError(f"unknown test {test!r}; expected one of {TESTS}")
    validate(effect, form, strength)
    if not (isinstance(sample_s, int | float) and 1.0 <= float(sample_s) <= 10.0):
        raise ValueError(f"sample_s must be within 1-10 s, got {sample_s!r}")
    sig, ev, _params = run_plant(
        boiler, test, background=background, effect=effect, form=form,
        strength=strength, seed=seed,
    )  # fmt: skip
    rng = np.random.default_rng([int(seed), 8, 2])
    t_end = float(sig[-1, SIGNAL_NAMES.index("time")])
    t = sample_times(rng, t_end, float(sample_s), bool(jitter))
    names, *_ = sequence_arrays(test)
    cols = measure(sig, t, rng, background, background["hopper_kg"], names)
    meta = {
        "boiler": boiler.get("name"),
        "test": test,
        "effect": effect,
        "form": form,
        "strength": float(strength),
        "seed": int(seed),
        "sample_s": float(sample_s),
        "jitter": bool(jitter),
        "t0_s": float(ev[0]),
        "t1_s": float(ev[1]),
        "t2_s": float(ev[2]),
        "t3_s": float(ev[3]),
        "t4_s": float(ev[4]),
        "background": dict(background),
        "fuel_burnt_kg": float(sig[:, SIGNAL_NAMES.index("m_burn")].sum()),
    }
    return cols, meta
