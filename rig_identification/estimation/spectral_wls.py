"""Frequency-domain weighted least squares on an inertia fit's linearisation: the machinery of
the model-validation checks (:mod:`~rig_identification.estimation.validation`).

The fit's residual, Jacobian and prediction over the interior of each fitted series, as DFTs
over the band (:class:`Spectra`, :func:`spectra`); a Whittle-weighted least-squares step on
them (:func:`wls_step`, pooled over series :func:`wls_step_joint`), compensated for the noise
in the input when the fit carries its realisations (errors in variables,
:mod:`~rig_identification.estimation.errors_in_variables`); its Wald statistic
(:func:`wald`); what a piece of the record determines (:func:`determined`) and the noise it
holds (:func:`piece_noise`, :func:`missed_noise`); the residual's excess over the noise
(:func:`residual_excess`).  The DFT coefficients of a stationary residual are asymptotically
independent complex normal with variance the spectrum (Whittle likelihood; Brillinger, *Time
Series*, 1981, §4.4), so the step's covariance is ½ (Σ Re Aᴴ S⁻¹ A)⁻¹ for the one-sided DFT.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.ndimage import median_filter, uniform_filter1d

from .errors_in_variables import EIV_LIMIT, capped
from .inertia_result import FitSeries

EDGE_PERIODS = 1.5          # periods of the band's low edge left out at each end of a series by the checks
SMOOTH_HZ = 0.25            # width of the running median that estimates the residual's spectrum (no realisations)
NOISE_BINS = 5              # neighbouring bins over which the noise realisations' periodograms are averaged


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
    dy: np.ndarray | None = None     # (K,B,3) and of y (FitSeries.noise_predicted)
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
    dA = dr = dy = None
    dof = None
    if series.noise_jacobian is not None and series.noise_residual is not None:
        dA = np.fft.rfft(series.noise_jacobian[:, rows], axis=1)[:, m]
        dr = np.fft.rfft(series.noise_residual[:, rows], axis=1)[:, m]
        if series.noise_predicted is not None:
            dy = np.fft.rfft(series.noise_predicted[:, rows], axis=1)[:, m]
        # the noise's own spectrum: the realisations' periodograms, averaged over them and
        # NOISE_BINS neighbouring bins (2·K·NOISE_BINS degrees of freedom per bin)
        S = uniform_filter1d(np.mean(np.abs(dr) ** 2, axis=0), NOISE_BINS, axis=0, mode="nearest")
        dof = 2 * len(dr) * NOISE_BINS
    else:
        width = max(5, int(round(SMOOTH_HZ * n / fs)) | 1)
        S = median_filter(P, size=(width, 1), mode="nearest") / np.log(2)
    S = np.maximum(S, 1e-12 * max(float(S.max()), 1e-300))
    return Spectra(f[m], R, np.fft.rfft(A, axis=0)[m], np.fft.rfft(y, axis=0)[m], S, dA, dr, dy, dof)


def fitted_noise_level(sp: Spectra, covariance: np.ndarray) -> np.ndarray:
    """(B,3) the noise's spectral level in the residual *at the fitted tensor*: ``sp.S`` (the
    realisations' residual, at a fixed tensor) plus the estimate's own error seen through the
    fit's Jacobian, diag(A C Aᴴ) per bin (covariance C (6,6) kg⁴·m⁴ of the fitted entries from the
    sensors' noise, :attr:`~rig_identification.estimation.inertia_result.FitSeries.noise_covariance`).
    The residual of a fit is the residual at the truth less A·(θ̂ − θ): where the motion fills one
    frequency (a rig driven near one speed) that error is a line there, which realisations at a
    fixed tensor do not have — bench_any_rig's 27020: the residual's largest line 1.7× the
    noise's level at the truth, 105× at the fitted tensor (0.959 Hz, gyro z), significant on 5 of
    12 noise seeds of the rig.  The two are added as if independent: for least squares on output
    noise they are anti-correlated (the fit removes noise along A), so the level is then an
    upper bound, and a line within the estimate's own error is not taken for a model error."""
    C = 0.5 * (np.asarray(covariance, float) + np.asarray(covariance, float).T)
    level: np.ndarray = sp.S + np.einsum("bip,pq,biq->bi", sp.A, C, np.conj(sp.A)).real
    return level


