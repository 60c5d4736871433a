"""Diagnosis: where a recording and the rigid-body model disagree, and which physics is missing.

The model (:mod:`~rig_identification.estimation.identification`) is the Newton–Euler equation of
a rigid body on cables, fed with the measured generalized wrench.  Three groups of
residuals test it, each on the recording's window, band-passed like the identifier
(zero-phase Butterworth, scipy ``sosfiltfilt``):

* **rotational** (gyro x, y, z): the band-limited output error of the integrated Euler
  equation, ``y = F ω`` vs ``ŷ = F P ∫(M − ω × Jω)``, as in the identifier;
* **translational** (accelerometer x, y, z): the measured specific force at the IMU vs
  Newton's law, ``F/m + α × ρ + ω × (ω × ρ)`` (ρ = IMU − CG, α = dω/dt), band-passed;
* **mean levels**: the mean gyro vs the net rotation over the window (the tracker's
  orientation), the mean specific force vs the mean F/m, the mean moment vs
  ``J mean(ω̇) + mean(ω × Jω)``, and the load cells' mean vertical force (world axes)
  vs rig.yaml's weight, m (g + mean vertical acceleration), with σ the cells' calibration
  (:data:`WEIGHT_SIGMA`): the one mean level the accelerometer does not enter, which tells
  a body heavier than rig.yaml says (or cables hanging on it) from an accelerometer bias.

Each candidate of the effect library (:mod:`~rig_identification.model.effects`) extends the
model by terms that are *linear in its parameters* (moment and force regressors,
output corrections, mean offsets; a sensor delay to first order, ``M(t − d) ≈ M − d Ṁ``),
so the extended model is fitted jointly with the tensor by variable projection: the
effect parameters by linear least squares for each tensor, Levenberg–Marquardt (scipy
``least_squares``) on the physically consistent log-Cholesky tensor parameters
(:func:`~rig_identification.model.parametrisation.consistent_from_params`).

The wrench components (force, torque: the Newton–Euler equation errors, the torque with
the mean moment, which must vanish over a window) and each load cell (the tension
correction that best explains them, least squares) are channels too.

Each channel's residual RMS is reported twice: as it is, and time-synchronously averaged
over the exciter's revolutions (:func:`synchronous_rms`): the part locked to the forcing,
with the sensor noise averaged down by about √(revolutions).  A model error smaller than
the noise (the gyroscopic term at a planned excitation: under half the gyro noise in the
band) barely moves the plain RMS, but is most of the synchronous one.

Baseline: the rig.yaml taken literally, with the cables' stiffness from rig.yaml, or —
when it gives none — fitted by the tracker (steel cables stretch 1–2 mm; the reference
recordings need it).  ``cable_elasticity`` is a candidate when rig.yaml states a stiffness
(the tracker then re-fits it), or when the fitted static stretch exceeds
:data:`STEEL_STRETCH` (then against rigid cables).

Sensor and rig errors (``sensor_delay``, ``imu_offset``, ``imu_misalignment``, the biases,
``load_cell_scale``, ``body_mass``, ``cable_elasticity``) also move the tracked pose, which the first-order
columns do not see: the most promising of them (:data:`EXACT_SCREEN` per step) are
evaluated exactly — the error removed from the data (:func:`corrected`), the pose
re-tracked, the model refitted, Broyden iterations on the first-order remainder — and the
selected one is iterated to convergence.  A load cell's gain (one candidate per cable)
moves the tracker's static pose (it balances forces and moments with the tensions) so
much that its first-order column points the wrong way: every significant one is
evaluated exactly at ±:data:`GAIN_STEP` (:func:`exact_screen`), and the selected one is
found by its exact profile likelihood (:func:`~rig_identification.diagnosis.exact.exact_profile`).
So is ``cable_mass``,
always: the lower half of each cable (μ kg) hangs on its body anchor, outside the load
cell at the ceiling, so the body the tensions move is heavier, its centre of gravity
higher and its tensor larger than rig.yaml's (:func:`corrected` gives the rig that body;
:func:`body_inertia` takes the cables' share off the fitted tensor).  To first order, its
moment is nearly collinear with the tensor and its weight with an accelerometer bias and
the load-cell gains; exactly, the re-tracked pose and the mean levels separate them.  A
``body_mass`` error (rig.yaml's body.mass off by δ: a weighing error) gives the same weight
surplus without the cables' lever arms, and competes with it the same way (else a 6 kg
weighing error was named a 1.1 kg cable mass, and "corrected" Ixx by −0.34 %).  Both are
evaluated when the load cells carry more (the body's mass: or less) than the weight by
:data:`WEIGHT_SURPLUS_SIGMA`, and their trial re-tracks keep the steel stretch fitted last
(a mass changes no tension), which is fitted again once one is selected.

Weights: each axis of the rotational and translational groups by its own residual scale
(the axes' scales differ several-fold: a pooled scale biased the tensor by several per
cent on some rigs, the identifier weights per axis too); the scales of the baseline fit
during the selection, the final fit's own afterwards (iteratively reweighted).

Selection: forward stepwise, by the likelihood-ratio statistic
``Λ = Σ_g N_eff,g ln(RSS_g,0 / RSS_g,1) + Δχ²_DC`` (Gaussian residuals with the
noise scale of each group; N_eff,g is the number of independent samples of the
band-passed residual: N · 2 (f_hi − f_lo) / f_s), against the χ² quantile of the
effect's number of parameters at p = :data:`ALPHA` / (number of candidates tried)
(Bonferroni).  An effect is kept only if it also reduces the residual RMS of some
channel by at least :data:`MIN_REDUCTION`, and a sensor-pose error must exceed the
engineering resolution :data:`PRACTICAL_FLOOR` (5 mm, 1 mrad, 1 ms): a statistically but
not physically significant term is not a finding.  ``gyroscopic_coupling`` is exempt from
the residual reduction: its size is known (κ = 1), and the test is whether κ = 0 is
rejected.  Standard deviations of the effect parameters: the
sandwich (batch-means) covariance, as the identifier's.

References: Ljung, *System Identification* (2nd ed., 1999), §16.4 (model validation by
residual analysis: whiteness, cross-correlation with the inputs) and §16.6 (likelihood
ratio and information criteria for model structure selection).
"""
from __future__ import annotations

