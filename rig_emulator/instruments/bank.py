"""Instrument models between the plant and the registers, vectorised over all signals.

Each measured signal passes, in this order: dead time (sample line), first-order lag
(thermowell, analyser cell), then at each update instant a fixed accuracy error drawn once
from the tolerance band, white noise, rounding to the resolution, and the floor of what the
instrument can show (``reading_min``: a vortex meter reads no negative velocity); between
updates the reading is held. With an ideal spec the reading equals the plant value exactly.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from numba import njit

from rig_emulator.instruments.profile import Profile


@njit(cache=True)
def _update(
    x,
    time_s,
    keep,
    lagged,
    error_fraction,
    acc_abs,
    acc_rel,
    noise_sd,
    noise_rel,
    normals,
    resolution,
    reading_min,
    period,
    next_update,
    reading,
):
    """Lag, then (where an update is due) fixed error, noise, rounding, floor; arrays in
    place."""
    for i in range(x.size):
        lagged[i] = x[i] + (lagged[i] - x[i]) * keep[i]
        if time_s + 1e-9 < next_update[i]:
            continue
        v = lagged[i]
        mag = abs(v)
        v += error_fraction[i] * (acc_abs[i] + acc_rel[i] * mag)
        v += normals[i] * (noise_sd[i] + noise_rel[i] * mag)
        if resolution[i] > 0:
            v = np.round(v / resolution[i]) * resolution[i]
        if v < reading_min[i]:  # (a NaN stays NaN)
            v = reading_min[i]
        reading[i] = v
        if period[i] > 0:
            next_update[i] = (np.floor(time_s / period[i]) + 1.0) * period[i]
        else:
            next_update[i] = time_s


class InstrumentBank:
    """Instruments for an ordered list of signals, driven by a seeded random generator."""

    def __init__(self, signals: tuple[str, ...], profile: Profile, seed: int) -> None:
        self.signals = signals
        specs = [profile.spec(name) for name in signals]
        self.ideal = all(spec.ideal for spec in specs)
        self.acc_abs = np.array([s.accuracy_abs for s in specs])
        self.acc_rel = np.array([s.accuracy_rel for s in specs])
        self.noise_sd = np.array([s.noise_sd for s in specs])
        self.noise_rel = np.array([s.noise_rel for s in specs])
        self.resolution = np.array([s.resolution for s in specs])
        # no floor: -inf, which every reading is above
        self.reading_min = np.array(
            [-np.inf if s.reading_min is None else s.reading_min for s in specs]
        )
        self.lag_s = np.array([s.lag_s for s in specs])
        self.delay_s = [s.delay_s for s in specs]
        self.period = np.array([s.update_period_s for s in specs])
        self._keep_dt = -1.0
        self._keep = np.zeros(len(signals))
        self._rng = np.random.default_rng(seed)
        # the fixed error of each instrument: a fraction of its band, uniform in [-1, 1]
        self.error_fraction = self._rng.uniform(-1.0, 1.0, len(signals))
        self._delayed = [i for i, d in enumerate(self.delay_s) if d > 0]
        self._buffers: dict[int, deque[tuple[float, float]]] = {}
        self._lagged: np.ndarray | None = None
        self._reading = np.zeros(len(signals))
        self._next_update = np.zeros(len(signals))

    def reset(self) -> None:
        self._lagged = None
        self._buffers.clear()
        self._next_update[:] = 0.0

    def read(self, true: np.ndarray, time_s: float, dt_s: float) -> np.ndarray:
        """Readings at ``time_s`` after a step of ``dt_s`` with plant values ``true``."""
        if self.ideal:
            return true
        x = true.copy()
        for i in self._delayed:
            buf = self._buffers.setdefault(i, deque())
            buf.append((time_s, float(true[i])))
            cutoff = time_s - self.delay_s[i]
            while len(buf) > 1 and buf[1][0] <= cutoff:
                buf.popleft()
            x[i] = buf[0][1]
        if self._lagged is None:
            self._lagged = x.copy()
        if dt_s != self._keep_dt:  # exact discretisation of the first-order lag
            lag = self.lag_s
            self._keep = np.where(lag > 0, np.exp(-dt_s / np.where(lag > 0, lag, 1.0)), 0.0)
            self._keep_dt = dt_s
        _update(
            x,
            time_s,
            self._keep,
            self._lagged,
            self.error_fraction,
            self.acc_abs,
            self.acc_rel,
            self.noise_sd,
            self.noise_rel,
            self._rng.standard_normal(len(x)),
            self.resolution,
            self.reading_min,
            self.period,
            self._next_update,
            self._reading,
        )
        return self._reading.copy()
