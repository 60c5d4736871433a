"""The identifier's signal helpers: stepped inputs found, integrated without smearing a step,
the pass band around the motion (the white-noise level is io.noise.white_sigma, the one estimator).

Used by the gyro-only fit (:mod:`rig_identification.estimation.gyro_fit`).
"""
from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_simpson, cumulative_trapezoid
from scipy.signal import welch

STEP_SCALE = 10.0
"""A jump between two samples counts as a stepped input when its second difference is this
many times the median ‖second difference‖ of the signal (see :func:`step_indices`): white
noise (√6 σ per component) never gets there by chance; a smooth signal's second
differences are all alike, and the shape test alone decides."""


def step_indices(x: np.ndarray) -> np.ndarray:
    """Samples at which a sampled signal steps (the thesis's force pulses, cases 1–8).

    With the second differences D_k = x_k − 2x_{k−1} + x_{k−2}, a step Δ between samples
    k−1 and k gives D_k ≈ Δ and D_{k+1} ≈ −Δ whatever the signal's slope; index ``k`` is
    returned when ‖D_k‖ > :data:`STEP_SCALE` × median ‖D‖ and ‖D_k + D_{k+1}‖ < ‖D_k‖/2
    (an outlier in one sample gives D_{k+1} ≈ −2 D_k, a kink no D_{k+1}; a smooth or
    noisy signal has no step).

    x: (N,) or (N, m) samples on a uniform grid.  Returns the indices (K,) int, each in
    [2, N−2], ascending.
    """
    x = np.asarray(x, float).reshape(len(x), -1)
    if len(x) < 5:
        return np.zeros(0, int)
    D = np.diff(x, 2, axis=0)                       # D[k-2] = x_k - 2 x_{k-1} + x_{k-2}
    n = np.linalg.norm(D, axis=1)
    floor = max(STEP_SCALE * float(np.median(n)), 1e-9 * float(np.abs(x).max()))
    big = (n[:-1] > floor) & (np.linalg.norm(D[:-1] + D[1:], axis=1) < 0.5 * n[:-1])
    return np.nonzero(big)[0] + 2


def cumulative_integral(x: np.ndarray, t: np.ndarray, steps: np.ndarray | None = None) -> np.ndarray:
    """∫ x dt from t[0] at every sample: Simpson's rule (scipy ``cumulative_simpson``)
    between stepped inputs, no interpolation across a step.

    A step at sample ``k`` (``steps``, default :func:`step_indices` of ``x``) is placed at
    t[k], the first sample that shows it (zero-order hold: an input switched on the
    sampling clock, as the thesis's Simulink pulses), so the interval [t[k−1], t[k]]
    is integrated from the samples before it (the two-step Adams–Bashforth rule,
    (3x_{k−1} − x_{k−2})/2 per dt).  Simpson's rule across the jump would put the step
    half a sample early: +0.13 % on Ixx of thesis case 2 with the true pose.

    x: (N, m); t: (N,) s.  Returns (N, m), 0 at t[0].
    """
    x = np.asarray(x, float)
    t = np.asarray(t, float)
    ks = step_indices(x) if steps is None else np.asarray(steps, int)
    if len(ks) == 0:
        whole: np.ndarray = cumulative_simpson(x, x=t, axis=0, initial=0.0)
        return whole
    out = np.empty_like(x)
    start, base = 0, 0.0
    for k in list(ks) + [len(x)]:
        piece = x[start:k]
        tp = t[start:k]
        rule = cumulative_simpson if len(piece) >= 3 else cumulative_trapezoid
        out[start:k] = base + rule(piece, x=tp, axis=0, initial=0.0)
        if k < len(x):
            prev = x[k - 2] if k - 2 >= start else x[k - 1]
            base = out[k - 1] + (1.5 * x[k - 1] - 0.5 * prev) * (t[k] - t[k - 1])
            start = k
    return out


def auto_band(omega: np.ndarray, fs: float, f_min: float = 0.15) -> tuple[float, float]:
    """Pass band (Hz) around where the body actually moves.

    From the Welch spectrum (scipy) of the gyro (N,3): the band holding the spectral
    bins that stand 100x above the noise floor (median of the upper half of the
    spectrum) and within 10^-4 of the highest peak, widened by 0.6x below and 1.5x
    above.  The low edge is at least ``f_min`` (1.5x the tracker's correction
    bandwidth): below it the pose, hence the integrated moment, carries the
    tracker's slow corrections.  Above the band there is only noise.
    """
    nper = int(min(len(omega), 2 ** np.ceil(np.log2(20 * fs))))
    f, P = welch(omega, fs=fs, nperseg=nper, axis=0)
    P = P.sum(1)
    floor = np.median(P[f > fs / 4])
    sig = np.nonzero((P > max(100 * floor, 1e-4 * P[f > 0.05].max())) & (f > 0.05))[0]
    if len(sig) == 0:
        return max(f_min, 0.25), min(5.0, 0.4 * fs)
    lo = max(f_min, 0.6 * f[sig[0]])
    return lo, min(0.4 * fs, max(1.5 * f[sig[-1]], 2.0 * lo))