import math
from collections import OrderedDict
from itertools import combinations

import numpy as np
from scipy.stats import chi2

from ..estimation.identification import IdentificationError, identify_inertia
from ..io.recording import Recording, RecordingError
from ..model.effects import EFFECT_NAMES
from ..model.parametrisation import from_tensor
from .candidates import CORRECTIONS, body_inertia, candidates, corrected, with_stiffness
from .distinguish import ambiguity, preferred
from .exact import (
    MASSES,
    PROFILED,
    columns_of,
    exact_iterate,
    exact_screen,
    likelihood_ratio,
    log_sf,
    mass_builder,
    residual_scales,
    weight_surplus,
)
from .finding import finding
from .model_extension import Model, fit_model
from .plausible import PRACTICAL_FLOOR
from .residuals import channel_residuals, effective_samples, exciter_phase, locate, rms, synchronous, synchronous_rms
from .result import Diagnosis, EffectWrench
from .retracked import DRIFT_STEP, SCALE_STEP, knots
from .retracked import columns as retracked_columns
from .structural import SENSORS as MODE_SENSORS
from .structural import fit_mode, out_of_band, transfer
from .window import Window, prepare_window

ALPHA = 0.01          # family-wise false-alarm probability of the selection
MIN_REDUCTION = 0.05  # an effect must reduce some channel's residual RMS by at least this fraction
MAX_EFFECTS = 3
EXACT_SCREEN = 4      # sensor/rig-error candidates evaluated exactly (re-tracked) per screening
POOL = 5              # the most significant screened candidates searched jointly
TRIPLES_FROM = 4      # triples among the first this many of the pool
MASKED = 2            # candidates significant only given the best combination, fitted with it
ALTERNATIVES = 3      # admissible combinations reported (and validated by the caller), the best first
EXCLUSIVE = ({"gyro_bias", "gyro_bias_drift"},)
"""Effects of which one contains the other (a constant bias is a drift with equal knots):
never fitted together."""
# the masses are evaluated exactly when the cells carry this many σ more (or less) than the weight
WEIGHT_SURPLUS_SIGMA = 3.0
# engineering resolution: a smaller sensor-pose error is no finding, however significant
WINDOW_CACHE = 8      # re-tracked windows kept (by their corrections): the joint search re-uses them
MODEL_CACHE = 3       # models of the last re-tracked windows kept (each a dozen band-passed (N,3) arrays)
STEEL_STRETCH = 4e-3  # m: static stretch beyond which cables without a rig.yaml stiffness are not "steel-like"


# --- diagnosis ------------------------------------------------------------------------------

