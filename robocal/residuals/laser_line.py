"""A laser beam on a frame passing through a fixed, unknown point (laser + position-sensitive detector).

The beam leaves origin o along u = R0 [a, b, 1]/|.| (both in the frame); the fixed point P is in the
measurement frame. The two rows are the components of d = P - M o across the beam, so |r| is the
distance of P from the beam. They are taken along a basis b1, b2 perpendicular to the beam that is
carried by the body K the frame's last joint turns against (the JOINT frame of that joint's parent):
fixed axes e1, e2 around a reference z0 in K (the last joint's axis, signed along the beam; the beam's
direction at the joint's zero if the joint is not revolute), turned by the smallest rotation taking z0
to the beam direction w. Hence:
* turning the last joint, or any spin of the frame relative to K, about the beam leaves r unchanged
  (a basis fixed in the frame would turn the 2-vector with it, so the Jacobian at a non-zero residual
  would credit such a spin with information it does not carry);
* moving the whole robot and P rigidly (base joint, a joint whose axis never moves) also leaves r
  unchanged (a basis fixed in the measurement frame would not: the 2-vector would turn then).
b1, b2 are smooth unless the beam points exactly against z0 in K: for a revolute last joint, a laser
aimed backwards along that joint's axis; refused with InputError.
Auxiliary: `<name>.target.{x,y,z}` (P), `<name>.origin.{x,y,z}`, `<name>.tilt_a`, `.tilt_b` (beam
direction). No measurement columns.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.model.lie_arrays import skew
from robocal.residuals.base import Aux, Residual, Term, basis_from_normal, tilted_direction, vector_aux

MIN_ALIGNMENT = 1e-6     # 1 + z0.w below this: the beam runs against z0 and b1, b2 are undefined


def beam_reference(robot, frame: str, direction) -> tuple[int, np.ndarray]:
    """(frame id of K, z0 in K) for a beam along `direction` in `frame` (nominal model, constants)."""
    model = robot.model
    f = model.frames[robot.frame_id(frame)]
    j = f.parentJoint
    if j == 0:                                 # frame fixed in the world: K is the world
        return 0, f.placement.rotation @ direction
    parent = model.parents[j]
    k = next((i for i, g in enumerate(model.frames)
              if g.parentJoint == parent and g.type == pin.FrameType.JOINT), None)
    if k is None:                              # e.g. the universe, whose frame 0 is not of type JOINT
        k = next(i for i, g in enumerate(model.frames) if g.parentJoint == parent)
    R_pk = model.frames[k].placement.rotation   # K in the parent joint's frame
    R_pj = model.jointPlacements[j].rotation    # joint j at zero, in the parent joint's frame
    beam = R_pk.T @ R_pj @ f.placement.rotation @ direction
    axis = robot.joint_axis(j)
    if axis is not None and axis[1]:                             # revolute: its axis, signed along the beam
        axis = R_pk.T @ R_pj @ axis[0]
        return k, axis if axis @ beam >= 0 else -axis
    return k, beam


class LaserLineResidual(Residual):
    """A laser beam on a frame passing through a fixed, unknown point (laser + position-sensitive detector). The
    error model, parameters and columns: this module's docstring."""

    type_name = "laser_line"
    observed = False

    def __init__(self, name, frame, samples, target, origin=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0),
                 target_unknown=True, beam_unknown=False, sigma=1e-5, weights=None):
        super().__init__(name, samples, sigma, weights)
        self.frame = frame
        self.R0 = basis_from_normal(direction)
        self.aux = (vector_aux("target", target, "m", target_unknown) + vector_aux("origin", origin, "m", beam_unknown)
                    + [Aux("tilt_a", 0.0, "rad", beam_unknown), Aux("tilt_b", 0.0, "rad", beam_unknown)])
        self._reference = None     # (robot, K frame id, z0 in K, E in K), from the nominal model

    dim = 2
    row_units = ("length", "length")

    def reference(self, robot):
        if self._reference is None or self._reference[0] is not robot:
            k, z0 = beam_reference(robot, self.frame, self.R0[:, 2])
            B = basis_from_normal(z0)
            self._reference = (robot, k, B[:, 2], B[:, :2])
        return self._reference[1:]

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        state = states[i]
        kid, z0, E = self.reference(state.ms.robot)
        M, K = state.pose(self.frame), state.pose(kid)
        RK = K.rotation
        P, o = aux[:3], aux[3:6]
        u, du = tilted_direction(self.R0, aux[6], aux[7])
        R = RK.T @ M.rotation                  # frame in K
        w = R @ u                              # beam direction in K
        d = RK.T @ (P - M.act(o))              # beam origin to P, in K
        s = 1.0 + z0 @ w
        if s < MIN_ALIGNMENT:
            raise InputError(f"{self.name}: sample {i}'s beam points against its reference {z0.tolist()} "
                             f"(the last joint's axis): the residual's basis is undefined there", field="direction")
        # b_j = e_j - (w.e_j)/s (z0 + w), so r = E^T d - g h / s with g = E^T w, h = (z0 + w).d
        g = E.T @ w
        h = (z0 + w) @ d
        r = E.T @ d - g * (h / s)
        dr_dd = E.T - np.outer(g, z0 + w) / s
        dr_dw = -(h / s) * E.T - np.outer(g, d - (h / s) * z0) / s
        # local right twist (v, omega) of M: dd = R(-v + o x omega), dw = -R skew(u) omega;
        # of K: dd = -omega x d, dw = -omega x w (both are expressed in K)
        D = np.hstack([-dr_dd @ R, dr_dd @ R @ skew(o) - dr_dw @ R @ skew(u)])
        DK = np.hstack([np.zeros((2, 3)), dr_dd @ skew(d) + dr_dw @ skew(w)])
        A = np.hstack([dr_dd @ RK.T, -dr_dd @ R, dr_dw @ R @ du])
        return Term(r, [(i, self.frame, D), (i, kid, DK)], A)
