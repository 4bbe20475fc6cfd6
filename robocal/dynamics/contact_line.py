"""The contact line F = k (x - x_c) of a stiff contact, fitted by running least squares, with the
standard deviation of the force it predicts.

The samples are (x, F): x the tool position along the path from the measured joints (exact to the
encoders), F a noisy force estimate. Positions are taken relative to the first sample, so the sums
stay well conditioned at micrometre spans. With sample noise sigma, the force predicted at x* has the
ordinary least-squares standard deviation sigma sqrt(1/n + (x* - x_mean)^2 / S_xx).
"""
from __future__ import annotations

import numpy as np

from robocal.errors import InputError


class ContactLine:
    """Running least-squares fit of F = k (x - x_ref) + b over the samples added so far."""

    def __init__(self):
        self._sums = np.zeros(5)           # n, sum dx, sum F, sum dx^2, sum dx F  (dx = x - x_ref)
        self._resid = 0.0                  # running sum F^2 for the residual
        self.x_ref: float | None = None
        self.f_min, self.f_max = np.inf, -np.inf

    @property
    def samples(self) -> int:
        return int(self._sums[0])

    def add(self, x: float, force: float) -> None:
        if not (np.isfinite(x) and np.isfinite(force)):
            raise InputError("contact-line sample must be finite", field="force")
        if self.x_ref is None:
            self.x_ref = float(x)
        dx = float(x) - self.x_ref
        self._sums += (1.0, dx, force, dx * dx, dx * force)
        self._resid += force * force
        self.f_min, self.f_max = min(self.f_min, force), max(self.f_max, force)

    def coefficients(self) -> tuple[float, float] | None:
        """(k N/m, b N at x_ref), or None with fewer than two distinct positions or k <= 0."""
        n, sx, sf, sxx, sxf = self._sums
        det = n * sxx - sx * sx
        if n < 2 or det <= 1e-30 * max(n * sxx, 1e-300):
            return None
        k = (n * sxf - sx * sf) / det
        return (float(k), float((sf - k * sx) / n)) if k > 0 else None

    def force_at(self, x: float) -> float:
        k, b = self.coefficients()
        return k * (float(x) - self.x_ref) + b

    def position_of(self, force: float) -> float:
        """The position where the line reaches `force`."""
        k, b = self.coefficients()
        return self.x_ref + (float(force) - b) / k

    def residual_std(self) -> float:
        """Standard deviation of the samples about the line (n - 2 degrees of freedom; nan for n < 3)."""
        n, sx, sf, sxx, sxf = self._sums
        line = self.coefficients()
        if n < 3 or line is None:
            return float("nan")
        k, b = line
        # sum (F - k dx - b)^2 expanded in the running sums
        rss = self._resid - 2 * k * sxf - 2 * b * sf + k * k * sxx + 2 * k * b * sx + n * b * b
        return float(np.sqrt(max(rss, 0.0) / (n - 2)))

    def prediction_std(self, x: float, sigma: float) -> float:
        """Standard deviation of the line's force at position x for sample noise sigma N."""
        n, sx, _, sxx, _ = self._sums
        sxx_c = sxx - sx * sx / n if n else 0.0
        if n < 2 or sxx_c <= 0:
            return float("inf")
        dx = float(x) - self.x_ref - sx / n
        return float(sigma * np.sqrt(1.0 / n + dx * dx / sxx_c))
