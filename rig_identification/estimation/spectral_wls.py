"""Frequency-domain weighted least squares on an inertia fit's linearisation: the machinery of
the model-validation checks (:mod:`~rig_identification.estimation.validation`).

The fit's residual, Jacobian and prediction over the interior of each fitted series, as DFTs
over the band (:class:`Spectra`, :func:`spectra`); a Whittle-weighted least-squares step on
them (:func:`wls_step`, pooled over series :func:`wls_step_joint`); its Wald statistic
(:func:`wald`); the noise the residual's spectrum misses (:func:`missed_noise`).  The DFT
coefficients of a stationary residual are asymptotically independent complex normal with
variance the spectrum (Whittle likelihood; Brillinger, *Time Series*, 1981, §4.4), so the
step's covariance is ½ (Σ Re Aᴴ S⁻¹ A)⁻¹ for the one-sided DFT.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

from .inertia_result import FitSeries

EDGE_PERIODS = 1.5          # periods of the band's low edge left out at each end of a series by the checks
SMOOTH_HZ = 0.25            # width of the running median that estimates the residual's spectrum


@dataclass(frozen=True)
class Spectra:
    """DFT of one fitted segment's residual, Jacobian and prediction over the bins of its band.

    f (B,) Hz; r (B,3) residual; A (B,3,6) Jacobian; y (B,3) predicted output; S (B,3) the
    noise's spectral level in the residual: the running median of the residual's periodogram
    over :data:`SMOOTH_HZ`, / ln 2 (the median of an exponential variate)."""

    f: np.ndarray
    r: np.ndarray
    A: np.ndarray
    y: np.ndarray
    S: np.ndarray


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
    width = max(5, int(round(SMOOTH_HZ * n / fs)) | 1)
    S = median_filter(P, size=(width, 1), mode="nearest") / np.log(2)
    S = np.maximum(S, 1e-12 * max(float(S.max()), 1e-300))
    return Spectra(f[m], R, np.fft.rfft(A, axis=0)[m], np.fft.rfft(y, axis=0)[m], S)


def wls_step(sp: Spectra, bins: np.ndarray | None = None, extra: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares step over the DFT bins (Whittle weights 1/S) (:func:`wls_step_joint`).

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


def wls_step_joint(sps: list[Spectra], bins: list[np.ndarray] | None = None, extras: list[np.ndarray] | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`wls_step` pooled over several segments' spectra (one tensor): the Whittle-weighted
    normal equations summed over ``sps`` (each restricted to its ``bins`` where given, its
    regressors extended by ``extras`` (B,3,q) where given), the step 2 C g and its covariance
    C = ½ (Σ Re Aᴴ S⁻¹ A)⁺ (the one-sided DFT's; module docstring)."""
    info: np.ndarray | float = 0.0
    g: np.ndarray | float = 0.0
    for i, sp in enumerate(sps):
        A = sp.A if extras is None else np.concatenate([sp.A, extras[i]], axis=2)
        r, S = sp.r, sp.S
        if bins is not None:
            A, r, S = A[bins[i]], r[bins[i]], S[bins[i]]
        W = 1.0 / S
        info = info + np.einsum("bip,bi,biq->pq", A.conj(), W, A).real
        g = g + np.einsum("bip,bi,bi->p", A.conj(), W, r).real
    cov = 0.5 * np.linalg.pinv(np.asarray(info), rcond=1e-12, hermitian=True)
    return 2.0 * cov @ np.asarray(g), cov
