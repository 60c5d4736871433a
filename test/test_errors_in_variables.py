"""Errors in variables: a fit whose input carries noise correlated with its output's is
biased; compensated with realisations of that noise (bias-compensated least squares) it is
not, and its σ covers the truth.  A synthetic closed loop with a known tensor, so that the
bias and its removal are measured against the truth over many noise draws."""
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, lfilter, sosfiltfilt

from rig_identification.estimation.errors_in_variables import (
    LEAK_SHARE,
    NoiseRealisations,
    antithetic_realisations,
    attenuation_leak,
    capped,
    noise_share,
    quadratic_forms,
    second_order_covariance,
)
from rig_identification.estimation.identification import Segment, fit_segments
from rig_identification.estimation.validation import EFFECT_FACTOR, quadrature_check
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import load_experiment
from rig_identification.model.parametrisation import basis, from_tensor, to_tensor

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "rigs" / "default.yaml"
FS = 200.0
N = 12000      # 60 s
J_TRUE = np.array([[900.0, -15.0, 40.0], [-15.0, 2400.0, 10.0], [40.0, 10.0, 2600.0]])


def _band(x):
    sos = butter(4, [0.3, 3.0], btype="bandpass", fs=FS, output="sos")
    return sosfiltfilt(sos, x, axis=0)


def _noise(rng, sig_y, gain):
    """One realisation of the loop's noise: the output's (N,3) white, band-passed, and the
    input's — the output noise integrated (leakily: a 0.5 s time constant, as the tracker's
    corrections bound the pose's drift) and scaled by ``gain`` (as the gyro's noise reaches
    the moment through the integrated pose), plus an independent part."""
    ey = sig_y * rng.standard_normal((N, 3))
    eu = gain * lfilter([1.0 / FS], [1.0, -0.99], ey, axis=0) + 0.2 * sig_y * gain * rng.standard_normal((N, 3))
    return _band(eu), _band(ey)


def _segment(u, y) -> Segment:
    t = np.arange(N) / FS
    return Segment(t, y, FS, (0.3, 3.0), lambda x: x, y, u, np.zeros((6, N, 3)))


def _signal():
    """A band-limited input that moves roll far less than pitch and yaw (a weakly excited
    axis), and the noise-free output P u."""
    rng = np.random.default_rng(0)
    u0 = _band(rng.standard_normal((N, 3)) * np.array([0.15, 1.0, 1.0]) * 60.0)
    return u0, u0 @ np.linalg.inv(J_TRUE).T


def _loop():
    """32 noise draws of the loop: (least-squares entries, compensated entries, compensated result)."""
    rig = load_experiment(DEFAULT).rig      # for the mass and CG the result reports
    u0, y0 = _signal()
    out = []
    for seed in range(32):
        rng = np.random.default_rng(100 + seed)
        eu, ey = _noise(rng, 2e-3, 4000.0)
        seg = _segment(u0 + eu, y0 + ey)
        pairs = [_noise(np.random.default_rng([seed, k]), 2e-3, 4000.0) for k in range(6)]
        noise = antithetic_realisations([u0 + p[0] for p in pairs], [u0 - p[0] for p in pairs],
                                        [y0 + p[1] for p in pairs], [y0 - p[1] for p in pairs])
        ls = fit_segments(rig, [seg])
        comp = fit_segments(rig, [seg], noise=[noise])
        out.append((from_tensor(ls.inertia), from_tensor(comp.inertia), comp))
    return out


@pytest.fixture(scope="module")
def loop():
    return _loop()


