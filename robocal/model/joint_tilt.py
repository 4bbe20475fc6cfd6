"""The `joint_tilt` parameter kind: a joint's bearing (or a prismatic column) bending under the gravity
moment it carries.

A joint carries the weight of everything beyond it. Its compliance (`joint_compliance`) takes the moment
about its axis; the bearing, housing or column also yields, less, to the moment about the two axes
perpendicular to it. With one isotropic compliance t per joint (rad/(N m)) the child side rotates, about
the joint's origin and in its placement frame, by

    phi = -t * M_perp,   M_perp = M - (M . a) a,

M the gravity moment transmitted through the joint (the nominal model's RNEA at the readings, taken about
the placement origin), a the joint axis. phi enters as a right perturbation of the joint placement:
origin <- origin * exp6(delta) * exp6([0, phi]). Like the gravity torque of `joint_compliance`, M is
evaluated at the readings with the nominal model, so it does not depend on the parameters; its change
with the readings (a second-order term) is left out of the joint Jacobian.

Unlike the axial compliance, the tilt turns the moment's direction into a pose error: an arm swinging about
a vertical first joint bends its column a different way at every azimuth, which a fixed base frame cannot
absorb.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin


class JointTilts:
    """The tilted joints of one ModelState: per-sample placements and Jacobian columns."""

    def __init__(self, robot, model, entries: list[tuple[int, float, list[tuple[int, float]]]]):
        """entries: (joint id, tilt compliance t, [(free column, coefficient)])."""
        if robot.loops is not None:
            raise ValueError("joint_tilt parameters are supported on serial (tree) robots only")
        self.entries = entries
        self.nominal = robot.model
        self.gdata = self.nominal.createData()
        self.placements = {jid: model.jointPlacements[jid].copy() for jid, _, _ in entries}
        self.axes = {jid: _axis(robot, jid) for jid, _, _ in entries}

    def moments(self, q_nominal: np.ndarray) -> dict[int, np.ndarray]:
        """Each tilted joint's perpendicular gravity moment about its placement origin, placement frame."""
        m = self.nominal
        zero = np.zeros(m.nv)
        pin.rnea(m, self.gdata, q_nominal, zero, zero)            # fills gdata.f: force from the parent
        out = {}
        for jid, _, _ in self.entries:
            motion = m.jointPlacements[jid].inverse() * self.gdata.liMi[jid]      # the joint's own motion
            moment = motion.act(self.gdata.f[jid]).angular
            a = self.axes[jid]
            out[jid] = moment - moment.dot(a) * a
        return out

    def apply(self, model, moments: dict[int, np.ndarray]) -> None:
        """Set the tilted joints' placements of `model` (the sampling copy) for one sample's moments."""
        for jid, t, _ in self.entries:
            model.jointPlacements[jid] = self.placements[jid] * pin.exp6(_twist(-t * moments[jid]))

    def jacobian(self, regressor: np.ndarray, P_joint: np.ndarray, moments: dict[int, np.ndarray]) -> np.ndarray:
        """(6, n_free) LOCAL frame twist per free parameter, from the frame's kinematic regressor (placements
        as tilted): the tilt columns, and the placement columns re-expressed past the tilt."""
        J = np.zeros((6, P_joint.shape[1]))
        for jid, t, cols in self.entries:
            rows = slice(6 * (jid - 1), 6 * jid)
            tilt = _twist(-t * moments[jid])
            R = regressor[:, rows]
            # placement errors act before the tilt: their local twist is carried through exp(-tilt)
            back = pin.exp6(-tilt).toActionMatrix()
            J += R @ (back - np.eye(6)) @ P_joint[rows]
            d_tilt = pin.Jexp6(tilt) @ _twist(-moments[jid])
            for c, w in cols:
                J[:, c] += w * (R @ d_tilt)
        return J


def _twist(rotation: np.ndarray) -> np.ndarray:
    return np.concatenate([np.zeros(3), rotation])


def _axis(robot, jid: int) -> np.ndarray:
    axis = robot.joint_axis(jid)
    if axis is None:
        raise ValueError(f"joint_tilt: joint '{robot.model.names[jid]}' is not a one-dof joint; only those tilt")
    return axis[0]