def diagnose(rec: Recording, model: str = "pem", max_effects: int = MAX_EFFECTS, alpha: float = ALPHA,
             band_hz: tuple[float, float] | None = None, cg_free: bool = False,
             cg_covariance: np.ndarray | None = None) -> Diagnosis:
    """Diagnose a dynamic recording (see module docstring).

    model: ``"pem"`` (ours, with the gyroscopic term) or ``"thesis"`` (the thesis's model:
    no ω × Jω).  The baseline is the rig.yaml taken literally: cables without a stiffness
    are inextensible.  Every candidate is screened alone against it; the most significant
    (:data:`POOL`) are then fitted together in every combination of up to ``max_effects``
    (triples among the first :data:`TRIPLES_FROM`), sensor and rig errors removed from the
    data and the pose re-tracked (:func:`corrected`) jointly, and the admissible
    combinations (every member significant given the others, and practical) are ranked by
    the Bayesian information criterion.  The best is :attr:`Diagnosis.effects`; it and
    the next ones are :attr:`Diagnosis.alternatives`, which the caller validates
    (:func:`~rig_identification.pipeline.offline.with_diagnosis`).  cg_free: rig.yaml's centre
    of gravity is a candidate error too (``cg_offset``; off by default: on the independent
    simulator's recordings, whose rig.yaml CG is the truth, it took up 29–111 mm of height on
    four of eight, docs/results.md).  cg_covariance: (3, 3) m², the σ of the CG the recording
    was given (a static test's): the CG is then a candidate, plausible within 3 σ of it.
    Returns a :class:`Diagnosis`.  Raises RecordingError, RigError, TrackerError,
    IdentificationError for recordings no fit can be made of.
    """
    if model not in ("pem", "thesis"):
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    warnings: list[str] = []
    kappa0 = 1.0 if model == "pem" else 0.0
    R_yaml = rec.rig.imu.rotation.as_matrix()
    state = {"applied": {}, "elastic": False, "band": band_hz, "candidate": True, "retracked": {},
             "cg_free": cg_free or cg_covariance is not None, "cg_covariance": cg_covariance}
    declared = np.isfinite(rec.rig.cable_stiffness).all()

    windows: OrderedDict = OrderedDict()   # the last WINDOW_CACHE windows, by their corrections

    def window_of(applied, elastic=False, keep_stretch=False):
        mode = "fitted" if elastic else ("declared" if declared else "rigid")
        # keep_stretch: the steel stretch fitted last is kept (one tracker pass, not two)
        steel = keep_stretch and "steel" in state
        key = (mode, _applied_key(applied), _array_key(state["steel"]) if steel else None)
        if key in windows:
            windows.move_to_end(key)
            return windows[key]
        src = with_stiffness(rec, state["steel"]) if steel else rec
        w = prepare_window(corrected(src, applied), warnings=[] if state["band"] else warnings,
                           cables=mode, imu_rot_yaml=R_yaml)
        windows[key] = w
        if len(windows) > WINDOW_CACHE:
            windows.popitem(last=False)
        return w

    models: OrderedDict = OrderedDict()    # id(window) -> (window, its Model in the band): one model per window

    def build(applied, elastic, profiled=None, keep_stretch=False):
        w = window_of(applied, elastic, keep_stretch)
        hit = models.get(id(w))
        if hit is not None and hit[0] is w and hit[1].band == state["band"]:
            M = hit[1]
            models.move_to_end(id(w))
        else:
            M = Model(w, state["band"])
            models[id(w)] = (w, M)
            if len(models) > MODEL_CACHE:
                models.popitem(last=False)
        M.n_eff_group = state.get("n_eff_group", {})
        state["band"] = M.band
        return w, M, candidates(w, M, kappa0, applied, allow_elasticity=state["candidate"] and not elastic,
                                profiled=state.get("profiled") if profiled is None else profiled,
                                retracked=state["retracked"], cg_free=state["cg_free"])

    if not declared:
        # rig.yaml gives no stiffness: steel cables stretch 1-2 mm, which the baseline fits
        # (the tracker's compliance); only a stretch beyond STEEL_STRETCH makes the cables'
        # elasticity a candidate, against the rigid-cable model
        w, M, cands = build({}, True)
        k = w.stiffness
        stretch = float(np.median(np.median(w.tensions, axis=0) / k))
        if stretch <= STEEL_STRETCH:
            state["candidate"] = False
            declared = True          # the fitted stiffness is the baseline's
            state["steel"] = k       # the last fitted (N/m per cable)
        else:
            warnings.append(f"the cables stretch {1e3 * stretch:.1f} mm under the static load (fitted stiffness "
                            f"{np.median(k):.3g} N/m), more than steel cables' 1-2 mm: cable elasticity is tested "
                            "against rigid cables")
            w, M, cands = build({}, False)
    else:
        w, M, cands = build({}, False)
    band = M.band
    j0 = from_tensor(identify_inertia(rec.rig, w.t, w.omega, w.torque, band_hz=band).inertia)
    scales = residual_scales(M, fit_model(M, [], kappa0, False, (1.0, 1.0, 1.0, 1.0, 1e9), j0))
    base = fit_model(M, [], kappa0, False, scales, j0)
    state["n_eff_group"] = M.n_eff_group = {"rot": min(M.n_eff, effective_samples(base.rot)),
                                            "tr": min(M.n_eff, effective_samples(base.tr))}
    M0, ch0 = M, channel_residuals(M, base)
    rms0 = rms(ch0)
    extra_lam = _retracked(state, window_of, w, M, warnings)
    cands = candidates(w, M, kappa0, state["applied"], allow_elasticity=state["candidate"],
                       profiled=state.get("profiled"), retracked=state["retracked"], cg_free=state["cg_free"])
    # the bias drift counts in the family of candidates whether or not its gate opens
    threshold_p = alpha / max(1, len(cands) + 1)
    cost0 = base.cost(scales)
    n_ic = 3 * sum(M.n_eff_group.values()) + 10     # independent residuals: the two groups' and the mean levels
    state["cands"] = cands
    tried: list = []
    ctx = {"w": w, "M": M, "cands": cands, "fit": base, "applied": dict(state["applied"]), "keys": [],
           "elastic": False, "free_kappa": False, "rms": rms0, "cost": cost0}
    screened = _screen(ctx, state, build, kappa0, scales, threshold_p, extra_lam, tried, warnings, step=1)
    # the gyro's bias drift (3K columns, 3K re-tracks: the costliest candidate) only where a
    # constant gyro bias is significant: a drift the constant cannot stand in for at all
    # (zero mean over the window on every axis) is not looked for
    bias = next((e for e in screened if e["c"].name == "gyro_bias"), None)
    if (bias is not None and chi2.sf(max(bias["lam_first"], 0.0), bias["dof"]) < threshold_p
            and _drift_columns(state, window_of, w, M, warnings)):
        cands = candidates(w, M, kappa0, state["applied"], allow_elasticity=state["candidate"],
                           profiled=state.get("profiled"), retracked=state["retracked"], cg_free=state["cg_free"])
        state["cands"] = cands
        ctx_d = {**ctx, "cands": [c for c in cands if c.name == "gyro_bias_drift"], "applied": dict(state["applied"])}
        screened += _screen(ctx_d, state, build, kappa0, scales, threshold_p, extra_lam, tried, warnings, step=1)
    pool = _pool(screened, threshold_p)
    evals: dict = {}

    def joint(members) -> dict:
        key = frozenset(m["c"].key for m in members)
        if key not in evals:
            evals[key] = _joint(members, state, build, kappa0, scales, cost0, j0, extra_lam, n_ic, warnings)
        return evals[key]

    size = min(max_effects, 3)
    subsets = [(m,) for m in pool]
    subsets += [s for s in combinations(pool, 2) if size >= 2]
    subsets += [s for s in combinations(pool[:TRIPLES_FROM], 3) if size >= 3]
    for s in subsets:
        if _exclusive(s):
            continue
        joint(s)
    # a bias drift is named only when it explains more than a constant bias would in its place
    constant = next((e for e in screened if e["c"].name == "gyro_bias"), None)

    def nested():
        for ev in list(evals.values()):
            if constant is not None and any(m["c"].name == "gyro_bias_drift" for m in ev["members"]):
                joint(tuple(constant if m["c"].name == "gyro_bias_drift" else m for m in ev["members"]))

    nested()
    ranked = _admissible(evals, threshold_p, rms0)
    # a candidate masked by the best combination's effects (significant only with them in the
    # model): one more screening given that combination, its new significant candidates fitted
    # with it
    if ranked and len(ranked[0]["members"]) < size:
        best = ranked[0]
        bw, bM, bc = build(best["applied"], best["elastic"], best["profiled"], best["keep_stretch"])
        ctx = {"w": bw, "M": bM, "cands": bc, "fit": best["fit"], "applied": best["applied"], "keys": best["keys"],
               "elastic": best["elastic"], "free_kappa": best["free_kappa"], "rms": best["rms"],
               "cost": best["fit"].cost(scales), "profiled": best["profiled"]}
        more = [e for e in _pool(_screen(ctx, state, build, kappa0, scales, threshold_p, extra_lam, tried, warnings,
                                         step=2), threshold_p) if e["c"].key not in best["keys"]][:MASKED]
        for e in more:
            s = tuple(best["members"]) + (e,)
            if not _exclusive(s):
                joint(s)
                for m in best["members"]:
                    joint(tuple(x for x in s if x is not m))
        nested()
        ranked = _admissible(evals, threshold_p, rms0)
    # the recording may not tell the best combination from a rival: the misfit modelled with
    # the preferred one (data errors first, then the fewest parameters), the members in doubt
    # named by their class, with the candidates
    ranked = preferred(ranked, threshold_p)
    doubt = {k: d for d in ambiguity(ranked, threshold_p) for k in d["candidate_keys"]}
    joints = [{"effects": [(m["c"].name, m["c"].label) for m in ev["members"]], "likelihood_ratio": ev["lam"],
               "dof": ev["dof"], "bic": ev["bic"], "admissible": ev.get("admissible", False),
               **({"why": ev["why"]} if ev.get("why") else {})}
              for ev in sorted(evals.values(), key=lambda e: e["bic"])]
    # the best combination's admissible proper subsets too (the caller names the smallest one
    # that passes validation: an effect is named only when the model fails without it)
    shown = ranked[:ALTERNATIVES]
    if ranked and len(ranked[0]["members"]) > 1:
        shown += [ev for ev in ranked[ALTERNATIVES:] if set(ev["keys"]) < set(ranked[0]["keys"])]
    found = []
    for ev in shown:
        try:
            found.append(finding(ev, rec, state, build, kappa0, scales, cost0, doubt))
        except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
            warnings.append(f"combination {', '.join(m['c'].name for m in ev['members'])}: its report failed ({err})")
    # the combinations whose every member is plausible and determined first (in their order):
    # the first of them is the diagnosis's finding, with its residuals and series
    found.sort(key=lambda cf: not all(e.get("plausible", True) for e in cf[0].effects))
    alternatives = [c for c, _ in found]
    first = found[0][1] if found else None
    located = locate(M0, base, rec.rig, base.J)
    std_of = lambda f: np.sqrt(np.clip(np.diag(f.cov)[:6], 0, None))  # noqa: E731
    if alternatives:
        a = alternatives[0]
        effects, applied, wrench, stiffness, inertia = a.effects, a.applied, a.effect_wrench, a.stiffness, a.inertia
        fit1, M1, w1, ch1 = first.fit, first.model, first.window, first.channels
    else:
        effects, applied, wrench, stiffness, inertia = [], {}, None, None, base.J
        fit1, M1, w1, ch1 = base, M0, w, ch0
    (sync0, revs), (sync1, _) = synchronous(M0, ch0), synchronous(M1, ch1)
    return Diagnosis(bool(effects), effects, located, rms0, rms(ch1), base.J, inertia,
                     std_of(base), std_of(fit1), tried, band, model, warnings + list(rec.warnings),
                     series={"t": w1.t - w1.t[0], "fs": M1.fs, "before": ch0, "after": ch1},
                     covariance_after=np.array(fit1.cov[:6, :6]),
                     corrections={k: v for k, v in applied.items() if k[0] in CORRECTIONS},
                     rms_sync_before=sync0, rms_sync_after=sync1, revolutions=revs,
                     effect_wrench=wrench, applied=dict(applied), stiffness=stiffness,
                     alternatives=alternatives, joint=joints, out_of_band=state.get("out_of_band", []))


