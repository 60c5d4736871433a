"""Identifier: the inertia tensor about the CG from the generalized wrench and the gyro.

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

Uncertainty — the residuals are coloured (band-passed), so the covariance of P is the
sandwich (heteroscedasticity- and autocorrelation-consistent) estimate with batch
means over blocks longer than the correlation time; J = P⁻¹ and its covariance follow
by the delta method (dJ = −J dP J).  The eigen-directions of the information matrix
of J tell which combinations the recording determines poorly (see
:attr:`InertiaResult.weak_directions`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import cumulative_simpson, cumulative_trapezoid
from scipy.signal import butter, decimate, sosfiltfilt

from ..io.export import (AXES, ENTRY_NAMES, INERTIA_SCHEMA, INERTIA_SCHEMA_VERSION, UNITS, VEHICLE_SIGN,
                     convention_lines, express, finite_or_none, with_effect_units)
from .errors_in_variables import Compensation, NoiseRealisations, compensate
from ..model.parametrisation import (basis, consistent_from_params, from_tensor, params_from_consistent,
                              physically_consistent, to_tensor)
from ..io.rig import Rig
from ..io.verdict import KEYS, Validation

class IdentificationError(ValueError):
    """The data cannot give a trustworthy inertia estimate (too short, gaps, no motion)."""


STAGE1_CONDITION = 100.0   # largest / smallest principal moment of the Levenberg–Marquardt start
FIT_RATE = 200.0  # Hz: streams sampled ≥ 2× faster are decimated to about this rate before the fit
@dataclass
class FitSeries:
    """The fit's output over one segment (one recording's window): t (N,) s; measured
    (N,3) band-passed gyro, rad/s, body axes; predicted (N,3) the model's band-passed ω
    with the identified tensor; band_hz the pass band; label the segment's name."""

    t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    band_hz: tuple[float, float]
    label: str = ""
    # the fit's local linearisation, for model validation (:mod:`rig_identification.estimation.validation`): jacobian
    # (N,3,6) d predicted / d tensor entries (KEYS order), rad/s per kg·m²; axis_scale (3,)
    # rad/s, the per-axis residual scale that weighted the fit; fs Hz
    jacobian: np.ndarray | None = None
    axis_scale: np.ndarray | None = None
    fs: float | None = None
    # first-order noise realisations of the Jacobian (K,N,3,6) and of the residual (K,N,3) at
    # the fitted tensor (:mod:`rig_identification.estimation.errors_in_variables`), when the fit was compensated: the
    # validation's sub-band and segment fits compensate with them too
    noise_jacobian: np.ndarray | None = None
    noise_residual: np.ndarray | None = None

    @property
    def residual(self) -> np.ndarray:
        """(N,3) rad/s measured − predicted."""
        return self.measured - self.predicted


