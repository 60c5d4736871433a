"""The gyro-only fit (the rig model's first start for the tensor): physically consistent
parametrisation, exactness on synthetic Euler dynamics, calibrated standard deviations."""
import numpy as np
import pytest
from synthetic import J_TRUE, euler_data

from rig_identification.estimation.gyro_fit import fit_gyro
from rig_identification.model.parametrisation import (
    consistent_from_params,
    from_tensor,
    params_from_consistent,
    physically_consistent,
    to_tensor,
)


def test_parametrisation_round_trip_and_consistency():
    rng = np.random.default_rng(1)
    for _ in range(200):
        th = rng.normal(size=6)
        j, dj = consistent_from_params(th)
        assert physically_consistent(to_tensor(j))
        np.testing.assert_allclose(consistent_from_params(params_from_consistent(to_tensor(j)))[0], j, rtol=1e-9)
        # analytic Jacobian against central differences
        num = np.array([(consistent_from_params(th + h)[0] - consistent_from_params(th - h)[0]) / 2e-6
                        for h in 1e-6 * np.eye(6)]).T
        np.testing.assert_allclose(dj, num, rtol=1e-5, atol=1e-6)
    # an inconsistent tensor (violates Izz <= Ixx + Iyy) is projected onto a consistent one
    bad = np.diag([100.0, 100.0, 300.0])
    assert not physically_consistent(bad)
    assert physically_consistent(to_tensor(consistent_from_params(params_from_consistent(bad))[0]))


def test_exact_on_noise_free_euler_dynamics():
    t, w, M = euler_data()
    res = fit_gyro(t, w, M, band_hz=(0.5, 5.0))
    assert res.consistent and physically_consistent(to_tensor(res.inertia))
    assert np.abs(to_tensor(res.inertia) - J_TRUE).max() < 0.5  # kg m^2, i.e. < 0.02 % of the largest moment


@pytest.mark.parametrize("seed", range(3))
def test_noisy_within_reported_sigma(seed):
    t, w, M = euler_data(noise=0.002, seed=seed)
    res = fit_gyro(t, w, M, band_hz=(0.5, 5.0))
    err = res.inertia - from_tensor(J_TRUE)
    assert np.all(np.abs(err) < 4 * res.std), (err, res.std)
    assert np.all(res.std > 0)


def test_integral_places_a_step_at_the_sample_that_shows_it():
    """A smooth signal plus a step switched on the sampling clock (zero-order hold, the
    thesis's pulses): the integral is exact to the quadrature's order; Simpson's rule
    across the jump errs by a third to a half sample × the step."""
    from scipy.integrate import cumulative_simpson

    from rig_identification.estimation.gyro_fit import cumulative_integral, step_indices
    t = np.arange(101) / 100.0
    step = 5.0 * (t >= 0.5 - 1e-9)
    x = np.column_stack([np.sin(2 * np.pi * t) + step, np.cos(3 * t)])
    exact = np.column_stack([(1 - np.cos(2 * np.pi * t)) / (2 * np.pi) + 5.0 * np.clip(t - 0.5, 0, None),
                             np.sin(3 * t) / 3])
    assert list(step_indices(x)) == [50]
    assert np.abs(cumulative_integral(x, t) - exact).max() < 1e-5
    # Simpson across the jump: a third to a half sample × the step, by where its panels fall
    assert np.abs(cumulative_simpson(x, x=t, axis=0, initial=0.0) - exact)[-1, 0] > 0.01


def test_no_steps_in_smooth_or_noisy_signals():
    rng = np.random.default_rng(5)
    t = np.arange(24000) / 200.0
    smooth = 600.0 * np.column_stack([np.cos(2 * np.pi * 1.5 * t), np.sin(2 * np.pi * 1.5 * t), 0 * t])
    from rig_identification.estimation.gyro_fit import step_indices
    assert len(step_indices(smooth)) == 0
    noisy = smooth + rng.normal(0, 0.5, smooth.shape)
    assert len(step_indices(noisy)) == 0
    noisy[12000:, 0] += 40.0      # ≈ 80 σ of the noise
    assert list(step_indices(noisy)) == [12000]
