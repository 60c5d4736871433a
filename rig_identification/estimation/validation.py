"""Model validation of an inertia fit: a verdict on every result, and honest σ.

A real rig never matches the model exactly.  The prediction-error fit
(:mod:`rig_identification.estimation.identification`) is unbiased and its σ calibrated *when the
rigid-body model holds*;
when it does not (a body that is not rigid, damping, a sensor delay, a drifting gyro, …)
the tensor can be far off while σ still claims a few percent.  This module tests the fit
with the standard tools of system identification (L. Ljung, *System Identification:
Theory for the User*, 2nd ed., ch. 16, "Model validation") and gives one of three verdicts:

* ``ok`` — every check passes: the σ are the calibrated ones;
* ``model_error`` — some check fails: the data disagree with the rigid-body model; σ is
  widened to cover what the checks saw (the spread between time segments and between
  frequency sub-bands) and is a lower bound of the error, not a calibrated σ;
* ``not_identifiable`` — some entry is not determined by the recording (relative σ above
  :data:`REL_STD_LIMIT`, an ill-conditioned or non-finite fit): those entries are reported
  as ``None`` with what to change on the rig or the excitation.

The checks (each a :class:`Check` with its statistic, threshold, pass/fail and a line of
detail):

``segments``
    cross-validation between time segments: the tensor fitted on each of K consecutive
    segments must agree with the whole window's within the noise — a Wald χ² of the
    segment estimates about the full one with 6 (K − 1) degrees of freedom.  A recording
    whose physics changes with time (a drifting bias, amplitude-dependent friction or
    drag, a transient) fails it.
``sub_bands``
    consistency across frequency: the tensor fitted on the lower and on the upper half
    (by information) of the fit band must agree — Wald χ², 6 degrees of freedom.  An
    apparent inertia that depends on frequency is the signature of a body that is not
    rigid (a sprung mass above its suspension's modes is isolated from the frame) or of
    unmodelled dynamics.
``input_correlation``
    the residual must not be correlated with the input: regressed on the quadrature
    (Hilbert transform, a quarter period of lag) of the model's predicted output, which
    is the input passed through the model — Wald χ², 9 degrees of freedom.  Dissipation
    (a moment in phase with ω instead of ω̇), a time delay between the streams and a
    compliance all put a quadrature component in the residual.  A long, well-excited
    recording resolves a quadrature misfit far too small to matter (bench_any_rig's clean
    6-cable seed 21029: χ²/dof 9.97, 71 of its 90 units in the one DFT bin of the rig's
    0.82 Hz yaw mode, every entry within 0.11 % and 0.49 σ), so beyond its failure threshold
    the check asks the tensor instead: fitted with and without the quadrature regressors,
    it fails only when the two differ beyond the noise (Hausman's test, :func:`hausman`,
    under :func:`chi2_check`'s rule; its statistic is then that test's).
``whiteness``
    no spectral line in the residual: Fisher's g-test (Fisher 1929) of the largest
    periodogram ordinate of the residual in the band over the noise's level there (the
    residual's local median), with the Bonferroni correction over the bins and axes.  A misfit locked to the
    forcing, a mode of the body or of the structure shows as a line.
``weight``
    the load cells' mean vertical force against rig.yaml's weight
    (:func:`~rig_identification.pipeline.fit_validation.weight_surplus`), within :data:`WEIGHT_TOLERANCE`.
``identifiable``
    every entry's σ within :data:`REL_STD_LIMIT` of its scale (its own value for a moment,
    the largest moment for a product), every number finite, a physically consistent
    tensor.

The frequency-domain statistics are weighted least-squares steps (one Gauss–Newton step
from the fitted tensor, on the fit's own linearisation ``FitSeries.jacobian``) over the
DFT bins of the band, each bin weighted by the residual's local spectral level (Whittle's
approximation: DFT ordinates of a stationary process are nearly independent with variance
its spectrum; Brillinger, *Time Series*, 1981, §4.4).  Their covariance is then
½ (Σ Re Aᴴ S⁻¹ A)⁻¹ for the one-sided DFT.  That machinery is
:mod:`~rig_identification.estimation.spectral_wls`; this module holds the checks and the verdict.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.stats import chi2

from ..io.export import MOMENTS
from ..io.verdict import KEYS, Check, Validation, fmt_p
from ..model.parametrisation import from_tensor, physically_consistent
from .directions import AXIS_WORDS, ENTRY_AXES, weak_directions
from .inertia_result import FitSeries, InertiaResult
from .spectral_wls import (
    interior,
    missed_noise,
    spectra,
    wald,
    wls_step,
    wls_step_joint,
)

if TYPE_CHECKING:
    from ..io.rig import Rig

ALPHA = 1e-3                # significance of each statistical check
EFFECT_FACTOR = 2.0         # a consistency check fails beyond this multiple of its significance threshold
WHITENESS_FACTOR = 3.0      # the whiteness check fails beyond this multiple of its significance threshold
REL_STD_LIMIT = 0.10        # σ of an entry beyond this fraction of its scale: not determined
WEAK_SHARE = 0.3            # an entry with this share of an undetermined tensor direction is not determined
DEGENERATE = 1e-6           # a σ (of an entry, or along a tensor direction) below this fraction of the largest
#                             is a singular covariance, not an exact entry
WEIGHT_TOLERANCE = 1e-3     # the load cells' mean vertical force vs rig.yaml's weight
HAUSMAN_RANK = 1e-2       # Hausman's test leaves out directions where the further regressors add less
#                             than this fraction of the variance
EDGE_MARGIN = 1.15          # the whiteness test skips the band's edges (the filter's skirts, where the
#                             residual's level falls faster than its running median follows)


def with_products(keys: Iterable[str]) -> set[str]:
    """The entry keys ``keys`` with every product of inertia about an axis whose moment is
    among them: a product is no better determined than the moments about its axes
    (:data:`~rig_identification.estimation.directions.ENTRY_AXES`)."""
    out = set(keys)
    return out | {k for k, axes in ENTRY_AXES.items() if len(axes) == 2 and any(MOMENTS[a] in out for a in axes)}


def entry_scale(theta: np.ndarray, determined: np.ndarray) -> np.ndarray:
    """(6,) kg·m², :data:`~rig_identification.io.verdict.KEYS` order: the scale an entry's σ is
    judged on for identifiability — a moment's own magnitude; for a product the largest
    *determined* moment's (``determined`` (3,) bool, ixx iyy izz: an undetermined moment's value
    means nothing), the largest moment's or 1 kg·m² when none is.  theta: (6,) kg·m²."""
    theta = np.abs(np.asarray(theta, float))
    diag = theta[[0, 3, 5]]
    det = np.asarray(determined, bool)
    big = float(diag[det].max()) if det.any() and diag[det].max() > 0 else float(max(diag.max(), 1.0))
    return np.array([theta[0], big, big, theta[3], big, theta[5]])