def _drift_columns(state: dict, window_of, w: Window, M: Model, warnings: list) -> bool:
    """The first-order columns of the gyro's bias drift (one per axis and knot, by finite
    differences of re-tracked windows: :mod:`~rig_identification.diagnosis.retracked`) into
    ``state["retracked"]["drift"]``, its knots into ``state["applied"]``.  Returns whether
    they could be made."""
    applied = state["applied"]
    try:
        ref = window_of(applied, False, True)
        kn = knots(w.t[0], w.t[-1])
        n = 3 * len(kn)
        trials = []
        for a in range(3):
            for k in range(len(kn)):
                c = np.zeros(n)
                c[a * len(kn) + k] = DRIFT_STEP
                trials.append((f"bias_{'xyz'[a]}_{k}", {**applied, ("gyro_bias_drift", "knots"): kn,
                                                         ("gyro_bias_drift", ""): c}, DRIFT_STEP))
        state["retracked"]["drift"] = (retracked_columns(lambda ap: window_of(ap, False, True), ref, M, trials), kn)
        applied[("gyro_bias_drift", "knots")] = kn
        return True
    except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
        warnings.append(f"the gyro's bias drift could not be re-tracked ({err}); it is not tried")
        state["retracked"].pop("drift", None)
        return False


def _array_key(x) -> tuple:
    """A hashable, exact key of a correction's value (a number, an array or a tuple of them)."""
    if isinstance(x, tuple):
        return tuple(_array_key(v) for v in x)
    a = np.asarray(x, float)
    return (a.shape, a.tobytes())


