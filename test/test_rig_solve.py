"""The rig fit's least-squares solve (rig_fit.solve) on problems whose minimum is known exactly."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_info, threadpool_limits

from rig_identification.estimation import rig_fit
from rig_identification.estimation.rig_fit import solve
from rig_identification.estimation.rig_problem import CompressedResidual, ReusedJacobian, sequential_blas
from rig_identification.model.rig_ode import moved_state


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


@pytest.mark.parametrize("reuse", [False, True])
def test_a_solve_that_spends_its_budget_says_it_did_not_settle(monkeypatch, reuse):
    # the far minimum above: with its budget of model runs the solve reaches it and has settled;
    # with a budget of two runs it stops short, its end no minimum, and says so
    J = np.diag([1.0, 1e-4])
    b = np.array([0.3, 1.0])
    sol, _, _ = solve(linear_problem(J, b), reuse=reuse)
    assert sol.settled and sol.cost < 1e-6, (sol.settled, sol.cost)
    monkeypatch.setattr(rig_fit, "MAX_ITERATIONS", 2)
    monkeypatch.setattr(rig_fit, "REUSED_EVALUATIONS", 1)
    sol, _, _ = solve(linear_problem(J, b), reuse=reuse)
    assert not sol.settled and sol.nfev <= 2 and sol.cost > 0.1, (sol.settled, sol.nfev, sol.cost)


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


def damped_sine_problem(seed: int = 3) -> tuple[SimpleNamespace, np.ndarray]:
    """A tall nonlinear least-squares problem (400 rows, 3 unknowns): a damped sine's amplitude,
    frequency and decay fitted to noisy samples, the residual weighted by the noise; returns the
    problem and the true unknowns."""
    t = np.linspace(0.0, 10.0, 400)
    truth = np.array([2.0, 1.3, 0.15])

    def model(z: np.ndarray) -> np.ndarray:
        a, w, d = truth + z
        return a * np.exp(-d * t) * np.sin(w * t)

    sigma = 0.05
    y = model(np.zeros(3)) + sigma * np.random.default_rng(seed).standard_normal(len(t))

    def jacobian(z: np.ndarray) -> np.ndarray:
        a, w, d = truth + z
        e, s, c = np.exp(-d * t), np.sin(w * t), np.cos(w * t)
        return np.column_stack([e * s, a * e * t * c, -a * t * e * s])

    lay = SimpleNamespace(size=3, inertia=slice(0, 1), cg=slice(1, 3), mass=2)
    start = np.array([-0.3, 0.02, 0.05])              # unknowns relative to the truth, the solve starting off it
    prob = SimpleNamespace(residual=lambda z: (model(start + z) - y) / sigma,        # weighted by the noise
                           jacobian=lambda z: jacobian(start + z) / sigma, lay=lay, seconds=10.0)
    return prob, truth


def test_the_compressed_residual_keeps_the_cost_and_the_gradient_exactly():
    # ½‖f̃‖² = ½‖r‖² and J̃ᵀf̃ = Jᵀr at any point; J̃ᵀJ̃ = JᵀJ where the Jacobian is the start's
    prob, _ = damped_sine_problem()
    jac = ReusedJacobian(prob.residual, prob.jacobian, 3, reuse=True)
    packed = CompressedResidual(jac, np.zeros(3))
    assert packed.basis is not None and packed.basis[0].shape == (400, 3)
    for z in (np.zeros(3), np.array([0.1, -0.01, 0.02])):
        f, J = packed.residual(z), packed.jacobian(z)
        r, Jr = prob.residual(z), jac.J               # the Jacobian the solve uses there (updated, not fresh)
        assert f.shape == (4,) and J.shape == (4, 3)
        np.testing.assert_allclose(f @ f, r @ r, rtol=1e-12)
        np.testing.assert_allclose(J.T @ f, Jr.T @ r, rtol=1e-9, atol=1e-9 * np.abs(Jr.T @ r).max())
    J0 = packed.jacobian(np.zeros(3))
    np.testing.assert_allclose(J0.T @ J0, prob.jacobian(np.zeros(3)).T @ prob.jacobian(np.zeros(3)), rtol=1e-9)


def test_the_compressed_solve_reaches_the_minimum_of_the_whole_residual():
    # the solve with the Jacobian reused (the residual compressed) ends at scipy's own minimum of
    # the uncompressed problem, within the solve's stop (a Gauss–Newton decrement of 0.01 in ½χ²)
    prob, truth = damped_sine_problem()
    sol, runs, _ = solve(prob, reuse=True)
    ref = least_squares(prob.residual, np.zeros(3), jac=prob.jacobian, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    assert sol.cost - ref.cost < 0.01, (sol.cost, ref.cost)
    cov = np.linalg.inv(ref.jac.T @ ref.jac)
    assert np.all(np.abs(sol.x - ref.x) < 0.1 * np.sqrt(np.diag(cov))), (sol.x - ref.x) / np.sqrt(np.diag(cov))
    np.testing.assert_allclose(sol.fun, prob.residual(sol.x))        # the whole residual, not the compressed one
    start = np.array([-0.3, 0.02, 0.05])
    assert np.all(np.abs(start + sol.x) < 4 * np.sqrt(np.diag(cov)))   # the truth within 4 σ
    assert runs < 60


def test_a_jacobian_with_a_column_the_residual_does_not_see_is_passed_uncompressed():
    # J0ᵀJ0 singular (a zero column: an unknown the residual does not see): no Cholesky factor, the
    # residual and the Jacobian go to the trust region as they are
    prob, _ = damped_sine_problem()
    jacobian = prob.jacobian
    prob.jacobian = lambda z: np.column_stack([jacobian(z[:3]), np.zeros(400)])
    residual = prob.residual
    jac = ReusedJacobian(lambda z: residual(z[:3]), prob.jacobian, 4, reuse=True)
    packed = CompressedResidual(jac, np.zeros(4))
    assert packed.basis is None
    z = np.array([0.1, -0.01, 0.02, 0.3])
    np.testing.assert_array_equal(packed.residual(z), residual(z[:3]))
    assert packed.jacobian(z).shape == (400, 4)
    with pytest.raises(ValueError, match="not compressed"):
        packed.projected(np.ones(400))


def test_sequential_blas_runs_blas_on_one_thread_and_restores_it():
    # numpy's BLAS is found (else the context would limit nothing); the suite runs with
    # OPENBLAS_NUM_THREADS=1, so BLAS is first given two threads for the context to take away
    def blas_threads() -> list[int]:
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    assert blas_threads(), "threadpoolctl finds no BLAS in this process"
    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        assert all(n == 2 for n in before)
        with sequential_blas():
            assert all(n == 1 for n in blas_threads())
            with sequential_blas():                 # a fit within a fit (the joint fit's single fits)
                pass
            assert all(n == 1 for n in blas_threads())
        assert blas_threads() == before


def test_moved_state_moves_a_stack_of_states_as_each_alone():
    rng = np.random.default_rng(3)
    q = Rotation.random(5, random_state=4).as_quat()[:, [3, 0, 1, 2]]      # wxyz
    y = np.column_stack([rng.normal(size=(5, 3)), q, rng.normal(size=(5, 6))])
    offsets = 1e-2 * rng.normal(size=(5, 12))
    stacked = moved_state(y, offsets)
    assert stacked.shape == (5, 13)
    for k in range(5):
        np.testing.assert_allclose(stacked[k], moved_state(y[k], offsets[k]), rtol=0, atol=1e-15)
    # the rotation: the offset's rotation vector (world) after the state's attitude
    R = Rotation.from_rotvec(offsets[0, 3:6]) * Rotation.from_quat(y[0, [4, 5, 6, 3]])
    np.testing.assert_allclose(Rotation.from_quat(stacked[0, [4, 5, 6, 3]]).as_matrix(), R.as_matrix(), atol=1e-15)
    np.testing.assert_allclose(stacked[0, :3], y[0, :3] + offsets[0, :3])
    np.testing.assert_allclose(stacked[0, 7:], y[0, 7:] + offsets[0, 6:])
