"""Measurement types. Each is one small file; `REGISTRY` maps config names to classes."""
from robocal.residuals.ball_bar import BallBarResidual
from robocal.residuals.base import Residual, Term
from robocal.residuals.cylinder import CylinderResidual
from robocal.residuals.laser_line import LaserLineResidual
from robocal.residuals.plane import PlaneResidual
from robocal.residuals.point import PointResidual
from robocal.residuals.pose import PoseResidual
from robocal.residuals.reprojection import ReprojectionResidual
from robocal.residuals.rigid_points import RigidPointsResidual
from robocal.residuals.sphere import SphereResidual
from robocal.residuals.sphere_artefact import SphereArtefactResidual
from robocal.residuals.strut_ik import StrutIKResidual
from robocal.residuals.tool_axis import ToolAxisResidual

REGISTRY: dict[str, type[Residual]] = {cls.type_name: cls for cls in (
    PoseResidual, PointResidual, RigidPointsResidual, PlaneResidual, SphereResidual, CylinderResidual,
    BallBarResidual, LaserLineResidual, StrutIKResidual, ToolAxisResidual, SphereArtefactResidual,
    ReprojectionResidual)}

from robocal.residuals.camera_model import CameraModel, CameraSpec, camera_spec_from_dict

__all__ = ["Residual", "Term", "REGISTRY", "CameraModel", "CameraSpec", "camera_spec_from_dict", *[c.__name__ for c in REGISTRY.values()]]