def chi2_check(name: str, stat: float, dof: int, detail: str) -> Check:
    """A consistency check from its Wald statistic ``stat`` with ``dof`` degrees of freedom:
    significant beyond the χ² quantile 1 − :data:`ALPHA`; failed beyond :data:`EFFECT_FACTOR`
    times it (a model error that matters, not one a long recording merely resolves); between
    the two σ is widened by the Birge ratio √(χ²/dof) (Birge 1932; the Particle Data Group's
    scale factor)."""
    dof = max(int(dof), 1)
    thr = float(chi2.ppf(1 - ALPHA, dof))
    p = float(chi2.sf(stat, dof))
    factor = float(np.sqrt(stat / dof)) if stat > thr else 1.0
    return Check(name, stat / dof, EFFECT_FACTOR * thr / dof, bool(stat <= EFFECT_FACTOR * thr),
                 f"{detail}; χ²/dof {stat / dof:.2f} ({dof} dof), p = {fmt_p(p)}"
                 + (f": beyond the noise, σ widened {factor:.2f}×" if 1.0 < factor and stat <= EFFECT_FACTOR * thr
                    else ""), factor if stat <= EFFECT_FACTOR * thr else 1.0)


def n_segments(duration: float) -> int:
    """Time segments of the cross-validation: 4 for ≥ 80 s, 3 for ≥ 40 s, else 2."""
    return 4 if duration >= 80 else 3 if duration >= 40 else 2


