"""How much the low-pass filter and decimation inflate least-squares variances.

The torques are low-pass filtered (zero-phase) before decimation (filtering.py), so the measurement
noise of neighbouring decimated samples stays correlated, and the textbook least-squares covariance,
which assumes independent rows, understates the uncertainty. For white noise through the known
filter, the variance of a mean over decimated samples grows by the sum of the filtered noise's
autocorrelation at multiples of the decimation step; standard errors are scaled by its square root.
(The Newey-West estimate from the residuals was tried: with ~500 samples and 61 parameters it gave
1.19x against the filter's exact 1.53x, and the synthetic-truth test failed with it.)
"""
from __future__ import annotations

import numpy as np
from scipy.signal import butter, sosfiltfilt


def filtered_noise_inflation(cutoff_hz: float, fs: float, order: int, decimation: int) -> float:
    """Variance factor of a mean over decimated samples of zero-phase Butterworth-filtered white
    noise, relative to independent samples (1 without filtering)."""
    half = int(20 * fs / cutoff_hz) + 10 * decimation         # the impulse response has died out
    impulse = np.zeros(2 * half + 1)
    impulse[half] = 1.0
    h = sosfiltfilt(butter(order, cutoff_hz, fs=fs, output="sos"), impulse)
    r = np.correlate(h, h, "full")
    lags = r[len(r) // 2::decimation]
    return float((lags[0] + 2.0 * lags[1:].sum()) / lags[0])
