"""``rig-identify inertia --model pem``'s result: the gyro-only prediction-error fit
(:mod:`~rig_identification.estimation.gyro_fit`: the estimator, its model and its sandwich
covariance) as an :class:`~rig_identification.estimation.inertia_result.InertiaResult` — with the
fit's series, the white-gyro Cramér–Rao bound of this estimator and the most weakly determined
combinations (:mod:`rig_identification.estimation.directions`).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..io.noise import white_sigma
from ..io.rig import Rig
from ..model.parametrisation import physically_consistent, to_tensor
from .directions import weak_directions
from .gyro_fit import Segment, fit_tensor, output_jacobian, predicted, prepare_segment
from .inertia_result import FitSeries, InertiaResult


def fit_segments(rig: Rig, segs: list[Segment], block_s: float = 4.0, consistent: bool = True) -> InertiaResult:
    """The two-stage fit (:func:`~rig_identification.estimation.gyro_fit.fit_tensor`) over prepared
    segments as an :class:`~rig_identification.estimation.inertia_result.InertiaResult`: its
    series (measured and predicted band-passed ω), residual RMS and R² per axis, and the
    predicted covariance from the gyro's white noise alone (the Cramér–Rao bound of this estimator
    for the recording's excitation): σ² B (FA)ᵀ(FA) B, F the prefilter, B the sandwich's bread."""
    fit = fit_tensor(segs, block_s, consistent)
    j = fit.inertia
    J = to_tensor(j)
    method = "prediction error: band-limited output error of the integrated Newton–Euler equation"
    if consistent:
        method += "; Levenberg–Marquardt on a physically consistent parametrisation"
    yhats, resids, A3s = [], [], []
    for s in segs:
        P, yhat = predicted(j, s)
        yhats.append(yhat.T)
        resids.append(s.y - yhat.T)
        A3s.append(output_jacobian(P, yhat, s))
    B = np.linalg.pinv(sum(A3.reshape(-1, 6).T @ A3.reshape(-1, 6) for A3 in A3s), rcond=1e-13, hermitian=True)
    sgs, crb = [], 0
    for A3, s in zip(A3s, segs):
        FA = s.filt(A3.reshape(len(s.t), -1)).reshape(-1, 6)
        sg = white_sigma(s.w)
        sgs.append(sg)
        crb = crb + sg**2 * B @ (FA.T @ FA) @ B
    resid = np.concatenate(resids)
    y_all = np.concatenate([s.y for s in segs])
    res_rms = np.sqrt(np.mean(resid**2, axis=0))
    r2 = 1 - np.sum(resid**2, 0) / np.sum(y_all**2, 0)
    warnings: list[str] = []
    if not physically_consistent(J):
        warnings.append("the identified tensor is not physically consistent (not positive definite "
                        "or violates the triangle inequality): the window does not excite the body enough")
    t0 = min(float(s.t[0]) for s in segs)
    t1 = max(float(s.t[-1]) for s in segs)
    band = (min(s.band[0] for s in segs), max(s.band[1] for s in segs))
    res = InertiaResult(rig.mass, rig.require_cg().copy(), J, fit.std, fit.covariance, t0, t1,
                        int(sum(len(s.t) for s in segs)), band, res_rms, r2, weak_directions(J, fit.covariance),
                        method=method, warnings=warnings)
    return replace(res, crb_std=np.sqrt(np.clip(np.diag(crb), 0, None)),
                   gyro_noise=sgs[0] if len(sgs) == 1 else float(np.sqrt(np.mean(np.square(sgs)))),
                   series=[FitSeries(s.t, s.y, yh, s.band, s.label, A3, fit.sigma.copy(), s.fs)
                           for s, yh, A3 in zip(segs, yhats, A3s)])


def identify_inertia(rig: Rig, t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray,
                     band_hz: tuple[float, float] | None = None, block_s: float = 4.0,
                     consistent: bool = True) -> InertiaResult:
    """Fit the inertia tensor about the CG (see module docstring).

    Two stages, no initial guess: (1) linear least squares in P = J⁻¹ (the gyroscopic
    term evaluated with the previous iterate, three passes from J = 0); (2) from there,
    Levenberg–Marquardt (scipy ``least_squares``, analytic Jacobian) on the physically
    consistent parametrisation
    :func:`~rig_identification.model.parametrisation.consistent_from_params`, with the gyroscopic
    term of the current J — the prediction-error estimate proper.

    t: (N,) s, uniformly sampled (a gap raises).  omega_body: (N,3) rad/s, body axes
    (gyro rotated from IMU axes).  torque: (N,3) N·m about the CG, body axes.
    band_hz: pass band of the zero-phase Butterworth prefilter applied to both sides
    (default: :func:`~rig_identification.estimation.signals.auto_band` of the gyro).  consistent:
    run stage 2.  Streams sampled at
    ≥ 2 × :data:`FIT_RATE` are first decimated to about that rate (zero-phase FIR).
    The result's ``series`` holds the band-passed measured and predicted ω.
    Raises :class:`IdentificationError` for too little data, gaps or no motion.
    """
    seg = prepare_segment(t, omega_body, torque, band_hz)
    return fit_segments(rig, [seg], block_s, consistent)
