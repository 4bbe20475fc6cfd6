"""What a calibrated model copy (kinematics.ModelState) depends on besides the parameter values.

A fit builds a ModelState at every pass; only the values change from one pass to the next. The free
columns, the tie coefficients, which joints are read, which placement groups exist and in what order
they apply: all of that is worked out once here and kept on the robot, keyed by the parameter set's
structure (names, free flags, ties) and the read joints. A ModelState then only applies the values.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robocal.model.parameters import COMPONENTS, ParameterSet
from robocal.model.robot import ConfigurationMap

MAX_LAYOUTS = 16     # per robot; a fit uses a handful (registration, selection, the fit itself)


@dataclass
class PlacementGroup:
    """A 6D placement (joint, frame or base) with at least one parameter, and `selector` (6, n_free), so that
    the group's block of d(placement twist)/d(free parameters) is Jexp6(delta) @ selector (its six values:
    StateLayout.group_value_index)."""

    kind: str
    target: str
    index: int                      # the joint's or frame's id in the model (-1: the base)
    selector: np.ndarray
    columns: slice | np.ndarray     # the free columns it moves (its block is 0 elsewhere); a slice if consecutive


class StateLayout:
    """The value-independent part of a ModelState (see the module docstring). `value_names` lists every
    parameter whose value the state reads, in one vector (`values`)."""

    def __init__(self, robot, params: ParameterSet, joint_names: list[str]):
        model = robot.model
        self.n_free = len(params.free_names)
        col = params.column_map()        # parameter -> [(free column, coefficient)]; ties act on their leaders
        self.columns = col
        read_v = {name: (k, model.joints[robot.joint_id(name)].idx_v) for k, name in enumerate(joint_names)}
        self.read_v_index = np.array([read_v[n][1] for n in joint_names], dtype=int)
        names: list[str] = []

        def value_slot(name: str) -> int:
            names.append(name)
            return len(names) - 1

        self.P_offset = np.zeros((model.nv, self.n_free))
        reads = {"joint_offset": [], "joint_compliance": [], "joint_backlash": []}   # (read index, value slot)
        self.compliance_cols: list[tuple] = []   # (read index, v index, free column, coefficient)
        self.backlash_cols: list[tuple] = []
        self.tilts: list[tuple] = []             # (joint id, value slot, columns)
        groups: dict[tuple[str, str], None] = {}
        for p in params:
            if p.kind in ("joint_placement", "frame_placement", "base"):
                groups[(p.kind, p.target)] = None
            elif p.kind == "joint_tilt":
                self.tilts.append((robot.joint_id(p.target), value_slot(p.name), col.get(p.name, [])))
            elif p.kind in reads:
                if p.target not in read_v:
                    raise ValueError(f"{p.kind.split('_')[1]} parameter {p.name}: joint '{p.target}' is not read "
                                     "by the data")
                k, iv = read_v[p.target]
                reads[p.kind].append((k, value_slot(p.name)))
                cols = col.get(p.name, [])
                if p.kind == "joint_offset":
                    for c, w in cols:
                        self.P_offset[iv, c] += w
                elif p.kind == "joint_backlash":
                    self.backlash_cols += [(k, iv, c, w) for c, w in cols]
                else:
                    self.compliance_cols += [(k, iv, c, w) for c, w in cols]
        self.reads = {kind: (np.array([k for k, _ in e], dtype=int), np.array([s for _, s in e], dtype=int))
                      for kind, e in reads.items()}
        # frames first: a joint below a calibrated frame gets that change before its own placement error;
        # among frames, parents first, so a calibrated frame below another takes its parent's change
        self.groups, slots = [], []
        for kind, target in sorted(groups, key=lambda g: (g[0] != "frame_placement", _frame_depth(robot, g))):
            prefix = "base" if kind == "base" else target
            selector = np.zeros((6, self.n_free))
            for c, comp in enumerate(COMPONENTS):
                name = f"{prefix}.{comp}"
                slots.append(value_slot(name) if name in params else None)
                for j, w in col.get(name, []):
                    selector[c, j] += w
            index = (robot.joint_id(target) if kind == "joint_placement" else
                     robot.frame_id(target) if kind == "frame_placement" else -1)
            self.groups.append(PlacementGroup(kind, target, index, selector,
                                              contiguous(np.flatnonzero(np.any(selector != 0.0, axis=0)))))
        self._reach(robot)
        self.value_names = names
        # each group's six values in the value vector extended by one 0 (a component without parameter)
        self.group_value_index = np.array([len(names) if i is None else i for i in slots], dtype=int).reshape(-1, 6)
        self.qmap = ConfigurationMap(robot, joint_names)
        self.has_transmission = any(p.kind == "transmission" for p in params)

    def _reach(self, robot) -> None:
        """Which free columns each joint's placement twist and each frame's constant block can move, whatever the
        values (the batched Jacobian's block GEMM and column terms), and which groups move joint placements."""
        def indices(group):
            return np.arange(self.n_free)[group.columns]
        moving: dict[int, list] = {}     # a joint: its own placement, a calibrated fixed link it hangs from
        framed: dict[int, list] = {}     # a frame: the calibrated frames it moves with
        joint_rows = []                  # groups that move joint placements: their ids and values decide them
        for i, g in enumerate(self.groups):
            if g.kind == "joint_placement":
                moved = [g.index]
            elif g.kind == "frame_placement":
                moved = [jid for jid, _ in robot.joints_moved_with(g.index)]
                for gid, _ in robot.frames_moved_with(g.index):
                    framed.setdefault(gid, []).append(indices(g))
            else:
                moved = []
            for jid in moved:
                moving.setdefault(jid, []).append(indices(g))
            if moved or g.kind == "joint_placement":
                joint_rows.append(i)
        self.joint_columns = {jid: np.unique(np.concatenate(c)) for jid, c in moving.items()}
        self.frame_columns = {gid: contiguous(np.unique(np.concatenate(c))) for gid, c in framed.items()}
        self.has_joint_params = any(len(c) for c in self.joint_columns.values())
        self.base_columns = next((g.columns for g in self.groups if g.kind == "base"), slice(0, 0))
        self.has_base_params = len(np.arange(self.n_free)[self.base_columns]) > 0
        self.joint_group_rows = np.array(joint_rows, dtype=int)     # ModelState.joint_key
        self.joint_placement_rows = np.array([i for i, g in enumerate(self.groups) if g.kind == "joint_placement"],
                                             dtype=int)
        self.has_frame_groups = any(g.kind == "frame_placement" for g in self.groups)
        self.joint_group_ids = np.array([[self.groups[i].index, self.groups[i].kind == "frame_placement"]
                                         for i in joint_rows], dtype=float).reshape(-1, 2)

    def values(self, params: ParameterSet) -> np.ndarray:
        """The current values of `value_names` (one vector: placements, offsets, compliance, ...)."""
        return params.value_array(self.value_names)

    def read_values(self, kind: str, values: np.ndarray, n_read: int) -> np.ndarray:
        """(n_read,) per read joint: the value of its `kind` parameter (0 where it has none)."""
        k, slots = self.reads[kind]
        out = np.zeros(n_read)
        out[k] = values[slots]
        return out


def contiguous(cols: np.ndarray):
    """A slice for a run of consecutive column indices (a view: no gather and scatter of J), else the indices."""
    if len(cols) and cols[-1] - cols[0] + 1 == len(cols):
        return slice(int(cols[0]), int(cols[-1]) + 1)
    return cols


def structure_key(params: ParameterSet, joint_names: list[str], robot) -> tuple:
    """What a layout depends on: parameter names and kinds, which are free, the ties; the read joints;
    the robot's frames (add_frame adds one)."""
    return (params.structure(), tuple(joint_names), robot.model.nframes)


def state_layout(robot, params: ParameterSet, joint_names: list[str]) -> StateLayout:
    """The robot's layout for this parameter structure, built on first use."""
    cache = robot.__dict__.setdefault("_state_layouts", {})
    key = structure_key(params, joint_names, robot)
    layout = cache.get(key)
    if layout is None:
        layout = StateLayout(robot, params, joint_names)
        if len(cache) >= MAX_LAYOUTS:
            cache.clear()
        cache[key] = layout
    return layout


def _frame_depth(robot, group: tuple[str, str]) -> int:
    """How many frames a calibrated frame hangs below on its joint (0 for other kinds)."""
    kind, target = group
    if kind != "frame_placement":
        return 0
    frames = robot.model.frames
    k, depth = robot.frame_id(target), 0
    while k != 0 and frames[frames[k].parentFrame].parentJoint == frames[k].parentJoint:
        k, depth = frames[k].parentFrame, depth + 1
    return depth
