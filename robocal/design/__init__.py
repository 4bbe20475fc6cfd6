"""Before measuring: which poses to measure, the accuracy to expect, and simulated data with a known truth."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "selection": "DesignMatrix PoseSelection select_poses", "plan": "Plan plan_from_config write_plan",
    "prediction": "predict_parameters predict_pose_accuracy",
    "simulate": "perturb random_configurations simulate_measurements", "dataset": "simulate_dataset"})
