"""Synthetic data sets of the five measuring modes with their instruments' errors, and the spec's accuracy statistic.

The true machine is the nominal one with N(0, sigma) on each of the 42 parameters; every mode puts the
tool tip where its reference object says (docs/stewart_calibration.md, "Example and benchmark") and
records the struts the true machine reads there, with the platform turned up to +-15 deg. Errors, each
stated and each scaled by `noise` (0: noise-free data, same stated sigmas, same draws):
  sig_p    positions, contact distances and ball-bar readings (1 sd, m)
  sig_a    angles of full poses (rad)
  sig_s    every strut reading (m)
  sig_cmm  the coordinate measuring machine that measures the platform joints T before the contact modes
           (1 sd per coordinate, m): the fit gets T as measured, never the truth
The ball bar is one instrument: a fixed nominal length BAR_LENGTH, readings within +-BAR_TRAVEL of its
zero, and one origin offset (true length at reading zero) shared by every place it is set up at.
The statistic is the spec's: the largest tool-tip error over fresh validation poses after the fit.
Used by examples/stewart_calibration.py and benchmarks/stewart_calibration.py. Machine k of a study draws
from its own seed (robocal.estimation.parallel_map), so `fit_machines` gives the same figures in this
process and on a Dask cluster (docs/fleet.md).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from robocal.errors import IdentifiabilityError
from robocal.estimation.calibrate import calibrate
from robocal.estimation.parallel_map import monte_carlo
from robocal.estimation.problem import Problem
from robocal.systems.stewart import calibration as sc
from robocal.systems.stewart import modes as sm

PLANES = [((0.0, 0.0, 0.25), (0.0, 0.0, 1.0)), ((0.12, 0.0, 0.33), (-1.0, 0.0, 0.3)),
          ((0.0, -0.12, 0.33), (0.0, 1.0, 0.3))]
# holes, balls and ball-bar bases spread over the workspace, holes 100 mm deep: data near a few
# clustered points leave the rest of the workspace to extrapolation (3 shallow holes near the centre
# gave 2-6 um instead of 1-2 um)
HOLES = [((0.1, 0.0, 0.25), (0.0, 0.0, 1.0)), ((-0.05, 0.09, 0.25), (1.0, 0.0, 1.0)),
         ((-0.05, -0.09, 0.25), (0.0, 1.0, 1.0)), ((0.0, 0.0, 0.35), (1.0, 1.0, 0.3))]
HOLE_RADIUS = 0.01
HOLE_DEPTH = 0.1
BALLS = [(0.1, 0.0, 0.3), (-0.05, 0.09, 0.3), (-0.05, -0.09, 0.3), (0.0, 0.0, 0.42)]
BALL_RADIUS = 0.0127
BAR_BASES = [(0.1, 0.0, 0.2), (-0.05, 0.09, 0.2), (-0.05, -0.09, 0.2)]
BAR_LENGTH = 0.15             # nominal length of the ball bar (the fit's start value of its origin offset)
BAR_TRAVEL = 1e-3             # the bar reads within +-1 mm of its zero
BAR_ORIGIN_OFFSET = BAR_LENGTH + 12.3e-6    # the true length at reading zero (unknown to the fit)
BAR = "dbb"                   # the instrument: its offset is the parameter dbb.offset
# how the platform joints T enter a fit: free (mode 1 sees them), measured by the CMM and carried as
# priors of its uncertainty, fixed at the CMM's values (its error ignored), fixed at the truth (no CMM error)
PLATFORM_JOINTS = ("free", "cmm_prior", "cmm_fixed", "true")


def _unit(v) -> np.ndarray:
    return np.asarray(v, dtype=float) / np.linalg.norm(v)


@dataclass
class ModeData:
    residuals: list
    struts: np.ndarray


class ModeStudy:
    """One simulated machine and its validation poses; each method returns a mode's data set, with
    samples numbered from `first` so that sets can be stacked into one mixed fit."""

    def __init__(self, robot, tool: sm.Tool, seed, sig_p: float = 1e-6, sig_a: float = 1e-6,
                 sigma_parameters: float = 1e-3, n_validation: int = 50, noise: float = 1.0,
                 sig_s: float = 1e-6, sig_cmm: float = 5e-6):
        # seed: anything numpy's default_rng takes (an int, a SeedSequence or a Generator, used as is)
        self.robot, self.tool, self.sig_p, self.sig_a, self.noise = robot, tool, sig_p, sig_a, float(noise)
        self.sig_s, self.sig_cmm = sig_s, sig_cmm
        self.rng = np.random.default_rng(seed)
        self.truth = sc.stewart_parameters()
        for p in self.truth:
            p.value = self.rng.normal(0.0, sigma_parameters)
        self.true_geo = sc.geometry(robot, self.truth)
        self.val_tips = sc.random_tips(n_validation, self.rng)
        self.val_R = sc.random_orientations(n_validation, self.rng)[1]
        # the CMM's measurement of the platform joints, taken once per machine
        self.cmm = {n: self.truth[n].value + self.noise * self.rng.normal(0.0, sig_cmm) for n in platform_names()}

    def struts_at(self, tips) -> tuple[np.ndarray, np.ndarray]:
        """Angles and noisy strut readings (K, 6) of the true machine with its tip at `tips`, turned at random."""
        abc, R = sc.random_orientations(len(tips), self.rng)
        s = sc.struts(self.true_geo, sc.tip_to_platform(tips, R, self.tool))
        return abc, s + self.noise * self.rng.normal(0.0, self.sig_s, s.shape)

    def full_poses(self, n: int, first: int = 0) -> ModeData:
        tips = sc.random_tips(n, self.rng)
        abc, s = self.struts_at(tips)
        rows = np.column_stack([tips + self.noise * self.rng.normal(0, self.sig_p, (n, 3)),
                                abc + self.noise * self.rng.normal(0, self.sig_a, (n, 3))])
        return ModeData(sm.pose_residuals("pose", self.robot, np.arange(first, first + n), rows, 1, self.tool,
                                          (self.sig_p, self.sig_a)), s)

    def contacts(self, objects, n: int, first: int, touch) -> ModeData:
        """n contacts in all, spread as evenly as they go over the objects (the first ones get one more):
        touch(k, object, n_k, samples) -> (residual, tip centres); the struts are read with the platform
        turned at random."""
        if n < len(objects):
            raise ValueError(f"{n} contacts cannot reach {len(objects)} objects")
        counts = [len(c) for c in np.array_split(np.arange(n), len(objects))]
        parts, start = [], first
        for k, (obj, n_k) in enumerate(zip(objects, counts)):
            residual, tips = touch(k, obj, n_k, np.arange(start, start + n_k))
            parts.append((residual, self.struts_at(tips)[1]))
            start += n_k
        return ModeData([r for r, _ in parts], np.vstack([s for _, s in parts]))

    def planes(self, n: int, first: int = 0, objects=PLANES) -> ModeData:
        def touch(k, obj, n, samples):
            point, nrm = obj[0], _unit(obj[1])
            tips = sc.plane_tips(point, nrm, self.tool, n, self.rng, span=0.15)
            tips += np.outer(self.noise * self.rng.normal(0, self.sig_p, n), nrm)
            return sm.plane_residual(f"plane{k}", samples, point, nrm, self.tool, self.sig_p), tips
        return self.contacts(objects, n, first, touch)

    def holes(self, n: int, first: int = 0, objects=HOLES) -> ModeData:
        def touch(k, obj, n, samples):
            c, a = np.asarray(obj[0], dtype=float), _unit(obj[1])
            tips = sc.cylinder_tips(c, a, HOLE_RADIUS, self.tool, n, self.rng, kind="hole", depth=HOLE_DEPTH)
            radial = tips - c - np.outer((tips - c) @ a, a)
            noise = self.noise * self.rng.normal(0, self.sig_p, (n, 1))
            tips += radial / np.linalg.norm(radial, axis=1, keepdims=True) * noise
            return sm.cylinder_residual(f"hole{k}", samples, c, a, HOLE_RADIUS, self.tool, "hole", self.sig_p), tips
        return self.contacts(objects, n, first, touch)

    def balls(self, n: int, first: int = 0, objects=BALLS) -> ModeData:
        def touch(k, c, n, samples):
            d = BALL_RADIUS + self.tool.tip_radius + self.noise * self.rng.normal(0, self.sig_p, n)
            tips = sc.sphere_tips(c, d, n, self.rng, min_up=0.0)
            return sm.ball_residual(f"ball{k}", samples, c, BALL_RADIUS, self.tool, self.sig_p), tips
        return self.contacts(objects, n, first, touch)

    def ball_bar(self, n: int, first: int = 0, objects=BAR_BASES) -> ModeData:
        """The one bar set up at each base in turn, swept over the upper half-sphere within its travel."""
        def touch(k, c, n, samples):
            reading = self.rng.uniform(-BAR_TRAVEL, BAR_TRAVEL, n)
            tips = sc.sphere_tips(c, BAR_ORIGIN_OFFSET + reading, n, self.rng, min_up=0.0)
            reading = reading + self.noise * self.rng.normal(0, self.sig_p, n)
            return sm.ball_bar_residual(f"{BAR}{k}", samples, reading, c, self.tool, self.sig_p, offset=BAR_LENGTH,
                                        instrument=BAR), tips
        return self.contacts(objects, n, first, touch)

    def parameters(self, platform_joints: str = "free"):
        """The 42 parameters at nominal, T as `platform_joints` says (PLATFORM_JOINTS)."""
        if platform_joints not in PLATFORM_JOINTS:
            raise ValueError(f"platform_joints '{platform_joints}' (one of {', '.join(PLATFORM_JOINTS)})")
        params = sc.stewart_parameters(fix_platform_joints=platform_joints in ("cmm_fixed", "true"))
        if platform_joints != "free":
            for name in platform_names():
                p = params[name]
                p.value = self.truth[name].value if platform_joints == "true" else self.cmm[name]
                if platform_joints == "cmm_prior":    # the stated sigma, also on noise-free data
                    p.prior_mean, p.prior_sigma = self.cmm[name], self.sig_cmm
        return params

    def fit(self, data: ModeData, platform_joints: str = "free"):
        """Calibrate from nominal; returns the result and the largest validation tool-tip error (m)."""
        params = self.parameters(platform_joints)
        result = calibrate(Problem(self.robot, params, sc.actuated(self.robot), data.struts, data.residuals))
        return result, float(self.tip_errors(params).max())

    def tip_errors(self, params) -> np.ndarray:
        return sc.tip_errors(self.true_geo, sc.geometry(self.robot, params), self.tool, self.val_tips, self.val_R)


def platform_names() -> list[str]:
    """The 18 coordinates of the platform joints T (platform frame)."""
    return [p.name for p in sc.stewart_parameters() if ".link2." in p.name]


def mix(parts: list[ModeData]) -> ModeData:
    """Several modes' data in one fit (their samples must already be numbered consecutively)."""
    return ModeData([r for p in parts for r in p.residuals], np.vstack([p.struts for p in parts]))