def _applied_key(applied: dict) -> tuple:
    """A hashable, exact key of the corrections ``applied`` (key -> value): equal keys, equal
    corrected recordings (:func:`corrected`), so equal re-tracked windows."""
    return tuple(sorted((k, _array_key(v)) for k, v in applied.items()))


def _retracked(state: dict, window_of, w: Window, M: Model, warnings: list) -> dict:
    """The first-order columns of the gyro's bias drift and scale factors, by finite
    differences of re-tracked windows (:mod:`~rig_identification.diagnosis.retracked`), and
    the structural modes the transfer above the band shows
    (:mod:`~rig_identification.diagnosis.structural`), into ``state["retracked"]``; the
    drift's knots and the modes' shapes into ``state["applied"]`` (inert until their value
    is set).  Returns the modes' out-of-band likelihood ratios (key -> Λ), evidence beyond
    the fit band's."""
    applied = state["applied"]
    extra = {}
    try:
        ref = window_of(applied, False, True)
        trials = [(f"scale_{'xyz'[a]}", {**applied, ("gyro_scale", ""): SCALE_STEP * np.eye(3)[a]}, SCALE_STEP)
                  for a in range(3)]
        state["retracked"]["scale"] = retracked_columns(lambda ap: window_of(ap, False, True), ref, M, trials)
    except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
        warnings.append(f"the gyro's scale could not be re-tracked ({err}); it is not tried")
        state["retracked"].pop("scale", None)
    tr = transfer(w, M)
    state["out_of_band"] = out_of_band(tr)
    for sensor in MODE_SENSORS:
        fit = fit_mode(tr, sensor, M.fs)
        if fit is None:
            continue
        state["retracked"].setdefault("modes", {})[sensor] = fit
        applied[("structural_mode", sensor + " shape")] = (fit.frequency, fit.damping_ratio)
        state.setdefault("fixed", {})[("structural_mode", sensor)] = fit.participation
        extra[("structural_mode", sensor)] = fit.likelihood_ratio
    return extra


