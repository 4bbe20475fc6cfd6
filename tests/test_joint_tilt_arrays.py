"""The batched joint tilt (robocal.model.joint_tilt_arrays): its Rodrigues formulas against Pinocchio and
finite differences, and the batched pass with tilts against the per-sample reference when only a tilt moves.

Tolerances: the closed forms and Pinocchio's agree to rounding of O(1) entries, except Pinocchio's Jexp3 near
its Taylor switch (|phi| ~ 1e-4), where its own cancellation reaches ~4e-13 (measured against 40-digit
arithmetic): 1e-12. Central differences with h = 1e-6 carry h^2 truncation and eps/h rounding, ~1e-10: 1e-8.
"""
import numpy as np
import pinocchio as pin
import pytest

from reference_evaluation import reference_evaluate
from test_batched_evaluation import _problem, _relative, RTOL
from robocal.estimation.problem import Problem
from robocal.model.batch_kinematics import supports_batch
from robocal.model.joint_tilt_arrays import right_jacobians, rotations


@pytest.mark.parametrize("scale", [0.0, 1e-9, 1e-5, 1.5e-4, 1e-2, 0.5, 2.5])
def test_rotations_and_right_jacobians_match_pinocchio(scale):
    phi = np.random.default_rng(1).normal(size=(20, 3)) * scale
    E, J = rotations(phi), right_jacobians(phi)
    for i in range(len(phi)):
        assert np.abs(E[i] - pin.exp3(phi[i])).max() < 1e-12
        assert np.abs(J[i] - pin.Jexp3(phi[i])).max() < 1e-12
    # Jexp6 of a pure rotation is diag(Jexp3, Jexp3): what add_terms takes for d(tilt twist)
    J6 = pin.Jexp6(np.r_[np.zeros(3), phi[0]])
    assert np.abs(J6[3:, 3:] - J[0]).max() < 1e-12 and np.abs(J6[:3, 3:]).max() == 0.0


@pytest.mark.parametrize("scale", [1e-3, 0.3, 2.0])
def test_right_jacobian_matches_finite_differences(scale):
    """exp3(phi + d) = exp3(phi) exp3(Jexp3(phi) d + o(d)), column by column."""
    phi = np.random.default_rng(2).normal(size=3) * scale
    J, h = right_jacobians(phi[None])[0], 1e-6
    for k in range(3):
        d = np.eye(3)[k] * h
        fd = (pin.log3(rotations(phi[None])[0].T @ rotations((phi + d)[None])[0])
              - pin.log3(rotations(phi[None])[0].T @ rotations((phi - d)[None])[0])) / (2 * h)
        assert np.abs(fd - J[:, k]).max() < 1e-8


def test_kept_kinematics_follow_a_tilt_change():
    """The regressors kept between passes depend on the tilts: a tilt moved alone must not reuse them, and the
    root joint's tilt (its placement differs per sample) must reach the poses."""
    full = _problem(np.random.default_rng(15), ("tilt",))
    # one residual: its samples are the kept regressors' (several residuals on other samples replace them)
    problem = Problem(full.robot, full.params, full.joint_names, full.values, full.residuals[:1])
    assert supports_batch(problem.model_state())
    problem.evaluate()
    for name, step in (("shoulder_pan_joint.tilt", 2e-3), ("elbow_joint.tilt", 2e-3), ("tcp.rx", 0.05)):
        problem.params[name].value += step
        ev, ref = problem.evaluate(), reference_evaluate(problem)
        assert _relative(ev.r, ref.r) < RTOL and _relative(ev.J, ref.J) < RTOL, name


def test_per_sample_states_stay_valid_around_a_batched_pass():
    """The batched pass sets the tilted placements in a scratch model, not in the ModelState's: a per-sample
    state of the same ModelState asked after a batched pass answers as one of a fresh ModelState."""
    problem = _problem(np.random.default_rng(16), ("tilt",))
    ms = problem.model_state()
    states = problem.states(ms)
    states[3].frame_parameter_jacobian("tcp")          # the per-sample model set to sample 3
    for _ in problem.pieces(ms=ms):                     # a batched pass of the same ModelState
        pass
    fresh = problem.states()
    assert np.array_equal(states[5].pose("tcp").homogeneous, fresh[5].pose("tcp").homogeneous)
    assert np.array_equal(states[5].frame_parameter_jacobian("tcp"), fresh[5].frame_parameter_jacobian("tcp"))


def test_tied_and_fixed_tilts_match_the_reference():
    """Two tilts tied to a third (one free column reached from three joints, with coefficients) and a fixed tilt
    away from zero (it tilts the placements but has no column)."""
    problem = _problem(np.random.default_rng(17), ("tilt",))
    problem.params.tie("wrist_1_joint.tilt", {"elbow_joint.tilt": 0.5})
    problem.params.tie("wrist_2_joint.tilt", {"elbow_joint.tilt": -1.0})
    problem.params.fix("shoulder_lift_joint.tilt")
    assert problem.params["shoulder_lift_joint.tilt"].value != 0.0
    ev, ref = problem.evaluate(), reference_evaluate(problem)
    assert _relative(ev.r, ref.r) < RTOL and _relative(ev.J, ref.J) < RTOL
    assert np.abs(ev.J[:, problem.params.free_names.index("elbow_joint.tilt")]).max() > 0.0
