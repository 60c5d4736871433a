"""Natural frequencies and mode shapes of the suspended body (issue 7).

Two independent sources, meant to agree:

* :func:`natural_modes` – from the geometry (rig.yaml) and the mass properties: the rigid
  body linearised about its static equilibrium.
* :func:`estimate_modes` – from a recording: the free-vibration peaks of the gyro spectrum.

Linear model
------------
Generalised coordinates q = [dp (3), φ (3)]: dp = displacement of the CG, world axes, m;
φ = small rotation vector in WORLD axes, rad (R = exp(φ) R0, R0 the equilibrium attitude).
Kinetic energy ½ q̇ᵀ M q̇ with M = diag(m, m, m, J_world), J_world = R0 J R0ᵀ about the CG.

Spring cables (stiffness k_i): potential V(q) = m g z_cg + Σ ½ k_i (l_i(q) − L_i)²; its
Hessian at equilibrium is K = Σ k_i ∇l_i ∇l_iᵀ + Σ T_i ∇²l_i + m g ∇²z_cg (the last is 0 for
these coordinates), i.e. elastic + geometric (tension) stiffness, including the moment
terms of the rotating lever arms.  Frequencies from ``scipy.linalg.eigh(K, M)``.

Inextensible cables: the motion stays on l_i(q) = L_i, i.e. to first order in the null
space Z of the N×6 length Jacobian G (rows ∇l_iᵀ); the stiffness is the Hessian of the
Lagrangian, Σ T_i ∇²l_i (+ gravity, 0 here), with T_i the equilibrium tensions; the
reduced problem is eigh(Zᵀ K Z, Zᵀ M Z) (6 − rank G modes: 2 for 4 generic cables).

The Hessians ∇²l_i are computed by central differences of the exact lengths (scipy
Rotation), the gradients analytically.
"""
from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import eigh, null_space
from scipy.ndimage import maximum_filter1d, median_filter
from scipy.optimize import least_squares
from scipy.signal import periodogram
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .cables import CableModel
from .equilibrium import equilibrium
from .rigid_body import SimulationError

if TYPE_CHECKING:
    from ..io.recording import Recording, TimeSeries

DOF_NAMES = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class Mode:
    """One natural mode.

    frequency: Hz.  shape: (6,) [dp_cg (m, world axes), φ (rad, world axes)], mass-normalised
    then scaled so its largest kinetic-energy component is positive.  energy: (6,) share of
    the modal kinetic energy in x, y, z, roll, pitch, yaw (world axes; sums to 1).
    description: e.g. ``"x-swing with pitch"``.
    """

    frequency: float
    shape: np.ndarray
    energy: np.ndarray
    description: str
    model: str = "spring"

    def to_dict(self) -> dict[str, Any]:
        return {"frequency_hz": float(self.frequency), "shape": [float(x) for x in self.shape],
                "energy": {k: float(e) for k, e in zip(DOF_NAMES, self.energy)},
                "description": self.description, "model": self.model,
                "shape_units": "dp_cg m (world axes), rotation rad (world axes)"}


@dataclass(frozen=True)
class EstimatedMode:
    """A free-vibration peak of a recording: frequency Hz, damping ratio (from the decay of
    the fitted damped sinusoid, may be ~0), gyro share (3,) of the mode's amplitude on the
    body x, y, z gyro axes, and ``axes``: the dominant ones as text."""

    frequency: float
    damping_ratio: float
    gyro_share: np.ndarray
    axes: str
    amplitude: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"frequency_hz": float(self.frequency), "damping_ratio": float(self.damping_ratio),
                "gyro_share": [float(x) for x in self.gyro_share], "axes": self.axes,
                "amplitude_rad_s": float(self.amplitude)}


@dataclass(frozen=True)
class ModalEstimate:
    """Output of :func:`estimate_modes`: the modes and the exciter frequency (Hz or None)."""

    modes: list[EstimatedMode]
    exciter_frequency: float | None
    warnings: list[str] = field(default_factory=list)


