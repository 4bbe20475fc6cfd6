"""A camera's projection: pinhole with distortion (OpenCV's models), with its derivatives.

Models (OpenCV's conventions, so that intrinsics from cv2.calibrateCamera carry over unchanged):
  plumb_bob  k1 k2 p1 p2 k3: radial (1 + k1 r^2 + k2 r^4 + k3 r^6) and tangential p1, p2
  rational   k1 k2 p1 p2 k3 k4 k5 k6: the radial factor divided by (1 + k4 r^2 + k5 r^4 + k6 r^6)
  fisheye    k1 k2 k3 k4: equidistant, theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8) (cv2.fisheye)
  pinhole    no distortion
u = fx x'' + cx, v = fy y'' + cy, with (x'', y'') the distorted normalised coordinates of X / Z.
Intrinsics are in pixels (fx fy cx cy) and unitless (distortion); the image is width x height pixels.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError

DISTORTION = {"pinhole": (), "plumb_bob": ("k1", "k2", "p1", "p2", "k3"),
              "rational": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"), "fisheye": ("k1", "k2", "k3", "k4")}
MIN_DEPTH = 1e-6          # m: a point closer to (or behind) the camera's plane is projected as if here
MIN_FOCAL_FRACTION = 0.1  # a focal length below this fraction of the image width is not in pixels


@dataclass
class CameraModel:
    """The projection's structure: distortion model and image size (the intrinsics' values are separate)."""

    model: str = "plumb_bob"
    width: int = 0
    height: int = 0

    def __post_init__(self):
        if self.model not in DISTORTION:
            raise InputError(f"unknown camera model '{self.model}' (known: {', '.join(DISTORTION)})",
                             field="camera.model")
        if not (self.width > 0 and self.height > 0):
            raise InputError(f"the image size must be positive pixels, got {self.width} x {self.height}",
                             field="camera.image_size")

    @property
    def names(self) -> tuple[str, ...]:
        """Intrinsic names in the order of the intrinsics vector."""
        return ("fx", "fy", "cx", "cy") + DISTORTION[self.model]

    def check_intrinsics(self, values, source: str = "config", prefix: str = "camera") -> np.ndarray:
        """The intrinsics as a vector in `names` order; refuses focal lengths that are not in pixels."""
        k = np.asarray(values, dtype=float).reshape(-1)
        if len(k) != len(self.names):
            raise InputError(f"a {self.model} camera has {len(self.names)} intrinsics ({', '.join(self.names)}), "
                             f"got {len(k)}", source=source, field=f"{prefix}.intrinsics")
        if not np.all(np.isfinite(k)):
            raise InputError("the intrinsics must be finite numbers", source=source, field=f"{prefix}.intrinsics")
        for name, f in zip(("fx", "fy"), k[:2]):
            if f < MIN_FOCAL_FRACTION * self.width:
                raise InputError(
                    f"{name} = {f:g} is not a focal length in pixels for a {self.width}-pixel-wide image (below "
                    f"{MIN_FOCAL_FRACTION:g} x width); a lens's focal length in mm divided by the pixel pitch in mm "
                    "gives pixels (e.g. 8 mm / 0.0034 mm = 2353 px)", source=source,
                    field=f"{prefix}.intrinsics.{name}")
        return k

    def inside(self, uv: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Whether each pixel (n, 2) lies within the image (OpenCV: pixel centres at integers, edges at -0.5)."""
        uv = np.asarray(uv, dtype=float)
        return ((uv[:, 0] >= -0.5 + margin) & (uv[:, 0] <= self.width - 0.5 - margin)
                & (uv[:, 1] >= -0.5 + margin) & (uv[:, 1] <= self.height - 0.5 - margin))

    def camera_matrix(self, k) -> np.ndarray:
        return np.array([[k[0], 0.0, k[2]], [0.0, k[1], k[3]], [0.0, 0.0, 1.0]])

    def project(self, X: np.ndarray, k: np.ndarray, derivatives: bool = True):
        """Pixels (n, 2) of camera-frame points X (n, 3); with derivatives also d uv / d X (n, 2, 3) and
        d uv / d intrinsics (n, 2, len(names))."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        Z = np.maximum(X[:, 2], MIN_DEPTH)
        x, y = X[:, 0] / Z, X[:, 1] / Z
        if self.model == "fisheye":
            xd, yd, dxy, dd = _fisheye(x, y, k[4:])
        else:
            xd, yd, dxy, dd = _radial_tangential(x, y, k[4:], self.model)
        uv = np.column_stack([k[0] * xd + k[2], k[1] * yd + k[3]])
        if not derivatives:
            return uv
        f = np.array([k[0], k[1]])
        dn = np.zeros((len(X), 2, 3))                     # d(x, y) / dX
        dn[:, 0, 0] = dn[:, 1, 1] = 1.0 / Z
        dn[:, 0, 2], dn[:, 1, 2] = -x / Z, -y / Z
        dX = f[None, :, None] * np.einsum("nij,njk->nik", dxy, dn)
        dk = np.zeros((len(X), 2, len(self.names)))
        dk[:, 0, 0], dk[:, 1, 1], dk[:, 0, 2], dk[:, 1, 3] = xd, yd, 1.0, 1.0
        dk[:, :, 4:] = f[None, :, None] * dd
        return uv, dX, dk


def _radial_tangential(x, y, d, model):
    """OpenCV's plumb_bob / rational distortion: (x'', y''), d(x'', y'')/d(x, y) (n, 2, 2), d/d coefficients."""
    if model == "pinhole":
        d = np.zeros(5)
    k1, k2, p1, p2, k3 = d[:5]
    k4, k5, k6 = d[5:8] if model == "rational" else (0.0, 0.0, 0.0)
    r2 = x * x + y * y
    a = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    b = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = a / b
    da = k1 + r2 * (2 * k2 + 3 * k3 * r2)
    db = k4 + r2 * (2 * k5 + 3 * k6 * r2)
    drad = (da * b - a * db) / b ** 2                  # d radial / d r2
    xy = x * y
    xd = x * radial + 2 * p1 * xy + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * xy
    dxy = np.empty((len(x), 2, 2))
    dxy[:, 0, 0] = radial + 2 * x * x * drad + 2 * p1 * y + 6 * p2 * x
    dxy[:, 0, 1] = 2 * xy * drad + 2 * p1 * x + 2 * p2 * y
    dxy[:, 1, 0] = 2 * xy * drad + 2 * p1 * x + 2 * p2 * y
    dxy[:, 1, 1] = radial + 2 * y * y * drad + 6 * p1 * y + 2 * p2 * x
    n_coef = {"pinhole": 0, "plumb_bob": 5, "rational": 8}[model]
    dd = np.zeros((len(x), 2, n_coef))
    if n_coef:
        xy_ = np.stack([x, y], axis=1)
        for j, power in ((0, 1), (1, 2), (4, 3)):               # k1 k2 k3
            dd[:, :, j] = xy_ * (r2 ** power / b)[:, None]
        dd[:, 0, 2], dd[:, 1, 2] = 2 * xy, r2 + 2 * y * y          # p1
        dd[:, 0, 3], dd[:, 1, 3] = r2 + 2 * x * x, 2 * xy          # p2
        if model == "rational":
            for j, power in ((5, 1), (6, 2), (7, 3)):           # k4 k5 k6
                dd[:, :, j] = -xy_ * (a * r2 ** power / b ** 2)[:, None]
    return xd, yd, dxy, dd


