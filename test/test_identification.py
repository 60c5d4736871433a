"""Identifier: physically consistent parametrisation, exactness on synthetic Euler dynamics,
calibrated standard deviations."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rig_identification.identification import (KEYS, consistent_from_params, from_tensor, identify_inertia,
                                               params_from_consistent, physically_consistent, to_tensor)
from rig_identification.rig import rig_from_dict

RIG = rig_from_dict({"gravity": 9.80665, "cables": [
    {"name": f"c{i}", "ceiling_anchor": [x, y, 0.0], "body_anchor": [x / 2, y / 2, 1.0], "length": 2.0}
    for i, (x, y) in enumerate([(-2, -2), (2, -2), (-2, 2), (2, 2)])],
    "body": {"mass": 1000.0, "center_of_gravity": [0.0, 0.0, 0.0]}, "imu": {"position": [0, 0, 0]}})
J_TRUE = np.array([[900.0, -15.0, 40.0], [-15.0, 2500.0, 25.0], [40.0, 25.0, 2800.0]])


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


def euler_data(noise=0.0, seed=0, T=120.0, fs=200.0):
    """Free rigid body driven by a known moment: J w' + w x Jw = M (exact ODE solution)."""
    t = np.arange(0, T, 1 / fs)
    f = np.array([0.9, 1.3, 1.7])

    def moment(tt):
        return 300 * np.array([np.sin(2 * np.pi * f[0] * tt), np.cos(2 * np.pi * f[1] * tt + 0.3),
                               np.sin(2 * np.pi * f[2] * tt + 1.0)])

    Jinv = np.linalg.inv(J_TRUE)
    sol = solve_ivp(lambda tt, w: Jinv @ (moment(tt) - np.cross(w, J_TRUE @ w)), (0, T), [0.05, -0.02, 0.03],
                    t_eval=t, rtol=1e-11, atol=1e-13, method="DOP853")
    w = sol.y.T
    rng = np.random.default_rng(seed)
    return t, w + noise * rng.standard_normal(w.shape), moment(t).T


def test_exact_on_noise_free_euler_dynamics():
    t, w, M = euler_data()
    res = identify_inertia(RIG, t, w, M, band_hz=(0.5, 5.0))
    assert np.abs(res.inertia - J_TRUE).max() < 0.5  # kg m^2, i.e. < 0.02 % of the largest moment


@pytest.mark.parametrize("seed", range(3))
def test_noisy_within_reported_sigma(seed):
    t, w, M = euler_data(noise=0.002, seed=seed)
    res = identify_inertia(RIG, t, w, M, band_hz=(0.5, 5.0))
    err = from_tensor(res.inertia) - from_tensor(J_TRUE)
    assert np.all(np.abs(err) < 4 * res.inertia_std), (err, res.inertia_std)
    # the white-noise prediction (Cramér–Rao bound of the estimator) agrees with the sandwich std
    np.testing.assert_allclose(res.crb_std, res.inertia_std, rtol=0.5)
    assert abs(res.gyro_noise - 0.002) < 2e-4
    assert set(res.to_dict()["inertia_std"]) == set(KEYS)
