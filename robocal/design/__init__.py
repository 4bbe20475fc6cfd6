"""Before measuring: which poses to measure, the accuracy to expect, and simulated data with a known truth."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "selection": "DesignMatrix PoseSelection select_poses",
    "candidates": "filter_candidates MeasurementVolume random_candidates",
    "simulate": "perturb random_configurations simulate_measurements", "plan": "Plan plan_from_config write_plan",
    "prediction": "pose_jacobians predict_parameters predict_pose_accuracy", "dataset": "simulate_dataset"})
