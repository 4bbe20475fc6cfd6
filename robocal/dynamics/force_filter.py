"""Low-pass filter on the external-force estimate, run once per control tick.

The current-based estimate carries the current noise and, when the tool moves fast, the error of
the differenced acceleration (m (a - a_hat)); both sit well above the few hertz of the force loop.
A Butterworth low-pass (scipy.signal) removes them. Its phase lag enters the loop: the admittance
must be chosen with the filter in the loop model (force_loop.py, docs/dynamics.md).
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from robocal.errors import InputError


class ForceFilter:
    """Butterworth low-pass of `order` with cut-off `cutoff_hz`, sampled every `period` s, applied
    per channel to a vector signal (a wrench (6,), or a scalar). Starts from rest (zero force)."""

    def __init__(self, cutoff_hz: float, period: float = 0.004, order: int = 2):
        if not period > 0 or not 0 < cutoff_hz < 0.5 / period:
            raise InputError(f"filter cut-off must lie in (0, {0.5 / period:g}) Hz, got {cutoff_hz}",
                             field="cutoff_hz")
        if order < 1:
            raise InputError(f"filter order must be >= 1, got {order}", field="order")
        self.cutoff_hz, self.period, self.order = float(cutoff_hz), float(period), int(order)
        self.sos = signal.butter(order, cutoff_hz, fs=1.0 / period, output="sos")
        self._zi = None

    def reset(self) -> None:
        self._zi = None

    def push(self, value) -> np.ndarray:
        """Filter one sample (any shape); returns the filtered sample (same shape)."""
        x = np.atleast_1d(np.asarray(value, float))
        if not np.all(np.isfinite(x)):
            raise InputError("force signal is not finite", field="wrench")
        if self._zi is None:
            self._zi = np.zeros((self.sos.shape[0], 2, x.size))
        y, self._zi = signal.sosfilt(self.sos, x.reshape(1, -1), axis=0, zi=self._zi)
        return y[0].reshape(np.shape(value)) if np.ndim(value) else y[0, 0]

    def response(self, z: np.ndarray) -> np.ndarray:
        """H(z) at complex points z (e.g. e^{j w T})."""
        b, a = signal.sos2tf(self.sos)       # equal lengths: coefficients of z^-k, so polyval in z works
        z = np.asarray(z, complex)
        return np.polyval(b, z) / np.polyval(a, z)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """(A, B, C, D) of the filter, one input and one output."""
        A, B, C, D = signal.tf2ss(*signal.sos2tf(self.sos))
        return A, B[:, 0], C[0], float(D[0, 0])

    def noise_gain(self) -> float:
        """sqrt(sum h_k^2): the ratio of output to input standard deviation for white noise."""
        impulse = signal.sosfilt(self.sos, np.r_[1.0, np.zeros(4095)])
        return float(np.sqrt(np.sum(impulse**2)))
