"""The gyro-only prediction-error fit: the inertia tensor about the CG from the generalized wrench and the gyro.

Model — the Newton–Euler rotational equation about the centre of gravity in body
axes, *with* the gyroscopic term the thesis dropped (thesis eq. 3.10 has ``J θ̈ = M``)::

    J ω̇ + ω × (J ω) = M                                   (Euler's equation)

Estimator — output-error form, no initial guess.  Integrating Euler's equation and
multiplying by the inverse tensor ``P = J⁻¹`` gives an equation that is *linear in P*
and predicts the measured output ω from the measured input M::

    ω(t) = ω(t0) + P ∫ (M − ω × J ω) dt

Both sides are band-pass filtered with the same zero-phase filter (scipy
``sosfiltfilt``; it removes ω(t0), the gyro bias and the slow drift of the integrated
moment and of the tracker), and P is fitted by linear least squares; the small
gyroscopic term is evaluated with the previous iterate of J (two or three passes,
starting from J = 0).  Because ω is the *output*, the gyro noise does not enter the
regressor: no errors-in-variables bias (least squares on differentiated noisy gyro
data is biased by a few percent; Ljung, *System Identification*, 2nd ed., §7.3 on
prediction-error vs. equation-error methods).  The regressor's own noise, the
integral of the load-cell noise, is small.

Uncertainty — the residuals are coloured (band-passed), so the covariance of the entries is
the sandwich (heteroscedasticity- and autocorrelation-consistent) estimate with batch means
over blocks longer than the correlation time (Huber 1967; White 1982).

Signals — stepped inputs (the thesis's force pulses) are found (:func:`step_indices`) and
integrated without smearing a step (:func:`cumulative_integral`); the pass band sits around the
motion (:func:`auto_band`).

This is the gyro-only fit: the rig model's first start for the tensor
(:func:`~rig_identification.pipeline.rig_model.start_tensor`: :func:`fit_gyro`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import cumulative_simpson, cumulative_trapezoid
from scipy.optimize import least_squares
from scipy.signal import butter, decimate, sosfiltfilt, welch

from ..model.parametrisation import basis, consistent_from_params, from_tensor, params_from_consistent, to_tensor

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


class IdentificationError(ValueError):
    """The data cannot give a trustworthy inertia estimate (too short, gaps, no motion)."""


STAGE1_CONDITION = 100.0   # largest / smallest principal moment of the Levenberg–Marquardt start
FIT_RATE = 200.0  # Hz: streams sampled ≥ 2× faster are decimated to about this rate before the fit


def sample_interval(t: np.ndarray, what: str) -> float:
    """The sampling interval (s) of a uniform grid t (N,) s.  Raises :class:`IdentificationError`
    (its message starting with ``what``) for fewer than 11 samples or a gap (an interval over
    1.5 × the median)."""
    dt = np.diff(t)
    if len(dt) < 10:
        raise IdentificationError(f"{what}: fewer than 10 samples in the window")
    med = float(np.median(dt))
    gaps = np.nonzero(dt > 1.5 * med)[0]
    if len(gaps):
        g = gaps[np.argmax(dt[gaps])]
        raise IdentificationError(f"{what}: gap of {dt[g]:.3f} s at t={t[g]:.3f} s in the window; "
                                  "choose a window without gaps")
    return med


def batch_means_meat(A3: np.ndarray, resid: np.ndarray, nb: int) -> np.ndarray:
    """(p,p) "meat" of the batch-means sandwich: Σ over blocks of nb samples of (Σ AᵀR)(Σ AᵀR)ᵀ,
    scaled to all samples.  A3: (N,3,p) Jacobian of the prediction; resid: (N,3)."""
    p = A3.shape[2]
    H = np.einsum("nik,ni->nk", A3, resid)
    nblocks = len(H) // nb
    if nblocks < 8:
        nb = max(1, len(H) // 8)
        nblocks = len(H) // nb
    S = H[: nblocks * nb].reshape(nblocks, nb, p).sum(1)
    meat: np.ndarray = S.T @ S * (len(H) / (nblocks * nb))
    return meat


@dataclass(frozen=True)
class Segment:
    """One stretch of data prepared for the fit (band-passed output and regressors)."""

    t: np.ndarray          # (N,) s
    w: np.ndarray          # (N,3) rad/s raw body-axis gyro
    fs: float              # Hz
    band: tuple[float, float]
    filt: Callable[[np.ndarray], np.ndarray]   # the zero-phase band-pass of this segment
    y: np.ndarray          # (N,3) band-passed gyro (the measured output)
    IM: np.ndarray         # (N,3) band-passed integrated moment
    G: np.ndarray          # (6,N,3) band-passed integrated gyroscopic regressors
    label: str = ""


def prepare_segment(t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray,
                     band_hz: tuple[float, float] | None, what: str = "identifier",
                     label: str = "") -> Segment:
    """Band-pass the output and integrate + band-pass the regressors of one segment
    (the first half of :func:`identify_inertia`).  Raises :class:`IdentificationError`."""
    t = np.asarray(t, float)
    dt = sample_interval(t, what)
    fs = 1.0 / dt
    w = np.asarray(omega_body, float)
    torque = np.asarray(torque, float)
    q = int(fs // FIT_RATE)
    if q >= 2 and len(t) > 40 * q:
        # the rig moves below ~5 Hz: a 1 kHz stream is decimated (zero-phase FIR
        # anti-aliasing, scipy ``decimate``) to ≈ FIT_RATE before the fit — same
        # information, a fraction of the work
        w = decimate(w, q, ftype="fir", zero_phase=True, axis=0)
        torque = decimate(torque, q, ftype="fir", zero_phase=True, axis=0)
        t = t[::q][: len(w)]
        fs = fs / q
    duration = t[-1] - t[0]
    if band_hz is None:
        lo, hi = auto_band(w, fs)
        lo = max(lo, 2.0 / duration)  # at least two periods of the high-pass edge in the window
    else:
        lo, hi = band_hz
    hi = min(hi, 0.4 * fs)
    if duration < 2.0 / lo:
        raise IdentificationError(f"{what}: window of {duration:.1f} s is too short for the "
                                  f"{lo:.2f} Hz high-pass (needs ≥ {2.0 / lo:.0f} s)")
    sos = butter(4, [lo, hi], btype="bandpass", fs=fs, output="sos")
    filt: Callable[[np.ndarray], np.ndarray] = lambda x: sosfiltfilt(sos, x, axis=0)  # noqa: E731
    y = filt(w)
    if np.sqrt(np.mean(y**2)) < 1e-5:
        raise IdentificationError(f"{what}: the body hardly rotated in the window "
                                  f"(band-passed gyro RMS {np.sqrt(np.mean(y**2)):.2e} rad/s)")
    E = basis()
    steps = step_indices(torque)   # stepped inputs (the thesis's pulses): no interpolation across them
    integ: Callable[[np.ndarray], np.ndarray] = lambda x: filt(cumulative_integral(x, t, steps))  # noqa: E731
    IM = integ(np.asarray(torque, float))
    # the gyroscopic term is linear in the entries: ω×(Jω) = Σ_m j_m ω×(E_m ω)
    G = np.stack([integ(np.cross(w, w @ Em.T)) for Em in E])  # (6,N,3)
    return Segment(t, w, fs, (lo, hi), filt, y, IM, G, label)


def predicted(j: np.ndarray, s: Segment) -> tuple[np.ndarray, np.ndarray]:
    """P = J⁻¹ (3, 3) of the tensor entries ``j`` (6,) and the band-passed gyro it predicts over segment
    ``s``, (3, N) rad/s: P (∫M − Σ_m j_m ∫ω×(E_m ω)), both integrals band-passed (module docstring)."""
    P = np.linalg.inv(to_tensor(j))
    u = s.IM - np.einsum("m,mni->ni", j, s.G)
    return P, P @ u.T


def output_jacobian(P: np.ndarray, yhat: np.ndarray, s: Segment) -> np.ndarray:
    """(N, 3, 6) d ŷ / d j_k = −P (E_k ŷ + G_k) over segment ``s`` (``P``, ``yhat``: :func:`predicted`)."""
    d: np.ndarray = -np.einsum("ij,knj->nik", P, np.einsum("kij,jn->kni", basis(), yhat) + s.G)
    return d


@dataclass(frozen=True)
class GyroFit:
    """The gyro-only fit: ``inertia`` (6,) kg·m² the tensor entries about the CG (body axes,
    KEYS order), ``covariance`` (6, 6) their sandwich covariance, ``sigma`` (3,) rad/s each gyro
    axis's residual scale the second stage weighted by (pooled over the segments), ``consistent``:
    whether the second stage (Levenberg–Marquardt on a physically consistent parametrisation) ran."""

    inertia: np.ndarray
    covariance: np.ndarray
    sigma: np.ndarray
    consistent: bool

    @property
    def std(self) -> np.ndarray:
        """(6,) σ of the entries, kg·m²."""
        out: np.ndarray = np.sqrt(np.clip(np.diag(self.covariance), 0, None))
        return out


def fit_tensor(segs: list[Segment], block_s: float = 4.0, consistent: bool = True) -> GyroFit:
    """The two-stage fit over one or more prepared segments (:func:`prepare_segment`) with a
    common tensor (module docstring): (1) linear least squares in P = J⁻¹, the gyroscopic term
    with the previous iterate, three passes from J = 0, P's eigenvalues held within
    :data:`STAGE1_CONDITION` of the largest; (2) where ``consistent``, Levenberg–Marquardt (scipy
    ``least_squares``, analytic Jacobian) on the physically consistent parametrisation
    (:func:`~rig_identification.model.parametrisation.consistent_from_params`).  The covariance:
    the sandwich, its meat summed over ``block_s`` s blocks of each segment, its bread the
    pseudo-inverse (a direction the noise swamped has no information: singular there)."""
    E = basis()
    Y = np.concatenate([s.y.reshape(-1) for s in segs])
    j = np.zeros(6)
    for _ in range(3):
        X = np.concatenate([np.einsum("kij,nj->nik", E, s.IM - np.einsum("m,mni->ni", j, s.G)).reshape(-1, 6)
                            for s in segs])  # (ΣN·3, 6)
        p, *_ = np.linalg.lstsq(X, Y, rcond=None)
        # unmodelled physics (strong damping, say) can make the linear estimate of P
        # indefinite or nearly singular, and J = P⁻¹ absurd, from which Levenberg–Marquardt
        # diverges: P's eigenvalues are held within STAGE1_CONDITION of the largest
        ev, V = np.linalg.eigh(to_tensor(p))
        ev = ev if ev.max() > 0 else np.abs(ev)
        ev = np.clip(ev, ev.max() / STAGE1_CONDITION, None)
        j = from_tensor(V @ np.diag(1.0 / ev) @ V.T)
    # per-axis residual scale, pooled over the segments (the same gyro)
    sigma = np.sqrt(np.mean(np.concatenate([(s.y - predicted(j, s)[1].T) ** 2 for s in segs]), axis=0))
    if consistent:
        def fun(th: np.ndarray) -> np.ndarray:
            jj, _ = consistent_from_params(th)
            return np.concatenate([((s.y - predicted(jj, s)[1].T) / sigma).ravel() for s in segs])

        def jac(th: np.ndarray) -> np.ndarray:
            jj, dj = consistent_from_params(th)
            out = []
            for s in segs:
                Pm, yh = predicted(jj, s)
                out.append(-(output_jacobian(Pm, yh, s) / sigma[None, :, None]).reshape(-1, 6) @ dj)
            return np.concatenate(out)

        sol = least_squares(fun, params_from_consistent(to_tensor(j)), jac=jac, method="lm",
                            xtol=1e-12, ftol=1e-12)
        j, _ = consistent_from_params(sol.x)
    A3s, resids = [], []
    for s in segs:
        P, yhat = predicted(j, s)
        A3s.append(output_jacobian(P, yhat, s))
        resids.append(s.y - yhat.T)
    # A.T @ A of one buffer: BLAS syrk.  Pseudo-inverse: a fit that ran off to J → ∞ along a
    # direction (the noise swamped it: a replay of a weakly excited rig, bench_any_rig's seed
    # 21014) has no information there; its covariance is then singular along it
    B = np.linalg.pinv(sum(A3.reshape(-1, 6).T @ A3.reshape(-1, 6) for A3 in A3s), rcond=1e-13, hermitian=True)
    meat = sum(batch_means_meat(A3, r, max(1, int(round(block_s * s.fs)))) for A3, r, s in zip(A3s, resids, segs))
    return GyroFit(j, B @ meat @ B, sigma, consistent)


def fit_gyro(t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray, band_hz: tuple[float, float] | None = None,
             block_s: float = 4.0) -> GyroFit:
    """The gyro-only fit of one stretch (:func:`prepare_segment`, :func:`fit_tensor`).  t: (N,) s,
    uniformly sampled (a gap raises); omega_body: (N, 3) rad/s, body axes; torque: (N, 3) N·m about
    the CG, body axes; band_hz: the prefilter's pass band (default:
    :func:`auto_band` of the gyro).  Raises
    :class:`IdentificationError` for too little data, gaps or no motion."""
    return fit_tensor([prepare_segment(t, omega_body, torque, band_hz)], block_s)


__all__ = ["IdentificationError", "STEP_SCALE", "step_indices", "cumulative_integral", "auto_band",
           "FIT_RATE", "STAGE1_CONDITION", "Segment", "GyroFit", "sample_interval",
           "batch_means_meat", "prepare_segment", "predicted", "output_jacobian", "fit_tensor", "fit_gyro"]