def _screen(ctx: dict, state: dict, build, kappa0: float, scales, threshold_p: float, extra_lam: dict, tried: list,
            warnings: list, step: int) -> list:
    """Every candidate not in ``ctx["keys"]`` added alone to the model of ``ctx`` (window,
    model, candidates, fit, corrections, keys, residual RMS and cost): first order, and
    exactly for the data errors (every significant load-cell gain and, when the cells carry
    more or less than the weight, the masses at trial values; the most promising
    :data:`EXACT_SCREEN` others iterated; the structural modes at their fitted values).
    Appends each to ``tried``; returns the screening entries (dict: c, lam, dof, fit, red,
    exact_state, log_p)."""
    M, cands, cur_fit, keys = ctx["M"], ctx["cands"], ctx["fit"], ctx["keys"]
    cost_cur, rms_cur, free_kappa = ctx["cost"], ctx["rms"], ctx["free_kappa"]
    st = {**state, "applied": dict(ctx["applied"]), "elastic": ctx["elastic"], "cands": cands,
          "profiled": dict(ctx.get("profiled") or {})}
    prof = st["profiled"]

    def bld(applied, elastic, profiled=None, keep_stretch=False):
        return build(applied, elastic, prof if profiled is None else profiled, keep_stretch)

    base_cols = columns_of(cands, keys)
    screened = []
    elastic_cache = None
    for c in cands:
        if c.key in keys:
            continue
        fk = free_kappa or c.gyroscopic
        Mc = M
        try:
            if c.name == "cable_elasticity":
                if elastic_cache is None:
                    elastic_cache = build(st["applied"], True, prof)
                _, Mc, ce = elastic_cache
                fit = fit_model(Mc, columns_of(ce, keys), kappa0, fk, scales, from_tensor(cur_fit.J))
            elif c.key in state.get("fixed", {}):
                _, Mc, ce = bld({**st["applied"], c.key: state["fixed"][c.key]}, st["elastic"])
                fit = fit_model(Mc, columns_of(ce, keys), kappa0, fk, scales, from_tensor(cur_fit.J))
            else:
                fit = fit_model(M, base_cols + c.columns, kappa0, fk, scales, from_tensor(cur_fit.J))
        except (np.linalg.LinAlgError, ValueError, RecordingError) as e:
            warnings.append(f"candidate {c.name} {c.label}: fit failed ({e})")
            continue
        lam = likelihood_ratio(cost_cur, fit.cost(scales), Mc) + extra_lam.get(c.key, 0.0)
        dof = (len(c.columns) + (1 if c.gyroscopic else 0) + (1 if c.name == "cable_elasticity" else 0)
               + (3 if c.name == "structural_mode" else 0))
        if c.name in PRACTICAL_FLOOR:
            size = float(np.linalg.norm(fit.beta[len(base_cols):len(base_cols) + len(c.columns)]))
            if size + float(np.linalg.norm(np.atleast_1d(st["applied"].get(c.key, 0.0)))) < PRACTICAL_FLOOR[c.name]:
                tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(lam),
                              "dof": dof, "p_value": float(chi2.sf(max(lam, 0.0), dof)), "max_rms_reduction": 0.0,
                              "exact": False, "below_practical_floor": PRACTICAL_FLOOR[c.name]})
                continue
        rms1 = rms(channel_residuals(Mc, fit))
        red = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
        fixed = c.key in state.get("fixed", {})
        screened.append({"c": c, "lam": lam, "lam_first": lam, "fit": fit, "red": red, "dof": dof,
                         "exact_state": ({**st["applied"], c.key: state["fixed"][c.key]}, None, None, None)
                         if fixed else None})
    # sensor and rig errors move the tracked pose too: the most promising ones are
    # evaluated exactly (data corrected, re-tracked, two Broyden steps)
    promising = sorted((e for e in screened if e["c"].exact and e["c"].name not in PROFILED
                        and e["c"].name != "cable_elasticity" and e["exact_state"] is None
                        and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p), key=lambda e: -e["lam"])
    # a load cell's gain and the cables' or the body's mass move the tracker's static pose,
    # so their first-order columns are no guide to their size or evidence: every
    # significant gain, and the masses when the cells carry more (or less) than the weight
    # (the cables' column is nearly collinear with the tensor), are evaluated exactly
    surplus = weight_surplus(M, cur_fit)
    for e in screened:
        if (e["c"].name == "cable_mass" and surplus > WEIGHT_SURPLUS_SIGMA) or (
                e["c"].name == "body_mass" and abs(surplus) > WEIGHT_SURPLUS_SIGMA) or (
                e["c"].name == "load_cell_scale" and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p):
            try:
                exact_screen(e, st, mass_builder(bld, e["c"].key), keys, cost_cur, rms_cur, kappa0,
                             free_kappa, scales, from_tensor(cur_fit.J), ctx["w"])
            except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
                warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
                e["lam"] = -np.inf
    for e in promising[:EXACT_SCREEN]:
        keys_e = keys + [e["c"].key]
        try:
            applied, we, Me, ce, fe = exact_iterate(e["c"].key, st, bld, keys_e, e["fit"], 2, kappa0, free_kappa,
                                                    scales)
        except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
            warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
            e["lam"] = -np.inf
            continue
        e["lam"] = likelihood_ratio(cost_cur, fe.cost(scales), Me)
        rms1 = rms(channel_residuals(Me, fe))
        e["red"] = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
        e["fit"] = fe
        e["exact_state"] = (applied, None, None, None)
    for e in screened:
        c = e["c"]
        p = float(chi2.sf(max(e["lam"], 0.0), e["dof"])) if np.isfinite(e["lam"]) else 1.0
        e["log_p"] = log_sf(e["lam"], e["dof"]) if np.isfinite(e["lam"]) else 0.0
        tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(e["lam"]),
                      "dof": e["dof"], "p_value": p, "max_rms_reduction": max(e["red"].values()),
                      "exact": e["exact_state"] is not None})
    return screened


