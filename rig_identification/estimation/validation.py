"""Model validation of an inertia fit: a verdict on every result, and honest σ.

A real rig never matches the model exactly.  The prediction-error fit
(:mod:`rig_identification.estimation.identification`) is unbiased and its σ calibrated *when the rigid-body model holds*;
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

``residual_level``
    the band-passed gyro residual RMS over the one the sensors' noise predicts (the noise
    realisations of the residual, :func:`residual_excess`, away from the band-pass's edge
    transients, :func:`interior`; else the fit's ``residual_excess``; per axis, the
    largest), ≤ :data:`RESIDUAL_RATIO`.
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
    compliance all put a quadrature component in the residual.
``whiteness``
    no spectral line in the residual: Fisher's g-test (Fisher 1929) of the largest
    periodogram ordinate of the residual in the band over the noise's level there (the
    noise realisations' spectrum; without them the residual's local median), with the
    Bonferroni correction over the bins and axes.  A misfit locked to the forcing, a
    mode of the body or of the structure shows as a line.
``accelerometer``
    a channel the fit does not use: the specific force at the IMU predicted from the
    generalized force and the identified model, ``f = F/m + α × ρ + ω × (ω × ρ)`` with
    ``α = J⁻¹(M − ω × Jω)`` (Newton–Euler, ρ from the CG to the IMU), band-passed as the
    fit, against the accelerometer: residual RMS over the accelerometer's in-band noise
    ≤ :data:`ACCEL_RATIO`.  A body that is not rigid, a wrong IMU position, a load-cell
    delay or gain fail it.
``weight``
    the load cells' mean vertical force against rig.yaml's weight
    (:func:`~rig_identification.pipeline.offline.weight_surplus`), within :data:`WEIGHT_TOLERANCE`.
``errors_in_variables``
    the share of the fit's input that is the sensors' noise (the gyro's reaches the moment
    through the tracked pose), along its noisiest direction, within
    :data:`~rig_identification.estimation.errors_in_variables.EIV_LIMIT`: the fit is compensated for that noise
    (:mod:`rig_identification.estimation.errors_in_variables`), which holds to first order; beyond the limit the noise
    is as large as the signal and the entries along that direction are not determined.
``identifiable``
    every entry's σ within :data:`REL_STD_LIMIT` of its scale (its own value for a moment,
    the largest moment for a product), every number finite, a physically consistent
    tensor.

The frequency-domain statistics are weighted least-squares steps (one Gauss–Newton step
from the fitted tensor, on the fit's own linearisation ``FitSeries.jacobian``) over the
DFT bins of the band, each bin weighted by the residual's local spectral level (Whittle's
approximation: DFT ordinates of a stationary process are nearly independent with variance
its spectrum; Brillinger, *Time Series*, 1981, §4.4).  Their covariance is then
½ (Σ Re Aᴴ S⁻¹ A)⁻¹ for the one-sided DFT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter, uniform_filter1d
from scipy.signal import butter, sosfiltfilt
from scipy.stats import chi2

from .errors_in_variables import EIV_LIMIT, capped
from .directions import weak_directions
from .inertia_result import FitSeries, InertiaResult
from ..io.verdict import KEYS, Check, Validation, fmt_p
from ..model.parametrisation import from_tensor, physically_consistent

ALPHA = 1e-3                # significance of each statistical check
EFFECT_FACTOR = 2.0         # a consistency check fails beyond this multiple of its significance threshold
WHITENESS_FACTOR = 3.0      # the whiteness check fails beyond this multiple of its significance threshold
RESIDUAL_RATIO = 1.6        # residual RMS / the noise's, per gyro axis
ACCEL_RATIO = 1.6           # accelerometer residual RMS / its in-band noise, per axis
REL_STD_LIMIT = 0.10        # σ of an entry beyond this fraction of its scale: not determined
WEAK_SHARE = 0.3            # an entry with this share of an undetermined tensor direction is not determined
DEGENERATE = 1e-6           # a σ (of an entry, or along a tensor direction) below this fraction of the largest
#                             is a singular covariance, not an exact entry
WEIGHT_TOLERANCE = 1e-3     # the load cells' mean vertical force vs rig.yaml's weight
EDGE_PERIODS = 1.5          # periods of the band's low edge left out at each end of a series by the checks
EDGE_MARGIN = 1.15          # the whiteness test skips the band's edges (the filter's skirts, where the
#                             residual's level falls faster than its running median follows)
SMOOTH_HZ = 0.25            # width of the running median that estimates the residual's spectrum (no realisations)
NOISE_BINS = 5              # neighbouring bins over which the noise realisations' periodograms are averaged


# --- frequency-domain weighted least squares on the fit's linearisation --------------------

@dataclass(frozen=True)
class Spectra:
    """DFT of one fitted segment's residual, Jacobian and prediction over the bins of its band.

    f (B,) Hz; r (B,3) residual; A (B,3,6) Jacobian; y (B,3) predicted output; S (B,3) the
    noise's spectral level in the residual: where the fit carries the noise realisations of
    its residual (a compensated fit), their periodograms averaged over the realisations and
    :data:`NOISE_BINS` bins — the noise's own spectrum, peaks included (the noise the
    tracker's pose passes through the cables' moment rises at the rig's modes: on a 6-cable
    rig 8× its neighbours at the yaw mode, where the residual's running median saw a
    spectral line 85× "the noise"); else the residual's running median of the periodogram /
    ln 2 (:data:`SMOOTH_HZ`)."""

    f: np.ndarray
    r: np.ndarray
    A: np.ndarray
    y: np.ndarray
    S: np.ndarray
    dA: np.ndarray | None = None     # (K,B,3,6) the noise realisations of A (FitSeries.noise_jacobian)
    dr: np.ndarray | None = None     # (K,B,3) and of r (FitSeries.noise_residual)
    dof: int | None = None           # degrees of freedom of S when it is the realisations' (else None: the median's)


def interior(series: FitSeries) -> slice:
    """The samples of a fitted series the checks use: all but :data:`EDGE_PERIODS` periods of
    the band's low edge at each end (at most a tenth of the series each).  There the
    band-pass's start-up transient still rings: scipy ``sosfiltfilt``'s odd extension
    reflects the output about its first and last *sample*, whose gyro noise (2e-3 rad/s, 9×
    the noise left in the band) becomes a step at each edge that rings through the band for
    about 1/f_lo; the regressor, an integral, has no such step.  Over a 60 s record with a
    0.18 Hz low edge those transients carry as much noise power as all the rest.  They made
    the ``residual_level`` false alarms of bench_trust's clean seeds 7312 (gyro z 1.73× the
    noise over the whole series, 1.1× without 2 s at each end) and 7611 (gyro y 1.83×, 0.93×)."""
    n = len(series.t)
    fs = series.fs if series.fs else 1.0 / float(np.median(np.diff(series.t)))
    c = int(min(n // 10, round(EDGE_PERIODS * fs / series.band_hz[0])))
    return slice(c, n - c)


def spectra(series: FitSeries, rows: slice | None = None) -> Spectra:
    """:class:`Spectra` of ``series`` (its jacobian must be set) over the time ``rows``
    (default its :func:`interior`).  Raises ValueError when the series has no Jacobian."""
    if series.jacobian is None:
        raise ValueError("validation needs the fit's Jacobian (FitSeries.jacobian)")
    if rows is None:
        rows = interior(series)
    r = series.residual[rows]
    A = series.jacobian[rows]
    y = series.predicted[rows]
    n = len(r)
    fs = series.fs if series.fs else 1.0 / float(np.median(np.diff(series.t)))
    f = np.fft.rfftfreq(n, 1.0 / fs)
    lo, hi = series.band_hz
    m = (f >= lo) & (f <= hi)
    R = np.fft.rfft(r, axis=0)[m]
    P = np.abs(R) ** 2
    dA = dr = None
    dof = None
    if series.noise_jacobian is not None and series.noise_residual is not None:
        dA = np.fft.rfft(series.noise_jacobian[:, rows], axis=1)[:, m]
        dr = np.fft.rfft(series.noise_residual[:, rows], axis=1)[:, m]
        # the noise's own spectrum: the realisations' periodograms, averaged over them and
        # NOISE_BINS neighbouring bins (2·K·NOISE_BINS degrees of freedom per bin)
        S = uniform_filter1d(np.mean(np.abs(dr) ** 2, axis=0), NOISE_BINS, axis=0, mode="nearest")
        dof = 2 * len(dr) * NOISE_BINS
    else:
        width = max(5, int(round(SMOOTH_HZ * n / fs)) | 1)
        S = median_filter(P, size=(width, 1), mode="nearest") / np.log(2)
    S = np.maximum(S, 1e-12 * max(float(S.max()), 1e-300))
    return Spectra(f[m], R, np.fft.rfft(A, axis=0)[m], np.fft.rfft(y, axis=0)[m], S, dA, dr, dof)


def wls_step(sp: Spectra, bins=None, extra=None) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares step over the DFT bins (Whittle weights 1/S), compensated for
    the noise in the input when the spectra carry its realisations (:func:`wls_step_joint`).

    extra: optional (B,3,q) further regressors.  Returns (step (6+q,), covariance (6+q,6+q))
    of the tensor entries (kg·m²) and of the extra coefficients."""
    return wls_step_joint([sp], None if bins is None else [bins], None if extra is None else [extra])


