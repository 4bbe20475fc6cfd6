"""What a visual check needs that result.json does not hold: the scene file of a calibration output.

`scene_bytes(problem, result, params_before)` evaluates the model twice (the parameters before and after
the fit) on every sample and records, in SI units:
  - the world pose of every link (and of every measured frame) per sample, before and after, and the
    skeleton drawn without meshes (robocal.viz.skeleton_layout), before and after;
  - per measurement block and term: the sample(s) it uses, the measured point(s), the model's
    prediction(s) and the raw residual vector, before and after, plus the measurement artefact (plane,
    sphere, cylinder, ball bar, laser line, sphere artefact) at its initial and estimated values; pose
    blocks also hold the measured and predicted orientations;
  - the identification Jacobian's singular values and the rank the base-parameter selection kept.

Poses of a serial robot come from the batched kinematics (robocal.model.batch_kinematics, all samples at
once); any other robot's from `SampleState.pose(frame)`, so a closed-chain machine (whose SampleState
assembles its loops) is recorded exactly like a serial arm. Nothing here loads meshes: the viewer does that.
Version 2 added the skeleton and `terms`; `read_scene` fills both in for a version-1 file. Version 3 added a
camera block's points (the detected pixel's ray at the corner's depth, the corner) and its `camera` entry
(robocal.viz.camera_scene); versions 1 and 2 have no camera blocks, so they read unchanged.
"""
from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np
import pinocchio as pin

from robocal.errors import InputError
from robocal.io.wording import plural
from robocal.model.batch_kinematics import BatchKinematics, supports_batch
from robocal.model.kinematics import ModelState
from robocal.model.lie_arrays import quaternions
from robocal.estimation.prediction_errors import subset_residual
from robocal.estimation.sessions import corrections, session_arrays
from robocal.residuals.base import tilted_direction
from robocal.viz.camera_scene import camera_entry, camera_points, undistorted
from robocal.viz.skeleton_layout import skeleton, skeleton_from_links
from robocal.residuals.sphere_fit import fit_sphere

log = logging.getLogger(__name__)

FORMAT = "robocal-scene"
VERSION = 3
SUPPORTED = (1, 2, 3)
STATES = ("before", "after")
# A scene draws at most this many samples: at 10000 UR5 poses scene.json is already ~37 MB and takes ~2 s,
# and a million would be gigabytes that no browser draws. Beyond it, evenly spaced samples are drawn, the
# scene says so ("drawn") and the command line says it too.
MAX_SAMPLES = 10000


def drawn_samples(n: int) -> np.ndarray:
    """The samples a scene draws: all of n up to MAX_SAMPLES, else MAX_SAMPLES evenly spaced (the first and
    the last included; deterministic)."""
    if n <= MAX_SAMPLES:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, MAX_SAMPLES)).astype(int))


def scene_note(problem) -> str | None:
    """What the scene of `problem` (a Problem or a config Setup) leaves out, or None when it draws everything."""
    n = len(getattr(problem, "problem", problem).values)
    if n <= MAX_SAMPLES:
        return None
    return (f"scene.json (the 3D check and the report's point plots) draws {MAX_SAMPLES} of the {n} samples, "
            "evenly spaced; every figure in result.json uses all of them")


def samples_phrase(scene: dict) -> str:
    """How many samples a scene holds, in words: "12 samples", or "5 of 12 samples drawn (evenly spaced)"."""
    drawn, n = scene.get("drawn"), len(scene["values"])
    return f"{n} of {plural(drawn['of'], 'sample')} drawn (evenly spaced)" if drawn else plural(n, "sample")


def _pose7(M: pin.SE3) -> list[float]:
    return [*M.translation.tolist(), *pin.Quaternion(M.rotation).coeffs().tolist()]


def link_tree(robot) -> list[dict]:
    """Links (BODY frames) with their parent link, root first: the skeleton drawn without meshes."""
    frames = robot.model.frames
    out = []
    for fid, f in enumerate(frames):
        if f.type != pin.FrameType.BODY:
            continue
        k, parent = f.parentFrame, None
        while k != 0 and k != fid:
            if frames[k].type == pin.FrameType.BODY:
                parent = frames[k].name
                break
            k = frames[k].parentFrame
        out.append({"name": f.name, "parent": parent})
    return out