@dataclass
class InertiaResult:
    """Identified mass properties.

    mass kg; center_of_gravity (3,) body m; inertia (3,3) kg·m² about the CG, body axes
    (geometry_msgs/Inertia entries: off-diagonals are negated products of inertia);
    inertia_std (6,) in :data:`KEYS` order; covariance (6,6); correlation (6,6);
    weak_directions: list of (relative std, (3,3) unit-norm tensor direction) for the
    poorly determined combinations; residual_rms (3,) rad/s of the band-passed gyro fit;
    series: one :class:`FitSeries` per fitted segment (empty for the thesis baseline).
    A joint fit (:func:`identify_inertia_joint`): t_start/t_end are the earliest start
    and latest end over the segments, n_samples their total, band_hz the union of bands.
    """

    mass: float
    center_of_gravity: np.ndarray
    inertia: np.ndarray
    inertia_std: np.ndarray
    covariance: np.ndarray
    t_start: float
    t_end: float
    n_samples: int
    band_hz: tuple[float, float]
    residual_rms: np.ndarray
    fit_r2: np.ndarray
    weak_directions: list = field(default_factory=list)
    method: str = "prediction error (band-limited output error, integrated Newton–Euler)"
    warnings: list[str] = field(default_factory=list)
    crb_std: np.ndarray | None = None
    gyro_noise: float | None = None
    series: list = field(default_factory=list)
    # filled by pipeline.refine_uncertainty (None otherwise): the identifier's own sandwich
    # σ (6,), the least-squares bias removed by the compensation for the noise in the input
    # (6,) kg·m², the estimated white-noise σ per sensor source, and the per-gyro-axis ratio
    # (3,) of the fit's residual RMS to the one the noise's replays predict
    sandwich_std: np.ndarray | None = None
    bias_correction: np.ndarray | None = None
    sensor_noise: dict | None = None
    residual_excess: np.ndarray | None = None
    # the propagated σ widened to the spread of replays with fresh noise (pipeline.refine_uncertainty)
    replay_factor: float | None = None
    # filled by pipeline.identify_recording: the load cells' mean vertical force over
    # rig.yaml's weight, − 1 (pipeline.weight_surplus)
    weight_surplus: float | None = None
    uncertainty: str = "sandwich"   # what inertia_std is: "sandwich", "propagated sensor noise", …
    # filled by pipeline.with_diagnosis when the fit showed model error and diagnose named its
    # cause: the rigid-body fit's tensor and σ, and the effects added (JSON of each)
    rigid_body: dict | None = None
    diagnosis: dict | None = None
    # filled by pipeline.identify_recording(s): the model validation's verdict and checks
    # (validation.validate); whether bias_correction was removed (it is not when the noise
    # dominates a direction of the input: then the compensation is impossible)
    validation: Validation | None = None
    bias_applied: bool = False
    # filled by a fit compensated for the noise in its input (pipeline.refine_uncertainty):
    # errors_in_variables.Compensation (share of noise in the regressor, the correction, its σ)
    errors_in_variables: Compensation | None = None

    @property
    def correlation(self) -> np.ndarray:
        """(6,6) correlation of the entries (NaN where a σ is 0 or not finite)."""
        with np.errstate(all="ignore"):
            s = np.sqrt(np.clip(np.diag(self.covariance), 0, None))
            return self.covariance / np.outer(s, s)

    def expressed(self, axes: str = "body"):
        """The mass properties in ``axes`` (a name of :data:`~rig_identification.io.export.AXES`: ``body`` — rig.yaml's,
        REP-103 — or ``sae``, SAE J670), the undetermined entries left out: an
        :class:`~rig_identification.io.export.Expressed` (:func:`~rig_identification.io.export.express`).  Raises KeyError for an unknown name."""
        return express(self.mass, self.center_of_gravity, self.inertia, self.inertia_std, self.undetermined, axes)

    @property
    def undetermined(self) -> tuple[str, ...]:
        """Entries the recording does not determine (validation verdict ``not_identifiable``):
        reported as None."""
        return () if self.validation is None else tuple(self.validation.undetermined)

    def to_dict(self, t0: float | list[float] | None = None) -> dict:
        """The result as JSON (schema :data:`~rig_identification.io.export.INERTIA_SCHEMA`, version
        :data:`~rig_identification.io.export.INERTIA_SCHEMA_VERSION`; ``units`` per field, :data:`~rig_identification.io.export.UNITS`).

        Tensor entries as geometry_msgs/Inertia (off-diagonals the negated products of inertia),
        body axes of rig.yaml; ``products_of_inertia`` with the vehicle-dynamics sign; the tensor
        about the body frame's origin; principal moments and axes.  Undetermined entries (and
        everything derived from them) are None, never NaN.  t0: the recording's first IMU stamp,
        s: ``window.start``/``end`` are then seconds from it (as ``--start`` takes them) and the
        absolute stamps are ``start_stamp``/``end_stamp``; without it (a stream, no first
        sample known) ``start``/``end`` are the absolute stamps too.  A joint fit takes one t0
        per recording (``series`` order): each of ``recordings`` gets its own window, and the
        overall ``window.start``/``end`` are None (no common origin).  The validation's time
        segments (``validation.segments[].start``/``end``) count from the same origin as their
        recording's window (the stamps in ``start_stamp``/``end_stamp``)."""
        theta = from_tensor(self.inertia)
        gone = set(self.undetermined)
        ex = express(self.mass, self.center_of_gravity, self.inertia, self.inertia_std, gone)
        num = finite_or_none

        def entry(k, v):
            return None if k in gone else num(v)

        def per_key(a):
            return None if a is None else {k: num(v) for k, v in zip(KEYS, a)}

        def window(t_start, t_end, n, origin):
            if origin is None:
                start, end = (None, None) if isinstance(t0, (list, tuple)) else (t_start, t_end)
            else:
                start, end = t_start - origin, t_end - origin
            return {"start": num(start), "end": num(end), "samples": int(n), "start_stamp": num(t_start),
                    "end_stamp": num(t_end)}

        origins = list(t0) if isinstance(t0, (list, tuple)) else [t0] * len(self.series)

        def segment_origins():
            # the first IMU stamp of each validation segment's recording: a recording's segments
            # follow each other in series order, the first starting at its series' first sample
            v = self.validation
            if t0 is None or v is None or v.segment_times is None:
                return None
            if not isinstance(t0, (list, tuple)):
                return [t0] * len(v.segment_times)
            firsts = [float(s.t[0]) for s in self.series]
            out, i = [], -1
            for a, _ in v.segment_times:
                if i + 1 < len(firsts) and float(a) == firsts[i + 1]:
                    i += 1
                out.append(origins[max(i, 0)])
            return out

        scale = float(np.trace(self.inertia)) / 3 if np.all(np.isfinite(self.inertia)) else None
        weak = [describe_direction(s, D, scale=scale, weakest=i == 0, undetermined=gone)
                for i, (s, D) in enumerate(self.weak_directions)]
        pm = ex.principal_dict()
        units = dict(UNITS) if t0 is not None else UNITS | dict.fromkeys(
            ("window.start", "window.end", "validation.segments.start", "validation.segments.end"), "s, stamps")
        return {
            "schema": INERTIA_SCHEMA, "schema_version": INERTIA_SCHEMA_VERSION, "units": units,
            "mass": float(self.mass),
            "center_of_gravity": [float(x) for x in self.center_of_gravity],
            "validation": None if self.validation is None else self.validation.to_dict(segment_origins()),
            "inertia_about_cg": {k: entry(k, v) for k, v in zip(KEYS, theta)},
            "inertia_std": {k: entry(k, v) for k, v in zip(KEYS, self.inertia_std)},
            "inertia_crb_std": per_key(self.crb_std),
            "frame": "body",
            "convention": "; ".join(convention_lines(AXES["body"])),
            "products_of_inertia": ex.products(),
            "inertia_about_origin": {k: ex.entry(k, "origin") for k in KEYS},
            "uncertainty": self.uncertainty,
            "residual_excess": None if self.residual_excess is None else [num(x) for x in self.residual_excess],
            "weight_surplus": num(self.weight_surplus),
            "inertia_sandwich_std": per_key(self.sandwich_std),
            "bias_correction": per_key(self.bias_correction),
            "bias_correction_applied": bool(self.bias_applied),
            "errors_in_variables": None if self.errors_in_variables is None else {
                "noise_share": num(self.errors_in_variables.share),
                "direction": {k: num(x) for k, x in zip(KEYS, self.errors_in_variables.direction)},
                "correction_std": per_key(self.errors_in_variables.correction_std),
                "realisations": int(self.errors_in_variables.count)},
            "replay_sigma_factor": num(self.replay_factor),
            "sensor_noise": None if self.sensor_noise is None else {k: num(v) for k, v in self.sensor_noise.items()},
            "principal_moments": None if pm is None else pm["moments"],
            "principal_axes": None if pm is None else pm["axes"],
            "physically_consistent": bool(np.all(np.isfinite(self.inertia)) and physically_consistent(self.inertia)),
            "correlation": {"keys": list(KEYS),
                            "matrix": [[None if not np.isfinite(x) else round(float(x), 4) for x in row]
                                       for row in self.correlation]},
            "weakly_determined": weak,
            "window": window(self.t_start, self.t_end, self.n_samples, None if isinstance(t0, (list, tuple)) else t0),
            "band_hz": [num(self.band_hz[0]), num(self.band_hz[1])],
            "residual_rms_rad_s": [num(x) for x in self.residual_rms],
            "fit_r2": [num(x) for x in self.fit_r2],
            "method": self.method,
            "warnings": list(self.warnings),
        } | ({"rigid_body": self.rigid_body, "diagnosis": with_effect_units(self.diagnosis)}
             if self.diagnosis is not None else {}) \
          | ({"recordings": [{"label": s.label, "window": window(float(s.t[0]), float(s.t[-1]), len(s.t), o),
                               "band_hz": [float(s.band_hz[0]), float(s.band_hz[1])],
                               "residual_rms_rad_s": [float(x) for x in np.sqrt(np.mean(s.residual**2, 0))]}
                              for s, o in zip(self.series, origins)]} if len(self.series) > 1 else {})