def _fisheye(x, y, d):
    """OpenCV's fisheye (equidistant) distortion, with its derivatives as in _radial_tangential."""
    k1, k2, k3, k4 = d
    r = np.sqrt(x * x + y * y)
    th = np.arctan(r)
    t2 = th * th
    thd = th * (1 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))))
    dthd = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + 9 * k4 * t2)))    # d theta_d / d theta
    small = r < 1e-4
    rs = np.where(small, 1.0, r)
    s = np.where(small, 1.0 + (k1 - 1.0 / 3.0) * r * r, thd / rs)             # theta_d / r
    # g = (ds/dr) / r, finite at r = 0 (series there)
    g = np.where(small, 2.0 * (k1 - 1.0 / 3.0), (dthd / (1 + rs * rs) * rs - thd) / rs ** 3)
    xd, yd = s * x, s * y
    dxy = np.empty((len(x), 2, 2))
    dxy[:, 0, 0] = s + g * x * x
    dxy[:, 0, 1] = dxy[:, 1, 0] = g * x * y
    dxy[:, 1, 1] = s + g * y * y
    dd = np.zeros((len(x), 2, 4))
    over_r = np.where(small, 1.0, th / rs)                  # theta / r (-> 1 at r = 0)
    for j in range(4):
        dd[:, 0, j] = x * over_r * th ** (2 * j + 2)
        dd[:, 1, j] = y * over_r * th ** (2 * j + 2)
    return xd, yd, dxy, dd


