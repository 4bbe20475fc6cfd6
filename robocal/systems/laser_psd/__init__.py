"""Zero-offset self-calibration of an arm with a laser on the flange and a PSD at an unknown point: plans,
simulated acquisition, calibration, Monte-Carlo accuracy (docs/laser_psd.md)."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "simulation": "acquire PSD SimRobot",
    "calibration": "calibrate_laser LaserMount offset_report reading_noise_covariance zero_offset_problem",
    "plans": "multi_fan patent_fan plan_configurations PlannedPose", "monte_carlo": "offset_monte_carlo"})
