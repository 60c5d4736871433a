"""What the noise does to a recording's inertia estimate: its σ, and draws of its noise.

The identifier's own sandwich covariance (:func:`~rig_identification.estimation.identification.identify_inertia`) sees
the fit's residuals only; the noise reaches the estimate by more paths than the output
(the tracker's pose, integrated from the same gyro and seen through the cable tensions,
the load cells, the exciter; see :mod:`rig_identification.design.planning`).  For a recording, this module

* estimates every sensor's white-noise σ from the data itself (:func:`sensor_noise`: the
  robust spread of third differences, which a motion below a few Hz does not reach);
* propagates those noise levels through the linearised tracker, preprocessor and
  identifier along the recording's own tracked trajectory
  (:func:`~rig_identification.estimation.propagation.predict_from_trajectory`; :func:`propagated`): the Cramér–Rao-type
  bound of this estimator for the recording's excitation, coloured residuals included;
* re-runs the chain with fresh noise at those levels (:func:`noise_replays`, antithetic
  pairs ``s ± m``): ``½[x(s + m) − x(s − m)]`` of any quantity x of the chain is a draw of
  its first-order noise.  The identifier's draws check the propagated σ
  (:meth:`NoiseReplays.sigma_factor`); the regressor's and output's are the realisations
  with which the fit is compensated for the noise in its input
  (:mod:`rig_identification.estimation.errors_in_variables`: the tracker's pose carries the integrated gyro noise into
  the torque while the output carries the same gyro noise — an errors-in-variables bias,
  on thesis case 16 at the reference noise +0.035 kg·m² on Iyy, a third of its σ; on an
  axis the body hardly turns, many σ).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from ..io.noise import white_sigma
from ..io.recording import SensorData, TimeSeries
from ..io.rig import Rig
from .preprocessor import generalized_wrench
from .propagation import Trajectory, predict_from_trajectory

if TYPE_CHECKING:
    from .prediction import Prediction
    from .tracker import PoseTrack

REPLAY_ALPHA = 0.05
"""Significance at which the replays' spread widens the propagated σ (:meth:`NoiseReplays.sigma_factor`)."""


def sensor_noise(rig: Rig, sensors: SensorData) -> tuple[dict[str, float], dict[str, float]]:
    """White-noise σ per source and sample rate per stream, estimated from a recording.

    sensors: :class:`~rig_identification.io.recording.SensorData`.  Returns (noise, rates): noise {"gyro" rad/s,
    "accelerometer" m/s², "load_cell" N (pooled over the cables), "exciter" N, "inclinometer"
    rad} (0.0 for a missing stream), rates {"imu", "load_cells", "exciter", "inclinometer"} Hz
    (the keys of :data:`~rig_identification.estimation.propagation.REFERENCE_NOISE` / ``REFERENCE_RATES``)."""
    def rate(ts: TimeSeries | None) -> float:
        return float(1.0 / np.median(np.diff(ts.t))) if ts is not None and len(ts.t) > 1 else 0.0

    cells = [sensors.load_cells[n] for n in rig.cable_names]
    noise = {"gyro": white_sigma(sensors.imu.data[:, :3]),
             "accelerometer": white_sigma(sensors.imu.data[:, 3:6]),
             "load_cell": float(np.sqrt(np.mean([white_sigma(c.data[:, 0]) ** 2 for c in cells]))),
             "exciter": white_sigma(sensors.exciter.data) if sensors.exciter is not None else 0.0,
             "inclinometer": white_sigma(sensors.inclinometer.data) if sensors.inclinometer is not None else 0.0}
    rates = {"imu": rate(sensors.imu), "load_cells": float(np.median([rate(c) for c in cells])),
             "exciter": rate(sensors.exciter) if sensors.exciter is not None else 0.0,
             "inclinometer": rate(sensors.inclinometer) if sensors.inclinometer is not None else 0.0}
    return noise, rates


