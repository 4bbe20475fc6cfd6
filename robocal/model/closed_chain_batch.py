"""Closed-chain samples evaluated all at once: assembly, implicit-function sensitivities, frame Jacobians.

The per-sample path (robocal.model.kinematics.SampleState) assembles each sample with the damped Newton of
robocal.model.loops.assemble and differentiates through the closures one sample at a time. Here the same
formulas run on whole arrays over the samples (robocal.model.tree_arrays walks the tree, robocal.model.
closure_arrays gives the closure rows):

- assembly: every sample takes the damped step of `damped_newton` (mu = |c|^2; the plain Newton step once mu
  is below 1e-20, where the two agree to rounding) from its warm start, moved by the first-order change of its
  solution when the previous Jacobian pass left its sensitivities (`_predicted`: after a parameter step, one
  Newton step instead of two); a sample whose full step does not lower |c|^2 enough (where the per-sample
  solver would start halving), or that has not converged in `max_iterations`, is handed to `assemble` itself
  from the same warm start, so the branch reached and the errors raised are those of the per-sample path;
- sensitivities: C_s dq_s = -C_theta dtheta with C_s = dc/dv on the solved coordinates, one inverse per
  sample (normal equations when there are more rows than unknowns: the least-squares solution lstsq gives);
- a 6-UPS C_s (each point closure owning two coordinates plus the shared platform's) is eliminated leg by leg
  for the steps and the inverse (robocal.model.point_closure_solve), the dense LU otherwise;
- a frame's parameter Jacobian is its tree Jacobian plus its solved-joint columns times dq_s/dtheta.

World twists are the working form: a joint's placement twist acts through Ad(oMi[parent] jointPlacement),
its offset through its world motion column; a frame's LOCAL twist is Ad(oMf^-1) of the world one.
Robots with joint relations, tilts, compliance or backlash parameters keep the per-sample path
(`supports_closed_batch`).
"""
from __future__ import annotations

import operator

import numpy as np
import pinocchio as pin

from robocal.model.batch_kinematics import FrameArrays
from robocal.model.closed_chain_compiled import CompiledPass, numba_wanted
from robocal.model.closure_groups import (anchor_frame_columns, closure_groups, closure_state, parameter_rows,
                                         with_placements)
from robocal.model.closure_solves import damped_step, sensitivity_solver
from robocal.model.lie_arrays import adjoint_inverse
from robocal.model.loops import assemble
from robocal.model.point_closure_solve import PointArrow
from robocal.model.tree_arrays import TreeArrays, supports_tree_arrays
from robocal.model.tree_twists import TreeTwists

CHUNK = 256              # samples per block: work arrays this size stay in cache and in reused memory
ARMIJO = 1e-4            # damped_newton's sufficient decrease: a full step below it goes to the per-sample solver
MAX_PREDICTION = 0.1     # m or rad: a larger first-order move of a warm start is not taken (_predicted)


def supports_closed_batch(ms) -> bool:
    """Whether a ModelState's samples can be evaluated here: a closed chain without joint relations, tilts,
    compliance or backlash, whose joints tree_arrays handles."""
    loops = ms.loops
    return (loops is not None and not loops.relations and ms.tilts is None and not ms.compliance_cols
            and not ms.backlash_cols and not ms.compliance.any() and not ms.backlash.any()
            and supports_tree_arrays(ms.model))


