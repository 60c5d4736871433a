"""diagnose's newer physics and its joint search: the structural mode located above the fit
band, the gyro's bias drift as knots, a load cell's gain on the right cell, two effects named
together — and none of them named where the recording does not hold them.

The building blocks are tested on synthetic data (milliseconds); the whole chain
(`pipeline.with_diagnosis`, what `rig-identify inertia` does under model error) on short
simulations of random rigs (design.scenarios, the bench_trust rows' physics), as background
jobs (conftest.background).
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import background, gather

from rig_identification.diagnosis.retracked import bias_path, knots, random_walk
from rig_identification.diagnosis.structural import Transfer, fit_mode, mode_filter, response
from rig_identification.model.effects import Effect
from rig_identification.model.sensors import mode_response
from rig_identification.model.sensors import random_walk as simulated_walk


def synthetic_transfer(sensor: str, frequency: float, zeta: float, p: float, sigma: float, seed: int = 1):
    """A :class:`Transfer` as a rig with a mode of ``sensor``'s mount shows it above a band of
    0.4–2 Hz: coherent frequencies 2–5 Hz every 0.1 Hz (the rig's higher modes), H = p G
    (imu) or 1/(1 + p G) − 1 (load cells), complex noise of σ ``sigma``."""
    rng = np.random.default_rng(seed)
    f = np.arange(0.1, 10.0, 0.1)
    g = p * response(f, frequency, zeta) if p else np.zeros(len(f), complex)
    H = g if sensor == "imu" else 1.0 / (1.0 + g) - 1.0
    H = H + sigma * (rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))) / np.sqrt(2)
    coh = np.where((f >= 2.0) & (f <= 5.0), 0.99, 0.2)
    return Transfer(f, H, np.full(len(f), sigma ** 2), coh, (0.4, 2.0))


@pytest.mark.parametrize("sensor", ["imu", "load_cells"])
def test_structural_mode_is_located_from_the_transfer_above_the_band(sensor):
    """A mode at 8 Hz (ζ 0.03, the physical oscillator p = 1) seen at 2–5 Hz through noise of
    σ 0.002 (the H1 estimate's on a 90 s recording): found on the right sensor's side, its
    frequency within 3 % and 3 σ; the other sensor's model finds nothing (None: no mode of
    positive participation explains a departure of the other sign)."""
    tr = synthetic_transfer(sensor, 8.0, 0.03, 1.0, 0.002)
    fit = fit_mode(tr, sensor, 200.0)
    assert fit is not None and fit.likelihood_ratio > 100, fit
    assert abs(fit.frequency - 8.0) < min(0.03 * 8.0, 3 * fit.std["frequency"] + 0.05), fit
    other = fit_mode(tr, "load_cells" if sensor == "imu" else "imu", 200.0)
    assert other is None or other.likelihood_ratio < 5.0, other


def test_no_structural_mode_in_noise():
    """H = 0 plus noise: no mode (None, or a likelihood ratio a χ² of 3 dof reaches by chance)."""
    for seed in range(5):
        tr = synthetic_transfer("imu", 8.0, 0.03, 0.0, 0.002, seed=seed)
        for sensor in ("imu", "load_cells"):
            fit = fit_mode(tr, sensor, 200.0)
            assert fit is None or fit.likelihood_ratio < 16.3, (seed, sensor, fit)   # χ²₃ at p = 0.001


def test_mode_filter_removes_the_simulated_mode():
    """The simulator's mount (model.sensors.mode_response, 8 Hz, ζ 0.03) on a 1.1 Hz + 2.3 Hz
    signal, removed by mode_filter: back to the signal within 1e-4 of the mode's effect, away
    from the ends."""
    t = np.arange(0.0, 60.0, 0.005)
    u = np.column_stack([np.sin(2 * np.pi * 1.1 * t) + 0.3 * np.sin(2 * np.pi * 2.3 * t + 0.4),
                         np.cos(2 * np.pi * 0.7 * t)])
    e = Effect("structural_mode", {"sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03})
    measured = u + mode_response(t, u, e)
    back = mode_filter(t, measured, 8.0, 0.03, 1.0)
    inner = slice(2000, -2000)
    assert np.abs(back - u)[inner].max() < 1e-4 * np.abs(measured - u).max()


def test_random_walk_from_knots():
    """A simulated random-walk bias (model.sensors.random_walk, 1e-4 rad/s/√s, 3 axes, 200 Hz,
    600 s) read at knots 10 s apart with σ 2e-5 rad/s of estimation noise: its intensity
    within 20 % (3(K − 1) = 177 increments: the χ² spread is 5 %)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 600.0, 0.005)
    b = simulated_walk(rng, len(t), 0.005, 1e-4)
    kn = knots(t[0], t[-1])
    idx = np.searchsorted(t, kn).clip(0, len(t) - 1)
    c = (b[idx] + 2e-5 * rng.standard_normal((len(kn), 3))).T.ravel()
    rw = random_walk(c, np.full(c.size, 2e-5), kn)
    assert abs(rw.intensity - 1e-4) < 0.2e-4, rw
    assert 0 < rw.std < 0.3 * rw.intensity and rw.increments == 3 * (len(kn) - 1)
    assert bias_path(t, kn, c).shape == (len(t), 3)
    np.testing.assert_allclose(bias_path(kn, kn, c), c.reshape(3, -1).T, atol=1e-15)   # through the knots