DIRECTION_LEVELS = ((1e-3, "well determined"), (1e-2, "fairly well determined"))
"""Words for a tensor direction by its relative σ (σ over tr J / 3, :func:`weak_directions`):
below each limit its words; from the last limit up to :data:`DIRECTION_NOT_DETERMINED`
"weakly determined"; beyond it "not determined"."""
DIRECTION_NOT_DETERMINED = 0.10
"""Relative σ from which a direction is "not determined": validation.REL_STD_LIMIT (a test holds
them equal; identification cannot import validation, which imports it)."""


def direction_level(rel_std: float) -> str:
    """"well determined", "fairly well determined", "weakly determined" or "not determined" for a
    direction of relative σ ``rel_std`` (:data:`DIRECTION_LEVELS`, :data:`DIRECTION_NOT_DETERMINED`)."""
    if not np.isfinite(rel_std) or rel_std >= DIRECTION_NOT_DETERMINED:
        return "not determined"
    return next((words for limit, words in DIRECTION_LEVELS if rel_std < limit), "weakly determined")


def describe_direction(rel_std: float, D: np.ndarray, scale: float | None = None, weakest: bool = False,
                       undetermined=()) -> dict:
    """A tensor direction (of :func:`weak_directions`) in words a lab engineer reads — the one
    wording of the CLI, the JSON and the report.

    rel_std: σ along the unit direction over tr J / 3; D (3,3) unit-norm direction; scale: tr J / 3
    kg·m² (for σ in kg·m²; None: relative only); weakest: this is the weakest direction (only it
    is called "the most weakly determined"); undetermined: entries the validation did not
    determine (a direction mostly along one of them is "not determined").

    Returns {"relative_std", "std" (kg·m² or None), "direction" {KEYS: coefficient, tensor
    entries}, "mostly" (the entry with the largest share), "combination" (e.g. "+0.96 Izz −0.29
    Ixz": products with the vehicle-dynamics sign, the main entry positive), "pure" (one entry
    holds over 90 % of it), "level" (:func:`direction_level`), "weakest", "text"}."""
    theta = from_tensor(D)
    share = theta * np.sqrt([1, 2, 2, 1, 2, 1])     # a product appears twice in the unit (Frobenius) tensor
    order = np.argsort(-np.abs(share))
    if (VEHICLE_SIGN * share)[order[0]] < 0:        # a direction's sign is arbitrary: its main entry positive
        theta, share = -theta, -share
    shown = VEHICLE_SIGN * share
    main = KEYS[order[0]]
    comb = " ".join(f"{shown[i]:+.2f} {ENTRY_NAMES[KEYS[i]].split()[-1]}" for i in order
                    if abs(share[i]) >= 0.2).replace("-", "−")
    pure = abs(share[order[0]]) > 0.9
    what = ENTRY_NAMES[main] if pure else f"{comb} (mostly {ENTRY_NAMES[main]})"
    level = "not determined" if main in undetermined else direction_level(rel_std)
    std = None if scale is None or not np.isfinite(rel_std) else float(rel_std * scale)
    size = (f"σ {std:.3g} kg·m², " if std is not None else "σ ") + f"{100 * rel_std:.3g} % of tr J/3"
    text = (f"the most weakly determined combination is {what}: {level} ({size})" if weakest
            else f"{what if pure else 'the combination ' + what} is {level} ({size})")
    return {"relative_std": finite_or_none(rel_std), "std": std,
            "direction": {k: round(float(v), 3) for k, v in zip(KEYS, theta)}, "mostly": main,
            "combination": comb, "pure": bool(pure), "level": level, "weakest": bool(weakest),
            "text": text[0].upper() + text[1:]}