def _pool(screened: list, threshold_p: float) -> list:
    """The candidates of the joint search: significant (p below ``threshold_p``), practical
    (some channel's residual RMS down by :data:`MIN_REDUCTION`; the gyroscopic term exempt:
    its size is known), data errors only once evaluated exactly; the strongest evidence first
    (the smallest p-value, its parameters counted), at most :data:`POOL`."""
    ok = [e for e in screened if np.isfinite(e["lam"])
          and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p
          and (max(e["red"].values()) >= MIN_REDUCTION or e["c"].gyroscopic)
          and (not e["c"].exact or e["c"].name == "cable_elasticity" or e["exact_state"] is not None)]
    return sorted(ok, key=lambda e: e["log_p"])[:POOL]


def _exclusive(members) -> bool:
    """Whether ``members`` hold two effects one of which contains the other (:data:`EXCLUSIVE`)."""
    names = {m["c"].name for m in members}
    return any(pair <= names for pair in EXCLUSIVE)


def _joint(members, state: dict, build, kappa0: float, scales, cost0: dict, j0: np.ndarray, extra_lam: dict,
           n_ic: float, warnings: list) -> dict:
    """The effects of ``members`` (screening entries) fitted together: the data errors
    removed at their screened values (:func:`corrected`), the pose re-tracked, the model
    refitted with every member's columns, each iterated data error moved by two more
    Broyden steps with the others in place (:func:`~rig_identification.diagnosis.exact.exact_iterate`).
    Returns the evaluation: members, keys, corrections, the fit, the likelihood ratio
    against the rigid-body fit (plus the structural modes' out-of-band evidence), its dof and
    the Bayesian information criterion −Λ + dof ln n (n: independent residuals)."""
    keys = [m["c"].key for m in members]
    applied = dict(state["applied"])
    for m in members:
        if m["exact_state"] is not None and m["c"].key in m["exact_state"][0]:
            applied[m["c"].key] = m["exact_state"][0][m["c"].key]
    elastic = any(m["c"].name == "cable_elasticity" for m in members)
    profiled = {m["c"].key: np.nan for m in members if m["c"].name in PROFILED}
    exact = [m for m in members if m["c"].exact and m["c"].name != "cable_elasticity"]
    keep = bool(exact) and all(m["c"].name in MASSES for m in exact)
    free_kappa = any(m["c"].gyroscopic for m in members)
    dof = sum(m["dof"] for m in members)
    out = {"members": list(members), "keys": keys, "elastic": elastic, "profiled": profiled, "keep_stretch": keep,
           "free_kappa": free_kappa, "dof": dof, "lam": -np.inf, "bic": np.inf}

    def bld(ap, el, pr=None, keep_stretch=False):
        return build(ap, el, profiled if pr is None else pr, keep_stretch or keep)

    try:
        w, M, cands = bld(applied, elastic)
        fit = fit_model(M, columns_of(cands, keys), kappa0, free_kappa, scales, j0)
        for m in exact:
            if m["c"].name in PROFILED or m["c"].key in state.get("fixed", {}):
                continue
            applied, w, M, cands, fit = exact_iterate(m["c"].key, {"applied": applied, "elastic": elastic,
                                                                   "cands": cands}, bld, keys, fit, 2, kappa0,
                                                      free_kappa, scales)
    except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
        warnings.append(f"combination {', '.join(m['c'].name for m in members)}: fit failed ({err})")
        out["why"] = f"fit failed ({err})"
        return out
    lam = likelihood_ratio(cost0, fit.cost(scales), M) + sum(extra_lam.get(k, 0.0) for k in keys)
    out.update(applied=applied, fit=fit, lam=float(lam), bic=float(-lam + dof * math.log(n_ic)),
               rms=rms(channel_residuals(M, fit)))
    return out