def test_random_walk_when_the_knots_err_more_than_stated():
    """Knots of a 60 s window (7, 10 s apart) whose values err 3× the σ their fit states
    (1.2e-4 rad/s against 4e-5 — on a simulated 60 s rig the end knots erred 4–10× theirs):
    over 100 realisations of a 1e-4 rad/s/√s walk the restricted-ML intensity comes out
    within 25 % of it on average (subtracting the stated variance alone gives ~1.9e-4: the
    increments' variance is q²d + 2s²), the error scale λ near 3, and ±2σ of q covers the
    truth on ≥ 75 % (with 18 increments the Fisher σ at the estimate runs ~20 % short: 83 %
    over 200 draws of another generator; 93 % with 180 increments)."""
    rng = np.random.default_rng(5)
    kn = np.arange(7) * 10.0
    est = [random_walk((np.cumsum(rng.standard_normal((3, 7)) * 1e-4 * np.sqrt(10.0), axis=1)
                        + 1.2e-4 * rng.standard_normal((3, 7))).ravel(), np.full(21, 4e-5), kn)
           for _ in range(100)]
    q = np.array([r.intensity for r in est])
    assert abs(q.mean() / 1e-4 - 1) < 0.25, q.mean()
    assert abs(np.median([r.error_scale for r in est]) / 3.0 - 1) < 0.25
    assert np.mean([abs(r.intensity - 1e-4) < 2 * r.std for r in est]) >= 0.75


# --- the whole chain on short simulated rigs ---------------------------------------------------

E2E_DURATION = 60.0


def _pipeline(seed: int, effects: list, duration: float = E2E_DURATION) -> dict:
    """Job: a random 4-cable rig (design.scenarios.simulate_random, ``wide`` layout, the
    bench_trust rows' physics) with ``effects``, the rigid-body fit and `pipeline.with_diagnosis`
    on it (what `rig-identify inertia` does).  Returns the JSON-safe result: verdict, the
    named effects, the truth."""
    from rig_identification.design.scenarios import simulate_random
    from rig_identification.io.recording import Recording
    from rig_identification.pipeline.offline import identify_recording, with_diagnosis
    _, sim = simulate_random(seed, 4, "wide", effects, duration)
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    res = with_diagnosis(rec, identify_recording(rec))
    diag = res.diagnosis or {}
    return json.loads(json.dumps({"verdict": res.validation.verdict if res.validation else None,
                                  "effects": diag.get("effects", []), "unexplained": diag.get("unexplained", []),
                                  "truth": sim.truth}, default=float))