def propagated(rig: Rig, poses: PoseTrack, sensors: SensorData, t_fit: np.ndarray, inertia: np.ndarray,
               band_hz: tuple[float, float], noise: dict[str, float], rates: dict[str, float],
               max_rate: float = 200.0) -> Prediction:
    """The σ of the identified tensor that the sensors' noise causes, along the recording's
    own trajectory (:func:`~rig_identification.estimation.propagation.predict_from_trajectory`).

    poses: the tracker's :class:`~rig_identification.estimation.tracker.PoseTrack` (from its initialisation on);
    sensors: the cleaned :class:`~rig_identification.io.recording.SensorData` it was tracked from; t_fit (N,) s:
    the fitted window's stamps; inertia (3,3) kg·m² the identified tensor (the linearisation
    point); band_hz: the fit's pass band; noise, rates: from :func:`sensor_noise`.  Streams
    faster than about ``max_rate`` Hz are sampled down for the prediction with the noise
    density kept.  Returns a :class:`~rig_identification.estimation.prediction.Prediction` (σ, covariance, per-source
    contributions).  Raises :class:`~rig_identification.estimation.prediction.PlanError` when the body hardly moves.
    """

    keep = poses.t <= t_fit[-1] + 1e-9
    t = poses.t[keep]
    fs = 1.0 / float(np.median(np.diff(t)))
    q = max(1, int(fs // max_rate))
    idx = np.arange(0, len(t), q)
    t = t[idx]
    R = Rotation.from_quat(poses.quaternion[keep][idx]).as_matrix()
    pos = poses.position[keep][idx]
    tens = np.column_stack([np.interp(t, sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0])
                            for n in rig.cable_names])
    exc = sensors.exciter.interp(t) if (sensors.exciter is not None and rig.exciter is not None) else None
    omega = rig.imu.rotation.apply(sensors.imu.interp(t)[:, :3])
    _, torque = generalized_wrench(rig, pos, R, tens, exc)
    fs_p = fs / q
    # per-sample σ at the prediction's rate with the white density of the real streams kept
    noise_p = dict(noise)
    noise_p["gyro"] = noise["gyro"] * math.sqrt(fs_p / rates["imu"])
    noise_p["accelerometer"] = noise["accelerometer"] * math.sqrt(fs_p / rates["imu"])
    rates_p = {k: (v if v > 0 else fs_p) for k, v in rates.items()}
    traj = Trajectory(t - t[0], omega, torque, pos, R, tens, exc, rig, np.asarray(inertia, float), rates_p)
    settle = float(t_fit[0] - t[0])
    return predict_from_trajectory(traj, noise_p, settle=settle, band_hz=tuple(band_hz))  # type: ignore[arg-type]  # (lo, hi)


def add_noise(sensors: SensorData, noise: dict[str, float], rng: np.random.Generator, sign: float = 1.0) -> SensorData:
    """A copy of ``sensors`` (:class:`~rig_identification.io.recording.SensorData`) with white noise of the σ in
    ``noise`` (keys as :func:`sensor_noise`) added (``sign`` = +1) or the same realisation
    subtracted (``sign`` = −1): pass generators in the same state for an antithetic pair.
    Draws in the order IMU (N,6), load cells, exciter, inclinometer."""

    def add(ts: TimeSeries | None, sig: float | list[float]) -> TimeSeries | None:
        if ts is None:
            return None
        z = rng.standard_normal(ts.data.shape)
        return TimeSeries(ts.t, ts.data + sign * np.asarray(sig, float) * z)

    imu = add(sensors.imu, [noise["gyro"]] * 3 + [noise["accelerometer"]] * 3)
    cells = {n: add(sensors.load_cells[n], noise["load_cell"]) for n in sensors.load_cells}
    return SensorData(imu, cells, add(sensors.exciter, noise["exciter"]),  # type: ignore[arg-type]  # add(): None for None only
                      add(sensors.inclinometer, noise["inclinometer"]))


@dataclass(frozen=True)
class NoiseReplays:
    """What replays with fresh noise say of an estimate (:func:`noise_replays`).

    bias (6,) kg·m²: the mean over the antithetic pairs of ``½[θ(s + m) + θ(s − m)] − θ(s)``,
    SIMEX's second-order estimate of the bias (Cook & Stefanski 1994; it sees only part of
    the errors-in-variables bias, which :mod:`rig_identification.estimation.errors_in_variables`
    removes); draws (K,6) kg·m²: ``½[θ(s + m) − θ(s − m)]`` per pair,
    each a draw of the estimate's first-order error at the recording's noise levels (the
    linear term ``L m``; the noise already in the data moves only the point it is taken at)."""

    bias: np.ndarray
    draws: np.ndarray

    def birge_ratio(self, covariance: np.ndarray) -> tuple[float, int]:
        """How much larger the replays' spread is than ``covariance`` (6,6) predicts: the
        Birge ratio √(Σ_k d_kᵀ C⁻¹ d_k / (6K)) (χ² with 6K degrees of freedom when C is right)
        and its degrees of freedom."""
        C = 0.5 * (covariance + covariance.T)
        ev, U = np.linalg.eigh(C)
        keep = ev > 1e-12 * max(ev.max(), 1e-300)
        z = self.draws @ U[:, keep]
        stat = float(np.sum(z**2 / ev[keep]))
        dof = int(keep.sum()) * len(self.draws)
        return float(np.sqrt(stat / max(dof, 1))), dof

    def sigma_factor(self, covariance: np.ndarray) -> tuple[float, int]:
        """The factor by which σ of ``covariance`` (6,6) must widen for the replays' spread, and
        the degrees of freedom of the comparison: the Birge ratio (:meth:`birge_ratio`) where
        the replays spread significantly more than the covariance predicts — its χ² beyond the
        1 − :data:`REPLAY_ALPHA` quantile —, else 1.  The rule of the validation's consistency
        checks (widened only beyond significance): with three pairs (18 dof) the ratio of a
        right covariance scatters ±17 %, and widening by every ratio above 1 made σ about 7 %
        too large on average (thesis case 16, 60 replays: the spread 1.05× the propagated σ,
        0.95× the widened one; bench_any_rig's clean sweep: error/σ RMS 1.04 with the
        propagated σ, 0.95 widened)."""
        ratio, dof = self.birge_ratio(covariance)
        significant = ratio**2 * dof > chi2.ppf(1.0 - REPLAY_ALPHA, max(dof, 1))
        return (ratio if significant else 1.0), dof


def noise_replays(fit: Callable[[list[SensorData]], ArrayLike], base: np.ndarray, sensors: list[SensorData],
                  noises: list[dict[str, float]], seed: int = 0, pairs: int = 1,
                  first: int = 0) -> NoiseReplays:
    """The estimate re-run on the recording(s) with ``pairs`` antithetic pairs of fresh white
    noise at the estimated levels (:func:`add_noise`): draws of the first-order error and
    the antithetic mean shift (:class:`NoiseReplays`).

    fit(list of SensorData) -> (6,) entries (the whole chain with the estimate's band and
    window); base: ``fit(sensors)``; sensors, noises: per recording.  ``fit`` is called
    2 × ``pairs`` times.  first: the number of the first pair — pairs first … first + pairs − 1
    draw the same noise whatever call makes them, so that a second call with ``first`` = the
    first call's ``pairs`` continues the series (:func:`pooled_replays`)."""
    base = np.asarray(base, float)
    bias, draws = [], []
    for p in range(first, first + pairs):
        out = []
        for sign in (+1.0, -1.0):
            out.append(np.asarray(fit([add_noise(s, n, np.random.default_rng([seed, i] if p == 0 else [seed, i, p]),
                                                 sign)
                                       for i, (s, n) in enumerate(zip(sensors, noises))]), float))
        bias.append(0.5 * (out[0] + out[1]) - base)
        draws.append(0.5 * (out[0] - out[1]))
    return NoiseReplays(np.mean(bias, axis=0), np.array(draws))


def pooled_replays(a: NoiseReplays, b: NoiseReplays) -> NoiseReplays:
    """The replays of ``a`` and ``b`` as one series (:func:`noise_replays` continued with
    ``first``): the bias averaged over all their pairs, the draws (K_a + K_b, 6) together."""
    ka, kb = len(a.draws), len(b.draws)
    return NoiseReplays((ka * np.asarray(a.bias) + kb * np.asarray(b.bias)) / max(ka + kb, 1),
                        np.vstack([a.draws, b.draws]))


@dataclass(frozen=True)
class ReplayFactor:
    """The replays' verdict on a propagated covariance (:func:`confirmed_sigma_factor`).

    factor ≥ 1: by which σ widens; dof: the degrees of freedom of the comparison (6 per pair);
    replays: every pair replayed (the confirmation's too)."""

    factor: float
    dof: int
    replays: NoiseReplays


def confirmed_sigma_factor(replays: NoiseReplays, covariance: np.ndarray, more: Callable[[int, int], NoiseReplays],
                           pairs: int) -> ReplayFactor:
    """:meth:`NoiseReplays.sigma_factor` of ``replays`` against ``covariance`` (6,6), confirmed:
    where it is significant, ``more(pairs, first)`` (:func:`noise_replays` continued at pair
    ``first``) replays ``pairs`` pairs more and the factor is that of all of them together —
    1 unless they still spread significantly more.  A sequential test: under a right covariance
    three pairs widen by chance 5 % of the time, by at least their threshold ratio (1.27 over
    18 dof); with three more the rate falls to 2 % and the factor is measured on 36 dof
    (±12 % instead of ±17 %; test_uncertainty measures both).  pairs = 0: no confirmation."""
    factor, dof = replays.sigma_factor(covariance)
    if factor > 1.0 and pairs > 0:
        replays = pooled_replays(replays, more(pairs, len(replays.draws)))
        factor, dof = replays.sigma_factor(covariance)
    return ReplayFactor(float(factor), int(dof), replays)
