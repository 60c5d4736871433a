"""A structural mode between the rigid body and a sensor, located above the fit band (the
effect ``structural_mode`` of :mod:`~rig_identification.model.effects`; the method as a
whole: :mod:`~rig_identification.diagnosis.selection`).

A sensor on a part of the carrying frame that flexes reads the body's motion through the
mount's mode: u_meas = u + p G(s) (u − u₀), G(s) = −s² / (s² + 2ζω s + ω²), ω = 2π f_n
(the base-excited oscillator of the effect library).  Inside the fit band (f ≪ f_n) that is a
gain rising as p (f/f_n)²: on the gyro, a frequency-dependent scale the tensor mostly
absorbs, and on a swinging body the accelerometer and the gyro agree with each other (the
specific force stays along the cables), so the band alone barely tells it.  Above the band,
where the rig's vertical and higher modes move the body and the load cells see the true
force, it shows: the accelerometer's departure from Newton's prediction from the load cells,
per unit of the measured force (:func:`transfer`: the H1 frequency-response estimate,
Welch, summed over the three axes), is p G (a mode of the IMU's mount) or 1/(1 + p G) − 1 (a
mode under the load cells' anchors).  :func:`fit_mode` fits (f_n, ζ, p) to that departure at every
frequency above the band where the two are coherent; its χ² gain over "no mode" is the
out-of-band evidence.  When those frequencies lie well below f_n, only p / f_n² is
determined — the in-band correction needs no more — and f_n is given for the physical
oscillator (p = 1, the library's default), said so.

:func:`mode_filter` removes a fitted mode from a stream (the inverse 1/(1 + p G), applied in
the frequency domain below f_n / 2 and faded out above it, so that the sensors' white noise
above the mode is not amplified): :func:`~rig_identification.diagnosis.candidates.corrected`
uses it.

References: Bendat & Piersol, *Random Data* (4th ed., 2010), §9.1–9.2 (H1 estimate, its
variance from the coherence); Ewins, *Modal Testing* (2nd ed., 2000), §4.3 (SDOF
base-excitation).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import csd, welch

from .model_extension import Model
from .window import Window

F_MIN = 3.0               # Hz: lowest mode frequency searched (and at least MIN_BAND_MULTIPLE × the band's top)
F_MAX = 45.0              # Hz: highest (and at most 0.4 × the IMU rate)
MIN_BAND_MULTIPLE = 2.0   # a mode must lie this many times above the fit band's upper edge
COHERENCE = 0.9           # frequencies used: accelerometer and prediction this coherent
SEGMENT_S = 10.0          # s: Welch segment length of the transfer estimate
LOCATED_REL_STD = 0.15    # the mode's frequency is located when its σ is below this fraction of it
ZETAS = (0.005, 0.01, 0.02, 0.03, 0.05, 0.1, 0.2, 0.3)
SENSORS = ("imu", "load_cells")
FADE_ORDER = 16           # order of the zero-phase fade of the inverse above f_n / 2


@dataclass(frozen=True)
class Transfer:
    """The accelerometer against Newton's prediction from the load cells, per frequency:
    f (K,) Hz, H (K,) complex (H1 estimate, summed over the body axes), var (K,) its
    variance, coherence (K,); band (2,) Hz the fit band."""

    f: np.ndarray
    H: np.ndarray
    var: np.ndarray
    coherence: np.ndarray
    band: tuple


@dataclass(frozen=True)
class ModeFit:
    """A structural mode fitted to a :class:`Transfer` above the band.  sensor: ``imu`` or
    ``load_cells``; frequency Hz, damping_ratio, participation (dimensionless) and their σ;
    located: the frequency is determined (σ within :data:`LOCATED_REL_STD`), else the
    frequency is the physical oscillator's (p = 1) for the fitted p / f_n²;
    likelihood_ratio: χ² of the departure from 1 minus that left with the mode (dof 3);
    points: frequencies used; hz (lo, hi): the span of them."""

    sensor: str
    frequency: float
    damping_ratio: float
    participation: float
    std: dict
    located: bool
    likelihood_ratio: float
    dof: int
    points: int
    hz: tuple


def transfer(w: Window, model: Model, segment_s: float = SEGMENT_S) -> Transfer:
    """H1 estimate of the accelerometer's departure from Newton's prediction at the IMU
    (``r = f − (F/m + α × ρ + ω × (ω × ρ))``, body axes, the diagnosis model's translational
    residual, not band-passed) over the load cells' and the exciter's force per mass ``F/m``:
    Welch segments of ``segment_s``, cross- and auto-spectra summed over the three axes.  A
    mode of the IMU's mount makes both the accelerometer and — through the gyro's α — the
    prediction's kinematic terms read 1 + p G of the truth, so r = p G F/m: H = p G; a mode
    under the load cells makes F/m read 1 + p G of the truth, so 1 + H = 1/(1 + p G).
    var = (1 − γ²) S_rr / (2 n_d S_FF) (Bendat & Piersol eq. 9.90, |H|²/γ² = S_rr/S_FF), n_d
    the number of (50 % overlapping) segments; ``coherence``: of F/m and the accelerometer
    (where the force moves the body measurably)."""
    fs = model.fs
    Fm = w.force / w.mass
    r = w.f - (Fm + np.cross(model.alpha, w.rho) + np.cross(w.omega, np.cross(w.omega, w.rho)))
    nper = int(min(len(w.t), 2 ** np.ceil(np.log2(segment_s * fs))))
    F = Fm - Fm.mean(0)
    R = r - r.mean(0)
    A = w.f - w.f.mean(0)
    f, Sfr = csd(F, R, fs=fs, nperseg=nper, axis=0)
    Sfr = Sfr.sum(1)
    Sfa = csd(F, A, fs=fs, nperseg=nper, axis=0)[1].sum(1)
    Sff = welch(F, fs=fs, nperseg=nper, axis=0)[1].sum(1)
    Srr = welch(R, fs=fs, nperseg=nper, axis=0)[1].sum(1)
    Saa = welch(A, fs=fs, nperseg=nper, axis=0)[1].sum(1)
    ok = Sff > 0
    H = np.where(ok, Sfr / np.where(ok, Sff, 1.0), 0.0)
    coh = np.where(ok & (Saa > 0), np.abs(Sfa) ** 2 / np.maximum(Sff * Saa, 1e-300), 0.0)
    coh_r = np.where(ok & (Srr > 0), np.abs(Sfr) ** 2 / np.maximum(Sff * Srr, 1e-300), 0.0)
    nd = max(1.0, 2.0 * len(w.t) / nper - 1.0)
    var = (1.0 - coh_r) * Srr / (2.0 * nd * np.where(ok, Sff, np.inf))
    return Transfer(f, H, var, coh, tuple(float(x) for x in model.band))


def response(f: np.ndarray, frequency: float, damping_ratio: float) -> np.ndarray:
    """G(j2πf) = −s² / (s² + 2ζω s + ω²) of the base-excited oscillator (ω = 2π frequency)."""
    s = 2j * np.pi * np.asarray(f, float)
    w = 2 * np.pi * frequency
    return -s * s / (s * s + 2 * damping_ratio * w * s + w * w)


def search_range(band: tuple, fs: float) -> tuple[float, float]:
    """(lowest, highest) mode frequency searched, Hz: above the band by
    :data:`MIN_BAND_MULTIPLE`, at least :data:`F_MIN`; at most :data:`F_MAX` and 0.4 fs."""
    return max(F_MIN, MIN_BAND_MULTIPLE * band[1]), min(F_MAX, 0.4 * fs)


def fit_mode(tr: Transfer, sensor: str, fs: float) -> ModeFit | None:
    """The structural mode of ``sensor`` (``imu``: H = p G; ``load_cells``: 1 + H = 1/(1 + p G))
    that best explains the transfer above the band (frequencies above its upper edge, below
    the search range's top, coherence ≥ :data:`COHERENCE`): a grid over f_n (log-spaced in
    :func:`search_range`) and ζ (:data:`ZETAS`), p by weighted least squares at each, then
    trust-region least squares (scipy ``least_squares``, bounded) on (ln f_n, ln ζ, p); σ from its Jacobian.  When
    f_n is not determined to :data:`LOCATED_REL_STD`, the fit is repeated with p = 1 (the
    physical oscillator) and ``located`` is False.  None when fewer than 3 frequencies
    qualify, or no mode of positive participation lowers the χ².  Raises ValueError for an unknown sensor."""
    if sensor not in SENSORS:
        raise ValueError(f"structural_mode: unknown sensor {sensor!r} ({', '.join(SENSORS)})")
    lo, hi = search_range(tr.band, fs)
    use = (tr.f > tr.band[1]) & (tr.f <= hi) & (tr.coherence >= COHERENCE) & np.isfinite(tr.var) & (tr.var > 0)
    if use.sum() < 3:
        return None
    f, H, var = tr.f[use], tr.H[use], tr.var[use]
    if sensor == "imu":
        Y, vY = H, var
    else:
        Y, vY = 1.0 / (1.0 + H) - 1.0, var / np.abs(1.0 + H) ** 4
    wgt = 1.0 / vY
    chi0 = float(np.sum(wgt * np.abs(Y) ** 2))

    def best_p(G):
        p = float(np.sum(wgt * np.real(np.conj(G) * Y)) / np.sum(wgt * np.abs(G) ** 2))
        return p, float(np.sum(wgt * np.abs(Y - p * G) ** 2))

    grid = [(fn, z) + best_p(response(f, fn, z)) for fn in np.geomspace(lo, hi, 60) for z in ZETAS]
    fn0, z0, p0, _ = min(grid, key=lambda g: g[3])

    def res(x, p_fixed=None):
        fn, z = np.exp(x[0]), np.exp(x[1])
        p = x[2] if p_fixed is None else p_fixed
        r = (Y - p * response(f, fn, z)) * np.sqrt(wgt)
        return np.concatenate([r.real, r.imag])

    lb, ub = [np.log(lo / 1.5), np.log(1e-3), -3.0], [np.log(1.5 * hi), 0.0, 3.0]
    sol = least_squares(res, np.clip([np.log(fn0), np.log(z0), p0], lb, ub), bounds=(lb, ub))
    fn, z, p = float(np.exp(sol.x[0])), float(np.exp(sol.x[1])), float(sol.x[2])
    J = sol.jac
    cov = np.linalg.pinv(J.T @ J)
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    chi1 = float(np.sum(sol.fun ** 2))
    if p <= 0 or chi1 >= chi0:
        return None                 # no mode of positive participation explains the departure
    located = bool(lo <= fn <= hi and sd[0] < LOCATED_REL_STD)
    std = {"frequency": fn * float(sd[0]), "damping_ratio": z * float(sd[1]), "participation": float(sd[2])}
    if not located:
        # only p / f_n² is determined: the physical oscillator's frequency for it
        x1 = np.clip([np.log(fn / np.sqrt(max(abs(p), 1e-6))), np.log(z)], lb[:2], ub[:2])
        sol1 = least_squares(lambda x: res(x, 1.0), x1, bounds=(lb[:2], ub[:2]))
        fn, z, p = float(np.exp(sol1.x[0])), float(np.exp(sol1.x[1])), 1.0
        cov1 = np.linalg.pinv(sol1.jac.T @ sol1.jac)
        sd1 = np.sqrt(np.clip(np.diag(cov1), 0, None))
        chi1 = float(np.sum(sol1.fun ** 2))
        std = {"frequency": fn * float(sd1[0]), "damping_ratio": z * float(sd1[1]), "participation": float("nan")}
        if chi1 >= chi0:
            return None
    # the H1 variances are the noise's alone: where the model leaves more than that (χ²/dof
    # above 1), the σ are widened by the Birge ratio
    dof_res = max(1, 2 * int(use.sum()) - (3 if located else 2))
    birge = max(1.0, float(np.sqrt(chi1 / dof_res)))
    std = {k: v * birge for k, v in std.items()}
    return ModeFit(sensor, fn, z, p, std, located, chi0 - chi1, 3, int(use.sum()), (float(f[0]), float(f[-1])))


def mode_filter(t: np.ndarray, u: np.ndarray, frequency: float, damping_ratio: float, participation: float,
                remove: bool = True) -> np.ndarray:
    """The readings u (K, n) sampled at the (nearly uniform) times t (K,) s with a
    structural mode removed (``remove``: multiplied by 1/(1 + p G), the inverse of
    :func:`~rig_identification.model.simulator.mode_response`'s u + p G (u − u₀)) or added
    (multiplied by 1 + p G), in the frequency domain (the record mirrored to twice its length
    against wrap-around), the change faded out above f_n / 2 by a zero-phase
    1/(1 + (f / (f_n/2))^16): the in-band correction is exact (below f_n/2 the fade is
    1 − 2⁻¹⁶ (f/(f_n/2))^16), the sensor noise above the mode is left as it is."""
    u = np.asarray(u, float)
    if participation == 0 or len(t) < 4:
        return u.copy()
    dt = (t[-1] - t[0]) / (len(t) - 1)
    x = np.concatenate([u, u[::-1]], axis=0)
    F = np.fft.rfft(x, axis=0)
    f = np.fft.rfftfreq(len(x), dt)
    g = 1.0 + participation * response(f, frequency, damping_ratio)
    c = 1.0 / g if remove else g
    fade = 1.0 / (1.0 + (f / (0.5 * frequency)) ** FADE_ORDER)
    c = 1.0 + (c - 1.0) * fade
    return np.fft.irfft(F * c[:, None] if F.ndim == 2 else F * c, n=len(x), axis=0)[:len(u)]


def out_of_band(tr: Transfer, sigmas: float = 5.0, limit: int = 4) -> list[dict]:
    """Where the accelerometer departs from Newton's prediction from the load cells above the
    fit band (coherence ≥ :data:`COHERENCE`, |H| beyond ``sigmas`` σ): ``{"channel":
    "accelerometer vs load cells", "band_hz": [lo, hi], "size": |H|, "sigma": |H| / σ}``
    (|H|: the departure per unit of the measured force), the largest first, at most ``limit``."""
    use = (tr.f > tr.band[1]) & (tr.coherence >= COHERENCE) & (tr.var > 0)
    df = float(tr.f[1] - tr.f[0]) if len(tr.f) > 1 else 0.1
    z = np.abs(tr.H) / np.sqrt(np.where(tr.var > 0, tr.var, np.inf))
    idx = [i for i in np.argsort(-z) if use[i] and z[i] > sigmas][:limit]
    return [{"channel": "accelerometer vs load cells", "band_hz": [round(float(tr.f[i] - df / 2), 3),
                                                                  round(float(tr.f[i] + df / 2), 3)],
             "size": round(float(abs(tr.H[i])), 5), "sigma": round(float(z[i]), 1)} for i in idx]


def gain_std(fit: ModeFit, f: float) -> float:
    """σ of the mode's in-band gain p G at frequency f Hz (the relative error a correction
    with the fitted mode leaves on the sensor's readings there, and so about on the tensor):
    the in-band gain itself, |p G(f)|, or its first-order σ (in the σ of the frequency,
    ∂G/∂f_n ≈ −2 G / f_n below the mode, and of the participation when it was fitted) where
    larger.  The floor at the whole correction is measured, not assumed: on bench_trust's
    structural_mode row (seed 8101, 90 s) the fit's own σ left the corrected tensor 1.01 %
    off at 3.1 σ — the mode placed from outside the band does not fix its in-band gain to
    better than its own size."""
    g = abs(fit.participation * response(np.array([f]), fit.frequency, fit.damping_ratio)[0])
    rel = 2.0 * fit.std.get("frequency", 0.0) / fit.frequency
    if fit.located and np.isfinite(fit.std.get("participation", np.nan)):
        rel = float(np.hypot(rel, fit.std["participation"] / max(abs(fit.participation), 1e-12)))
    return float(g * max(1.0, rel))