def _aux(params, res) -> np.ndarray:
    """A residual's auxiliary values from a parameter set (its own initial values where absent)."""
    return np.array([params[p.name].value if p.name in params else p.value for p in res.aux_parameters()])


# ---- per measurement type: (measured points, predicted points) of a term, world frame --------------
def _points(res, k, M, aux, rays=None) -> tuple[np.ndarray, np.ndarray]:
    """rays: a camera block's undistorted pixels (camera_scene.undistorted), computed once per state."""
    t = res.type_name
    if t == "pose":
        return res.measurements[k, None, :3], M.translation[None, :]
    if t == "point":
        return res.measurements[k, None, :], M.act(aux[:3])[None, :]
    if t == "rigid_points":
        P = aux.reshape(-1, 3)
        return res.measurements[k].reshape(-1, 3), P @ M.rotation.T + M.translation
    if t == "plane":
        x = M.act(aux[3:6])
        n = res.normal(aux)
        r = n @ x - aux[2] - res.tip_radius
        return (x - r * n)[None, :], x[None, :]
    if t in ("sphere", "ball_bar"):
        c = aux[:3]
        x = M.act(aux[4:7])
        e = (x - c) / np.linalg.norm(x - c)
        length = aux[3] + res.tip_radius if t == "sphere" else res.measurements[k, 0] + aux[3]
        return (c + length * e)[None, :], x[None, :]
    if t == "cylinder":
        a, u = res.axis(aux)
        x = M.act(aux[5:8])
        w = x - a
        perp = w - (w @ u) * u
        h = np.linalg.norm(perp)
        touch = aux[4] + res.contact_sign * res.tip_radius
        return (x - (h - touch) * perp / h)[None, :], x[None, :]
    if t == "laser_line":
        P, o = aux[:3], M.act(aux[3:6])
        u = M.rotation @ tilted_direction(res.R0, aux[6], aux[7])[0]
        return P[None, :], (o + ((P - o) @ u) * u)[None, :]
    if t == "camera":
        return camera_points(res, k, M, aux, None if rays is None else rays[k])
    return np.zeros((0, 3)), np.zeros((0, 3))


def _artefact_hits(res, k, states, aux) -> tuple[np.ndarray, np.ndarray, list]:
    """A sphere-artefact placement: (measured, predicted) per hit, in term_samples order, and the fitted
    centres. Predicted: the probe point; measured: where it would be on a sphere of the certified radius
    about the fitted centre (as for a single sphere), so each arrow is that hit's radial error."""
    meas, pred, centres = [], [], []
    for j, hits in enumerate(res.placements[k]):
        X = np.array([states[int(i)].pose(res.frame).act(res.point) for i in hits])
        c = fit_sphere(X, source=f"{res.name}, placement {k}, sphere {j}").centre
        e = (X - c) / np.linalg.norm(X - c, axis=1, keepdims=True)
        meas.append(c + (aux[j] + aux[-1]) * e)
        pred.append(X)
        centres.append(c.tolist())
    return np.vstack(meas), np.vstack(pred), centres


def _artefact(res, aux) -> dict | None:
    t = res.type_name
    if t == "plane":
        n = res.normal(aux)
        return {"kind": "plane", "normal": n.tolist(), "offset": float(aux[2])}
    if t == "sphere":
        return {"kind": "sphere", "centre": aux[:3].tolist(), "radius": float(aux[3])}
    if t == "cylinder":
        a, u = res.axis(aux)
        return {"kind": "cylinder", "point": a.tolist(), "direction": u.tolist(), "radius": float(aux[4])}
    if t == "ball_bar":
        return {"kind": "ball_bar", "centre": aux[:3].tolist()}
    if t == "laser_line":
        return {"kind": "laser_line", "target": aux[:3].tolist()}
    if t == "sphere_artefact":     # the fitted centres are added per placement
        return {"kind": "sphere_artefact", "radii": aux[:res.n_spheres].tolist(), "centres": []}
    return None


def identification(result) -> dict:
    """The identification summary of a CalibrationResult, as the scene records it."""
    sel = result.selection
    return {"singular_values": np.asarray(sel.singular_values, float).tolist(), "rank": sel.rank,
            "requested": len(result.requested), "rtol": sel.rtol, "condition": result.condition}


