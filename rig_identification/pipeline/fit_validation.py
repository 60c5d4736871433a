"""A fit validated the one way the offline path and the identifier node share: the load cells'
weight surplus (:func:`force_weight_surplus`), the verdict applied to the result
(:func:`apply_validation`: σ widened, warnings).
"""
from __future__ import annotations

import logging
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..estimation.inertia_result import InertiaResult
from ..estimation.validation import beyond_limit_widened, validate, widened_std
from ..model.parametrisation import from_tensor
from .prepare import PreparedRecording

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them


WEIGHT_TOLERANCE = 1e-3
"""Relative difference between the load cells' mean vertical force and rig.yaml's weight
beyond which the fit's input is not the body rig.yaml describes (a cable's mass hanging
outside its load cell, a load cell's gain, a wrong body.mass): about a vehicle scale's
accuracy.  Clean simulated recordings and the clean references: below 1e-4."""


def force_weight_surplus(rig, quaternion: np.ndarray, force: np.ndarray) -> float:
    """The mean vertical force of the generalized force ``force`` (N,3) N, body axes (the
    load cells' and the exciter's, weight excluded:
    :func:`~rig_identification.estimation.preprocessor.generalized_wrench`),
    turned to world axes by the tracked orientation ``quaternion`` (N,4) x, y, z, w (body to
    world, at the same stamps), relative to rig.yaml's weight: mean(F_z) / (m g) − 1 (over a
    window of bounded motion the mean vertical acceleration vanishes, so the mean force is the
    weight; Newton's second law).  Dimensionless; positive when the cells carry more.  The
    formula of :func:`weight_surplus` and of the identifier node's validation."""
    fz = Rotation.from_quat(quaternion).apply(force)[:, 2]
    return float(np.mean(fz) / (rig.mass * rig.gravity) - 1.0)


def weight_surplus(prep: PreparedRecording) -> float:
    """The load cells' (and the exciter's) mean vertical force over the fit window, world
    axes, relative to rig.yaml's weight (:func:`force_weight_surplus` of ``prep.force`` at
    the tracked pose).  Dimensionless; positive when the cells carry more."""
    P = prep.poses
    q = P.quaternion[np.searchsorted(P.t, prep.t)]     # prep.t are pose stamps
    return force_weight_surplus(prep.rec.rig, q, prep.force)

def weight_warning(surplus: float | None, rig) -> str | None:
    """The warning of a weight surplus (:func:`force_weight_surplus`, dimensionless) beyond
    :data:`WEIGHT_TOLERANCE`, naming it in % and kg of rig.yaml's ``body.mass``; None within
    it (or for None)."""
    if surplus is None or abs(surplus) <= WEIGHT_TOLERANCE:
        return None
    # the rotational residual cannot see this: the heavier body is still a rigid body
    return (f"the load cells carry {100 * surplus:+.2f} % of rig.yaml's weight ({surplus * rig.mass:+.1f} kg) beyond "
            "it: the tensions do not move the body rig.yaml describes (each cable's lower half hanging outside its "
            "load cell, a load cell's gain, or a wrong body.mass); rig-identify diagnose looks for the cause")


def validate_fit(preps: list[PreparedRecording], result: InertiaResult) -> InertiaResult:
    """Model validation of the fit (:func:`~rig_identification.estimation.validation.validate`): ``result.validation``.
    When a consistency check fails (verdict ``model_error``, or ``not_identifiable`` with
    a failed check) the σ (``inertia_std``, the covariance's diagonal) is
    widened to the spread the checks saw (:func:`~rig_identification.estimation.validation.widened_std`) and a warning
    says the tensor is not trustworthy; under ``not_identifiable`` a warning names the
    entries reported as null and what to change.  Returns the validated result (a new record)."""
    log.info("validating the fit")
    surplus = [weight_surplus(p) for p in preps]
    return apply_validation(result, max(surplus, key=abs), preps[0].rec.rig)


def apply_validation(result: InertiaResult, surplus: float | None, rig) -> InertiaResult:
    """The model validation of a fit from its inputs, as :func:`validate_fit` makes it (the
    one core the offline path and the identifier node run): :func:`~rig_identification.estimation.validation.validate`
    with the load cells' weight surplus ``surplus`` (:func:`force_weight_surplus`; None: skipped) and the ``rig`` (for
    the advice); ``result.validation`` set, σ and covariance widened
    (:func:`~rig_identification.estimation.validation.widened_std`; under ``not_identifiable`` the entries
    that widening leaves beyond the identifiability limit are null too:
    :func:`~rig_identification.estimation.validation.beyond_limit_widened`), the verdict's summary a
    warning unless ``ok``.
    Returns the validated result (a new record)."""
    v = validate(result, surplus, rig)
    w = widened_std(result.inertia_std, v)
    if np.any(w > result.inertia_std):
        covariance = result.covariance * v.sigma_factor**2 + np.diag(
            np.maximum(w**2 - (v.sigma_factor * result.inertia_std) ** 2, 0.0))
        uncertainty = result.uncertainty
        if v.sigma_factor > 1.0 or v.failed:
            uncertainty += (f"; widened {v.sigma_factor:.2f}× for what the consistency checks saw beyond the "
                            "noise" if not v.failed else
                            f"; widened to the validation's spread ({', '.join(v.failed)} failed: a lower bound "
                            "of the error)")
        result = replace(result, covariance=covariance, inertia_std=w, uncertainty=uncertainty)
        # under not_identifiable, an entry the widening leaves beyond the limit is not given either
        v = beyond_limit_widened(from_tensor(result.inertia), w, v, rig)
    warned = [v.summary] if v.verdict in ("model_error", "not_identifiable") else []
    return replace(result, validation=v, warnings=result.warnings + warned)
