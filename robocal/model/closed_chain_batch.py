"""Closed-chain samples evaluated all at once: assembly, implicit-function sensitivities, frame Jacobians.

The per-sample path (robocal.model.kinematics.SampleState) assembles each sample with the damped Newton of
robocal.model.loops.assemble and differentiates through the closures one sample at a time. Here the same
formulas run on whole arrays over the samples (robocal.model.tree_arrays walks the tree, robocal.model.
closure_arrays gives the closure rows):

- assembly: every sample takes the damped step of `damped_newton` (mu = |c|^2) from its warm start; a sample
  whose full step does not lower |c|^2 enough (where the per-sample solver would start halving), or that has
  not converged in `max_iterations`, is handed to `assemble` itself from the same warm start, so the branch
  reached and the errors raised are those of the per-sample path;
- sensitivities: C_s dq_s = -C_theta dtheta with C_s = dc/dv on the solved coordinates, one inverse per
  sample (normal equations when there are more rows than unknowns: the least-squares solution lstsq gives);
- a frame's parameter Jacobian is its tree Jacobian plus its solved-joint columns times dq_s/dtheta.

World twists are the working form: a joint's placement twist acts through Ad(oMi[parent] jointPlacement),
its offset through its world motion column; a frame's LOCAL twist is Ad(oMf^-1) of the world one.
Robots with joint relations, tilts, compliance or backlash parameters keep the per-sample path
(`supports_closed_batch`).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.errors import AssemblyError
from robocal.model.batch_kinematics import FrameArrays
from robocal.model.closure_arrays import closure_arrays
from robocal.model.lie_arrays import adjoint_inverse, skew
from robocal.model.loops import assemble
from robocal.model.tree_arrays import TreeArrays, supports_tree_arrays

ARMIJO = 1e-4            # damped_newton's sufficient decrease: a full step below it goes to the per-sample solver
SINGULAR_RCOND = 1e-5    # assemble's default: smallest / largest singular value of C_s at the solution


def supports_closed_batch(ms) -> bool:
    """Whether a ModelState's samples can be evaluated here: a closed chain without joint relations, tilts,
    compliance or backlash, whose joints tree_arrays handles."""
    loops = ms.loops
    return (loops is not None and not loops.relations and ms.tilts is None and not ms.compliance_cols
            and not ms.backlash_cols and not ms.compliance.any() and not ms.backlash.any()
            and supports_tree_arrays(ms.model))


def adjoint(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(n, 6, 6) action matrices of the poses (R, p), twist order [v; w]."""
    out = np.zeros(R.shape[:-2] + (6, 6))
    out[..., :3, :3] = R
    out[..., 3:, 3:] = R
    out[..., :3, 3:] = skew(p) @ R
    return out