def test_least_squares_is_biased_and_the_compensation_removes_it(loop):
    truth = from_tensor(J_TRUE)
    ls = np.array([o[0] for o in loop])
    comp = np.array([o[1] for o in loop])
    spread = comp.std(axis=0, ddof=1)
    ixx = KEYS.index("ixx")
    # least squares: Ixx far off, the same way every draw (attenuation: J inflated)
    assert np.mean(ls[:, ixx] - truth[ixx]) > 5 * spread[ixx] / np.sqrt(len(loop)), (ls[:, ixx], spread)
    # compensated: the mean error within 3 standard errors of the mean on every entry, Ixx's
    # bias down to a third or less
    err = comp.mean(axis=0) - truth
    assert abs(err[ixx]) < abs(np.mean(ls[:, ixx]) - truth[ixx]) / 3, (err[ixx], np.mean(ls[:, ixx]) - truth[ixx])
    assert np.all(np.abs(err) < 3 * spread / np.sqrt(len(loop)) + 1e-9 * np.abs(truth)), (err, spread)
    # and it reports how much of its input was noise, mostly along Ixx
    c = loop[0][2].errors_in_variables
    assert 0.02 < c.share < 0.5, c.share
    assert KEYS[int(np.argmax(np.abs(c.direction)))] == "ixx", c.direction
    # the jackknife σ of the correction is finite and smaller than the correction it qualifies
    assert np.all(np.isfinite(c.correction_std)) and c.correction_std[ixx] < abs(c.correction[ixx])


def test_the_compensated_fits_series_carry_the_noise_realisations(loop):
    comp = loop[0][2]
    s = comp.series[0]
    assert s.noise_jacobian.shape == (6, N, 3, 6) and s.noise_residual.shape == (6, N, 3)
    # the residual's noise realisation is Δy − P Δu: with the fitted P it is the output noise
    # less what the input noise predicts — not zero, and not the output noise alone
    assert np.all(np.isfinite(s.noise_residual))


def test_the_input_correlation_check_holds_its_null_on_a_compensated_fit(loop):
    """validation.quadrature_check on the 32 compensated fits of the closed loop (no model
    error): its regressors, the quadrature of the predicted ω, carry the input's noise too
    (FitSeries.noise_predicted), and with it compensated the Wald statistic is χ² with 9 dof —
    mean χ²/dof within 0.75–1.25 (its sampling sd over 288 dof: 0.08), none beyond the
    significance threshold.  (Taken noise-free, the regressors' noise correlates with the
    residual's: on bench_any_rig's undetermined rigs the check was significant on 30 of 74.)"""
    stats = np.array([quadrature_check(o[2].series).statistic for o in loop])
    assert 0.75 < stats.mean() < 1.25, stats
    assert loop[0][2].series[0].noise_predicted.shape == (6, N, 3)
    thr = quadrature_check(loop[0][2].series).threshold / EFFECT_FACTOR
    assert np.all(stats < thr), (stats.max(), thr)


def test_noise_share_and_cap():
    A = np.diag([4.0, 1.0, 2.0])
    N_ = np.diag([1.0, 0.9, 0.2])
    share, v = noise_share(A, N_)
    assert share == pytest.approx(0.9) and abs(v[1]) == pytest.approx(1.0)
    # capped: no direction keeps more than the cap's share, the others untouched
    Nc = capped(A, N_, 0.5)
    np.testing.assert_allclose(np.diag(Nc), [1.0, 0.5, 0.2])
    with pytest.raises(ValueError):
        NoiseRealisations(np.zeros((2, 5, 3)), np.zeros((2, 4, 3)))


