"""The 4-PUU parallel CMM: reference machine, closed-form kinematics, error model, self-calibration from a sphere
artefact, compensation (docs/pcmm_calibration.md)."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "calibration": "calibrate_pcmm effective_rank machine_jacobian measurement_rows",
    "compensation": "first_order_pose_correction validate",
    "kinematics": "forward_kinematics inverse_kinematics random_workspace_poses reduced_names tip_points",
    "machine": "reference_artefact reference_geometry reference_placements reference_raw simulate_probing"})
