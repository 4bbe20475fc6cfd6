"""The Levenberg-Marquardt solver does not report success when its Jacobian is wrong: a damped step's
predicted gain shrinks with the damping whatever the Jacobian, so 'nothing left to gain' must be judged
on the undamped (Gauss-Newton) prediction."""
import numpy as np

from robocal.estimation.solve import levenberg_marquardt

TARGET = np.array([1.0, -2.0, 0.5])


def fun_with(jacobian):
    def fun(x):
        r = np.r_[x - TARGET, 0.1 * (x[0] - TARGET[0]) ** 2]
        return r, jacobian(x), np.arange(4)
    return fun


def right(x):
    return np.vstack([np.eye(3), [0.2 * (x[0] - TARGET[0]), 0.0, 0.0]])


def test_right_jacobian_converges_to_the_target():
    sol = levenberg_marquardt(fun_with(right), np.zeros(3))
    assert sol.status > 0
    assert np.allclose(sol.x, TARGET, atol=1e-9)


def test_wrong_jacobian_is_a_failure_not_a_success():
    wrong = lambda x: -right(x)                      # noqa: E731  (sign flipped: every step goes uphill)
    sol = levenberg_marquardt(fun_with(wrong), np.zeros(3))
    assert sol.status < 0, (sol.status, sol.message)
    assert "bad Jacobian" in sol.message


def test_noise_free_data_end_at_the_rounding_level():
    """Exact data: the cost reaches rounding and the fit says so (a success)."""
    sol = levenberg_marquardt(fun_with(right), TARGET + 1e-9)
    assert sol.status > 0 and np.allclose(sol.x, TARGET, atol=1e-12)
