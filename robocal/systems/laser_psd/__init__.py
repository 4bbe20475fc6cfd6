"""Zero-offset self-calibration of an arm with a laser on the flange and a PSD at an unknown point: plans,
simulated acquisition, calibration, Monte-Carlo accuracy (docs/laser_psd.md)."""
from robocal.systems.laser_psd.calibration import (LaserMount, calibrate_laser, offset_report,
                                                   reading_noise_covariance, zero_offset_problem)
from robocal.systems.laser_psd.monte_carlo import offset_monte_carlo
from robocal.systems.laser_psd.plans import PlannedPose, multi_fan, patent_fan, plan_configurations
from robocal.systems.laser_psd.simulation import PSD, SimRobot, acquire

__all__ = ["LaserMount", "calibrate_laser", "offset_report", "reading_noise_covariance", "zero_offset_problem",
           "offset_monte_carlo", "PlannedPose", "multi_fan", "patent_fan", "plan_configurations", "PSD", "SimRobot",
           "acquire"]
