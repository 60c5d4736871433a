"""Offline replay: recording -> tracker -> preprocessor -> identifier (the nodes' core code)."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from dataclasses import dataclass, field, replace
from pathlib import Path

from .identification import InertiaResult, identify_inertia, identify_inertia_joint, identify_inertia_thesis
from .preprocessor import preprocess
from .recording import Recording, RecordingError, crop, fill_short_gaps, find_bad_spans
from .tracker import track


def default_initial_guess(rig) -> np.ndarray:
    """A rough tensor (6,) for the thesis model when none is given: the mass spread over
    a box spanned by the body anchors, diagonal (kg·m²)."""
    half = np.ptp(rig.body_anchors, axis=0) / 2 + 0.1
    sx, sy, sz = half**2
    return rig.mass / 3 * np.array([sy + sz, 0.0, 0.0, sx + sz, 0.0, sx + sy])


MIN_CLEAN = 15.0  # s: shortest clean span worth fitting (tracker settling + two high-pass periods);
#                   a shorter recording (the thesis's 10 s case studies) needs 75 % of its length clean
MIN_MOTION = 2e-4  # rad/s: RMS of the low-passed gyro about its mean below which the body "hardly moved"


def _check_units(rec: Recording) -> None:
    rig, s = rec.rig, rec.sensors
    total = np.sum([np.median(s.load_cells[n].data[:, 0]) for n in rig.cable_names])
    weight = rig.mass * rig.gravity
    if not 0.5 <= total / weight <= 50.0:
        raise RecordingError(f"{rec.path}: the load-cell tensions (median sum {total:.4g} N) do not match the "
                             f"weight in rig.yaml (body.mass × gravity = {weight:.4g} N): check the units of the "
                             "tensions (N, not kN) and body.mass (kg)")


def clean_sensors(rec: Recording, warnings: list[str]):
    """Exclude bad spans (gaps, saturation, slack cables; :func:`~.recording.find_bad_spans`):
    keep the longest span free of them, bridge short IMU gaps.  Appends one warning per
    excluded span.  Raises :class:`RecordingError` if less than :data:`MIN_CLEAN` s (in a
    shorter recording, 75 % of its length) remain."""
    s = rec.sensors
    t0, t_end = s.t_start, s.t_end
    spans = sorted(find_bad_spans(rec.rig, s), key=lambda b: b.t0)
    a, b = t0, t_end
    if spans:
        edges, cur = [], t0
        for sp in spans:
            if sp.t0 > cur:
                edges.append((cur, sp.t0))
            cur = max(cur, sp.t1)
        if cur < t_end:
            edges.append((cur, t_end))
        a, b = max(edges, key=lambda e: e[1] - e[0]) if edges else (t0, t0)
        what = "; ".join(f"{sp.topic}: {sp.reason} at t={sp.t0 - t0:.2f}–{sp.t1 - t0:.2f} s" for sp in spans[:5])
        if len(spans) > 5:
            what += f"; and {len(spans) - 5} more"
        need = min(MIN_CLEAN, 0.75 * (t_end - t0))
        if b - a < need:
            raise RecordingError(f"{rec.path}: after excluding the bad spans ({what}) the longest clean span is "
                                 f"{b - a:.1f} s (t={a - t0:.1f}–{b - t0:.1f} s), less than the {need:.3g} s "
                                 "needed for a trustworthy fit")
        for sp in spans:
            warnings.append(f"{sp.topic}: {sp.reason} at t={sp.t0 - t0:.2f}–{sp.t1 - t0:.2f} s from the start; "
                            f"span excluded, fit on the longest clean span t={a - t0:.2f}–{b - t0:.2f} s")
        s = crop(s, a, b)
    imu, filled = fill_short_gaps(s.imu)
    if filled:
        s.imu = imu
        warnings.append(f"{'/rig/imu'}: {len(filled)} short gap(s) (≤ 0.1 s) bridged by linear interpolation, "
                        f"first at t={filled[0][0] - t0:.2f}–{filled[0][1] - t0:.2f} s from the start")
    return s


def _check_motion(rec: Recording, s) -> None:
    """Refuse a recording in which the body did not move beyond the gyro's own noise:
    the gyro low-passed at 10 Hz (zero-phase Butterworth, scipy) about its mean must stand
    out of the noise it would have in that band (σ from the spectrum's flat top), by 5x,
    and be at least MIN_MOTION."""
    from scipy.signal import butter, sosfiltfilt

    from .identification import gyro_noise_sigma
    g = s.imu.data[:, :3]
    fs = 1.0 / np.median(np.diff(s.imu.t))
    f_lp = min(10.0, 0.4 * fs)
    sm = sosfiltfilt(butter(4, f_lp, fs=fs, output="sos"), g - g.mean(0), axis=0)
    rms = float(np.sqrt(np.mean(np.sum(sm**2, axis=1))))
    noise = gyro_noise_sigma(g, fs) * np.sqrt(3 * 2 * f_lp / fs)
    threshold = max(5 * noise, MIN_MOTION)
    if rms < threshold:
        raise RecordingError(f"{rec.path}: the body hardly moved (gyro RMS below 10 Hz {rms:.1e} rad/s, threshold "
                             f"{threshold:.1e} rad/s from the gyro noise): is this a static recording? inertia "
                             "needs a dynamic one")


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


def _replay_window(rig, s, lo: float, hi: float):
    """Tracker -> preprocessor over the cleaned sensors ``s``; the window [lo, hi] (absolute
    stamps, s).  Returns (poses, t (N,), gyro_body (N,3), torque (N,3), force (N,3))."""
    poses = track(rig, s)
    wrench = preprocess(rig, poses, s)
    m = (wrench.t >= lo) & (wrench.t <= hi)
    gyro = s.imu.interp(wrench.t[m])[:, :3]
    return poses, wrench.t[m], rig.imu.rotation.apply(gyro), wrench.torque[m], wrench.force[m]


def prepare_recording(rec: Recording, start: float | None = None, end: float | None = None,
                      settle: float = 5.0) -> PreparedRecording:
    """Clean a dynamic recording, run the tracker and the preprocessor, cut the window.

    start/end: window in seconds from the first IMU stamp (default: the whole
    recording after ``settle`` s, the tracker's convergence time, at most a tenth of
    the recording).  Raises :class:`~rig_identification.recording.RecordingError`,
    :class:`~rig_identification.rig.RigError` (no CG in rig.yaml),
    :class:`~rig_identification.tracker.TrackerError`.
    """
    rig, s = rec.rig, rec.sensors
    rig.require_cg()
    if rig.exciter is not None and s.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no "
                             "/rig/exciter/wrench topic")
    _check_units(rec)
    warnings: list[str] = []
    s = clean_sensors(rec, warnings)
    _check_motion(rec, s)
    t0 = rec.sensors.t_start  # --start/--end count from the recording's first IMU sample
    settle = min(settle, 0.1 * (s.t_end - s.t_start))
    lo = s.t_start + settle if start is None else max(t0 + start, s.t_start + settle)
    hi = s.t_end if end is None else min(t0 + end, s.t_end)
    poses, t, gyro_body, torque, force = _replay_window(rig, s, lo, hi)
    if len(t) < 10:
        raise RecordingError(f"{rec.path}: no samples in the window [{lo - t0:.1f}, {hi - t0:.1f}] s")
    return PreparedRecording(rec, t, gyro_body, torque, warnings, s, poses, (lo, hi), force)


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


def weight_surplus(prep: PreparedRecording) -> float:
    """The load cells' (and the exciter's) mean vertical force over the fit window, world
    axes, relative to rig.yaml's weight: mean(F_z) / (m g) − 1, F the preprocessor's
    generalized force (``prep.force``, :func:`~.preprocessor.generalized_wrench`) turned to
    world axes at the tracked pose (over a window of bounded motion the mean vertical
    acceleration vanishes, so the mean force is the weight; Newton's second law).
    Dimensionless; positive when the cells carry more."""
    rig, P = prep.rec.rig, prep.poses
    q = P.quaternion[np.searchsorted(P.t, prep.t)]     # prep.t are pose stamps
    fz = Rotation.from_quat(q).apply(prep.force)[:, 2]
    return float(np.mean(fz) / (rig.mass * rig.gravity) - 1.0)


def refine_uncertainty(preps: list[PreparedRecording], result: InertiaResult, seed: int = 0) -> InertiaResult:
    """Remove the second-order bias from a prediction-error estimate and give it the σ that
    the sensors' noise causes along the recordings' trajectories (:mod:`.uncertainty`).

    preps: the prepared recording(s) the result was fitted to (one, or several for a joint
    fit, in the order of ``result.series``).  The white-noise σ of every stream is
    estimated from each recording (:func:`~.uncertainty.sensor_noise`); the bias is
    measured by re-running tracker, preprocessor and identifier (same windows and bands)
    with an antithetic pair of fresh noise realisations
    (:func:`~.uncertainty.antithetic_bias`) and subtracted; the covariance is the
    linearised propagation of that noise through the same chain
    (:func:`~.uncertainty.propagated`, recordings combined by :func:`~.planning.combine`):
    ``crb_std`` holds it, and ``inertia_std`` and ``covariance`` too unless the fit's residual
    RMS exceeds the one the noise predicts by more than :data:`MODEL_ERROR_RATIO` on a gyro
    axis (``residual_excess``): that is model error, and the identifier's sandwich σ (from
    the residuals; always in ``sandwich_std``) is kept, with a warning.  If the propagation fails (too little motion) or the corrected
    tensor is not physically consistent, the result keeps the sandwich σ (or the
    uncorrected tensor) with a warning.  Returns ``result``, updated in place.
    """
    from .identification import from_tensor, physically_consistent, to_tensor, weak_directions
    from .planning import PlanError, combine
    from .uncertainty import antithetic_bias, propagated, sensor_noise

    rigs = [p.rec.rig for p in preps]
    bands = [tuple(s.band_hz) for s in result.series] if len(result.series) == len(preps) else \
        [tuple(result.band_hz)] * len(preps)
    labels = [s.label for s in result.series] if len(result.series) == len(preps) else None
    est = [sensor_noise(r, p.sensors) for r, p in zip(rigs, preps)]
    noises = [e[0] for e in est]
    result.sensor_noise = {k: float(np.sqrt(np.mean([n[k] ** 2 for n in noises]))) for k in noises[0]}
    result.sandwich_std = result.inertia_std.copy()

    def fit(sensor_list):
        segs = [_replay_window(r, s, *p.window)[1:4] for r, s, p in zip(rigs, sensor_list, preps)]
        if len(segs) == 1:
            res = identify_inertia(rigs[0], *segs[0], band_hz=bands[0])
        else:
            res = identify_inertia_joint(rigs, segs, band_hz=bands, labels=labels)
        return from_tensor(res.inertia)

    theta = from_tensor(result.inertia)
    bias = antithetic_bias(fit, theta, [p.sensors for p in preps], noises, seed)
    J = to_tensor(theta - bias)
    if physically_consistent(J):
        result.inertia = J
        result.bias_correction = bias
        result.method += "; second-order bias removed (antithetic SIMEX)"
    else:
        result.warnings.append("the second-order bias correction would make the tensor physically inconsistent; "
                               "not applied")
    try:
        pred = combine([propagated(r, p.poses, p.sensors, p.t, result.inertia, b, n, rt)
                        for r, p, b, (n, rt) in zip(rigs, preps, bands, est)])
    except (PlanError, np.linalg.LinAlgError, ValueError) as e:
        result.warnings.append(f"noise propagation failed ({e}); σ from the fit's residuals (sandwich)")
        return result
    result.crb_std = pred.std
    r = np.asarray(result.residual_rms) / pred.residual_rms
    result.residual_excess = r
    if np.max(r) > MODEL_ERROR_RATIO:
        # the residual is not the noise: model error, whose effect on the estimate the
        # residuals themselves (the sandwich) measure
        ax = "xyz"[int(np.argmax(r))]
        result.warnings.append(f"the fit's residual is {np.max(r):.2f}× what the sensors' noise explains (gyro {ax}): "
                               "a misfit — physics the model leaves out (rig-identify diagnose looks for it); "
                               "σ from the fit's residuals (sandwich), not from the noise")
        result.uncertainty = "sandwich (model error)"
    else:
        result.inertia_std = pred.std
        result.covariance = pred.covariance
        result.uncertainty = "propagated sensor noise"
    result.weak_directions = weak_directions(result.inertia, result.covariance)
    return result


def identify_recording(rec: Recording, start: float | None = None, end: float | None = None,
                       settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                       model: str = "pem", initial_guess=None, refine: bool = True) -> InertiaResult:
    """Identify the inertia tensor of a dynamic recording.

    start/end/settle: the window, see :func:`prepare_recording`.  model: ``"pem"`` (ours;
    with ``refine``, :func:`refine_uncertainty`: second-order bias removed, σ propagated
    from the estimated sensor noise — about three times the work of the plain fit)
    or ``"thesis"`` (the thesis's model and estimator,
    :func:`~rig_identification.identification.identify_inertia_thesis`, from
    ``initial_guess`` (6,) tensor entries or :func:`default_initial_guess`).  Raises
    :class:`~rig_identification.recording.RecordingError`,
    :class:`~rig_identification.rig.RigError`,
    :class:`~rig_identification.identification.IdentificationError`.
    """
    prep = prepare_recording(rec, start, end, settle)
    rig = rec.rig
    if model == "thesis":
        guess = default_initial_guess(rig) if initial_guess is None else np.asarray(initial_guess, float)
        result = identify_inertia_thesis(rig, prep.t, prep.gyro_body, prep.torque, guess)
    elif model == "pem":
        result = identify_inertia(rig, prep.t, prep.gyro_body, prep.torque, band_hz=band_hz)
        if refine:
            refine_uncertainty([prep], result)
    else:
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    result.warnings[:0] = rec.warnings + prep.warnings
    result.weight_surplus = weight_surplus(prep)
    if abs(result.weight_surplus) > WEIGHT_TOLERANCE:
        # the rotational residual cannot see this: the heavier body is still a rigid body
        result.warnings.append(
            f"the load cells carry {100 * result.weight_surplus:+.2f} % of rig.yaml's weight "
            f"({result.weight_surplus * rig.mass:+.1f} kg) beyond it: the tensions do not move the body rig.yaml "
            "describes (each cable's lower half hanging outside its load cell, a load cell's gain, or a wrong "
            "body.mass); rig-identify diagnose looks for the cause")
    return result


def with_diagnosis(rec: Recording, result: InertiaResult, start: float | None = None,
                   end: float | None = None, band_hz: tuple[float, float] | None = None) -> InertiaResult:
    """Model error handled: when the rigid-body fit's residual exceeds what the sensors' noise
    explains by more than :data:`MODEL_ERROR_RATIO` (``result.residual_excess``, set by
    :func:`refine_uncertainty`), or the load cells' mean vertical force differs from
    rig.yaml's weight by more than :data:`WEIGHT_TOLERANCE` (``result.weight_surplus``: a
    heavier body is still a rigid body, and the residual does not show it), run :func:`~.diagnosis.diagnose` on the recording (cut to
    ``start``/``end``, s from the first IMU sample) and use what it names:

    * only errors of the data (:data:`~.diagnosis.CORRECTIONS`: a sensor delay, gain, bias
      or IMU pose): they are removed from the recording (:func:`~.diagnosis.corrected`) and
      it is identified again as :func:`identify_recording` does (same window and band) —
      the returned result is that one, σ from the propagated noise where the residual is
      now the noise's.  A 20 ms load-cell delay on thesis case 16 (60 s, reference noise):
      Ixx +8.7 %, Izz +11 % → within 0.10 % and 1 σ (the diagnosis's own fit: 0.20 %);
    * physics the model leaves out (damping, drag, the exciter's rotor, …): the tensor of
      diagnose's fit with it; ``inertia``, ``inertia_std``, ``covariance`` and
      ``weak_directions`` are replaced (σ from its residuals; ``uncertainty`` says so).  On
      visible_case16_damped: Izz +3.1 % → +0.34 %, every entry within 0.46 %.

    Either way ``rigid_body`` keeps the rigid-body tensor and σ, ``diagnosis`` the named
    effects with their parameters and the residual RMS before/after, and a warning says what
    was done.  When the fit shows no model error, ``result`` is returned as it was; when
    diagnose names nothing or cannot run, too, with a warning saying so.
    """
    from .diagnosis import CORRECTIONS, corrected, diagnose, effect_parameters_text
    from .identification import KEYS, from_tensor, weak_directions
    misfit = result.residual_excess is not None and np.max(result.residual_excess) > MODEL_ERROR_RATIO
    heavier = result.weight_surplus is not None and abs(result.weight_surplus) > WEIGHT_TOLERANCE
    if not (misfit or heavier):
        return result
    full = rec
    if start is not None or end is not None:
        t0 = rec.sensors.t_start
        lo = t0 + (start if start is not None else 0.0)
        hi = t0 + end if end is not None else rec.sensors.t_end
        rec = replace(rec, sensors=crop(rec.sensors, lo, hi))
    try:
        d = diagnose(rec)
    except (ValueError, np.linalg.LinAlgError) as e:   # RecordingError, RigError, TrackerError, IdentificationError
        result.warnings.append(f"diagnose could not run on the recording ({e}); the tensor is the rigid-body fit's")
        return result
    if not d.mismatch or d.covariance_after is None:
        result.warnings.append("diagnose found no physics in its library that explains the misfit; the tensor is "
                               "the rigid-body fit's")
        return result
    names = [e["name"] for e in d.effects]
    rigid_body = {"inertia_about_cg": {k: float(v) for k, v in zip(KEYS, from_tensor(result.inertia))},
                  "inertia_std": {k: float(v) for k, v in zip(KEYS, result.inertia_std)},
                  "uncertainty": result.uncertainty}
    diagnosis = {"effects": d.effects, "residual_rms_before": d.rms_before,
                 "residual_rms_after": d.rms_after, "band_hz": [float(x) for x in d.band]}
    found = "; ".join(f"{e['name']} ({effect_parameters_text(e)})" for e in d.effects)
    again = None
    if d.corrections and all(n in CORRECTIONS for n in names):
        # errors of the data: removed, and the recording identified again the ordinary way
        try:
            again = identify_recording(corrected(full, d.corrections), start=start, end=end, band_hz=band_hz)
        except (ValueError, np.linalg.LinAlgError) as e:
            result.warnings.append(f"the recording with {', '.join(names)} removed could not be identified again "
                                   f"({e}); the tensor is diagnose's fit")
    if again is not None:
        again.rigid_body, again.diagnosis = rigid_body, {**diagnosis, "handled": "removed from the data"}
        again.method += f"; {', '.join(names)} diagnosed and removed from the data (rig-identify diagnose)"
        again.warnings = result.warnings + [
            f"model error diagnosed: {found} — removed from the data and the recording identified again; the "
            "rigid-body fit of the uncorrected data is under 'rigid_body' in the JSON (--no-diagnose reports that "
            "one instead)"] + [w for w in again.warnings if w not in result.warnings]
        return again
    result.rigid_body, result.diagnosis = rigid_body, {**diagnosis, "handled": "added to the model"}
    result.inertia = d.inertia_after
    result.covariance = d.covariance_after
    result.inertia_std = np.sqrt(np.clip(np.diag(d.covariance_after), 0, None))
    result.crb_std = None
    result.bias_correction = None
    result.weak_directions = weak_directions(result.inertia, result.covariance)
    result.uncertainty = "sandwich (diagnosed model)"
    result.method += f"; model error diagnosed, the fit with {', '.join(names)} (rig-identify diagnose)"

    result.warnings.append(f"model error diagnosed: {found} — the tensor reported is the fit with it; the "
                           "rigid-body fit's is under 'rigid_body' in the JSON (--no-diagnose reports that one "
                           "instead)")
    return result


MASS_RTOL = 1e-3   # relative: rig.yaml body.mass of recordings fitted jointly must agree this well
CG_TOL = 0.002     # m: and their body.center_of_gravity this well


def _rig_file(rec: Recording) -> str:
    """The recording's rig.yaml, or its rig's source for an in-memory recording."""
    return str(Path(rec.path) / "rig.yaml") if rec.path is not None else str(rec.rig.source)


def check_same_body(recs: list[Recording], mass_rtol: float = MASS_RTOL, cg_tol: float = CG_TOL) -> None:
    """Refuse a joint fit of recordings whose rig.yaml describe different bodies: body.mass
    must agree within ``mass_rtol`` (relative) and body.center_of_gravity within ``cg_tol``
    m (body axes) of the first recording's.  Raises
    :class:`~rig_identification.recording.RecordingError` naming both files."""
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
    :func:`~rig_identification.identification.identify_inertia_joint` (each recording
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
    result = identify_inertia_joint([p.rec.rig for p in preps], [(p.t, p.gyro_body, p.torque) for p in preps],
                                    band_hz=band_hz, labels=labels)
    if refine:
        refine_uncertainty(preps, result)
    result.warnings[:0] = [f"{lab}: {w}" for lab, p in zip(labels, preps) for w in p.rec.warnings + p.warnings]
    return result


def compare_to_truth(result: InertiaResult, truth: dict) -> dict:
    """Errors of the identified tensor against truth.yaml's ``inertia_about_cg``.

    Returns {key: {"value", "truth", "error", "error_percent", "error_sigma"}}; the
    percentage is of the entry for diagonals and of the largest diagonal for products.
    """
    from .identification import KEYS, from_tensor
    tru = truth["inertia_about_cg"]
    big = max(abs(tru["ixx"]), abs(tru["iyy"]), abs(tru["izz"]))
    out = {}
    for k, v, s in zip(KEYS, from_tensor(result.inertia), result.inertia_std):
        e = float(v - tru[k])
        ref = abs(tru[k]) if k in ("ixx", "iyy", "izz") else big
        out[k] = {"value": float(v), "truth": float(tru[k]), "error": e, "error_percent": 100 * e / ref,
                  "error_sigma": e / s if s > 0 else float(np.inf)}
    return out
