"""Monte-Carlo studies on the fleet engine (docs/fleet.md, "Monte-Carlo studies on the cluster"): each
repetition draws from its own child seed, so a run on a Dask LocalCluster of 2 worker processes gives
exactly (==, not within a tolerance) the numbers of the serial run, and repetition k does not depend on
how many repetitions there are."""
import sys

import numpy as np
import pytest

pytest.importorskip("dask.distributed")   # the [fleet] extra; the [test] extra installs it (never skipped in CI)

import cloudpickle  # noqa: E402  (a dask dependency)
from dask.distributed import LocalCluster  # noqa: E402

from laser_psd_cases import DELTA_TRUE, MOUNT, exact_readings, joints, robot  # noqa: E402
from robocal.model.robot import load_urdf  # noqa: E402
from robocal.systems.laser_psd.monte_carlo import offset_monte_carlo  # noqa: E402
from robocal.systems.stewart import fit_machines  # noqa: E402
from robocal.systems.stewart import modes as sm  # noqa: E402
from robocal.testing import monte_carlo  # noqa: E402

# the workers cannot import this test module (or laser_psd_cases): send their functions by value
cloudpickle.register_pickle_by_value(sys.modules[__name__])
cloudpickle.register_pickle_by_value(sys.modules["laser_psd_cases"])
STEWART = load_urdf(__file__.rsplit("/tests/", 1)[0] + "/urdf/stewart_6_6.urdf")
TOOL = sm.Tool(length=0.2, tip_radius=0.003)


@pytest.fixture(scope="module")
def scheduler():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


def draws(rng):
    return rng.normal(size=3)


def test_helper_maps_a_trial_over_child_seeds_the_same_on_the_cluster(scheduler):
    serial = monte_carlo(draws, 4, seed=7)
    expected = [np.random.default_rng(s).normal(size=3) for s in np.random.SeedSequence(7).spawn(4)]
    assert all(np.array_equal(a, b) for a, b in zip(serial, expected))
    assert all(np.array_equal(a, b) for a, b in zip(serial, monte_carlo(draws, 4, seed=7, scheduler=scheduler)))
    # repetition k is the same in a shorter study; another seed gives other draws; no two repetitions alike
    assert all(np.array_equal(a, b) for a, b in zip(serial, monte_carlo(draws, 2, seed=7)))
    assert not np.array_equal(serial[0], monte_carlo(draws, 1, seed=8)[0])
    assert len({tuple(d) for d in serial}) == 4


def test_helper_runs_a_synthetic_truth_trial_on_a_local_cluster_of_two_workers():
    # workers=2 starts its own LocalCluster (the path `--workers 2` takes)
    def trial(rng):
        return float(rng.standard_normal(50).mean())
    assert monte_carlo(trial, 3, seed=1, workers=2) == monte_carlo(trial, 3, seed=1)


def test_laser_psd_monte_carlo_is_identical_on_the_cluster(scheduler):
    args = (robot(), joints(), exact_readings("three_fans"), MOUNT, DELTA_TRUE, np.radians(0.0005), 3)
    serial = offset_monte_carlo(*args, trials=3, seed=5)
    spread = offset_monte_carlo(*args, trials=3, seed=5, scheduler=scheduler)
    assert np.array_equal(serial.errors, spread.errors) and np.array_equal(serial.predicted_sd, spread.predicted_sd)
    assert np.array_equal(offset_monte_carlo(*args, trials=2, seed=5).errors, serial.errors[:2])
    # the trials differ (noise of 0.0005 deg per read moves every offset by ~1e-6 rad, far above round-off)
    assert np.all(np.abs(serial.errors[0] - serial.errors[1]) > 1e-10)


def test_stewart_mode_study_is_identical_on_the_cluster(scheduler):
    def twelve_poses(study):
        return study.full_poses(12)
    serial = fit_machines(STEWART, TOOL, twelve_poses, "free", 2, seed=3)
    assert fit_machines(STEWART, TOOL, twelve_poses, "free", 2, seed=3, scheduler=scheduler) == serial
    before = fit_machines(STEWART, TOOL, None, "free", 2, seed=3, scheduler=scheduler)
    assert before == fit_machines(STEWART, TOOL, None, "free", 2, seed=3)
    # two different machines, each fitted far below its error before calibration (1 mm parameter errors
    # give mm at the tip; 1 um noise on 12 poses gives a few um, docs/stewart_calibration.md)
    assert serial[0] != serial[1] and all(rank == 42 for _, rank, _, _ in serial)
    assert all(after < 1e-4 < b for (after, *_), (b, *_) in zip(serial, before))
