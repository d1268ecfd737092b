"""Agreement metrics between a model series and a lab series (Table 4 of the paper and the
residual structure used by the gap diagnosis)."""

from __future__ import annotations

import math

import numpy as np


def max_deviation(model: np.ndarray, lab: np.ndarray) -> float:
    """Largest absolute difference."""
    return float(np.max(np.abs(model - lab))) if len(model) else math.nan


def rmsd(model: np.ndarray, lab: np.ndarray) -> float:
    """Root-mean-square deviation."""
    return float(np.sqrt(np.mean((model - lab) ** 2))) if len(model) else math.nan


def correlation(model: np.ndarray, lab: np.ndarray) -> float:
    """Pearson correlation coefficient (NaN if either series is constant)."""
    if len(model) < 2 or np.std(model) == 0 or np.std(lab) == 0:
        return math.nan
    return float(np.corrcoef(model, lab)[0, 1])


def theil_shares(model: np.ndarray, lab: np.ndarray) -> tuple[float, float, float]:
    """(bias, variance, covariance) shares of the mean squared deviation (Theil 1966):
    MSD = (mean_m - mean_l)^2 + (sd_m - sd_l)^2 + 2 (1 - r) sd_m sd_l; shares sum to 1."""
    msd = float(np.mean((model - lab) ** 2))
    if msd == 0 or len(model) < 2:
        return math.nan, math.nan, math.nan
    sm, sl = float(np.std(model)), float(np.std(lab))
    r = correlation(model, lab)
    r = 0.0 if math.isnan(r) else r
    bias = (float(np.mean(model)) - float(np.mean(lab))) ** 2 / msd
    variance = (sm - sl) ** 2 / msd
    return bias, variance, max(1.0 - bias - variance, 0.0)


def lag_at_peak(model: np.ndarray, lab: np.ndarray, dt_s: float, max_lag_s: float = 900.0) -> float:
    """Lag [s] at the peak of the cross-correlation of the de-meaned series: positive when
    the lab follows the model late. The products are summed for every lag at once by FFT
    (zero-padded, so not circular), O(n log n) for a day-long 1-s log."""
    a = model - np.mean(model)
    b = lab - np.mean(lab)
    n = len(a)
    max_lag = min(int(max_lag_s / dt_s), n // 2)
    if max_lag < 1 or np.std(a) == 0 or np.std(b) == 0:
        return math.nan
    size = 1 << int(2 * n - 1).bit_length()
    summed = np.fft.irfft(np.conj(np.fft.rfft(a, size)) * np.fft.rfft(b, size), size)
    lags = np.arange(-max_lag, max_lag + 1)
    # mean product over the overlap: no bias towards small lags
    products = summed[lags % size] / (n - np.abs(lags))
    return float(lags[int(np.argmax(products))]) * dt_s


def autocorrelation(residual: np.ndarray, lag: int = 60) -> float:
    """Autocorrelation of the residual at ``lag`` rows (near 1: structured, near 0: noise)."""
    r = residual - np.mean(residual)
    if len(r) <= lag or np.dot(r, r) == 0:
        return math.nan
    return float(np.dot(r[:-lag], r[lag:]) / np.dot(r, r))


def table4_metrics(model: np.ndarray, lab: np.ndarray) -> dict[str, float]:
    """Maximum deviation, correlation coefficient and RMSD (Table 4)."""
    return {
        "max_dev": max_deviation(model, lab),
        "r": correlation(model, lab),
        "rmsd": rmsd(model, lab),
        "n": len(model),
    }
