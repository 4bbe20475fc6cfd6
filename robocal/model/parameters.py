"""Named model parameters: what can be calibrated, and which of it is free.

A parameter is a scalar with a name, a value, `vary`, optional bounds and prior, a unit and a kind.
Kinds and their names (components follow Pinocchio's twist order tx ty tz rx ry rz):

  joint_placement  <joint>.tx .. <joint>.rz   origin <- origin * exp6(delta), right (local) perturbation
  joint_offset     <joint>.offset             encoder zero: q_model = q_read + offset
  frame_placement  <frame>.tx .. <frame>.rz   frame placement <- placement * exp6(delta)
  base             base.tx .. base.rz          measurement frame -> robot root, right perturbation
  joint_compliance <joint>.compliance         elastic sag under gravity: q_link = q_read + offset - c * tau_g,
                                              tau_g the gravity torque of the nominal model (rad/(N m), m/N)
  joint_backlash   <joint>.backlash           signed half-play: q_link = q_read + offset + b * d - c * tau_g, d in
                                              {-1, 0, +1} the joint's approach direction at the sample
                                              (robocal.model.approach; 0 = unknown, centre of the play); b < 0:
                                              the link lags the reading (rad, m)
  joint_tilt       <joint>.tilt               bearing/column bending: the child side rotates by -t * M_perp, M_perp the
                                              gravity moment across the joint axis (robocal.model.joint_tilt; rad/(N m))
  transmission     <relation>.lead / .hand / .ratio   a closed chain's joint relation (robocal.model.joint_relations):
                                              screw lead (m), thread-hand sign (+-1, discrete: never varied),
                                              coupling ratio
  auxiliary        <residual>.<name>           unknowns of a measurement set-up (plane, sphere centre, ...)

Packing to and from the solver's vector happens here only (`free_values` / `set_free_values`).
"""
from __future__ import annotations

import copy
import fnmatch
from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError

COMPONENTS = ("tx", "ty", "tz", "rx", "ry", "rz")
KINDS = ("joint_placement", "joint_offset", "frame_placement", "base", "auxiliary", "joint_compliance",
         "joint_backlash", "joint_tilt", "transmission")


@dataclass
class Parameter:
    name: str
    kind: str
    target: str              # joint, frame or residual name
    index: int = 0           # component 0..5 for placements, position within a residual's unknowns
    value: float = 0.0
    vary: bool = True
    min: float = -np.inf
    max: float = np.inf
    prior_sigma: float | None = None
    prior_mean: float = 0.0
    unit: str = ""
    # follower of other parameters: value = sum(coefficient * leader value); its effect adds to their columns
    tied_to: dict[str, float] | None = None
    # written by a fit: standard error with the prior's contribution (if any), and from the data alone (the
    # parameters set only by their prior held; inf: the data cannot tell it; robocal.estimation.determinacy)
    stderr: float | None = None
    stderr_data: float | None = None
    identifiable: bool | None = None
    confounded_with: list[tuple[str, float]] = field(default_factory=list)

    def copy(self) -> "Parameter":
        """An independent copy: copy.deepcopy's result (its two mutable fields copied; everything else is immutable)
        without deepcopy's walk of every field (model selection copies ~65 parameters some 26 times)."""
        out = copy.copy(self)
        out.tied_to = None if self.tied_to is None else dict(self.tied_to)
        out.confounded_with = list(self.confounded_with)
        return out

    def to_dict(self) -> dict:
        d = {"name": self.name, "kind": self.kind, "value": self.value, "unit": self.unit, "vary": self.vary,
             "stderr": self.stderr, "identifiable": self.identifiable}
        if self.stderr_data is not None:
            d["stderr_data_only"] = self.stderr_data
        if self.confounded_with:
            d["confounded_with"] = [[n, c] for n, c in self.confounded_with]
        if self.prior_sigma is not None:
            d["prior"] = {"mean": self.prior_mean, "sigma": self.prior_sigma}
        if self.tied_to:
            d["tied_to"] = dict(self.tied_to)
        if np.isfinite(self.min) or np.isfinite(self.max):
            d["bounds"] = [self.min if np.isfinite(self.min) else None, self.max if np.isfinite(self.max) else None]
        return d


def _unit(component_index: int) -> str:
    return "m" if component_index < 3 else "rad"


