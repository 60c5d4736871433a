"""A recording read whole: the rig's grey-box model fitted to every sensor (``rig-identify inertia``).

recording → :func:`~rig_identification.estimation.rig_record.record` (every stream on one grid, the
exciter's force denoised) → a start for the tensor (the prediction-error fit on the gyro,
:func:`~rig_identification.estimation.gyro_fit.fit_gyro`, where it gives a
physical tensor: its first stage a linear regression that needs no start; else the body anchors'
box; the cables' stiffness, where rig.yaml gives none, from the forced response:
:func:`~rig_identification.estimation.harmonic_start.forced_response_start`) →
:func:`~rig_identification.estimation.rig_fit.fit_rig`
(the exact model, every sensor an output, mass, CG, cables, load cells and geometry fitted with
their priors; the whole-record fit also restarted from the gyro-only fit's tensor: a minimum
another estimator found is one the likelihood may hold too) → :class:`RigModelResult`.

The CG's prior: a saved static result (``--cg CG.json``, its σ), else rig.yaml's CG with σ
:data:`RIG_YAML_CG_STD`; the result gives the static and the fitted CG side by side and their
difference in σ.

Several recordings of one body (``rig-identify inertia RUN1 RUN2 …``): :mod:`~rig_identification.pipeline.joint`.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace

import numpy as np

from ..diagnosis.rig_diagnosis import RigDiagnosis, diagnose_rig, lost
from ..estimation.gyro_fit import IdentificationError, fit_gyro
from ..estimation.harmonic_start import ForcedResponseStart, box_tensor, damped_start, forced_response_start
from ..estimation.rig_fit import LEVEL_LIMIT, RigFit, fit_rig
from ..estimation.rig_problem import sequential_blas
from ..estimation.rig_record import Record, record
from ..estimation.rig_unknowns import EXTENSIONS, Prior
from ..estimation.tracker_replay import replay_cleaned
from ..io.export import Axes, Expressed, express
from ..io.quality import check_motion, check_units, clean_sensors
from ..io.recording import Recording, SensorData
from ..io.rig import Survey
from ..io.verdict import KEYS
from ..model.parametrisation import entry_scales, physically_consistent, to_tensor

log = logging.getLogger(__name__)

#: Beyond :data:`~rig_identification.estimation.rig_fit.LEVEL_LIMIT` a channel does not fit; beyond
#: this the fit has not found the motion at all (verdict ``failed``).
FAILED_LEVEL = 10.0
#: σ (m) assumed of rig.yaml's CG when no static result with its own σ is given (``--cg``): a
#: static test's typical z (docs/cg.md).  Without any prior the CG's height, the mass and the
#: moments trade along a curved valley on some rigs (bench_crb 31003: ixx 37 % off at 10 σ).
RIG_YAML_CG_STD = 5e-3
#: The static and the dynamic test's CG must agree within this many combined σ.
CONSISTENCY_SIGMA = 3.0
#: The gyro-only fit is a start only where its trace is within this factor of the box's.
START_TRACE_FACTOR = 5.0
#: The gyro-only fit is the first start where each σ is within this share of its entry's scale.
TRUSTED_START_SHARE = 0.05
#: The body anchors' box scaled by these are the starts tried after the first (:func:`start_tensors`),
#: and the forced response's fit starts from them (:func:`prepared`).
BOX_SCALES = (1.0, 0.6, 0.35)
#: The box scaled by these are tried last (:func:`start_tensors`): they lie between
#: :data:`BOX_SCALES`, and a start's basin can be narrower than those steps (bench_any_rig's clean
#: 5-cable 21011 and 21017: no start of the others fitted the first stage, the fit did not find the
#: motion; from the box at 0.8 it did, 12–23 % off the truth, where the box at 0.6, 11–18 % off, failed).
BOX_SCALES_BETWEEN = (0.8, 0.45)


@dataclass(frozen=True)
class CentreOfGravity:
    """The centre of gravity from each test and from both, body frame, m.

    static, static_std: (3,) the static test's (the fit's prior; σ inf: none), from
    ``static_source``.  dynamic, dynamic_std: (3,) what the swinging body alone gives — the
    compound pendulum's moments of the cable forces about the CG (Atkeson, An & Hollerbach 1986:
    the first moments are identifiable with the tensor) — σ inf where the run does not determine
    it.  combined, combined_std: (3,) the fit's, which used the static one as its prior.
    """

    static: np.ndarray
    static_std: np.ndarray
    static_source: str
    dynamic: np.ndarray
    dynamic_std: np.ndarray
    combined: np.ndarray
    combined_std: np.ndarray

    @property
    def difference_sigma(self) -> np.ndarray:
        """(3,) (dynamic − static) over their combined σ; nan where either is not determined."""
        s = np.sqrt(self.dynamic_std ** 2 + self.static_std ** 2)
        return np.where(np.isfinite(s), (self.dynamic - self.static) / np.where(np.isfinite(s), s, 1.0), np.nan)

    @property
    def agree(self) -> bool:
        """Static and dynamic within :data:`CONSISTENCY_SIGMA` on every axis both determine."""
        d = self.difference_sigma
        return bool(np.all(np.abs(d[np.isfinite(d)]) <= CONSISTENCY_SIGMA))

    def to_dict(self) -> dict:
        def v(x):
            return [float(a) if np.isfinite(a) else None for a in x]
        return {"static": v(self.static), "static_std": v(self.static_std), "static_source": self.static_source,
                "dynamic": v(self.dynamic), "dynamic_std": v(self.dynamic_std),
                "combined": v(self.combined), "combined_std": v(self.combined_std),
                "difference_sigma": v(self.difference_sigma), "agree": self.agree, "units": "m, body frame"}


def split_cg(combined: np.ndarray, covariance: np.ndarray, static: np.ndarray, static_std: np.ndarray,
             source: str) -> CentreOfGravity:
    """The dynamic test's own CG out of the fit that combined it with the static one.

    combined: (3,) m, covariance: (3, 3) m² its block of the fit's covariance; static,
    static_std: (3,) m the prior (σ inf: none).  The prior adds its information only to the CG's
    block, so the run's own information on the CG (every other unknown profiled out) is the
    combined one less the prior's, and its estimate the information-weighted difference
    (Gaussian fusion inverted).  A direction whose own information is below 10⁻⁹ of the
    combined's is not determined by the run: σ inf on the axes it touches.
    """
    info_c = np.linalg.inv(covariance)
    prior_info = np.where(np.isfinite(static_std), 1.0 / np.where(np.isfinite(static_std), static_std, 1.0) ** 2, 0.0)
    info_d = info_c - np.diag(prior_info)
    w, v = np.linalg.eigh(0.5 * (info_d + info_d.T))
    ok = w > 1e-9 * np.max(np.linalg.eigvalsh(info_c))
    cov_d = (v[:, ok] / w[ok]) @ v[:, ok].T
    dynamic = cov_d @ (info_c @ combined - prior_info * np.where(np.isfinite(static), static, 0.0))
    touched = np.any(np.abs(v[:, ~ok]) > 1e-3, axis=1) if np.any(~ok) else np.zeros(3, bool)
    dyn_std = np.where(touched, np.inf, np.sqrt(np.maximum(np.diag(cov_d), 0.0)))
    dynamic = np.where(touched, np.nan, dynamic)
    return CentreOfGravity(np.asarray(static, float), np.asarray(static_std, float), source, dynamic, dyn_std,
                           np.asarray(combined, float), np.sqrt(np.diag(covariance)))


@dataclass(frozen=True)
class RigModelResult:
    """The rig model fitted to one recording.

    fit: :class:`~rig_identification.estimation.rig_fit.RigFit`.  path: the recording.  t0: the
    record's first stamp, s; start_s, duration_s: the compared span from t0, s; band_hz: the
    fit's band edge.  inertia_start: (6,) the tensor the fit started from, and where it came from
    (``start_source``), with its σ (6,) (inf: none).  cg_prior: (3,) m and cg_prior_std (3,) m
    (inf: none) of the CG's prior,
    cg_source: where it came from.  survey: the geometry's, the mass's and the gains' σ the fit assumed
    (rig.yaml ``survey``).  seconds: wall time.  truth: truth.yaml or None.  warnings: what reading
    the recording did (:attr:`~rig_identification.io.recording.Recording.warnings`: stamps put on
    their rate, samples dropped) and the data's cleaning
    (:func:`~rig_identification.io.quality.clean_sensors`: spans excluded, gaps bridged,
    spikes replaced).  diagnosis: what the rigid-body rig model left out
    (:func:`~rig_identification.diagnosis.rig_diagnosis.diagnose_rig`; None: not run); where it
    added extensions, ``fit`` is the refit with them and ``diagnosis.rigid`` the fit before.
    """

    fit: RigFit
    path: str
    t0: float
    start_s: float
    duration_s: float
    band_hz: float
    inertia_start: np.ndarray
    start_std: np.ndarray
    start_source: str
    cg_prior: np.ndarray
    cg_prior_std: np.ndarray
    cg_source: str
    survey: Survey
    seconds: float
    truth: dict | None
    warnings: tuple[str, ...] = ()
    diagnosis: RigDiagnosis | None = None

    @property
    def verdict(self) -> str:
        """``ok`` (every channel within :data:`LEVEL_LIMIT` of its noise, the tensor consistent with
        the gyro-only fit), ``model_error`` (some channel beyond: the model misses physics or a
        sensor's trait, σ not calibrated), ``not_identifiable`` (some entry :attr:`undetermined` or
        :attr:`ambiguous`:
        then no entry is an estimate — the directions of the tensor are coupled, and on bench_crb's
        31003 a moment whose σ said ±0.85 % at 95 % was 9 % off beside the undetermined one),
        ``inconsistent`` (the static and dynamic CG disagree beyond :data:`CONSISTENCY_SIGMA`:
        not an estimate to use) or ``failed`` (a channel beyond
        :data:`FAILED_LEVEL`, or a number not
        finite: the fit did not find the motion; the numbers are not an estimate)."""
        f = self.fit
        finite = np.all(np.isfinite(f.inertia)) and np.all(np.isfinite(f.inertia_std))
        if not finite or np.max(f.residual_level) > FAILED_LEVEL:
            return "failed"
        if self.poorly_fitted:
            return "model_error"
        if self.undetermined or self.ambiguous:
            return "not_identifiable"
        return "ok" if self.cg.agree else "inconsistent"

    @property
    def undetermined(self) -> list[str]:
        """The entries whose 95 % half-width exceeds
        :data:`~rig_identification.io.verdict.DETERMINED_SHARE` of their scale (a moment's
        own, the largest moment's for a product; :attr:`~.rig_fit.RigFit.undetermined`).  Their values
        are not an estimate:
        where the recording determines a direction of the tensor that weakly, the likelihood is
        far from quadratic and another minimum may explain the data as well (bench_crb 31003,
        6 cables: every channel at its noise, Ixx 37 % off at 10 σ with σ 2.5 %)."""
        return self.fit.undetermined

    @property
    def ambiguous(self) -> list[str]:
        """The entries on which a restart of the fit (1 % away, 10 σ along the weakest direction,
        or from the gyro-only fit's tensor) settled more than 3 σ from the estimate at a χ²
        within the tensor's 95 % likelihood-ratio region, or on which the fit's own descent ended
        more than 3 σ from a lower minimum a restart found
        (:attr:`~rig_identification.estimation.rig_fit.RigFit.ambiguous`): the likelihood is
        flat or multimodal where σ says it is sharp, so σ is not the error's size and no entry is
        an estimate."""
        return [KEYS[i] for i in self.fit.ambiguous]

    @property
    def summary(self) -> str:
        """The verdict and what it means for the numbers, one line."""
        added = self.diagnosis.extensions if self.diagnosis is not None else ()
        return self.verdict_line + (f" (the model with {', '.join(added)} added: below)" if added else "")

    @property
    def verdict_line(self) -> str:
        """The verdict and what it means for the numbers, one line, without what the diagnosis added."""
        v = self.verdict
        if v == "ok":
            return "ok — the model explains every channel at its noise level"
        if v == "model_error":
            return (f"model_error — {', '.join(self.poorly_fitted)} beyond {LEVEL_LIMIT}× their noise: the model "
                    "misses something there; σ below is not calibrated")
        if v == "not_identifiable":
            why = (f"{', '.join(self.undetermined)} not determined to ±1 % at 95 %: the fit may sit in another "
                   "minimum that explains the data as well, and the tensor's directions are coupled"
                   if self.undetermined else
                   f"restarted, the fit settled more than 3 σ off on {', '.join(self.ambiguous)} at a χ² only "
                   f"{min(self.fit.other_chi2):.1f} above the estimate's: the likelihood is flat where σ says it is "
                   "sharp")
            return f"not_identifiable — {why}; no entry below is an estimate to use"
        if v == "inconsistent":
            return ("inconsistent — the static and the dynamic test's CG disagree (below); the numbers below are not "
                    "an estimate to use")
        return ("failed — the fit did not find the motion (a channel beyond 10× its noise, or a number not finite): "
                "the numbers below are not an estimate")

    @property
    def rigid_body(self) -> "RigModelResult | None":
        """The rigid-body rig model's fit before the diagnosis added extensions (its verdict, tensor
        and channels), or None where nothing was added (then :attr:`fit` is that fit)."""
        if self.diagnosis is None or self.diagnosis.refit is None:
            return None
        return replace(self, fit=self.diagnosis.rigid, diagnosis=None)

    def rigid_body_dict(self) -> dict | None:
        """The JSON of :attr:`rigid_body` (verdict, summary, tensor with σ, each channel's residual
        over its noise), or None."""
        r = self.rigid_body
        if r is None:
            return None
        return {"verdict": r.verdict, "summary": r.summary,
                "inertia_about_cg": {k: float(v) for k, v in zip(KEYS, r.fit.inertia)},
                "inertia_std": {k: float(v) for k, v in zip(KEYS, r.fit.inertia_std)},
                "residual_level": {c: float(v) for c, v in zip(r.fit.channels, r.fit.residual_level)}}

    @property
    def withheld(self) -> tuple[str, ...]:
        """The entries given as no estimate: all six where the verdict is ``not_identifiable`` or
        ``failed`` (no entry is one then: :attr:`verdict`), else none."""
        return KEYS if self.verdict in ("not_identifiable", "failed") else ()

    def expressed(self, axes: str | Axes = "body") -> Expressed:
        """The mass, the fitted CG (m) and the tensor about it in ``axes`` with σ
        (:func:`~rig_identification.io.export.express`, the one way to other axes), the
        :attr:`withheld` entries left out.  The σ hold the CG's and the mass's (fitted with it)."""
        f = self.fit
        return express(f.body.mass, f.body.cg, to_tensor(f.inertia), f.inertia_std,
                       self.withheld, axes)

    @property
    def poorly_fitted(self) -> list[str]:
        """The channels whose residual in the band exceeds :data:`LEVEL_LIMIT` times their noise."""
        return [c for c, v in zip(self.fit.channels, self.fit.residual_level) if v > LEVEL_LIMIT]

    @property
    def cg(self) -> CentreOfGravity:
        """The CG from the static test (the prior), the run alone and both (:func:`split_cg`)."""
        f = self.fit
        return split_cg(f.body.cg, f.body.covariance[6:9, 6:9], self.cg_prior, self.cg_prior_std,
                        self.cg_source)

    def to_dict(self) -> dict:
        """The JSON object of ``rig-identify inertia --model rig --json`` (SI units)."""
        f = self.fit
        p = f.parameters
        sd = f.inertia_std
        bd_cov = f.covariance[f.layout.body_damping][:, f.layout.body_damping]
        d = {
            "schema": "rig_identification.rig_model_result", "schema_version": 8,
            "recording": self.path, "model": "rig (grey-box, every sensor an output)",
            "verdict": self.verdict, "undetermined": self.undetermined, "ambiguous": self.ambiguous,
            "other_minima": [{"inertia_about_cg": {k: float(v) for k, v in zip(KEYS, m + f.inertia - p.inertia)},
                              "chi2_over_estimate": float(c), "settled": e}
                             for m, c, e in zip(f.other_minima, f.other_chi2, f.minima_settled)],
            "other_minima_note": "the whole-record fit restarted with every entry 1 % away, once each way, 10 σ "
                                 "either way along the tensor's weakest direction, and from the gyro-only fit's "
                                 "tensor where it gave one; the lowest of the minima is the estimate; another more "
                                 "than 3 σ off at a χ² within 12.6 of the estimate's, or the fit's own descent ending "
                                 "more than 3 σ from it, makes those entries ambiguous; settled false: that restart "
                                 "spent its budget of model runs first, its end no minimum",
            "window": {"start_s": self.start_s, "duration_s": self.duration_s, "band_hz": [0.0, self.band_hz]},
            "inertia_about_cg": {k: float(v) for k, v in zip(KEYS, f.inertia)},
            "inertia_std": {k: float(v) for k, v in zip(KEYS, sd)},
            "inertia_crb": {k: float(v) for k, v in zip(KEYS, f.crb)},
            "sigma_over_crb": {k: float(a / b) for k, a, b in zip(KEYS, sd, f.crb)},
            "inertia_units": "kg m^2 (tensor entries about the CG, body axes; ixy = -product of inertia)",
            "inertia_start": {"entries": {k: float(v) for k, v in zip(KEYS, self.inertia_start)},
                              "std": {k: float(v) if np.isfinite(v) else None for k, v in zip(KEYS, self.start_std)},
                              "source": self.start_source},
            "mass": f.body.mass, "mass_std": float(f.body.std[9]), "exciter_rotor_removed_kg": f.body.rotor,
            "center_of_gravity": self.cg.to_dict(),
            "survey": {"anchors_m": self.survey.anchors, "lengths_m": self.survey.lengths,
                       "mass_kg": self.survey.mass_std(f.body.mass),
                       "load_cell_gain": self.survey.load_cell_gain,
                       "source": "rig.yaml survey (defaults where it says nothing)"},
            "cables": {"stiffness": p.stiffness.tolist(), "damping_time": float(p.damping_time),
                       "load_cell_gain": p.gain.tolist()},
            "body_damping": {"linear": float(p.body_damping[0]), "angular": float(p.body_damping[1]),
                             "linear_std": float(np.sqrt(bd_cov[0, 0])), "angular_std": float(np.sqrt(bd_cov[1, 1])),
                             "units": "N s/m on the CG's velocity, N m s on the angular velocity"},
            "residual_level": {c: float(v) for c, v in zip(f.channels, f.residual_level)},
            "offsets": None if f.offsets is None else {c: float(v) for c, v in zip(f.channels, f.offsets)},
            "poorly_fitted_channels": self.poorly_fitted,
            "natural_frequencies_hz": f.natural_frequencies.tolist(),
            "seconds": self.seconds,
            "warnings": list(self.warnings),
            "extensions": {e: dict(zip(("values", "std"), (a.tolist() for a in f.extension(e))),
                                   units=EXTENSIONS[e][1]) for e in f.layout.extensions},
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_dict(),
            "rigid_body_fit": self.rigid_body_dict(),
        }
        if self.truth and "inertia_about_cg" in self.truth:
            t = np.array([float(self.truth["inertia_about_cg"][k]) for k in KEYS])
            err = f.inertia - t
            d["truth_comparison"] = {k: {"truth": float(a), "error_percent": float(100 * e / s),
                                         "error_sigma": float(e / sg)}
                                     for k, a, e, s, sg in zip(KEYS, t, err, entry_scales(t), sd)}
        return d


def start_tensor(rec: Recording, sensors: SensorData) -> tuple[np.ndarray, np.ndarray, str]:
    """The tensor entries (6,) the fit starts from, their σ (6,) (inf: a guess) and their source:
    the prediction-error fit on the gyro, the tensions its input (``sensors``: ``rec``'s, cleaned;
    :func:`~rig_identification.estimation.tracker_replay.replay_cleaned`: tracker and preprocessor;
    :func:`~rig_identification.estimation.gyro_fit.fit_gyro`; thesis §3.3), where it
    gives a physical tensor whose trace is within a factor :data:`START_TRACE_FACTOR` of the body
    anchors' box's, else that box (:func:`~rig_identification.estimation.harmonic_start.box_tensor`)."""
    box = box_tensor(rec.rig)
    try:
        prep = replay_cleaned(rec, sensors, [])
        res = fit_gyro(prep.t, prep.gyro_body, prep.torque)
        tensor = to_tensor(res.inertia)
        if np.all(np.isfinite(tensor)) and physically_consistent(tensor):
            ratio = np.trace(tensor) / (box[0] + box[3] + box[5])
            if 1 / START_TRACE_FACTOR <= ratio <= START_TRACE_FACTOR:
                std = res.std
                return np.asarray(res.inertia, float), np.where(np.isfinite(std), std, np.inf), \
                    "the prediction-error fit on the gyro"
            log.info("the prediction-error start's trace is %.3g times the box's: not a start", ratio)
    except (IdentificationError, np.linalg.LinAlgError, ValueError) as e:
        log.info("no prediction-error start (%s): the body anchors' box", e)
    return box, np.full(6, np.inf), "the body anchors' box (a guess)"


def start_tensors(rec: Recording, first: np.ndarray, first_std: np.ndarray, harmonic: np.ndarray) -> np.ndarray:
    """(k, 6) the starts the fit tries in turn: ``first`` (the gyro-only fit's, σ ``first_std``)
    where every σ is within :data:`TRUSTED_START_SHARE` of its entry's scale, then ``harmonic``,
    the tensor whose linearised forced response matches the record's fundamental
    (:func:`~rig_identification.estimation.harmonic_start.forced_response_start`, itself fitted
    from the others; first where ``first`` is not trusted), then the body anchors' box scaled by
    :data:`BOX_SCALES` and by :data:`BOX_SCALES_BETWEEN` (a body's radius of gyration is some
    fraction of the frame that carries it).  The fit tries them in this order until one fits its
    first stage (:func:`~rig_identification.estimation.rig_fit.fit_rig`): the later ones only where
    no earlier one did."""
    box = box_tensor(rec.rig)
    boxes = [f * box for f in BOX_SCALES + BOX_SCALES_BETWEEN if not np.allclose(f * box, first)]
    trusted = bool(np.all(first_std <= TRUSTED_START_SHARE * entry_scales(first)))
    return np.vstack(([first, harmonic] if trusted else [harmonic, first]) + boxes)


@dataclass(frozen=True)
class FitInput:
    """A recording made ready for the rig model's fit (:func:`prepared`): ``rc`` its
    :class:`~rig_identification.estimation.rig_record.Record`, ``prior`` the fit's
    :class:`~rig_identification.estimation.rig_unknowns.Prior`, ``starts`` (k, 6) kg·m² the tensors
    tried in turn (:func:`start_tensors`), ``restarts`` (0 or 1, 6) the gyro-only fit's tensor the
    whole-record fit is restarted from, ``forced`` the forced response's start (the cables'
    stiffness's, :func:`~rig_identification.estimation.harmonic_start.forced_response_start`), ``guess`` (6,)
    and ``guess_std`` (6,) the gyro-only start and its σ (inf: the box), ``source`` its name, ``cg_source``
    where the CG's prior came from, ``warnings`` what reading and cleaning did, ``t_first`` the first IMU stamp, s."""

    rec: Recording
    rc: Record
    prior: Prior
    starts: np.ndarray
    restarts: np.ndarray
    forced: ForcedResponseStart
    guess: np.ndarray
    guess_std: np.ndarray
    source: str
    cg_source: str
    warnings: tuple[str, ...]
    t_first: float

    def fit(self, extensions: dict[str, np.ndarray] | None = None, first: np.ndarray | None = None,
            stiffness: np.ndarray | None = None) -> RigFit:
        """The rig model fitted to the record (:func:`~rig_identification.estimation.rig_fit.fit_rig`),
        with ``extensions`` (name -> start) where given, from ``first`` (6,) kg·m² before the starts,
        the cables' stiffness from ``stiffness`` (N,) N/m (default the forced response's start)."""
        starts = self.starts if first is None else np.vstack([first, self.starts])
        return fit_rig(self.rc, self.rec.rig, self.prior, starts, restarts=self.restarts, extensions=extensions,
                       stiffness=self.forced.stiffness if stiffness is None else stiffness)

    def result(self, fit: RigFit, seconds: float, diagnosis: RigDiagnosis | None = None) -> RigModelResult:
        """The :class:`RigModelResult` of ``fit`` (``seconds``: the wall time)."""
        rc = self.rc
        return RigModelResult(fit, str(self.rec.path), rc.t0, rc.t0 - self.t_first + rc.start * rc.dt,
                              (len(rc.y) - 1 - rc.start) * rc.dt, rc.band, self.guess, self.guess_std, self.source,
                              self.prior.cg, self.prior.cg_std, self.cg_source, self.rec.rig.survey, seconds,
                              self.rec.truth, self.warnings, diagnosis)


def prepared(rec: Recording, cg=None, cg_std=None, cg_source: str | None = None, start: float | None = None,
             end: float | None = None) -> FitInput:
    """The recording checked, cleaned and put on one grid, the CG's prior, the starts (the
    gyro-only fit's and the forced response's: module docstring).  Arguments as
    :func:`fit_whole_recording`'s; raises as it does."""
    t_first = float(rec.sensors.t_start)
    check_units(rec)
    warnings = list(rec.warnings)       # the reader's (stamps regularised, samples dropped), then the cleaning's
    sensors = clean_sensors(rec, warnings)
    for w in warnings[len(rec.warnings):]:       # the cleaning's, as they happen
        log.warning(w)
    check_motion(rec, sensors)
    rc = record(sensors, rec.rig, None if start is None else t_first + start,
                None if end is None else t_first + end)
    given = cg is not None
    if cg is None:                                  # rig.yaml's CG: the static test's, its σ unknown
        cg, cg_std = rec.rig.require_cg(), np.full(3, RIG_YAML_CG_STD)
        cg_source = cg_source or f"rig.yaml (σ {1e3 * RIG_YAML_CG_STD:g} mm assumed)"
    prior = Prior.from_rig(rec.rig, cg, cg_std)
    guess, guess_std, source = start_tensor(rec, sensors)
    box = box_tensor(rec.rig)
    stiff = forced_response_start(rc, rec.rig, prior,
                                  np.vstack([guess] + [f * box for f in BOX_SCALES if not np.allclose(f * box, guess)]))
    if stiff.moved:
        warnings.append(f"the cables' stiffness starts at {np.exp(stiff.log_scale):.3g}× the default steel cable's "
                        f"({np.mean(stiff.stiffness):.3g} N/m; rig.yaml gives none): the forced response's misfit "
                        f"{stiff.level:.3g}× the noise there, {stiff.prior_level:.3g}× at the default's")
    starts = start_tensors(rec, guess, guess_std, stiff.tensor)
    restarts = guess[None] if np.any(np.isfinite(guess_std)) else np.zeros((0, 6))
    source_cg = cg_source or ("given" if given and cg_std is not None else "rig.yaml (start only)")
    return FitInput(rec, rc, prior, starts, restarts, stiff, guess, guess_std, source,
                    source_cg, tuple(warnings), t_first)


def fit_whole_recording(rec: Recording, cg=None, cg_std=None, cg_source: str | None = None,
                        start: float | None = None, end: float | None = None, diagnose: bool = True
                        ) -> RigModelResult:
    """Fit the rig model to the whole recording (module docstring).

    cg, cg_std: the static CG (3,) m and its σ (3,) m as the CG's prior (default: rig.yaml's CG
    with σ :data:`RIG_YAML_CG_STD`).  start/end: s from the first IMU sample.  diagnose: what the
    model leaves out tested and, where the recording tells it, added (:func:`~rig_identification.
    diagnosis.rig_diagnosis.diagnose_rig`: the reported fit is then the refit).  The data are checked
    and cleaned as for every fit (:mod:`~rig_identification.io.quality`: the tensions'
    units, bad spans, spikes, a body that did not move).  Raises
    :class:`~rig_identification.estimation.rig_record.RigFitError`,
    :class:`~rig_identification.io.rig.RigError`,
    :class:`~rig_identification.io.recording.RecordingError`."""
    with sequential_blas():
        t_wall = time.perf_counter()
        inp = prepared(rec, cg, cg_std, cg_source, start, end)
        log.info("fitting the rig model to every sensor (%.0f s, %d channels)", inp.rc.duration, len(inp.rc.channels))
        fit = inp.fit()
        diagnosis = None
        if diagnose and np.all(np.isfinite(fit.inertia_std)):
            log.info("testing what the model leaves out")

            def refit(extensions: dict[str, np.ndarray], start: np.ndarray, stiffness: np.ndarray | None) -> RigFit:
                log.info("fitting the rig model with %s", ", ".join(extensions) or "nothing added, again")
                return inp.fit(extensions, start, stiffness)

            # where the fit did not find the motion, the damping the fundamental asks for starts the drag's
            # fit, and the forced response with the exciter rotor's unbalance (its weight turning with the
            # force) the rotor's: the tensor and the cables' stiffness
            damped = turning = None
            if lost(fit):
                damped = damped_start(inp.rc, rec.rig, inp.prior, inp.forced)
                unbalance = inp.rc.unbalance()
                if unbalance is not None:
                    turning = forced_response_start(inp.rc, rec.rig, inp.prior, inp.starts,
                                                    rotor=np.array([unbalance, 0.0]))
            diagnosis = diagnose_rig(inp.rc, inp.prior, fit, list(rec.rig.cable_names), refit, damped, turning)
            fit = diagnosis.refit or diagnosis.rigid
        return inp.result(fit, time.perf_counter() - t_wall, diagnosis)
