"""The rig fit's least-squares solve (rig_fit.solve) on problems whose minimum is known exactly."""

from types import SimpleNamespace

import numpy as np
import pytest

from rig_identification.estimation.rig_fit import solve
from rig_identification.estimation.rig_problem import ReusedJacobian


def linear_problem(J: np.ndarray, b: np.ndarray) -> SimpleNamespace:
    """The residual J z − b of the unknowns z, laid out like the rig model's body unknowns."""
    size = J.shape[1]
    lay = SimpleNamespace(size=size, inertia=slice(0, 1), cg=slice(1, size), mass=size - 1)
    return SimpleNamespace(residual=lambda z: J @ z - b, jacobian=lambda z: J.copy(), lay=lay, seconds=1.0)


@pytest.mark.parametrize("reuse", [False, True])
def test_solve_reaches_a_far_minimum_the_trust_region_crawls_towards(reuse):
    # a weakly determined unknown whose minimum lies 10⁴ from the start: scipy's trust region starts
    # at radius 1 and gains ~1e-4 of cost per unit step, so five iterations gain less than the
    # Newton decrement the solve stops by, while the Gauss–Newton step reaches the minimum at once
    J = np.diag([1.0, 1e-4])
    b = np.array([0.3, 1.0])
    truth = np.linalg.solve(J, b)
    sol, runs, _ = solve(linear_problem(J, b), reuse=reuse)
    assert sol.cost < 1e-6, sol.cost                       # 0.5 at the start, 0 at the minimum
    np.testing.assert_allclose(sol.x, truth, rtol=1e-6)
    assert runs < 100


def test_reused_jacobian_resumed_at_its_own_point_keeps_the_fresh_one():
    # a solve resumed where the last fresh Jacobian was made: no update along a zero step (which
    # would divide by zero), the fresh Jacobian itself
    J = np.array([[2.0, 0.0], [0.0, 3.0], [1.0, 1.0]])
    jac = ReusedJacobian(lambda z: J @ z, lambda z: J.copy(), 2, reuse=True)
    z = np.array([0.5, -1.0])
    jac.residual(z)
    jac.refresh(z)
    jac.residual(z)
    assert np.array_equal(jac.jacobian(z), J) and jac.fresh
