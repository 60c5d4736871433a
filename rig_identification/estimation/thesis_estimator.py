"""The thesis's identification, as a baseline (thesis sections 3.3 and 3.5): :func:`identify_inertia_thesis`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..model.parametrisation import physically_consistent, to_tensor
from .gyro_fit import sample_interval


@dataclass(frozen=True)
class ThesisFit:
    """The thesis's estimate: ``inertia`` (3, 3) kg·m² about the CG, body axes; ``std`` (6,) kg·m² its
    entries' σ (:data:`~rig_identification.io.verdict.KEYS` order) under the white-residual assumption;
    ``warnings`` what went wrong (not converged, not physically consistent)."""

    inertia: np.ndarray
    std: np.ndarray
    warnings: tuple[str, ...]


def identify_inertia_thesis(t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray,
                            initial_guess: np.ndarray) -> ThesisFit:
    """The thesis's identification, as a baseline (thesis sections 3.3 and 3.5).

    Model: eq. 3.10/3.11 — ``J θ̈ = M`` with the angular velocities as states, *without*
    the gyroscopic term ω × Jω; forward-Euler discretisation (eqs. 3.17–3.21,
    A_d = 1 + T·A, B_d = T·B); one-step-ahead predictor of the measured output
    (eq. 3.25 with C = I): ``ω̂(n+1) = ω(n) + T J⁻¹ M(n)``; prediction errors minimised
    by Levenberg–Marquardt (eq. 3.30) from ``initial_guess`` (6,) tensor entries in
    :data:`~rig_identification.io.verdict.KEYS` order, as MATLAB's ``pem`` did.  Covariance: σ² (AᵀA)⁻¹ of the
    white-residual assumption.  t: (N,) s uniform; omega_body (N,3) rad/s; torque (N,3) N·m, both
    body axes, the torque about the CG.  Raises :class:`~rig_identification.estimation.gyro_fit.IdentificationError`
    for a non-uniform ``t``.
    """
    t = np.asarray(t, float)
    T = sample_interval(t, "identifier (thesis model)")
    w = np.asarray(omega_body, float)
    M = np.asarray(torque, float)
    dw = w[1:] - w[:-1]

    def fun(j: np.ndarray) -> np.ndarray:
        r: np.ndarray = (dw - T * M[:-1] @ np.linalg.inv(to_tensor(j)).T).ravel()
        return r

    sol = least_squares(fun, np.asarray(initial_guess, float), method="lm", xtol=1e-12, ftol=1e-12)
    J = to_tensor(sol.x)
    A = sol.jac
    resid = sol.fun.reshape(-1, 3)
    dof = max(1, A.shape[0] - 6)
    cov = float(resid.ravel() @ resid.ravel()) / dof * np.linalg.pinv(A.T @ A)
    warnings = [] if physically_consistent(J) else ["the identified tensor is not physically consistent"]
    if not sol.success:
        warnings.append(f"Levenberg–Marquardt did not converge: {sol.message}")
    return ThesisFit(J, np.sqrt(np.clip(np.diag(cov), 0, None)), tuple(warnings))
