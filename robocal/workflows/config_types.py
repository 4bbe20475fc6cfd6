"""The calibration config as typed objects: what `read_config` returns and every workflow reads.

Each section of the YAML (docs/config.md) is one frozen dataclass; values are checked and converted
(paths resolved, sigmas numbers in the data's units, angles and lengths of placements in SI). `path` fields
keep the key path of a section in the file (`measurements[1]`), so that a later check against the robot or
the data still names where the mistake is. `CalibrationConfig.to_dict()` gives the YAML mapping back, with
absolute paths: written into an output folder, it rebuilds the same model from there.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

from robocal.design.candidates import MeasurementVolume
from robocal.estimation.calibrate import CalibrationOptions
from robocal.model.approach import ApproachSpec

#: a component list (tx ... rz), or True for all six, or False for none
Components = bool | tuple[str, ...]


@dataclass(frozen=True)
class Placement:
    """A rigid placement: xyz (m) and roll-pitch-yaw (rad)."""

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def to_dict(self) -> dict:
        return {"xyz": list(self.xyz), "rpy": list(self.rpy)}


@dataclass(frozen=True)
class FrameSpec:
    """A frame the config adds to the robot: its name, parent frame and placement in the parent."""

    name: str
    parent: str
    placement: Placement = Placement()


@dataclass(frozen=True)
class RobotConfig:
    """`robot:` one of a URDF file, an MJCF file (with its actuated joints; default: its <actuator> joints) or
    an example robot, its base placement and added frames."""

    urdf: Path | None = None
    example: str | None = None
    package_dirs: tuple[Path, ...] = ()
    base: Placement = Placement()
    frames: tuple[FrameSpec, ...] = ()
    mjcf: Path | None = None
    actuated: tuple[str, ...] | None = None

    def to_dict(self) -> dict:
        out: dict = ({"urdf": str(self.urdf)} if self.urdf is not None else
                     {"mjcf": str(self.mjcf)} if self.mjcf is not None else {"example": self.example})
        if self.actuated is not None:
            out["actuated"] = list(self.actuated)
        if self.package_dirs:
            out["package_dirs"] = [str(d) for d in self.package_dirs]
        if self.base != Placement():
            out["base"] = self.base.to_dict()
        if self.frames:
            out["frames"] = [{"name": f.name, "parent": f.parent, **f.placement.to_dict()} for f in self.frames]
        return out


@dataclass(frozen=True)
class Units:
    """The unit of the lengths and of the angles of a set of columns (names of io.tables' units)."""

    length: str = "m"
    angle: str = "rad"

    def as_dict(self) -> dict[str, str]:
        return {"length": self.length, "angle": self.angle}


@dataclass(frozen=True)
class SessionSpec:
    """One session of `data.sessions`: its name and its CSV (same columns as every other session's)."""

    name: str
    csv: Path


@dataclass(frozen=True)
class DataConfig:
    """`data:` the main CSV, which column holds each joint (None: every joint moving a measured frame,
    same names), the units of measurement and joint columns, the approach directions (backlash), and the
    sessions: several CSVs (`sessions`), or one CSV whose `session_column` names each row's session."""

    csv: Path | None = None
    joints: dict[str, str] | None = None
    units: Units = Units()
    joint_units: Units = Units()
    approach: ApproachSpec | None = None
    sessions: tuple[SessionSpec, ...] = ()
    session_column: str | None = None

    def to_dict(self) -> dict:
        out: dict = {}
        if self.csv is not None:
            out["csv"] = str(self.csv)
        if self.joints is not None:
            out["joints"] = dict(self.joints)
        out["units"] = self.units.as_dict()
        out["joint_units"] = self.joint_units.as_dict()
        if self.approach is not None:
            a = self.approach
            out["approach"] = {"from": a.source, **({"sort_by": a.sort_by} if a.sort_by else {}),
                               "threshold": dict(a.threshold), "initial": dict(a.initial), "columns": dict(a.columns)}
        if self.sessions:
            out["sessions"] = [{"name": s.name, "csv": str(s.csv)} for s in self.sessions]
        if self.session_column is not None:
            out["session_column"] = self.session_column
        return out


@dataclass(frozen=True)
class ParametersConfig:
    """`parameters:` which parameters the fit frees, and per-pattern fixes, initial values, priors, bounds
    (SI: m and rad). joints None: the joints moving a measured frame. per_session: the frames re-registered
    in every session (`base`, the measurement frame; robocal.estimation.sessions)."""

    preset: str = "full"
    joints: tuple[str, ...] | None = None
    frames: dict[str, Components] = field(default_factory=dict)
    base: Components = False
    compliance: Components = False
    backlash: Components = False
    tilt: Components = False
    fix: tuple[str, ...] = ()
    free: tuple[str, ...] = ()
    initial: dict[str, float] = field(default_factory=dict)
    priors: dict[str, float] = field(default_factory=dict)
    bounds: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    per_session: tuple[str, ...] = ("base",)

    def to_dict(self) -> dict:
        out: dict = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "joints" and value is None:
                continue
            out[f.name] = _plain(value)
        return out


@dataclass(frozen=True)
class CameraBlockConfig:
    """The own keys of a `type: camera` block (workflows/config_camera.py, docs/camera.md): the frame the camera
    (target) hangs on, the mount, the detections CSV, the target and camera mappings as given (checked), the
    fewest corners an image may have, and the world pose of the part not on the robot (robocal plan)."""

    attached_to: str = "tool0"
    mount: str = "eye_in_hand"
    detections: Path | tuple[Path, ...] | None = None      # a tuple: several files read as one
    target: dict = field(default_factory=dict)
    camera: dict = field(default_factory=dict)
    min_corners: int = 6
    world_pose: Placement | None = None

    def to_dict(self) -> dict:
        out = {"attached_to": self.attached_to, "mount": self.mount}
        if isinstance(self.detections, tuple):
            out["detections"] = [str(p) for p in self.detections]
        elif self.detections is not None:
            out["detections"] = str(self.detections)
        out.update({"target": _plain(self.target), "camera": _plain(self.camera), "min_corners": self.min_corners})
        if self.world_pose is not None:
            out["world_pose"] = self.world_pose.to_dict()
        return out


@dataclass(frozen=True)
class MeasurementConfig:
    """One measurement block: its type, name, measured frame, where its rows come from (csv, where), its
    columns, sigma (a number, or (position, orientation), in the data's units; None: the type's default) and
    the type's own settings (constructor keywords, e.g. point, normal, centre). samples: rows `robocal
    simulate` makes for a contact block. path: the block's key path for error messages. camera: a camera
    block's own keys (its sigma in px)."""

    type: str
    name: str
    frame: str
    path: str
    csv: Path | None = None
    where: tuple[str, object] | None = None
    columns: tuple[str, ...] = ()
    sigma: float | tuple[float, float] | None = None
    settings: dict = field(default_factory=dict)
    samples: int | None = None
    camera: CameraBlockConfig | None = None

    @property
    def moved_frame(self) -> str:
        """The robot frame whose joints move this block's frame: a camera block's may not exist before the
        set-up adds it on `attached_to`, which the same joints move."""
        return self.camera.attached_to if self.camera is not None else self.frame

    def to_dict(self) -> dict:
        out: dict = {"type": self.type, "name": self.name, "frame": self.frame}
        if self.csv is not None:
            out["csv"] = str(self.csv)
        if self.where is not None:
            out["where"] = {self.where[0]: self.where[1]}
        if self.columns:
            out["columns"] = list(self.columns)
        if self.sigma is not None:
            out["sigma"] = ({"position": self.sigma[0], "orientation": self.sigma[1]}
                            if isinstance(self.sigma, tuple) else self.sigma)
        out.update({k: _plain(v) for k, v in self.settings.items()})
        if self.samples is not None:
            out["samples"] = self.samples
        if self.camera is not None:
            out.update(self.camera.to_dict())
        return out


@dataclass(frozen=True)
class OutputConfig:
    """`output:` the default output folder and whether report.html is written."""

    dir: Path
    report: bool = True


@dataclass(frozen=True)
class SimulationConfig:
    """`simulation:` how `robocal simulate` draws a dataset: seed, samples, the perturbation spans of the true
    robot (m, rad) and values it pins."""

    seed: int = 0
    samples: int = 60
    translation: float = 2e-3
    rotation: float = 0.0034906585039886592      # 0.2 degree
    truth: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"seed": self.seed, "samples": self.samples,
                "perturb": {"translation": self.translation, "rotation": self.rotation}, "truth": dict(self.truth)}


