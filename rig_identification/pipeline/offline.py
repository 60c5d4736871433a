"""Offline replay: recording -> tracker -> preprocessor -> identifier (the nodes' core code)."""
from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..diagnosis.distinguish import effect_name, finding_text
from ..diagnosis.not_rigid import not_rigid_hypothesis, two_body_reason
from ..diagnosis.residuals import unexplained
from ..diagnosis.result import Combination, Diagnosis
from ..diagnosis.selection import body_inertia, corrected, diagnose, with_stiffness
from ..estimation.harmonic_start import box_tensor
from ..estimation.identification import identify_inertia, identify_inertia_joint
from ..estimation.inertia_result import InertiaResult
from ..estimation.thesis_estimator import identify_inertia_thesis
from ..io.recording import Recording, RecordingError, crop
from ..io.verdict import KEYS
from ..model.parametrisation import entry_scales, from_tensor
from .fit_validation import WEIGHT_TOLERANCE, validate_fit, weight_surplus, weight_warning
from .prepare import PreparedRecording, prepare_recording, with_effect_wrench
from .sigma import MODEL_ERROR_RATIO, refine_uncertainty

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them


def identify_recording(rec: Recording, start: float | None = None, end: float | None = None,
                       settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                       model: str = "pem", initial_guess=None, refine: bool = True,
                       effect_wrench=None) -> InertiaResult:
    """Identify the inertia tensor of a dynamic recording.

    start/end/settle: the window, see :func:`~rig_identification.pipeline.prepare.prepare_recording`.
    model: ``"pem"`` (ours; with ``refine``, :func:`~rig_identification.pipeline.sigma.refine_uncertainty`:
    compensated for the noise in its input, σ propagated from the estimated sensor noise — about
    three times the work of the plain fit) or ``"thesis"`` (the thesis's model and estimator,
    :func:`~rig_identification.estimation.thesis_estimator.identify_inertia_thesis`, from
    ``initial_guess`` (6,) tensor entries or the body anchors' box,
    :func:`~rig_identification.estimation.harmonic_start.box_tensor`).  effect_wrench:
    physics added to the model (:class:`~rig_identification.diagnosis.result.EffectWrench`,
    :func:`~rig_identification.pipeline.prepare.with_effect_wrench`).  Every fit is validated
    (:func:`~rig_identification.pipeline.fit_validation.validate_fit`: ``result.validation``).  Raises
    :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError`,
    :class:`~rig_identification.estimation.identification.IdentificationError`.
    """
    prep = prepare_recording(rec, start, end, settle)
    if effect_wrench is not None:
        prep = with_effect_wrench(prep, effect_wrench)
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


def unidentified(rig, prep: PreparedRecording, reason: str) -> InertiaResult:
    """The result of a fit that could not be made: every entry NaN (reported as null, verdict
    ``not_identifiable``), ``reason`` as a warning."""
    nan = np.full(6, np.nan)
    res = InertiaResult(rig.mass, rig.require_cg().copy(), np.full((3, 3), np.nan), nan, np.full((6, 6), np.nan),
                        float(prep.t[0]), float(prep.t[-1]), len(prep.t), (np.nan, np.nan), np.full(3, np.nan),
                        np.full(3, np.nan), warnings=[reason])
    return res


