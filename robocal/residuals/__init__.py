"""Measurement types. Each is one small file; `REGISTRY` maps config names to classes."""
from .ball_bar import BallBarResidual
from .base import Residual, Term
from .cylinder import CylinderResidual
from .laser_line import LaserLineResidual
from .plane import PlaneResidual
from .point import PointResidual
from .pose import PoseResidual
from .rigid_points import RigidPointsResidual
from .sphere import SphereResidual
from .sphere_artefact import SphereArtefactResidual
from .strut_ik import StrutIKResidual
from .tool_axis import ToolAxisResidual

REGISTRY: dict[str, type[Residual]] = {cls.type_name: cls for cls in (
    PoseResidual, PointResidual, RigidPointsResidual, PlaneResidual, SphereResidual, CylinderResidual,
    BallBarResidual, LaserLineResidual, StrutIKResidual, ToolAxisResidual, SphereArtefactResidual)}

__all__ = ["Residual", "Term", "REGISTRY", *[c.__name__ for c in REGISTRY.values()]]