def wald(d: np.ndarray, V: np.ndarray) -> tuple[float, int]:
    """Wald statistic dᵀ V⁺ d and its degrees of freedom (rank of V, eigenvalues above 1e-9
    of the largest)."""
    ev, U = np.linalg.eigh(0.5 * (V + V.T))
    keep = ev > 1e-9 * max(ev.max(), 1e-300)
    z = U[:, keep].T @ d
    return float(np.sum(z**2 / ev[keep])), int(keep.sum())


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


def segment_check(series: list[FitSeries], theta: np.ndarray, scale: np.ndarray) -> tuple[Check, np.ndarray, np.ndarray]:
    """Cross-validation between time segments (see module docstring).  Each series (one per
    recording) is cut into :func:`n_segments` pieces; each piece's tensor is the full fit
    moved by its own weighted least-squares step.  With K independent pieces of covariance
    V_k about their common mean, Σ (θ_k − θ̄)ᵀ V_k⁻¹ (θ_k − θ̄) is χ² with 6 (K − 1) degrees of
    freedom; the whole window's estimate stands for θ̄.  scale (6,): the factor by which each
    entry's σ exceeds the frequency-domain one (the noise that reaches the estimate through
    the tracker's pose, which the residual's spectrum does not show; see :func:`noise_scale`).
    Returns the check, the segments' entries (K,6) kg·m² and their (start, end) stamps (K,2) s."""
    D = np.diag(scale)
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
            mom = [piece_noise(full, part, (hi - lo) / (inner.stop - inner.start))]
            d, V = wls_step_joint([part], moments=mom)
            B = determined([part], moments=mom)
            x, k = wald(B.T @ (d - d0), B.T @ D @ V @ D @ B)
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