def _uniform(t: np.ndarray, what: str) -> float:
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


def cumulative_integral(x: np.ndarray, t: np.ndarray, steps=None) -> np.ndarray:
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
        return cumulative_simpson(x, x=t, axis=0, initial=0.0)
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
    from scipy.signal import welch
    nper = int(min(len(omega), 2 ** np.ceil(np.log2(20 * fs))))
    f, P = welch(omega, fs=fs, nperseg=nper, axis=0)
    P = P.sum(1)
    floor = np.median(P[f > fs / 4])
    sig = np.nonzero((P > max(100 * floor, 1e-4 * P[f > 0.05].max())) & (f > 0.05))[0]
    if len(sig) == 0:
        return max(f_min, 0.25), min(5.0, 0.4 * fs)
    lo = max(f_min, 0.6 * f[sig[0]])
    return lo, min(0.4 * fs, max(1.5 * f[sig[-1]], 2.0 * lo))


def _batch_means_meat(A3: np.ndarray, resid: np.ndarray, nb: int) -> np.ndarray:
    """(p,p) "meat" of the batch-means sandwich: Σ over blocks of nb samples of (Σ AᵀR)(Σ AᵀR)ᵀ,
    scaled to all samples.  A3: (N,3,p) Jacobian of the prediction; resid: (N,3)."""
    p = A3.shape[2]
    H = np.einsum("nik,ni->nk", A3, resid)
    nblocks = len(H) // nb
    if nblocks < 8:
        nb = max(1, len(H) // 8)
        nblocks = len(H) // nb
    S = H[: nblocks * nb].reshape(nblocks, nb, p).sum(1)
    return S.T @ S * (len(H) / (nblocks * nb))


def gyro_noise_sigma(omega: np.ndarray, fs: float) -> float:
    """White-noise σ (rad/s) of the gyro from the flat top of its Welch spectrum (scipy)."""
    from scipy.signal import welch
    f, P = welch(omega, fs=fs, nperseg=min(len(omega), 1024), axis=0)
    return float(np.sqrt(np.median(P[f > fs / 4].mean(1)) * fs / 2))


@dataclass
class Segment:
    """One stretch of data prepared for the fit (band-passed output and regressors)."""

    t: np.ndarray          # (N,) s
    w: np.ndarray          # (N,3) rad/s raw body-axis gyro
    fs: float              # Hz
    band: tuple[float, float]
    filt: object           # the zero-phase band-pass of this segment
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
    dt = _uniform(t, what)
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
    filt = lambda x: sosfiltfilt(sos, x, axis=0)  # noqa: E731
    y = filt(w)
    if np.sqrt(np.mean(y**2)) < 1e-5:
        raise IdentificationError(f"{what}: the body hardly rotated in the window "
                                  f"(band-passed gyro RMS {np.sqrt(np.mean(y**2)):.2e} rad/s)")
    E = basis()
    steps = step_indices(torque)   # stepped inputs (the thesis's pulses): no interpolation across them
    integ = lambda x: filt(cumulative_integral(x, t, steps))  # noqa: E731
    IM = integ(np.asarray(torque, float))
    # the gyroscopic term is linear in the entries: ω×(Jω) = Σ_m j_m ω×(E_m ω)
    G = np.stack([integ(np.cross(w, w @ Em.T)) for Em in E])  # (6,N,3)
    return Segment(t, w, fs, (lo, hi), filt, y, IM, G, label)


def fit_segments(rig: Rig, segs: list[Segment], block_s: float = 4.0, consistent: bool = True,
                 noise: list[NoiseRealisations] | None = None) -> InertiaResult:
    """The two-stage fit of :func:`identify_inertia` over one or more prepared segments
    (:func:`prepare_segment`) with a common tensor: residuals and Jacobians stacked,
    sandwich meat and Cramér–Rao information summed over the segments (they are independent).

    noise: one :class:`~rig_identification.estimation.errors_in_variables.NoiseRealisations` per segment (the regressor's
    and output's first-order noise, from replays with fresh noise): the least-squares
    estimate is then compensated for the noise in its input (bias-compensated least squares,
    :func:`compensate`; ``result.errors_in_variables``), and the result's series carry the
    noise realisations of the Jacobian and residual.  When the noise dominates a direction
    (share ≥ 1) the compensation is impossible: the least-squares estimate is kept with a
    warning and ``errors_in_variables.share`` says it.  Raises :class:`IdentificationError`
    for mismatched noise."""
    from scipy.optimize import least_squares

    E = basis()

    def predict(j, s):
        P = np.linalg.inv(to_tensor(j))
        u = s.IM - np.einsum("m,mni->ni", j, s.G)
        return P, P @ u.T

    # stage 1: linear in P
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
    method = "prediction error: band-limited output error of the integrated Newton–Euler equation"
    # per-axis residual scale, pooled over the segments (the same gyro)
    sigma = np.sqrt(np.mean(np.concatenate([(s.y - predict(j, s)[1].T) ** 2 for s in segs]), axis=0))

    def jac_entries(j, P, yhat, s):
        # d yhat / d j_k = -P (E_k yhat + G_k)   -> (N,3,6)
        return -np.einsum("ij,knj->nik", P, np.einsum("kij,jn->kni", E, yhat) + s.G)

    if consistent:
        def fun(th):
            jj, _ = consistent_from_params(th)
            return np.concatenate([((s.y - predict(jj, s)[1].T) / sigma).ravel() for s in segs])

        def jac(th):
            jj, dj = consistent_from_params(th)
            out = []
            for s in segs:
                Pm, yh = predict(jj, s)
                out.append(-(jac_entries(jj, Pm, yh, s) / sigma[None, :, None]).reshape(-1, 6) @ dj)
            return np.concatenate(out)

        sol = least_squares(fun, params_from_consistent(to_tensor(j)), jac=jac, method="lm",
                            xtol=1e-12, ftol=1e-12)
        j, _ = consistent_from_params(sol.x)
        method += "; Levenberg–Marquardt on a physically consistent parametrisation"
    comp = None
    eiv_warnings = []
    if noise is not None:
        if len(noise) != len(segs) or any(nz.du.shape[1:] != s.y.shape for nz, s in zip(noise, segs)):
            raise IdentificationError("identifier: one noise realisation set (K,N,3) per segment is needed")
        j, comp, eiv_warnings = compensate(segs, j, sigma, noise, consistent)
        if not eiv_warnings:
            method += (f"; compensated for the noise in its input (bias-compensated least squares, "
                       f"{comp.count} noise realisations)")
    if len(segs) > 1:
        method += f"; joint fit of {len(segs)} recordings with a common tensor"
    J = to_tensor(j)
    yhats, resids, A3s = [], [], []
    for s in segs:
        P, yhat = predict(j, s)
        yhats.append(yhat.T)
        resids.append(s.y - yhat.T)
        A3s.append(jac_entries(j, P, yhat, s))
    # sandwich covariance: bread from all segments, meat summed over the independent segments
    As = [A3.reshape(-1, 6) for A3 in A3s]
    # A.T @ A of one buffer: BLAS syrk.  Pseudo-inverse: a fit that ran off to J → ∞ along a
    # direction (the noise swamped it: a replay of a weakly excited rig, bench_any_rig's seed
    # 21014) has no information there; its covariance is then singular along it, which the
    # validation reports as not determined (validation.DEGENERATE), instead of a LinAlgError
    # ending the command
    B = np.linalg.pinv(sum(A.T @ A for A in As), rcond=1e-13, hermitian=True)
    meat = sum(_batch_means_meat(A3, r, max(1, int(round(block_s * s.fs)))) for A3, r, s in zip(A3s, resids, segs))
    cov_J = B @ meat @ B
    std = np.sqrt(np.clip(np.diag(cov_J), 0, None))
    # predicted covariance from the gyro's white noise alone (the Cramér–Rao bound of
    # this estimator for the recording's excitation): σ² B⁻¹ (FA)ᵀ(FA) B⁻¹, F = prefilter
    sgs, crb = [], 0
    for A3, s in zip(A3s, segs):
        FA = s.filt(A3.reshape(len(s.t), -1)).reshape(-1, 6)
        sg = gyro_noise_sigma(s.w, s.fs)
        sgs.append(sg)
        crb = crb + sg**2 * B @ (FA.T @ FA) @ B
    resid = np.concatenate(resids)
    y_all = np.concatenate([s.y for s in segs])
    res_rms = np.sqrt(np.mean(resid**2, axis=0))
    r2 = 1 - np.sum(resid**2, 0) / np.sum(y_all**2, 0)
    warnings = list(eiv_warnings)
    if not physically_consistent(J):
        warnings.append("the identified tensor is not physically consistent (not positive definite "
                        "or violates the triangle inequality): the window does not excite the body enough")
    t0 = min(float(s.t[0]) for s in segs)
    t1 = max(float(s.t[-1]) for s in segs)
    band = (min(s.band[0] for s in segs), max(s.band[1] for s in segs))
    res = InertiaResult(rig.mass, rig.require_cg().copy(), J, std, cov_J, t0, t1, int(sum(len(s.t) for s in segs)),
                        band, res_rms, r2, weak_directions(J, cov_J), method=method, warnings=warnings)
    res.crb_std = np.sqrt(np.clip(np.diag(crb), 0, None))
    res.gyro_noise = sgs[0] if len(sgs) == 1 else float(np.sqrt(np.mean(np.square(sgs))))
    res.series = [FitSeries(s.t, s.y, yh, s.band, s.label, A3, sigma.copy(), s.fs)
                  for s, yh, A3 in zip(segs, yhats, A3s)]
    if comp is not None:
        res.errors_in_variables = comp
        P = np.linalg.inv(J)
        for ser, nz in zip(res.series, noise):
            dyh = nz.du @ P.T                                         # (K,N,3) P Δu
            ser.noise_jacobian = -np.einsum("ij,knjq->kniq", P, np.einsum("qjl,knl->knjq", E, dyh))
            ser.noise_residual = nz.dy - dyh
    return res


def weak_directions(J: np.ndarray, cov_J: np.ndarray, n: int = 2) -> list:
    """The ``n`` most weakly determined tensor combinations: eigen-directions of the
    covariance (equivalently of the information matrix, its inverse) in the Frobenius
    metric of the tensor, largest std first.  Returns [(std / (tr J / 3), (3,3) unit-norm
    tensor direction)]; ``n=6`` gives all of them; [] when J or the covariance is not finite.
    :func:`describe_direction` puts one in words."""
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(cov_J))):
        return []
    scale = np.trace(J) / 3
    Dm = np.diag([1, np.sqrt(2), np.sqrt(2), 1, np.sqrt(2), 1])  # Frobenius metric on the entries
    evals, evecs = np.linalg.eigh(Dm @ cov_J @ Dm)
    weak = []
    for lam, vec in sorted(zip(evals, evecs.T), key=lambda z: -z[0])[:n]:
        D = to_tensor(np.linalg.solve(Dm, vec))
        D /= np.linalg.norm(D)
        weak.append((float(np.sqrt(max(lam, 0)) / scale), D))
    return weak


