"""Calibrated uncertainty (issue 4): noise levels from the data, the propagated σ, the
compensation for the noise in the fit's input."""
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import background, gather

from rig_identification.estimation.uncertainty import (
    NoiseReplays,
    confirmed_sigma_factor,
    noise_replays,
    pooled_replays,
)
from rig_identification.io.noise import white_sigma
from rig_identification.io.recording import Recording, SensorData, TimeSeries
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.parametrisation import from_tensor
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import identify_recording

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "rigs" / "default.yaml"


def test_white_sigma_ignores_slow_motion_and_steps():
    rng = np.random.default_rng(3)
    fs = 200.0
    t = np.arange(0, 60, 1 / fs)
    x = 5.0 * np.sin(2 * np.pi * 1.2 * t) + 2.0 * np.sin(2 * np.pi * 2.9 * t + 1) + 30.0 * (t > 20)
    sig = 0.01
    est = white_sigma(x + sig * rng.standard_normal(len(t)))
    assert est == pytest.approx(sig, rel=0.03)
    # without noise, the motion alone reads as (almost) nothing
    assert white_sigma(x) < 0.05 * sig


def _case16_noisy():
    """Job: thesis case 16 (config/rigs/default.yaml: reference noise), 120 s, identified.
    Returns (truth, result)."""
    d = yaml.safe_load(DEFAULT.read_text())
    d["rig"].pop("dummy_mass", None)
    sim = simulate(experiment_from_dict(d, "case 16"))
    return sim.truth, identify_recording(Recording(sim.rig, sim.sensors, sim.truth))


background("case16_noisy", __file__, _case16_noisy, {"run": ()})


@pytest.fixture(scope="module")
def case16_noisy():
    return gather("case16_noisy")["run"]


def test_bias_correction_matches_the_monte_carlo_bias(case16_noisy):
    """bench/bench_montecarlo_inertia.py measured the least-squares estimator's bias on this
    case: Iyy +0.035 kg·m² (0.3 of its spread; with the true pose it vanishes: the gyro's
    noise in the input, through the pose).  The compensation for the noise in the input
    (three antithetic pairs on one recording) must remove about that much."""
    _, res = case16_noisy
    corr = dict(zip(KEYS, res.bias_correction))
    assert 0.015 < corr["iyy"] < 0.06, corr
    # and the correction is small against the σ everywhere (a clean, well-excited rig)
    assert np.all(np.abs(res.bias_correction) < 0.5 * res.inertia_std), (res.bias_correction, res.inertia_std)


def test_propagated_std_accounts_for_more_than_the_gyro(case16_noisy):
    """On a clean simulated recording the reported σ is the noise propagated through the
    whole chain, from noise levels the recording itself gives, and the truth lies within
    3 of them.  (That these σ are the spread of the estimator — 0.99–1.01 of it on 200
    replays — is bench/bench_montecarlo_inertia.py's measurement, not a test's.)"""
    tru, res = case16_noisy
    truth = np.array([tru["inertia_about_cg"][k] for k in KEYS])
    err = from_tensor(res.inertia) - truth
    assert np.all(np.abs(err) < 3 * res.inertia_std), (err, res.inertia_std)
    assert res.sensor_noise["gyro"] == pytest.approx(0.002, rel=0.05)
    assert res.sensor_noise["load_cell"] == pytest.approx(0.5, rel=0.05)
    assert res.sensor_noise["inclinometer"] == pytest.approx(0.0002, rel=0.05)
    d = res.to_dict()
    assert d["uncertainty"].startswith("propagated sensor noise") and set(d["inertia_sandwich_std"]) == set(KEYS)
    # the propagated σ (the compensation's own jackknife σ counted in it); verdict ok, so
    # nothing else widens it
    assert res.validation.verdict == "ok", res.validation.summary
    np.testing.assert_allclose(res.inertia_std, res.crb_std * res.validation.sigma_factor * (res.replay_factor or 1.0),
                               rtol=1e-12)


