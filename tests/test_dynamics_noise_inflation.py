"""The variance inflation of filtered, decimated white noise (robocal.dynamics.serial_correlation)
against a Monte-Carlo of the same filter."""
import numpy as np
from scipy.signal import butter, sosfiltfilt

from robocal.dynamics.serial_correlation import filtered_noise_inflation


def test_inflation_matches_monte_carlo_of_the_filtered_noise():
    fs, cutoff, order, decimation = 100.0, 3.4, 4, 7
    rng = np.random.default_rng(11)
    noise = sosfiltfilt(butter(order, cutoff, fs=fs, output="sos"), rng.normal(size=(2000, 2800)), axis=1)
    samples = noise[:, 200:-200:decimation]          # away from the filter's edges
    means = samples.mean(axis=1)
    measured = means.var() / (samples.var() / samples.shape[1])
    predicted = filtered_noise_inflation(cutoff, fs, order, decimation)
    # 2000 realisations: the variance of the means is known to sqrt(2/1999) = 3.2 %, and the sample
    # variance of the filtered noise to well under that; 4 sd = 13 %
    assert abs(measured / predicted - 1) < 0.13, (measured, predicted)
    assert predicted > 1.5                       # the test is not vacuous: independent rows would give 1


def test_no_inflation_when_decimation_outruns_the_correlation():
    # a cut-off near Nyquist leaves the decimated samples nearly independent
    assert abs(filtered_noise_inflation(45.0, 100.0, 4, 10) - 1.0) < 0.05
