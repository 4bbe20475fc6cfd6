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
from robocal.model.closure_groups import closure_groups, closure_parts, closure_state
from robocal.model.lie_arrays import adjoint_inverse, skew
from robocal.model.loops import assemble
from robocal.model.tree_arrays import TreeArrays, supports_tree_arrays

CHUNK = 256              # samples per block: work arrays this size stay in cache and in reused memory
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
    per-sample path); jacobian: whether frames will be asked for their parameter Jacobians."""

    def __init__(self, ms, values: np.ndarray, warm_starts: dict, jacobian: bool = True, tol: float = 1e-12,
                 max_iterations: int = 50):
        self.ms, self.model, self.loops = ms, ms.model, ms.loops
        self.tree = TreeArrays(ms.model)
        self.solved = self.loops.solved_v
        self.n = n = len(values)
        self.actuated = (values + ms.offsets)[:, ms.actuated_order]
        self.groups = closure_groups(self.model, self.loops, self.tree)
        # the few columns the closures' parameter rows can hold: tree joints' placements and offsets (tcols)
        # and the anchor frames' placements
        self.tcols = np.flatnonzero(np.any(ms.P_joint != 0.0, axis=0) | np.any(ms.P_offset != 0.0, axis=0))
        anchors = [f for g in self.groups for side in g.frames for f in side]
        framed = [np.any(ms.P_frame[f] != 0.0, axis=0) for f in anchors if f in ms.P_frame]
        self.ccols = np.union1d(self.tcols, np.flatnonzero(np.any(framed, axis=0)) if framed else [])
        self.ccols = self.ccols.astype(int)
        ns, m = len(self.solved), self.loops.n_rows
        self.R, self.p = np.empty((n, self.model.njoints, 3, 3)), np.empty((n, self.model.njoints, 3))
        self.W = np.empty((n, 6, ns))
        self.solver = np.empty((n, ns, m)) if jacobian else None
        self.C_theta = np.empty((n, m, len(self.ccols))) if jacobian else None
        neutral = pin.neutral(self.model)
        guesses = np.array([warm_starts.get(i, neutral) for i in range(n)], dtype=float).reshape(n, -1)
        self.q = np.empty_like(guesses)
        for start in range(0, n, CHUNK):
            block = slice(start, min(start + CHUNK, n))
            self.q[block], st = self._assemble(block, guesses[block], tol, max_iterations)
            self.R[block], self.p[block], self.W[block] = st["R"], st["p"], st["W"]
            solver = self._solver(st["Cs"], start)     # the per-sample path's regularity check, always
            if jacobian:
                self.solver[block] = solver
                self.C_theta[block] = self._parameter_rows(st)
        rows = list(self.q.copy())     # handed out as warm starts: never written to again
        warm_starts.update(zip(range(n), rows))

    # ---- assembly --------------------------------------------------------------------------
    def _state(self, q: np.ndarray) -> dict:
        return closure_state(self.tree, self.groups, self.loops.n_rows, self.solved, q)

    def _set_actuated(self, q: np.ndarray, actuated: np.ndarray) -> np.ndarray:
        q = q.copy()
        for k, name in enumerate(self.loops.actuated):
            j = self.model.joints[self.model.getJointId(name)]
            if j.nq == 1:
                q[:, j.idx_q] = actuated[:, k]
            else:   # continuous joint stored as (cos, sin)
                q[:, j.idx_q], q[:, j.idx_q + 1] = np.cos(actuated[:, k]), np.sin(actuated[:, k])
        return q

    def _assemble(self, block: slice, guesses: np.ndarray, tol: float, max_iterations: int):
        """(q, closure state) of the samples `block`: damped Newton steps on all of them at once."""
        actuated = self.actuated[block]
        q = self._set_actuated(guesses, actuated)
        n, ns = len(q), len(self.solved)
        state = None
        moving, failed = np.ones(n, dtype=bool), np.zeros(n, dtype=bool)
        last_cost = np.full(n, np.inf)
        for it in range(max_iterations + 1):
            idx = np.flatnonzero(moving)
            sub = self._state(q[idx])
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
        if failed.any():    # the per-sample solver (line search, its error messages) from the warm start
            data = self.model.createData()
            for i in np.flatnonzero(failed):
                q[i] = assemble(self.ms.robot, self.model, actuated[i], q_guess=guesses[i].copy(),
                                sample=block.start + i, data=data, loops=self.loops, tol=tol)
            idx = np.flatnonzero(failed)
            state = _scatter(state, self._state(q[idx]), idx)
        return q, state

    def _solver(self, Cs: np.ndarray, first: int) -> np.ndarray:
        """(n, n_solved, m): C_s^-1, or (C_s^T C_s)^-1 C_s^T with more rows than unknowns (lstsq's solution);
        raises AssemblyError where C_s is singular, as `assemble` does (exact check on the samples whose
        norm bound on s_min / s_max falls below the threshold; `first`: index of the block's first sample)."""
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
                raise AssemblyError(f"sample {first + i}: closed-chain assembly reached a singular configuration "
                                    f"(condition number {s[0] / max(s[-1], 1e-300):.3g}); the passive joints are "
                                    "not determined by these readings")
        return inv if square else inv @ np.swapaxes(Cs, 1, 2)

    # ---- parameter Jacobians ---------------------------------------------------------------
    def _tree_twists(self, joint: int, R: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        """(n, 6, len(tcols)) world twist of `joint` per free parameter in `tcols` with every joint held, at the
        joint placements R, p (None if no parameter moves it): placement twists and offsets of its supports."""
        ms, cols, out = self.ms, self.tcols, None
        for i in list(self.model.supports[joint])[1:]:
            block = ms.P_joint[6 * (i - 1):6 * i][:, cols]
            iv, nv = self.tree.idx_v[i], self.tree.nv_j[i]
            offsets = ms.P_offset[iv:iv + nv][:, cols]
            if block.any():
                aR, ap = self.tree.before_motion(R, p, np.array([i]))
                term = adjoint(aR[..., 0, :, :], ap[..., 0, :]) @ block
                out = term if out is None else out + term
            if offsets.any():
                term = self.tree.motion_columns(R, p, np.arange(iv, iv + nv)) @ offsets
                out = term if out is None else out + term
        return None if out is None else np.broadcast_to(out, (len(R), 6, len(cols)))

    def _parameter_rows(self, st: dict) -> np.ndarray:
        """C_theta (n, m, len(ccols)): the closure rows' derivative w.r.t. the free parameters, joints held."""
        n, ms = len(st["c"]), self.ms
        out = np.zeros((n, self.loops.n_rows, len(self.ccols)))
        tpos = np.searchsorted(self.ccols, self.tcols)
        twists: dict = {}
        for g, (D1, D2, E1, E2) in zip(self.groups, closure_parts(self.groups, st["R"], st["p"])):
            k, r = D1.shape[1], D1.shape[2]
            rows = np.zeros((n, k, r, len(self.ccols)))
            for js, fids, D, E in zip(g.joints, g.frames, (D1, D2), (E1, E2)):
                for j in js:
                    if j not in twists:
                        twists[j] = self._tree_twists(int(j), st["R"], st["p"])
                if any(twists[j] is not None for j in js):
                    zero = np.zeros((n, 6, len(self.tcols)))
                    rows[..., tpos] += E @ np.stack([zero if twists[j] is None else twists[j] for j in js], axis=1)
                if any(f in ms.P_frame for f in fids):
                    F = np.array([ms.P_frame[f][:, self.ccols] if f in ms.P_frame else np.zeros((6, len(self.ccols)))
                                  for f in fids])
                    rows += D @ F
            out[:, g.rows] = rows.reshape(n, k * r, -1)
        return out

    def frame(self, frame, samples, jacobian: bool = True) -> FrameArrays:
        """The frame at the samples; its own LOCAL parameter Jacobian (to_frame = I) when asked for:
        J = J_tree + J_solved dq_s/dtheta, dq_s/dtheta = -C_s^-1 C_theta (implicit-function theorem)."""
        ms = self.ms
        fid = frame if isinstance(frame, (int, np.integer)) else ms.robot.frame_id(frame)
        samples = np.asarray(samples, dtype=int)
        f = self.model.frames[fid]
        Rj, pj = self.R[samples, f.parentJoint], self.p[samples, f.parentJoint]
        R0, p0 = Rj @ f.placement.rotation, pj + Rj @ f.placement.translation
        Rb, pb = ms.base.rotation, ms.base.translation
        R, p = Rb @ R0, p0 @ Rb.T + pb
        if not jacobian:
            return FrameArrays(R, p, R0, p0, None, np.eye(6))
        mask = np.isin(self.solved, self.tree.support_v[f.parentJoint]).astype(float)
        J = np.zeros((len(samples), 6, ms.n_free))
        for start in range(0, len(samples), CHUNK):
            block = slice(start, min(start + CHUNK, len(samples)))
            s, Jb = samples[block], J[block]
            to_local = adjoint_inverse(R0[block], p0[block])
            Y = (to_local @ (self.W[s] * mask)) @ self.solver[s]
            Jb[..., self.ccols] = -(Y @ self.C_theta[s])
            twists = self._tree_twists(f.parentJoint, self.R[s], self.p[s])
            if twists is not None:
                Jb[..., self.tcols] += to_local @ twists
            if ms.has_base_params:
                Jb += to_local @ ms.P_base
        if fid in ms.P_frame:
            J += ms.P_frame[fid]
        return FrameArrays(R, p, R0, p0, J, np.eye(6))


def _scatter(state: dict, sub: dict, idx: np.ndarray) -> dict:
    """`state` with the samples `idx` replaced by `sub` (same keys)."""
    if len(idx) == len(state["c"]) and np.array_equal(idx, np.arange(len(idx))):
        return sub
    for key, value in sub.items():
        state[key][idx] = value
    return state
