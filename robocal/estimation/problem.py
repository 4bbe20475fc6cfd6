"""Problem: the robot, its parameters, the samples and the residual blocks, stacked for a solver.

Rows are scaled to unit variance (row * weight / sigma); rows with weight 0 are dropped. The
Jacobian columns are the free parameters, in `params.free_names` order. `directions` (N, n_joints), the
joints' approach directions at each sample (robocal.model.approach), is needed by backlash parameters only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.model.batch_kinematics import BatchKinematics, SampleConstants, supports_batch
from robocal.model.closed_chain_batch import ClosedChainBatch, supports_closed_batch
from robocal.model.kinematics import ModelState
from robocal.estimation.sessions import (Sessions, SessionStates, correction_jacobian, correction_jacobians,
                                         corrections, exp_jacobians, session_arrays)
from robocal.model.parameters import ParameterSet
from robocal.residuals.base import Residual
from robocal.residuals.prior import prior_rows


KIND_ORDER = {"base": 0, "session_frame": 0, "auxiliary": 1}
EVALUATE_CHUNK_TERMS = 20_000   # terms of a batched residual evaluated at once


@dataclass
class Evaluation:
    r: np.ndarray            # (m,) scaled residual
    J: np.ndarray | None     # (m, n_free)
    raw: np.ndarray          # (m,) unscaled residual, SI units
    group: np.ndarray        # (m,) term id of each row (for robust losses: one weight per term)


@dataclass
class Block:
    name: str
    type_name: str
    rows: slice
    units: list[str]         # 'length' / 'angle' / 'prior' per kept row


class Problem:
    """joint_names: the joints each sample reads; values: (N, len(joint_names)) readings, SI; sessions: which
    session each sample belongs to and the frames re-registered per session (robocal.estimation.sessions)."""

    def __init__(self, robot, params: ParameterSet, joint_names, values, residuals: list[Residual],
                 directions=None, sessions: Sessions | None = None):
        self.robot, self.params = robot, params
        self.joint_names = list(joint_names)
        self.values = np.asarray(values, dtype=float).reshape(-1, len(self.joint_names))
        self.directions = None if directions is None else np.asarray(directions, dtype=float)
        if self.directions is not None and self.directions.shape != self.values.shape:
            raise ValueError(f"directions have shape {self.directions.shape}, the readings {self.values.shape}")
        backlash = [p.name for p in params if p.kind == "joint_backlash"]
        if backlash and self.directions is None:
            raise ValueError(f"backlash parameters ({backlash[0]}, ...) need the approach direction of every "
                             "sample (Problem(..., directions=...); config: data.approach)")
        self.sessions = sessions
        if sessions is not None:
            if len(sessions.of_sample) != len(self.values):
                raise ValueError(f"sessions name {len(sessions.of_sample)} samples, the readings {len(self.values)}")
            for p in sessions.parameters() if sessions.corrected else []:
                if p.name not in params:
                    params.add(p)
        self.residuals = list(residuals)
        names = [r.name for r in self.residuals]
        if len(set(names)) != len(names):
            raise ValueError(f"residual names must be unique: {names}")
        for res in self.residuals:
            for p in res.aux_parameters():
                if p.name not in params:
                    params.add(p)
            bad = [s for s in res.samples if not 0 <= s < len(self.values)]
            if bad:
                raise ValueError(f"residual '{res.name}' refers to sample {bad[0]}, outside 0..{len(self.values) - 1}")
        # Identifiability keeps the earlier of two parameters it cannot tell apart: the measurement frame
        # first, then the measurement set-up (plane, sphere centre, marker points) and the frames a residual
        # registers (a camera's hand-eye: it keeps the last joint's zero it cannot tell from it), then the robot.
        registered = {f for res in self.residuals for f in res.registration_frames}
        params.reorder(lambda p: KIND_ORDER.get(p.kind, 1 if p.kind == "frame_placement" and p.target in registered
                                                else 2))
        self.blocks = self.layout()
        self.warm_starts: dict = {}
        self.closed_chain_cache: dict = {}   # closed chains: what stays between passes (robocal.model.closed_chain_batch)
        self._constants: SampleConstants | None = None
        self._aux_names: dict = {}

    def layout(self) -> list[Block]:
        """The row blocks: one per residual (its kept rows times its terms), then the prior rows."""
        blocks, start = [], 0
        for res in self.residuals:
            keep = res.row_scale() != 0
            units = [u for u, k in zip(res.row_units, keep) if k] * res.n_terms
            blocks.append(Block(res.name, res.type_name, slice(start, start + len(units)), units))
            start += len(units)
        n_prior = sum(1 for p in self.params if p.prior_sigma is not None and p.vary)
        if n_prior:
            blocks.append(Block("priors", "prior", slice(start, start + n_prior), ["prior"] * n_prior))
        return blocks

    def model_state(self) -> ModelState:
        return ModelState(self.robot, self.params, self.joint_names)

    def states(self, ms: ModelState | None = None, params: ParameterSet | None = None):
        """states[i]: sample i's state at `ms` (default: the current values), its poses in its session's
        measurement frame (session corrections at `params`, default the problem's)."""
        ms = ms or self.model_state()
        ms.warm_starts = self.warm_starts   # closed chains: start each assembly from the last solution
        states = LazyStates(ms, self.values, self.directions)
        if self.sessions is not None and self.sessions.corrected:
            return SessionStates(states, self.sessions, corrections(self.sessions, params or self.params))
        return states

    def session_columns(self, col: dict) -> list[list[list[tuple[int, float]]]]:
        """Per session, per component of its correction: the (free column, coefficient) pairs (empty lists for
        the reference session, and without sessions)."""
        if self.sessions is None or not self.sessions.corrected:
            return []
        return [[col.get(n, []) for n in self.sessions.parameter_names(s)] for s in range(len(self.sessions.names))]

    def aux_names(self, res: Residual) -> list[str]:
        """The names of `res`'s auxiliary parameters (fixed at construction), worked out once per residual."""
        names = self._aux_names.get(res)
        if names is None:
            names = self._aux_names[res] = [p.name for p in res.aux_parameters()]
        return names

    def aux_values(self, res: Residual) -> np.ndarray:
        return np.array([self.params[p.name].value for p in res.aux_parameters()])

    def evaluate(self, jacobian: bool = True) -> Evaluation:
        """Residuals (and Jacobian) at the parameters' current values.

        Serial robots (robocal.model.batch_kinematics) and closed chains (robocal.model.closed_chain_batch)
        evaluate the residual types that define `evaluate_batch` for all their terms at once; every other
        case goes term by term through SampleState. Both write straight into one preallocated Jacobian."""
        self.blocks = self.layout()  # priors may have been switched on or off
        m = self.blocks[-1].rows.stop if self.blocks else 0
        ms = self.model_state()
        n_free = ms.n_free
        # every row is written below (each piece fills its rows): no zeroing pass
        ev = Evaluation(np.empty(m), np.empty((m, n_free)) if jacobian else None, np.empty(m), np.empty(m, int))
        # in chunks of terms: the per-sample work arrays (regressors: 1.7 kB a pose) stay bounded
        for rows, r, raw, group, J in self.pieces(jacobian, EVALUATE_CHUNK_TERMS, out=ev.J, ms=ms):
            ev.r[rows], ev.raw[rows], ev.group[rows] = r, raw, group
            if jacobian and not np.may_share_memory(J, ev.J):
                ev.J[rows] = J
        return ev

    def pieces(self, jacobian: bool = True, chunk_terms: int | None = None, out: np.ndarray | None = None,
               ms: ModelState | None = None):
        """Yield (rows, r, raw, group, J) for consecutive row ranges of the stacked problem: a batched
        residual in chunks of at most `chunk_terms` terms (None: all at once), any other residual whole,
        and the prior rows last. Memory then grows with the chunk, not with the samples. With `out`, the
        whole (m, n_free) Jacobian, batched rows are written straight into it (J is then a view of it). `ms`: the
        model at the current values, when the caller has it already."""
        ms = ms or self.model_state()
        col = ms.layout.columns        # the parameter structure's column map, worked out once
        n_free = ms.n_free
        batch = None
        if any(res.batched for res in self.residuals):
            if supports_batch(ms):
                batch = BatchKinematics(ms, self.sample_constants(ms), self.values, self.directions)
            elif supports_closed_batch(ms):     # closed chains: every sample assembled and differentiated at once
                used = np.concatenate([res.samples for res in self.residuals if res.batched])
                batch = ClosedChainBatch(ms, self.values, self.warm_starts, jacobian, used, self.closed_chain_cache)
        states = None
        gid = 0
        session_cols = self.session_columns(col)
        T = corrections(self.sessions, self.params) if session_cols else None
        Jexp = exp_jacobians(self.sessions, self.params) if session_cols else None
        for res, block in zip(self.residuals, self.blocks):
            scale = res.row_scale()
            keep = scale != 0
            n_keep = int(keep.sum())
            aux_names = self.aux_names(res)
            aux = self.params.value_array(aux_names)
            aux_cols = [(j, c, w) for j, n in enumerate(aux_names) for c, w in col.get(n, [])]
            step = res.n_terms if batch is None or not res.batched else (chunk_terms or res.n_terms)
            for k0 in range(0, res.n_terms, max(step, 1)):
                terms = slice(k0, min(k0 + max(step, 1), res.n_terms))
                n_t = terms.stop - terms.start
                rows = slice(block.rows.start + k0 * n_keep, block.rows.start + terms.stop * n_keep)
                group = gid + np.repeat(np.arange(k0, terms.stop), n_keep)
                # a per-term sigma (res.term_scale) makes the row scale (n_t, dim)
                sc = scale if res.term_scale is None else scale * res.term_scale[terms, None]
                if batch is not None and res.batched:
                    fa = batch.frame(res.frame, res.samples[terms], jacobian)
                    session = None if T is None else self.sessions.of_sample[res.samples[terms]]
                    if session is None:
                        t = res.evaluate_batch(terms, fa.R, fa.p, aux)
                    else:
                        t = res.evaluate_batch(terms, *session_arrays(fa.R, fa.p, T, session), aux)
                    Jt = None
                    if jacobian:
                        direct = out is not None and n_keep == res.dim
                        # the row scales and the frame's placement folded into the (n, dim, 6) derivative:
                        # no extra pass over J (the stack times one matrix as one GEMM)
                        M = ((t.D * sc[..., None]).reshape(-1, 6) @ fa.to_frame).reshape(t.D.shape)
                        Jt = fa.project(M,
                                        out=out[rows].reshape(n_t, res.dim, n_free) if direct else None)
                        for j, c, w in aux_cols:
                            Jt[:, :, c] += w * t.aux[:, :, j] * sc
                        if session is not None:
                            add_session_columns(Jt, correction_jacobians(t.D * sc[..., None], fa.R, fa.p,
                                                                         Jexp[session]), session, session_cols)
                        Jt = (Jt if n_keep == res.dim else Jt[:, keep]).reshape(n_t * n_keep, n_free)
                    raw = t.r if n_keep == res.dim else t.r[:, keep]
                    yield rows, (raw * sc[..., keep]).ravel(), raw.ravel(), group, Jt
                    continue
                states = states or self.states(ms)
                r, raw = np.empty((n_t, n_keep)), np.empty((n_t, n_keep))
                Jr = np.zeros((n_t, n_keep, n_free)) if jacobian else None
                for k in range(terms.start, terms.stop):
                    t = res.evaluate(k, states, aux)
                    sk = scale if res.term_scale is None else scale * res.term_scale[k]
                    raw[k - k0], r[k - k0] = t.r[keep], (t.r * sk)[keep]
                    if jacobian:
                        Jt = np.zeros((res.dim, n_free))
                        for i, frame, D in t.frames:
                            Jt += D @ states[i].frame_parameter_jacobian(frame)
                            if session_cols:
                                s = int(self.sessions.of_sample[i])
                                cj = correction_jacobian(D, states.raw[i].pose(frame), Jexp[s])
                                for comp, pairs in enumerate(session_cols[s]):
                                    for c, w in pairs:
                                        Jt[:, c] += w * cj[:, comp]
                        for j, c, w in aux_cols:
                            Jt[:, c] += w * t.aux[:, j]
                        Jr[k - k0] = (Jt * sk[:, None])[keep]
                yield rows, r.ravel(), raw.ravel(), group, (Jr.reshape(n_t * n_keep, n_free) if jacobian else None)
            gid += res.n_terms
        if not (self.blocks and self.blocks[-1].type_name == "prior"):    # the layout has no prior rows
            return
        pr, pJ, _ = prior_rows(self.params)
        if len(pr):
            rows = slice(self.blocks[-1].rows.start, self.blocks[-1].rows.stop)
            yield rows, pr, pr, np.arange(gid, gid + len(pr)), pJ if jacobian else None

    def sample_constants(self, ms: ModelState) -> SampleConstants:
        """Per-sample quantities that the parameters cannot change (gravity torques, regressors while the
        kinematics stay put), kept between evaluations while the readings are the same."""
        c = self._constants
        if c is None or not c.matches(self.values) or (ms.needs_gravity and c.tau is None):
            c = self._constants = SampleConstants(self.robot, self.joint_names, self.values, ms.needs_gravity,
                                                  ms.read_v_index)
        return c


def add_session_columns(J: np.ndarray, CJ: np.ndarray, session: np.ndarray, session_cols) -> None:
    """J (n, d, n_free) += each term's correction derivative CJ (n, d, 6) in its session's columns."""
    for s, comps in enumerate(session_cols):
        mask = session == s
        if not mask.any():
            continue
        for comp, pairs in enumerate(comps):
            for c, w in pairs:
                J[mask, :, c] += w * CJ[mask, :, comp]


class LazyStates:
    """states[i] -> SampleState of sample i, built on first use for the current model."""

    def __init__(self, ms: ModelState, values: np.ndarray, directions: np.ndarray | None = None):
        self.ms, self.values, self.directions = ms, values, directions
        self._states: dict[int, object] = {}

    def __getitem__(self, i):
        i = int(i)
        s = self._states.get(i)
        if s is None:
            d = None if self.directions is None else self.directions[i]
            s = self._states[i] = self.ms.sample(self.values[i], label=i, direction=d)
        return s

    def __len__(self):
        return len(self.values)
