"""Robot: a Pinocchio model loaded from URDF, plus the frames and joints robocal refers to by name.

The nominal model is never modified; calibrated copies are made by `robocal.model.parameters`.
Only kinematics and inertias are loaded (no meshes), which takes about a millisecond.
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import numpy as np
import pinocchio as pin
from lxml import etree

from robocal.errors import FrameNotFound, InputError
from robocal.model.constraint_models import pinocchio_constraints
from robocal.model.urdf_check import c_stderr_captured, check_urdf_elements
from robocal.model.urdf_tree import check_urdf_tree
from robocal.model.loops_urdf import read_loops

# Robots of the example-robot-data package, by the short names users type.
EXAMPLES: dict[str, str] = {
    "panda": "panda_description/urdf/panda.urdf",
    "so100": "so_arm_description/urdf/so100.urdf",
    "so101": "so_arm_description/urdf/so101.urdf",
    "tiago": "tiago_description/robots/tiago.urdf",
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "xarm7": "xarm_description/urdf/xarm7.urdf",
    "z1": "z1_description/urdf/z1.urdf",
}


@lru_cache(maxsize=1)
def example_robot_data_share() -> Path:
    """The `share` folder of the example-robot-data wheel (its `package://` root)."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError as exc:  # pragma: no cover - declared dependency
        raise InputError("the package example-robot-data is not installed "
                         "(pip install example-robot-data)") from exc
    marker = next((f for f in dist.files or [] if str(f).endswith("share/example-robot-data/package.xml")),
                  None)
    if marker is None:  # pragma: no cover
        raise InputError("example-robot-data is installed but its share folder was not found")
    return Path(dist.locate_file(marker)).resolve().parent.parent


