"""What a camera calibration found, in the terms a camera user reads (docs/camera.md): hand_eye.json.

The frame on the robot (the camera eye-in-hand, the target eye-to-hand) relative to the frame it hangs on, the
fixed object's pose in the world (the target, or the camera), which of the two is the hand-eye transform, the
intrinsics with their standard errors, each image's pixel RMS after the fit and how the fit was started.
Placements as xyz (m), roll-pitch-yaw (rad) and a quaternion (x, y, z, w); standard errors of the placement
parameters are of the local twist components (m, rad).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.estimation.camera_block import CameraSetup
from robocal.estimation.problem import Problem
from robocal.model.parameters import COMPONENTS
from robocal.residuals.reprojection import POSE_SUFFIXES, pose_of


def placement_dict(M: pin.SE3, stderr: dict[str, float | None] | None = None) -> dict:
    out = {"xyz": M.translation.tolist(), "rpy": pin.rpy.matrixToRpy(M.rotation).tolist(),
           "quaternion_xyzw": pin.Quaternion(M.rotation).coeffs().tolist()}
    if stderr:
        out["stderr"] = stderr
    return out


def image_rms(problem: Problem, setup: CameraSetup) -> dict[int, tuple[int, float]]:
    """{sample index: (corners, RMS pixel error per corner)} at the problem's current values."""
    res = setup.residual
    aux = problem.aux_values(res)
    states = problem.states()
    out = {}
    for i in np.unique(res.samples):
        terms = np.flatnonzero(res.samples == i)
        M = states[int(i)].pose(res.frame)
        uv = res.predict(terms, np.broadcast_to(M.rotation, (len(terms), 3, 3)),
                         np.broadcast_to(M.translation, (len(terms), 3)), aux)
        e = uv - res.measurements[terms]
        out[int(i)] = (len(terms), float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))))
    return out


def camera_summary(problem: Problem, setup: CameraSetup) -> dict:
    """The hand_eye.json entry of one camera block at the problem's current values (module docstring)."""
    res, params = setup.residual, problem.params
    aux = problem.aux_values(res)
    s = problem.model_state().sample(problem.values[int(res.samples[0])])
    on_robot = s.pose(setup.attached_to).inverse() * s.pose(setup.frame)
    fixed = pose_of(aux[res.n_intrinsics:])

    def stderr(names):
        return {n.rsplit(".", 1)[-1]: params[n].stderr for n in names if n in params and params[n].vary}

    in_hand = res.mount == "eye_in_hand"
    intrinsics = {}
    for n, v in zip(res.camera.names, aux[:res.n_intrinsics]):
        p = params[f"{res.name}.{n}"]
        intrinsics[n] = {"value": float(v), "stderr": p.stderr if p.vary else None, "free": bool(p.vary),
                         "unit": p.unit or "1"}
    return {
        "name": res.name, "mount": res.mount, "model": res.camera.model,
        "image_size": [res.camera.width, res.camera.height],
        "hand_eye": (f"frame: the camera '{setup.frame}' relative to '{setup.attached_to}'" if in_hand
                     else "fixed: the camera's pose in the world"),
        "frame": {"name": setup.frame, "relative_to": setup.attached_to,
                  "what": "camera" if in_hand else "target",
                  **placement_dict(on_robot, stderr([f"{setup.frame}.{c}" for c in COMPONENTS]))},
        "fixed": {"what": ("target in the world" if in_hand else "camera in the world")
                  + (f" (session '{problem.sessions.names[0]}'; the others' placements: result.json sessions, "
                     "their frame corrections)" if problem.sessions is not None and problem.sessions.corrected
                     else ""),
                  **placement_dict(fixed, stderr([f"{res.pose_prefix}.{c}" for c in POSE_SUFFIXES]))},
        "intrinsics": intrinsics,
        "images": [{"sample": setup.labels.get(i, str(i + 1)), "corners": n, "rms_px": e}
                   for i, (n, e) in image_rms(problem, setup).items()],
        "start": {"hand_eye_method": setup.hand_eye.method, "spread_m": setup.hand_eye.spread[0],
                  "spread_rad": setup.hand_eye.spread[1]},
        "notes": list(setup.notes),
        "units": "m, rad, px; stderr of the placements: local twist components",
    }
