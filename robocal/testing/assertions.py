"""Assertions for users' own test suites (pytest or plain asserts): each raises AssertionError with a
message that names what broke (the Jacobian column, the parameter, the measurement block, the frame).

  assert_jacobian_matches_fd      any function and its analytic Jacobian, columns named
  assert_problem_jacobian         a Problem's residual Jacobian (columns = free parameters)
  assert_frame_jacobians          a model's frame Jacobians w.r.t. parameters and joints
  assert_calibration_recovers     a calibration recovers a synthetic truth within what the noise predicts
  assert_reproduces_dataset       a (calibrated) URDF reproduces a recorded dataset, per block
  assert_urdf_loads               a URDF loads, has the named frames, and its closures assemble at home
  synthetic_pose_case             a seeded synthetic problem (the plugin's factory fixture uses it)
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import pinocchio as pin
from scipy import stats

from robocal.design.simulate import perturb, random_configurations, simulate_measurements
from robocal.workflows.setup import load_config
from robocal.errors import InputError, RobocalError
from robocal.estimation.calibrate import CalibrationOptions, calibrate
from robocal.estimation.identifiability import select_base_parameters
from robocal.estimation.problem import Problem
from robocal.estimation.result import UNIT_SCALE, block_statistics
from robocal.io.text_files import numbers_in
from robocal.model.kinematics import ModelState
from robocal.model.loops import assemble
from robocal.model.parameters import robot_parameters
from robocal.model.robot import EXAMPLES, Robot, load_example, load_urdf
from robocal.residuals import PoseResidual

# Central differences: truncation ~ h^2 |f'''| / 6, rounding ~ eps |f| / h; h = 1e-6 balances them at
# ~1e-10 for O(1) functions, so 1e-6 leaves room for curvature and still catches any wrong column.
FD_STEP = 1e-6
FD_TOL = 1e-6


def _fail(msg: str):
    raise AssertionError(msg)


# ---- Jacobians ----------------------------------------------------------------------------------
def finite_difference_jacobian(fun: Callable[[np.ndarray], np.ndarray], x0, h: float = FD_STEP) -> np.ndarray:
    """Central-difference Jacobian of fun at x0."""
    x0 = np.asarray(x0, dtype=float)
    cols = []
    for j in range(len(x0)):
        xp, xm = x0.copy(), x0.copy()
        xp[j] += h
        xm[j] -= h
        cols.append((np.asarray(fun(xp), dtype=float) - np.asarray(fun(xm), dtype=float)) / (2 * h))
    return np.column_stack(cols) if cols else np.zeros((len(np.atleast_1d(fun(x0))), 0))


def assert_jacobian_matches_fd(fun, x0, jacobian, names: Sequence[str] | None = None,
                               rows: Sequence[str] | None = None, h: float = FD_STEP, tol: float = FD_TOL,
                               what: str = "Jacobian") -> float:
    """Fail unless |J - J_fd| / max(1, max|J|) < tol; the message lists the wrong columns by name.

    jacobian: the analytic (m, n) matrix at x0. Returns the scaled worst difference.
    """
    J = np.asarray(jacobian, dtype=float)
    Jfd = finite_difference_jacobian(fun, x0, h)
    if J.shape != Jfd.shape:
        _fail(f"{what}: analytic shape {J.shape} but finite differences give {Jfd.shape}")
    names = list(names) if names is not None else [f"column {j}" for j in range(J.shape[1])]
    scale = max(1.0, float(np.abs(J).max()) if J.size else 1.0)
    diff = np.abs(J - Jfd) / scale
    worst = float(diff.max()) if diff.size else 0.0
    if not worst < tol:   # also catches NaN
        per_col = np.nanmax(np.where(np.isnan(diff), np.inf, diff), axis=0)
        bad = [j for j in np.argsort(-per_col, kind="stable") if per_col[j] >= tol]
        lines = [f"{what} does not match central finite differences (h={h:g}) in {len(bad)} of "
                 f"{J.shape[1]} columns (tolerance {tol:g} relative to max|J| = {scale:.3g}):"]
        for j in bad[:8]:
            i = int(np.nanargmax(np.where(np.isnan(diff[:, j]), np.inf, diff[:, j])))
            row = rows[i] if rows is not None else f"row {i}"
            lines.append(f"  {names[j]}: worst at {row}: analytic {J[i, j]:.6g}, finite difference "
                         f"{Jfd[i, j]:.6g} (scaled difference {per_col[j]:.3g})")
        if len(bad) > 8:
            lines.append(f"  ... and {len(bad) - 8} more columns")
        _fail("\n".join(lines))
    return worst


def assert_problem_jacobian(problem, h: float = FD_STEP, tol: float = FD_TOL) -> float:
    """A Problem's analytic Jacobian (every residual block) against finite differences.

    Columns are the free parameters (named in the message); rows are named by block and row.
    The parameters are left at their values.
    """
    params = problem.params
    x0 = params.free_values()
    ev = problem.evaluate()
    rows = [""] * len(ev.r)
    for b in problem.blocks:
        for k, i in enumerate(range(b.rows.start, b.rows.stop)):
            rows[i] = f"block '{b.name}' row {k}"

    def fun(x):
        params.set_free_values(x)
        return problem.evaluate(jacobian=False).r

    try:
        return assert_jacobian_matches_fd(fun, x0, ev.J, params.free_names, rows, h, tol,
                                          what="residual Jacobian")
    finally:
        params.set_free_values(x0)


def assert_frame_jacobians(robot, params, joint_names, values, frame: str, h: float = FD_STEP,
                           tol: float = FD_TOL, model_state: Callable | None = None) -> None:
    """The model's LOCAL frame Jacobians (w.r.t. free parameters and read joints) at one sample
    against finite differences of log6(M0^-1 M(x)).

    model_state(robot, params, joint_names) builds the state (default robocal.model.kinematics.ModelState);
    pass your own to test a custom kinematics layer.
    """
    make = model_state or ModelState
    values = np.asarray(values, dtype=float)
    s0 = make(robot, params, joint_names).sample(values)
    M0 = s0.pose(frame)
    x0 = params.free_values()
    rows = [f"{frame}.{c}" for c in ("vx", "vy", "vz", "wx", "wy", "wz")]

    def by_params(x):
        params.set_free_values(x)
        return pin.log6(M0.actInv(make(robot, params, joint_names).sample(values).pose(frame))).vector

    try:
        assert_jacobian_matches_fd(by_params, x0, s0.frame_parameter_jacobian(frame), params.free_names, rows,
                                   h, tol, what=f"frame '{frame}' parameter Jacobian")
    finally:
        params.set_free_values(x0)
    ms = make(robot, params, joint_names)
    assert_jacobian_matches_fd(lambda v: pin.log6(M0.actInv(ms.sample(v).pose(frame))).vector, values,
                               s0.frame_joint_jacobian(frame), list(joint_names), rows, h, tol,
                               what=f"frame '{frame}' joint Jacobian")


# ---- synthetic truth ------------------------------------------------------------------------------
@dataclass
class SyntheticCase:
    """A problem whose measurements were simulated from `truth` with the stated sigmas."""

    problem: object
    truth: object
    seed: int
    identifiable: list[str]


def synthetic_pose_case(robot="ur5", n_samples: int = 40, seed: int = 0, frame: str | None = None,
                        sigma=(5e-5, 5e-5), preset: str = "full", base: bool = True,
                        translation: float = 2e-3, rotation: float = np.radians(0.2),
                        identifiable_only: bool = True) -> SyntheticCase:
    """Tracker poses of `frame` (default: the last frame) on a perturbed robot, deterministic in `seed`.

    robot: a Robot, an example name or a URDF path. Only identifiable parameters are perturbed by
    default, so the truth is recoverable parameter by parameter.
    """

    rng = np.random.default_rng(seed)
    robot = load_robot(robot)
    frame = frame or robot.frame_names[-1]
    joints = [j for j in robot.supporting_joints(frame)]
    params = robot_parameters(robot, joints, preset, frames={frame: True}, base=base)
    values = random_configurations(robot, joints, n_samples, rng)
    placeholder = np.tile([0, 0, 0, 0, 0, 0, 1.0], (n_samples, 1))
    problem = Problem(robot, params, joints, values, [PoseResidual("poses", frame, np.arange(n_samples),
                                                                   placeholder, sigma=sigma)])
    sel = select_base_parameters(problem.evaluate().J, params.free_names)
    identifiable = [params.free_names[i] for i in sel.independent]
    truth = perturb(params, rng, translation, rotation, patterns=identifiable if identifiable_only else None)
    simulate_measurements(problem, truth, rng)
    return SyntheticCase(problem, truth, seed, identifiable)


def assert_calibration_recovers(problem, truth, options=None, alpha: float = 1e-3):
    """Calibrate `problem` and fail unless the estimates agree with `truth` as the noise predicts.

    With the stated sigmas trusted (scale_covariance=False) the errors e = estimate - truth over the
    estimated parameters are ~ N(0, C). Three checks, each with false-failure probability <= alpha:
      * every |e_i| / stderr_i below the two-sided Bonferroni bound z = Phi^-1(1 - alpha / (2 n));
      * e^T C^-1 e below the chi-square(n) quantile 1 - alpha;
      * the residual variance ratio SSR / dof inside its chi-square(dof) / dof band (wrong sigmas).
    Parameters the data cannot determine are skipped: perturb only identifiable ones in the truth.
    Returns the CalibrationResult.
    """

    opts = copy.copy(options) if options is not None else CalibrationOptions()
    opts.scale_covariance = False
    result = calibrate(problem, opts)
    if not result.success:
        _fail(f"calibration did not succeed: {result.status} ({result.solve.message})")
    names = result.estimated
    e = np.array([problem.params[n].value - truth[n].value for n in names])
    se = np.array([problem.params[n].stderr for n in names])
    z = e / se
    n = len(names)
    z_max = stats.norm.ppf(1 - alpha / (2 * n))
    chi2 = float(e @ np.linalg.solve(result.covariance, e))
    chi2_max = stats.chi2.ppf(1 - alpha, n)
    ratio = float(np.sum(result.solve.fun ** 2) / result.dof)
    lo, hi = (stats.chi2.ppf(q, result.dof) / result.dof for q in (alpha / 2, 1 - alpha / 2))
    problems = []
    order = np.argsort(-np.abs(z), kind="stable")
    for i in order:
        if abs(z[i]) > z_max:
            unit = problem.params[names[i]].unit
            problems.append(f"  {names[i]}: estimate {problem.params[names[i]].value:.6g} {unit}, truth "
                            f"{truth[names[i]].value:.6g} {unit}, error {e[i]:.3g} = {z[i]:+.1f} standard errors "
                            f"(bound {z_max:.2f})")
    if chi2 > chi2_max:
        problems.append(f"  all {n} estimates together: chi-square {chi2:.1f} > {chi2_max:.1f} "
                        f"(quantile {1 - alpha:g})")
    if not lo <= ratio <= hi:
        problems.append(f"  residual variance / stated variance = {ratio:.3f}, outside [{lo:.3f}, {hi:.3f}]: "
                        "the stated sigmas do not describe the residuals")
    if problems:
        _fail("calibration does not recover the truth within what the noise predicts:\n" + "\n".join(problems))
    return result


# ---- datasets and URDFs -----------------------------------------------------------------------------
def load_robot(robot_or_name):
    """A Robot from a Robot, an example name ('ur5') or a URDF path."""
    if isinstance(robot_or_name, Robot):
        return robot_or_name
    text = str(robot_or_name)
    if text.lower() in EXAMPLES and not Path(text).exists():
        return load_example(text)
    return load_urdf(text)


def _tolerances(value, kind: str) -> dict[str, float]:
    """{'length': m, 'angle': rad} from a float (a length) or a dict."""
    if value is None:
        return {}
    if isinstance(value, dict):
        bad = set(value) - {"length", "angle"}
        if bad:
            raise InputError(f"unknown tolerance kind(s) {sorted(bad)} (length, angle)", field=kind)
        return {k: float(v) for k, v in value.items()}
    return {"length": float(value)}


def dataset_setup(config, urdf=None):
    """The Setup of a calibration YAML, with the robot taken from `urdf` instead when given.

    Sections the setup does not use (simulation, plan, iso9283) are checked for misspelt keys only.
    """
    return load_config(config, urdf)


def assert_reproduces_dataset(config, urdf=None, rms=None, max=None, blocks: dict | None = None,
                              setup_values: dict[str, float] | None = None, fit_setup: bool = True):
    """Fail unless the robot (the config's, or `urdf`) reproduces the config's measurements.

    rms, max      tolerances in SI for every block: a float (metres) or {'length': m, 'angle': rad}
    blocks        per-block overrides {block name: {'rms': ..., 'max': ...}}
    setup_values  values of measurement set-up parameters (base.*, auxiliary, frames the config adds),
                  e.g. from a calibration's result.json; they are not part of a URDF
    fit_setup     fit those set-up parameters first (the robot's own parameters stay as the URDF has them)
    Returns the list of BlockStats (mm / mrad).
    """

    setup = dataset_setup(config, urdf)
    problem, robot = setup.problem, setup.robot
    for p in problem.params:
        is_setup = p.kind in ("base", "auxiliary") or (p.kind == "frame_placement" and p.target in robot.extra_frames)
        if not is_setup:
            p.value, p.vary = 0.0, False
        elif not fit_setup:
            p.vary = False
    if setup_values:
        problem.params.set_values(setup_values)
    if fit_setup and problem.params.free_names:
        calibrate(problem, setup.options, source=str(config))
    stats_ = block_statistics(problem, problem.evaluate(jacobian=False))
    default = {"rms": _tolerances(rms, "rms"), "max": _tolerances(max, "max")}
    failures = []
    label = {k: lab for k, (_, lab) in UNIT_SCALE.items()}
    for b in stats_:
        own = (blocks or {}).get(b.name, {})
        for stat in ("rms", "max"):
            tol = _tolerances(own[stat], stat) if stat in own else default[stat]
            values = getattr(b, stat)
            for kind, limit in tol.items():
                scale, unit = UNIT_SCALE[kind]
                v = values.get(label[kind])
                if v is not None and not v <= limit * scale:
                    failures.append(f"  block '{b.name}' ({b.type_name}, {b.rows} rows): {stat.upper()} "
                                    f"{v:.4g} {unit} > {limit * scale:.4g} {unit}")
    if failures:
        who = f"URDF {urdf}" if urdf is not None else f"the robot of {config}"
        _fail(f"{who} does not reproduce the dataset {config} (tolerances in mm / mrad):\n" + "\n".join(failures))
    return stats_


def assert_urdf_loads(urdf, frames: Sequence[str] = (), home=None, package_dirs=None, tol: float = 1e-9):
    """Fail unless the URDF (or example name) loads, has `frames`, and its closures assemble at home.

    home: the actuated joints' readings at the home pose (closed chains only); default: their values
    in the neutral configuration. Closures are checked only when the robot has them (robot.loops);
    a serial robot is checked for a finite forward kinematics at neutral instead.
    Returns the Robot.
    """
    try:
        robot = load_urdf(urdf, package_dirs) if package_dirs else load_robot(urdf)
    except RobocalError as exc:
        _fail(f"URDF {urdf} does not load: {exc}")
    missing = [f for f in frames if not robot.model.existFrame(f)]
    if missing:
        lines = []
        for f in missing:
            try:
                robot.frame_id(f)
            except InputError as exc:
                lines.append(f"  {exc.reason}")
        _fail(f"URDF {urdf}: {len(missing)} of {len(frames)} frames missing:\n" + "\n".join(lines))
    q0 = robot.neutral()
    loops = getattr(robot, "loops", None)
    if loops is not None and getattr(loops, "closures", None):
        values = loops.actuated_values(q0) if home is None else np.asarray(home, dtype=float)
        try:
            q0 = assemble(robot, robot.model, values, sample="home")
        except RobocalError as exc:
            _fail(f"URDF {urdf}: the closures do not assemble at the home pose {np.round(values, 6).tolist()}: "
                  f"{exc}")
        residual = loops.constraint_error(robot.model, robot.model.createData(), q0)
        worst = int(np.argmax(np.abs(residual)))
        if abs(residual[worst]) > tol:
            _fail(f"URDF {urdf}: closure rows not closed at home (max |c| = {abs(residual[worst]):.3g})")
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, q0)
    bad = [robot.model.frames[i].name for i in range(robot.model.nframes)
           if not np.all(np.isfinite(data.oMf[i].homogeneous))]
    if bad:
        _fail(f"URDF {urdf}: non-finite poses at home for frames {', '.join(bad[:5])}")
    return robot


def assert_same_text_and_numbers(actual: str, expected: str, rtol: float = 1e-12, atol: float = 1e-13,
                                 what: str = "text") -> None:
    """Two generated files agree: every character outside numbers exactly, every number within
    atol + rtol |expected|. Numbers that come from trigonometry differ in their last bits between CPUs
    and libm builds (~1e-16 relative, a few ulps after a few operations), so byte equality cannot be
    promised; the default tolerances are 1e3-1e4 times that and far below any physical dimension."""
    skel_a, num_a = numbers_in(actual)
    skel_e, num_e = numbers_in(expected)
    if skel_a != skel_e:
        diff = next(i for i, (a, b) in enumerate(zip(skel_a + "\0", skel_e + "\0")) if a != b)
        _fail(f"{what} differs outside its numbers near character {diff}: "
              f"{skel_a[max(0, diff - 40):diff + 40]!r} vs {skel_e[max(0, diff - 40):diff + 40]!r}")
    bad = np.flatnonzero(np.abs(num_a - num_e) > atol + rtol * np.abs(num_e))
    if bad.size:
        k = bad[0]
        _fail(f"{what}: {bad.size} numbers differ beyond atol {atol:g} + rtol {rtol:g}; first: number {k}, "
              f"{num_a[k]!r} vs {num_e[k]!r}")
