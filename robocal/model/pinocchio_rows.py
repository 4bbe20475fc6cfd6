"""A closed chain's closure rows at one configuration, from Pinocchio's constraint kinematics where it has the kind.

Point and frame closures are Pinocchio 4.1 constraint models (robocal.model.constraint_models): one
computeJointJacobians, `calc` per constraint and one getConstraintsJacobian give their residuals and their
derivative d c / d v (q <- integrate(q, v)). Distance and revolute closures have no constraint model in this
wheel; their rows are robocal's (robocal.model.loop_rows), on the anchor frames' placements.

Pinocchio's frame-anchor residual is log6(c1Mc2) and its Jacobian the relative twist of the two anchors in
frame c1, not the derivative of log6: the exact derivative is Jlog6(c1Mc2) Ad(c2Mc1) times it (the two agree at
c = 0; robocal's Newton steps and implicit-function sensitivities want the exact one). The rows equal
robocal's own formulas to rounding (tests/test_loops_pinocchio.py).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model.constraint_models import PINOCCHIO_KINDS, pinocchio_constraints
from robocal.model.loop_rows import closure_rows

LOCAL = pin.ReferenceFrame.LOCAL


class PinocchioRows:
    """The rows of `closures` (slices: each one's rows in the closure vector) for one model: Pinocchio's constraint
    models and their data, built once (anchored as the closures' frames are in `model` at construction)."""

    def __init__(self, model: pin.Model, closures, slices, n_rows: int):
        self.model, self.n_rows = model, n_rows
        self.constraints = pinocchio_constraints(model, closures)
        self.datas = pin.StdVec_ConstraintData()
        for cm in self.constraints:
            self.datas.append(cm.createData())
        # extract() returns a reference into the vector's element: read after every calc without a new wrapper
        self.views = [cd.extract() for cd in self.datas]
        ours = [k for k, c in enumerate(closures) if c.kind in PINOCCHIO_KINDS]
        self.rows = np.concatenate([np.arange(slices[k].start, slices[k].stop) for k in ours]).astype(int) \
            if ours else np.zeros(0, dtype=int)
        self.in_order = n_rows > 0 and bool(np.array_equal(self.rows, np.arange(n_rows)))
        self.frame_kind = [(i, slices[k]) for i, k in enumerate(ours) if closures[k].kind == "frame"]
        self.own = [(closures[k], slices[k], model.getFrameId(closures[k].frame1), model.getFrameId(closures[k].frame2))
                    for k, c in enumerate(closures) if c.kind not in PINOCCHIO_KINDS]

    def _calc(self, model, data):
        for cm, cd in zip(self.constraints, self.datas):
            cm.calc(model, data, cd)
        if not self.views:
            return np.zeros(0)
        return np.concatenate([v.constraint_position_error for v in self.views])

    def rows_and_jacobian(self, model: pin.Model, data: pin.Data, q: np.ndarray):
        """c (n_rows,) and dc/dv (n_rows, nv) at q; runs computeJointJacobians on `data`."""
        pin.computeJointJacobians(model, data, q)
        c_pin = self._calc(model, data)
        if self.in_order:
            c = c_pin
            jac = pin.getConstraintsJacobian(model, data, self.constraints, self.datas).reshape(self.n_rows, -1)
        else:
            c, jac = np.empty(self.n_rows), np.empty((self.n_rows, model.nv))
            if len(self.rows):
                c[self.rows] = c_pin
                jac[self.rows] = pin.getConstraintsJacobian(model, data, self.constraints, self.datas).reshape(
                    len(self.rows), -1)
        for i, sl in self.frame_kind:        # d log6 exactly (see the module docstring)
            c1Mc2 = self.views[i].c1Mc2
            jac[sl] = pin.Jlog6(c1Mc2) @ c1Mc2.inverse().toActionMatrix() @ jac[sl]
        for closure, sl, i1, i2 in self.own:
            M1, M2 = pin.updateFramePlacement(model, data, i1), pin.updateFramePlacement(model, data, i2)
            ck, d1, d2 = closure_rows(closure, M1, M2)
            c[sl] = ck
            jac[sl] = (d1 @ pin.getFrameJacobian(model, data, i1, LOCAL).reshape(6, -1)
                       + d2 @ pin.getFrameJacobian(model, data, i2, LOCAL).reshape(6, -1))
        return c, jac

    def rows_only(self, model: pin.Model, data: pin.Data, q: np.ndarray) -> np.ndarray:
        """c (n_rows,) at q (forward kinematics only)."""
        pin.forwardKinematics(model, data, q)
        c_pin = self._calc(model, data)
        if self.in_order:
            return c_pin
        c = np.empty(self.n_rows)
        c[self.rows] = c_pin
        for closure, sl, i1, i2 in self.own:
            c[sl] = closure_rows(closure, pin.updateFramePlacement(model, data, i1),
                                 pin.updateFramePlacement(model, data, i2))[0]
        return c
