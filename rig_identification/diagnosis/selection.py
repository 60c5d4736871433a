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
(:func:`~rig_identification.estimation.identification.consistent_from_params`).

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
evaluated exactly at ±:data:`GAIN_STEP` (:func:`_exact_screen`), and the selected one is
found by its exact profile likelihood (:func:`_exact_profile`).  So is ``cable_mass``,
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
from dataclasses import dataclass, field
from dataclasses import replace as _replace

import numpy as np
from scipy.stats import chi2

from .candidates import CORRECTIONS, body_inertia, candidates, corrected, with_stiffness
from ..model.effects import EFFECT_NAMES
from ..estimation.identification import KEYS, IdentificationError, from_tensor, identify_inertia
from .model_extension import Fit, Model, Window, fit_model, prepare_window
from ..io.recording import Recording, RecordingError
from .residuals import (channel_residuals, effective_samples, exciter_phase, locate, rms, synchronous,
                                synchronous_rms)

ALPHA = 0.01          # family-wise false-alarm probability of the selection
MIN_REDUCTION = 0.05  # an effect must reduce some channel's residual RMS by at least this fraction
MAX_EFFECTS = 3
EXACT_SCREEN = 3      # sensor/rig-error candidates evaluated exactly (re-tracked) per selection step
REWEIGHT_ITER = 2     # reweighting iterations of the final fit (per-axis residual scales)
GAIN_STEP = 0.02      # load-cell gain steps of the exact screening (relative)
CABLE_MASS_STEP = 2e-3  # cables' mass steps of the exact screening: body anchors' share of the body's mass
MASSES = ("cable_mass", "body_mass")
"""Errors of the mass the tensions move: they change no tension (their trials keep the steel stretch)."""
PROFILED = ("load_cell_scale",) + MASSES
"""One-parameter errors placed by their exact profile likelihood (:func:`_exact_profile`)."""
WEIGHT_SURPLUS_SIGMA = 3.0   # the masses are evaluated exactly when the cells carry this many σ more (or less) than the weight
# engineering resolution: a smaller sensor-pose error is no finding, however significant
PRACTICAL_FLOOR = {"imu_offset": 0.005, "imu_misalignment": 0.001, "sensor_delay": 0.001}   # m, rad, s
STEEL_STRETCH = 4e-3  # m: static stretch beyond which cables without a rig.yaml stiffness are not "steel-like"


# --- diagnosis ------------------------------------------------------------------------------

@dataclass(frozen=True)
class EffectWrench:
    """The generalized wrench that the diagnosed physics adds to the measured one (the
    extended model's moment and force columns times their fitted parameters; Newton–Euler:
    J ω̇ + ω × Jω = M + M_effect, m a = F + F_effect).

    t (N,) s, absolute stamps of the diagnosis window; torque (N,3) N·m about the CG and force
    (N,3) N, body axes; names: the effects it holds."""

    t: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    names: tuple

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(torque (M,3), force (M,3)) at the stamps ``t`` (M,) s: linear interpolation, the
        end values held outside the window."""
        tq = np.column_stack([np.interp(t, self.t, self.torque[:, k]) for k in range(3)])
        fc = np.column_stack([np.interp(t, self.t, self.force[:, k]) for k in range(3)])
        return tq, fc


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`; :meth:`to_dict` is the JSON of ``rig-identify diagnose``."""

    mismatch: bool
    effects: list
    located: dict
    rms_before: dict
    rms_after: dict
    inertia_before: np.ndarray
    inertia_after: np.ndarray
    inertia_std_before: np.ndarray
    inertia_std_after: np.ndarray
    tried: list
    band: tuple
    model: str
    warnings: list = field(default_factory=list)
    series: dict = field(default_factory=dict)
    covariance_after: np.ndarray | None = None   # (6,6) of the entries of inertia_after, KEYS order
    # the sensor and rig errors removed from the data (key -> value, as :func:`corrected` takes)
    corrections: dict = field(default_factory=dict)
    # time-synchronous residual RMS per channel (None: no rotating exciter), and the revolutions averaged
    rms_sync_before: dict | None = None
    rms_sync_after: dict | None = None
    revolutions: float | None = None
    # the physics added to the model (not errors of the data), as the generalized wrench it
    # adds to the measured one along the window: :class:`EffectWrench` or None
    effect_wrench: "EffectWrench | None" = None
    # every correction made to the data or the rig (key -> value, :func:`corrected`; the
    # cables' mass included), and the cables' stiffness (n,) N/m when their elasticity was found
    applied: dict = field(default_factory=dict)
    stiffness: np.ndarray | None = None

    def to_dict(self) -> dict:
        ent = lambda J: {k: float(x) for k, x in zip(KEYS, from_tensor(J))}  # noqa: E731
        return {"mismatch": self.mismatch, "effects": self.effects, "located": self.located,
                "residual_rms_before": self.rms_before, "residual_rms_after": self.rms_after,
                "inertia_about_cg_before": ent(self.inertia_before),
                "inertia_about_cg_after": ent(self.inertia_after),
                "inertia_std_before": {k: float(x) for k, x in zip(KEYS, self.inertia_std_before)},
                "inertia_std_after": {k: float(x) for k, x in zip(KEYS, self.inertia_std_after)},
                "candidates": self.tried, "band_hz": [float(x) for x in self.band], "model": self.model,
                "warnings": self.warnings,
                "residual_rms_synchronous_before": self.rms_sync_before,
                "residual_rms_synchronous_after": self.rms_sync_after,
                "synchronous_revolutions": self.revolutions}


