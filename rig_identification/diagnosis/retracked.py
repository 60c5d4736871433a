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
fitted knot values give q (:func:`random_walk`: q and the knots' own error fitted together to
their increments).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
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


@dataclass(frozen=True)
class RandomWalk:
    """A random-walk intensity estimated from knot values (:func:`random_walk`).

    intensity, std: q and its σ, rad/s/√s; error_scale: λ, the knot values' real error over
    the σ their fit states; increments: how many increments it rests on."""

    intensity: float
    std: float
    error_scale: float
    increments: int


def random_walk(coefficients: np.ndarray, std: np.ndarray, knot_t: np.ndarray) -> RandomWalk:
    """The random-walk intensity of a bias drift from its knot values (3K,) rad/s (axis-major)
    at the knot stamps ``knot_t`` (K,) s and the σ their fit states, ``std`` (3K,) rad/s.

    Per axis, the increments Δ = D c of knot values that read a random walk of intensity q
    with errors of covariance λ² diag(σ²) are Gaussian with covariance
    V = q² diag(d) + λ² D diag(σ²) Dᵀ (d the knot spacings, D the first difference); q² and
    λ² are their restricted maximum-likelihood estimate over the three axes (differencing
    removes the unknown level: Harville, JASA 72:320, 1977).  λ is free because the fit's σ
    of the knots is not to be trusted on its own: on a 60 s, 4-cable simulated rig (seed
    8900) the end knots of the z axis erred by 4–10 times their stated σ, and subtracting the
    stated variance made q 2.08e-4 for a realised 1.03e-4.  σ of q from the Fisher
    information of (ln q², ln λ²), I_ij = ½ Σ tr(V⁻¹ ∂_iV V⁻¹ ∂_jV), mapped as
    σ_q = √(q² + σ_{q²}) − q (the delta method's σ_{q²} / 2q for q ≫ σ, √σ_{q²} at q = 0).
    Raises ValueError for fewer than three knots."""
    K = len(knot_t)
    if K < 3:
        raise ValueError(f"random_walk: {K} knot(s), at least 3 needed")
    D = np.diff(np.eye(K), axis=0)
    y = np.asarray(coefficients, float).reshape(3, K) @ D.T                 # (3, K−1) increments
    s2 = np.asarray(std, float).reshape(3, K) ** 2
    A = np.diag(np.diff(np.asarray(knot_t, float)))
    B = [D @ np.diag(v) @ D.T for v in s2]
    jitter = 1e-12 * float(np.mean(y ** 2)) * np.eye(K - 1)

    def parts(x):
        q2, l2 = np.exp(x)
        return [q2 * A + l2 * b + jitter for b in B]

    def nll(x):
        out = 0.0
        for V, ya in zip(parts(x), y):
            sign, logdet = np.linalg.slogdet(V)
            out += logdet + ya @ np.linalg.solve(V, ya)
        return 0.5 * out if sign > 0 else np.inf

    q2_0 = max(float(np.mean(y ** 2)) / float(np.mean(np.diag(A))), 1e-30)
    starts = [np.log([q2_0 * a, l2]) for a in (0.1, 0.5) for l2 in (1.0, 4.0)]
    best = min((minimize(nll, x0, method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-9, "maxiter": 2000})
                for x0 in starts), key=lambda r: r.fun)
    q2, l2 = np.exp(best.x)
    info = np.zeros((2, 2))        # of (ln q², ln λ²): ∂V/∂ln q² = q² A (well scaled, unlike q², λ²)
    for V, b in zip(parts(best.x), B):
        Vi = np.linalg.inv(V)
        P = (q2 * Vi @ A, l2 * Vi @ b)
        info += 0.5 * np.array([[np.trace(P[i] @ P[j]) for j in range(2)] for i in range(2)])
    std_q2 = q2 * float(np.sqrt(max(np.linalg.pinv(info)[0, 0], 0.0)))
    q = float(np.sqrt(q2))
    return RandomWalk(q, float(np.sqrt(q2 + std_q2) - q), float(np.sqrt(l2)), 3 * (K - 1))


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
