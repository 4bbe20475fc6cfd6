"""Geometric sphere fit and its analytic sensitivity (spec seed-003 acceptance test 5)."""
import numpy as np
import pytest

from robocal.errors import InputError
from robocal.systems.pcmm.machine import cap_directions
from robocal.residuals.sphere_fit import fit_sphere, sphere_fit_sensitivity

C0, R0 = np.array([0.1, -0.2, -0.6]), 0.0137


def test_noise_free_cap_gives_centre_and_radius():
    X = C0 + R0 * cap_directions(9)
    f = fit_sphere(X)
    assert np.abs(f.centre - C0).max() < 1e-13 and abs(f.radius - R0) < 1e-13   # spec 1e-10 mm
    assert f.rms < 1e-15


def test_fit_is_unbiased_far_below_sigma():
    """1000 Monte-Carlo fits with 1 um noise. The bias of a nonlinear LS fit is O(sigma^2 / r) = 7e-11 m;
    the mean over 1000 runs has a standard error of sigma_fit / sqrt(1000), sigma_fit ~ a few sigma on a
    75-deg cap, so |mean error| < 0.5 sigma is ~5 standard errors away from failing by chance."""
    rng = np.random.default_rng(11)
    sigma = 1e-6
    base = C0 + R0 * cap_directions(25)
    err = np.array([np.concatenate([f.centre - C0, [f.radius - R0]])
                    for f in (fit_sphere(base + rng.normal(0, sigma, base.shape)) for _ in range(1000))])
    assert np.abs(err.mean(axis=0)).max() < 0.5 * sigma
    assert err.std(axis=0).max() > 0.1 * sigma          # the noise did reach the fit


def test_too_few_or_coplanar_points_raise():
    with pytest.raises(InputError, match="at least 4"):
        fit_sphere(C0 + R0 * cap_directions(3), source="placement 2, sphere 1")
    ring = np.column_stack([np.cos(np.arange(8)), np.sin(np.arange(8)), np.zeros(8)])
    with pytest.raises(InputError, match="coplanar"):
        fit_sphere(ring)
    X = C0 + R0 * cap_directions(6)
    X[3, 1] = np.nan
    with pytest.raises(InputError, match="row 4"):
        fit_sphere(X)


def test_sensitivity_matches_finite_differences_with_residual():
    rng = np.random.default_rng(12)
    X = C0 + R0 * cap_directions(9) + rng.normal(0, 2e-5, (9, 3))   # noisy: the exact IFT form is needed
    f = fit_sphere(X)
    S = sphere_fit_sensitivity(X, f.centre, f.radius)
    h = 1e-7
    fd = np.zeros_like(S)
    for k in range(X.size):
        d = np.zeros(X.size)
        d[k] = h
        fp, fm = fit_sphere(X + d.reshape(X.shape)), fit_sphere(X - d.reshape(X.shape))
        fd[:, k] = (np.append(fp.centre, fp.radius) - np.append(fm.centre, fm.radius)) / (2 * h)
    assert np.abs(fd - S).max() < 1e-6