def _admissible(evals: dict, threshold_p: float, rms0: dict) -> list:
    """The combinations in which every member earns its place, by the Bayesian information
    criterion (the smallest first): its likelihood ratio over the combination without it
    significant at ``threshold_p`` (χ² of its dof; without it: the rigid-body fit, Λ = 0),
    and some channel's residual RMS down by :data:`MIN_REDUCTION` (the gyroscopic term
    exempt); a bias drift must beat a constant bias in its place (χ² of the dof it adds).
    Marks every evaluation ``admissible`` (with ``why`` not) and each member's evidence."""
    for ev in evals.values():
        ev["admissible"], ev["why"], ev["evidence"] = False, ev.get("why"), {}
        if not np.isfinite(ev["lam"]):
            continue
        why = None
        for m in ev["members"]:
            key = m["c"].key
            rest = frozenset(k for k in ev["keys"] if k != key)
            sub = evals.get(rest) if rest else {"lam": 0.0, "rms": rms0}
            if sub is None or not np.isfinite(sub["lam"]):
                why = f"{m['c'].name} not tested without it"
                break
            lam = ev["lam"] - sub["lam"]
            p = float(chi2.sf(max(lam, 0.0), m["dof"]))
            rms_ref = sub["rms"]
            red = {k: 1 - ev["rms"][k] / rms_ref[k] for k in ev["rms"] if rms_ref.get(k, 0) > 0}
            ev["evidence"][key] = {"likelihood_ratio": float(lam), "dof": m["dof"], "p_value": p,
                                   "threshold_p": threshold_p, "rms_reduction": red}
            if p >= threshold_p:
                why = f"{m['c'].name} adds nothing significant to the others (Λ {lam:.3g}, {m['dof']} dof)"
                break
            if max(red.values()) < MIN_REDUCTION and not m["c"].gyroscopic:
                why = f"{m['c'].name} reduces no channel's residual by {100 * MIN_REDUCTION:.0f} %"
                break
            if m["c"].name == "gyro_bias_drift":
                const = frozenset(rest | {("gyro_bias", "")})
                ref = evals.get(const)
                if ref is not None and np.isfinite(ref["lam"]):
                    extra = ev["lam"] - ref["lam"]
                    dd = m["dof"] - 3
                    if chi2.sf(max(extra, 0.0), dd) >= threshold_p:
                        why = f"the drift explains no more than a constant gyro bias (Λ {extra:.3g}, {dd} dof)"
                        break
        ev["admissible"], ev["why"] = why is None, why
    return sorted((ev for ev in evals.values() if ev["admissible"]), key=lambda e: e["bic"])


# the diagnosis as a whole: diagnose() and what its callers take of the modules it is made of
__all__ = ["Diagnosis", "EffectWrench", "diagnose", "prepare_window", "candidates", "corrected", "body_inertia",
           "with_stiffness", "locate", "exciter_phase", "synchronous_rms", "EFFECT_NAMES", "IdentificationError"]
