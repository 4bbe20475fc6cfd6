"""Candidate poses for experiment design: random or gridded readings, minus the self-evidently bad ones.

A candidate is one row of joint readings (the joints the measurements read; for a parallel machine,
its actuators). Candidates are dropped when
  - the robot cannot take them (a closed chain that does not assemble raises AssemblyError),
  - the measured frame is near a singularity: the smallest of the first min(6, n) singular values of
    its joint Jacobian [J_v / length_scale; J_w] falls below `min_singular` (a pose where the
    joints barely move the frame in some direction, so the readings there say little and the
    robot is hard to hold),
  - the measured frame's origin lies outside the measurement volume (the tracker's field).
"""
from __future__ import annotations

import itertools
import logging
from dataclasses import dataclass, field

import numpy as np

from robocal.errors import InputError, RobocalError

log = logging.getLogger(__name__)


@dataclass
class MeasurementVolume:
    """Where the instrument can measure, in the measurement frame (m).

    box     (lower xyz, upper xyz) corners, or None
    center, max_range, min_range: a spherical shell around the instrument (a tracker's range)
    """

    box: tuple[np.ndarray, np.ndarray] | None = None
    center: np.ndarray | None = None
    max_range: float = np.inf
    min_range: float = 0.0

    def contains(self, points: np.ndarray) -> np.ndarray:
        p = np.atleast_2d(np.asarray(points, dtype=float))
        ok = np.ones(len(p), bool)
        if self.box is not None:
            lo, hi = (np.asarray(b, dtype=float) for b in self.box)
            ok &= np.all((p >= lo) & (p <= hi), axis=1)
        if self.center is not None:
            d = np.linalg.norm(p - np.asarray(self.center, dtype=float), axis=1)
            ok &= (d <= self.max_range) & (d >= self.min_range)
        return ok

    @classmethod
    def from_dict(cls, d: dict | None, source: str = "config", field_prefix: str = "plan.volume"):
        """{box: {min: [x,y,z], max: [x,y,z]}, sphere: {center: [x,y,z], max_range: r, min_range: r0}}."""
        if not d:
            return None
        if not isinstance(d, dict):
            raise InputError("expected a mapping with 'box' and/or 'sphere'", source=source, field=field_prefix)
        for k in d:
            if k not in ("box", "sphere"):
                raise InputError("unknown key (allowed: box, sphere)", source=source, field=f"{field_prefix}.{k}")
        vol = cls()
        if "box" in d:
            b = d["box"] or {}
            lo, hi = (_vec3(b.get(k), source, f"{field_prefix}.box.{k}") for k in ("min", "max"))
            if np.any(lo >= hi):
                raise InputError("box min must be below max on every axis", source=source,
                                 field=f"{field_prefix}.box")
            vol.box = (lo, hi)
        if "sphere" in d:
            s = d["sphere"] or {}
            vol.center = _vec3(s.get("center"), source, f"{field_prefix}.sphere.center")
            vol.max_range = float(s.get("max_range", np.inf))
            vol.min_range = float(s.get("min_range", 0.0))
            if not 0 <= vol.min_range < vol.max_range:
                raise InputError("need 0 <= min_range < max_range", source=source, field=f"{field_prefix}.sphere")
        return vol


def _vec3(v, source, field_name) -> np.ndarray:
    try:
        a = np.asarray(v, dtype=float).reshape(3)
    except (TypeError, ValueError):
        raise InputError(f"expected three numbers, got {v!r}", source=source, field=field_name) from None
    return a


def random_candidates(robot, joint_names, n: int, rng: np.random.Generator, margin: float = 0.05) -> np.ndarray:
    """(n, len(joint_names)) uniform within the joint limits shrunk by `margin` of their range."""
    lo, hi = robot.limits(joint_names)
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * (1 - margin)
    return rng.uniform(mid - half, mid + half, (n, len(joint_names)))


def grid_candidates(robot, joint_names, levels, margin: float = 0.05) -> np.ndarray:
    """Full grid within the limits: `levels` values per joint (an int, or one int per joint).

    A joint with one level sits at the middle of its range. Rows are in lexicographic order.
    """
    lo, hi = robot.limits(joint_names)
    levels = np.broadcast_to(np.asarray(levels, dtype=int), (len(joint_names),))
    if np.any(levels < 1):
        raise InputError("grid levels must be >= 1", field="levels")
    if np.prod(levels.astype(float)) > 1e6:
        raise InputError(f"a grid of {int(np.prod(levels.astype(float)))} poses is too large", field="levels")
    mid, half = (lo + hi) / 2, (hi - lo) / 2 * (1 - margin)
    axes = [np.array([m]) if k == 1 else np.linspace(m - h, m + h, k) for m, h, k in zip(mid, half, levels)]
    return np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, len(joint_names))


@dataclass
class CandidateFilter:
    """Counts of dropped candidates, by reason, and the kept rows."""

    kept: np.ndarray                       # indices into the proposed rows
    dropped: dict[str, int] = field(default_factory=dict)
    dexterity: np.ndarray | None = None    # conditioning measure of every proposed row (nan if not assembled)


def filter_candidates(model_state, values: np.ndarray, frame: str, volume: MeasurementVolume | None = None,
                      min_singular: float = 0.02, length_scale: float = 0.5) -> CandidateFilter:
    """Keep the rows of `values` that assemble, are not near singular and lie in the volume.

    model_state  robocal.model.kinematics.ModelState (or anything whose .sample(values) gives a state with
                 pose(frame) and frame_joint_jacobian(frame)); closed chains assemble in .sample.
    """
    n = len(values)
    dext = np.full(n, np.nan)
    inside = np.zeros(n, bool)
    assembled = np.zeros(n, bool)
    for i, v in enumerate(values):
        try:
            s = model_state.sample(v)
            Jq = s.frame_joint_jacobian(frame)
            p = s.pose(frame).translation
        except RobocalError as exc:  # AssemblyError and friends: the machine cannot take this pose
            log.debug("candidate %d dropped: %s", i, exc)
            continue
        assembled[i] = True
        R = s.pose(frame).rotation
        Jw = np.vstack([R @ Jq[:3] / length_scale, R @ Jq[3:]])
        sv = np.linalg.svd(Jw, compute_uv=False)
        dext[i] = sv[min(6, Jw.shape[1]) - 1] if len(sv) else 0.0
        inside[i] = True if volume is None else bool(volume.contains(p)[0])
    regular = assembled & (dext >= min_singular)
    kept = np.flatnonzero(regular & inside)
    dropped = {"not assembled": int(np.sum(~assembled)), "near singular": int(np.sum(assembled & ~regular)),
               "outside volume": int(np.sum(regular & ~inside))}
    log.info("candidates: %d proposed, %d kept, dropped %s", n, len(kept), dropped)
    return CandidateFilter(kept, dropped, dext)