@dataclass
class MachineFit:
    """One repetition of a mode study: a simulated machine drawn from `rng`, its data set make(study),
    the fit; returns (largest validation tool-tip error (m), rank of the fit, the solver's success, its
    iterations); (nan, -1, False, 0) when calibrate refuses the data set (fewer rows than unknowns). make=None: the machine's error before calibration (nominal model), rank 0, True, 0.
    Pickled whole for Dask, robot included."""
    robot: object
    tool: sm.Tool
    make: Callable | None
    platform_joints: str = "free"
    study_options: dict = field(default_factory=dict)   # ModeStudy's sig_p, sig_a, sig_s, sig_cmm, ...

    def __call__(self, rng: np.random.Generator) -> tuple[float, int, bool, int]:
        study = ModeStudy(self.robot, self.tool, rng, **self.study_options)
        if self.make is None:
            return float(study.tip_errors(sc.stewart_parameters()).max()), 0, True, 0
        try:
            result, tip = study.fit(self.make(study), self.platform_joints)
        except IdentifiabilityError:          # fewer rows than unknowns: calibrate refuses, and says so
            return float("nan"), -1, False, 0
        return tip, int(result.selection.rank), bool(result.solve.success), int(result.solve.nit)


def fit_machines(robot, tool: sm.Tool, make, platform_joints: str, machines: int, seed=0,
                 scheduler: str | None = None, workers: int | None = None,
                 **study_options) -> list[tuple[float, int, bool, int]]:
    """[(largest validation tip error (m), rank, solver success, iterations)] of `machines` simulated
    machines, each fitted on its data set make(study) with T as `platform_joints` says (make=None: errors
    before calibration). Machine k draws from the k-th child of SeedSequence(seed), the same machine in
    every call with that seed; `scheduler`/`workers` spread the machines over Dask with the same results
    as the serial run."""
    return monte_carlo(MachineFit(robot, tool, make, platform_joints, study_options), machines, seed,
                       scheduler, workers)