def identify_inertia(rig: Rig, t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray,
                     band_hz: tuple[float, float] | None = None, block_s: float = 4.0,
                     consistent: bool = True) -> InertiaResult:
    """Fit the inertia tensor about the CG (see module docstring).

    Two stages, no initial guess: (1) linear least squares in P = J⁻¹ (the gyroscopic
    term evaluated with the previous iterate, three passes from J = 0); (2) from there,
    Levenberg–Marquardt (scipy ``least_squares``, analytic Jacobian) on the physically
    consistent parametrisation :func:`consistent_from_params`, with the gyroscopic
    term of the current J — the prediction-error estimate proper.

    t: (N,) s, uniformly sampled (a gap raises).  omega_body: (N,3) rad/s, body axes
    (gyro rotated from IMU axes).  torque: (N,3) N·m about the CG, body axes.
    band_hz: pass band of the zero-phase Butterworth prefilter applied to both sides
    (default: :func:`auto_band` of the gyro).  consistent: run stage 2.  Streams sampled at
    ≥ 2 × :data:`FIT_RATE` are first decimated to about that rate (zero-phase FIR).
    The result's ``series`` holds the band-passed measured and predicted ω.
    Raises :class:`IdentificationError` for too little data, gaps or no motion.
    """
    seg = prepare_segment(t, omega_body, torque, band_hz)
    return fit_segments(rig, [seg], block_s, consistent)