def _block(res, states, param_sets, position: np.ndarray) -> dict:
    """position: a problem sample's index among the drawn samples (the scene's numbering)."""
    block = {"name": res.name, "type": res.type_name, "frame": getattr(res, "frame", None),
             "samples": position[np.asarray(res.samples, dtype=int)].tolist(),
             "terms": [position[list(res.term_samples(k))].tolist() for k in range(res.n_terms)],
             "row_units": list(res.row_units), "sigma": res.sigma.tolist()}
    for s in STATES:
        aux = _aux(param_sets[s], res)
        art = _artefact(res, aux) if hasattr(res, "frame") else None
        meas, pred, rows, beams = [], [], [], []
        rays = undistorted(res, aux) if res.type_name == "camera" else None
        poses = []                 # camera: the rows in one evaluate_batch below (per term: 2 x 1080 calls, 0.1 s)
        for k in range(res.n_terms):
            if rays is None:
                rows.append(res.evaluate(k, states[s], aux).r.tolist())
            if res.type_name == "sphere_artefact":
                m, p, centres = _artefact_hits(res, k, states[s], aux)
                art["centres"].append(centres)
            elif len(res.term_samples(k)) == 1 and hasattr(res, "frame"):
                M = states[s][int(res.term_samples(k)[0])].pose(res.frame)
                m, p = _points(res, k, M, aux, rays)
                if rays is not None:
                    poses.append(M)
                if res.type_name == "laser_line":
                    beams.append(M.act(aux[3:6]).tolist())   # where the beam leaves the tool
            else:
                continue
            meas.append(m.tolist())
            pred.append(p.tolist())
        if rays is not None:
            R, t = np.array([M.rotation for M in poses]), np.array([M.translation for M in poses])
            rows = res.evaluate_batch(slice(0, res.n_terms), R, t, aux).r.tolist()
        block[f"measured_{s}"] = meas
        block[f"predicted_{s}"] = pred
        block[f"residual_{s}"] = rows
        block[f"artefact_{s}"] = art
        if beams:
            block[f"beam_origin_{s}"] = beams
        if res.type_name == "pose":
            block[f"orientation_{s}"] = [pin.Quaternion(states[s][int(i)].pose(res.frame).rotation).coeffs().tolist()
                                         for i in res.samples]
    if res.type_name == "pose":
        block["measured_orientation"] = res.measurements[:, 3:7].tolist()
    if res.type_name == "camera":
        block["camera"] = camera_entry(res, {s: _aux(param_sets[s], res) for s in STATES})
    if not block["measured_after"]:
        log.info("block %s (%s): no points to draw for this measurement type", res.name, res.type_name)
    return block


def scene_data(problem, result, params_before, ident: dict | None = None) -> dict:
    """The scene of a calibration as plain data (see module doc). `problem` may be a config Setup;
    `ident` replaces `identification(result)` (result may then be None)."""
    problem = getattr(problem, "problem", problem)
    robot = problem.robot
    links = link_tree(robot)
    measured_frames = [f for f in dict.fromkeys(getattr(r, "frame", None) for r in problem.residuals) if f]
    # closed chains: each closure's two anchor frames, to draw the links reaching them and the joint
    closures = [{"name": c.name, "frames": [c.frame1, c.frame2],
                 "links": [robot.model.frames[robot.model.frames[robot.frame_id(f)].parentFrame].name
                           for f in (c.frame1, c.frame2)]}
                for c in (robot.loops.closures if robot.loops is not None else [])]
    anchors = [f for c in closures for f in c["frames"]]
    frame_names = list(dict.fromkeys([lk["name"] for lk in links] + measured_frames + anchors))
    param_sets = {"before": params_before, "after": problem.params}
    models = {s: ModelState(robot, p, problem.joint_names) for s, p in param_sets.items()}
    # each sample drawn in its own session's measurement frame; closed chains assemble from the fit's solutions
    states = {s: problem.states(ms, param_sets[s]) for s, ms in models.items()}
    for ms in models.values():            # a copy: drawing must not move the fit's own warm starts
        ms.warm_starts = dict(problem.warm_starts)
    n = len(problem.values)
    drawn = drawn_samples(n)
    position = np.full(n, -1)
    position[drawn] = np.arange(len(drawn))
    residuals = problem.residuals if len(drawn) == n else [subset_residual(r, drawn) for r in problem.residuals]
    poses = {s: frame_poses(problem, models[s], states[s], frame_names, drawn, param_sets[s]) for s in STATES}
    out = {
        "format": FORMAT, "version": VERSION, "units": "SI (m, rad)",
        "robot": {"name": robot.name, "urdf_path": str(robot.urdf_path) if robot.urdf_path else None,
                  "package_dirs": list(robot.package_dirs), "links": links,
                  "closed_chain": robot.loops is not None, "closures": closures,
                  "skeleton": {s: skeleton(robot, models[s].model, links) for s in STATES}},
        "joint_names": list(problem.joint_names),
        "values": problem.values[drawn].tolist(),
        "frames": frame_names,
        "poses": poses,
        "blocks": [_block(res, states, param_sets, position) for res in residuals],
        "identification": ident if ident is not None else identification(result),
    }
    if len(drawn) < n:      # which samples of the problem these are (its numbering, from 0)
        out["drawn"] = {"of": n, "samples": drawn.tolist()}
    return out