def segment_check(series: list[FitSeries], theta: np.ndarray,
                  scale: np.ndarray) -> tuple[Check, np.ndarray, np.ndarray]:
    """Cross-validation between time segments (see module docstring).  Each series (one per
    recording) is cut into :func:`n_segments` pieces; each piece's tensor is the full fit
    moved by its own weighted least-squares step.  With K independent pieces of covariance
    V_k about their common mean, Σ (θ_k − θ̄)ᵀ V_k⁻¹ (θ_k − θ̄) is χ² with 6 (K − 1) degrees of
    freedom; the whole window's estimate stands for θ̄.  scale (6,6): E, the covariance
    of the whole fit that its frequency-domain one misses (the noise that reaches the
    estimate through the tracker's pose, which the residual's spectrum does not show; see
    :func:`missed_noise`): a piece with a fraction f of the samples has V_k + E / f.
    Returns the check, the segments' entries (K,6) kg·m² and their (start, end) stamps (K,2) s."""
    E = np.asarray(scale, float)
    ests: Any   # a list of (6,), then their (K,6) array
    ests, times, stat, dof = [], [], 0.0, 0
    for s in series:
        full = spectra(s)
        d0, _ = wls_step(full)
        K = n_segments(float(s.t[-1] - s.t[0]))
        # the segments partition the window (their stamps say so); each is fitted over its
        # samples in the interior (the first and last lose the band-pass's edge transients)
        inner = interior(s)
        edges = np.linspace(0, len(s.t), K + 1).astype(int)
        for a, b in zip(edges[:-1], edges[1:]):
            lo, hi = max(a, inner.start), min(b, inner.stop)
            part = spectra(s, slice(lo, hi))
            frac = (hi - lo) / (inner.stop - inner.start)
            d, V = wls_step_joint([part])
            x, k = wald(d - d0, V + E / frac)
            stat += x
            dof += k
            ests.append(theta + d)
            times.append((s.t[a], s.t[b - 1]))
        dof -= 6
    ests = np.array(ests)
    worst = np.max(np.abs(ests - theta), axis=0)
    big = int(np.argmax(worst / np.maximum(np.abs(theta[[0, 0, 0, 3, 3, 5]]), 1e-9)))
    detail = (f"{len(ests)} segments of the window fitted on their own; largest departure from the whole "
              f"window's tensor {KEYS[big]} {worst[big]:.3g} kg·m²")
    return chi2_check("segments", stat, max(dof, 1), detail), ests, np.array(times)


def band_check(series: list[FitSeries], theta: np.ndarray,
               scale: np.ndarray) -> tuple[Check | None, np.ndarray | None, tuple[float, float, float] | None]:
    """Consistency across frequency (see module docstring): the band split where the
    information (trace of the covariance-weighted information of the bins) reaches half,
    both halves fitted, their difference tested.  Returns the check (None when the band
    has fewer than 8 bins per half), the halves' entries (2,6) kg·m² and the edges (3,) Hz
    (of the first series).  scale (6,6): :func:`missed_noise`'s E; each half holds half the
    information, its covariance V_h + 2 E."""
    sps = [spectra(s) for s in series]
    _, V = wls_step_joint(sps)
    halves = []
    for sp in sps:
        W = 1.0 / sp.S
        per_bin = np.einsum("bip,bi,biq->bpq", sp.A.conj(), W, sp.A).real
        info = np.einsum("pq,bqp->b", V, per_bin)
        c = np.cumsum(info) / max(info.sum(), 1e-300)
        k = int(np.searchsorted(c, 0.5)) + 1
        k = min(max(k, 1), len(sp.f) - 1)
        if k < 8 or len(sp.f) - k < 8:
            return None, None, None
        halves.append((np.arange(k), np.arange(k, len(sp.f))))
    (d1, V1), (d2, V2) = [wls_step_joint(sps, [h[i] for h in halves]) for i in (0, 1)]
    E = np.asarray(scale, float)
    stat, dof = wald(d1 - d2, V1 + V2 + 4.0 * E)
    f = sps[0].f
    split = 0.5 * (f[halves[0][0][-1]] + f[halves[0][1][0]])
    edges = (float(series[0].band_hz[0]), float(split), float(series[0].band_hz[1]))
    diff = np.abs(d1 - d2)
    big = int(np.argmax(diff / np.maximum(np.abs(theta[[0, 0, 0, 3, 3, 5]]), 1e-9)))
    detail = (f"the band split at {split:.2f} Hz (half the information below): {KEYS[big]} "
              f"{theta[big] + d1[big]:.4g} below vs {theta[big] + d2[big]:.4g} kg·m² above")
    return chi2_check("sub_bands", stat, dof, detail), np.array([theta + d1, theta + d2]), edges