@dataclass(frozen=True)
class CandidatesConfig:
    """`plan.candidates:` how candidate readings are drawn and screened (robocal.design.candidates)."""

    method: str = "random"
    count: int = 1000
    margin: float = 0.05
    levels: int | tuple[int, ...] = 4
    min_singular: float = 0.02
    length_scale: float = 0.5

    def to_dict(self) -> dict:
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True)
class PlanConfig:
    """`plan:` which poses `robocal plan` proposes and how it predicts their accuracy (docs/experiment_design.md).
    frame None: the first block's frame; noise: replaces every block's sigma (data units); curve None: ~8
    counts from the minimum to 2 N."""

    frame: str | None = None
    n: int = 30
    criterion: str = "D"
    seed: int = 0
    noise: float | tuple[float, float] | None = None
    candidates: CandidatesConfig = CandidatesConfig()
    volume: MeasurementVolume | None = None
    validation: int = 200
    curve: tuple[int, ...] | None = None
    output_dir: Path | None = None

    def to_dict(self) -> dict:
        out = {"frame": self.frame, "N": self.n, "criterion": self.criterion, "seed": self.seed,
               "noise": ({"position": self.noise[0], "orientation": self.noise[1]} if isinstance(self.noise, tuple)
                         else self.noise),
               "candidates": self.candidates.to_dict(), "volume": volume_dict(self.volume),
               "validation": self.validation, "curve": _plain(self.curve),
               "output": None if self.output_dir is None else {"dir": str(self.output_dir)}}
        return {k: v for k, v in out.items() if v is not None}


