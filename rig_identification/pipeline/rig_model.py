"""A recording read whole: the rig's grey-box model fitted to every sensor (``rig-identify inertia --model rig``).

recording → :func:`~rig_identification.estimation.rig_fit.record` (every stream on one grid, the
exciter's force denoised) → a start for the tensor (the prediction-error fit of
:func:`~rig_identification.pipeline.offline.identify_recording`, unrefined, where it gives a
physical tensor; else the body anchors' box) → :func:`~rig_identification.estimation.rig_fit.fit_rig`
(the exact model, every sensor an output, mass, CG, cables, load cells and geometry fitted with
their priors) → :class:`RigModelResult`.

The CG's prior: a saved static result (``--cg CG.json``, its σ) or none (rig.yaml's CG is the
start, the dynamic test alone determines it); the result gives the static and the dynamic CG
side by side and their difference in σ.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass

import numpy as np

from ..estimation.identification import IdentificationError
from ..estimation.rig_fit import Prior, RigFit, fit_rig, record
from ..estimation.validation import REL_STD_LIMIT
from ..io.recording import Recording
from ..io.verdict import KEYS
from ..model.parametrisation import entry_scales, from_tensor, physically_consistent
from .offline import default_initial_guess, identify_recording

log = logging.getLogger(__name__)

#: A channel whose residual in the band exceeds its noise by this factor is said not to fit;
#: beyond :data:`FAILED_LEVEL` the fit has not found the motion at all (verdict ``failed``).
LEVEL_LIMIT = 1.5
FAILED_LEVEL = 10.0


@dataclass(frozen=True)
class RigModelResult:
    """The rig model fitted to one recording.

    fit: :class:`~rig_identification.estimation.rig_fit.RigFit`.  path: the recording.  t0: the
    record's first stamp, s; start_s, duration_s: the compared span from t0, s; band_hz: the
    fit's band edge.  inertia_start: (6,) the tensor the fit started from, and where it came from
    (``start_source``).  cg_prior: (3,) m and cg_prior_std (3,) m (inf: none) of the CG's prior,
    cg_source: where it came from.  seconds: wall time.  truth: truth.yaml or None.
    """

    fit: RigFit
    path: str
    t0: float
    start_s: float
    duration_s: float
    band_hz: float
    inertia_start: np.ndarray
    start_source: str
    cg_prior: np.ndarray
    cg_prior_std: np.ndarray
    cg_source: str
    seconds: float
    truth: dict | None

    @property
    def verdict(self) -> str:
        """``ok`` (every channel within :data:`LEVEL_LIMIT` of its noise), ``model_error`` (some
        beyond: the model misses physics or a sensor's trait, σ not calibrated) or ``failed``
        (a channel beyond :data:`FAILED_LEVEL`, or a number not finite: the fit did not find the
        motion; the numbers are not an estimate)."""
        f = self.fit
        finite = np.all(np.isfinite(f.inertia)) and np.all(np.isfinite(f.inertia_std))
        if not finite or np.max(f.residual_level) > FAILED_LEVEL:
            return "failed"
        return "model_error" if self.poorly_fitted else "ok"

    @property
    def undetermined(self) -> list[str]:
        """The entries whose σ exceeds :data:`~rig_identification.estimation.validation.REL_STD_LIMIT`
        of their scale (a moment's own, the largest moment's for a product)."""
        scale = entry_scales(self.fit.inertia)
        return [k for k, s, c in zip(KEYS, self.fit.inertia_std, scale) if not s <= REL_STD_LIMIT * c]

    @property
    def poorly_fitted(self) -> list[str]:
        """The channels whose residual in the band exceeds :data:`LEVEL_LIMIT` times their noise."""
        return [c for c, v in zip(self.fit.channels, self.fit.residual_level) if v > LEVEL_LIMIT]

    def cg_difference_sigma(self) -> np.ndarray:
        """(3,) the dynamic CG's difference from the static one over their combined σ (the
        dynamic's σ comes from the fit that used the static prior: a lower bound of the
        disagreement's significance); nan without a static CG."""
        d = self.fit.parameters.cg - self.cg_prior
        s = np.sqrt(self.fit.cg_std ** 2 + np.where(np.isfinite(self.cg_prior_std), self.cg_prior_std, np.nan) ** 2)
        return d / s

    def to_dict(self) -> dict:
        """The JSON object of ``rig-identify inertia --model rig --json`` (SI units)."""
        f = self.fit
        p = f.parameters
        sd = f.inertia_std
        d = {
            "schema": "rig_identification.rig_model_result", "schema_version": 1,
            "recording": self.path, "model": "rig (grey-box, every sensor an output)",
            "verdict": self.verdict, "undetermined": self.undetermined,
            "window": {"start_s": self.start_s, "duration_s": self.duration_s, "band_hz": [0.0, self.band_hz]},
            "inertia_about_cg": {k: float(v) for k, v in zip(KEYS, p.inertia)},
            "inertia_std": {k: float(v) for k, v in zip(KEYS, sd)},
            "inertia_crb": {k: float(v) for k, v in zip(KEYS, f.crb)},
            "sigma_over_crb": {k: float(a / b) for k, a, b in zip(KEYS, sd, f.crb)},
            "inertia_units": "kg m^2 (tensor entries about the CG, body axes; ixy = -product of inertia)",
            "inertia_start": {"entries": {k: float(v) for k, v in zip(KEYS, self.inertia_start)},
                              "source": self.start_source},
            "mass": float(p.mass), "mass_std": float(np.sqrt(f.covariance[f.layout.mass, f.layout.mass])),
            "center_of_gravity": {"dynamic": p.cg.tolist(), "dynamic_std": f.cg_std.tolist(),
                                  "prior": self.cg_prior.tolist(),
                                  "prior_std": [float(x) if np.isfinite(x) else None for x in self.cg_prior_std],
                                  "prior_source": self.cg_source, "units": "m, body frame"},
            "cables": {"stiffness": p.stiffness.tolist(), "damping_time": float(p.damping_time),
                       "load_cell_gain": p.gain.tolist()},
            "residual_level": {c: float(v) for c, v in zip(f.channels, f.residual_level)},
            "poorly_fitted_channels": self.poorly_fitted,
            "natural_frequencies_hz": f.natural_frequencies.tolist(),
            "seconds": self.seconds,
        }
        if self.truth and "inertia_about_cg" in self.truth:
            t = np.array([float(self.truth["inertia_about_cg"][k]) for k in KEYS])
            err = p.inertia - t
            d["truth_comparison"] = {k: {"truth": float(a), "error_percent": float(100 * e / s),
                                         "error_sigma": float(e / sg)}
                                     for k, a, e, s, sg in zip(KEYS, t, err, entry_scales(t), sd)}
        return d


def start_tensor(rec: Recording) -> tuple[np.ndarray, str]:
    """The tensor entries (6,) the fit starts from, and their source: the prediction-error fit on
    the gyro (unrefined) where it gives a physical tensor, else the body anchors' box."""
    try:
        tensor = np.asarray(identify_recording(rec, refine=False).inertia, float)      # (3, 3)
        if np.all(np.isfinite(tensor)) and physically_consistent(tensor):
            return from_tensor(tensor), "the prediction-error fit on the gyro"
    except (IdentificationError, np.linalg.LinAlgError, ValueError) as e:
        log.info("no prediction-error start (%s): the body anchors' box", e)
    return default_initial_guess(rec.rig), "the body anchors' box (a guess)"


def fit_whole_recording(rec: Recording, cg=None, cg_std=None, cg_source: str | None = None,
                        start: float | None = None, end: float | None = None) -> RigModelResult:
    """Fit the rig model to the whole recording (module docstring).

    cg, cg_std: the static CG (3,) m and its σ (3,) m as the CG's prior (default: rig.yaml's CG
    as the start, no prior).  start/end: s from the first IMU sample.  Raises
    :class:`~rig_identification.estimation.rig_fit.RigFitError`,
    :class:`~rig_identification.io.rig.RigError`."""
    t_wall = time.perf_counter()
    t_first = float(rec.sensors.t_start)
    rc = record(rec.sensors, rec.rig, None if start is None else t_first + start,
                None if end is None else t_first + end)
    prior = Prior.from_rig(rec.rig, cg, cg_std)
    guess, source = start_tensor(rec)
    log.info("fitting the rig model to every sensor (%.0f s, %d channels)", rc.duration, len(rc.channels))
    fit = fit_rig(rc, rec.rig, prior, guess)
    return RigModelResult(fit, str(rec.path), rc.t0, rc.t0 - t_first + rc.start * rc.dt,
                          (len(rc.y) - 1 - rc.start) * rc.dt, rc.band, guess, source, prior.cg, prior.cg_std,
                          cg_source or ("rig.yaml (start only)" if cg_std is None else "given"),
                          time.perf_counter() - t_wall, rec.truth)