@dataclass
class Robot:
    """A robot model and the names robocal uses to talk about it.

    model        nominal Pinocchio model (kinematic tree; closures live in `loops`)
    urdf_path    the file it came from (None when built in memory or read from MJCF: mjcf_path)
    urdf_text    the URDF source, kept for export
    package_dirs folders that resolve `package://` URIs (meshes are loaded only for viewing)
    loops        closed-chain description (robocal.model.loops.LoopSet) or None for a serial robot
    base_placement  nominal pose of the robot root in the measurement frame (tracker, CMM, world)
    """

    model: pin.Model
    urdf_path: Path | None = None
    urdf_text: str = ""
    package_dirs: list[str] = field(default_factory=list)
    name: str = ""
    loops: object | None = None
    extra_frames: dict[str, tuple[str, pin.SE3]] = field(default_factory=dict)
    base_placement: pin.SE3 = field(default_factory=pin.SE3.Identity)  # measurement frame -> robot root
    mjcf_path: Path | None = None    # the MJCF file it came from (robocal.model.mjcf), if any

    @property
    def source(self) -> str:
        """The file the robot came from, or its name: what error messages about it say first."""
        path = self.urdf_path or self.mjcf_path
        return str(path) if path else (self.name or "robot")

    # ---- names -------------------------------------------------------------------------
    @property
    def joint_names(self) -> list[str]:
        """Joints with degrees of freedom, in Pinocchio's order (universe excluded)."""
        return [self.model.names[j] for j in range(1, self.model.njoints)]

    @property
    def frame_names(self) -> list[str]:
        return [f.name for f in self.model.frames]

    def frame_id(self, name: str) -> int:
        cache = self.__dict__.setdefault("_frame_ids", {})   # frames are only ever added (add_frame clears it)
        fid = cache.get(name)
        if fid is not None:
            return fid
        if not self.model.existFrame(name):
            close = difflib.get_close_matches(name, self.frame_names, n=5, cutoff=0.5)
            hint = f" Close matches: {', '.join(close)}." if close else ""
            raise FrameNotFound(f"robot '{self.name}' has no frame '{name}'.{hint}", field=name)
        cache[name] = fid = self.model.getFrameId(name)
        return fid

    def joint_id(self, name: str) -> int:
        if not self.model.existJointName(name):
            close = difflib.get_close_matches(name, self.joint_names, n=5, cutoff=0.5)
            hint = f" Close matches: {', '.join(close)}." if close else f" Joints: {', '.join(self.joint_names)}."
            raise InputError(f"robot '{self.name}' has no joint '{name}'.{hint}", field=name)
        return self.model.getJointId(name)

    def supporting_joints(self, frame: str) -> list[str]:
        """Joints that move `frame`, root first."""
        jid = self.model.frames[self.frame_id(frame)].parentJoint
        return [self.model.names[j] for j in self.model.supports[jid] if j > 0]

    # ---- frames ------------------------------------------------------------------------
    def add_frame(self, name: str, parent: str, placement: pin.SE3 | None = None) -> int:
        """Attach a new frame (tool, marker, sensor) to an existing frame.

        `placement` is relative to `parent`. The new frame is independent afterwards: its own
        frame parameters move it alone.
        """
        if self.model.existFrame(name):
            raise InputError(f"robot '{self.name}' already has a frame '{name}'", field=name)
        pid = self.frame_id(parent)
        pf = self.model.frames[pid]
        placement = pin.SE3.Identity() if placement is None else placement
        frame = pin.Frame(name, pf.parentJoint, pid, pf.placement * placement, pin.FrameType.OP_FRAME)
        self.extra_frames[name] = (parent, placement.copy())
        self.__dict__.pop("_frame_ids", None)
        self.__dict__.pop("_moved_with", None)
        return self.model.addFrame(frame, False)

    def frames_moved_with(self, frame) -> list[tuple[int, pin.SE3]]:
        """Frames that move rigidly with `frame` when its placement is calibrated, and their offsets.

        These are the frame itself, the frames hanging below it on the same joint (child links of fixed
        joints, markers attached with add_frame), and for a link made by a fixed joint, that joint's
        frame, since both stand for the one URDF origin an export edits.
        Returns [(frame id, nominal placement of it relative to `frame`)].
        """
        fid = frame if isinstance(frame, int) else self.frame_id(frame)
        cache = self.__dict__.setdefault("_moved_with", {})      # structure only: add_frame clears it
        key = ("frames", fid, self.model.nframes)
        if key in cache:
            return cache[key]
        frames = self.model.frames
        base = frames[fid].placement
        out = cache[key] = []
        for g, f in enumerate(frames):
            k, below = g, False
            while k != 0 and frames[k].parentJoint == frames[fid].parentJoint:
                if k == fid:
                    below = True
                    break
                k = frames[k].parentFrame
            same_origin = (g == frames[fid].parentFrame and frames[g].type == pin.FrameType.FIXED_JOINT
                           and frames[fid].type == pin.FrameType.BODY)
            if below or same_origin:
                out.append((g, base.inverse() * f.placement))
        return out

    def joints_moved_with(self, frame) -> list[tuple[int, pin.SE3]]:
        """Movable joints whose origin Pinocchio measures through `frame` (a fixed-joint link), and the
        nominal placement of each relative to it; calibrating the frame moves them too."""
        fid = frame if isinstance(frame, int) else self.frame_id(frame)
        cache = self.__dict__.setdefault("_moved_with", {})
        key = ("joints", fid, self.model.nframes)
        if key in cache:
            return cache[key]
        frames, m = self.model.frames, self.model
        out = cache[key] = []
        for k in range(1, m.njoints):
            if m.parents[k] != frames[fid].parentJoint or not m.existFrame(m.names[k], pin.FrameType.JOINT):
                continue
            g = frames[m.getFrameId(m.names[k], pin.FrameType.JOINT)].parentFrame  # the frame it hangs on
            while g != 0 and g != fid and frames[g].parentJoint == frames[fid].parentJoint:
                g = frames[g].parentFrame
            if g == fid:
                out.append((k, frames[fid].placement.inverse() * m.jointPlacements[k]))
        return out

    def joint_axis(self, jid: int) -> tuple[np.ndarray, bool] | None:
        """(unit axis in the joint's frame, revolute?) of a one-dof joint, from its motion subspace S
        (angular part for a revolute, linear for a prismatic joint); None for any other joint."""
        jm = self.model.joints[jid]
        if jm.nv != 1:
            return None
        data = self.model.createData()
        pin.computeJointJacobians(self.model, data, pin.neutral(self.model))
        S = pin.getJointJacobian(self.model, data, jid, pin.ReferenceFrame.LOCAL)[:, jm.idx_v]
        revolute = np.linalg.norm(S[3:]) > 0.5
        axis = S[3:] if revolute else S[:3]
        return axis / np.linalg.norm(axis), bool(revolute)

    # ---- loops as Pinocchio sees them ----------------------------------------------------
    def constraint_models(self, model: pin.Model | None = None) -> pin.StdVec_ConstraintModel:
        """Pinocchio constraint models of the point and frame closures (PointAnchor / FrameAnchor, named after
        them), anchored as their frames are in `model` (default robot.model; a calibrated copy gives the calibrated
        anchors). The distance and revolute kinds have none in Pinocchio 4.1 (docs/closed_loops.md)."""
        if self.loops is None:
            return pin.StdVec_ConstraintModel()
        return pinocchio_constraints(self.model if model is None else model, self.loops.closures)

    # ---- configurations ----------------------------------------------------------------
    def neutral(self) -> np.ndarray:
        return pin.neutral(self.model)

    def configuration(self, joint_names: list[str], values: np.ndarray,
                      base: np.ndarray | None = None) -> np.ndarray:
        """Full Pinocchio q from readings of the named 1-dof joints (others at `base` or neutral).

        Continuous joints (Pinocchio stores cos, sin) are handled.
        """
        return ConfigurationMap(self, joint_names, base)(values)

    def limits(self, joint_names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper position limits of 1-dof joints (infinite ones clipped to +-pi)."""
        lo, hi = [], []
        for name in joint_names:
            j = self.model.joints[self.joint_id(name)]
            if j.nq == 1:
                a, b = self.model.lowerPositionLimit[j.idx_q], self.model.upperPositionLimit[j.idx_q]
            else:
                a, b = -np.pi, np.pi
            lo.append(max(a, -np.pi) if np.isfinite(a) else -np.pi)
            hi.append(min(b, np.pi) if np.isfinite(b) else np.pi)
        return np.array(lo), np.array(hi)


class ConfigurationMap:
    """Readings of named 1-dof joints -> full Pinocchio q, with the index work done once."""

    def __init__(self, robot: Robot, joint_names: list[str], base: np.ndarray | None = None):
        self.q0 = robot.neutral() if base is None else np.array(base, dtype=float)
        plain, cont_k, cont_q = [], [], []
        for k, name in enumerate(joint_names):
            j = robot.model.joints[robot.joint_id(name)]
            if j.nq == 1:
                plain.append((k, j.idx_q))
            elif j.nq == 2 and j.nv == 1:
                cont_k.append(k)
                cont_q.append(j.idx_q)
            else:
                raise InputError(f"joint '{name}' has {j.nv} degrees of freedom; robocal reads "
                                 "one value per joint", field=name)
        self.plain_k = np.array([k for k, _ in plain], dtype=int)
        self.plain_q = np.array([i for _, i in plain], dtype=int)
        self.cont_k, self.cont_q = np.array(cont_k, dtype=int), np.array(cont_q, dtype=int)

    def __call__(self, values: np.ndarray) -> np.ndarray:
        values = np.asarray(values, dtype=float)
        q = self.q0.copy()
        q[self.plain_q] = values[self.plain_k]
        if len(self.cont_k):
            q[self.cont_q] = np.cos(values[self.cont_k])
            q[self.cont_q + 1] = np.sin(values[self.cont_k])
        return q


def _parse_urdf_text(path: Path) -> tuple[str, etree._ElementTree]:
    if not path.is_file():
        raise InputError("URDF file not found", source=str(path))
    text = path.read_text(encoding="utf-8", errors="replace")
    try:
        tree = etree.fromstring(text.encode("utf-8"), parser=etree.XMLParser(remove_comments=False))
    except etree.XMLSyntaxError as exc:
        # an XML line, not a data row: said as "line N"
        raise InputError(f"not valid XML at line {exc.lineno}: {exc.msg.splitlines()[0].strip()}",
                         source=str(path)) from None
    if tree.tag != "robot":
        raise InputError(f"not a URDF: the root element (line {tree.sourceline}) is <{tree.tag}>, expected <robot>",
                         source=str(path))
    check_urdf_elements(tree, path)
    check_urdf_tree(tree, path)             # before Pinocchio: two parents can crash it
    return text, tree


def load_urdf(path: str | Path, package_dirs: list[str | Path] | None = None) -> Robot:
    """Load a robot from a URDF file (kinematics and inertias; meshes only when viewing).

    Loop closures (`<loop_joint>` or URDF+ `<constraint>`) are read when present.
    """
    path = Path(path).resolve()
    text, tree = _parse_urdf_text(path)
    error = None
    with c_stderr_captured() as c_errors:
        try:
            model = pin.buildModelFromXML(text)
        except (RuntimeError, ValueError) as exc:
            error = exc
    if error is not None:
        # urdfdom's lines: "Error:   <what>" then "at line N in <its source file>", which means nothing to a user
        detail = " ".join(line.strip().removeprefix("Error:").strip() for line in "".join(c_errors).splitlines()
                          if line.strip() and not line.strip().startswith("at line "))
        named = re.search(r"(joint|link) \[([^\]]+)\]", detail)     # urdfdom names the element it rejects
        raise InputError(f"Pinocchio cannot build a model from this URDF: {error}"
                         + (f" (urdfdom: {detail})" if detail else ""), source=str(path),
                         field=f"{named.group(1)} {named.group(2)}" if named else "robot") from None
    dirs = [str(p) for p in (package_dirs or [])] + [str(path.parent)]
    robot = Robot(model=model, urdf_path=path, urdf_text=text, package_dirs=dirs,
                  name=tree.get("name", path.stem))
    robot.loops = read_loops(robot, tree)
    return robot


def load_example(name: str) -> Robot:
    """Load a robot of example-robot-data by short name (`ur5`, `panda`, ...)."""
    key = name.lower()
    if key not in EXAMPLES:
        raise InputError(f"unknown example robot '{name}'. Known: {', '.join(sorted(EXAMPLES))}",
                         field="example")
    share = example_robot_data_share()
    robot = load_urdf(share / "example-robot-data" / "robots" / EXAMPLES[key], package_dirs=[share])
    robot.name = key
    return robot
