"""Calibrating a Stewart platform (docs/stewart_calibration.md): its 42 parameters, strut data, identifiability words.

Parameters (names of the generic kinds, see robocal.systems.stewart.mechanism):
  N_j  base joint        leg{j}_u1.tx/ty/tz        (translation of the joint placement, u1 frame)
  T_j  platform joint    leg{j}_top.link2.tx/ty/tz (platform frame)
  o_j  strut offset      leg{j}_slide.offset       (joint-to-joint length = o_j + s_j)
The measurement frame is the reference coordinate system (RCS); the tool tip tau = (0, 0, -L).

Strut data come from the NC (readings) or from its posture commands converted with the NC's current
parameters (`commands_to_struts`, claims 12 and 14). Synthetic data (docs/stewart_calibration.md): the tool is put
physically on the reference object, so the struts are the true machine's closed-form IK of that pose.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.estimation.identifiability import BaseSelection, select_base_parameters
from robocal.model.kinematics import ModelState
from robocal.systems.stewart.fk import forward_kinematics
from robocal.systems.stewart.mechanism import StewartGeometry, geometry_from_model, inverse_kinematics
from robocal.model.parameters import ParameterSet, offset_parameter, placement_parameters
from robocal.systems.stewart.modes import Tool, numeric_rows, rotation

LEGS = 6


def stewart_parameters(fix_platform_joints: bool = False) -> ParameterSet:
    """The 42 parameters, all at 0 (nominal); T fixed (mode 1 with a CMM-measured T) on request."""
    ps = ParameterSet()
    for j in range(1, LEGS + 1):
        for p in placement_parameters("joint_placement", f"leg{j}_u1", ("tx", "ty", "tz")):
            ps.add(p)
    for j in range(1, LEGS + 1):
        for p in placement_parameters("frame_placement", f"leg{j}_top.link2", ("tx", "ty", "tz")):
            p.vary = not fix_platform_joints
            ps.add(p)
    for j in range(1, LEGS + 1):
        ps.add(offset_parameter(f"leg{j}_slide", "m"))
    return ps


def actuated(robot) -> list[str]:
    return list(robot.loops.actuated)


def geometry(robot, params: ParameterSet) -> StewartGeometry:
    """Closed-form geometry (N, T, o, tool) of the model at `params` (strut offsets included in o)."""
    ms = ModelState(robot, params, actuated(robot))
    g = geometry_from_model(robot, ms.model)
    o = g.offsets + ms.offsets
    return StewartGeometry(g.base_joints, g.platform_joints, g.legs, o, g.tool, g.home)


def tip_to_platform(tips, R, tool: Tool) -> list[pin.SE3]:
    """Platform poses whose tool tip is at tips (K, 3) with rotations R (K, 3, 3)."""
    return [pin.SE3(Rk, t - Rk @ tool.tip) for t, Rk in zip(np.asarray(tips, float).reshape(-1, 3), R)]


def struts(geo: StewartGeometry, poses: list[pin.SE3]) -> np.ndarray:
    """(K, 6) strut coordinates s of platform poses (closed-form IK)."""
    return np.array([inverse_kinematics(geo, M) for M in poses])


def commands_to_struts(commands, nc_geometry: StewartGeometry, tool: Tool, convention: str = "xyz_intrinsic",
                       source: str = "commands") -> np.ndarray:
    """Claims 12, 14: strut coordinates the NC drove for posture commands (K, 6) X Y Z A B C (m, rad),
    i.e. IK(command, x_NC) with the NC's current parameters: exactly the strut readings it stored."""
    m = numeric_rows(commands, 6, source)
    R = np.array([rotation(r[3:], convention) for r in m])
    return struts(nc_geometry, tip_to_platform(m[:, :3], R, tool))


def forward_pose(geo: StewartGeometry, s, tool: Tool, guess: pin.SE3 | None = None, sample=None) -> pin.SE3:
    """Platform pose reached with strut coordinates s (closed-form Newton FK)."""
    return forward_kinematics(geo, s, guess=guess, sample=sample)