class ParameterSet:
    """An ordered collection of `Parameter`s, addressed by name or glob pattern."""

    def __init__(self, parameters: list[Parameter] | None = None):
        self._params: dict[str, Parameter] = {}
        for p in parameters or []:
            self.add(p)

    # ---- collection ---------------------------------------------------------------
    def add(self, p: Parameter) -> Parameter:
        if p.name in self._params:
            raise InputError(f"parameter '{p.name}' is defined twice", field=p.name)
        self._params[p.name] = p
        return p

    def __getitem__(self, name: str) -> Parameter:
        try:
            return self._params[name]
        except KeyError:
            raise InputError(f"no parameter named '{name}'", field=name) from None

    def __contains__(self, name: str) -> bool:
        return name in self._params

    def __iter__(self):
        return iter(self._params.values())

    def __len__(self) -> int:
        return len(self._params)

    @property
    def names(self) -> list[str]:
        return list(self._params)

    def copy(self) -> "ParameterSet":
        return ParameterSet([p.copy() for p in self])

    def select(self, pattern: str, strict: bool = True) -> list[str]:
        """Names matching a glob pattern (`arm_*.offset`, `base.*`)."""
        hits = [n for n in self._params if fnmatch.fnmatchcase(n, pattern)]
        if strict and not hits:
            raise InputError(f"pattern '{pattern}' matches no parameter", field=pattern)
        return hits

    def fix(self, *patterns: str) -> "ParameterSet":
        for pat in patterns:
            for n in self.select(pat):
                self._params[n].vary = False
        return self

    def free(self, *patterns: str) -> "ParameterSet":
        for pat in patterns:
            for n in self.select(pat):
                self._params[n].vary = True
        return self

    def reorder(self, rank) -> None:
        """Stable re-sort by rank(parameter) (the order is the identifiability tie-break)."""
        items = sorted(self._params.items(), key=lambda kv: rank(kv[1]))
        self._params = dict(items)

    def tie(self, follower: str, leader: str | dict[str, float]) -> "ParameterSet":
        """Make `follower` a fixed linear combination of leaders: value = sum(coefficient * leader value).

        `leader` is a name (coefficient 1: two joints that coincide, frames with the same orientation) or
        {name: coefficient} (the same point seen in differently oriented frames). The follower is no longer
        free; wherever it acts, its effect counts towards the leaders' columns with those coefficients.
        """
        f = self[follower]
        leaders = {leader: 1.0} if isinstance(leader, str) else {k: float(v) for k, v in leader.items()}
        for name in leaders:
            if self[name].tied_to is not None:
                raise InputError(f"'{name}' is itself tied; tie '{follower}' to its leaders instead", field=name)
            if self[name].unit != f.unit:
                raise InputError(f"cannot tie '{follower}' ({f.unit}) to '{name}' ({self[name].unit})", field=follower)
        f.tied_to = leaders
        self._sync_ties()
        return self

    def _sync_ties(self) -> None:
        for p in self._params.values():
            if p.tied_to is not None:
                p.value = sum(c * self._params[n].value for n, c in p.tied_to.items())

    def column_map(self) -> dict[str, list[tuple[int, float]]]:
        """Solver columns of every parameter that acts on them, with coefficients: a free parameter acts
        on its own column (1.0), a follower on its free leaders' columns (their coefficients)."""
        col = {n: i for i, n in enumerate(self.free_names)}
        out = {n: [(i, 1.0)] for n, i in col.items()}
        for p in self._params.values():
            if p.tied_to is not None:
                hits = [(col[n], c) for n, c in p.tied_to.items() if n in col]
                if hits:
                    out[p.name] = hits
        return out

    def set_values(self, values: dict[str, float]) -> "ParameterSet":
        for n, v in values.items():
            self[n].value = float(v)
        return self

    def values(self) -> dict[str, float]:
        return {n: p.value for n, p in self._params.items()}

    def value_array(self, names: list[str]) -> np.ndarray:
        """The values of `names`, in that order, as one vector."""
        params = self._params
        return np.array([params[n].value for n in names], dtype=float)

    def structure(self) -> tuple:
        """What the parameters are, apart from their values: names, kinds, targets, which are free, the
        ties. Equal structures give equal solver columns (robocal.model.state_layout keys on it)."""
        ps = list(self._params.values())
        return (tuple(self._params), tuple([p.kind for p in ps]), tuple([p.target for p in ps]),
                tuple([p.vary for p in ps]), tuple([(p.name, tuple(p.tied_to.items())) for p in ps if p.tied_to]))

    # ---- solver vector ----------------------------------------------------------------
    @property
    def free_names(self) -> list[str]:
        return [n for n, p in self._params.items() if p.vary and p.tied_to is None]

    def free_values(self) -> np.ndarray:
        return np.array([p.value for p in self if p.vary and p.tied_to is None], dtype=float)

    def set_free_values(self, x: np.ndarray) -> None:
        for p, v in zip((p for p in self if p.vary and p.tied_to is None), x):
            p.value = float(v)
        self._sync_ties()

    def free_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        free = [p for p in self if p.vary and p.tied_to is None]
        return np.array([p.min for p in free]), np.array([p.max for p in free])

    # ---- grouped access used by the kinematics layer --------------------------------------
    def placement_vector(self, kind: str, target: str) -> np.ndarray | None:
        """The 6-vector of a placement parameter group, or None if the group is not defined."""
        names = [f"{target}.{c}" for c in COMPONENTS]
        if kind == "base":
            names = [f"base.{c}" for c in COMPONENTS]
        if not any(n in self._params and self._params[n].kind == kind for n in names):
            return None
        return np.array([self._params[n].value if n in self._params else 0.0 for n in names])

    def to_list(self) -> list[dict]:
        return [p.to_dict() for p in self]