# --- geometry -> modes ------------------------------------------------------------------

def length_fn(rig: Rig, p_cg: np.ndarray, R0: Rotation, cg: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    A = rig.ceiling_anchors
    S = rig.body_anchors - cg          # anchors relative to the CG, body frame

    def lengths(q: np.ndarray) -> np.ndarray:
        R = Rotation.from_rotvec(q[3:]) * R0
        P = p_cg + q[:3] + R.apply(S)
        out: np.ndarray = np.linalg.norm(A - P, axis=1)
        return out
    return lengths


def gradients(rig: Rig, p_cg: np.ndarray, R0: Rotation, cg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 6) length Jacobian G at q = 0 and lengths (N,)."""
    A = rig.ceiling_anchors
    s = R0.apply(rig.body_anchors - cg)
    d = p_cg + s - A                   # from ceiling anchor to body anchor
    l = np.linalg.norm(d, axis=1)
    u = d / l[:, None]
    return np.hstack([u, np.cross(s, u)]), l


def length_hessians(lengths: Callable[[np.ndarray], np.ndarray], n: int, h: float = 1e-4) -> np.ndarray:
    """(N, 6, 6) Hessians of the lengths at q = 0 by central differences."""
    H = np.zeros((n, 6, 6))
    E = np.eye(6) * h
    f0 = lengths(np.zeros(6))
    for a in range(6):
        H[:, a, a] = (lengths(E[a]) - 2 * f0 + lengths(-E[a])) / h**2
        for b in range(a + 1, 6):
            v = (lengths(E[a] + E[b]) - lengths(E[a] - E[b]) - lengths(-E[a] + E[b])
                 + lengths(-E[a] - E[b])) / (4 * h * h)
            H[:, a, b] = H[:, b, a] = v
    return H


def describe_shape(energy: np.ndarray) -> str:
    """Text for a mode from its kinetic-energy shares (x, y, z, roll, pitch, yaw)."""
    names = ("x-swing", "y-swing", "bounce", "roll", "pitch", "yaw")
    order = np.argsort(energy)[::-1]
    main = [names[i] for i in order if energy[i] >= 0.15]
    if not main:
        main = [names[order[0]]]
    return main[0] + (" with " + " and ".join(main[1:]) if len(main) > 1 else "")


def _make_modes(w2: np.ndarray, V: np.ndarray, M: np.ndarray, model: str) -> list[Mode]:
    modes = []
    for lam, v in zip(w2, V.T):
        e = v * (M @ v)
        e = np.clip(e, 0, None)
        e = e / e.sum() if e.sum() > 0 else e
        k = int(np.argmax(e))
        if v[k] < 0:
            v = -v
        f = np.sqrt(max(lam, 0.0)) / (2 * np.pi)
        modes.append(Mode(float(f), v.copy(), e, describe_shape(e), model))
    return modes


def natural_modes(rig: Rig, mass: float, cg: ArrayLike, inertia: ArrayLike,
                  stiffness: ArrayLike | None = None) -> list[Mode]:
    """Natural modes of the body hanging at rest, lowest frequency first.

    rig: geometry; mass kg; cg (3,) body frame m; inertia (3, 3) kg m² about the CG, body
    axes (tensor, off-diagonals = negated products).  stiffness: None or inf ->
    inextensible cables (constrained system, 6 − rank modes); a scalar or (N,) N/m ->
    spring cables (6 modes).  Raises :class:`~rig_identification.model.simulator.SimulationError` (no equilibrium).
    """
    cg = np.asarray(cg, float)
    J = np.asarray(inertia, float)
    n = len(rig.cables)
    k = None if stiffness is None else np.broadcast_to(np.asarray(stiffness, float), (n,)).copy()
    rigid = k is None or not np.all(np.isfinite(k))
    cm = CableModel.inextensible() if rigid else CableModel.spring(rig, mass, stiffness=k)
    pos, R0, T = equilibrium(rig, mass, cg, cm)
    p_cg = pos + R0.apply(cg)
    Jw = R0.as_matrix() @ J @ R0.as_matrix().T
    M = np.zeros((6, 6))
    M[:3, :3] = mass * np.eye(3)
    M[3:, 3:] = Jw
    G, _ = gradients(rig, p_cg, R0, cg)
    H = length_hessians(length_fn(rig, p_cg, R0, cg), n)
    K = np.einsum("i,iab->ab", T, H)     # geometric (tension) stiffness; gravity term is 0
    if rigid:
        taut = T > 1e-9 * mass * rig.gravity
        Z = null_space(G[taut])
        if Z.shape[1] == 0:
            return []
        Kr, Mr = Z.T @ K @ Z, Z.T @ M @ Z
        w2, Vr = eigh(0.5 * (Kr + Kr.T), Mr)
        return _make_modes(w2, Z @ Vr, M, "inextensible")
    assert k is not None   # not rigid: a finite stiffness
    K = K + np.einsum("i,ia,ib->ab", k * (T > 0), G, G)
    w2, V = eigh(0.5 * (K + K.T), M)
    return _make_modes(w2, V, M, "spring")


# --- recording -> modes -----------------------------------------------------------------

def _uniform(ts: TimeSeries, t0: float, t1: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(t0, t1, 1.0 / fs)
    return t, ts.interp(t)


def _peak_refine(P: np.ndarray, f: np.ndarray, i: int) -> float:
    """Parabolic interpolation of the log spectrum around bin i."""
    if i <= 0 or i >= len(P) - 1:
        return float(f[i])
    a, b, c = np.log(P[i - 1:i + 2])
    den = a - 2 * b + c
    d = 0.5 * (a - c) / den if den != 0 else 0.0
    return float(f[i] + d * (f[1] - f[0]))


def exciter_frequency(rec: Recording, fs: float | None = None) -> float | None:
    """The exciter's rotation frequency, Hz, from the /rig/exciter/wrench spectrum (None if absent)."""
    ex = rec.sensors.exciter
    if ex is None or len(ex) < 64:
        return None
    fs = fs or 1.0 / np.median(np.diff(ex.t))
    t0 = ex.t[0] + min(5.0, 0.1 * (ex.t[-1] - ex.t[0]))
    t, x = _uniform(ex, t0, ex.t[-1], fs)
    z = (x[:, 0] - x[:, 0].mean()) + 1j * (x[:, 1] - x[:, 1].mean())
    if np.max(np.abs(z)) <= 0:
        return None
    nfft = int(2 ** np.ceil(np.log2(len(z)) + 2))
    Z = np.abs(np.fft.fft(z * np.hanning(len(z)), nfft)) ** 2
    fr = np.fft.fftfreq(nfft, 1 / fs)
    i = int(np.argmax(Z))
    lo, hi = max(i - 1, 0), min(i + 1, nfft - 1)
    a, b, c = np.log(Z[[lo, i, hi]])
    den = a - 2 * b + c
    d = 0.5 * (a - c) / den if den != 0 else 0.0
    return float(abs(fr[i] + d * (fr[1] - fr[0])))


def _combination(fr: float, base: list[float], tol: float, order: int = 4) -> bool:
    """True if ``fr`` is within ``tol`` of an integer combination Σ n_i f_i of the ``base``
    frequencies with 2 <= Σ|n_i| <= order (intermodulation / harmonics of a nonlinear response)."""
    b = np.asarray(base, float)
    for coeffs in itertools.product(range(-order, order + 1), repeat=len(b)):
        c = np.abs(coeffs).sum()
        if 2 <= c <= order and abs(abs(np.dot(coeffs, b)) - fr) < tol:
            return True
    return False


@dataclass(frozen=True)
class _ImuWindow:
    """The IMU signals the modes are estimated from.  t: (N,) s, a uniform grid at ``fs`` Hz.
    y: (N, 3) gyro, or (N, 6) gyro then specific force, body axes, each channel less its mean and
    divided by ``scale`` (3,) or (6,) (its RMS, rad/s or m/s²; 1 for a zero channel)."""

    t: np.ndarray
    y: np.ndarray
    scale: np.ndarray
    fs: float

    @property
    def duration(self) -> float:
        """T = t[-1] - t[0], s."""
        T: float = self.t[-1] - self.t[0]
        return T


def _imu_window(rec: Recording, settle: float, use_accel: bool) -> _ImuWindow:
    """The IMU of ``rec`` from ``settle`` s after its start (at most a tenth of it) to its end,
    resampled at its median rate, rotated into body axes and scaled to unit RMS per channel."""
    rig, s = rec.rig, rec.sensors
    fs = 1.0 / np.median(np.diff(s.imu.t))
    t0 = s.t_start + min(settle, 0.1 * (s.t_end - s.t_start))
    t, x = _uniform(s.imu, t0, s.t_end, fs)
    g = rig.imu.rotation.apply(x[:, :3])
    chans = [g]
    if use_accel:
        chans.append(rig.imu.rotation.apply(x[:, 3:]))
    y = np.hstack(chans)
    y = y - y.mean(axis=0)
    scale = np.sqrt(np.mean(y**2, axis=0))
    scale[scale <= 0] = 1.0
    return _ImuWindow(t, y / scale, scale, fs)


def _spectral_peaks(imu: _ImuWindow, forced: list[float], f_min: float, f_max: float,
                    prominence: float) -> tuple[list[tuple[float, float]], float]:
    """(candidate peaks as (power, frequency Hz refined by :func:`_peak_refine`), strongest first;
    the periodogram's bin width df, Hz).

    Hann periodogram of ``imu.y`` (zero-padded to 4× the next power of 2), summed over the
    channels; a peak is the maximum within ±2/T, at least ``prominence`` times the local median
    floor, in [f_min, f_max] Hz and outside ±max(0.02, 2/T) Hz of every ``forced`` frequency."""
    T = imu.duration
    nfft = int(2 ** np.ceil(np.log2(len(imu.t)) + 2))
    f, P = periodogram(imu.y, fs=imu.fs, window="hann", nfft=nfft, axis=0)
    Ps = P.sum(axis=1)
    df = f[1] - f[0]
    w = max(5, int(1.0 / df) | 1)
    floor = median_filter(Ps, size=w, mode="nearest")
    lobe = max(1, int(round(2.0 / T / df)))
    bad = np.zeros(len(f), bool)
    for fh in forced:
        bad |= np.abs(f - fh) < max(0.02, 2.0 / T)
    loc = maximum_filter1d(Ps, size=2 * lobe + 1, mode="nearest")
    cand = [(Ps[i], _peak_refine(Ps, f, i)) for i in range(1, len(f) - 1)
            if f_min <= f[i] <= f_max and not bad[i] and Ps[i] >= loc[i] and Ps[i] > prominence * floor[i]]
    cand.sort(reverse=True)
    return cand, df


def _free_peaks(cand: list[tuple[float, float]], fex: float | None, tol: float,
                max_modes: int) -> tuple[list[float], list[float]]:
    """(free-vibration frequencies, at most ``max_modes``; intermodulation/harmonic frequencies),
    Hz, from the candidate peaks ``cand`` (strongest first): a peak within ``tol`` Hz of a
    combination (:func:`_combination`) of the exciter frequency ``fex`` and the first free peaks
    (3 frequencies in all) is not free."""
    freqs: list[float]
    combos: list[float]
    freqs, combos = [], []
    for _, fr in cand:
        base = ([fex] if fex is not None else []) + freqs
        if base and _combination(fr, base[:3], tol):
            combos.append(fr)
            continue
        freqs.append(fr)
        if len(freqs) >= max_modes:
            break
    return freqs, combos


def _damped_basis(p: np.ndarray, tt: np.ndarray, forced: list[float]) -> np.ndarray:
    """(N, 2 nm + 2 len(forced) + 1) columns: per mode j (p = [f_d (nm) Hz, σ (nm) 1/s]) the damped
    cosine and sine e^(-σ_j t) cos/sin(2π f_j t), the cosine and sine of every ``forced``
    frequency, and a constant; tt (N,) s from the window's start."""
    nm = len(p) // 2
    cols: list[np.ndarray] = []
    for j in range(nm):
        e = np.exp(-p[nm + j] * tt)
        cols += [e * np.cos(2 * np.pi * p[j] * tt), e * np.sin(2 * np.pi * p[j] * tt)]
    for fh in forced:
        cols += [np.cos(2 * np.pi * fh * tt), np.sin(2 * np.pi * fh * tt)]
    cols.append(np.ones_like(tt))
    return np.column_stack(cols)


def _basis_coefficients(B: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(k, channels) least-squares coefficients of the basis B (N, k) for y (N, channels)."""
    # normal equations (the columns are near-orthogonal sinusoids; much faster than SVD lstsq)
    N = B.T @ B
    return np.linalg.solve(N + 1e-12 * np.trace(N) / len(N) * np.eye(len(N)), B.T @ y)


def _fit_damped_sinusoids(imu: _ImuWindow, freqs: list[float], forced: list[float],
                          warnings: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(p = [damped frequencies f_d (nm) Hz, decay rates σ (nm) 1/s], coefficients (2 nm +
    2 len(forced) + 1, channels) of :func:`_damped_basis`): one nonlinear least-squares fit over
    the window, each frequency within ±1/T of its peak ``freqs`` (nm,).  A failed fit keeps the
    peaks (σ 0.01 1/s) with a warning appended to ``warnings``."""
    T = imu.duration
    tt = imu.t - imu.t[0]
    nm = len(freqs)

    def resid(p: np.ndarray) -> np.ndarray:
        B = _damped_basis(p, tt, forced)
        r: np.ndarray = (imu.y - B @ _basis_coefficients(B, imu.y)).ravel()
        return r

    p0 = np.r_[freqs, np.full(nm, 0.01)]
    lb = np.r_[np.array(freqs) - 1.0 / T, np.full(nm, -0.05)]
    ub = np.r_[np.array(freqs) + 1.0 / T, np.full(nm, 50.0)]
    p0 = np.clip(p0, lb + 1e-9, ub - 1e-9)
    try:
        p = least_squares(resid, p0, bounds=(lb, ub),
                          x_scale=np.r_[np.full(nm, 1e-3), np.full(nm, 1e-2)]).x
    except (ValueError, np.linalg.LinAlgError) as e:   # pragma: no cover - fall back to the peaks
        warnings.append(f"damped-sinusoid fit failed ({e}); spectral peaks only")
        p = p0
    return p, _basis_coefficients(_damped_basis(p, tt, forced), imu.y)


def _fitted_modes(p: np.ndarray, C: np.ndarray, scale: np.ndarray,
                  max_damping: float) -> tuple[list[EstimatedMode], list[str]]:
    """(the modes of the fit ``p``, ``C`` (:func:`_fit_damped_sinusoids`; ``scale`` the channels'
    RMS), each with its undamped natural frequency sqrt(ω_d² + σ²)/2π and gyro share; the damped
    frequencies, as text in Hz, of the components dropped for a damping ratio above
    ``max_damping``)."""
    nm = len(p) // 2
    modes, dropped = [], []
    for j in range(nm):
        amp = np.hypot(C[2 * j], C[2 * j + 1])[:3] * scale[:3]       # gyro rad/s per body axis
        tot = amp.sum()
        share = amp / tot if tot > 0 else amp
        axes = "+".join("xyz"[a] for a in np.argsort(share)[::-1] if share[a] >= 0.25)
        fd, sig = float(p[j]), float(p[nm + j])
        wn = np.hypot(2 * np.pi * fd, sig)
        if sig / wn > max_damping:
            dropped.append(f"{fd:.2f}")
            continue
        modes.append(EstimatedMode(float(wn / (2 * np.pi)), float(sig / wn), share,
                                   "gyro " + (axes or "-"), float(np.linalg.norm(amp))))
    return modes, dropped


def estimate_modes(rec: Recording, f_min: float = 0.2, f_max: float = 40.0, max_modes: int = 8,
                   prominence: float = 30.0, settle: float = 3.0, use_accel: bool = True,
                   max_damping: float = 0.2) -> ModalEstimate:
    """Free-vibration modes of a recording from its gyro (and accelerometer) signals.

    Hann periodogram of the whole window (each body-axis channel scaled to unit RMS, summed)
    -> peaks that are the maximum within ±2/T (no window side lobes), at least
    ``prominence`` times the local median floor, outside ±max(0.02, 2/T) Hz of the exciter
    frequency (from /rig/exciter/wrench) and its harmonics, and not intermodulation products
    (n_1 f_1 + n_2 f_2 + … of the exciter and the 2 strongest peaks, order 2–4) -> one joint
    nonlinear least-squares fit over the window of damped sinusoids (shared frequency and decay
    over all channels) plus the exciter's harmonics, refining each frequency far below 1/T.
    Components with a damping ratio above ``max_damping`` (the broadband transient of a force
    step) are dropped.  The frequencies returned are undamped natural frequencies
    sqrt(ω_d² + σ²)/2π.  Note: a large forced response shifts the pendulum frequencies
    (amplitude-dependent, about −0.8 % at 200 N on case 16).
    """
    imu = _imu_window(rec, settle, use_accel)
    fex = exciter_frequency(rec)
    forced = [] if fex is None else [h * fex for h in (1, 2, 3) if h * fex < imu.fs / 2]
    cand, df = _spectral_peaks(imu, forced, f_min, f_max, prominence)
    freqs, combos = _free_peaks(cand, fex, max(0.3 / imu.duration, 2 * df), max_modes)
    warnings = []
    if combos:
        warnings.append("intermodulation/harmonic peaks ignored at " + ", ".join(f"{c:.3f}" for c in sorted(combos))
                        + " Hz")
    if not freqs:
        return ModalEstimate([], fex, warnings + ["no free-vibration peak found in the IMU spectrum"])
    freqs.sort()
    p, C = _fit_damped_sinusoids(imu, freqs, forced, warnings)
    modes, dropped = _fitted_modes(p, C, imu.scale, max_damping)
    if dropped:
        warnings.append("heavily damped transient components ignored (damping ratio > "
                        f"{max_damping}) at " + ", ".join(dropped) + " Hz")
    return ModalEstimate(modes, fex, warnings)

def match_modes(geometric: list[Mode], estimated: list[EstimatedMode],
                tol: float = 0.1) -> list[tuple[Mode, EstimatedMode | None, float | None]]:
    """Pairs (Mode, EstimatedMode or None, difference % of the estimate vs geometry): each
    geometric mode with the nearest estimated frequency within ``tol`` (relative)."""
    out: list[tuple[Mode, EstimatedMode | None, float | None]] = []
    for m in geometric:
        best = min(estimated, key=lambda e: abs(e.frequency - m.frequency), default=None)
        if best is not None and abs(best.frequency - m.frequency) <= tol * m.frequency:
            out.append((m, best, 100 * (best.frequency - m.frequency) / m.frequency))
        else:
            out.append((m, None, None))
    return out


__all__ = ["Mode", "EstimatedMode", "ModalEstimate", "natural_modes", "estimate_modes", "exciter_frequency",
           "match_modes", "describe_shape", "SimulationError"]