def wls_step(sp: Spectra, bins: np.ndarray | None = None, extra: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
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


def missed_noise(series: list[FitSeries], cov: np.ndarray | None) -> np.ndarray:
    """(6,6) kg²·m⁴ E = (C − V)₊: the covariance the noise gives the whole fit (``cov``, C:
    propagated through tracker, preprocessor and identifier) beyond the frequency-domain one
    V (:func:`wls_step_joint`, which sees the output's residual only), its positive part.
    Zeros when ``cov`` is None or not finite.  A piece of the record holding a fraction f of
    its information has V_k + E / f (the missed noise is the record's own, like the rest).

    The noise the residual's spectrum misses (the gyro's, through the tracked pose into the
    cables' moment) lies along tensor directions of its own, not along the entries: the
    per-entry factor √(C_ii / V_ii) used before left a clean 4-cable rig's time segments
    short along Ixy and wide along the rest (bench_any_rig's seed 21008: its own noise failed
    ``segments`` at χ²/dof 4.76; ``bench/bench_validation_null.py --any-rig 21008`` measures
    the check's null over noise seeds)."""
    if cov is None or not np.all(np.isfinite(cov)):
        return np.zeros((6, 6))
    _, V = wls_step_joint([spectra(s) for s in series])
    ev, U = np.linalg.eigh(0.5 * (cov + cov.T) - 0.5 * (V + V.T))
    E: np.ndarray = (U * np.clip(ev, 0.0, None)) @ U.T
    return E


def normal_equations(sps: list[Spectra], bins: list[np.ndarray] | None, extras: list[np.ndarray] | None,
                     moments: list[tuple[np.ndarray, np.ndarray] | None] | None,
                     extras_noise: list[np.ndarray | None] | None = None) -> tuple[Any, Any, Any, Any, Any]:
    """The Whittle-weighted normal equations pooled over ``sps`` (see :func:`wls_step_joint`;
    extras_noise: per spectra the noise realisations (K,B,3,q) of its extra regressors, or None
    for noise-free ones):
    info (p,p), g (p,), the noise moments per realisation Nk (K,p,p), nk (K,p), and Cq (p,p)
    the covariance of the gradient's noise × noise term (the sample covariance over the
    realisations, bin by bin, summed: the bins are independent) — 0.0 when the spectra carry
    no realisations."""
    Nk: np.ndarray | float
    nk: np.ndarray | float
    info, g, Nk, nk, Cq = 0.0, 0.0, 0.0, 0.0, 0.0
    for i, sp in enumerate(sps):
        A = sp.A if extras is None else np.concatenate([sp.A, extras[i]], axis=2)
        r, S = sp.r, sp.S
        dA, dr = sp.dA, sp.dr
        if dA is not None and extras is not None:
            dX = np.zeros(dA.shape[:3] + (extras[i].shape[2],), complex) \
                if extras_noise is None or extras_noise[i] is None else extras_noise[i]
            dA = np.concatenate([dA, dX], axis=3)
        if bins is not None:
            A, r, S = A[bins[i]], r[bins[i]], S[bins[i]]
            if dA is not None:
                dA, dr = dA[:, bins[i]], dr[:, bins[i]]  # type: ignore[index]  # dr is set with dA (spectra)
        W = 1.0 / S
        info = info + np.einsum("bip,bi,biq->pq", A.conj(), W, A).real
        g = g + np.einsum("bip,bi,bi->p", A.conj(), W, r).real
        if dA is not None:
            t = np.einsum("kbip,bi,kbi->kbp", dA.conj(), W, dr).real  # type: ignore[arg-type]  # per realisation and bin
            if len(t) >= 2:
                dev = t - t.mean(0)
                Cq = Cq + np.einsum("kbp,kbq->pq", dev, dev) / (len(t) - 1)
        if moments is not None and moments[i] is not None:
            Nk, nk = Nk + moments[i][0], nk + moments[i][1]  # type: ignore[index]  # mypy: moments[i] not narrowed
        elif dA is not None:     # per realisation (K,p,p), (K,p)
            Nk = Nk + np.einsum("kbip,bi,kbiq->kpq", dA.conj(), W, dA).real
            nk = nk + t.sum(1)
    return info, g, Nk, nk, Cq


def wls_step_joint(sps: list[Spectra], bins: list[np.ndarray] | None = None, extras: list[np.ndarray] | None = None,
                   moments: list[tuple[np.ndarray, np.ndarray] | None] | None = None,
                   extras_noise: list[np.ndarray | None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`wls_step` pooled over several segments' spectra (one tensor).

    When the spectra carry the noise realisations of the fit (``dA``, ``dr``: a fit
    compensated for the noise in its input, :mod:`rig_identification.estimation.errors_in_variables`), the step is
    compensated the same way: the realisations' mean second moments are removed from the
    information and the gradient (the extra regressors noise-free unless ``extras_noise``
    gives their realisations, per spectra (K,B,3,q)), each
    direction's share capped at :data:`~rig_identification.estimation.errors_in_variables.SHARE_CAP`; the covariance is
    then the sandwich I_c⁻¹ (½ I + C_q) I_c⁻¹ (C_q: the fluctuation of the noise × noise term
    of the gradient about its removed mean, :func:`normal_equations`) plus the jackknife covariance of the step over the
    realisations (their finite number makes the compensation uncertain).  moments: per
    spectra, the noise moments (N (K,p,p), n (K,p)) to use instead of its own realisations'
    (:func:`piece_noise`), or None for them."""
    info, g, Nk, nk, Cq = normal_equations(sps, bins, extras, moments, extras_noise)
    if np.ndim(Nk):
        try:
            def solve(keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def projector(B: np.ndarray) -> np.ndarray:
    """Orthogonal projector onto the columns of B (6, q)."""
    Q, _ = np.linalg.qr(B)
    P: np.ndarray = Q @ Q.T
    return P


def determined(sps: list[Spectra], bins: list[np.ndarray] | None = None,
               moments: list[tuple[np.ndarray, np.ndarray] | None] | None = None) -> np.ndarray:
    """(6, q) B: the combinations ``Bᵀ θ`` of the tensor entries that a piece of the record
    determines despite the noise in the input — the coordinates along the generalized
    eigenvectors (of the noise moments and the information,
    :func:`~rig_identification.estimation.errors_in_variables.noise_share`) whose noise share is within
    :data:`~rig_identification.estimation.errors_in_variables.EIV_LIMIT`, blind to the others.
    Along the others the compensated step is the
    noise's (a quarter of a damped record whose roll has died away: share 1.0, Ixx moved
    600 kg·m² at "σ" 360), and the consistency checks leave them out.  The identity when the
    spectra carry no realisations."""
    info, _, Nk, _, _ = normal_equations(sps, bins, None, moments)
    if not np.ndim(Nk):
        return np.eye(6)
    try:
        L = np.linalg.cholesky(0.5 * (info + info.T))
    except np.linalg.LinAlgError:
        return np.eye(6)
    N = Nk.mean(0)
    S = np.linalg.solve(L, np.linalg.solve(L, 0.5 * (N + N.T)).T)
    ev, V = np.linalg.eigh(0.5 * (S + S.T))
    B: np.ndarray = L @ V[:, ev <= EIV_LIMIT]
    return B