class ClosedChainBatch:
    """One ModelState of a closed chain at all samples; `frame(name, samples)` -> FrameArrays.

    values: (N, n_read) readings in `ms.joint_names` order; warm_starts: sample index -> q (nq,), read for
    the start of each assembly and updated with the solutions (the problem's dict, shared with the
    per-sample path)."""

    def __init__(self, ms, values: np.ndarray, warm_starts: dict, tol: float = 1e-12, max_iterations: int = 50):
        self.ms, self.model, self.loops = ms, ms.model, ms.loops
        self.tree = TreeArrays(ms.model)
        self.solved = self.loops.solved_v
        self.n = len(values)
        self.actuated = (values + ms.offsets)[:, ms.actuated_order]
        frames = self.model.frames
        self.anchors = [(self.model.getFrameId(c.frame1), self.model.getFrameId(c.frame2)) for c in self.loops.closures]
        self.mask = {}   # joint -> (n_solved,) 1.0 where the solved coordinate moves the joint
        for f1, f2 in self.anchors:
            for f in (f1, f2):
                j = frames[f].parentJoint
                self.mask[j] = np.isin(self.solved, self.tree.support_v[j]).astype(float)
        self._sensitivity = None
        self._joint_twists: dict = {}
        self.q = self._assemble(warm_starts, tol, max_iterations)

    # ---- assembly --------------------------------------------------------------------------
    def _frame_pose(self, R, p, fid):
        f = self.model.frames[fid]
        Rj, pj = R[:, f.parentJoint], p[:, f.parentJoint]
        return Rj @ f.placement.rotation, pj + Rj @ f.placement.translation

    def _closure_state(self, q: np.ndarray) -> dict:
        """Poses of every joint, the closure rows c (n, m), dc/dv on the solved coordinates (n, m, n_solved)
        and, per closure, D1, D2 and E = D Ad(oMf^-1) (the rows' derivative w.r.t. a world twist)."""
        R, p, AR, Ap = self.tree.placements(q)
        W = self.tree.motion_columns(R, p, self.solved)
        m = self.loops.n_rows
        c, Cs = np.empty((len(q), m)), np.empty((len(q), m, len(self.solved)))
        rows = []
        start = 0
        for closure, (f1, f2) in zip(self.loops.closures, self.anchors):
            R1, p1 = self._frame_pose(R, p, f1)
            R2, p2 = self._frame_pose(R, p, f2)
            ck, D1, D2 = closure_arrays(closure, R1, p1, R2, p2)
            E1, E2 = D1 @ adjoint_inverse(R1, p1), D2 @ adjoint_inverse(R2, p2)
            sl = slice(start, start + closure.rows)
            start = sl.stop
            j1, j2 = self.model.frames[f1].parentJoint, self.model.frames[f2].parentJoint
            c[:, sl] = ck
            Cs[:, sl] = E1 @ (W * self.mask[j1]) + E2 @ (W * self.mask[j2])
            rows.append((D1, D2, E1, E2))
        return {"R": R, "p": p, "AR": AR, "Ap": Ap, "W": W, "c": c, "Cs": Cs, "rows": rows}

    def _set_actuated(self, q: np.ndarray) -> np.ndarray:
        q = q.copy()
        for k, name in enumerate(self.loops.actuated):
            j = self.model.joints[self.model.getJointId(name)]
            if j.nq == 1:
                q[:, j.idx_q] = self.actuated[:, k]
            else:   # continuous joint stored as (cos, sin)
                q[:, j.idx_q], q[:, j.idx_q + 1] = np.cos(self.actuated[:, k]), np.sin(self.actuated[:, k])
        return q

    def _assemble(self, warm_starts: dict, tol: float, max_iterations: int) -> np.ndarray:
        neutral = pin.neutral(self.model)
        guesses = np.array([warm_starts.get(i, neutral) for i in range(self.n)], dtype=float)
        q = self._set_actuated(guesses)
        state = None
        moving = np.ones(self.n, dtype=bool)
        failed = np.zeros(self.n, dtype=bool)
        last_cost = np.full(self.n, np.inf)
        ns = len(self.solved)
        for it in range(max_iterations + 1):
            idx = np.flatnonzero(moving)
            sub = self._closure_state(q[idx])
            state = sub if state is None else _scatter(state, sub, idx)
            err = np.abs(sub["c"]).max(axis=1) if sub["c"].shape[1] else np.zeros(len(idx))
            cost = np.einsum("ni,ni->n", sub["c"], sub["c"])
            # a full step that did not help (or left the numbers): the per-sample solver takes over
            failed[idx] = ~(cost < (1.0 - ARMIJO) * last_cost[idx]) | ~np.isfinite(cost)
            moving[idx] = (err >= tol) & ~failed[idx]
            if not moving.any() or it == max_iterations:
                break
            keep = moving[idx]
            A, r, mu = sub["Cs"][keep], sub["c"][keep], cost[keep]
            normal = np.swapaxes(A, 1, 2) @ A
            normal[:, np.arange(ns), np.arange(ns)] += mu[:, None]
            step = -np.linalg.solve(normal, np.einsum("nmi,nm->ni", A, r)[:, :, None])[:, :, 0]
            go = idx[keep]
            last_cost[go] = mu
            v = np.zeros((len(go), self.model.nv))
            v[:, self.solved] = step
            q[go] = self.tree.integrate(q[go], v)
        failed |= moving
        if failed.any():    # the per-sample solver (line search, its error messages) from the same start
            data = self.model.createData()
            for i in np.flatnonzero(failed):
                q[i] = assemble(self.ms.robot, self.model, self.actuated[i], q_guess=guesses[i].copy(), sample=i,
                                data=data, loops=self.loops, tol=tol)
            idx = np.flatnonzero(failed)
            state = _scatter(state, self._closure_state(q[idx]), idx)
        self.state = state
        solution = q.copy()     # rows handed out as warm starts: never written to again
        warm_starts.update(zip(range(self.n), solution))
        return solution

    # ---- parameter Jacobians ---------------------------------------------------------------
    def _tree_twists(self, joint: int) -> np.ndarray | float:
        """(n, 6, n_free) world twist of `joint` per free parameter with every joint held (0.0 if none):
        placement twists of its supporting joints and offsets of its supporting read joints."""
        hit = self._joint_twists.get(joint)
        if hit is None:
            ms, st = self.ms, self.state
            hit = 0.0
            for i in list(self.model.supports[joint])[1:]:
                block = ms.P_joint[6 * (i - 1):6 * i]
                iv, nv = self.tree.idx_v[i], self.tree.nv_j[i]
                offsets = ms.P_offset[iv:iv + nv]
                if block.any():
                    hit = hit + adjoint(st["AR"][:, i], st["Ap"][:, i]) @ block
                if offsets.any():
                    cols = self.tree.motion_columns(st["R"], st["p"], np.arange(iv, iv + nv))
                    hit = hit + cols @ offsets
            self._joint_twists[joint] = hit
        return hit

    def _frame_tree_jacobian(self, fid: int, E: np.ndarray, D: np.ndarray) -> np.ndarray | float:
        """E @ (frame's world tree twists) + D @ (its own placement columns): a closure's view of one anchor."""
        out = 0.0
        twists = self._tree_twists(self.model.frames[fid].parentJoint)
        if not np.isscalar(twists):
            out = E @ twists
        if fid in self.ms.P_frame:
            out = out + D @ self.ms.P_frame[fid]
        return out

    def sensitivity(self) -> np.ndarray:
        """(n, n_solved, n_free) d q_solved / d theta, from C_s dq_s + C_theta dtheta = 0."""
        if self._sensitivity is None:
            st, nf = self.state, self.ms.n_free
            C_theta = np.zeros((self.n, self.loops.n_rows, nf))
            start = 0
            for closure, (f1, f2), (D1, D2, E1, E2) in zip(self.loops.closures, self.anchors, st["rows"]):
                sl = slice(start, start + closure.rows)
                start = sl.stop
                C_theta[:, sl] += self._frame_tree_jacobian(f1, E1, D1) + self._frame_tree_jacobian(f2, E2, D2)
            self._sensitivity = -(self._solver() @ C_theta)
        return self._sensitivity

    def _solver(self) -> np.ndarray:
        """(n, n_solved, m): C_s^-1, or (C_s^T C_s)^-1 C_s^T with more rows than unknowns; raises AssemblyError
        where C_s is singular (the per-sample path's check, on the samples a norm bound flags)."""
        Cs = self.state["Cs"]
        square = Cs.shape[1] == Cs.shape[2]
        A = Cs if square else np.swapaxes(Cs, 1, 2) @ Cs
        try:
            inv = np.linalg.inv(A)
            bound = 1.0 / (np.linalg.norm(A, axis=(1, 2)) * np.linalg.norm(inv, axis=(1, 2)))
        except np.linalg.LinAlgError:
            inv, bound = None, np.zeros(len(A))
        ratio_bound = bound if square else np.sqrt(bound)       # <= s_min / s_max of C_s
        for i in np.flatnonzero(~(ratio_bound >= SINGULAR_RCOND)):
            s = np.linalg.svd(Cs[i], compute_uv=False)
            if s[-1] < SINGULAR_RCOND * max(s[0], 1e-300) or inv is None:
                raise AssemblyError(f"sample {i}: closed-chain assembly reached a singular configuration "
                                    f"(condition number {s[0] / max(s[-1], 1e-300):.3g}); the passive joints are "
                                    "not determined by these readings")
        return inv if square else inv @ np.swapaxes(Cs, 1, 2)

    def frame(self, frame, samples, jacobian: bool = True) -> FrameArrays:
        """The frame at the samples; its own LOCAL parameter Jacobian (to_frame = I) when asked for."""
        ms = self.ms
        fid = frame if isinstance(frame, (int, np.integer)) else ms.robot.frame_id(frame)
        samples = np.asarray(samples, dtype=int)
        st = self.state
        R0, p0 = self._frame_pose(st["R"][samples], st["p"][samples], fid)
        Rb, pb = ms.base.rotation, ms.base.translation
        R, p = Rb @ R0, p0 @ Rb.T + pb
        if not jacobian:
            return FrameArrays(R, p, R0, p0, None, np.eye(6))
        joint = self.model.frames[fid].parentJoint
        mask = np.isin(self.solved, self.tree.support_v[joint]).astype(float)
        world = (st["W"][samples] * mask) @ self.sensitivity()[samples]
        twists = self._tree_twists(joint)
        if not np.isscalar(twists):
            world += twists[samples]
        if ms.has_base_params:
            world += ms.P_base
        J = adjoint_inverse(R0, p0) @ world
        if fid in ms.P_frame:
            J += ms.P_frame[fid]
        return FrameArrays(R, p, R0, p0, J, np.eye(6))


def _scatter(state: dict, sub: dict, idx: np.ndarray) -> dict:
    """`state` with the samples `idx` replaced by `sub` (same keys; 'rows' holds per-closure tuples)."""
    if len(idx) == len(state["c"]) and np.array_equal(idx, np.arange(len(idx))):
        return sub
    for key, value in sub.items():
        if key == "rows":
            for old, new in zip(state["rows"], value):
                for a, b in zip(old, new):
                    a[idx] = b
        else:
            state[key][idx] = value
    return state