def tip_errors(true_geo: StewartGeometry, model_geo: StewartGeometry, tool: Tool, tips, R) -> np.ndarray:
    """Tool-tip position errors (K,) (m) of a model over validation poses: the true machine is put at
    (tips, R); the model computes the tip by FK from the struts the true machine reads there."""
    poses = tip_to_platform(tips, R, tool)
    out = []
    for k, M in enumerate(poses):
        est = forward_kinematics(model_geo, inverse_kinematics(true_geo, M), guess=M, sample=k)
        out.append(np.linalg.norm(est.act(tool.tip) - M.act(tool.tip)))
    return np.array(out)


# ---- synthetic acquisition plans (docs/stewart_calibration.md): tool-tip centres on the reference objects
def random_tips(n: int, rng: np.random.Generator, xy: float = 0.15, z=(0.25, 0.45)) -> np.ndarray:
    """(n, 3) tool tips uniform in the spec workspace (x, y in +-xy, z in `z`, m)."""
    return np.column_stack([rng.uniform(-xy, xy, n), rng.uniform(-xy, xy, n), rng.uniform(z[0], z[1], n)])


def random_orientations(n: int, rng: np.random.Generator, degrees: float = 15.0,
                        convention: str = "xyz_intrinsic") -> tuple[np.ndarray, np.ndarray]:
    """Angles (n, 3) uniform in +-degrees (rad) and their rotations (n, 3, 3)."""
    abc = np.radians(rng.uniform(-degrees, degrees, (n, 3)))
    return abc, np.array([rotation(a, convention) for a in abc])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _perpendicular(a: np.ndarray, n: int, rng) -> np.ndarray:
    w = rng.normal(size=(n, 3))
    w -= np.outer(w @ a, a)
    return _unit(w)


def plane_tips(point, normal, tool: Tool, n: int, rng, span: float = 0.08) -> np.ndarray:
    """Tip centres touching a plane: random points within +-span of `point`, lifted r along the normal."""
    nrm = _unit(normal)
    w = _perpendicular(nrm, n, rng) * rng.uniform(0, span, (n, 1))
    return np.asarray(point, dtype=float) + w + tool.tip_radius * nrm


def cylinder_tips(centre, axis, radius: float, tool: Tool, n: int, rng, kind: str = "hole",
                  depth: float = 0.03) -> np.ndarray:
    """Tip centres touching a hole (at R - r from the axis) or a pin (R + r), up to `depth` along it."""
    a = _unit(axis)
    rho = radius - tool.tip_radius if kind == "hole" else radius + tool.tip_radius
    return np.asarray(centre, float) + np.outer(rng.uniform(0, depth, n), a) + rho * _perpendicular(a, n, rng)


def sphere_tips(centre, distance, n: int, rng, min_up: float = 0.3) -> np.ndarray:
    """Points at `distance` (scalar or (n,)) from `centre` in directions with z component >= min_up
    (a ball touched from above: distance R + r; a ball bar's movable ball: its true length)."""
    v = np.zeros((0, 3))
    while len(v) < n:
        w = _unit(rng.normal(size=(4 * n, 3)))
        v = np.vstack([v, w[w[:, 2] >= min_up]])
    return np.asarray(centre, float) + np.asarray(distance, float).reshape(-1, 1) * v[:n]


# ---- identifiability in the machine's words ---------------------------------------------------
def _direction(params: ParameterSet, robot, dN=None, dT=None, extra: dict | None = None) -> np.ndarray:
    """A parameter-space direction (over params.free_names) from world shifts dN (6, 3) of the base
    joints and platform-frame shifts dT (6, 3) of the platform joints."""
    free = params.free_names
    v = np.zeros(len(free))
    col = {n: i for i, n in enumerate(free)}
    for j in range(LEGS):
        if dN is not None:
            Ru1 = robot.model.jointPlacements[robot.joint_id(f"leg{j + 1}_u1")].rotation
            for c, d in zip(("tx", "ty", "tz"), Ru1.T @ dN[j]):
                if f"leg{j + 1}_u1.{c}" in col:
                    v[col[f"leg{j + 1}_u1.{c}"]] = d
        if dT is not None:
            for c, d in zip(("tx", "ty", "tz"), dT[j]):
                if f"leg{j + 1}_top.link2.{c}" in col:
                    v[col[f"leg{j + 1}_top.link2.{c}"]] = d
    for n, d in (extra or {}).items():
        if n in col:
            v[col[n]] = d
    return v