def quadrature_check(series: list[FitSeries]) -> Check:
    """Correlation of the residual with the input (see module docstring): the residual of
    each gyro axis regressed on the quadrature of the three predicted outputs, jointly with
    the tensor; Wald χ² of the 9 coefficients (:func:`chi2_check`).  Where that χ² is beyond
    the failure threshold, whether the correlation matters is asked of the tensor
    (:func:`hausman`): the check then fails only when adding the quadrature regressors moves
    the tensor beyond its failure threshold, and its statistic is that test's."""
    sps = [spectra(s) for s in series]

    def quadrature(y: np.ndarray) -> np.ndarray:         # (…,B,3) → (…,B,3,9)
        X = np.zeros(y.shape + (9,), complex)
        for a in range(3):
            X[..., a, 3 * a:3 * a + 3] = -1j * y         # Hilbert transform, positive frequencies
        return X

    step, cov = wls_step_joint(sps, extras=[quadrature(sp.y) for sp in sps])
    beta, V = step[6:], cov[6:, 6:]
    stat, dof = wald(beta, V)
    B = beta.reshape(3, 3)
    a = int(np.argmax(np.abs(np.diag(B))))
    detail = (f"residual regressed on the quadrature (a quarter period late) of the predicted ω: "
              f"largest direct coefficient {B[a, a]:+.3g} on gyro {'xyz'[a]}")
    check = chi2_check("input_correlation", stat, dof, detail)
    if check.passed:
        return check
    d0, V0 = wls_step_joint(sps)
    h, hdof, moved = hausman(step[:6] - d0, cov[:6, :6], V0)
    big = int(np.argmax(np.abs(moved)))
    return chi2_check("input_correlation", h, hdof,
                      f"{detail}, χ²/dof {stat / max(dof, 1):.2f} ({dof} dof) beyond {check.threshold:.2f}: "
                      f"does it move the tensor? Fitted with the quadrature regressors {KEYS[big]} moves "
                      f"{moved[big]:+.2f} σ (the frequency-domain fit's σ; Hausman's test of the difference)")


def hausman(diff: np.ndarray, V1: np.ndarray, V0: np.ndarray) -> tuple[float, int, np.ndarray]:
    """Hausman's specification test (J. A. Hausman, Econometrica 46:1251, 1978) of the tensor
    fitted with further regressors against the tensor without them: diff (6,) kg·m² the
    difference of the two estimates, V1, V0 (6,6) their covariances (the efficient one, V0,
    without the regressors).  Under the null — the regressors' coefficients zero, so both
    estimates consistent — diff has covariance V1 − V0, and diffᵀ (V1 − V0)⁺ diff is χ² with
    its rank.  The rank is taken in V0's metric: along a direction where the further
    regressors add less than :data:`HAUSMAN_RANK` of V0's variance (the generalized
    eigenvalues of (V1 − V0, V0)) a difference can only be a small fraction of σ, and there
    it is the compensated steps' numerical difference rather than a sample of V1 − V0 (on
    bench_any_rig's seed 21029 a move of 0.016 σ along a direction of relative variance 9·10⁻⁶
    made 31 of the statistic's 43 units); those directions are left out.
    Returns (statistic, degrees of freedom, diff over V0's σ per entry (6,))."""
    V0 = 0.5 * (V0 + V0.T)
    ev0, U0 = np.linalg.eigh(V0)
    keep = ev0 > 1e-9 * max(float(ev0.max()), 1e-300)
    T = U0[:, keep] / np.sqrt(ev0[keep])                 # whitening by V0: x = Tᵀ d has unit covariance
    lam, W = np.linalg.eigh(T.T @ (0.5 * (V1 + V1.T) - V0) @ T)
    z = W.T @ (T.T @ diff)
    use = lam > HAUSMAN_RANK
    moved = diff / np.sqrt(np.clip(np.diag(V0), 1e-300, None))
    return float(np.sum(z[use] ** 2 / lam[use])), int(use.sum()), moved