def test_replays_widen_sigma_only_beyond_their_significance():
    """NoiseReplays.sigma_factor: the replays' Birge ratio widens σ only where their χ² is
    significant (beyond the 95 % quantile): three pairs (18 dof) spreading 1.2× the
    covariance's σ are within the noise of the comparison (χ² 25.9 < 28.9) and leave σ alone;
    spreading 3× they widen it 3×."""
    rng = np.random.default_rng(3)
    C = np.diag([4.0, 1.0, 9.0, 0.25, 1.0, 16.0])
    L = np.linalg.cholesky(C)
    z = rng.standard_normal((3, 6))
    z *= np.sqrt(18 / np.sum(z**2))                 # Σ dᵀ C⁻¹ d = 18 exactly: ratio 1
    for scale, factor in ((1.0, 1.0), (1.2, 1.0), (3.0, 3.0)):
        rep = NoiseReplays(bias=np.zeros(6), draws=scale * z @ L.T)
        ratio, dof = rep.birge_ratio(C)
        assert dof == 18 and ratio == pytest.approx(scale, rel=1e-9)
        assert rep.sigma_factor(C)[0] == pytest.approx(factor, rel=1e-9)


def test_confirmation_halves_false_widening_and_measures_the_real_factor():
    """confirmed_sigma_factor (the sequential test of pipeline.refine_uncertainty): draws from
    the right covariance widen σ about 5 % of the time on three pairs alone, about 2 % with
    three pairs more to confirm; draws spreading 1.5× are widened about as often as before,
    by 1.5 on average (three pairs alone: by their threshold ratio 1.27 at least, and by
    chance above it)."""
    rng = np.random.default_rng(11)
    C = np.diag([4.0, 1.0, 9.0, 0.25, 1.0, 16.0])
    L = np.linalg.cholesky(C)
    n = 4000
    for true in (1.0, 1.5):
        def draws(k):
            return NoiseReplays(np.zeros(6), true * rng.standard_normal((k, 6)) @ L.T)
        single, confirmed, factors = 0, 0, []
        for _ in range(n):
            first = draws(3)
            single += first.sigma_factor(C)[0] > 1.0
            v = confirmed_sigma_factor(first, C, lambda pairs, at: draws(pairs), 3)
            assert len(v.replays.draws) == (6 if first.sigma_factor(C)[0] > 1.0 else 3)
            if v.factor > 1.0:
                confirmed += 1
                factors.append(v.factor)
                assert v.dof == 36
        if true == 1.0:
            assert 0.04 < single / n < 0.06 and 0.012 < confirmed / n < 0.03, (single / n, confirmed / n)
        else:
            assert confirmed / n > 0.75 and np.mean(factors) == pytest.approx(1.5, rel=0.05), np.mean(factors)


def test_replays_continue_the_same_noise():
    """noise_replays(first=K) draws pairs K, K+1, … of the same series: three pairs and three
    more pooled (pooled_replays) are the six of one call, bias and draws."""
    t = np.arange(50) * 0.005
    sensors = SensorData(TimeSeries(t, np.zeros((50, 6))), {"c0": TimeSeries(t, np.full(50, 100.0))})
    noise = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 0.0002}

    def fit(sl):   # a nonlinear "estimate" of the noise: its odd and even parts both move
        s = sl[0]
        x = np.concatenate([s.imu.data[:3].ravel(), s.load_cells["c0"].data[:3].ravel()])[:6]
        return x + 10.0 * x**2

    base = fit([sensors])
    whole = noise_replays(fit, base, [sensors], [noise], seed=5, pairs=6)
    parts = pooled_replays(noise_replays(fit, base, [sensors], [noise], seed=5, pairs=3),
                           noise_replays(fit, base, [sensors], [noise], seed=5, pairs=3, first=3))
    np.testing.assert_allclose(parts.draws, whole.draws, rtol=0, atol=0)
    np.testing.assert_allclose(parts.bias, whole.bias, rtol=1e-12, atol=1e-15)
    assert np.any(whole.bias != 0.0) and len(whole.draws) == 6
