"""Offline replay: recording -> tracker -> preprocessor -> identifier (the nodes' core code)."""
from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np

from ..estimation.harmonic_start import box_tensor
from ..estimation.identification import identify_inertia
from ..estimation.inertia_result import InertiaResult
from ..estimation.thesis_estimator import identify_inertia_thesis
from ..io.recording import Recording
from ..model.parametrisation import from_tensor
from .fit_validation import validate_fit, weight_surplus, weight_warning
from .prepare import PreparedRecording, prepare_recording

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them


def identify_recording(rec: Recording, start: float | None = None, end: float | None = None,
                       settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                       model: str = "pem", initial_guess=None) -> InertiaResult:
    """Identify the inertia tensor of a dynamic recording.

    start/end/settle: the window, see :func:`~rig_identification.pipeline.prepare.prepare_recording`.
    model: ``"pem"`` (the prediction-error fit on the gyro, the tensions its input through tracker
    and preprocessor, :func:`~rig_identification.estimation.identification.identify_inertia`; σ its
    own sandwich, from the residuals) or ``"thesis"`` (the thesis's model and estimator,
    :func:`~rig_identification.estimation.thesis_estimator.identify_inertia_thesis`, from
    ``initial_guess`` (6,) tensor entries or the body anchors' box,
    :func:`~rig_identification.estimation.harmonic_start.box_tensor`).  Every fit is validated
    (:func:`~rig_identification.pipeline.fit_validation.validate_fit`: ``result.validation``).  Raises
    :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError`,
    :class:`~rig_identification.estimation.identification.IdentificationError`.
    """
    prep = prepare_recording(rec, start, end, settle)
    rig = rec.rig
    if model == "thesis":
        guess = box_tensor(rig) if initial_guess is None else np.asarray(initial_guess, float)
        result = identify_inertia_thesis(rig, prep.t, prep.gyro_body, prep.torque, guess)
    elif model == "pem":
        log.info("fitting the inertia tensor (prediction error, %.0f s of data)", prep.t[-1] - prep.t[0])
        try:
            result = identify_inertia(rig, prep.t, prep.gyro_body, prep.torque, band_hz=band_hz)
        except np.linalg.LinAlgError as e:
            result = unidentified(rig, prep, f"the fit's normal equations are singular ({e})")
    else:
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    result = replace(result, warnings=rec.warnings + prep.warnings + result.warnings,
                     weight_surplus=weight_surplus(prep))
    result = validate_fit([prep], result)
    note = weight_warning(result.weight_surplus, rig)
    return result if note is None else replace(result, warnings=result.warnings + [note])


def unidentified(rig, prep: PreparedRecording, reason: str) -> InertiaResult:
    """The result of a fit that could not be made: every entry NaN (reported as null, verdict
    ``not_identifiable``), ``reason`` as a warning."""
    nan = np.full(6, np.nan)
    res = InertiaResult(rig.mass, rig.require_cg().copy(), np.full((3, 3), np.nan), nan, np.full((6, 6), np.nan),
                        float(prep.t[0]), float(prep.t[-1]), len(prep.t), (np.nan, np.nan), np.full(3, np.nan),
                        np.full(3, np.nan), warnings=[reason])
    return res


def with_cg_uncertainty(rec: Recording, result: InertiaResult, cg_covariance: np.ndarray,
                        start: float | None = None, end: float | None = None, settle: float = 5.0) -> InertiaResult:
    """``result`` with the uncertainty of the CG it was fitted about carried into the tensor's σ.

    The CG sets the moment arms of every measured force, so an error of the CG moves the fitted
    tensor.  Linear error propagation by central differences along the principal axes of the
    CG's covariance ``cg_covariance`` (3, 3) m², body frame (a ``rig-identify cg`` result's):
    for each eigenpair (λ_k, v_k), s_k = √λ_k v_k, the recording is prepared again with the CG at
    c ± s_k (tracker, generalized wrench) and the tensor refitted in the result's band
    (:func:`~rig_identification.estimation.identification.identify_inertia`); d_k = (J(c + s_k) −
    J(c − s_k)) / 2 (6,) tensor entries, and the covariance of the entries grows by Σ_k d_k d_kᵀ
    (JCGM 100:2008, GUM §5.1, with the sensitivities by finite differences).  ``uncertainty``
    says so, ``cg_contribution_std`` (6,) kg·m² holds √diag Σ d_k d_kᵀ.  A result without a finite
    tensor, or a rig without a CG, is returned as it is.  Raises like :func:`identify_recording`."""
    if not np.all(np.isfinite(result.inertia)) or rec.rig.center_of_gravity is None:
        return result
    lam, vec = np.linalg.eigh(0.5 * (np.asarray(cg_covariance, float) + np.asarray(cg_covariance, float).T))
    c0 = rec.rig.require_cg()
    added = np.zeros((6, 6))
    for lk, vk in zip(lam, vec.T):
        if lk <= 0:
            continue
        fits = []
        for sign in (1.0, -1.0):
            moved = replace(rec, rig=rec.rig.with_cg(c0 + sign * np.sqrt(lk) * vk))
            prep = prepare_recording(moved, start, end, settle)
            fits.append(from_tensor(identify_inertia(moved.rig, prep.t, prep.gyro_body, prep.torque,
                                                     band_hz=tuple(result.band_hz)).inertia))
        d = 0.5 * (fits[0] - fits[1])
        added += np.outer(d, d)
    covariance = result.covariance + added
    return replace(result, covariance=covariance, inertia_std=np.sqrt(np.clip(np.diag(covariance), 0, None)),
                   cg_contribution_std=np.sqrt(np.clip(np.diag(added), 0, None)),
                   uncertainty=result.uncertainty + "; with the CG's σ propagated (the tensor refitted with the CG "
                   "±1 σ along each principal axis of its covariance)")
