"""A camera's view of a target: pixel of each detected corner (docs/camera.md).

One term per detected corner: r = project(X) - (u, v), X the corner in the camera frame, in pixels.
mount eye_in_hand: the residual's frame is the camera (on the robot: its placement is the hand-eye transform);
                   the target is fixed in the world, at an unknown pose `<name>.target.{x,y,z,rx,ry,rz}`.
mount eye_to_hand: the residual's frame is the target (on the robot); the camera is fixed in the world, at an
                   unknown pose `<name>.camera.{x,y,z,rx,ry,rz}` (the hand-eye transform of this mount).
The fixed pose is a translation and a rotation vector (R = exp3(r)). The intrinsics `<name>.fx`, `.fy`, `.cx`,
`.cy` and the distortion coefficients (robocal.residuals.camera_model) are auxiliary parameters too: fixed,
free, or free with a prior (a prior intrinsic calibration). Pixel sigma per row, or per corner (term_scale).
Camera frame: OpenCV's (x right, y down, z along the optical axis).
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from robocal.model import lie_arrays
from robocal.model.lie_arrays import skew
from robocal.model.parameters import Parameter
from robocal.residuals.base import Aux, BatchTerms, Residual, Term
from robocal.residuals.camera_model import CameraModel

MOUNTS = ("eye_in_hand", "eye_to_hand")
POSE_SUFFIXES = ("x", "y", "z", "rx", "ry", "rz")
# physical scale of intrinsics (how far they are from a prior calibration or a nominal datasheet value): focal
# lengths 1 %, principal point 1 % of the image's larger side, radial terms 0.05, tangential 0.005; determined
# at a hundredth of that, as lengths and angles are (docs/validation.md)
FOCAL_FRACTION, CENTRE_FRACTION, RADIAL_SCALE, TANGENTIAL_SCALE = 0.01, 0.01, 0.05, 0.005
DETERMINED_FRACTION = 0.01


def pose_vector(M: pin.SE3) -> np.ndarray:
    """[x, y, z, rx, ry, rz] of a pose (rotation vector)."""
    return np.concatenate([M.translation, pin.log3(M.rotation)])


def pose_of(v) -> pin.SE3:
    v = np.asarray(v, dtype=float)
    return pin.SE3(pin.exp3(v[3:6]), v[:3].copy())


class ReprojectionResidual(Residual):
    type_name = "camera"

    def __init__(self, name, frame, samples, measurements, corners, points, camera: CameraModel, intrinsics,
                 mount="eye_in_hand", fixed_pose=None, intrinsics_free=True, intrinsics_prior=None,
                 pose_free=True, sigma=0.5, term_sigma=None, weights=None, columns=None):
        """corners (n,) corner id of each term, points (n, 3) that corner on the target (m); measurements (n, 2)
        pixels; fixed_pose the world pose (SE3 or 6-vector) of the target (eye_in_hand) or the camera
        (eye_to_hand); intrinsics_free True, False or a list of names; intrinsics_prior {name: sigma} around the
        given values; term_sigma (n,) pixel sigma per corner (else `sigma` for all)."""
        super().__init__(name, samples, sigma, weights)
        if mount not in MOUNTS:
            raise ValueError(f"camera '{name}': mount must be one of {', '.join(MOUNTS)}, got {mount!r}")
        self.frame, self.mount, self.camera = frame, mount, camera
        # the camera (target) frame's placement is the hand-eye transform: a registration, kept before the joints
        # (no image tells its turn about the last joint's axis from that joint's zero: the joint's is dropped)
        self.registration_frames = (frame,)
        self.corners = np.asarray(corners, dtype=int).reshape(-1)
        self.points = np.asarray(points, dtype=float).reshape(-1, 3)
        self.measurements = np.asarray(measurements, dtype=float).reshape(-1, 2)
        if not len(self.corners) == len(self.points) == len(self.measurements) == len(self.samples):
            raise ValueError(f"camera '{name}': samples, corners, points and measurements differ in length")
        k = camera.check_intrinsics(intrinsics)
        free = set(camera.names) if intrinsics_free is True else set(intrinsics_free or [])
        unknown = free - set(camera.names)
        if unknown:
            raise ValueError(f"camera '{name}': no intrinsic named {sorted(unknown)[0]} ({', '.join(camera.names)})")
        self.prior = dict(intrinsics_prior or {})
        self.aux = [Aux(n, float(v), "px" if i < 4 else "", n in free) for i, (n, v) in enumerate(zip(camera.names, k))]
        pose = pose_vector(fixed_pose) if isinstance(fixed_pose, pin.SE3) else (
            np.zeros(6) if fixed_pose is None else np.asarray(fixed_pose, dtype=float).reshape(6))
        which = "target" if mount == "eye_in_hand" else "camera"
        self.aux += [Aux(f"{which}.{c}", float(v), "m" if j < 3 else "rad", pose_free)
                     for j, (c, v) in enumerate(zip(POSE_SUFFIXES, pose))]
        self.n_intrinsics = len(camera.names)
        self.columns = list(columns or ["u", "v"])
        if term_sigma is not None:
            ts = np.asarray(term_sigma, dtype=float).reshape(-1)
            if len(ts) != len(self.samples) or np.any(~(ts > 0)):
                raise ValueError(f"camera '{name}': term_sigma needs one positive pixel sigma per corner")
            self.term_scale = self.sigma[0] / ts

    dim = 2
    row_units = ("pixel", "pixel")

    @classmethod
    def column_kinds(cls, n_columns):
        return [""] * n_columns

    def term_feature(self, k: int) -> tuple:
        return (int(self.corners[k]),)          # an image gives one term per corner

    def placed_per_session(self) -> list[str]:
        return [p.name for p in self.aux_parameters() if p.name.startswith(self.pose_prefix + ".")]

    @property
    def pose_prefix(self) -> str:
        return f"{self.name}.{'target' if self.mount == 'eye_in_hand' else 'camera'}"

    def aux_parameters(self) -> list[Parameter]:
        out = super().aux_parameters()
        for p in out:
            sigma = self.prior.get(p.name.rsplit(".", 1)[-1])
            if sigma is not None:
                p.prior_sigma, p.prior_mean = float(sigma), p.value
        return out

    def aux_scales(self) -> dict[str, tuple[float, float]]:
        k = np.array([a.value for a in self.aux[:self.n_intrinsics]])
        size = max(self.camera.width, self.camera.height)
        out = {}
        for n, v in zip(self.camera.names, k):
            s = (FOCAL_FRACTION * abs(v) if n in ("fx", "fy") else CENTRE_FRACTION * size if n in ("cx", "cy")
                 else TANGENTIAL_SCALE if n in ("p1", "p2") else RADIAL_SCALE)
            out[f"{self.name}.{n}"] = (s, DETERMINED_FRACTION * s)
        return out

    # ---- geometry ----------------------------------------------------------------------
    def camera_points(self, terms, R, p, aux):
        """Corners of `terms` in the camera frame (n, 3), with dX/d(robot frame twist) (n, 3, 6) and
        dX/d(fixed pose) (n, 3, 6)."""
        P = self.points[terms]
        v = aux[self.n_intrinsics:]
        Rf, Jr = pin.exp3(v[3:6]), pin.Jexp3(v[3:6])
        n = len(P)
        dxi, dpose = np.empty((n, 3, 6)), np.empty((n, 3, 6))
        if self.mount == "eye_in_hand":       # camera = robot frame, target fixed in the world
            Y = P @ Rf.T + v[:3]
            X = np.einsum("nji,nj->ni", R, Y - p)
            dxi[:, :, :3] = -np.eye(3)
            dxi[:, :, 3:] = skew(X)
            RcT = lie_arrays.transpose(R)
            dpose[:, :, :3] = RcT
            dpose[:, :, 3:] = -RcT @ (Rf @ skew(P)) @ Jr
        else:                                  # target = robot frame, camera fixed in the world
            Y = lie_arrays.act(R, p, P)
            X = (Y - v[:3]) @ Rf
            dxi[:, :, :3] = Rf.T @ R
            dxi[:, :, 3:] = -Rf.T @ R @ skew(P)
            dpose[:, :, :3] = -Rf.T
            dpose[:, :, 3:] = skew(X) @ Jr
        return X, dxi, dpose

    def predict(self, terms, R, p, aux) -> np.ndarray:
        X = self.camera_points(terms, R, p, aux)[0]
        return self.camera.project(X, aux[:self.n_intrinsics], derivatives=False)

    def evaluate_batch(self, terms, R, p, aux):
        X, dxi, dpose = self.camera_points(terms, R, p, aux)
        uv, dX, dk = self.camera.project(X, aux[:self.n_intrinsics])
        r = uv - self.measurements[terms]
        A = np.concatenate([dk, dX @ dpose], axis=2)
        return BatchTerms(r, dX @ dxi, A)

    def evaluate(self, k, states, aux):
        i = int(self.samples[k])
        M = states[i].pose(self.frame)
        t = self.evaluate_batch(slice(k, k + 1), M.rotation[None], M.translation[None], aux)
        return Term(t.r[0], [(i, self.frame, t.D[0])], t.aux[0])

    def simulate(self, k, states, aux, rng):
        M = states[self.samples[k]].pose(self.frame)
        uv = self.predict(slice(k, k + 1), M.rotation[None], M.translation[None], aux)[0]
        sigma = self.sigma if self.term_scale is None else self.sigma / self.term_scale[k]
        return uv + rng.normal(0.0, sigma)

    def set_measurements(self, m: np.ndarray) -> None:
        self.measurements = np.asarray(m, dtype=float).reshape(-1, 2)

    def views(self, terms, R, p, aux) -> tuple[np.ndarray, np.ndarray]:
        """Per term: depth of the corner along the optical axis (m), and the cosine between the optical axis and
        the target's z axis (> 0: the camera faces the printed side; robocal.io.camera_target's convention)."""
        X = self.camera_points(terms, R, p, aux)[0]
        Rf = pin.exp3(aux[self.n_intrinsics + 3:self.n_intrinsics + 6])
        if self.mount == "eye_in_hand":
            zt = np.einsum("nji,j->ni", R, Rf[:, 2])        # target z in the camera frame
        else:
            zt = np.einsum("ij,nj->ni", Rf.T, R[:, :, 2])
        return X[:, 2], zt[:, 2]
