"""Slow random processes of the plant (room drift, pellet bulk density), one value per second."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def ar1(white: np.ndarray, tau_s: float, sd: float) -> np.ndarray:
    """Stationary AR(1) series at 1 s: x_k = a x_(k-1) + sd sqrt(1 - a^2) e_k, a = exp(-1/tau)."""
    a = math.exp(-1.0 / tau_s)
    b = sd * math.sqrt(1.0 - a * a)
    out = np.empty(white.shape[0])
    x = sd * white[0]
    for k in range(white.shape[0]):
        if k > 0:
            x = a * x + b * white[k]
        out[k] = x
    return out


@njit(cache=True)
def delay_lag(x: np.ndarray, delay_s: int, tau_s: float) -> np.ndarray:
    """Gas analyser: transport delay of the heated sample line, then a first-order cell."""
    n = x.shape[0]
    out = np.empty(n)
    a = math.exp(-1.0 / tau_s)
    y = x[0]
    for k in range(n):
        u = x[max(k - delay_s, 0)]
        y = u + (y - u) * a
        out[k] = y
    return out


def room_series(rng: np.random.Generator, bg: dict, n: int) -> np.ndarray:
    """Room temperature: base + slow (h) swing + small AR(1) wander, C."""
    t = np.arange(n, dtype=float)
    swing = bg["room_drift_K"] * np.sin(
        2 * np.pi * t / (bg["room_period_h"] * 3600.0) + bg["room_phase"]
    )
    return bg["room_C"] + swing + ar1(rng.standard_normal(n), 900.0, 0.1)


def density_series(rng: np.random.Generator, bg: dict, n: int) -> np.ndarray:
    """Relative bulk density of the pellets the auger moves (1 = calibration), >= 0.8."""
    x = 1.0 + ar1(rng.standard_normal(n), bg["density_tau_s"], bg["density_sd"])
    return np.clip(x, 0.8, 1.2)
