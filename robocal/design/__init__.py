"""Before measuring: which poses to measure, the accuracy to expect, and simulated data with a known truth."""
from robocal.design.camera_poses import CameraView, camera_candidates, camera_design_problem, simulate_detections
from robocal.design.candidates import MeasurementVolume, filter_candidates, random_candidates
from robocal.design.prediction import pose_jacobians, predict_parameters, predict_pose_accuracy
from robocal.design.selection import DesignMatrix, PoseSelection, select_poses
from robocal.design.simulate import perturb, random_configurations, simulate_measurements

__all__ = ["CameraView", "camera_candidates", "camera_design_problem", "simulate_detections", "MeasurementVolume", "filter_candidates", "random_candidates", "pose_jacobians", "predict_parameters",
           "predict_pose_accuracy", "DesignMatrix", "PoseSelection", "select_poses", "perturb",
           "random_configurations", "simulate_measurements"]