def piece_noise(full: Spectra, part: Spectra, fraction: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The noise moments of the compensated step (:func:`wls_step_joint`) of a piece of a
    record — ``fraction`` of its samples, spectra ``part`` — from the whole record's noise
    realisations (``full``): the noise is stationary, so its cross-spectrum is estimated
    from the whole record (far more bins than the piece's own realisations have: a quarter
    of a 90 s record compensated with its own three realisations scattered 3× beyond its
    σ), weighted with the piece's own residual level and scaled to its length (a piece's
    periodogram and level are ``fraction`` of the whole's, its bins ``fraction`` as many).
    Returns (N (K,6,6), n (K,6)) per realisation, or None when ``full`` has none."""
    if full.dA is None or full.dr is None:
        return None
    W = 1.0 / np.column_stack([np.interp(full.f, part.f, part.S[:, i]) for i in range(3)])
    return (fraction**2 * np.einsum("kbip,bi,kbiq->kpq", full.dA.conj(), W, full.dA).real,
            fraction**2 * np.einsum("kbip,bi,kbi->kp", full.dA.conj(), W, full.dr).real)


def residual_excess(series: list[FitSeries]) -> np.ndarray | None:
    """(3,) per gyro axis: the fit's residual RMS over the :func:`interior` of its series over the
    RMS of the noise realisations of the residual there (every path of the noise: the
    replays', :attr:`FitSeries.noise_residual`); None when a series has no realisations."""
    num, den = np.zeros(3), np.zeros(3)
    for s in series:
        if s.noise_residual is None:
            return None
        rows = interior(s)
        num += np.sum(s.residual[rows] ** 2, axis=0)
        den += np.mean(np.sum(s.noise_residual[:, rows] ** 2, axis=1), axis=0)
    return np.sqrt(num / np.maximum(den, 1e-300))


def noise_scale(series: list[FitSeries], std: np.ndarray | None) -> np.ndarray:
    """(6,) ≥ 1: the propagated σ of each entry (``std``: the noise's, through tracker,
    preprocessor and identifier) over the frequency-domain σ of the same fit, which sees
    the output's residual only.  Ones when ``std`` is None."""
    if std is None:
        return np.ones(6)
    _, V = wls_step_joint([spectra(s) for s in series])
    return np.maximum(1.0, np.asarray(std, float) / np.sqrt(np.maximum(np.diag(V), 1e-300)))


def band_check(series: list[FitSeries], theta: np.ndarray, scale: np.ndarray) -> tuple[Check | None, np.ndarray | None, tuple | None]:
    """Consistency across frequency (see module docstring): the band split where the
    information (trace of the covariance-weighted information of the bins) reaches half,
    both halves fitted, their difference tested.  Returns the check (None when the band
    has fewer than 8 bins per half), the halves' entries (2,6) kg·m² and the edges (3,) Hz
    (of the first series)."""
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
    D = np.diag(scale)
    B1, B2 = [determined(sps, [h[i] for h in halves]) for i in (0, 1)]
    # the directions both halves determine (the complement of the union of the noisy ones)
    U, sv, _ = np.linalg.svd(np.eye(6) - _projector(B1) @ _projector(B2) @ _projector(B1) if B1.shape[1] < 6 or
                             B2.shape[1] < 6 else np.zeros((6, 6)))
    B = U[:, sv < 0.5]
    stat, dof = wald(B.T @ (d1 - d2), B.T @ D @ (V1 + V2) @ D @ B)
    f = sps[0].f
    split = 0.5 * (f[halves[0][0][-1]] + f[halves[0][1][0]])
    edges = (float(series[0].band_hz[0]), float(split), float(series[0].band_hz[1]))
    diff = np.abs(d1 - d2)
    big = int(np.argmax(diff / np.maximum(np.abs(theta[[0, 0, 0, 3, 3, 5]]), 1e-9)))
    detail = (f"the band split at {split:.2f} Hz (half the information below): {KEYS[big]} "
              f"{theta[big] + d1[big]:.4g} below vs {theta[big] + d2[big]:.4g} kg·m² above")
    return chi2_check("sub_bands", stat, dof, detail), np.array([theta + d1, theta + d2]), edges


def _normal(sps: list[Spectra], bins: list | None, extras: list | None, moments: list | None):
    """The Whittle-weighted normal equations pooled over ``sps`` (see :func:`wls_step_joint`):
    info (p,p), g (p,), the noise moments per realisation Nk (K,p,p), nk (K,p), and Cq (p,p)
    the covariance of the gradient's noise × noise term (the sample covariance over the
    realisations, bin by bin, summed: the bins are independent) — 0.0 when the spectra carry
    no realisations."""
    info, g, Nk, nk, Cq = 0.0, 0.0, 0.0, 0.0, 0.0
    for i, sp in enumerate(sps):
        A = sp.A if extras is None else np.concatenate([sp.A, extras[i]], axis=2)
        r, S = sp.r, sp.S
        dA, dr = sp.dA, sp.dr
        if dA is not None and extras is not None:
            dA = np.concatenate([dA, np.zeros(dA.shape[:3] + (extras[i].shape[2],), complex)], axis=3)
        if bins is not None:
            A, r, S = A[bins[i]], r[bins[i]], S[bins[i]]
            if dA is not None:
                dA, dr = dA[:, bins[i]], dr[:, bins[i]]
        W = 1.0 / S
        info = info + np.einsum("bip,bi,biq->pq", A.conj(), W, A).real
        g = g + np.einsum("bip,bi,bi->p", A.conj(), W, r).real
        if dA is not None:
            t = np.einsum("kbip,bi,kbi->kbp", dA.conj(), W, dr).real       # per realisation and bin
            if len(t) >= 2:
                dev = t - t.mean(0)
                Cq = Cq + np.einsum("kbp,kbq->pq", dev, dev) / (len(t) - 1)
        if moments is not None and moments[i] is not None:
            Nk, nk = Nk + moments[i][0], nk + moments[i][1]
        elif dA is not None:     # per realisation (K,p,p), (K,p)
            Nk = Nk + np.einsum("kbip,bi,kbiq->kpq", dA.conj(), W, dA).real
            nk = nk + t.sum(1)
    return info, g, Nk, nk, Cq


def wls_step_joint(sps: list[Spectra], bins: list | None = None, extras: list | None = None,
                   moments: list | None = None):
    """:func:`wls_step` pooled over several segments' spectra (one tensor).

    When the spectra carry the noise realisations of the fit (``dA``, ``dr``: a fit
    compensated for the noise in its input, :mod:`rig_identification.estimation.errors_in_variables`), the step is
    compensated the same way: the realisations' mean second moments are removed from the
    information and the gradient (the extra regressors are taken as noise-free), each
    direction's share capped at :data:`~rig_identification.estimation.errors_in_variables.SHARE_CAP`; the covariance is
    then the sandwich I_c⁻¹ (½ I + C_q) I_c⁻¹ (C_q: the fluctuation of the noise × noise term
    of the gradient about its removed mean, :func:`_normal`) plus the jackknife covariance of the step over the
    realisations (their finite number makes the compensation uncertain).  moments: per
    spectra, the noise moments (N (K,p,p), n (K,p)) to use instead of its own realisations'
    (:func:`piece_noise`), or None for them."""
    info, g, Nk, nk, Cq = _normal(sps, bins, extras, moments)
    if np.ndim(Nk):
        try:
            def solve(keep):
                Ic = np.linalg.pinv(info - capped(info, Nk[keep].mean(0)), rcond=1e-12, hermitian=True)
                return Ic @ (g - nk[keep].mean(0)), Ic

            K = len(Nk)
            step, Ic = solve(np.arange(K))
            # the noise's own product in the gradient (input noise × output noise) fluctuates
            # about the mean that is removed: its variance, per bin from the realisations
            cov = Ic @ (0.5 * info + Cq) @ Ic
            if K >= 2:
                # the realisations' finite number: the jackknife of the compensated step
                loo = np.array([solve(np.delete(np.arange(K), k))[0] for k in range(K)])
                dev = loo - loo.mean(0)
                cov = cov + (K - 1) / K * dev.T @ dev
            return step, cov
        except np.linalg.LinAlgError:
            pass
    cov = 0.5 * np.linalg.pinv(info, rcond=1e-12, hermitian=True)
    return 2.0 * cov @ g, cov


def _projector(B: np.ndarray) -> np.ndarray:
    """Orthogonal projector onto the columns of B (6, q)."""
    Q, _ = np.linalg.qr(B)
    return Q @ Q.T


def determined(sps: list[Spectra], bins: list | None = None, moments: list | None = None) -> np.ndarray:
    """(6, q) B: the combinations ``Bᵀ θ`` of the tensor entries that a piece of the record
    determines despite the noise in the input — the coordinates along the generalized
    eigenvectors (of the noise moments and the information,
    :func:`~rig_identification.estimation.errors_in_variables.noise_share`) whose noise share is within
    :data:`~rig_identification.estimation.errors_in_variables.EIV_LIMIT`, blind to the others.  Along the others the compensated step is the
    noise's (a quarter of a damped record whose roll has died away: share 1.0, Ixx moved
    600 kg·m² at "σ" 360), and the consistency checks leave them out.  The identity when the
    spectra carry no realisations."""
    info, _, Nk, _, _ = _normal(sps, bins, None, moments)
    if not np.ndim(Nk):
        return np.eye(6)
    try:
        L = np.linalg.cholesky(0.5 * (info + info.T))
    except np.linalg.LinAlgError:
        return np.eye(6)
    N = Nk.mean(0)
    S = np.linalg.solve(L, np.linalg.solve(L, 0.5 * (N + N.T)).T)
    ev, V = np.linalg.eigh(0.5 * (S + S.T))
    return L @ V[:, ev <= EIV_LIMIT]


def quadrature_check(series: list[FitSeries]) -> Check:
    """Correlation of the residual with the input (see module docstring): the residual of
    each gyro axis regressed on the quadrature of the three predicted outputs, jointly with
    the tensor; Wald χ² of the 9 coefficients."""
    sps = [spectra(s) for s in series]
    extras = []
    for sp in sps:
        Q = -1j * sp.y                                   # Hilbert transform, positive frequencies
        X = np.zeros(sp.r.shape + (9,), complex)
        for a in range(3):
            X[:, a, 3 * a:3 * a + 3] = Q
        extras.append(X)
    step, cov = wls_step_joint(sps, extras=extras)
    beta, V = step[6:], cov[6:, 6:]
    stat, dof = wald(beta, V)
    B = beta.reshape(3, 3)
    a = int(np.argmax(np.abs(np.diag(B))))
    detail = (f"residual regressed on the quadrature (a quarter period late) of the predicted ω: "
              f"largest direct coefficient {B[a, a]:+.3g} on gyro {'xyz'[a]}")
    return chi2_check("input_correlation", stat, dof, detail)


def whiteness_check(series: list[FitSeries]) -> Check:
    """Fisher's g-test for a spectral line in the residual (see module docstring): the
    largest ratio of a periodogram ordinate to the noise's level there (:class:`Spectra`'s S:
    the noise realisations' spectrum, the ratio then F(2, 2ν) distributed; without them the
    residual's running median, the ratio exponential), Bonferroni over the bins and axes.
    Statistic and threshold in units of that ratio."""
    worst, where, n, nu = 0.0, "", 0, None
    for s in series:
        sp = spectra(s)
        lo, hi = s.band_hz
        inner = (sp.f >= EDGE_MARGIN * lo) & (sp.f <= hi / EDGE_MARGIN)   # the filter's skirts excluded
        ratio = (np.abs(sp.r) ** 2 / sp.S)[inner]                       # P / the noise's level
        n += ratio.size
        if sp.dof is not None:
            nu = sp.dof // 2 if nu is None else min(nu, sp.dof // 2)
        i, a = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
        if ratio[i, a] > worst:
            worst, where = float(ratio[i, a]), f"gyro {'xyz'[a]} at {sp.f[inner][i]:.3f} Hz"
    if nu is None:
        # the level a running median: P / level is exponential, P(ratio > x) = e^−x
        thr, p = float(np.log(n / ALPHA)), min(1.0, n * float(np.exp(-worst)))
        what = "its local median level"
    else:
        # the level the noise realisations' mean over 2ν degrees of freedom: P / level is
        # F(2, 2ν), P(ratio > x) = (1 + x/ν)^−ν
        thr = float(nu * ((n / ALPHA) ** (1.0 / nu) - 1.0))
        p = min(1.0, n * float((1.0 + worst / nu) ** -nu))
        what = "the noise's level there (the replays' residual spectrum)"
    return Check("whiteness", worst, WHITENESS_FACTOR * thr, bool(worst <= WHITENESS_FACTOR * thr),
                 f"largest residual line {worst:.1f}× {what} ({where}); p = {fmt_p(p)}"
                 + (" (significant, but too small to matter)" if thr < worst <= WHITENESS_FACTOR * thr else ""))


@dataclass(frozen=True)
class AccelInput:
    """What the accelerometer check needs of one prepared recording: t (N,) s; gyro (N,3)
    rad/s and torque (N,3) N·m and force (N,3) N (generalized, weight excluded), body axes;
    accel (N,3) m/s² the measured specific force, body axes; mass kg; rho (3,) m from the CG to
    the IMU, body axes; band_hz; noise m/s² the accelerometer's white σ; replays: (torque,
    force) pairs of the same window replayed with a fresh realisation of the sensors' noise
    added and subtracted (:func:`~rig_identification.pipeline.offline.refine_uncertainty`'s antithetic pair): half their
    difference is a draw of the prediction's own noise (the tracker's pose error seen through
    the tensions' lever arms), which the check adds to the accelerometer's."""

    t: np.ndarray
    gyro: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    accel: np.ndarray
    mass: float
    rho: np.ndarray
    band_hz: tuple
    noise: float
    replays: tuple = ()


def accelerometer_check(inputs: list[AccelInput], J: np.ndarray) -> Check | None:
    """The specific force at the IMU predicted by the identified model against the
    accelerometer (see module docstring); None without inputs or noise level."""
    worst, axis = 0.0, 0
    for a in inputs:
        if a.noise <= 0 or len(a.t) < 100:
            return None
        fs = 1.0 / float(np.median(np.diff(a.t)))
        w = a.gyro

        def predicted(torque, force):
            alpha = np.linalg.solve(J, (torque - np.cross(w, w @ J.T)).T).T
            return force / a.mass + np.cross(alpha, a.rho) + np.cross(w, np.cross(w, a.rho))
        lo, hi = a.band_hz
        sos = butter(4, [lo, min(hi, 0.45 * fs)], btype="bandpass", fs=fs, output="sos")
        cut = int(min(len(a.t) // 10, 2 * fs / lo))          # the filter's edge transients

        def band_rms(x):
            y = sosfiltfilt(sos, x, axis=0)[cut:len(x) - cut]
            return np.sqrt(np.mean(y**2, axis=0))
        res_rms = band_rms(a.accel - predicted(a.torque, a.force))
        imp = np.zeros(4096)
        imp[2048] = 1.0
        gain = float(np.sqrt(np.sum(sosfiltfilt(sos, imp) ** 2)))   # noise gain of the filter
        pred_noise = np.zeros(3)
        if len(a.replays) == 2:
            (tq1, f1), (tq2, f2) = a.replays
            pred_noise = band_rms(0.5 * (predicted(tq1, f1) - predicted(tq2, f2)))
        ratio = res_rms / np.sqrt((a.noise * gain) ** 2 + pred_noise**2)
        if ratio.max() > worst:
            worst, axis = float(ratio.max()), int(np.argmax(ratio))
    return Check("accelerometer", worst, ACCEL_RATIO, bool(worst <= ACCEL_RATIO),
                 f"the specific force predicted from the load cells, exciter and identified tensor vs the "
                 f"accelerometer (a channel the fit does not use): residual {worst:.2f}× what the noise explains "
                 f"(the accelerometer's and the prediction's own, in band; body {'xyz'[axis]})")


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
    big = float(diag[ok_diag].max()) if ok_diag.any() and diag[ok_diag].max() > 0 else float(max(diag.max(), 1.0))
    scale = np.array([abs(theta[0]), big, big, abs(theta[3]), big, abs(theta[5])])
    rel = std / np.maximum(scale, 1e-9 * big)
    # and a product of two axes is no better determined than the moments about them
    axes = {"ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}
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


def advice(bad: tuple[str, ...], rig=None) -> tuple[str, ...]:
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
                       "restores roll and pitch — splay the ceiling anchors outward (0.3–0.8 m)")
        if len(rig.cables) == 3:
            out.append("with three cables one swing of the body is not held by the cable lengths; a fourth cable "
                       "helps")
    axes = {"ixx": "x", "iyy": "y", "izz": "z"}
    turn = [axes[k] for k in bad if k in axes]
    if turn:
        out.append(f"the body hardly turned about {', '.join(turn)}: move the exciter farther from that axis or "
                   "turn its spin axis, raise the force or move its frequency nearer a mode that turns the body "
                   "about it — `rig-identify plan RIG --inertia …` finds the run")
    elif bad:
        out.append("the products need the body turned about two axes at once: mount the exciter off the body's "
                   "planes of symmetry or with a diagonal spin axis — `rig-identify plan` finds the run")
    return tuple(out)


def validate(result: InertiaResult, accel: list[AccelInput] | None = None, weight_surplus: float | None = None,
             rig=None) -> Validation:
    """The verdict on an inertia fit (see module docstring).

    result: the fit (:func:`~rig_identification.estimation.identification.identify_inertia`, with ``series`` carrying
    the Jacobian; ``residual_excess`` and ``bias_correction`` from
    :func:`~rig_identification.pipeline.offline.refine_uncertainty` are used when set).  accel: the accelerometer
    check's inputs, one per fitted recording.  weight_surplus: see
    :func:`~rig_identification.pipeline.offline.weight_surplus`.  rig: for the advice on geometry.  Never raises on
    bad numbers: a fit that produced them is ``not_identifiable``.
    """
    checks: list[Check] = []
    theta = from_tensor(result.inertia)
    std = np.asarray(result.inertia_std, float)
    finite = bool(np.all(np.isfinite(theta)) and np.all(np.isfinite(std)))
    segs = times = bands = edges = None
    series = [s for s in result.series if s.jacobian is not None]
    excess = residual_excess(series) if series else None
    if excess is None and result.residual_excess is not None:
        excess = np.asarray(result.residual_excess, float)
    if excess is not None:
        r = excess
        checks.append(Check("residual_level", float(np.max(r)), RESIDUAL_RATIO, bool(np.max(r) <= RESIDUAL_RATIO),
                            f"the fit's residual is {np.max(r):.2f}× what the sensors' noise explains "
                            f"(gyro {'xyz'[int(np.argmax(r))]})"))
    if series and finite:
        with np.errstate(all="ignore"):
            try:
                scale = noise_scale(series, result.crb_std)
                c, segs, times = segment_check(series, theta, scale)
                checks.append(c)
                c, bands, edges = band_check(series, theta, scale)
                if c is not None:
                    checks.append(c)
                checks.append(quadrature_check(series))
                checks.append(whiteness_check(series))
            except (np.linalg.LinAlgError, ValueError) as e:
                checks.append(Check("segments", None, None, False, f"the validation could not run ({e})"))
    if accel and finite:
        c = accelerometer_check(accel, result.inertia)
        if c is not None:
            checks.append(c)
    if weight_surplus is not None:
        checks.append(Check("weight", abs(weight_surplus), WEIGHT_TOLERANCE, bool(abs(weight_surplus) <= WEIGHT_TOLERANCE),
                            f"the load cells carry {100 * weight_surplus:+.3f} % of rig.yaml's weight beyond it"))
    factor = max([1.0] + [c.sigma_factor for c in checks])
    biased: tuple[str, ...] = ()
    eiv = result.errors_in_variables
    if eiv is not None and finite:
        if not (eiv.share <= EIV_LIMIT and eiv.applied):
            biased = tuple(k for k, x in zip(KEYS, eiv.direction) if abs(x) >= WEAK_SHARE) or tuple(KEYS)
        main = KEYS[int(np.argmax(np.abs(eiv.direction)))]
        moved = np.abs(eiv.correction) / np.maximum(std, 1e-300)
        k = int(np.argmax(moved))
        checks.append(Check("errors_in_variables", float(eiv.share), EIV_LIMIT, not biased,
                            f"the sensors' noise is {100 * min(eiv.share, 9.99):.3g} % of the fit's input along its "
                            f"noisiest direction (mostly {main}); the compensation for it moved {KEYS[k]} by "
                            f"{moved[k]:.2f} σ"
                            + ((f" (beyond {100 * EIV_LIMIT:g} %: " if not eiv.share <= EIV_LIMIT else
                                " (the fit could not be compensated for it: ")
                               + "the entries along that direction are not determined; the body hardly turns about "
                               "it)" if biased else "")))
    # whether the recording determines an entry is the noise's question (the propagated σ, checked
    # against the replays): a model error's residuals widen the sandwich σ of an entry the
    # excitation determines well (unmodelled damping: Ixx's σ 4 % from the noise, 20 % widened).
    # Nor does the consistency checks' Birge factor enter it: it measures a misfit between
    # segments or sub-bands (the model's question, σ is widened by it in widened_std), not
    # how much the geometry and the excitation tell about an entry — with it, a damped 4-cable
    # rig (test_validation's, Ixx's noise σ 4.7 %) turned not_identifiable as soon as its
    # sub-band misfit fell from "failed" to "widened 2.48×"
    noise_std = std if result.crb_std is None else np.asarray(result.crb_std, float) * (result.replay_factor or 1.0)
    ident, bad = identifiability(result, noise_std)
    # a product is not determined when a moment about one of its axes is not, whichever check
    # found the moment undetermined (the noise in the input along it too: bench_any_rig's seed
    # 21000 gave Ixy 22 % off under a biased Ixx)
    out = set(bad) | set(biased)
    products = {"ixy": ("ixx", "iyy"), "ixz": ("ixx", "izz"), "iyz": ("iyy", "izz")}
    out |= {p for p, (a, b) in products.items() if a in out or b in out}
    bad = tuple(k for k in KEYS if k in out)
    checks.append(ident)
    parts = [np.zeros(6)]
    if segs is not None:
        parts.append(np.max(np.abs(segs - theta), axis=0))
    if bands is not None:
        parts.append(np.abs(bands[0] - bands[1]))
    spread = np.max(parts, axis=0)
    failed = tuple(c.name for c in checks if c.passed is False and c.name not in ("identifiable", "errors_in_variables"))
    if bad:
        verdict = "not_identifiable"
    elif failed:
        verdict = "model_error"
    else:
        verdict = "ok"
    return Validation(verdict, tuple(checks), bad, advice(bad, rig) if bad else (), segs, times, bands, edges,
                      spread, failed, factor)


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
    return np.sqrt(s**2 + validation.spread_std**2)