# ---- builders ---------------------------------------------------------------------------
def placement_parameters(kind: str, target: str, components=COMPONENTS, prefix: str | None = None) -> list[Parameter]:
    prefix = target if prefix is None else prefix
    return [Parameter(f"{prefix}.{c}", kind, target, COMPONENTS.index(c), unit=_unit(COMPONENTS.index(c)))
            for c in components]


def offset_parameter(joint: str, unit: str = "rad") -> Parameter:
    return Parameter(f"{joint}.offset", "joint_offset", joint, 0, unit=unit)


def robot_parameters(robot, joints: list[str], preset: str = "full", frames: dict[str, tuple] | None = None,
                     base: tuple | bool = False, compliance: bool | list[str] = False,
                     backlash: bool | list[str] = False, tilt: bool | list[str] = False,
                     read: list[str] | None = None) -> ParameterSet:
    """Parameters for a preset over `joints`, plus chosen frame and base components.

    preset: "offsets" (one zero offset per joint), "full" (offset + 6 placement components per joint),
            "placements" (6 placement components, no offsets) or "none".
    frames: {frame_name: components} (True = all six), base: components or True,
    compliance: True (every joint in `joints`) or a list of joints that get a compliance parameter;
    backlash: the same for a backlash parameter (the samples then need approach directions);
    tilt: the same for a tilt compliance (bending across the joint axis under the gravity moment).
    Joints of a prismatic kind get their offset in metres.
    read: the joints the data read (None: all of `joints`). A joint not read (a closed chain's passive joint,
    solved by its loops) has no zero to offset, nor a load reading to comply or play with: the presets and
    `True` skip it, and naming it for compliance or backlash is an error.
    """
    ps = ParameterSet()
    if preset not in ("offsets", "full", "placements", "none"):
        raise InputError(f"unknown preset '{preset}' (offsets, full, placements, none)", field="preset")
    # Order is the identifiability tie-break: the measurement frame first (it absorbs the first joint's
    # placement), then joints root to tip, then frames on the robot.
    if base:
        comps = COMPONENTS if base is True else tuple(base)
        for p in placement_parameters("base", "base", comps, prefix="base"):
            ps.add(p)
    is_read = (lambda j: True) if read is None else set(read).__contains__
    for kind, chosen in (("compliance", compliance), ("backlash", backlash)):
        unread = [j for j in (chosen if isinstance(chosen, (list, tuple)) else []) if not is_read(j)]
        if unread:
            raise InputError(f"{kind} of '{unread[0]}': the data do not read that joint (a closed chain's passive "
                             f"joint is solved by its loops), so there is no reading to offset by a load",
                             field=kind)
    for j in joints:
        jm = robot.model.joints[robot.joint_id(j)]
        prismatic = jm.shortname().startswith("JointModelP")
        if preset in ("offsets", "full") and is_read(j):
            ps.add(offset_parameter(j, "m" if prismatic else "rad"))
        if preset in ("full", "placements"):
            for p in placement_parameters("joint_placement", j):
                ps.add(p)
    for j in ([j for j in joints if is_read(j)] if compliance is True else list(compliance or [])):
        jm = robot.model.joints[robot.joint_id(j)]
        unit = "m/N" if jm.shortname().startswith("JointModelP") else "rad/(N m)"
        ps.add(Parameter(f"{j}.compliance", "joint_compliance", j, 0, unit=unit))
    for j in ([j for j in joints if is_read(j)] if backlash is True else list(backlash or [])):
        jm = robot.model.joints[robot.joint_id(j)]
        unit = "m" if jm.shortname().startswith("JointModelP") else "rad"
        ps.add(Parameter(f"{j}.backlash", "joint_backlash", j, 0, unit=unit))
    for j in (joints if tilt is True else list(tilt or [])):
        robot.joint_id(j)
        ps.add(Parameter(f"{j}.tilt", "joint_tilt", j, 0, unit="rad/(N m)"))
    for frame, comps in (frames or {}).items():
        robot.frame_id(frame)
        comps = COMPONENTS if comps is True else tuple(comps)
        for p in placement_parameters("frame_placement", frame, comps):
            ps.add(p)
    return ps