class ClosedChainBatch:
    """One ModelState of a closed chain at all samples; `frame(name, samples)` -> FrameArrays.

    values: (N, n_read) readings in `ms.joint_names` order; warm_starts: sample index -> q (nq,), read for
    the start of each assembly and updated with the solutions (the problem's dict, shared with the
    per-sample path); jacobian: whether frames will be asked for their parameter Jacobians; samples: the
    samples to assemble (default all); cache: a dict the caller keeps between passes of one problem;
    use_numba: the hot loops in numba kernels (robocal.model.closed_chain_compiled.numba_wanted: None from
    NUMBA_MIN_SAMPLES samples when numba imports and ROBOCAL_NO_NUMBA is not 1; False: numpy only; True: numba
    required), same results to rounding."""

    def __init__(self, ms, values: np.ndarray, warm_starts: dict, jacobian: bool = True, samples=None,
                 cache: dict | None = None, tol: float = 1e-12, max_iterations: int = 50,
                 use_numba: bool | None = None):
        self.ms, self.model, self.loops = ms, ms.model, ms.loops
        cache = {} if cache is None else cache
        if cache.get("robot") is not ms.robot or cache.get("loops") is not ms.loops:
            # what does not change between passes of one problem: the tree's and the closures' structure
            tree = TreeArrays(ms.model)
            groups = closure_groups(ms.model, ms.loops, tree)
            cache.update(robot=ms.robot, loops=ms.loops, tree=tree, groups=groups,
                         arrow=PointArrow.from_groups(groups, ms.loops.n_rows, len(ms.loops.solved_v)))
        self.arrow = cache["arrow"]     # C_s's block structure when it has one (6-UPS): eliminated, no 18 x 18 LU
        self.tree = cache["tree"].at_placements(ms.model)
        self.solved = self.loops.solved_v
        # the samples assembled (all by default): as the per-sample path, only those a residual looks at
        self.samples = np.arange(len(values)) if samples is None else np.unique(np.asarray(samples, dtype=int))
        self.position = np.full(len(values), -1)
        self.position[self.samples] = np.arange(len(self.samples))
        self.n = n = len(self.samples)
        self.actuated = (values[self.samples] + ms.offsets)[:, ms.actuated_order]
        self.groups = with_placements(cache["groups"], self.model)
        anchors = [f for g in self.groups for side in g.frames for f in side]
        # the parameters' structure: the same arrays as the last pass's (the usual case within one problem)
        # reuse its tables, only the placements are read again
        key = (ms.P_joint, ms.P_offset, [ms.P_frame.get(f) for f in anchors], numba_wanted(use_numba, self.n))
        saved = cache.get("structure")
        if saved is not None and _same_structure(saved["key"], key):
            self.twists = saved["twists"].at_tree(self.tree)
            self.group_pairs, self.ccols, self.positions, self.group_frames = saved["tables"]
            self.compiled = saved["compiled"] and saved["compiled"].at_placements(self.tree, self.groups)
        else:
            self._parameter_tables(ms, anchors, key[3])
            kept = (key[0].copy(), key[1].copy(), [None if f is None else f.copy() for f in key[2]], key[3])
            cache["structure"] = {"key": kept, "twists": self.twists, "compiled": self.compiled,
                                  "tables": (self.group_pairs, self.ccols, self.positions, self.group_frames)}
        previous = cache.get("previous")
        held = list(map(warm_starts.get, self.samples.tolist()))       # the warm starts (C-level loops: n is large)
        same = (np.fromiter(map(operator.is_, held, previous["rows"]), dtype=bool, count=n)
                if previous is not None and len(previous["rows"]) == n else np.zeros(n, dtype=bool))
        if n and same.all():      # all still the previous pass's solutions: its stacked array, no row-by-row copy
            guesses = previous["q"].copy()
        else:
            neutral = pin.neutral(self.model)
            guesses = np.array([neutral if h is None else h for h in held], dtype=float).reshape(n, self.model.nq)
        starts = self._predicted(previous, guesses, same, tol)
        # per block of CHUNK samples: joint placements R, p, solved-coordinate columns W, C_s^-1, C_theta (kept
        # per block: one array for all samples, allocated up front, makes every temporary fault in fresh pages)
        self.blocks, solutions = [], []
        for start in range(0, n, CHUNK):
            block = slice(start, min(start + CHUNK, n))
            q, st = self._assemble(block, guesses[block], starts[block], tol, max_iterations)
            solver = self._solver(st["Cs"], self.samples[block])     # the per-sample path's check, always
            self.blocks.append({"R": st["R"], "p": st["p"], "W": st["W"], "solver": solver,
                                "C_theta": self._parameter_rows(st) if jacobian else None})
            solutions.append(q)
        self.q = np.concatenate(solutions) if solutions else guesses
        solution = self.q.copy()
        rows = list(solution)     # handed out as warm starts: never written to again
        warm_starts.update(zip(self.samples.tolist(), rows))
        if jacobian:      # the next pass predicts its starts from these sensitivities (_predicted)
            cache["previous"] = {"x": ms.params.free_values(), "n_free": ms.n_free, "ccols": self.ccols,
                                 "samples": self.samples, "rows": rows, "q": solution,
                                 "blocks": [(b["solver"], b["C_theta"]) for b in self.blocks],
                                 "compiled": self.compiled is not None}     # C_theta (n, nnz) there

    def _parameter_tables(self, ms, anchors: list, use_numba: bool) -> None:
        """The parameters' structure as the pass uses it: active joints (TreeTwists), the closures' supporting pairs,
        the compact columns ccols, and the kernels' tables."""
        self.twists = TreeTwists(ms, self.tree)
        self.group_pairs = [[self.twists.pairs(js) for js in g.joints] for g in self.groups]
        # the few columns the closures' parameter rows can hold: tree joints' placements and offsets
        # and the anchor frames' placements
        framed = [np.any(ms.P_frame[f] != 0.0, axis=0) for f in anchors if f in ms.P_frame]
        self.ccols = np.union1d(self.twists.free_columns, np.flatnonzero(np.any(framed, axis=0)) if framed else [])
        self.ccols = self.ccols.astype(int)
        self.positions = np.searchsorted(self.ccols, self.twists.columns)     # padding (n_free) -> len(ccols)
        self.group_frames = [[anchor_frame_columns(ms.P_frame, fids, self.ccols) for fids in g.frames]
                             for g in self.groups]
        self.compiled = (CompiledPass(self.tree, self.groups, self.loops.n_rows, self.solved, self.twists,
                                      self.group_pairs, self.group_frames, self.positions, len(self.ccols), self.arrow)
                         if use_numba else None)

    def _predicted(self, previous: dict | None, guesses: np.ndarray, same: np.ndarray, tol: float) -> np.ndarray:
        """Where to start each sample's Newton: its warm start moved by the first-order change of the solution,
        dq_s = -C_s^-1 C_theta dtheta, with the previous Jacobian pass's C_s^-1 and C_theta (which it kept). Only
        for samples whose warm start is still that pass's solution, and moves below MAX_PREDICTION: the error left is
        second order in dtheta, so a parameter step needs one Newton step instead of two. Where the closures move
        by less than sqrt(tol), one quadratic step from the warm start reaches tol anyway: the plain
        start is kept (and the assembly's rounding with it). The per-sample fallback starts from the warm start.
        same: whether each sample's warm start is still the previous pass's solution."""
        ms = self.ms
        if (previous is None or previous["n_free"] != ms.n_free or not np.array_equal(previous["ccols"], self.ccols)
                or not np.array_equal(previous["samples"], self.samples)
                or previous["compiled"] != (self.compiled is not None)):
            return guesses
        dx = (ms.params.free_values() - previous["x"])[self.ccols]
        if not dx.any() or not same.any():
            return guesses
        if self.compiled is not None:
            dq, dc_max = self.compiled.predicted_moves(previous["blocks"], dx)
        else:
            dc = [C_theta @ dx for _, C_theta in previous["blocks"]]        # first-order change of the closures
            dq = np.concatenate([-np.einsum("nsm,nm->ns", solver, d) for (solver, _), d in zip(previous["blocks"], dc)])
            dc_max = np.abs(np.concatenate(dc)).max(axis=1)
        small = dc_max < np.sqrt(tol)     # one Newton step from the start will do
        dq[~same | small | (np.abs(dq).max(axis=1) > MAX_PREDICTION)] = 0.0
        v = np.zeros((self.n, self.model.nv))
        v[:, self.solved] = dq
        return self._integrate(guesses, v)

    def _integrate(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return self.compiled.integrate(q, v) if self.compiled is not None else self.tree.integrate(q, v)

    def _take(self, key: str, samples: np.ndarray, joint=None) -> np.ndarray:
        """The per-sample array `key` at the samples (and one joint of it), gathered from the blocks."""
        b = samples // CHUNK
        index = (slice(None),) if joint is None else (slice(None), joint)
        if len(b) and (b == b[0]).all():
            local = samples - b[0] * CHUNK
            if local[-1] - local[0] == len(local) - 1 and (np.diff(local) == 1).all():
                local = slice(local[0], local[-1] + 1)       # a run of samples: a view, no copy
            return self.blocks[b[0]][key][(local,) + index[1:]]
        first = self.blocks[0][key][(slice(0, 1),) + index[1:]]
        out = np.empty((len(samples),) + first.shape[1:])
        for i in np.unique(b):
            sel = b == i
            out[sel] = self.blocks[i][key][(samples[sel] - i * CHUNK,) + index[1:]]
        return out

    # ---- assembly --------------------------------------------------------------------------
    def _state(self, q: np.ndarray) -> dict:
        if self.compiled is not None:
            return self.compiled.state(q)
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

    def _assemble(self, block: slice, guesses: np.ndarray, starts: np.ndarray, tol: float, max_iterations: int):
        """(q, closure state) of the samples `block`: damped Newton steps on all of them at once, from `starts` (the
        warm starts `guesses`, or their first-order prediction)."""
        actuated = self.actuated[block]
        q = self._set_actuated(starts, actuated)
        n = len(q)
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
            if keep.all():       # no copies while every sample still moves
                keep = slice(None)
            A, r, mu = sub["Cs"][keep], sub["c"][keep], cost[keep]
            step = self._step(A, r, mu)
            go = idx[keep]
            last_cost[go] = mu
            v = np.zeros((len(go), self.model.nv))
            v[:, self.solved] = step
            q[go] = self._integrate(q[go], v)
        failed |= moving
        if failed.any():    # the per-sample solver (line search, its error messages) from the warm start
            data = self.model.createData()
            for i in np.flatnonzero(failed):
                q[i] = assemble(self.ms.robot, self.model, actuated[i], q_guess=guesses[i].copy(),
                                sample=int(self.samples[block][i]), data=data, loops=self.loops, tol=tol)
            idx = np.flatnonzero(failed)
            state = _scatter(state, self._state(q[idx]), idx)
        return q, state

    def _step(self, A: np.ndarray, r: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """The damped Newton step for the stack, through C_s's block structure (robocal.model.closure_solves)."""
        return damped_step(A, r, mu, self.arrow, self.compiled)

    def _solver(self, Cs: np.ndarray, labels: np.ndarray) -> np.ndarray:
        """C_s^-1 (or its least-squares form) with the singularity check (robocal.model.closure_solves)."""
        return sensitivity_solver(Cs, labels, self.arrow, self.compiled)

    # ---- parameter Jacobians ---------------------------------------------------------------
    def _parameter_rows(self, st: dict) -> np.ndarray:
        """C_theta (n, m, len(ccols)): the closure rows' derivative w.r.t. the free parameters, joints held; with the
        kernels (n, nnz), its entries that can be nonzero (CompiledPass.parameter_rows)."""
        if self.compiled is not None:
            return self.compiled.parameter_rows(st)
        n, nc = len(st["c"]), len(self.ccols)
        G = self.twists.twists(st["R"], st["p"]) if len(self.twists.active) else None
        pieces = []
        for g, pairs, frames in zip(self.groups, self.group_pairs, self.group_frames):
            sides = [(pk, self.positions[pa], G[:, pa]) if G is not None and len(pk) else (None, None, None)
                     for pk, pa in pairs]
            pieces.append((g, parameter_rows(g, st["R"], st["p"], sides, frames, nc)))
        if len(pieces) == 1 and pieces[0][0].in_order:
            return pieces[0][1]
        out = np.empty((n, self.loops.n_rows, nc))      # allocated last (see closure_state)
        for g, rows in pieces:
            out[:, g.rows] = rows
        return out

    def frame(self, frame, samples, jacobian: bool = True) -> FrameArrays:
        """The frame at the samples; its own LOCAL parameter Jacobian (to_frame = I) when asked for:
        J = J_tree + J_solved dq_s/dtheta, dq_s/dtheta = -C_s^-1 C_theta (implicit-function theorem)."""
        ms = self.ms
        fid = frame if isinstance(frame, (int, np.integer)) else ms.robot.frame_id(frame)
        samples = self.position[np.asarray(samples, dtype=int)]
        if (samples < 0).any():
            raise ValueError("ClosedChainBatch.frame: a sample that was not assembled")
        f = self.model.frames[fid]
        Rj, pj = self._take("R", samples, f.parentJoint), self._take("p", samples, f.parentJoint)
        R0, p0 = Rj @ f.placement.rotation, pj + Rj @ f.placement.translation
        Rb, pb = ms.base.rotation, ms.base.translation
        R, p = Rb @ R0, p0 @ Rb.T + pb
        if not jacobian:
            return FrameArrays(R, p, R0, p0, None, np.eye(6))
        moving = np.flatnonzero(np.isin(self.solved, self.tree.support_v[f.parentJoint]))   # solved coordinates
        _, supports = self.twists.pairs([f.parentJoint])
        J = np.zeros((len(samples), 6, ms.n_free))      # filled block by block (no concatenation)
        for start in range(0, len(samples), CHUNK):
            block = slice(start, min(start + CHUNK, len(samples)))
            s = samples[block]
            Jb = J[block]
            to_local = adjoint_inverse(R0[block], p0[block]) if len(supports) or ms.has_base_params else None
            if len(moving) and self.compiled is not None:
                self.compiled.frame_solved_columns(R0[block], p0[block], self._take("W", s), moving,
                                                   self._take("solver", s), self._take("C_theta", s), self.ccols, Jb)
            elif len(moving):     # the frame's solved joints' columns times their rows of C_s^-1
                to_local_m = adjoint_inverse(R0[block], p0[block]) if to_local is None else to_local
                Y = (to_local_m @ self._take("W", s)[:, :, moving]) @ self._take("solver", s)[:, moving]
                Jb[..., self.ccols] = -(Y @ self._take("C_theta", s))
            if len(supports):
                R_s, p_s = self._take("R", s), self._take("p", s)
                G = self.compiled.twists_at(R_s, p_s) if self.compiled is not None else self.twists.twists(R_s, p_s)
                for a in supports:
                    real = self.twists.columns[a] < ms.n_free        # padding columns carry zeros: dropped
                    Jb[..., self.twists.columns[a][real]] += (to_local @ G[:, a])[..., real]
            if ms.has_base_params:
                Jb += to_local @ ms.P_base
        if fid in ms.P_frame:
            J += ms.P_frame[fid]
        return FrameArrays(R, p, R0, p0, J, np.eye(6))


def _same_structure(a: tuple, b: tuple) -> bool:
    """Whether two passes' (P_joint, P_offset, anchor frames' P_frame, numba) keys hold equal arrays."""
    same = lambda x, y: x is y or (x is not None and y is not None and np.array_equal(x, y))     # noqa: E731
    return (a[3] == b[3] and same(a[0], b[0]) and same(a[1], b[1]) and len(a[2]) == len(b[2])
            and all(same(x, y) for x, y in zip(a[2], b[2])))


def _scatter(state: dict, sub: dict, idx: np.ndarray) -> dict:
    """`state` with the samples `idx` replaced by `sub` (same keys)."""
    if len(idx) == len(state["c"]) and np.array_equal(idx, np.arange(len(idx))):
        return sub
    for key, value in sub.items():
        state[key][idx] = value
    return state