def test_attenuation_leak_recovers_the_bias_the_compensation_did_not_remove():
    """errors_in_variables.attenuation_leak on a regression in P = J⁻¹'s entries whose regressor
    is measured with noise (share of the noisiest direction ~0.7, beyond the compensation's
    limit): j_ls + leak is the true tensor within 1 % of Ixx's bias and 5 % of the largest (regression
    dilution undone along every direction: Fuller 1987 §1.1), and every entry is reached — the
    inverse spreads the bias of one direction over all of J.  A direction all noise (share ≥ 1)
    is undone at most to LEAK_SHARE."""
    rng = np.random.default_rng(21)
    J = np.array([[900.0, -20.0, 40.0], [-20.0, 2500.0, 15.0], [40.0, 15.0, 2800.0]])
    p = from_tensor(np.linalg.inv(J))
    n = 400_000
    X = rng.standard_normal((n, 6)) * np.array([1.0, 0.3, 0.3, 1.0, 0.3, 1.0])
    U = rng.standard_normal((n, 6)) * np.array([1.5, 0.05, 0.05, 0.1, 0.05, 0.1])   # mostly along ixx's p
    Xm = X + U
    y = X @ p
    A = Xm.T @ Xm
    N = n * np.diag(np.array([1.5, 0.05, 0.05, 0.1, 0.05, 0.1]) ** 2)
    share, _ = noise_share(A, N)
    assert 0.6 < share < 0.8
    p_ls = np.linalg.solve(A, Xm.T @ y)
    j_ls = from_tensor(np.linalg.inv(to_tensor(p_ls)))
    bias = j_ls - from_tensor(J)
    leak = attenuation_leak(j_ls, A, N)
    assert abs(bias[0]) > 0.5 * J[0, 0]                         # Ixx more than 50 % off
    left = j_ls + leak - from_tensor(J)
    # what is left is the compensated estimator's own scatter (its noise amplified 1/(1 − s)):
    # tens of kg·m² on this sample, against a bias of 2000 on Ixx
    assert abs(left[0]) < 0.01 * abs(bias[0]) and np.abs(left).max() < 0.05 * np.abs(bias).max(), (bias, left)
    assert np.all(leak != 0.0)
    # every direction all noise (share 1.2): undone at most to LEAK_SHARE, P / (1 − 0.99), so J / 100
    np.testing.assert_allclose(attenuation_leak(j_ls, A, 1.2 * A), -LEAK_SHARE * j_ls, rtol=1e-9)


def test_second_order_covariance_is_the_spread_of_the_second_order_term():
    """errors_in_variables.second_order_covariance, from three realisations of a correlated
    closed-loop noise (the input an integrated, band-passed mix of the output's noise), against
    the covariance of the normal equations' second-order term Σ_n ΔX_nᵀ W (Δy_n − P Δu_n) over
    600 draws: the estimate's mean over 100 independent sets within 15 % on every entry's
    variance (the empirical one itself ±6 %), their correlations within 0.15; one set's
    estimate scatters (a few frequencies carry the input noise) but not by a factor."""
    rng = np.random.default_rng(5)
    n = 4000
    mix = rng.standard_normal((6, 6))
    sos = butter(2, [0.3, 3.0], btype="bandpass", fs=FS, output="sos")

    def draw(m):
        x = rng.standard_normal((m, n, 6)) @ mix.T
        du = sosfiltfilt(sos, np.cumsum(x[..., :3], axis=1) * 0.05, axis=1)
        dy = sosfiltfilt(sos, x[..., 3:] + 0.3 * x[..., :3], axis=1)
        return du, dy

    P = np.linalg.inv(J_TRUE / 1000.0)
    w = np.array([1.0, 2.0, 0.5])
    H = quadratic_forms(basis(), w, P)
    # the quadratic forms are the normal equations' term: zᵀ H_k z = (ΔXᵀ W (Δy − P Δu))_k
    du, dy = draw(1)
    z = np.concatenate([du, dy], axis=2)[0]
    dX = np.einsum("kij,nj->nik", basis(), du[0])
    np.testing.assert_allclose(np.einsum("na,kab,nb->k", z, H, z),
                               np.einsum("nik,i,ni->k", dX, w, dy[0] - du[0] @ P.T), rtol=1e-10)
    q, est = [], []
    for _ in range(100):
        du, dy = draw(6)
        z = np.concatenate([du, dy], axis=2)
        q.extend(np.einsum("mna,kab,mnb->mk", z, H, z))
        est.append(second_order_covariance([NoiseRealisations(du[:3], dy[:3])], w, P))
    emp = np.cov(np.array(q).T)
    est = np.array(est)
    mean = est.mean(0)
    ratio = np.diag(mean) / np.diag(emp)
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio

    def corr(C):
        d = np.sqrt(np.diag(C))
        return C / np.outer(d, d)

    np.testing.assert_allclose(corr(mean), corr(emp), atol=0.15)
    one = est[:, range(6), range(6)] / np.diag(emp)
    assert np.all(np.median(one, axis=0) > 0.6) and np.all(np.median(one, axis=0) < 1.4), np.median(one, axis=0)
