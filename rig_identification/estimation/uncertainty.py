"""What the noise does to a recording's gyro-only inertia estimate: its σ, and draws of noise.

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
* adds fresh white noise at given levels to a recording's streams (:func:`add_noise`; antithetic
  pairs ``s ± m`` with ``sign``), for the benches' Monte Carlo draws.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ..io.noise import white_sigma
from ..io.recording import SensorData, TimeSeries
from ..io.rig import Rig
from .preprocessor import generalized_wrench
from .propagation import Trajectory, predict_from_trajectory

if TYPE_CHECKING:
    from .prediction import Prediction
    from .tracker import PoseTrack



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