PLAUSIBLE = {
    "viscous_damping": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "air_drag": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "coulomb_friction": {"torque": (0.0, np.inf), "force": (0.0, np.inf)},
    "sensor_delay": {"delay": (-0.1, 0.1)},
    "load_cell_scale": {"scale": (0.8, 1.25)},
    "gyro_bias": {"bias": (-0.05, 0.05)},
    "gyro_scale": {"scale": (0.9, 1.1)},
    "accelerometer_bias": {"bias": (-0.5, 0.5)},
    "imu_misalignment": {"rpy": (-0.1, 0.1)},
    "imu_offset": {"offset": (-1.0, 1.0)},
    "cable_elasticity": {"stiffness": (1e4, 1e9)},
    "gyroscopic_coupling": {"scale": (0.5, 1.5)},
}
"""The range (SI) each effect's parameters must fall in to be named: a fit that needs a
dissipation of the wrong sign, a sensor delay of a tenth of a second or an IMU a metre from
where rig.yaml puts it has found a stand-in for other physics, not the effect.  Besides:
``cable_mass`` between 0 and 5 % of the body's mass per cable, ``body_mass`` within 10 %
of rig.yaml's, the exciter's rotor ``unbalance`` within 0.3–3× the mass that makes the
measured force (F / (2π f)²), and a dissipative effect's moment at most
:data:`MAX_EFFECT_SHARE` of the measured moment (RMS in the band: a rig's damping is small)."""
MAX_EFFECT_SHARE = 0.3


def implausible(entry: dict, rig, effect_share: float | None = None, unbalance: float | None = None) -> str | None:
    """Why the effect ``entry`` (of :attr:`Diagnosis.effects`) cannot be the physics in the
    recording (see :data:`PLAUSIBLE`), or None when it is plausible.  effect_share: the RMS
    of its moment over the measured moment's; unbalance: kg·m that makes the measured
    exciter force."""
    name, par = entry["name"], entry["parameters"]
    for k, (lo, hi) in PLAUSIBLE.get(name, {}).items():
        v = np.atleast_1d(np.asarray(par.get(k, 0.0), float))
        if np.any(v < lo) or np.any(v > hi):
            return f"{k} = {fmt_value(par.get(k))} outside {lo:g}…{hi:g}"
    if name == "cable_mass" and not 0.0 <= par.get("mass", 0.0) <= 0.05 * rig.mass:
        return f"mass {par['mass']:.3g} kg per cable outside 0…{0.05 * rig.mass:.3g} kg"
    if name == "body_mass" and abs(par.get("mass_error", 0.0)) > 0.1 * rig.mass:
        return f"mass error {par['mass_error']:.3g} kg beyond 10 % of rig.yaml's {rig.mass:.6g} kg"
    if name == "exciter_rotor" and unbalance:
        u = par.get("unbalance", 0.0)
        if not 0.3 * unbalance <= u <= 3.0 * unbalance:
            return f"unbalance {u:.3g} kg·m outside 0.3–3× the {unbalance:.3g} kg·m that makes the measured force"
    if name in ("viscous_damping", "air_drag", "coulomb_friction") and effect_share is not None \
            and effect_share > MAX_EFFECT_SHARE:
        return f"its moment is {100 * effect_share:.0f} % of the measured moment (at most {100 * MAX_EFFECT_SHARE:.0f} %)"
    return None