def whiteness_check(series: list[FitSeries]) -> Check:
    """Fisher's g-test for a spectral line in the residual (see module docstring): the
    largest ratio of a periodogram ordinate to the noise's level there
    (:class:`~rig_identification.estimation.spectral_wls.Spectra`'s S, the residual's running
    median: the ratio exponential), Bonferroni over the bins and axes.  Statistic and threshold
    in units of that ratio."""
    worst, where, n = 0.0, "", 0
    for s in series:
        sp = spectra(s)
        lo, hi = s.band_hz
        inner = (sp.f >= EDGE_MARGIN * lo) & (sp.f <= hi / EDGE_MARGIN)   # the filter's skirts excluded
        ratio = (np.abs(sp.r) ** 2 / sp.S)[inner]                      # P / the noise's level
        n += ratio.size
        i, a = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[i, a] > worst:
            worst, where = float(ratio[i, a]), f"gyro {'xyz'[a]} at {sp.f[inner][i]:.3f} Hz"
    # the level a running median: P / level is exponential, P(ratio > x) = e^−x
    thr, p = float(np.log(n / ALPHA)), min(1.0, n * float(np.exp(-worst)))
    return Check("whiteness", worst, WHITENESS_FACTOR * thr, bool(worst <= WHITENESS_FACTOR * thr),
                 f"largest residual line {worst:.1f}× its local median level ({where}); p = {fmt_p(p)}"
                 + (" (significant, but too small to matter)" if thr < worst <= WHITENESS_FACTOR * thr else ""))


def identifiability(result: InertiaResult, std: np.ndarray, cov: np.ndarray | None = None
                    ) -> tuple[Check, tuple[str, ...]]:
    """Which entries the recording determines (see module docstring): std (6,) kg·m² the σ the
    noise gives each entry; cov (6,6) their covariance (default: ``result.covariance``'s
    correlations with ``std``) — a tensor direction (:func:`~rig_identification.estimation.directions.weak_directions`)
    whose σ is beyond :data:`REL_STD_LIMIT` of tr J / 3 leaves every entry with a component of
    at least :data:`WEAK_SHARE` in it undetermined: the systematic errors of the chain act
    along it too, and move those entries far beyond their σ (a 5-cable rig whose roll and
    pitch the exciter hardly moved: Iyy 42 % off at 5 σ with a relative σ of 6 %)."""
    theta = from_tensor(result.inertia)
    finite = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(std)) and np.all(np.isfinite(result.covariance)))
    if not finite:
        return Check("identifiable", None, REL_STD_LIMIT, False,
                     "the fit produced non-finite numbers: the recording does not determine the tensor"), KEYS
    diag = np.abs(theta[[0, 3, 5]])
    rel_diag = std[[0, 3, 5]] / np.maximum(diag, 1e-300)
    nil = (std <= DEGENERATE * float(np.max(std))) if np.max(std) > 0 else np.zeros(6, bool)
    ok_diag = (rel_diag <= REL_STD_LIMIT) & ~nil[[0, 3, 5]]
    # a product's scale: the largest determined moment (an undetermined one's value means nothing)
    scale = entry_scale(theta, ok_diag)
    big = float(scale[1])
    rel = std / np.maximum(scale, 1e-9 * big)
    # and a product of two axes is no better determined than the moments about them
    axes = {k: a for k, a in ENTRY_AXES.items() if len(a) == 2}
    if cov is None:
        with np.errstate(all="ignore"):
            c = np.sqrt(np.clip(np.diag(result.covariance), 1e-300, None))
            corr = np.nan_to_num(result.covariance / np.outer(c, c))
        cov = corr * np.outer(std, std)
    weak = set()
    dirs = weak_directions(result.inertia, cov, n=6)
    top = max((r for r, _ in dirs), default=0.0)
    for rel_d, D in dirs:
        # a direction whose variance is numerically nil beside the others' is not exact: the
        # covariance is singular there (an estimate the data do not hold, J → ∞ along it: a
        # 5-cable rig whose roll and pitch the noise swamped gave Ixx = Iyy = 1.2e10 kg·m²
        # with σ 0, bench_any_rig's seed 21017)
        if rel_d > REL_STD_LIMIT or (top > 0 and rel_d <= DEGENERATE * top):
            weak |= {k for k, x in zip(KEYS, from_tensor(D)) if abs(x) >= WEAK_SHARE}
    ok_diag = ok_diag & np.array([k not in weak for k in ("ixx", "iyy", "izz")])
    bad = tuple(k for k, r, z in zip(KEYS, rel, nil)
                if not r <= REL_STD_LIMIT or z or k in weak or (k in axes and not all(ok_diag[i] for i in axes[k])))
    consistent = physically_consistent(result.inertia)
    if not consistent and not bad:
        bad = tuple(KEYS)
    worst = int(np.argmax(rel))
    detail = (f"largest relative σ {KEYS[worst]} {100 * rel[worst]:.3g} % (limit {100 * REL_STD_LIMIT:g} %: "
              "of the entry for moments, of the largest determined moment for products; a product is not "
              "determined when a moment about one of its axes is not)")
    if not consistent:
        detail += "; the tensor is not physically consistent"
    return Check("identifiable", float(rel[worst]), REL_STD_LIMIT, not bad, detail), bad