# seeds of their own (not bench_trust's), 60 s each
E2E = {
    "gyro_bias_drift": (8900, [{"name": "gyro_bias_drift", "random_walk": 1e-4}]),
    "structural_mode": (8901, [{"name": "structural_mode", "sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03}]),
    "pair": (8902, [{"name": "sensor_delay", "stream": "load_cells", "delay": 0.02},
                    {"name": "viscous_damping", "linear": 150.0, "angular": 300.0}]),
}
background("diagnose_search", __file__, _pipeline, {k: v for k, v in E2E.items()})


def _named(res: dict) -> list:
    return [e["name"] for e in res["effects"]]


def test_gyro_bias_drift_is_named_with_its_random_walk():
    """A random-walk gyro bias of 1e-4 rad/s/√s (60 s, 4-cable rig): diagnosis names
    gyro_bias_drift and nothing else; the fit with it passes validation; its intensity within
    a factor 2 and 3 of its σ of the simulator's (7 knots 10 s apart, 18 increments over the
    three axes: the χ² spread of the estimate alone is ~17 %, the realised walk's another
    ~17 %; the knots' own error, 1.3–1.8× their stated σ here, is estimated with q:
    retracked.random_walk)."""
    res = gather("diagnose_search", "gyro_bias_drift")["gyro_bias_drift"]
    assert _named(res) == ["gyro_bias_drift"], (_named(res), res["unexplained"][:2])
    assert res["verdict"] == "ok"
    q = res["effects"][0]["parameters"]["random_walk"]
    sq = res["effects"][0]["parameters_std"]["random_walk"]
    assert 0.5e-4 < q < 2e-4 and abs(q - 1e-4) < 3 * sq, res["effects"][0]


def test_structural_mode_is_named_with_an_honest_frequency():
    """An 8 Hz mode (ζ 0.03) of the IMU's mount (60 s, 4-cable rig): named on the IMU's side,
    nothing else named, and its frequency honest — within 3 of its σ of the simulator's, and
    ``frequency_located`` saying whether the transfer above the band fixed it
    (structural.LOCATED_REL_STD) or only p / f_n² (the frequency then the physical
    oscillator's, p = 1).  (The frequency to 3 % when the data hold it: the synthetic
    transfer test above; this 60 s recording has three coherent frequencies at 2.0–2.4 Hz,
    far below the mode.)"""
    res = gather("diagnose_search", "structural_mode")["structural_mode"]
    assert _named(res) == ["structural_mode"], (_named(res), res["unexplained"][:2])
    e = res["effects"][0]
    p, sd = e["parameters"], e["parameters_std"]
    assert p["sensor"] == "imu", p
    assert abs(p["frequency"] - 8.0) < 3 * sd["frequency"], (p, sd)
    assert p["frequency_located"] == (sd["frequency"] < 0.15 * p["frequency"]), (p, sd)
    if not p["frequency_located"]:
        assert p["participation"] == 1.0 and "participation" not in sd, (p, sd)


@pytest.mark.xfail(strict=True, reason="open: measured on a370322, seed 8902 (60 s): nothing named, unexplained "
                   "accel_x/force_x at 1.32-1.42 Hz; bench_trust delay_damping names the pair on seed 7900 (90 s), "
                   "not on 7901")
def test_two_effects_are_named_together():
    """Load cells 20 ms late and viscous damping at once (60 s, 4-cable rig): both named, each
    parameter within 15 %, nothing else; the fit with both passes validation."""
    res = gather("diagnose_search", "pair")["pair"]
    assert sorted(_named(res)) == ["sensor_delay", "viscous_damping"], (_named(res), res["unexplained"][:2])
    assert res["verdict"] == "ok"
    p = {e["name"]: e["parameters"] for e in res["effects"]}
    assert abs(p["sensor_delay"]["delay"] / 0.02 - 1) < 0.15, p
    for k, v in (("linear", 150.0), ("angular", 300.0)):
        assert abs(p["viscous_damping"][k] / v - 1) < 0.15, p