def fmt_value(v) -> str:
    """A parameter value of an effect's JSON as text (numbers to 4 digits; lists, dicts)."""
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {fmt_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(fmt_value(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}"
    return str(v)



def _lr(cost0: dict, cost1: dict, model: Model) -> float:
    lam = 0.0
    for g in ("rot", "tr"):
        # costs are in units of the baseline scales over n·3 samples; per-group likelihood
        # ratio with the group's effective number of independent samples
        if cost0[g] > 0 and cost1[g] > 0:
            lam += model.n_eff_group.get(g, model.n_eff) * 3 * np.log(cost0[g] / cost1[g])
    lam += sum(cost0[k] - cost1[k] for k in ("dcg", "dca", "dcm", "dcw"))
    return float(lam)


def _scales(M: Model, f0: Fit) -> tuple:
    """The residual scales of the fit ``f0`` (the baseline's during the selection): per
    axis (3,) for the rotational and translational groups, scalars for the mean levels."""
    return (np.sqrt(np.mean(f0.rot**2, 0)), np.sqrt(np.mean(f0.tr**2, 0)),
            float(np.mean(M.sigma_dcg)), float(np.mean(M.sigma_dca)), float(M.sigma_dcm))


def _columns(cands: list, keys: list) -> list:
    by = {c.key: c for c in cands}
    return [col for k in keys if k in by for col in by[k].columns]


def _exact_iterate(key, state: dict, build, keys: list, fit: Fit, n_iter: int, kappa0: float,
                  free_kappa: bool, scales) -> tuple:
    """Remove a selected sensor or rig error from the data and re-track, iterating its
    value x so that the first-order column's fitted remainder β(x) vanishes: Broyden's
    method (quasi-Newton; the starting Jacobian dβ/dx = −I is the first-order model, the
    tracker's response updates it).  Returns (applied, w, M, cands, fit)."""
    applied = dict(state["applied"])
    beta = _beta_of(fit, None, keys, key, state)
    x = np.zeros(len(beta)) + np.asarray(applied.get(key, 0.0), float)
    B = -np.eye(len(x))
    cands = None
    w = M = None
    for it in range(n_iter):
        dx = -np.linalg.solve(B, beta)
        x_new = x + dx
        applied[key] = float(x_new[0]) if len(x_new) == 1 else x_new.copy()
        w, M, cands = build(applied, state["elastic"])
        fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, from_tensor(fit.J))
        beta_new = _beta_of(fit, cands, keys, key, state)
        dbeta = beta_new - beta
        B = B + np.outer(dbeta - B @ dx, dx) / max(float(dx @ dx), 1e-300)
        x, beta = x_new, beta_new
        k0 = len(_columns(cands, keys[:keys.index(key)]))
        n = len(beta)
        std = np.sqrt(np.clip(np.diag(fit.cov)[6 + k0:6 + k0 + n], 0, None))
        if np.all(np.abs(beta) <= 0.1 * std):
            break
    return applied, w, M, cands, fit


def _beta_of(fit: Fit, cands, keys: list, key, state) -> np.ndarray:
    """The fitted values of the columns of ``key`` in ``fit`` (columns ordered by ``keys``)."""
    by = {c.key: c for c in (cands if cands is not None else state["cands"])}
    k0 = sum(len(by[k].columns) for k in keys[:keys.index(key)] if k in by)
    return np.asarray(fit.beta[k0:k0 + len(by[key].columns)], float)


def _profile_steps(key, w: Window) -> tuple:
    """(screening step, lower bound, curvature step) of the exact one-parameter evaluation
    of ``key``: a load cell's gain error (relative) :data:`GAIN_STEP`, unbounded; the
    half-cable mass per body anchor (kg) :data:`CABLE_MASS_STEP` of the body's mass shared
    by the anchors, at least 0; the body's mass error (kg) that share of the body's mass,
    unbounded."""
    if key[0] == "cable_mass":
        h = CABLE_MASS_STEP * w.mass / len(w.cable_names)
        return h, 0.0, 0.1 * h
    if key[0] == "body_mass":
        h = CABLE_MASS_STEP * w.mass
        return h, -np.inf, 0.1 * h
    return GAIN_STEP, -np.inf, 2e-3


def _builder(build, key):
    """The re-track of ``key``'s trial values: a mass (the cables', the body's) changes no
    tension, so its trials keep the steel stretch fitted last (one tracker pass, not two); a gain or a
    delay changes what the stretch is fitted to, so theirs fit it again."""
    if key[0] not in MASSES:
        return build
    return lambda applied, elastic, profiled=None: build(applied, elastic, profiled, keep_stretch=True)


def _weight_surplus(M: Model, fit: Fit) -> float:
    """How much more than the body's weight the load cells carry, in σ of the mean level:
    the mean cable and exciter force / mass minus the mean specific force, along gravity
    (body axes) — what the cables' mass does (each cable's lower half hangs on the body,
    outside its load cell), or a body heavier than rig.yaml says; beyond
    :data:`WEIGHT_SURPLUS_SIGMA` they are worth an exact evaluation.  ``fit.dca`` is the
    mean measured minus modelled specific force."""
    g_hat = -M.w.g_body.mean(0)
    g_hat = g_hat / np.linalg.norm(g_hat)
    return -float(fit.dca @ g_hat) / float(np.mean(M.sigma_dca))


def _exact_screen(e: dict, state: dict, build, keys: list, cost_ref: dict, rms_ref: dict, kappa0: float,
                  free_kappa: bool, scales, j0: np.ndarray, w: Window) -> None:
    """Exact evidence of a one-parameter rig or data error (a load cell's gain, the cables'
    or the body's mass, a gyro axis's scale; screening entry ``e``, updated in place): the error
    applied at two trial values about its current one (±h, or +h and +2h at its lower bound;
    :func:`_profile_steps`), the pose re-tracked and the model refitted; the parabola of the
    likelihood ratio against ``cost_ref`` through those two points and the current fit (Λ = 0)
    proposes a maximum (at most 3h away), where the error is evaluated exactly too.  The
    evidence is the largest likelihood ratio *evaluated*, never the parabola's: the profile
    is not quadratic where a trial moves the tracked pose discontinuously — a load cell's gain
    error of −2 % turned the yaw anchor's moment balance by 52 mrad on a random rig, and the
    parabola through that trial promised Λ = 1.8·10⁶ at h/2 for the wrong cell (c3 instead
    of c1), where the exact re-track gives Λ < 0.  The best evaluated point is the starting
    point of :func:`_exact_profile`."""
    key = e["c"].key
    h, lower, _ = _profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    offsets = (-h, h) if x0 - h >= lower else (h, 2 * h)
    lams, fits = [], []

    def trial(d):
        w1, M, cands = build({**state["applied"], key: x0 + d}, state["elastic"])
        fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, j0)
        lams.append(_lr(cost_ref, fit.cost(scales), M))
        fits.append((d, fit, M))

    for d in offsets:
        trial(d)
    (p1, p2), (l1, l2) = offsets, lams
    A = (l2 / p2 - l1 / p1) / (p2 - p1)       # Λ(d) = A d² + B d through (0, 0), (p1, l1), (p2, l2)
    B = l1 / p1 - A * p1
    if A < 0:
        d = float(np.clip(-B / (2 * A), max(-3 * h, lower - x0), 3 * h))
        if min(abs(d - p1), abs(d - p2)) > 0.05 * h and abs(d) > 0.05 * h:
            trial(d)
    best = int(np.argmax(lams))
    d, fit, M = fits[best]
    rms1 = rms(channel_residuals(M, fit))
    e.update(lam=float(lams[best]), fit=fit, red={k: 1 - rms1[k] / rms_ref[k] for k in rms1 if rms_ref[k] > 0},
             exact_state=({**state["applied"], key: x0 + d}, None, None, None))


