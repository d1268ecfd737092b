"""Instrument models between the plant and the registers, vectorised over all signals.

Each measured signal passes, in this order: dead time (sample line), first-order lag
(thermowell, analyser cell), then at each update instant a fixed accuracy error drawn once
from the tolerance band, white noise, and rounding to the resolution; between updates the
reading is held. With an ideal spec the reading equals the plant value exactly.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from rig_emulator.instruments.profile import Profile


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
        self.lag_s = np.array([s.lag_s for s in specs])
        self.delay_s = [s.delay_s for s in specs]
        self.period = np.array([s.update_period_s for s in specs])
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
        else:
            with np.errstate(divide="ignore"):
                keep = np.where(self.lag_s > 0, np.exp(-dt_s / np.maximum(self.lag_s, 1e-300)), 0.0)
            self._lagged = x + (self._lagged - x) * keep
        due = time_s + 1e-9 >= self._next_update
        if due.any():
            lagged = self._lagged
            mag = np.abs(lagged)
            value = lagged + self.error_fraction * (self.acc_abs + self.acc_rel * mag)
            sd = self.noise_sd + self.noise_rel * mag
            value = value + self._rng.standard_normal(len(value)) * sd
            res = self.resolution
            value = np.where(res > 0, np.round(value / np.where(res > 0, res, 1.0)) * res, value)
            self._reading = np.where(due, value, self._reading)
            period = self.period
            self._next_update = np.where(
                due,
                np.where(
                    period > 0,
                    (np.floor(time_s / np.where(period > 0, period, 1.0)) + 1) * period,
                    time_s,
                ),
                self._next_update,
            )
        return self._reading.copy()