def advice(bad: tuple[str, ...], rig: Rig | None = None) -> tuple[str, ...]:
    """What to change so that the ``bad`` entries are determined, in words."""
    out = []
    if rig is not None:
        up = []
        for c in rig.cables:
            v = np.asarray(c.ceiling_anchor, float)
            up.append(v)
        # the cables' largest angle from the vertical at the rig.yaml geometry (level body)
        d = rig.ceiling_anchors[:, :2] - rig.body_anchors[:, :2]
        d = d - d.mean(0)
        splay = np.max(np.linalg.norm(d, axis=1) / rig.cable_lengths)
        if splay < 0.05 and any(k in bad for k in ("ixx", "iyy", "ixy")):
            out.append(f"the cables are nearly parallel (splay {splay:.3f} m per m of cable): the geometry hardly "
                       "restores the body's tilt about x and y — splay the ceiling anchors outward (0.3–0.8 m)")
        if len(rig.cables) == 3:
            out.append("with three cables one swing of the body is not held by the cable lengths; a fourth cable "
                       "helps")
    turn = [AXIS_WORDS[ENTRY_AXES[k][0]] for k in bad if k in MOMENTS]
    if turn:
        out.append(f"the body hardly turned about {', '.join(turn)}: move the exciter farther from that axis or "
                   "turn its spin axis, raise the force or move its frequency nearer a mode that turns the body "
                   "about it — `rig-identify plan RIG --inertia …` finds the run")
    elif bad:
        out.append("the products need the body turned about two axes at once: mount the exciter off the body's "
                   "planes of symmetry or with a diagonal spin axis — `rig-identify plan` finds the run")
    return tuple(out)


def propagated_covariance(result: InertiaResult) -> np.ndarray | None:
    """(6,6) kg²·m⁴: the covariance the sensors' noise gives the estimate — its σ
    ``result.crb_std`` (propagated through the chain) with the correlations of
    ``result.covariance`` (the propagated covariance's when σ is; the sandwich's under a
    residual excess); None without ``crb_std``."""
    if result.crb_std is None:
        return None
    C = np.asarray(result.covariance, float)
    with np.errstate(all="ignore"):
        c = np.sqrt(np.clip(np.diag(C), 1e-300, None))
        corr = np.nan_to_num(C / np.outer(c, c))
    return corr * np.outer(result.crb_std, result.crb_std)