def _exact_profile(key, state: dict, build, keys: list, cost_ref: dict, kappa0: float, free_kappa: bool, scales,
                   j0: np.ndarray, w: Window) -> tuple:
    """The exact profile likelihood of a one-parameter rig or data error (a load cell's
    gain, the cables' or the body's mass): the error applied at trial values x (:func:`corrected`), the
    pose re-tracked and the model (without the error's first-order column) refitted; x
    maximises the likelihood ratio against ``cost_ref`` (scipy ``minimize_scalar``,
    bounded, ± a screening step about the current value and above the lower bound of
    :func:`_profile_steps`, to 1 % of a step), σ from its curvature (Λ(x) ≈ Λ̂ − (x − x̂)²/σ²).
    They move the tracker's static pose, so the first-order column's zero
    (:func:`_exact_iterate`) is not the optimum.  Returns (applied, w, M, cands, fit, σ)."""
    from scipy.optimize import minimize_scalar
    others = [k for k in keys if k != key]
    prof = {**state.get("profiled", {}), key: np.nan}
    memo = {}

    def evaluate(x):
        x = float(x)
        if x not in memo:
            applied = {**state["applied"], key: x}
            w, M, cands = build(applied, state["elastic"], prof)
            fit = fit_model(M, _columns(cands, others), kappa0, free_kappa, scales, j0)
            memo[x] = (_lr(cost_ref, fit.cost(scales), M), (applied, w, M, cands, fit))
        return memo[x]

    step, lower, h = _profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    sol = minimize_scalar(lambda x: -evaluate(x)[0], bounds=(max(lower, x0 - step), x0 + step),
                          method="bounded", options={"xatol": 0.01 * step})
    xh = max(float(sol.x), lower + h)
    curv = 2 * evaluate(xh)[0] - evaluate(xh + h)[0] - evaluate(xh - h)[0]
    sd = float(np.sqrt(2 * h * h / curv)) if curv > 0 else float("nan")
    prof[key] = sd
    state["profiled"] = prof
    applied, w, M, cands, fit = evaluate(xh)[1]
    return applied, w, M, cands, fit, sd


