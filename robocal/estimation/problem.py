"""Problem: the robot, its parameters, the samples and the residual blocks, stacked for a solver.

Rows are scaled to unit variance (row * weight / sigma); rows with weight 0 are dropped. The
Jacobian columns are the free parameters, in `params.free_names` order. `directions` (N, n_joints), the
joints' approach directions at each sample (robocal.model.approach), is needed by backlash parameters only.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.model.kinematics import ModelState
from robocal.model.parameters import ParameterSet
from robocal.residuals.base import Residual
from robocal.residuals.prior import prior_rows


KIND_ORDER = {"base": 0, "auxiliary": 1}


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
    """joint_names: the joints each sample reads; values: (N, len(joint_names)) readings, SI."""

    def __init__(self, robot, params: ParameterSet, joint_names, values, residuals: list[Residual],
                 directions=None):
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
        # first, then the measurement set-up (plane, sphere centre, marker points), then the robot.
        params.reorder(lambda p: KIND_ORDER.get(p.kind, 2))
        self.blocks = self._layout()
        self.warm_starts: dict = {}

    def _layout(self) -> list[Block]:
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

    def states(self, ms: ModelState | None = None) -> "LazyStates":
        ms = ms or self.model_state()
        ms.warm_starts = self.warm_starts   # closed chains: start each assembly from the last solution
        return LazyStates(ms, self.values, self.directions)

    def aux_values(self, res: Residual) -> np.ndarray:
        return np.array([self.params[p.name].value for p in res.aux_parameters()])

    def evaluate(self, jacobian: bool = True) -> Evaluation:
        """Residuals (and Jacobian) at the parameters' current values."""
        self.blocks = self._layout()  # priors may have been switched on or off
        states = self.states()
        free = self.params.free_names
        col = self.params.column_map()
        n_free = len(free)
        rs, raws, Js, groups = [], [], [], []
        gid = 0
        for res in self.residuals:
            scale = res.row_scale()
            keep = scale != 0
            aux_names = [p.name for p in res.aux_parameters()]
            aux = np.array([self.params[n].value for n in aux_names])
            aux_cols = [(j, c, w) for j, n in enumerate(aux_names) for c, w in col.get(n, [])]
            for k in range(res.n_terms):
                t = res.evaluate(k, states, aux)
                raws.append(t.r[keep])
                rs.append((t.r * scale)[keep])
                groups.append(np.full(int(keep.sum()), gid))
                gid += 1
                if jacobian:
                    Jt = np.zeros((res.dim, n_free))
                    for i, frame, D in t.frames:
                        Jt += D @ states[i].frame_parameter_jacobian(frame)
                    for j, c, w in aux_cols:
                        Jt[:, c] += w * t.aux[:, j]
                    Js.append((Jt * scale[:, None])[keep])
        pr, pJ, _ = prior_rows(self.params)
        if len(pr):
            rs.append(pr)
            raws.append(pr)
            groups.append(np.arange(gid, gid + len(pr)))
            if jacobian:
                Js.append(pJ)
        r = np.concatenate(rs) if rs else np.zeros(0)
        J = (np.vstack(Js) if Js else np.zeros((0, n_free))) if jacobian else None
        return Evaluation(r, J, np.concatenate(raws) if raws else np.zeros(0),
                          np.concatenate(groups) if groups else np.zeros(0, int))


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