def with_diagnosis(rec: Recording, result: InertiaResult, start: float | None = None,
                   end: float | None = None, band_hz: tuple[float, float] | None = None,
                   cg_covariance: np.ndarray | None = None) -> InertiaResult:
    """Model error handled — or said plainly.  When the rigid-body fit's validation says
    ``model_error`` (:func:`validate_fit`; also when its residual exceeds what the sensors'
    noise explains by :data:`MODEL_ERROR_RATIO`, or the load cells' mean vertical force
    differs from rig.yaml's weight by :data:`WEIGHT_TOLERANCE`), run
    :func:`~rig_identification.diagnosis.selection.diagnose` on the recording (cut to
    ``start``/``end``, s from the first
    IMU sample) and test what it proposes the way every fit is tested.  diagnose fits the
    library's most significant effects jointly, in every combination, and ranks the admissible
    ones by an information criterion (:attr:`~rig_identification.diagnosis.result.Diagnosis.alternatives`);
    each, best first (at most :data:`~rig_identification.diagnosis.selection.ALTERNATIVES`, and
    the best one's admissible proper subsets):

    * the errors of the data it holds (a sensor delay, gain, bias or bias drift, gyro scale,
      a sensor mount's structural mode, the IMU's pose, the body's or the cables' mass, the
      cables' stiffness) are removed from the recording
      (:func:`~rig_identification.diagnosis.selection.corrected`) and the physics (damping, drag, the exciter's
      rotor, …) is added to the model as the wrench it contributes
      (:class:`~rig_identification.diagnosis.result.EffectWrench`, :func:`with_effect_wrench`);
    * the recording is identified again the ordinary way (same window and band: fit,
      propagated σ, validation).

    An effect the recording does not tell from a rival's (``told_apart`` false:
    :mod:`~rig_identification.diagnosis.distinguish`) is named by its class, with the
    candidates and what would tell them apart; the fit is made with the preferred member.

    The first combination whose fit's validation says ``ok`` and whose every effect is
    physically plausible (:func:`~rig_identification.diagnosis.plausible.implausible`) is *named*
    — unless one of its proper subsets passes too: then the smallest such is (an effect is named
    only when the model fails its validation without it);
    the result is then that fit (σ: the propagated noise, or diagnose's joint fit's where
    larger — it carries the effects' own uncertainty), the cables' share taken off when their
    mass was found (:func:`~rig_identification.diagnosis.selection.body_inertia`).  A
    combination with an implausible effect is not tried.  When none passes, nothing is
    named: ``result`` stays the rigid-body fit with its ``model_error`` verdict and widened
    σ, ``diagnosis`` says where the mismatch is (``unexplained``: channel, band, time, size;
    :func:`~rig_identification.diagnosis.residuals.unexplained`, with the departures of the
    accelerometer from the load cells above the fit band) and lists the combinations as
    ``hypotheses`` (each with the checks its fit still failed), never their tensors.

    cg_covariance: (3, 3) m², the σ of the CG the recording was given (``inertia --cg``): the
    diagnosis then screens the CG as a data error (``cg_offset``), plausible within 3 σ of it.

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
        d = diagnose(rec, cg_covariance=cg_covariance)
    except (ValueError, np.linalg.LinAlgError) as e:   # RecordingError, RigError, TrackerError, IdentificationError
        result.warnings.append(f"diagnose could not run on the recording ({e}); the tensor is the rigid-body fit's")
        return result
    rigid_body = {"inertia_about_cg": {k: float(v) for k, v in zip(KEYS, from_tensor(result.inertia))},
                  "inertia_std": {k: float(v) for k, v in zip(KEYS, result.inertia_std)},
                  "uncertainty": result.uncertainty,
                  "validation": None if result.validation is None else result.validation.verdict}
    where = mismatch_places(d, float(result.t_end - result.t_start))
    hypotheses: list[dict] = []
    again, chosen, chosen_hyp = None, None, None
    for alt in d.alternatives:
        if chosen is not None and not set(alt.keys) < set(chosen.keys):
            continue   # after a validated combination, only its proper subsets are tried (parsimony)
        fit, hyp = _refit(full, alt, start, end, band_hz)
        hypotheses.append(hyp)
        if fit is not None:
            again, chosen, chosen_hyp = fit, alt, hyp   # kept looking: a smaller one that also validates is named
    # a body that may not be rigid: said, with what to do, not fitted (the two-body fit is
    # rig-identify diagnose --two-body's, experimental)
    gate = two_body_reason(rec, result, again is not None)
    if gate:
        hypotheses.append(_refit(full, not_rigid_hypothesis(gate), start, end, band_hz)[1])
    diagnosis = {"effects": [], "hypotheses": [e for h in hypotheses for e in h["effects"]],
                 "combinations_tried": hypotheses, "unexplained": where,
                 "residual_rms_before": d.rms_before, "residual_rms_after": d.rms_after,
                 "band_hz": [float(x) for x in d.band]}
    if again is None or chosen is None:
        return _not_explained(result, rigid_body, diagnosis, hypotheses, where)
    diagnosis["combinations_tried"] = [h for h in hypotheses if h is not chosen_hyp]
    return _named(result, again, chosen, rec, rigid_body, diagnosis)


def mismatch_places(d: Diagnosis, window_s: float) -> list[dict]:
    """Where a recording and the rigid-body model disagree, for a diagnosis that names nothing:
    :func:`~rig_identification.diagnosis.residuals.unexplained` of ``d.located`` (channel,
    band Hz, time s from the window's start, size, what the frequency is) over the diagnosis
    window (``window_s`` s when it kept no series), then the accelerometer's departures from
    Newton's prediction from the load cells above the fit band (``d.out_of_band``), over the
    whole window, their size in σ."""
    duration = float(d.series["t"][-1]) if d.series else window_s
    return unexplained(d.located, duration) + [
        {"channel": u["channel"], "band_hz": u["band_hz"], "time_s": [0.0, round(duration, 1)], "size": u["sigma"],
         "is": f"above the fit band: the accelerometer over Newton's prediction from the load cells departs from 1 "
               f"by {u['size']:.3g} ({u['sigma']:.0f} σ; size in σ) — a sensor mount's structural mode, or a body "
               "that is not rigid?"}
        for u in d.out_of_band]


def _why(hyp: dict) -> str:
    """A combination tried and not named, in one phrase: its effects and why not."""
    return f"{' + '.join(e['name'] for e in hyp['effects'])}: {hyp['not_named']}"


def _refit(full: Recording, alt: Combination, start: float | None, end: float | None,
           band_hz: tuple[float, float] | None) -> tuple[InertiaResult | None, dict]:
    """One combination tested the way every fit is: the recording ``full`` corrected, identified
    again with its wrench (same window and band), validated.  Returns (its fit when the
    validation says ``ok``, else None; the combination as tried: ``effects``, and when not named
    ``not_named`` (why) and ``failed_checks``).  A hypothesis by its own test (``not_named``
    set: the unfitted sprung body) or a combination with an implausible effect is not fitted."""
    names = [e["name"] for e in alt.effects]
    bad = [e for e in alt.effects if not e.get("plausible", True)]
    hyp: dict = {"effects": alt.effects}
    if alt.not_named:
        hyp["not_named"] = alt.not_named
        return None, hyp
    if bad:
        hyp["not_named"] = "not physically plausible: " + "; ".join(f"{e['name']}: {e['implausible']}" for e in bad)
        return None, hyp
    fixed = corrected(full, alt.applied)
    if alt.stiffness is not None:
        fixed = with_stiffness(fixed, alt.stiffness)
    log.info("identifying again with %s", ", ".join(names))
    try:
        fit = identify_recording(fixed, start=start, end=end, band_hz=band_hz, effect_wrench=alt.effect_wrench)
    except (ValueError, np.linalg.LinAlgError) as e:
        hyp["not_named"] = f"could not be identified again ({e})"
        return None, hyp
    if fit.validation is None or fit.validation.verdict != "ok":
        failed = () if fit.validation is None else fit.validation.failed
        hyp["not_named"] = (f"the fit with it does not determine the tensor (not_identifiable: "
                            f"{', '.join(failed + tuple(fit.undetermined))})"
                            if fit.validation is not None and fit.validation.verdict == "not_identifiable" else
                            f"the fit with it still fails its validation ({', '.join(failed)})")
        hyp["failed_checks"] = list(failed)
        return None, hyp
    return fit, hyp


def _not_explained(result: InertiaResult, rigid_body: dict, diagnosis: dict, hypotheses: list[dict],
                   where: list[dict]) -> InertiaResult:
    """``result`` (the rigid-body fit) with the diagnosis that names nothing: why, the
    hypotheses, where the mismatch is."""
    why = ("diagnose found no effect of its library that explains the misfit" if not hypotheses else
           "no combination of the library's effects explains it: " + "; ".join(_why(h) for h in hypotheses))
    names = [e["name"] for h in hypotheses for e in h["effects"]]
    diagnosis["handled"] = "not: " + why
    result.rigid_body, result.diagnosis = rigid_body, diagnosis
    result.warnings.append(
        f"model error not explained: {why}; the tensor is the rigid-body fit's (σ widened, not trustworthy)"
        + (f"; hypotheses, not findings: {', '.join(dict.fromkeys(names))}" if names else "")
        + ("; the mismatch is in " + ", ".join(f"{u['channel']} at {u['band_hz'][0] + 0.05:.2f} Hz"
                                               for u in where if u["band_hz"]) if where else ""))
    return result


def _named(result: InertiaResult, again: InertiaResult, chosen: Combination, rec: Recording, rigid_body: dict,
           diagnosis: dict) -> InertiaResult:
    """The fit ``again`` with the named combination ``chosen``: the cables' share taken off the
    tensor when their mass was found, σ at least diagnose's joint fit's (and widened by what the
    corrections fixed from outside the band leave), the diagnosis, verdict, method and warnings
    saying what was named (a class where the recording does not tell its candidates apart)."""
    effects = chosen.effects
    names = [effect_name(e) for e in effects]
    found = "; ".join(finding_text(e) for e in effects)   # with units, as the CLI's
    applied = chosen.applied
    mu = float(applied.get(("cable_mass", ""), 0.0))
    if mu:   # the fit's tensor is the body's with the cables' lower halves, about their combined CG
        body_rig = replace(rec.rig, mass=rec.rig.mass + float(applied.get(("body_mass", ""), 0.0)))
        again.inertia = body_inertia(again.inertia, body_rig, mu)
        again.mass, again.center_of_gravity = body_rig.mass, body_rig.require_cg().copy()
    if chosen.effect_wrench is not None and chosen.covariance is not None:
        # the effects' own uncertainty: diagnose's joint fit of the tensor with them
        joint = np.sqrt(np.clip(np.diag(chosen.covariance), 0, None))
        wider = np.maximum(joint, again.inertia_std)
        again.covariance = again.covariance + np.diag(wider**2 - again.inertia_std**2)
        again.inertia_std = wider
        again.uncertainty += "; at least diagnose's joint fit with the effects (their own uncertainty)"
    rel = chosen.relative_std
    if rel > 0:
        # a correction fixed from outside the fit band (a structural mode's shape) leaves a
        # relative error of the readings in the band, and so about of the tensor
        wider = np.sqrt(again.inertia_std ** 2 + (rel * entry_scales(from_tensor(again.inertia))) ** 2)
        again.covariance = again.covariance + np.diag(wider ** 2 - again.inertia_std ** 2)
        again.inertia_std = wider
        again.uncertainty += f"; with the {100 * rel:.3g} % the corrections fixed from outside the band leave"
    handled = ("removed from the data" if chosen.effect_wrench is None else
               "added to the model" if not applied and chosen.stiffness is None else
               "removed from the data and added to the model")
    diagnosis["effects"], diagnosis["hypotheses"], diagnosis["unexplained"] = effects, [], []
    again.rigid_body, again.diagnosis = rigid_body, {**diagnosis, "handled": handled}
    # the verdict is on the model with the effects, not the rigid body's alone
    modelled = ", ".join(e["name"] for e in effects)
    assert again.validation is not None   # _refit names only a fit whose validation is ok
    again.validation = replace(again.validation, model=f"the rigid-body model with {modelled}")
    again.method += f"; {', '.join(names)} diagnosed (rig-identify diagnose), {handled}, validated"
    rigid_verdict = result.validation.summary if result.validation is not None else None
    again.warnings = [w for w in result.warnings if w != rigid_verdict] + [
        f"model error diagnosed: {found} — {handled}, the recording identified again and validated (the "
        "rigid-body fit's verdict was model_error; it is under 'rigid_body' in the JSON, --no-diagnose reports "
        "it instead)"] + [w for w in again.warnings if w not in result.warnings]
    return again


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
    result.covariance = result.covariance + added
    result.inertia_std = np.sqrt(np.clip(np.diag(result.covariance), 0, None))
    result.cg_contribution_std = np.sqrt(np.clip(np.diag(added), 0, None))
    result.uncertainty += ("; with the CG's σ propagated (the tensor refitted with the CG ±1 σ along each "
                           "principal axis of its covariance)")
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
    each recording with :func:`~rig_identification.pipeline.prepare.prepare_recording` (the same
    start/end/settle window on each), then fits jointly with
    :func:`~rig_identification.estimation.identification.identify_inertia_joint` (each recording
    band-passed on its own, ``band_hz`` or automatic per recording) and, with ``refine``,
    :func:`~rig_identification.pipeline.sigma.refine_uncertainty` over them all.  One recording:
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
    refs = entry_scales([tru[k] for k in KEYS])
    out = {}
    for k, v, s, ref in zip(KEYS, from_tensor(result.inertia), result.inertia_std, refs):
        e = float(v - tru[k])
        out[k] = {"value": float(v), "truth": float(tru[k]), "error": e, "error_percent": 100 * e / ref,
                  "error_sigma": e / s if s > 0 else float(np.inf)}
    return out