def identify_inertia_joint(rig_list: list[Rig], segments: list, band_hz=None, block_s: float = 4.0,
                           consistent: bool = True, labels: list[str] | None = None) -> InertiaResult:
    """Joint fit of one inertia tensor to several recordings of the same body.

    Each segment (t (N_i,) s uniform, omega_body (N_i,3) rad/s body axes, torque (N_i,3)
    N·m about the CG, body axes) is band-passed and integrated on its own (its own pass
    band, its own integration constant), exactly as in :func:`identify_inertia`; the
    residuals of all segments are stacked and the same two-stage fit run with a common
    tensor.  The residual scale per gyro axis is pooled over the segments (one sensor);
    the sandwich covariance sums the batch-means meat of the independent segments, and
    the Cramér–Rao std sums their white-noise information.  With one segment this is
    :func:`identify_inertia`, number for number.

    rig_list: one Rig per segment (mass and CG of the result from the first; the caller
    checks that the bodies agree, see :func:`~rig_identification.pipeline.offline.identify_recordings`).  band_hz:
    None (auto per segment), one (lo, hi) pair for all, or a list of pairs/None.
    labels: names of the segments (e.g. recording folders), for messages and
    ``result.series``.  Raises :class:`IdentificationError` (also for no segments or
    mismatched list lengths).
    """
    segments = list(segments)
    rig_list = list(rig_list)
    if not segments:
        raise IdentificationError("identifier: no segments to fit")
    if len(rig_list) != len(segments):
        raise IdentificationError(f"identifier: {len(rig_list)} rigs for {len(segments)} segments")
    labels = list(labels) if labels is not None else [f"segment {i + 1}" for i in range(len(segments))]
    if band_hz is None or (len(band_hz) == 2 and np.isscalar(band_hz[0])):
        bands = [band_hz] * len(segments)
    else:
        bands = list(band_hz)
    segs = [prepare_segment(t, w, m, b, what=f"identifier ({lab})", label=lab)
            for (t, w, m), b, lab in zip(segments, bands, labels)]
    return fit_segments(rig_list[0], segs, block_s, consistent)