@dataclass
class CameraSpec:
    """A camera as a config gives it: the model, the intrinsics' values, which are free and their priors."""

    model: CameraModel
    intrinsics: np.ndarray                 # in model.names order
    free: bool | tuple[str, ...] = True    # True: all; False: none; or the free names
    prior: dict[str, float] = field(default_factory=dict)    # {name: sigma} around the given values


SPEC_KEYS = ("model", "image_size", "intrinsics", "free", "prior")


def camera_spec_from_dict(d, source: str = "config", prefix: str = "camera") -> CameraSpec:
    """The camera of a config mapping {model, image_size: [w, h], intrinsics: [fx, fy, cx, cy, k1 ...] or
    {fx: .., cx: .., k1: ..} (distortion terms left out are 0), free: true | false | [names], prior: {name:
    sigma}} (docs/camera.md); every error names the key under `prefix`."""
    def error(msg, key=None):
        return InputError(msg, source=source, field=f"{prefix}.{key}" if key else prefix)
    if not isinstance(d, dict):
        raise error(f"expected a mapping ({', '.join(SPEC_KEYS)})")
    for key in d:
        if key not in SPEC_KEYS:
            raise error(f"unknown key (allowed: {', '.join(SPEC_KEYS)})", key)
    size = d.get("image_size")
    if (not isinstance(size, (list, tuple)) or len(size) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size)):
        raise error(f"expected [width, height] in pixels, two positive integers, got {size!r}", "image_size")
    model = d.get("model", "plumb_bob")
    if model not in DISTORTION:
        raise error(f"unknown camera model {model!r} (known: {', '.join(DISTORTION)})", "model")
    cam = CameraModel(model, int(size[0]), int(size[1]))
    raw = d.get("intrinsics")
    if isinstance(raw, dict):
        unknown = [n for n in raw if n not in cam.names]
        missing = [n for n in cam.names[:4] if n not in raw]
        if unknown or missing:
            raise error(f"{'no intrinsic named ' + repr(unknown[0]) if unknown else 'missing ' + missing[0]} "
                        f"(a {model} camera has {', '.join(cam.names)})", "intrinsics")
        raw = [raw.get(n, 0.0) for n in cam.names]
    if not isinstance(raw, (list, tuple)) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                     for v in raw):
        raise error(f"expected a list of numbers ({', '.join(cam.names)}) or a mapping name: value, got {raw!r}",
                    "intrinsics")
    k = cam.check_intrinsics(raw, source, prefix)
    free = d.get("free", True)
    if isinstance(free, list) and all(isinstance(n, str) for n in free):
        bad = [n for n in free if n not in cam.names]
        if bad:
            raise error(f"no intrinsic named {bad[0]!r} ({', '.join(cam.names)})", "free")
        free = tuple(free)
    elif not isinstance(free, bool):
        raise error(f"expected true, false or a list of intrinsic names, got {free!r}", "free")
    prior = d.get("prior", {})
    if not isinstance(prior, dict):
        raise error(f"expected a mapping intrinsic name: sigma, got {prior!r}", "prior")
    for n, sigma in prior.items():
        if n not in cam.names:
            raise error(f"no intrinsic named {n!r} ({', '.join(cam.names)})", f"prior.{n}")
        if isinstance(sigma, bool) or not isinstance(sigma, (int, float)) or not (np.isfinite(sigma) and sigma > 0):
            raise error(f"a prior sigma must be a positive number (px for fx fy cx cy), got {sigma!r}", f"prior.{n}")
        if not (free is True or n in (free or ())):
            raise error(f"{n} is fixed (camera.free): a prior needs it free", f"prior.{n}")
    return CameraSpec(cam, k, free, {str(n): float(v) for n, v in prior.items()})
