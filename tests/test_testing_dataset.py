"""robocal.testing.assert_reproduces_dataset on the built-in UR5 demo (60 tracker poses, 50 um / 50 urad)."""
from importlib.resources import files

import pytest

from robocal.estimation.calibrate import calibrate
from robocal.workflows.setup import load_config
from robocal.model.urdf_export import export_urdf
from robocal.testing import assert_reproduces_dataset

DEMO = files("robocal.io") / "demo" / "ur5_calibrate.yaml"
SIGMA = 5e-5   # the demo's stated (and simulated) noise, m and rad
# At the fit the 180 length rows (and the 180 angle rows) are ~N(0, sigma) less the fitted directions:
# RMS = sigma sqrt((m - n) / m) <= sigma, and RMS^2 / sigma^2 has a spread of sqrt(2 / 180) = 0.11, so
# RMS < 1.25 sigma holds with > 4 spreads to spare. The largest of 180 |N(0, sigma)| exceeds
# 5 sigma with probability 180 * 5.7e-7 = 1e-4.
RMS = {"length": 1.25 * SIGMA, "angle": 1.25 * SIGMA}
MAX = {"length": 5 * SIGMA, "angle": 5 * SIGMA}


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    setup = load_config(DEMO)
    result = calibrate(setup.problem, setup.options)
    assert result.success
    urdf = export_urdf(setup.robot, result.params, tmp_path_factory.mktemp("cal") / "ur5_calibrated.urdf")
    base = {p.name: p.value for p in result.params if p.kind == "base"}
    return urdf, base


def test_calibrated_urdf_reproduces_the_dataset(calibrated):
    urdf, _ = calibrated
    stats = assert_reproduces_dataset(DEMO, urdf, rms=RMS, max=MAX)
    assert [b.name for b in stats] == ["tracker"]


def test_set_up_values_from_the_result_instead_of_a_fit(calibrated):
    urdf, base = calibrated
    assert_reproduces_dataset(DEMO, urdf, rms=RMS, max=MAX, setup_values=base, fit_setup=False)


def test_the_uncalibrated_model_fails_and_the_message_names_block_and_statistic():
    with pytest.raises(AssertionError) as info:
        assert_reproduces_dataset(DEMO, rms=RMS, max=MAX)
    msg = str(info.value)
    assert "does not reproduce the dataset" in msg
    assert "block 'tracker' (pose, 360 rows): RMS" in msg and "mm > 0.0625 mm" in msg
    assert "block 'tracker' (pose, 360 rows): MAX" in msg


def test_per_block_override_and_angle_only_tolerance(calibrated):
    urdf, _ = calibrated
    # a loose length limit and a too-tight angle limit: only the angle line fails
    with pytest.raises(AssertionError) as info:
        assert_reproduces_dataset(DEMO, urdf, rms=RMS, blocks={"tracker": {"rms": {"length": 1.0, "angle": 1e-6}}})
    msg = str(info.value)
    assert "RMS" in msg and "mrad > 0.001 mrad" in msg and " mm >" not in msg