def validate(result: InertiaResult, weight_surplus: float | None = None, rig: Rig | None = None) -> Validation:
    """The verdict on an inertia fit (see module docstring).

    result: the fit (:func:`~rig_identification.estimation.identification.identify_inertia`, with ``series`` carrying
    the Jacobian).  weight_surplus: see
    :func:`~rig_identification.pipeline.fit_validation.weight_surplus`.  rig: for the advice on
    geometry.  Never raises on
    bad numbers: a fit that produced them is ``not_identifiable``.
    """
    checks: list[Check] = []
    c: Check | None
    theta = from_tensor(result.inertia)
    std = np.asarray(result.inertia_std, float)
    finite = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(std)))
    segs = times = bands = edges = None
    series = [s for s in result.series if s.jacobian is not None]
    if series and finite:
        with np.errstate(all="ignore"):
            try:
                scale = missed_noise(series, propagated_covariance(result))
                c, segs, times = segment_check(series, theta, scale)
                checks.append(c)
                c, bands, edges = band_check(series, theta, scale)
                if c is not None:
                    checks.append(c)
                checks.append(quadrature_check(series))
                checks.append(whiteness_check(series))
            except (np.linalg.LinAlgError, ValueError) as e:
                checks.append(Check("segments", None, None, False, f"the validation could not run ({e})"))
    if weight_surplus is not None:
        checks.append(Check("weight", abs(weight_surplus), WEIGHT_TOLERANCE,
                            bool(abs(weight_surplus) <= WEIGHT_TOLERANCE),
                            f"the load cells carry {100 * weight_surplus:+.3f} % of rig.yaml's weight beyond it"))
    factor = max([1.0] + [c.sigma_factor for c in checks])
    # whether the recording determines an entry is the noise's question (the propagated σ, checked
    # against the replays): a model error's residuals widen the sandwich σ of an entry the
    # excitation determines well (unmodelled damping: Ixx's σ 4 % from the noise, 20 % widened).
    # Nor does the consistency checks' Birge factor enter it: it measures a misfit between
    # segments or sub-bands (the model's question, σ is widened by it in widened_std), not
    # how much the geometry and the excitation tell about an entry — with it, a damped 4-cable
    # rig (test_validation's, Ixx's noise σ 4.7 %) turned not_identifiable as soon as its
    # sub-band misfit fell from "failed" to "widened 2.48×"
    noise_std = std if result.crb_std is None else np.asarray(result.crb_std, float)
    ident, bad = identifiability(result, noise_std)
    # a product is not determined when a moment about one of its axes is not, whichever check
    # found the moment undetermined (the noise in the input along it too: bench_any_rig's seed
    # 21000 gave Ixy 22 % off under a biased Ixx)
    out = with_products(set(bad))
    bad = tuple(k for k in KEYS if k in out)
    checks.append(ident)
    parts = [np.zeros(6)]
    if segs is not None:
        parts.append(np.max(np.abs(segs - theta), axis=0))
    if bands is not None:
        parts.append(np.abs(bands[0] - bands[1]))
    spread = np.max(parts, axis=0)
    failed = tuple(c.name for c in checks
                   if c.passed is False and c.name != "identifiable")
    if bad:
        verdict = "not_identifiable"
    elif failed:
        verdict = "model_error"
    else:
        verdict = "ok"
    return Validation(verdict, tuple(checks), bad, advice(bad, rig) if bad else (), segs, times, bands, edges,
                      spread, failed, factor)


def beyond_limit_widened(theta: np.ndarray, widened: np.ndarray, validation: Validation,
                         rig: Rig | None = None) -> Validation:
    """Under ``not_identifiable``, the entries the widened σ (``widened`` (6,) kg·m²,
    :func:`widened_std`) leaves beyond :data:`REL_STD_LIMIT` of their scale (a moment's own, the
    largest determined moment's for a product), and the products of their moments, are not
    determined either: ``validation`` with them added to ``undetermined`` and the ``advice``
    made again (``rig`` as :func:`advice`).  Identifiability is the noise's question
    (:func:`validate`), so a model error alone never takes an entry away; but once the recording
    is ``not_identifiable`` with a consistency check failed, an entry given with σ several times
    itself is no answer (bench_any_rig's seed 25002: Iyy 72 % off with σ 347 %, where the truth's
    prediction says Iyy is not determined).  ``validation`` unchanged otherwise.  theta: (6,)
    kg·m², the fit's entries."""
    if validation.verdict != "not_identifiable":
        return validation
    gone = set(validation.undetermined)
    scale = entry_scale(theta, np.array([k not in gone for k in MOMENTS]))
    with np.errstate(all="ignore"):
        rel = np.asarray(widened, float) / scale
    out = with_products(gone | {k for k, r in zip(KEYS, rel) if not r <= REL_STD_LIMIT})
    if out == gone:
        return validation
    bad = tuple(k for k in KEYS if k in out)
    return replace(validation, undetermined=bad, advice=advice(bad, rig))


def widened_std(std: np.ndarray, validation: Validation) -> np.ndarray:
    """σ (6,) kg·m² as the validation leaves it: the fit's σ times the consistency checks'
    :attr:`~rig_identification.io.verdict.Validation.sigma_factor`; under ``model_error`` also the spread the
    validation saw between time segments and frequency sub-bands, in quadrature — then a
    lower bound of the error, not a calibrated σ.  So also under ``not_identifiable`` when a
    consistency check failed: the entries it still gives carry the same spread (clean 5-cable
    rigs of bench_trust: the determined entries 3.5–4.3 σ off with the fit's σ alone)."""
    s = np.asarray(std, float) * validation.sigma_factor
    if not validation.failed or validation.spread_std is None:
        return s
    widened: np.ndarray = np.sqrt(s**2 + validation.spread_std**2)
    return widened
