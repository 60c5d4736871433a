"""Exact evaluation of the sensor and rig errors a diagnosis considers (the method:
:mod:`~rig_identification.diagnosis.selection`): the error removed from the data
(:func:`~rig_identification.diagnosis.candidates.corrected`), the pose re-tracked and the
extended model refitted — iterated to the zero of the first-order column's remainder
(:func:`exact_iterate`, Broyden's method), or, for a one-parameter error whose first-order
column is no guide (a load cell's gain, the cables' or the body's mass), screened at trial
values (:func:`exact_screen`) and placed by its exact profile likelihood
(:func:`exact_profile`).  Also the likelihood-ratio statistic every comparison of fits uses
(:func:`likelihood_ratio`) and its χ² tail probability (:func:`log_sf`).

Reference: Ljung, *System Identification* (2nd ed., 1999), §16.4–16.6.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.stats import chi2

from ..model.parametrisation import from_tensor
from .model_extension import Fit, Model, fit_model
from .residuals import channel_residuals, rms
from .window import Window

GAIN_STEP = 0.02      # load-cell gain steps of the exact screening (relative)
CABLE_MASS_STEP = 2e-3  # cables' mass steps of the exact screening: body anchors' share of the body's mass
MASSES = ("cable_mass", "body_mass")
"""Errors of the mass the tensions move: they change no tension (their trials keep the steel stretch)."""
PROFILED = ("load_cell_scale",) + MASSES
"""One-parameter errors placed by their exact profile likelihood (:func:`exact_profile`)."""


def likelihood_ratio(cost0: dict, cost1: dict, model: Model) -> float:
    lam = 0.0
    for g in ("rot", "tr"):
        # costs are in units of the baseline scales over n·3 samples; per-group likelihood
        # ratio with the group's effective number of independent samples
        if cost0[g] > 0 and cost1[g] > 0:
            lam += model.n_eff_group.get(g, model.n_eff) * 3 * np.log(cost0[g] / cost1[g])
    lam += sum(cost0[k] - cost1[k] for k in ("dcg", "dca", "dcm", "dcw"))
    return float(lam)


def residual_scales(M: Model, f0: Fit) -> tuple:
    """The residual scales of the fit ``f0`` (the baseline's during the selection): per
    axis (3,) for the rotational and translational groups, scalars for the mean levels."""
    return (np.sqrt(np.mean(f0.rot**2, 0)), np.sqrt(np.mean(f0.tr**2, 0)),
            float(np.mean(M.sigma_dcg)), float(np.mean(M.sigma_dca)), float(M.sigma_dcm))


def columns_of(cands: list, keys: list) -> list:
    by = {c.key: c for c in cands}
    return [col for k in keys if k in by for col in by[k].columns]


def exact_iterate(key, state: dict, build, keys: list, fit: Fit, n_iter: int, kappa0: float,
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
        fit = fit_model(M, columns_of(cands, keys), kappa0, free_kappa, scales, from_tensor(fit.J))
        beta_new = _beta_of(fit, cands, keys, key, state)
        dbeta = beta_new - beta
        B = B + np.outer(dbeta - B @ dx, dx) / max(float(dx @ dx), 1e-300)
        x, beta = x_new, beta_new
        k0 = len(columns_of(cands, keys[:keys.index(key)]))
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


def profile_steps(key, w: Window) -> tuple:
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


def mass_builder(build, key):
    """The re-track of ``key``'s trial values: a mass (the cables', the body's) changes no
    tension, so its trials keep the steel stretch fitted last (one tracker pass, not two); a gain or a
    delay changes what the stretch is fitted to, so theirs fit it again."""
    if key[0] not in MASSES:
        return build
    return lambda applied, elastic, profiled=None: build(applied, elastic, profiled, keep_stretch=True)


def weight_surplus(M: Model, fit: Fit) -> float:
    """How much more than the body's weight the load cells carry, in σ of the mean level:
    the mean cable and exciter force / mass minus the mean specific force, along gravity
    (body axes) — what the cables' mass does (each cable's lower half hangs on the body,
    outside its load cell), or a body heavier than rig.yaml says; beyond
    :data:`WEIGHT_SURPLUS_SIGMA` they are worth an exact evaluation.  ``fit.dca`` is the
    mean measured minus modelled specific force."""
    g_hat = -M.w.g_body.mean(0)
    g_hat = g_hat / np.linalg.norm(g_hat)
    return -float(fit.dca @ g_hat) / float(np.mean(M.sigma_dca))


def exact_screen(e: dict, state: dict, build, keys: list, cost_ref: dict, rms_ref: dict, kappa0: float,
                  free_kappa: bool, scales, j0: np.ndarray, w: Window) -> None:
    """Exact evidence of a one-parameter rig or data error (a load cell's gain, the cables'
    or the body's mass, a gyro axis's scale; screening entry ``e``, updated in place): the error
    applied at two trial values about its current one (±h, or +h and +2h at its lower bound;
    :func:`profile_steps`), the pose re-tracked and the model refitted; the parabola of the
    likelihood ratio against ``cost_ref`` through those two points and the current fit (Λ = 0)
    proposes a maximum (at most 3h away), where the error is evaluated exactly too.  The
    evidence is the largest likelihood ratio *evaluated*, never the parabola's: the profile
    is not quadratic where a trial moves the tracked pose discontinuously — a load cell's gain
    error of −2 % turned the yaw anchor's moment balance by 52 mrad on a random rig, and the
    parabola through that trial promised Λ = 1.8·10⁶ at h/2 for the wrong cell (c3 instead
    of c1), where the exact re-track gives Λ < 0.  The best evaluated point is the starting
    point of :func:`exact_profile`."""
    key = e["c"].key
    h, lower, _ = profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    offsets = (-h, h) if x0 - h >= lower else (h, 2 * h)
    lams, fits = [], []

    def trial(d):
        w1, M, cands = build({**state["applied"], key: x0 + d}, state["elastic"])
        fit = fit_model(M, columns_of(cands, keys), kappa0, free_kappa, scales, j0)
        lams.append(likelihood_ratio(cost_ref, fit.cost(scales), M))
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


def exact_profile(key, state: dict, build, keys: list, cost_ref: dict, kappa0: float, free_kappa: bool, scales,
                   j0: np.ndarray, w: Window) -> tuple:
    """The exact profile likelihood of a one-parameter rig or data error (a load cell's
    gain, the cables' or the body's mass): the error applied at trial values x (:func:`corrected`), the
    pose re-tracked and the model (without the error's first-order column) refitted; x
    maximises the likelihood ratio against ``cost_ref`` (scipy ``minimize_scalar``,
    bounded, ± a screening step about the current value and above the lower bound of
    :func:`profile_steps`, to 1 % of a step), then — a load cell's gain — Newton steps on its
    first-order column's remainder; x̂ the best point evaluated; σ from the curvature
    (Λ(x) ≈ Λ̂ − (x − x̂)²/σ²), a gain's from its column at x̂.  They move the tracker's
    static pose, so the first-order column's zero (:func:`exact_iterate`) from afar is not the
    optimum.  Returns (applied, w, M, cands, fit, σ)."""
    others = [k for k in keys if k != key]
    prof = {**state.get("profiled", {}), key: np.nan}
    memo = {}

    def evaluate(x):
        x = float(x)
        if x not in memo:
            applied = {**state["applied"], key: x}
            w, M, cands = build(applied, state["elastic"], prof)
            fit = fit_model(M, columns_of(cands, others), kappa0, free_kappa, scales, j0)
            memo[x] = (likelihood_ratio(cost_ref, fit.cost(scales), M), (applied, w, M, cands, fit))
        return memo[x]

    step, lower, h = profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    sol = minimize_scalar(lambda x: -evaluate(x)[0], bounds=(max(lower, x0 - step), x0 + step),
                          method="bounded", options={"xatol": 0.01 * step})
    evaluate(max(float(sol.x), lower))
    sd = float("nan")
    if key[0] == "load_cell_scale":
        # near its optimum the gain's first-order column is a good guide, and the profile is a
        # narrow plateau (the tracker's initial pose takes the yaw from the tensions' moment
        # balance: 0.05 % off the gain it drops by hundreds) that the bracket search can step
        # over: Newton steps on the column's remainder from the best point evaluated, kept
        # while they raise the likelihood; σ the column's
        for _ in range(3):
            xb = max(memo, key=lambda x: memo[x][0])
            applied, _, _, _, fit_b = memo[xb][1]
            prof_wo = {k: v for k, v in prof.items() if k != key}
            _, M1, c1 = build(applied, state["elastic"], prof_wo)
            f1 = fit_model(M1, columns_of(c1, others + [key]), kappa0, free_kappa, scales, from_tensor(fit_b.J))
            k0 = len(columns_of(c1, others))
            beta, sd = float(f1.beta[k0]), float(np.sqrt(max(f1.cov[6 + k0, 6 + k0], 0.0)))
            if abs(beta) < 0.5 * sd or xb + beta < lower or evaluate(xb + beta)[0] <= memo[xb][0]:
                break
    xh = max(memo, key=lambda x: memo[x][0])          # the best point evaluated, never an extrapolation
    if not np.isfinite(sd):
        xc = max(xh, lower + h)
        curv = 2 * evaluate(xc)[0] - evaluate(xc + h)[0] - evaluate(xc - h)[0]
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