def log_sf(x: float, dof: int) -> float:
    """ln P(χ²_dof > x), finite however large x: scipy's ``chi2.logsf``, and where that
    underflows its asymptotic form −x/2 + (dof/2 − 1) ln(x/2) − ln Γ(dof/2) (the upper
    incomplete gamma function's leading term; Abramowitz & Stegun 6.5.32)."""
    x = max(float(x), 0.0)
    v = float(chi2.logsf(x, dof))
    if np.isfinite(v):
        return v
    return -x / 2 + (dof / 2 - 1) * math.log(x / 2) - math.lgamma(dof / 2)


def diagnose(rec: Recording, model: str = "pem", max_effects: int = MAX_EFFECTS, alpha: float = ALPHA,
             band_hz: tuple[float, float] | None = None) -> Diagnosis:
    """Diagnose a dynamic recording (see module docstring).

    model: ``"pem"`` (ours, with the gyroscopic term) or ``"thesis"`` (the thesis's model:
    no ω × Jω).  The baseline is the rig.yaml taken literally: cables without a stiffness
    are inextensible.  Sensor and rig errors (delays, gains, biases, IMU pose, cable
    elasticity), once selected, are removed from the data and the pose re-tracked
    (:func:`corrected`), iterating the first-order estimate to convergence.
    Returns a :class:`Diagnosis`.  Raises RecordingError, RigError, TrackerError,
    IdentificationError for recordings no fit can be made of.
    """
    if model not in ("pem", "thesis"):
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    warnings: list[str] = []
    kappa0 = 1.0 if model == "pem" else 0.0
    R_yaml = rec.rig.imu.rotation.as_matrix()
    state = {"applied": {}, "elastic": False, "band": band_hz, "candidate": True}
    declared = np.isfinite(rec.rig.cable_stiffness).all()

    def build(applied, elastic, profiled=None, keep_stretch=False):
        mode = "fitted" if elastic else ("declared" if declared else "rigid")
        # keep_stretch: the steel stretch fitted last is kept (one tracker pass, not two)
        src = with_stiffness(rec, state["steel"]) if keep_stretch and "steel" in state else rec
        w = prepare_window(corrected(src, applied), warnings=[] if state["band"] else warnings,
                           cables=mode, imu_rot_yaml=R_yaml)
        M = Model(w, state["band"])
        M.n_eff_group = state.get("n_eff_group", {})
        state["band"] = M.band
        return w, M, candidates(w, M, kappa0, applied, allow_elasticity=state["candidate"] and not elastic,
                                profiled=state.get("profiled") if profiled is None else profiled)

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
            cands = candidates(w, M, kappa0, {}, allow_elasticity=False)
        else:
            warnings.append(f"the cables stretch {1e3 * stretch:.1f} mm under the static load (fitted stiffness "
                            f"{np.median(k):.3g} N/m), more than steel cables' 1-2 mm: cable elasticity is tested "
                            "against rigid cables")
            w, M, cands = build({}, False)
    else:
        w, M, cands = build({}, False)
    band = M.band
    j0 = from_tensor(identify_inertia(rec.rig, w.t, w.omega, w.torque, band_hz=band).inertia)
    scales = _scales(M, fit_model(M, [], kappa0, False, (1.0, 1.0, 1.0, 1.0, 1e9), j0))
    base = fit_model(M, [], kappa0, False, scales, j0)
    state["n_eff_group"] = M.n_eff_group = {"rot": min(M.n_eff, effective_samples(base.rot)),
                                            "tr": min(M.n_eff, effective_samples(base.tr))}
    M0, ch0 = M, channel_residuals(M, base)
    rms0 = rms(ch0)
    threshold_p = alpha / max(1, len(cands))
    keys: list = []
    entries: list = []
    free_kappa = False
    cur_fit = base
    tried = []
    elastic_cache = None
    state["cands"] = cands
    for step in range(1, max_effects + 1):
        cost_cur = cur_fit.cost(scales)
        rms_cur = rms(channel_residuals(M, cur_fit))
        base_cols = _columns(cands, keys)
        screened = []
        for c in cands:
            if c.key in keys:
                continue
            fk = free_kappa or c.gyroscopic
            Mc = M
            try:
                if c.name == "cable_elasticity":
                    if elastic_cache is None or elastic_cache[0] != repr(state["applied"]):
                        we, Me, ce = build(state["applied"], True)
                        elastic_cache = (repr(state["applied"]), we, Me, ce)
                    _, we, Mc, ce = elastic_cache
                    fit = fit_model(Mc, _columns(ce, keys), kappa0, fk, scales, from_tensor(cur_fit.J))
                else:
                    fit = fit_model(M, base_cols + c.columns, kappa0, fk, scales, from_tensor(cur_fit.J))
            except (np.linalg.LinAlgError, ValueError) as e:
                warnings.append(f"candidate {c.name} {c.label}: fit failed ({e})")
                continue
            lam = _lr(cost_cur, fit.cost(scales), M)
            dof = len(c.columns) + (1 if c.gyroscopic else 0) + (1 if c.name == "cable_elasticity" else 0)
            if c.name in PRACTICAL_FLOOR:
                k0 = len(base_cols)
                size = float(np.linalg.norm(fit.beta[k0:k0 + len(c.columns)]))
                if size + float(np.linalg.norm(np.atleast_1d(state["applied"].get(c.key, 0.0)))) < \
                        PRACTICAL_FLOOR[c.name]:
                    tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(lam),
                                  "dof": dof, "p_value": float(chi2.sf(max(lam, 0.0), dof)),
                                  "max_rms_reduction": 0.0, "exact": False,
                                  "below_practical_floor": PRACTICAL_FLOOR[c.name]})
                    continue
            rms1 = rms(channel_residuals(Mc, fit))
            red = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
            screened.append({"c": c, "lam": lam, "fit": fit, "red": red, "dof": dof, "exact_state": None})
        # sensor and rig errors move the tracked pose too: the most promising ones are
        # evaluated exactly (data corrected, re-tracked, two Broyden steps) before choosing
        promising = sorted((e for e in screened if e["c"].exact and e["c"].name not in PROFILED
                            and e["c"].name != "cable_elasticity"
                            and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p), key=lambda e: -e["lam"])
        # a load cell's gain and the cables' or the body's mass move the tracker's static pose,
        # so their first-order columns are no guide to their size or evidence: every
        # significant gain, and the masses when the cells carry more (or less) than the weight
        # (the cables' column is nearly collinear with the tensor), are evaluated exactly
        surplus = _weight_surplus(M, cur_fit)
        for e in screened:
            if (e["c"].name == "cable_mass" and surplus > WEIGHT_SURPLUS_SIGMA) or (
                    e["c"].name == "body_mass" and abs(surplus) > WEIGHT_SURPLUS_SIGMA) or (
                    e["c"].name == "load_cell_scale" and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p):
                try:
                    _exact_screen(e, state, _builder(build, e["c"].key), keys, cost_cur, rms_cur, kappa0,
                                  free_kappa, scales, from_tensor(cur_fit.J), w)
                except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
                    warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
                    e["lam"] = -np.inf
        for e in promising[:EXACT_SCREEN]:
            keys_e = keys + [e["c"].key]
            try:
                applied, we, Me, ce, fe = _exact_iterate(e["c"].key, state, build, keys_e, e["fit"], 2, kappa0,
                                                         free_kappa, scales)
            except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
                warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
                e["lam"] = -np.inf
                continue
            e["lam"] = _lr(cost_cur, fe.cost(scales), Me)
            rms1 = rms(channel_residuals(Me, fe))
            e["red"] = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
            e["fit"] = fe
            e["exact_state"] = (applied, we, Me, ce)
        best = None
        for e in screened:
            c = e["c"]
            p = float(chi2.sf(max(e["lam"], 0.0), e["dof"])) if np.isfinite(e["lam"]) else 1.0
            best_red = max(e["red"].values())
            tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(e["lam"]),
                          "dof": e["dof"], "p_value": p, "max_rms_reduction": best_red,
                          "exact": e["exact_state"] is not None})
            if c.exact and c.name != "cable_elasticity" and e["exact_state"] is None:
                continue   # not evaluated exactly: its first-order fit is no evidence
            # the gyroscopic term is physics of known size (κ = 1), missing from the model
            # by construction: its test is κ = 0 rejected, however small the residual's change
            practical = best_red >= MIN_REDUCTION or c.gyroscopic
            # the strongest evidence, its parameters counted: the smallest p-value (log, so that
            # underflowing ones still rank) — a 3-parameter accelerometer bias with a likelihood
            # ratio 3 above a 1-parameter body mass error is the weaker explanation
            e["log_p"] = log_sf(e["lam"], e["dof"]) if np.isfinite(e["lam"]) else 0.0
            if p < threshold_p and practical and (best is None or e["log_p"] < best[0]["log_p"]):
                best = (e, p)
        if best is None:
            break
        e, p = best
        c, dof = e["c"], e["dof"]
        keys.append(c.key)
        free_kappa = free_kappa or c.gyroscopic
        fit = e["fit"]
        if c.name == "cable_elasticity":
            state["elastic"] = True
            _, w, M, cands = elastic_cache
        elif c.name in PROFILED:
            state["applied"] = e["exact_state"][0]
            state["applied"], w, M, cands, fit, _ = _exact_profile(c.key, state, _builder(build, c.key), keys,
                                                                   cost_cur, kappa0,
                                                                   free_kappa, scales, from_tensor(fit.J), w)
        elif c.exact:
            state["applied"], w, M, cands = e["exact_state"]
            state["applied"], w, M, cands, fit = _exact_iterate(c.key, {**state, "cands": cands}, build, keys,
                                                                fit, 3, kappa0, free_kappa, scales)
        if c.name in MASSES and "steel" in state:
            # its trial re-tracks kept the steel stretch: fitted again with the mass in place
            w, M, cands = build(state["applied"], False)
            fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, from_tensor(fit.J))
        state["cands"] = cands
        if "steel" in state:
            state["steel"] = w.stiffness
        rms1 = rms(channel_residuals(M, fit))
        red = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
        lam = _lr(cost_cur, fit.cost(scales), M)
        cur_fit = fit
        affected = sorted((k for k, r in red.items() if r >= 0.1), key=lambda k: -red[k])
        entries.append({"name": c.name, "parameters": {}, "parameters_std": {},
                        "evidence": {"likelihood_ratio": lam, "dof": dof, "p_value": p, "threshold_p": threshold_p,
                                     "step": step, "rms_reduction": {k: round(red[k], 4) for k in affected[:8]}}})
    # backward elimination: forward selection can pick a stand-in first (drag for a delay's
    # quadrature) and keep it once the real effect is in; each physics effect (the first-order
    # ones: the data corrections are tested again by the validation of the corrected fit) is
    # dropped when the others explain the recording as well without it
    by_key = {c.key: c for c in cands}
    for key in [k for k in keys if k in by_key and not by_key[k].exact and not by_key[k].gyroscopic]:
        if len(keys) < 2:
            break
        others = [k for k in keys if k != key]
        try:
            fit_wo = fit_model(M, _columns(cands, others), kappa0, free_kappa, scales, from_tensor(cur_fit.J))
        except (np.linalg.LinAlgError, ValueError):
            continue
        lam = _lr(fit_wo.cost(scales), cur_fit.cost(scales), M)
        dof = len(by_key[key].columns)
        if chi2.sf(max(lam, 0.0), dof) >= threshold_p:
            i = keys.index(key)
            keys.pop(i)
            dropped = entries.pop(i)
            warnings.append(f"{dropped['name']} dropped: with the other effects in the model it adds nothing "
                            f"(likelihood ratio {lam:.3g}, {dof} dof)")
            cur_fit = fit_wo
    # the selection weighted each axis by the baseline's residual scale, which the missing
    # physics inflated on some axes: the final fit is reweighted by its own residual scales
    # (iteratively reweighted least squares: the maximum-likelihood estimate with unknown
    # per-axis noise levels)
    for _ in range(REWEIGHT_ITER if entries else 0):
        sr, sa = _scales(M, cur_fit)[:2]
        cur_fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, (sr, sa) + tuple(scales[2:]),
                            from_tensor(cur_fit.J))
    # the parameters of every selected effect, from the final joint fit
    pos = 0
    by = {cc.key: cc for cc in cands}
    for e, key in zip(entries, keys):
        if key[0] == "cable_elasticity":
            k = w.stiffness[np.isfinite(w.stiffness)]
            e["parameters"], e["parameters_std"] = {"stiffness": float(np.median(k))}, \
                {"stiffness": float(w.stiffness_std) if w.stiffness_std is not None else float("nan")}
            continue
        c = by[key]
        if c.gyroscopic:
            vals, stds = [cur_fit.kappa], [float(np.sqrt(max(cur_fit.cov[-1, -1], 0.0)))]
        else:
            vals = cur_fit.beta[pos:pos + len(c.columns)]
            stds = np.sqrt(np.clip(np.diag(cur_fit.cov)[6 + pos:6 + pos + len(c.columns)], 0, None))
            pos += len(c.columns)
        e["parameters"], e["parameters_std"] = c.report(vals, stds)
    # the physics the model lacks (not an error of the data), as the wrench it adds
    pos = 0
    tq_add, f_add, phys, share = np.zeros_like(w.omega), np.zeros_like(w.omega), [], {}
    for key in keys:
        c = by.get(key)
        if c is None or c.gyroscopic:
            continue
        vals = cur_fit.beta[pos:pos + len(c.columns)]
        pos += len(c.columns)
        if c.exact:
            continue
        phys.append(c.name)
        tq_c = np.zeros_like(w.omega)
        for b, col in zip(vals, c.columns):
            if col.rot_D is not None:
                tq_c += b * col.rot_D
            if col.tr_D is not None:
                f_add += b * w.mass * col.tr_D
        tq_add += tq_c
        share[c.name] = float(np.sqrt(np.mean(M.filt(tq_c) ** 2)) / max(np.sqrt(np.mean(M.filt(w.torque) ** 2)),
                                                                        1e-12))
    effect_wrench = EffectWrench(w.t.copy(), tq_add, f_add, tuple(phys)) if phys else None
    phase = exciter_phase(w)
    unbalance = None
    if phase is not None:
        ok = np.isfinite(phase)
        f_hz = abs(float(np.polyfit(w.t[ok], phase[ok], 1)[0])) / (2 * np.pi)
        unbalance = float(np.median(np.linalg.norm(w.f_exc, axis=1))) / (2 * np.pi * f_hz) ** 2
    for e in entries:
        why = implausible(e, rec.rig, share.get(e["name"]), unbalance)
        e["plausible"] = why is None
        if why is not None:
            e["implausible"] = why
        if e["name"] in share:
            e["evidence"]["moment_share"] = round(share[e["name"]], 4)
    entries.sort(key=lambda e: -e["evidence"]["likelihood_ratio"])
    located = locate(M0, base, rec.rig, base.J)
    std_of = lambda f: np.sqrt(np.clip(np.diag(f.cov)[:6], 0, None))  # noqa: E731
    ch1 = channel_residuals(M, cur_fit)
    (sync0, revs), (sync1, _) = synchronous(M0, ch0), synchronous(M, ch1)
    return Diagnosis(bool(entries), entries, located, rms0, rms(ch1), base.J,
                     body_inertia(cur_fit.J, _replace(rec.rig, mass=rec.rig.mass + float(state["applied"].get(
                         ("body_mass", ""), 0.0))), float(state["applied"].get(("cable_mass", ""), 0.0))),
                     std_of(base), std_of(cur_fit), tried, band, model, warnings + list(rec.warnings),
                     series={"t": w.t - w.t[0], "fs": M.fs, "before": ch0, "after": ch1},
                     covariance_after=np.array(cur_fit.cov[:6, :6]),
                     corrections={k: v for k, v in state["applied"].items() if k[0] in CORRECTIONS},
                     rms_sync_before=sync0, rms_sync_after=sync1, revolutions=revs, effect_wrench=effect_wrench,
                     applied=dict(state["applied"]), stiffness=w.stiffness.copy() if state["elastic"] else None)


# the diagnosis as a whole: diagnose() and what its callers take of the modules it is made of
__all__ = ["Diagnosis", "EffectWrench", "diagnose", "prepare_window", "candidates", "corrected", "body_inertia",
           "with_stiffness", "locate", "exciter_phase", "synchronous_rms", "EFFECT_NAMES", "IdentificationError"]