def identify_inertia_thesis(rig: Rig, t: np.ndarray, omega_body: np.ndarray, torque: np.ndarray,
                            initial_guess: np.ndarray) -> InertiaResult:
    """The thesis's identification, as a baseline (thesis sections 3.3 and 3.5).

    Model: eq. 3.10/3.11 — ``J θ̈ = M`` with the angular velocities as states, *without*
    the gyroscopic term ω × Jω; forward-Euler discretisation (eqs. 3.17–3.21,
    A_d = 1 + T·A, B_d = T·B); one-step-ahead predictor of the measured output
    (eq. 3.25 with C = I): ``ω̂(n+1) = ω(n) + T J⁻¹ M(n)``; prediction errors minimised
    by Levenberg–Marquardt (eq. 3.30) from ``initial_guess`` (6,) tensor entries in
    :data:`KEYS` order, as MATLAB's ``pem`` did.  Covariance: σ² (AᵀA)⁻¹ of the
    white-residual assumption.  t: (N,) s uniform; omega_body (N,3) rad/s; torque (N,3) N·m.
    """
    from scipy.optimize import least_squares

    t = np.asarray(t, float)
    T = _uniform(t, "identifier (thesis model)")
    w = np.asarray(omega_body, float)
    M = np.asarray(torque, float)
    dw = w[1:] - w[:-1]

    def fun(j):
        return (dw - T * M[:-1] @ np.linalg.inv(to_tensor(j)).T).ravel()

    sol = least_squares(fun, np.asarray(initial_guess, float), method="lm", xtol=1e-12, ftol=1e-12)
    J = to_tensor(sol.x)
    A = sol.jac
    resid = sol.fun.reshape(-1, 3)
    dof = max(1, A.shape[0] - 6)
    cov = float(resid.ravel() @ resid.ravel()) / dof * np.linalg.pinv(A.T @ A)
    warnings = [] if physically_consistent(J) else ["the identified tensor is not physically consistent"]
    if not sol.success:
        warnings.append(f"Levenberg–Marquardt did not converge: {sol.message}")
    return InertiaResult(rig.mass, rig.require_cg().copy(), J, np.sqrt(np.clip(np.diag(cov), 0, None)), cov,
                         float(t[0]), float(t[-1]), len(t), (0.0, 0.5 / T), np.sqrt(np.mean(resid**2, 0)),
                         1 - np.sum(resid**2, 0) / np.sum((dw - dw.mean(0)) ** 2, 0), [],
                         method="thesis: eq. 3.11 without gyroscopic terms, forward Euler, one-step "
                                "predictor (3.25), Levenberg–Marquardt from the initial guess",
                         warnings=warnings)