@dataclass(frozen=True)
class Iso9283Config:
    """`iso9283:` the pose-label column, the pose block of attained poses, the commanded pose columns and the
    distance pairs (docs/validation.md)."""

    pose_id: str
    measurement: str | None = None
    commanded: tuple[str, ...] | None = None
    distance_pairs: tuple[tuple[str, str], ...] | None = None

    def to_dict(self) -> dict:
        return {f.name: _plain(getattr(self, f.name)) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class CalibrationConfig:
    """A whole calibration YAML, checked. source: the file (for messages); base_dir: its folder."""

    source: str
    base_dir: Path
    robot: RobotConfig
    data: DataConfig
    parameters: ParametersConfig
    measurements: tuple[MeasurementConfig, ...]
    solver: CalibrationOptions
    output: OutputConfig
    simulation: SimulationConfig | None = None
    plan: PlanConfig | None = None
    iso9283: Iso9283Config | None = None

    @property
    def frames(self) -> list[str]:
        """The measured frame of every block, in order (a camera block: the frame its camera or target hangs on,
        moved by the same joints)."""
        return [m.moved_frame for m in self.measurements]

    def to_dict(self) -> dict:
        """The YAML mapping of this config, paths absolute: it rebuilds the same model from anywhere."""
        defaults = CalibrationOptions()
        out = {"robot": self.robot.to_dict(), "data": self.data.to_dict(), "parameters": self.parameters.to_dict(),
               "measurements": [m.to_dict() for m in self.measurements],
               "solver": {f.name: getattr(self.solver, f.name) for f in fields(self.solver)
                          if getattr(self.solver, f.name) != getattr(defaults, f.name)},
               "output": {"dir": str(self.output.dir), "report": self.output.report}}
        for key in ("simulation", "plan", "iso9283"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key).to_dict()
        return out


def volume_dict(volume: MeasurementVolume | None) -> dict | None:
    """The `plan.volume` mapping of a measurement volume (MeasurementVolume.from_dict reads it back)."""
    if volume is None:
        return None
    out: dict = {}
    if volume.box is not None:
        out["box"] = {"min": [float(x) for x in volume.box[0]], "max": [float(x) for x in volume.box[1]]}
    if volume.center is not None:
        out["sphere"] = {"center": [float(x) for x in volume.center], "max_range": float(volume.max_range),
                         "min_range": float(volume.min_range)}
    return out


def _plain(value):
    """A YAML-ready copy: tuples to lists, recursively."""
    if isinstance(value, (tuple, list)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value
