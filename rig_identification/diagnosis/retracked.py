"""First-order columns of the data errors that act through the tracker: the gyro's bias
drift and scale factors, and a structural mode of a sensor's mount (the method as a whole:
:mod:`~rig_identification.diagnosis.selection`).

An error of the gyro reaches the fit twice: in the angular velocity the fit compares with
the Euler equation, and through the tracked orientation, from which the cables' directions
— and so the measured moment and force — are computed.  The second path dominates: a
random-walk bias of 1e-4 rad/s/√s (its in-band power 1/12 of the gyro's white noise)
turned a random 4-cable rig's tracked yaw by tens of mrad over 90 s, and its gyro-z residual
was 8× the noise.  How the tracker answers a bias or a scale (its complementary filters, the
inclinometer, the cables' length constraints, the yaw anchor) is measured, not modelled:
each column is the finite difference of two windows re-tracked from the recording, one with
a small trial of the error removed (:func:`columns`) — the angular velocity, the specific
force, the moment and force from the re-tracked cable directions, and the mean levels.
Once, at the rigid-body baseline; the exact iteration of
:func:`~rig_identification.diagnosis.exact.exact_iterate` corrects what the first order
misses.

``gyro_bias_drift`` is a bias that is a smooth function of time, per gyro axis: piecewise
linear between knots :data:`KNOT_SPACING` apart (:func:`knots`, :func:`bias_path`).  A
random walk of intensity q (rad/s/√s) changes by q √Δ between knots Δ apart, so the
fitted knot values give q (:func:`random_walk`, their own noise subtracted).
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .model_extension import Column, Model
from .window import Window

KNOT_SPACING = 10.0   # s: knots of the bias drift (a 1e-4 rad/s/√s walk: 10 s left the fit ok, 20 s did not)
MIN_KNOTS = 3
DRIFT_STEP = 1e-3     # rad/s: trial bias of the finite differences
SCALE_STEP = 1e-3     # trial scale-factor error
MODE_STEP = 0.05      # trial participation of a structural mode


def knots(t0: float, t1: float, spacing: float = KNOT_SPACING) -> np.ndarray:
    """Knot stamps (K,) s of the bias drift over [t0, t1]: evenly spaced, about ``spacing``
    apart, at least :data:`MIN_KNOTS`, the first and last at the ends."""
    k = max(MIN_KNOTS, int(round((t1 - t0) / spacing)) + 1)
    return np.linspace(t0, t1, k)


def bias_path(t: np.ndarray, knot_t: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """The drifting bias (N, 3) rad/s at stamps t (N,) s: per axis, linear between the knots
    ``knot_t`` (K,) s through the values ``coefficients`` (3K,) rad/s (axis-major: x at every
    knot, then y, then z), held beyond the ends."""
    c = np.asarray(coefficients, float).reshape(3, len(knot_t))
    return np.column_stack([np.interp(t, knot_t, c[a]) for a in range(3)])


def random_walk(coefficients: np.ndarray, std: np.ndarray, knot_t: np.ndarray) -> tuple[float, float]:
    """(q, σ_q) rad/s/√s: the random-walk intensity of a bias drift from its knot values
    (3K,) rad/s and their σ (3K,): q² = (mean of the squared increments between knots − the
    mean variance the knots' own noise gives them) / Δ, floored at 0; σ_q from the χ² spread
    of 3(K − 1) increments (σ_q² ≈ q² / (2 n))."""
    K = len(knot_t)
    c = np.asarray(coefficients, float).reshape(3, K)
    s = np.asarray(std, float).reshape(3, K)
    d = float(np.mean(np.diff(knot_t)))
    inc = np.diff(c, axis=1)
    noise = s[:, 1:] ** 2 + s[:, :-1] ** 2
    q2 = max(float(np.mean(inc ** 2) - np.mean(noise)), 0.0) / d
    n = inc.size
    return float(np.sqrt(q2)), float(np.sqrt(q2 / (2 * n) + np.mean(noise) / d / (2 * n)) if n else float("nan"))


def _mean_gyro_level(w: Window) -> np.ndarray:
    """Mean angular velocity minus the tracked net rotation over the window (3,) rad/s,
    body axes (the diagnosis model's mean-gyro residual before any fit)."""
    net = Rotation.from_matrix(w.R[0].T @ w.R[-1]).as_rotvec()
    return w.omega.mean(0) - net / (w.t[-1] - w.t[0])


def columns(window_of, ref: Window, model: Model, trials: list) -> list[Column]:
    """One :class:`~rig_identification.diagnosis.model_extension.Column` per trial: the
    change of the model's data per unit of an error removed, by finite differences of
    re-tracked windows.  ``window_of(applied)`` re-tracks the recording with the corrections
    ``applied`` (key -> value, :func:`~rig_identification.diagnosis.candidates.corrected`);
    ``ref`` is its window for the reference corrections; ``trials`` (name, applied, step):
    the corrections with one error's trial value ``step`` in place.  Raises ValueError when
    a trial window's stamps differ from the reference's (the cleaning excluded other spans).
    """
    out = []
    g0 = _mean_gyro_level(ref)
    newton0 = ref.force / ref.mass
    for name, applied, step in trials:
        w = window_of(applied)
        if len(w.t) != len(ref.t) or np.max(np.abs(w.t - ref.t)) > 1e-9:
            raise ValueError(f"the re-tracked window of {name} has other stamps than the reference's")
        d_om = (w.omega - ref.omega) / step
        d_f = (w.f - ref.f) / step
        d_newton = (w.force / w.mass - newton0) / step
        d_M = (w.torque - ref.torque) / step
        any_f = bool(np.any(d_f))
        out.append(Column(name, rot_D=d_M, rot_O=model.filt(d_om), tr_D=d_newton,
                          tr_O=model.filt(d_f) if any_f else None,
                          dcg=(_mean_gyro_level(w) - g0) / step,
                          dca=(d_f.mean(0) if any_f else 0.0) - d_newton.mean(0)))
    return out
