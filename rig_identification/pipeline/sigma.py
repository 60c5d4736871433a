"""A fit's σ from the sensors' noise: the fit compensated for the noise in its input and given the
σ that noise causes along the recordings' trajectories (:func:`refine_uncertainty`), or the
sandwich σ where the residual is model error (:data:`MODEL_ERROR_RATIO`).
"""
from __future__ import annotations

import logging

import numpy as np

from ..estimation.directions import weak_directions
from ..estimation.errors_in_variables import NoiseRealisations, antithetic_realisations
from ..estimation.identification import fit_segments, prepare_segment
from ..estimation.inertia_result import InertiaResult
from ..estimation.prediction import PlanError, combine
from ..estimation.spectral_wls import residual_excess
from ..estimation.uncertainty import confirmed_sigma_factor, noise_replays, propagated, sensor_noise
from ..model.parametrisation import from_tensor
from .prepare import PreparedRecording, replay_window

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them

REPLAY_PAIRS = 3   # antithetic pairs of replays with fresh noise: the input-noise compensation, a check of σ
CONFIRM_PAIRS = 3
"""Antithetic pairs more, replayed only where the first :data:`REPLAY_PAIRS` spread
significantly more than the propagated covariance predicts: σ is widened only when all of them
together (36 dof) still do, by their pooled Birge ratio.  Three pairs alone widened by chance
and by too much: bench_any_rig's 21005 and 23005 by 1.37 and 1.27, where 16 first-order draws of
the chain give 0.92 and 0.96; its 26022 (3 cables) by 1.92, where they give 1.49
(``bench_validation_null.py --any-rig SEED --first-order 16``; docs/validation.md)."""

MODEL_ERROR_RATIO = 2.0
"""Fit residual RMS over the one the sensors' noise predicts beyond which the residual is
model error.  Clean simulated recordings: 1.00–1.31 on 200 noisy 120 s replays of thesis
case 16; up to 1.47 on a 35 s one at 200 Hz (the tracker's start-up misfit, which the noise
does not explain, weighs more in a short run); the damped reference recording: 9.8."""


def refine_uncertainty(preps: list[PreparedRecording], result: InertiaResult, seed: int = 0) -> InertiaResult:
    """Compensate a prediction-error estimate for the noise in its input and give it the σ
    that the sensors' noise causes along the recordings' trajectories
    (:mod:`rig_identification.estimation.uncertainty`).

    preps: the prepared recording(s) the result was fitted to (one, or several for a joint
    fit, in the order of ``result.series``).  The white-noise σ of every stream is
    estimated from each recording (:func:`~rig_identification.estimation.uncertainty.sensor_noise`); tracker,
    preprocessor and identifier (same windows and bands) are re-run with
    :data:`REPLAY_PAIRS` antithetic pairs of fresh noise at those levels
    (:func:`~rig_identification.estimation.uncertainty.noise_replays`).  Their regressors and
    outputs are realisations of
    the noise the chain puts into the fit — the gyro's through the tracked pose into the
    moment included — and the fit is re-solved with the noise's second moments removed from
    its normal equations (bias-compensated least squares, :mod:`rig_identification.estimation.errors_in_variables`;
    ``errors_in_variables``; ``bias_correction`` the least-squares estimate's bias it removed).  The covariance is the
    linearised propagation of that noise through the same chain
    (:func:`~rig_identification.estimation.uncertainty.propagated`, recordings combined by
    :func:`~rig_identification.estimation.prediction.combine`),
    mapped onto the compensated estimate, with the compensation's own jackknife σ in
    quadrature: ``crb_std`` holds it.  Where the replays' draws spread significantly more than
    that covariance predicts, :data:`CONFIRM_PAIRS` pairs more are replayed and σ is widened by
    all the draws' Birge ratio if it is still significant (``replay_factor``;
    :meth:`~rig_identification.estimation.uncertainty.NoiseReplays.sigma_factor`).
    ``inertia_std`` and ``covariance`` are that σ unless the
    fit's residual RMS exceeds the one the noise predicts (the replays' residual
    realisations, over the series' interior:
    :func:`~rig_identification.estimation.spectral_wls.residual_excess`) by more than
    :data:`MODEL_ERROR_RATIO` on a gyro axis
    (``residual_excess``): that is model error, and the identifier's sandwich σ (from the
    residuals; always in ``sandwich_std``) is kept.  If the propagation fails (too little
    motion) the result keeps the sandwich σ with a warning.  seed: the replays' noise
    generator — fixed by default, so that the same recording is replayed with the same noise on
    every run (the replays' own sampling error is in σ: the compensation's jackknife, and the
    replays' Birge ratio check).  Not bit for bit: floating-point sums that depend on where the
    arrays sit in memory moved ``replay_sigma_factor`` by 10⁻⁶ relative between runs on
    test_validation's seed 7700 (docs/validation.md).  Returns ``result``, updated in place.
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
        # finite number of realisations adds the jackknife σ of the correction, and the
        # recording's own second-order noise term its spread about the mean removed
        cov = eiv.sensitivity @ cov @ eiv.sensitivity.T + np.diag(np.nan_to_num(eiv.correction_std) ** 2)
        if eiv.second_order is not None:
            cov = cov + eiv.second_order
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    result.crb_std = std.copy()
    # the linearised propagation checked against the replays' own spread (their Birge ratio
    # over 6 × REPLAY_PAIRS degrees of freedom, confirmed over CONFIRM_PAIRS more where it is
    # significant): where the replays spread more, σ follows them —
    # a tracker or rig the linearisation misses (a 3-cable rig: 1.47 over 6 pairs, 1.3–1.5 in
    # Monte Carlo over 8 recordings); never narrower than the propagation
    def more(pairs: int, first: int):
        log.info("σ: the replays spread significantly more than the propagation; %d replays more to confirm it",
                 2 * pairs)
        return noise_replays(fit, theta, [p.sensors for p in preps], noises, seed, pairs=pairs, first=first)

    verdict = confirmed_sigma_factor(replays, pred.covariance, more, CONFIRM_PAIRS)
    factor, replays = verdict.factor, verdict.replays
    if factor > 1.0:
        std = std * factor
        cov = cov * factor**2
        result.replay_factor = factor
    for s in result.series:   # the residual at the fitted tensor carries the estimate's error (validation)
        s.noise_covariance = cov.copy()
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
            f" (widened {result.replay_factor:.2f}× to the spread of {2 * len(replays.draws)} replays with fresh noise)"
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
