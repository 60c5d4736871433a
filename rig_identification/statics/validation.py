"""Model validation of a CG fit of the static experiment: a verdict and named checks.

Under the fitted model the normalised residuals r of the static fit have the covariance
I − U Uᵀ (U: left singular vectors of the weighted Jacobian, the linearised least-squares
result); the inclinometer's tilt change between the states and its mean level are tested
against it (Wald statistics), with the fit's χ² and the scale-vs-load-cell mass
(:class:`CgValidation`, :func:`validate_fit`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as _chi2
from scipy.stats import norm as _norm

from ..io.verdict import Check

CHI2_P_WARN = 0.01               # global fit: p-value below which σ are inflated (Birge ratio)
# Model validation of the CG fit (CgValidation): a check fails beyond the two-sided 3 σ of a
# normal variable (p = 0.0027 per check; for a 2-dof Wald statistic the same p-value).
VALIDATION_SIGMA = 3.0
CG_VERDICTS = ("ok", "model_error")
# the checks that bear on the CG (a failure makes the verdict model_error); "mass" is a cross-check
CG_MODEL_CHECKS = ("fit_chi2", "tilt_change", "inclinometer_level")


@dataclass(frozen=True)
class CgValidation:
    """Model validation of a CG fit: ``verdict`` (one of :data:`CG_VERDICTS`: ``model_error``
    when a check of :data:`CG_MODEL_CHECKS` failed) and the :class:`~rig_identification.io.verdict.Check` list:

    * ``fit_chi2``: χ²/dof of the whole fit (threshold: its 99th percentile);
    * ``tilt_change``: the inclinometer's change of elevation between the baseline and each
      dummy state against the rigid-body equilibrium's with the fitted CG (a Wald statistic
      over the residual's own covariance, said as the equivalent two-sided normal σ; threshold
      :data:`VALIDATION_SIGMA`): a body that tilts more (or less) than the frame under the
      dummy's moment allows -- a vehicle on an unlocked suspension, an inclinometer on the
      sprung body, a load that shifted, an inclinometer that moved between the recordings;
    * ``inclinometer_level``: the same for the mean of the states' elevations: an inclinometer
      zero offset or mounting error (``inclinometer.rpy``), or rig geometry off beyond its σ;
    * ``mass``: the load cells' weight against the scale's, in combined σ (threshold 3).

    A check whose residual the fit absorbs entirely (no redundancy) is not applicable
    (statistic None)."""

    verdict: str
    checks: tuple[Check, ...]

    @property
    def failed(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.checks if c.passed is False)

    @property
    def summary(self) -> str:
        """The verdict in words (first line of the text output)."""
        if self.verdict == "ok":
            return ("validation: ok — the static states agree with a rigid body on these cables (checks "
                    + ", ".join(c.name for c in self.checks if c.passed) + " passed)")
        bad = [c.name for c in self.checks if c.passed is False and c.name in CG_MODEL_CHECKS]
        return ("validation: MODEL ERROR — the static states disagree with a rigid body on these cables ("
                + ", ".join(bad) + " failed): the CG below is not trustworthy")

    def to_dict(self) -> dict:
        return {"verdict": self.verdict, "failed": list(self.failed), "checks": [c.to_dict() for c in self.checks]}


def _wald_sigma(d: np.ndarray, V: np.ndarray, V_raw: np.ndarray) -> tuple[float | None, int]:
    """Wald statistic dᵀV⁺d of residual combinations d (k,) with covariance V (k, k), said
    as the two-sided normal σ of the same p-value (χ² with the rank as dof), and that rank.
    The pseudo-inverse keeps the eigen-directions whose variance exceeds 1e-4 of the largest
    variance the same combinations of the raw measurements have (V_raw): a residual the fit
    absorbs to within 1 % of its σ is not tested.  (None, 0) when none is left."""
    ev, Q = np.linalg.eigh(0.5 * (V + V.T))
    keep = ev > 1e-4 * max(float(np.linalg.eigvalsh(V_raw).max()), 1e-300)
    k = int(keep.sum())
    if k == 0:
        return None, 0
    z = Q[:, keep].T @ d
    w = float(np.sum(z**2 / ev[keep]))
    p = float(_chi2.sf(w, k))
    return float(_norm.isf(max(p, 1e-300) / 2.0)), k


def validate_fit(r: np.ndarray, U: np.ndarray, incl_rows: list, labels: list[str], chi2: float, dof: int,
                 mass_check: Check | None, offset_fitted: bool) -> CgValidation:
    """The :class:`CgValidation` of a fit: normalised residuals r (n,), U (n, p) the left
    singular vectors of the fit's Jacobian (so that the residuals' covariance under the model
    is I − U Uᵀ, the linearised least-squares result), incl_rows: per state (row of elevation x,
    row of elevation y, their σ (2,) rad) or empty without an inclinometer.

    labels: the states' labels (baseline first); chi2, dof: the fit's χ² and degrees of
    freedom; mass_check: the load cells' weight against the scale's (a
    :class:`~rig_identification.io.verdict.Check`, or None without load cells), appended as is;
    offset_fitted: the inclinometer's offsets were fitted (then ``inclinometer_level`` is not
    testable).  Checks and thresholds: :class:`CgValidation`."""
    checks = []
    if dof > 0:
        thr = float(_chi2.ppf(1 - CHI2_P_WARN, dof))
        checks.append(Check("fit_chi2", chi2 / dof, thr / dof, bool(chi2 <= thr),
                            f"χ²/dof {chi2 / dof:.2f} ({dof} dof), p = {_chi2.sf(chi2, dof):.2g}; threshold "
                            f"{thr / dof:.2f} (p = {CHI2_P_WARN:g})"))
    else:
        checks.append(Check("fit_chi2", None, None, None, "no degrees of freedom: nothing to test"))
    n = len(r)
    cov_r = np.eye(n) - U @ U.T

    def combo(weights: list[tuple[int, float]]) -> np.ndarray:
        a = np.zeros(n)
        for row, wgt in weights:
            a[row] += wgt
        return a

    if incl_rows:
        base = incl_rows[0]
        A_t, A_l = [], []
        for st in incl_rows[1:]:
            for ax in range(2):
                A_t.append(combo([(st[ax], st[2][ax]), (base[ax], -base[2][ax])]))
        S = len(incl_rows)
        for ax in range(2):
            A_l.append(combo([(st[ax], st[2][ax] / S) for st in incl_rows]))
        for name, A, what in (
                ("tilt_change", np.array(A_t),
                 "the inclinometer's change of elevation x, y from the baseline to the " + ", ".join(labels[1:])),
                ("inclinometer_level", np.array(A_l), "the inclinometer's mean elevation x, y over the states")):
            d = A @ r
            z, k = _wald_sigma(d, A @ cov_r @ A.T, A @ A.T)
            V = A @ cov_r @ A.T
            if name == "inclinometer_level" and offset_fitted:
                z = None
            if z is None:
                checks.append(Check(name, None, None, None, f"{what}: not testable (the fit absorbs it: no redundancy"
                                    + (", inclinometer offsets fitted"
                                       if offset_fitted and name != "tilt_change" else "")
                                    + ")"))
                continue
            text = ", ".join(f"{x * 1e6:+.1f}" for x in d) + " µrad"
            sd = ", ".join(f"{math.sqrt(max(x, 0.0)) * 1e6:.1f}" for x in np.diag(V))
            ok = z <= VALIDATION_SIGMA
            why = ""
            if not ok and name == "tilt_change":
                why = ("; the body tilts more (or less) under the dummy mass than a rigid body with the fitted CG on "
                       "these cables: a compliant body (a vehicle on an unlocked suspension, its sprung mass shifting "
                       "as the frame tilts; or an inclinometer on the sprung body), a load that shifted or an "
                       "inclinometer that moved between the recordings -- lock the suspension (or fix the load) and "
                       "record both states again")
            if not ok and name == "inclinometer_level":
                why = ("; the inclinometer's zero or mounting (rig.yaml inclinometer.rpy) disagrees with the pose the "
                       "cables and load cells give, or the geometry is off beyond its σ: check inclinometer.rpy, "
                       "or fit its offsets (--fit-inclinometer-offset)")
            checks.append(Check(name, z, VALIDATION_SIGMA, bool(ok),
                                f"{what} differs from the rigid-body equilibrium's by {text} (σ of the difference "
                                f"{sd} µrad): {z:.1f} σ ({k} dof), threshold {VALIDATION_SIGMA:g} σ{why}"))
    else:
        for name in ("tilt_change", "inclinometer_level"):
            checks.append(Check(name, None, None, None, "no inclinometer in the fit"))
    if mass_check is not None:
        checks.append(mass_check)
    bad = any(c.passed is False and c.name in CG_MODEL_CHECKS for c in checks)
    return CgValidation("model_error" if bad else "ok", tuple(checks))