def null_directions(J: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
    """(n, k) orthonormal basis of the numerical null space of the column-scaled J (relative
    singular-value threshold rtol; docs/stewart_calibration.md), in the scaled coordinates, and the scales."""
    scale = np.linalg.norm(J, axis=0)
    scale[scale == 0] = 1.0
    _, s, Vt = np.linalg.svd(J / scale, full_matrices=True)
    k = int(np.sum(s > rtol * s[0])) if len(s) else 0
    return (Vt[k:].T, scale)


def explain(J: np.ndarray, robot, params: ParameterSet, tool: Tool, centres=(), normals=(),
            rtol: float = 1e-10) -> list[str]:
    """Sentences naming the machine motions the data cannot see (each checked against the null
    space of J over params.free_names), then the count of unexplained null directions."""
    basis, scale = null_directions(J, rtol)
    n_null = basis.shape[1]
    free = params.free_names
    lines = [f"{len(free) - n_null} of {len(free)} free parameters are determined "
             f"({n_null} null direction{'s' if n_null != 1 else ''})."]
    if n_null == 0:
        return lines
    nom = geometry(robot, params)
    N, T = np.array(nom.leg_base), np.array(nom.leg_platform) - tool.tip
    candidates = [("spinning the platform joints T about the tool axis (C is not measured)",
                   _direction(params, robot, dT=np.cross([0, 0, 1.0], T)))]
    for axis, label in zip(np.eye(3)[:2], "XY"):
        candidates.append((f"rotating the platform joints T about the tool tip (about the platform {label} axis)",
                           _direction(params, robot, dT=np.cross(axis, T))))
    for k, c in enumerate(centres):
        for axis, label in zip(np.eye(3), "XYZ"):
            candidates.append((f"rotating the base joints N about centre {k + 1} (about RCS {label})",
                               _direction(params, robot, dN=np.cross(axis, N - np.asarray(c)))))
    for k, n in enumerate(normals):
        candidates.append((f"rotating the base joints N about the normal of plane {k + 1}",
                           _direction(params, robot, dN=np.cross(np.asarray(n), N))))
    for axis, label in zip(np.eye(3), "XYZ"):
        candidates.append((f"translating all base joints N along RCS {label}",
                           _direction(params, robot, dN=np.tile(axis, (LEGS, 1)))))
    for j in range(LEGS):
        for axis, label in zip(np.eye(3), "XYZ"):
            d = np.zeros((LEGS, 3))
            d[j] = axis
            candidates.append((f"shifting base joint N{j + 1} together with platform joint T{j + 1} along {label} "
                               "(constant orientation)", _direction(params, robot, dN=d, dT=d)))
    seen = np.zeros((len(free), 0))
    for text, v in candidates:
        w = v * scale
        if not np.any(w):
            continue
        w /= np.linalg.norm(w)
        if np.linalg.norm(basis.T @ w) > 1 - 1e-6:
            if seen.shape[1] and np.linalg.norm(w - seen @ np.linalg.lstsq(seen, w, rcond=None)[0]) < 1e-6:
                continue      # a combination of motions already named
            lines.append(f"The data cannot see {text}.")
            seen = np.column_stack([seen, w])
    rest = n_null - seen.shape[1]
    if rest > 0:
        lines.append(f"{rest} further null direction{'s' if rest > 1 else ''} combine several parameters.")
    return lines


def identifiability(problem, rtol: float = 1e-8) -> BaseSelection:
    """The core's deterministic base-parameter selection at the current parameters."""
    ev = problem.evaluate()
    return select_base_parameters(ev.J, problem.params.free_names, rtol)


def check_readings(s, source: str = "struts") -> np.ndarray:
    """(K, 6) strut readings; InputError naming the row and field of a bad value."""
    m = numeric_rows(s, LEGS, source)
    return m


__all__ = ["stewart_parameters", "actuated", "geometry", "commands_to_struts", "tip_errors", "explain", "identifiability",
           "null_directions", "struts", "tip_to_platform", "check_readings",
           "forward_pose", "random_tips", "random_orientations", "plane_tips", "cylinder_tips", "sphere_tips"]
