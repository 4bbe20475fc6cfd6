"""The 4-PUU parallel CMM: reference machine, closed-form kinematics, error model, self-calibration from a sphere
artefact, compensation (docs/pcmm_calibration.md)."""
from robocal.systems.pcmm.calibration import calibrate_pcmm, effective_rank, machine_jacobian, measurement_rows
from robocal.systems.pcmm.compensation import first_order_pose_correction, validate
from robocal.systems.pcmm.kinematics import (forward_kinematics, inverse_kinematics, pose_error_jacobian,
                                             random_workspace_poses, reduced_names, tip_points)
from robocal.systems.pcmm.machine import (reference_artefact, reference_geometry, reference_placements,
                                          reference_raw, simulate_probing)
from robocal.systems.pcmm.realism import BowedColumns, PreTravel, bowed_readings, certificate

__all__ = ["calibrate_pcmm", "effective_rank", "machine_jacobian", "measurement_rows", "first_order_pose_correction",
           "validate", "forward_kinematics", "inverse_kinematics", "random_workspace_poses", "reduced_names",
           "tip_points", "reference_artefact", "reference_geometry", "reference_placements", "reference_raw",
           "simulate_probing", "pose_error_jacobian", "BowedColumns", "PreTravel", "bowed_readings", "certificate"]
