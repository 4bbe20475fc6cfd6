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
        self._gdata = None
        self.placements = {jid: model.jointPlacements[jid].copy() for jid, _, _ in entries}
        memo = robot.__dict__.setdefault("_tilt_axes", {})    # joint kinds never change: once per robot
        self.axes = {jid: memo[jid] if jid in memo else memo.setdefault(jid, _axis(robot, jid))
                     for jid, _, _ in entries}

    @property
    def gdata(self):
        """The nominal model's Data for the gravity moments, made on first use (a batched pass needs it once)."""
        if self._gdata is None:
            self._gdata = self.nominal.createData()
        return self._gdata

    def moments(self, q_nominal: np.ndarray) -> dict[int, np.ndarray]:
        """Each tilted joint's perpendicular gravity moment about its placement origin, placement frame."""
        joints = [jid for jid, _, _ in self.entries]
        return dict(zip(joints, perpendicular_moments(self.nominal, self.gdata, q_nominal, joints, self.axes)))

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


def perpendicular_moments(model, data, q_nominal: np.ndarray, joints: list[int], axes: dict) -> np.ndarray:
    """(len(joints), 3): each joint's gravity moment across its axis about its placement origin, placement frame
    (the nominal `model`'s RNEA at rest at q_nominal, in `data`)."""
    zero = np.zeros(model.nv)
    pin.rnea(model, data, q_nominal, zero, zero)            # fills data.f: force from the parent
    out = np.empty((len(joints), 3))
    for k, jid in enumerate(joints):
        motion = model.jointPlacements[jid].inverse() * data.liMi[jid]      # the joint's own motion
        moment = motion.act(data.f[jid]).angular
        a = axes[jid]
        out[k] = moment - moment.dot(a) * a
    return out


def _twist(rotation: np.ndarray) -> np.ndarray:
    return np.concatenate([np.zeros(3), rotation])


def _axis(robot, jid: int) -> np.ndarray:
    axis = robot.joint_axis(jid)
    if axis is None:
        raise ValueError(f"joint_tilt: joint '{robot.model.names[jid]}' is not a one-dof joint; only those tilt")
    return axis[0]
