"""Offline replay: recording -> tracker -> preprocessor -> identifier (the nodes' core code)."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..diagnosis.selection import body_inertia, corrected, diagnose, with_stiffness
from ..io.export import effect_text
from ..estimation.errors_in_variables import NoiseRealisations, antithetic_realisations
from ..estimation.identification import (KEYS, InertiaResult, fit_segments, from_tensor, identify_inertia, identify_inertia_joint,
                             identify_inertia_thesis, prepare_segment, weak_directions)
from ..estimation.preprocessor import preprocess
from ..estimation.quality import check_motion, check_units, clean_sensors
from ..io.recording import Recording, RecordingError, crop
from ..diagnosis.residuals import unexplained
from ..estimation.tracker_replay import track
from ..estimation.uncertainty import noise_replays, propagated, sensor_noise
from ..io.noise import white_sigma
from ..estimation.propagation import PlanError, combine
from ..estimation.validation import AccelInput, residual_excess, validate, widened_std
from ..estimation.yaw_anchor import YawAnchor, anchor_yaw

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them

REPLAY_PAIRS = 3   # antithetic pairs of replays with fresh noise: the input-noise compensation, a check of σ


def default_initial_guess(rig) -> np.ndarray:
    """A rough tensor (6,) for the thesis model when none is given: the mass spread over
    a box spanned by the body anchors, diagonal (kg·m²)."""
    half = np.ptp(rig.body_anchors, axis=0) / 2 + 0.1
    sx, sy, sz = half**2
    return rig.mass / 3 * np.array([sy + sz, 0.0, 0.0, sx + sz, 0.0, sx + sy])


@dataclass
class PreparedRecording:
    """A recording replayed through the cleaning, the tracker and the preprocessor, cut
    to the fit window: the identifier's input.

    rec: the recording; t (N,) s (absolute stamps, uniform; tracked pose stamps); gyro_body
    (N,3) rad/s, body axes; torque (N,3) N·m about the CG, body axes; force (N,3) N, body
    axes (the generalized force, weight excluded); warnings: the excluded spans etc.
    (the recording's own reader warnings stay in ``rec.warnings``).
    """

    rec: Recording
    t: np.ndarray
    gyro_body: np.ndarray
    torque: np.ndarray
    warnings: list[str] = field(default_factory=list)
    sensors: object = None      # the cleaned SensorData that was tracked
    poses: object = None        # the tracker's PoseTrack over it
    window: tuple = (0.0, 0.0)  # (lo, hi) absolute stamps, s, of the fit window
    force: np.ndarray | None = None
    # the wrench of physics added to the rigid-body model (diagnosis.EffectWrench) on t: torque
    # (N,3) N·m and force (N,3) N, body axes, already in ``torque``/``force``; the replays of
    # refine_uncertainty add them too
    extra_torque: np.ndarray | None = None
    extra_force: np.ndarray | None = None
    # refine_uncertainty's replays with fresh noise (antithetic pair): (torque, force) on t, for
    # the validation's noise of channels predicted from the wrench (validation.AccelInput)
    replays: list = field(default_factory=list)
    yaw_anchor: YawAnchor | None = None     # what the yaw anchoring did (yaw_anchor.anchor_yaw)


@dataclass(frozen=True)
class Replay:
    """One pass of tracker, yaw anchoring and preprocessor over a recording
    (:func:`replay_window`): poses (the whole :class:`~rig_identification.estimation.tracker.PoseTrack`); t (N,) s the
    window's pose stamps; gyro_body (N,3) rad/s; torque (N,3) N·m about the CG; force (N,3)
    N, body axes; anchor (:class:`~rig_identification.estimation.yaw_anchor.YawAnchor`)."""

    poses: object
    t: np.ndarray
    gyro_body: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    anchor: YawAnchor


def with_effect_wrench(prep: PreparedRecording, effect) -> PreparedRecording:
    """``prep`` with the wrench of the diagnosed physics (:class:`~rig_identification.diagnosis.selection.EffectWrench`,
    interpolated onto ``prep.t``) added to the measured generalized wrench: the rigid-body
    identifier then fits the model extended by it (Newton–Euler with the effect's moment
    and force)."""
    tq, fc = effect.at(prep.t)
    return replace(prep, torque=prep.torque + tq, force=None if prep.force is None else prep.force + fc,
                   extra_torque=tq, extra_force=fc)


def replay_window(rig, s, lo: float, hi: float) -> Replay:
    """Tracker -> yaw anchoring (:func:`~rig_identification.estimation.yaw_anchor.anchor_yaw`: where the cables leave the
    yaw free) -> preprocessor over the cleaned sensors ``s``; the window [lo, hi] (absolute
    stamps, s).  The one replay every fit of a recording makes (the identification, the
    replays of :func:`refine_uncertainty`).  Returns a :class:`Replay`."""
    poses, anchor = anchor_yaw(rig, track(rig, s), s, lo, hi)
    wrench = preprocess(rig, poses, s)
    m = (wrench.t >= lo) & (wrench.t <= hi)
    gyro = s.imu.interp(wrench.t[m])[:, :3]
    return Replay(poses, wrench.t[m], rig.imu.rotation.apply(gyro), wrench.torque[m], wrench.force[m], anchor)


def prepare_recording(rec: Recording, start: float | None = None, end: float | None = None,
                      settle: float = 5.0) -> PreparedRecording:
    """Clean a dynamic recording, run the tracker and the preprocessor, cut the window.

    start/end: window in seconds from the first IMU stamp (default: the whole
    recording after ``settle`` s, the tracker's convergence time, at most a tenth of
    the recording).  Raises :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError` (no CG in rig.yaml),
    :class:`~rig_identification.estimation.tracker.TrackerError`.
    """
    rig, s = rec.rig, rec.sensors
    rig.require_cg()
    if rig.exciter is not None and s.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no "
                             "/rig/exciter/wrench topic")
    check_units(rec)
    warnings: list[str] = []
    s = clean_sensors(rec, warnings)
    check_motion(rec, s)
    t0 = rec.sensors.t_start  # --start/--end count from the recording's first IMU sample
    settle = min(settle, 0.1 * (s.t_end - s.t_start))
    lo = s.t_start + settle if start is None else max(t0 + start, s.t_start + settle)
    hi = s.t_end if end is None else min(t0 + end, s.t_end)
    for w in warnings:
        log.warning(w)
    log.info("tracking the pose and computing the generalized wrench")
    r = replay_window(rig, s, lo, hi)
    poses, t, gyro_body, torque, force = r.poses, r.t, r.gyro_body, r.torque, r.force
    if r.anchor.applied:
        log.info("yaw anchored by the moment balance (%.2f mrad): the cables' lengths leave it free",
                 1e3 * r.anchor.offset)
    if len(t) < 10:
        raise RecordingError(f"{rec.path}: no samples in the window [{lo - t0:.1f}, {hi - t0:.1f}] s")
    return PreparedRecording(rec, t, gyro_body, torque, warnings, s, poses, (lo, hi), force, yaw_anchor=r.anchor)


MODEL_ERROR_RATIO = 2.0
"""Fit residual RMS over the one the sensors' noise predicts beyond which the residual is
model error.  Clean simulated recordings: 1.00–1.31 on 200 noisy 120 s replays of thesis
case 16; up to 1.47 on a 35 s one at 200 Hz (the tracker's start-up misfit, which the noise
does not explain, weighs more in a short run); the damped reference recording: 9.8."""


WEIGHT_TOLERANCE = 1e-3
"""Relative difference between the load cells' mean vertical force and rig.yaml's weight
beyond which the fit's input is not the body rig.yaml describes (a cable's mass hanging
outside its load cell, a load cell's gain, a wrong body.mass): about a vehicle scale's
accuracy.  Clean simulated recordings and the clean references: below 1e-4."""


def force_weight_surplus(rig, quaternion: np.ndarray, force: np.ndarray) -> float:
    """The mean vertical force of the generalized force ``force`` (N,3) N, body axes (the
    load cells' and the exciter's, weight excluded: :func:`~rig_identification.estimation.preprocessor.generalized_wrench`),
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


def refine_uncertainty(preps: list[PreparedRecording], result: InertiaResult, seed: int = 0) -> InertiaResult:
    """Compensate a prediction-error estimate for the noise in its input and give it the σ
    that the sensors' noise causes along the recordings' trajectories (:mod:`rig_identification.estimation.uncertainty`).

    preps: the prepared recording(s) the result was fitted to (one, or several for a joint
    fit, in the order of ``result.series``).  The white-noise σ of every stream is
    estimated from each recording (:func:`~rig_identification.estimation.uncertainty.sensor_noise`); tracker,
    preprocessor and identifier (same windows and bands) are re-run with
    :data:`REPLAY_PAIRS` antithetic pairs of fresh noise at those levels
    (:func:`~rig_identification.estimation.uncertainty.noise_replays`).  Their regressors and outputs are realisations of
    the noise the chain puts into the fit — the gyro's through the tracked pose into the
    moment included — and the fit is re-solved with the noise's second moments removed from
    its normal equations (bias-compensated least squares, :mod:`rig_identification.estimation.errors_in_variables`;
    ``errors_in_variables``; ``bias_correction`` the least-squares estimate's bias it removed).  The covariance is the
    linearised propagation of that noise through the same chain
    (:func:`~rig_identification.estimation.uncertainty.propagated`, recordings combined by :func:`~rig_identification.estimation.propagation.combine`),
    mapped onto the compensated estimate, with the compensation's own jackknife σ in
    quadrature: ``crb_std`` holds it, and ``inertia_std`` and ``covariance`` too unless the
    fit's residual RMS exceeds the one the noise predicts (the replays' residual
    realisations, over the series' interior:
    :func:`~rig_identification.estimation.validation.residual_excess`) by more than :data:`MODEL_ERROR_RATIO` on a gyro axis
    (``residual_excess``): that is model error, and the identifier's sandwich σ (from the
    residuals; always in ``sandwich_std``) is kept.  If the propagation fails (too little
    motion) the result keeps the sandwich σ with a warning.  Returns ``result``, updated in
    place.
    """

    rigs = [p.rec.rig for p in preps]
    bands = [tuple(s.band_hz) for s in result.series] if len(result.series) == len(preps) else \
        [tuple(result.band_hz)] * len(preps)
    labels = [s.label for s in result.series] if len(result.series) == len(preps) else [""] * len(preps)
    est = [sensor_noise(r, p.sensors) for r, p in zip(rigs, preps)]
    noises = [e[0] for e in est]
    result.sensor_noise = {k: float(np.sqrt(np.mean([n[k] ** 2 for n in noises]))) for k in noises[0]}
    result.sandwich_std = result.inertia_std.copy()
    theta = from_tensor(result.inertia)
    logs: list[list] = [[] for _ in preps]   # each replay's fit input (u, y), in call order (+m, −m, …)

    def replay(i, r, s, p):
        rp = replay_window(r, s, *p.window)
        t, gyro, torque, force = rp.t, rp.gyro_body, rp.torque, rp.force
        if p.extra_torque is not None and len(t) == len(p.t):
            torque, force = torque + p.extra_torque, force + p.extra_force
        seg = prepare_segment(t, gyro, torque, bands[i], label=labels[i])
        same = len(t) == len(p.t)
        if same:
            p.replays.append((torque, force))
            del p.replays[:-2]   # the last antithetic pair is all the validation uses (memory)
        logs[i].append(fit_input(seg, theta) if same else None)
        return seg

    def fit(sensor_list):
        segs = [replay(i, r, s, p) for i, (r, s, p) in enumerate(zip(rigs, sensor_list, preps))]
        return from_tensor(fit_segments(rigs[0], segs).inertia)

    log.info("σ: %d replays with fresh sensor noise", 2 * REPLAY_PAIRS)
    replays = noise_replays(fit, theta, [p.sensors for p in preps], noises, seed, pairs=REPLAY_PAIRS)
    noise = noise_realisations(logs)
    if noise is not None:
        log.info("compensating the fit for the noise in its input (errors in variables)")
        base = [prepare_segment(p.t, p.gyro_body, p.torque, b, label=lab) for p, b, lab in zip(preps, bands, labels)]
        comp = fit_segments(rigs[0], base, noise=noise)
        result.inertia, result.residual_rms, result.fit_r2 = comp.inertia, comp.residual_rms, comp.fit_r2
        result.series, result.method = comp.series, comp.method
        result.inertia_std, result.covariance = comp.inertia_std, comp.covariance
        result.sandwich_std = comp.inertia_std.copy()
        result.errors_in_variables = comp.errors_in_variables
        result.warnings.extend(comp.warnings)
        result.bias_correction = -comp.errors_in_variables.correction   # the least-squares bias, removed
        result.bias_applied = not comp.warnings
    log.info("propagating the sensor noise")
    try:
        pred = combine([propagated(r, p.poses, p.sensors, p.t, result.inertia, b, n, rt)
                        for r, p, b, (n, rt) in zip(rigs, preps, bands, est)])
    except (PlanError, np.linalg.LinAlgError, ValueError) as e:
        result.warnings.append(f"noise propagation failed ({e}); σ from the fit's residuals (sandwich)")
        return result
    cov = pred.covariance
    eiv = result.errors_in_variables
    if eiv is not None and result.bias_applied:
        # the same noise moves the compensated estimate by G times the least-squares one; the
        # finite number of realisations adds the jackknife σ of the correction
        cov = eiv.sensitivity @ cov @ eiv.sensitivity.T + np.diag(np.nan_to_num(eiv.correction_std) ** 2)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    result.crb_std = std.copy()
    # the linearised propagation checked against the replays' own spread (their Birge ratio
    # over 6 × REPLAY_PAIRS degrees of freedom): where the replays spread more, σ follows them —
    # a tracker or rig the linearisation misses (a 3-cable rig: 1.47 over 6 pairs, 1.3–1.5 in
    # Monte Carlo over 8 recordings); never narrower than the propagation
    factor, dof = replays.sigma_factor(pred.covariance)
    if factor > 1.0:
        std = std * factor
        cov = cov * factor**2
        result.replay_factor = factor
    # the residual over the one the noise leaves at the fitted tensor: the replays' residual
    # realisations (every path of the noise, the input's included) over the series' interior,
    # as the validation's residual_level measures it (one rule: a clean 180 s recording at 1 kHz
    # had 8.5x on gyro y over the whole window, the band-pass's edge transients, 1.03x inside,
    # verdict ok, yet its σ became the sandwich's and the diagnosis ran); else the prediction
    r = residual_excess(result.series)
    if r is None:
        r = np.asarray(result.residual_rms) / pred.residual_rms
    result.residual_excess = r
    if np.max(r) > MODEL_ERROR_RATIO:
        # the residual is not the noise: model error, whose effect on the estimate the
        # residuals themselves (the sandwich) measure
        result.uncertainty = "sandwich (model error)"
    else:
        result.inertia_std = std
        result.covariance = cov
        result.uncertainty = "propagated sensor noise" + (
            f" (widened {result.replay_factor:.2f}× to the spread of replays with fresh noise)"
            if result.replay_factor else "")
    result.weak_directions = weak_directions(result.inertia, result.covariance)
    return result


def fit_input(seg, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fit's regressor and output of a prepared segment
    (:func:`~rig_identification.estimation.identification.prepare_segment`): u (N,3) N·m·s, the band-passed
    ``∫(M − ω × Jω)`` with the gyroscopic term at the entries ``theta`` (6,) kg·m² (the
    least-squares estimate; the measured ω in it carries the gyro's noise into the input too),
    and y (N,3) rad/s, the band-passed gyro."""
    return seg.IM - np.einsum("m,mni->ni", theta, seg.G), seg.y


def noise_realisations(logs: list[list]) -> list[NoiseRealisations] | None:
    """The :class:`~rig_identification.estimation.errors_in_variables.NoiseRealisations` of each recording from its
    replays' fit inputs (``logs[i]``: :func:`fit_input`'s (u, y) in call order +m₁, −m₁, +m₂, …;
    None for a replay whose window came out with another length); None when some recording
    has no complete pair."""
    out = []
    for lg in logs:
        pairs = [(a, b) for a, b in zip(lg[0::2], lg[1::2]) if a is not None and b is not None]
        if not pairs:
            return None
        out.append(antithetic_realisations([a[0] for a, _ in pairs], [b[0] for _, b in pairs],
                                           [a[1] for a, _ in pairs], [b[1] for _, b in pairs]))
    return out


def identify_recording(rec: Recording, start: float | None = None, end: float | None = None,
                       settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                       model: str = "pem", initial_guess=None, refine: bool = True,
                       effect_wrench=None) -> InertiaResult:
    """Identify the inertia tensor of a dynamic recording.

    start/end/settle: the window, see :func:`prepare_recording`.  model: ``"pem"`` (ours;
    with ``refine``, :func:`refine_uncertainty`: compensated for the noise in its input, σ
    propagated from the estimated sensor noise — about three times the work of the plain fit)
    or ``"thesis"`` (the thesis's model and estimator,
    :func:`~rig_identification.estimation.identification.identify_inertia_thesis`, from
    ``initial_guess`` (6,) tensor entries or :func:`default_initial_guess`).  effect_wrench:
    physics added to the model (:class:`~rig_identification.diagnosis.selection.EffectWrench`, :func:`with_effect_wrench`).
    Every fit is validated (:func:`validate_fit`: ``result.validation``).  Raises
    :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError`,
    :class:`~rig_identification.estimation.identification.IdentificationError`.
    """
    prep = prepare_recording(rec, start, end, settle)
    if effect_wrench is not None:
        prep = with_effect_wrench(prep, effect_wrench)
    rig = rec.rig
    if model == "thesis":
        guess = default_initial_guess(rig) if initial_guess is None else np.asarray(initial_guess, float)
        result = identify_inertia_thesis(rig, prep.t, prep.gyro_body, prep.torque, guess)
    elif model == "pem":
        log.info("fitting the inertia tensor (prediction error, %.0f s of data)", prep.t[-1] - prep.t[0])
        try:
            result = identify_inertia(rig, prep.t, prep.gyro_body, prep.torque, band_hz=band_hz)
        except np.linalg.LinAlgError as e:
            result = unidentified(rig, prep, f"the fit's normal equations are singular ({e})")
        if refine and np.all(np.isfinite(result.inertia)):
            refine_uncertainty([prep], result)
    else:
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    result.warnings[:0] = rec.warnings + prep.warnings
    result.weight_surplus = weight_surplus(prep)
    validate_fit([prep], result)
    note = weight_warning(result.weight_surplus, rig)
    if note is not None:
        result.warnings.append(note)
    return result


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


def unidentified(rig, prep: PreparedRecording, reason: str) -> InertiaResult:
    """The result of a fit that could not be made: every entry NaN (reported as null, verdict
    ``not_identifiable``), ``reason`` as a warning."""
    nan = np.full(6, np.nan)
    res = InertiaResult(rig.mass, rig.require_cg().copy(), np.full((3, 3), np.nan), nan, np.full((6, 6), np.nan),
                        float(prep.t[0]), float(prep.t[-1]), len(prep.t), (np.nan, np.nan), np.full(3, np.nan),
                        np.full(3, np.nan), warnings=[reason])
    return res


def accel_inputs(preps: list[PreparedRecording], result: InertiaResult) -> list[AccelInput]:
    """The accelerometer check's inputs (:class:`~rig_identification.estimation.validation.AccelInput`) of each prepared
    recording: its fit window, the gyro, torque and generalized force of the replay, the
    measured specific force turned to body axes, the accelerometer's estimated noise."""
    out = []
    bands = [s.band_hz for s in result.series] if len(result.series) == len(preps) else [result.band_hz] * len(preps)
    for p, band in zip(preps, bands):
        out.append(accel_input(p.rec.rig, p.t, p.gyro_body, p.torque, p.force, p.sensors.imu.interp(p.t)[:, 3:6],
                               white_sigma(p.sensors.imu.data[:, 3:6]), band,
                               tuple(p.replays[-2:]) if len(p.replays) >= 2 else ()))
    return out


def accel_input(rig, t: np.ndarray, gyro_body: np.ndarray, torque: np.ndarray, force: np.ndarray,
                accel_imu: np.ndarray, accel_noise: float, band_hz, replays: tuple = ()) -> AccelInput:
    """The accelerometer check's input (:class:`~rig_identification.estimation.validation.AccelInput`) of one fit window:
    t (N,) s the fit's stamps; gyro_body (N,3) rad/s, torque (N,3) N·m about the CG and force
    (N,3) N (generalized, weight excluded), body axes, at t; accel_imu (N,3) m/s² the measured
    specific force at t, IMU axes (turned to body axes here); accel_noise m/s² its white σ
    (:func:`~rig_identification.io.noise.white_sigma`); band_hz the fit's band; replays: see AccelInput.  Used by
    :func:`accel_inputs` and by the identifier node."""
    return AccelInput(t, gyro_body, torque, force, rig.imu.rotation.apply(accel_imu), rig.mass,
                      rig.imu.position - rig.require_cg(), tuple(band_hz), float(accel_noise), tuple(replays))


def validate_fit(preps: list[PreparedRecording], result: InertiaResult) -> InertiaResult:
    """Model validation of the fit (:func:`~rig_identification.estimation.validation.validate`): ``result.validation``.
    When a consistency check fails (verdict ``model_error``, or ``not_identifiable`` with
    a failed check) the σ (``inertia_std``, the covariance's diagonal) is
    widened to the spread the checks saw (:func:`~rig_identification.estimation.validation.widened_std`) and a warning
    says the tensor is not trustworthy; under ``not_identifiable`` a warning names the
    entries reported as null and what to change.  Returns ``result``, updated in place."""
    log.info("validating the fit")
    surplus = [weight_surplus(p) for p in preps]
    return apply_validation(result, accel_inputs(preps, result) if result.series else None,
                            max(surplus, key=abs), preps[0].rec.rig)


def apply_validation(result: InertiaResult, accel: list[AccelInput] | None, surplus: float | None,
                     rig) -> InertiaResult:
    """The model validation of a fit from its inputs, as :func:`validate_fit` makes it (the
    one core the offline path and the identifier node run): :func:`~rig_identification.estimation.validation.validate`
    with the accelerometer check's inputs ``accel`` (None: skipped), the load cells' weight
    surplus ``surplus`` (:func:`force_weight_surplus`; None: skipped) and the ``rig`` (for
    the advice); ``result.validation`` set, σ and covariance widened
    (:func:`~rig_identification.estimation.validation.widened_std`), the verdict's summary a warning unless ``ok``.
    Returns ``result``, updated in place."""
    v = validate(result, accel, surplus, rig)
    result.validation = v
    w = widened_std(result.inertia_std, v)
    if np.any(w > result.inertia_std):
        result.covariance = result.covariance * v.sigma_factor**2 + np.diag(
            np.maximum(w**2 - (v.sigma_factor * result.inertia_std) ** 2, 0.0))
        result.inertia_std = w
        result.uncertainty += (f"; widened {v.sigma_factor:.2f}× for what the consistency checks saw beyond the noise"
                               if not v.failed else
                               f"; widened to the validation's spread ({', '.join(v.failed)} failed: a lower bound "
                               "of the error)")
    if v.verdict == "model_error":
        result.warnings.append(v.summary)
    elif v.verdict == "not_identifiable":
        result.warnings.append(v.summary)
    return result


def with_diagnosis(rec: Recording, result: InertiaResult, start: float | None = None,
                   end: float | None = None, band_hz: tuple[float, float] | None = None) -> InertiaResult:
    """Model error handled — or said plainly.  When the rigid-body fit's validation says
    ``model_error`` (:func:`validate_fit`; also when its residual exceeds what the sensors'
    noise explains by :data:`MODEL_ERROR_RATIO`, or the load cells' mean vertical force
    differs from rig.yaml's weight by :data:`WEIGHT_TOLERANCE`), run
    :func:`~rig_identification.diagnosis.selection.diagnose` on the recording (cut to ``start``/``end``, s from the first
    IMU sample) and test what it proposes the way every fit is tested.  diagnose fits the
    library's most significant effects jointly, in every combination, and ranks the admissible
    ones by an information criterion (:attr:`~rig_identification.diagnosis.selection.Diagnosis.alternatives`);
    each, best first (at most :data:`~rig_identification.diagnosis.selection.ALTERNATIVES`):

    * the errors of the data it holds (a sensor delay, gain, bias or bias drift, gyro scale,
      a sensor mount's structural mode, the IMU's pose, the body's or the cables' mass, the
      cables' stiffness) are removed from the recording
      (:func:`~rig_identification.diagnosis.selection.corrected`) and the physics (damping, drag, the exciter's
      rotor, …) is added to the model as the wrench it contributes
      (:class:`~rig_identification.diagnosis.selection.EffectWrench`, :func:`with_effect_wrench`);
    * the recording is identified again the ordinary way (same window and band: fit,
      propagated σ, validation).

    The first combination whose fit's validation says ``ok`` and whose every effect is
    physically plausible (:func:`~rig_identification.diagnosis.plausible.implausible`) is *named*;
    the result is then that fit (σ: the propagated noise, or diagnose's joint fit's where
    larger — it carries the effects' own uncertainty), the cables' share taken off when their
    mass was found (:func:`~rig_identification.diagnosis.selection.body_inertia`).  A
    combination with an implausible effect is not tried.  When none passes, nothing is
    named: ``result`` stays the rigid-body fit with its ``model_error`` verdict and widened
    σ, ``diagnosis`` says where the mismatch is (``unexplained``: channel, band, time, size;
    :func:`~rig_identification.diagnosis.residuals.unexplained`, with the departures of the
    accelerometer from the load cells above the fit band) and lists the combinations as
    ``hypotheses`` (each with the checks its fit still failed), never their tensors.

    ``diagnosis`` also keeps the residual RMS before/after; ``rigid_body`` the rigid-body
    tensor and σ.  A fit without model error is returned as it was.
    """
    misfit = result.residual_excess is not None and np.max(result.residual_excess) > MODEL_ERROR_RATIO
    heavier = result.weight_surplus is not None and abs(result.weight_surplus) > WEIGHT_TOLERANCE
    flagged = result.validation is not None and result.validation.verdict == "model_error"
    if not (misfit or heavier or flagged):
        return result
    full = rec
    if start is not None or end is not None:
        t0 = rec.sensors.t_start
        lo = t0 + (start if start is not None else 0.0)
        hi = t0 + end if end is not None else rec.sensors.t_end
        rec = replace(rec, sensors=crop(rec.sensors, lo, hi))
    log.info("diagnosing the model error")
    try:
        d = diagnose(rec)
    except (ValueError, np.linalg.LinAlgError) as e:   # RecordingError, RigError, TrackerError, IdentificationError
        result.warnings.append(f"diagnose could not run on the recording ({e}); the tensor is the rigid-body fit's")
        return result
    rigid_body = {"inertia_about_cg": {k: float(v) for k, v in zip(KEYS, from_tensor(result.inertia))},
                  "inertia_std": {k: float(v) for k, v in zip(KEYS, result.inertia_std)},
                  "uncertainty": result.uncertainty,
                  "validation": None if result.validation is None else result.validation.verdict}
    duration = float(d.series["t"][-1]) if d.series else float(result.t_end - result.t_start)
    where = unexplained(d.located, duration) + [
        {"channel": u["channel"], "band_hz": u["band_hz"], "time_s": [0.0, round(duration, 1)], "size": u["sigma"],
         "is": f"above the fit band: the accelerometer over Newton's prediction from the load cells departs from 1 "
               f"by {u['size']:.3g} ({u['sigma']:.0f} σ; size in σ) — a sensor mount's structural mode?"}
        for u in getattr(d, "out_of_band", []) or []]
    alternatives = getattr(d, "alternatives", None) or ([{
        "effects": d.effects, "applied": d.applied, "effect_wrench": d.effect_wrench, "stiffness": d.stiffness,
        "covariance": d.covariance_after}] if d.mismatch else [])
    hypotheses, again, chosen, whys = [], None, None, []
    for alt in alternatives:
        names = [e["name"] for e in alt["effects"]]
        bad = [e for e in alt["effects"] if not e.get("plausible", True)]
        hyp = {"effects": alt["effects"]}
        hypotheses.append(hyp)
        if bad:
            hyp["not_named"] = "not physically plausible: " + "; ".join(f"{e['name']}: {e['implausible']}" for e in bad)
            whys.append(f"{' + '.join(names)}: {hyp['not_named']}")
            continue
        fixed = corrected(full, alt["applied"])
        if alt.get("stiffness") is not None:
            fixed = with_stiffness(fixed, alt["stiffness"])
        log.info("identifying again with %s", ", ".join(names))
        try:
            fit = identify_recording(fixed, start=start, end=end, band_hz=band_hz,
                                     effect_wrench=alt.get("effect_wrench"))
        except (ValueError, np.linalg.LinAlgError) as e:
            hyp["not_named"] = f"could not be identified again ({e})"
            whys.append(f"{' + '.join(names)}: {hyp['not_named']}")
            continue
        if fit.validation is None or fit.validation.verdict != "ok":
            failed = () if fit.validation is None else fit.validation.failed
            hyp["not_named"] = f"the fit with it still fails its validation ({', '.join(failed)})"
            hyp["failed_checks"] = list(failed)
            whys.append(f"{' + '.join(names)}: {hyp['not_named']}")
            continue
        again, chosen = fit, alt
        break
    diagnosis = {"effects": [], "hypotheses": [e for h in hypotheses for e in h["effects"]],
                 "combinations_tried": hypotheses, "unexplained": where,
                 "residual_rms_before": d.rms_before, "residual_rms_after": d.rms_after,
                 "band_hz": [float(x) for x in d.band]}
    if again is None:
        why = ("diagnose found no effect of its library that explains the misfit" if not alternatives else
               "no combination of the library's effects explains it: " + "; ".join(whys))
        names = [e["name"] for h in hypotheses for e in h["effects"]]
        diagnosis["handled"] = "not: " + why
        result.rigid_body, result.diagnosis = rigid_body, diagnosis
        result.warnings.append(
            f"model error not explained: {why}; the tensor is the rigid-body fit's (σ widened, not trustworthy)"
            + (f"; hypotheses, not findings: {', '.join(dict.fromkeys(names))}" if names else "")
            + ("; the mismatch is in " + ", ".join(f"{u['channel']} at {u['band_hz'][0] + 0.05:.2f} Hz"
                                                   for u in where if u["band_hz"]) if where else ""))
        return result
    effects = chosen["effects"]
    names = [e["name"] for e in effects]
    found = "; ".join(f"{e['name']} ({effect_text(e)})" for e in effects)   # with units, as the CLI's
    applied = chosen["applied"]
    mu = float(applied.get(("cable_mass", ""), 0.0))
    if mu:   # the fit's tensor is the body's with the cables' lower halves, about their combined CG
        body_rig = replace(rec.rig, mass=rec.rig.mass + float(applied.get(("body_mass", ""), 0.0)))
        again.inertia = body_inertia(again.inertia, body_rig, mu)
        again.mass, again.center_of_gravity = body_rig.mass, body_rig.require_cg().copy()
    if chosen.get("effect_wrench") is not None and chosen.get("covariance") is not None:
        # the effects' own uncertainty: diagnose's joint fit of the tensor with them
        joint = np.sqrt(np.clip(np.diag(chosen["covariance"]), 0, None))
        wider = np.maximum(joint, again.inertia_std)
        again.covariance = again.covariance + np.diag(wider**2 - again.inertia_std**2)
        again.inertia_std = wider
        again.uncertainty += "; at least diagnose's joint fit with the effects (their own uncertainty)"
    rel = float(chosen.get("relative_std") or 0.0)
    if rel > 0:
        # a correction fixed from outside the fit band (a structural mode's shape) leaves a
        # relative error of the readings in the band, and so about of the tensor
        th = from_tensor(again.inertia)
        big = max(abs(th[0]), abs(th[3]), abs(th[5]))
        ref = np.array([abs(th[0]), big, big, abs(th[3]), big, abs(th[5])])    # KEYS order; products: of the largest
        wider = np.sqrt(again.inertia_std ** 2 + (rel * ref) ** 2)
        again.covariance = again.covariance + np.diag(wider ** 2 - again.inertia_std ** 2)
        again.inertia_std = wider
        again.uncertainty += f"; with the {100 * rel:.3g} % the corrections fixed from outside the band leave"
    handled = ("removed from the data" if chosen.get("effect_wrench") is None else
               "added to the model" if not applied and chosen.get("stiffness") is None else
               "removed from the data and added to the model")
    diagnosis["effects"], diagnosis["hypotheses"], diagnosis["unexplained"] = effects, [], []
    diagnosis["combinations_tried"] = hypotheses[:-1]
    again.rigid_body, again.diagnosis = rigid_body, {**diagnosis, "handled": handled}
    # the verdict is on the model with the effects, not the rigid body's alone
    again.validation = replace(again.validation, model=f"the rigid-body model with {', '.join(names)}")
    again.method += f"; {', '.join(names)} diagnosed (rig-identify diagnose), {handled}, validated"
    rigid_verdict = result.validation.summary if result.validation is not None else None
    again.warnings = [w for w in result.warnings if w != rigid_verdict] + [
        f"model error diagnosed: {found} — {handled}, the recording identified again and validated (the "
        "rigid-body fit's verdict was model_error; it is under 'rigid_body' in the JSON, --no-diagnose reports "
        "it instead)"] + [w for w in again.warnings if w not in result.warnings]
    return again


MASS_RTOL = 1e-3   # relative: rig.yaml body.mass of recordings fitted jointly must agree this well
CG_TOL = 0.002     # m: and their body.center_of_gravity this well


def _rig_file(rec: Recording) -> str:
    """The recording's rig.yaml, or its rig's source for an in-memory recording."""
    return str(Path(rec.path) / "rig.yaml") if rec.path is not None else str(rec.rig.source)


def check_same_body(recs: list[Recording], mass_rtol: float = MASS_RTOL, cg_tol: float = CG_TOL) -> None:
    """Refuse a joint fit of recordings whose rig.yaml describe different bodies: body.mass
    must agree within ``mass_rtol`` (relative) and body.center_of_gravity within ``cg_tol``
    m (body axes) of the first recording's.  Raises
    :class:`~rig_identification.io.recording.RecordingError` naming both files."""
    ref = recs[0]
    m0, c0 = ref.rig.mass, ref.rig.require_cg()
    for r in recs[1:]:
        m, c = r.rig.mass, r.rig.require_cg()
        where = f"{_rig_file(ref)} and {_rig_file(r)}"
        if abs(m - m0) > mass_rtol * abs(m0):
            raise RecordingError(f"{where} describe different bodies: body.mass {m0:g} kg vs {m:g} kg (a joint "
                                 f"fit needs the same body; tolerance {100 * mass_rtol:g} %)")
        d = float(np.linalg.norm(np.asarray(c) - np.asarray(c0)))
        if d > cg_tol:
            raise RecordingError(f"{where} describe different bodies: body.center_of_gravity "
                                 f"[{', '.join(f'{x:g}' for x in c0)}] vs [{', '.join(f'{x:g}' for x in c)}] m, "
                                 f"{1000 * d:.1f} mm apart (a joint fit needs the same body; tolerance "
                                 f"{1000 * cg_tol:g} mm)")


def recording_labels(recs: list[Recording]) -> list[str]:
    """Short names of the recordings: folder names, or full paths where names repeat."""
    names = [Path(r.path).name if r.path is not None else f"recording {i + 1}" for i, r in enumerate(recs)]
    return [n if names.count(n) == 1 else str(r.path) for n, r in zip(names, recs)]


def identify_recordings(recs: list[Recording], start: float | None = None, end: float | None = None,
                        settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                        mass_rtol: float = MASS_RTOL, cg_tol: float = CG_TOL, refine: bool = True) -> InertiaResult:
    """One inertia tensor from several recordings of the same body (different exciter
    frequencies or positions, cable geometries).

    Checks the bodies agree (:func:`check_same_body`) before any processing, replays
    each recording with :func:`prepare_recording` (the same start/end/settle window on
    each), then fits jointly with
    :func:`~rig_identification.estimation.identification.identify_inertia_joint` (each recording
    band-passed on its own, ``band_hz`` or automatic per recording) and, with ``refine``,
    :func:`refine_uncertainty` over them all.  One recording:
    :func:`identify_recording`.  Warnings are prefixed with the recording's name; the
    result's ``series`` labels are :func:`recording_labels`.  Raises like
    :func:`identify_recording`.
    """
    recs = list(recs)
    if not recs:
        raise RecordingError("no recording given")
    if len(recs) == 1:
        return identify_recording(recs[0], start=start, end=end, settle=settle, band_hz=band_hz, refine=refine)
    check_same_body(recs, mass_rtol, cg_tol)
    labels = recording_labels(recs)
    preps = [prepare_recording(r, start, end, settle) for r in recs]
    log.info("fitting one inertia tensor to %d recordings (prediction error)", len(preps))
    result = identify_inertia_joint([p.rec.rig for p in preps], [(p.t, p.gyro_body, p.torque) for p in preps],
                                    band_hz=band_hz, labels=labels)
    if refine:
        refine_uncertainty(preps, result)
    result.warnings[:0] = [f"{lab}: {w}" for lab, p in zip(labels, preps) for w in p.rec.warnings + p.warnings]
    validate_fit(preps, result)
    return result


def compare_to_truth(result: InertiaResult, truth: dict) -> dict:
    """Errors of the identified tensor against truth.yaml's ``inertia_about_cg``.

    Returns {key: {"value", "truth", "error", "error_percent", "error_sigma"}}; the
    percentage is of the entry for diagonals and of the largest diagonal for products.
    """
    tru = truth["inertia_about_cg"]
    big = max(abs(tru["ixx"]), abs(tru["iyy"]), abs(tru["izz"]))
    out = {}
    for k, v, s in zip(KEYS, from_tensor(result.inertia), result.inertia_std):
        e = float(v - tru[k])
        ref = abs(tru[k]) if k in ("ixx", "iyy", "izz") else big
        out[k] = {"value": float(v), "truth": float(tru[k]), "error": e, "error_percent": 100 * e / ref,
                  "error_sigma": e / s if s > 0 else float(np.inf)}
    return out