class InertiaIdentifier:
    """Streaming buffer for the identifier node: gyro and generalized wrench samples.

    ``identify(start, end, last)`` fits over a window (absolute stamps in s, or the last
    ``last`` seconds) with :func:`identify_inertia`.  The wrench samples carry the pose
    stamps, i.e. the IMU stamps; the gyro is interpolated to them.
    """

    def __init__(self, rig: Rig, max_seconds: float = 900.0, **fit_params):
        self.rig = rig
        rig.require_cg()
        self.fit_params = fit_params
        self.max_seconds = max_seconds
        self._imu_t: list[float] = []
        self._gyro: list[np.ndarray] = []
        self._w_t: list[float] = []
        self._torque: list[np.ndarray] = []
        self._imu_to_body = rig.imu.rotation

    def add_imu(self, t: float, gyro) -> None:
        if self._imu_t and t <= self._imu_t[-1]:
            raise ValueError(f"IMU stamp {t:.6f} s not after the previous one")
        self._imu_t.append(float(t))
        self._gyro.append(np.asarray(gyro, float))
        self._trim(self._imu_t, self._gyro)

    def add_wrench(self, w) -> None:
        if self._w_t and w.t <= self._w_t[-1]:
            raise ValueError(f"wrench stamp {w.t:.6f} s not after the previous one")
        self._w_t.append(float(w.t))
        self._torque.append(np.asarray(w.torque, float))
        self._trim(self._w_t, self._torque)

    def _trim(self, ts: list, vals: list) -> None:
        if len(ts) > 1000 and ts[-1] - ts[0] > self.max_seconds * 1.1:
            cut = int(np.searchsorted(ts, ts[-1] - self.max_seconds))
            del ts[:cut], vals[:cut]

    @property
    def span(self) -> tuple[float, float] | None:
        if not self._w_t:
            return None
        return self._w_t[0], self._w_t[-1]

    def identify(self, start: float | None = None, end: float | None = None,
                 last: float | None = None) -> InertiaResult:
        if len(self._w_t) < 10 or len(self._imu_t) < 10:
            raise IdentificationError("identifier: no data buffered yet (is the preprocessor running?)")
        tw = np.array(self._w_t)
        lo = tw[0] if start is None else start
        hi = tw[-1] if end is None else end
        if last is not None:
            lo = max(lo, hi - last)
        m = (tw >= lo) & (tw <= hi)
        ti = np.array(self._imu_t)
        m &= (tw >= ti[0]) & (tw <= ti[-1])
        if m.sum() < 10:
            raise IdentificationError(f"identifier: no samples in the window [{lo:.3f}, {hi:.3f}] s")
        g = np.array(self._gyro)
        gyro = np.column_stack([np.interp(tw[m], ti, g[:, k]) for k in range(3)])
        return identify_inertia(self.rig, tw[m], self._imu_to_body.apply(gyro), np.array(self._torque)[m],
                                **self.fit_params)