def frame_poses(problem, ms: ModelState, states, frame_names: list[str],
                samples: np.ndarray | None = None, params=None) -> list:
    """[sample][frame] -> [x, y, z, qx, qy, qz, qw] world poses at `samples` (default all, increasing): all at
    once for a serial robot (robocal.model.batch_kinematics; with sessions, each sample in its session's frame
    at the corrections of `params`, default the problem's, as `states` holds them), else sample by sample
    (closed chains assemble their loops there)."""
    samples = np.arange(len(problem.values)) if samples is None else np.asarray(samples, dtype=int)
    if not supports_batch(ms):
        return [[_pose7(states[int(i)].pose(f)) for f in frame_names] for i in samples]
    batch = BatchKinematics(ms, problem.sample_constants(ms), problem.values, problem.directions)
    sessions = problem.sessions if getattr(problem.sessions, "corrected", False) else None
    T = corrections(sessions, params or problem.params) if sessions is not None else None
    out = np.empty((len(samples), len(frame_names), 7))
    for k, f in enumerate(frame_names):
        fa = batch.frame(f, samples, jacobian=False)
        R, p = (fa.R, fa.p) if T is None else session_arrays(fa.R, fa.p, T, sessions.of_sample[samples])
        out[:, k, :3], out[:, k, 3:] = p, quaternions(R)
    return out.tolist()


def scene_bytes(problem, result, params_before) -> bytes:
    """scene.json content for `write_results(..., extra={"scene.json": ...})`."""
    return scene_json(scene_data(problem, result, params_before))


def scene_json(scene: dict) -> bytes:
    """scene.json content of a scene_data dict (keep the dict for the report: no second parse)."""
    return json.dumps(scene, separators=(",", ":")).encode("utf-8")


def read_scene(path: str | Path) -> dict:
    """Load and check a scene.json (a file, or a result folder holding one)."""
    path = Path(path)
    if path.is_dir():
        path = path / "scene.json"
    if not path.is_file():
        raise InputError("no scene.json: this result was written without visual-check data "
                         "(re-run `robocal calibrate` with a version that writes it)", source=str(path))
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", source=str(path), row=exc.lineno) from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"not a robocal scene file (expected format '{FORMAT}')", source=str(path), field="format")
    if data.get("version") not in SUPPORTED:
        raise InputError(f"scene file version {data.get('version')} is not supported (expected one of "
                         f"{', '.join(map(str, SUPPORTED))})", source=str(path), field="version")
    for key in ("robot", "frames", "poses", "blocks", "values", "identification"):
        if key not in data:
            raise InputError("required key is missing", source=str(path), field=key)
    n = len(data["values"])
    for s in STATES:
        if len(data["poses"].get(s, [])) != n:
            raise InputError(f"poses.{s} must have one entry per sample ({n})", source=str(path), field=f"poses.{s}")
    return upgrade(data)


def upgrade(data: dict) -> dict:
    """An older scene in the current layout: version 1 gets the skeleton from the link origins and one sample per
    term; version 2 needs nothing (it has no camera blocks)."""
    if data.get("version") == 1:
        data["robot"]["skeleton"] = {s: skeleton_from_links(data, s) for s in STATES}
        for b in data["blocks"]:
            b["terms"] = [[i] for i in b["samples"]]
    data["version"] = VERSION
    return data
