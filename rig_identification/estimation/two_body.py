"""The body on the cables as two bodies: a frame and a sprung body on a compliant mount.

A vehicle on its unlocked suspension inside the carrying frame is not rigid: its sprung
body rolls and pitches on springs relative to the frame (modes at 1–3 Hz).  The load cells
and the exciter measure the generalized wrench on the *whole* body, the rate of change of
the frame's and the sprung body's momentum together; the gyro on the frame sees the frame
only.  Linearised about rest (small motions relative to the frame), the sprung body's
motion relative to the frame is a set of base-excited oscillators driven by the frame's
angular acceleration, and the whole body's Euler equation about its centre of gravity at
rest gains their reaction (modal form of a substructure on a moving base; Craig & Bampton,
AIAA J. 6 (1968); the "effective modal mass", Géradin & Rixen, *Mechanical Vibrations*,
3rd ed. 2015, §4.4)::

    J ω̇ + ω × (J ω) + Σ_k ℓ_k q̈_k = M              (whole body, about its CG at rest, body axes)
    q̈_k + 2 ζ_k ω_k q̇_k + ω_k² q_k = −ℓ_kᵀ ω̇        (mode k of the sprung body, the frame held)

J (3,3) kg·m² is the whole body's inertia tensor at rest — what a lab wants — and
ℓ_k (3,) kg^½·m its participation (ℓ_k = J_s v_k with the mode shape v_k normalised by
v_kᵀ J_s v_k = 1, J_s the sprung body's tensor: Σ over all its rotational modes ℓ_k ℓ_kᵀ =
J_s).  In the frequency domain the body has the apparent tensor
J_app(s) = J + Σ_k ℓ_k ℓ_kᵀ G_k(s), G_k(s) = −s² / (s² + 2ζ_k ω_k s + ω_k²): the tensor
at rest at s → 0, J − Σ ℓ_k ℓ_kᵀ (the frame's part) far above the modes, and near them
the apparent inertia a rigid-body fit reports, frequency dependent — the signature
:mod:`~rig_identification.estimation.validation`'s ``sub_bands`` check sees.

Integrated once (as the rigid-body identifier, :mod:`~rig_identification.estimation.identification`),
with z_k = q̇_k + ℓ_kᵀ ω the equations become a stable state space from the integrated
moment U = ∫(M − ω × Jω) to the frame's angular velocity, no integrator left::

    ω = Q (U − Σ ℓ_k z_k),   Q = (J − Σ ℓ_k ℓ_kᵀ)⁻¹
    q̇_k = z_k − ℓ_kᵀ ω,      ż_k = −2 ζ_k ω_k q̇_k − ω_k² q_k

The prediction is output error, band-passed like the identifier's: ŷ = F H(s) U against
y = F ω (F the zero-phase Butterworth band-pass; H discretised exactly for a piecewise-linear
input, scipy ``cont2discrete(method="foh")``, then ``lfilter``).  The gyroscopic term is
evaluated with the measured ω and the current J, as there.

Everything here is plain numpy/scipy on arrays; the candidate that fits it to a recording is
:mod:`rig_identification.diagnosis.compliant_body`.
"""
from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import cont2discrete, lfilter, sosfiltfilt, ss2tf

from ..model.parametrisation import basis, to_tensor


@dataclass(frozen=True)
class SprungModes:
    """The parameters of the two-body model: j (6,) the whole body's tensor at rest, entries
    in :data:`~rig_identification.io.verdict.KEYS` order, kg·m²; participation (n,3)
    kg^½·m, one row ℓ_k per mode (body axes); frequency (n,) Hz (the mode's undamped natural
    frequency with the frame held); damping_ratio (n,)."""

    j: np.ndarray
    participation: np.ndarray
    frequency: np.ndarray
    damping_ratio: np.ndarray

    @property
    def n(self) -> int:
        return int(len(self.frequency))

    @property
    def tensor(self) -> np.ndarray:
        """(3,3) kg·m² the whole body's tensor at rest."""
        return to_tensor(self.j)

    @property
    def sprung_tensor(self) -> np.ndarray:
        """(3,3) kg·m²: Σ ℓ_k ℓ_kᵀ, the part of the sprung body's tensor its fitted modes carry."""
        L = np.asarray(self.participation, float).reshape(-1, 3)
        sprung: np.ndarray = L.T @ L
        return sprung

    def apparent(self, f_hz: float) -> np.ndarray:
        """(3,3) complex: the apparent tensor J + Σ ℓ_k ℓ_kᵀ G_k(j 2π f) at f Hz (module docstring)."""
        s = 2j * np.pi * f_hz
        out = self.tensor.astype(complex)
        for L, fk, zk in zip(np.reshape(self.participation, (-1, 3)), self.frequency, self.damping_ratio):
            w = 2 * np.pi * fk
            out = out + np.outer(L, L) * (-s * s / (s * s + 2 * zk * w * s + w * w))
        return out


def oscillator(x: np.ndarray, f: float, zeta: float, fs: float) -> np.ndarray:
    """G(s) x = −s² / (s² + 2ζω s + ω²) x (ω = 2π f): the base-excited oscillator's relative
    acceleration per unit base acceleration, applied along the last axis of x sampled at fs
    Hz from rest (exact for a piecewise-linear input, ``cont2discrete(method="foh")``)."""
    w = 2 * np.pi * f
    num, den, _ = cont2discrete(([-1.0, 0.0, 0.0], [1.0, 2 * zeta * w, w * w]), 1.0 / fs, method="foh")
    y: np.ndarray = lfilter(np.ravel(num), den, x, axis=-1)
    return y


def state_space(m: SprungModes) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Continuous state space (A (2n,2n), B (2n,3), C (3,2n), D (3,3)) from the integrated
    moment U (N·m·s) to ω (rad/s), states (q, z) (module docstring).  Raises
    numpy.linalg.LinAlgError when J − Σ ℓ ℓᵀ is singular."""
    n = m.n
    L = np.asarray(m.participation, float).reshape(n, 3).T          # (3, n)
    Q = np.linalg.inv(m.tensor - L @ L.T)
    W = np.diag(2 * np.pi * np.asarray(m.frequency, float))
    Z2W = 2 * np.diag(np.asarray(m.damping_ratio, float)) @ W
    LQ = L.T @ Q
    Aqz = np.eye(n) + LQ @ L                                        # q̇ = Aqz z − LQ U
    A = np.block([[np.zeros((n, n)), Aqz], [-W @ W, -Z2W @ Aqz]])
    B = np.vstack([-LQ, Z2W @ LQ])
    C = np.hstack([np.zeros((3, n)), -Q @ L])
    return A, B, C, Q


def frame_inertia_definite(m: SprungModes) -> bool:
    """Whether J − Σ ℓ_k ℓ_kᵀ (the frame's part of the tensor) is positive definite: a
    physical split (the sprung body cannot carry more inertia than the whole)."""
    L = np.asarray(m.participation, float).reshape(-1, 3)
    F = m.tensor - L.T @ L
    if not np.all(np.isfinite(F)):
        return False
    return bool(np.linalg.eigvalsh(F)[0] > 0)


def respond(m: SprungModes, U: np.ndarray, fs: float) -> np.ndarray:
    """ω (…, N, 3) rad/s of the two-body model driven by the integrated moment U (…, N, 3)
    N·m·s sampled at fs Hz, from rest (the states zero at the first sample).  Raises
    numpy.linalg.LinAlgError for a singular frame part."""
    A, B, C, D = state_space(m)
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), 1.0 / fs, method="foh")
    U = np.asarray(U, float)
    out = np.zeros(U.shape)
    for i in range(3):
        num, den = ss2tf(Ad, Bd, Cd, Dd, input=i)
        for o in range(3):
            out[..., o] += lfilter(num[o], den, U[..., i], axis=-1)
    return out


@dataclass(frozen=True)
class FitInput:
    """One window at the fit rate: t (N,) s; omega (N,3) rad/s the gyro, body axes; y (N,3)
    its band-passed version (the measured output); IM (N,3) N·m·s ∫M dt from the window's
    start; GM (6,N,3) ∫ ω × (E_m ω) dt (the gyroscopic term's regressors, E the tensor
    basis); fs Hz; sos the band-pass (second-order sections); band_hz; keep (N,) bool the
    samples the fit uses (after the modes' start-up transient)."""

    t: np.ndarray
    omega: np.ndarray
    y: np.ndarray
    IM: np.ndarray
    GM: np.ndarray
    fs: float
    sos: np.ndarray
    band_hz: tuple[float, ...]
    keep: np.ndarray

    def filt(self, x: np.ndarray) -> np.ndarray:
        """The band-pass along the time axis (−2) of x (…, N, 3)."""
        y: np.ndarray = sosfiltfilt(self.sos, x, axis=-2)
        return y

    def U(self, j: np.ndarray) -> np.ndarray:
        """(N,3) N·m·s: ∫(M − ω × Jω) dt with the tensor entries j (6,)."""
        U: np.ndarray = self.IM - np.einsum("m,mni->ni", j, self.GM)
        return U


@dataclass(frozen=True)
class InputNoise:
    """K first-order noise realisations of a :class:`FitInput` (half the difference of an
    antithetic pair of replays with fresh sensor noise): dy (K,N,3) of the band-passed gyro,
    dIM (K,N,3) of ∫M, dGM (K,6,N,3) of the gyroscopic regressors."""

    dy: np.ndarray
    dIM: np.ndarray
    dGM: np.ndarray

    @property
    def count(self) -> int:
        return int(self.dy.shape[0])

    def dU(self, j: np.ndarray) -> np.ndarray:
        """(K,N,3) the noise of U at the tensor entries j (6,)."""
        dU: np.ndarray = self.dIM - np.einsum("m,kmni->kni", j, self.dGM)
        return dU


def predict(m: SprungModes, x: FitInput, noise: InputNoise | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """The band-passed prediction ŷ (N,3) rad/s of the window ``x``, and with ``noise`` the
    realisations of the residual's noise dr_k = dy_k − F H dU_k (K,N,3) (the output's and the
    input's noise through the model: errors in variables, Söderström 2018 ch. 5)."""
    U = x.U(m.j)
    if noise is None:
        return x.filt(respond(m, U, x.fs)), None
    both = respond(m, np.concatenate([U[None], noise.dU(m.j)]), x.fs)
    yh = x.filt(both)
    return yh[0], noise.dy - yh[1:]


E_BASIS = basis()


# --- the parameters ---------------------------------------------------------------------------

ALIGNED = np.array([[True, False, True], [False, True, False]])
"""Which participation components are free, per mode (rows: the roll and the pitch mode; columns
x, y, z): a vehicle in its frame is symmetric about the body's x–z plane, so its sprung body's
roll mode turns it about an axis in that plane (ℓ = J_s e_x / √J_s,xx = (J_s,xx, J_s,xy ≈ 0,
J_s,xz) / √J_s,xx) and its pitch mode about y (ℓ ≈ (0, √J_s,yy, 0)); yaw, fore-aft and lateral
are held by the suspension's links (tens of Hz, outside the band)."""
FREE = np.ones((2, 3), bool)
WITH_LOCK = np.ones((3, 3), bool)     # roll, pitch and the locked directions (:data:`LOCK_HZ`), every component free
"""Every participation component free (roll and pitch modes): a sprung body with products of
inertia J_s,xy ≠ 0 (the random NHTSA vehicles: J_s,xy −43 kg·m² for J_s,xx 734 on
bench_compliant_body's seed 9100) has ℓ_roll = J_s v_roll with a y component; the ALIGNED
shape then biases ixy and Ixx."""
FREQUENCY_BOUNDS = (0.5, 6.0)      # Hz: where the fit may put a mode (plausibility is the caller's)
DAMPING_BOUNDS = (0.01, 0.9)       # the modes' damping ratio, ditto


LOCK_HZ = 20.0
"""Hz: the frequency at which the suspension's locked directions (yaw, fore-aft, lateral:
links and bushings, tens of Hz) are modelled — one more mode, its participation ℓ free
(3 components), its frequency and damping (:data:`LOCK_DAMPING`) held.  In the band it adds
the apparent inertia ℓ ℓᵀ (f / f_lock)² (the residual term of a truncated modal expansion:
Craig & Bampton 1968; Géradin & Rixen §4.4), which the fit's ℓ takes whatever the true lock
frequency above the band.  Left out, it biased the tensor at rest: on a 0.5–3.5 Hz sweep of
bench_compliant_body's seed 9100 with the simulator's 25 Hz locks Ixx −0.47 % (3.5 σ); with
the locks at 100 Hz −0.08 % (0.5 σ)."""
LOCK_DAMPING = 0.1


@dataclass(frozen=True)
class Parametrisation:
    """The scaled parameter vector of a :class:`SprungModes`: j / scale (6), the free
    participation components (``shape`` (n,3) bool) / √scale, then (f Hz, ζ) per mode but
    the last len(``fixed``), whose (f, ζ) are held at ``fixed``; scale kg·m² a typical moment
    (tr J / 3), so that every parameter is of order one."""

    shape: np.ndarray
    scale: float
    fixed: tuple[tuple[float, float], ...] = ()

    @property
    def n(self) -> int:
        return int(len(self.shape))

    @property
    def n_free(self) -> int:
        """The modes whose frequency and damping are fitted."""
        return self.n - len(self.fixed)

    @property
    def size(self) -> int:
        return 6 + int(np.sum(self.shape)) + 2 * self.n_free

    def pack(self, m: SprungModes) -> np.ndarray:
        L = np.asarray(m.participation, float).reshape(self.n, 3)
        fz = np.column_stack([m.frequency, m.damping_ratio])[:self.n_free].ravel()
        return np.concatenate([np.asarray(m.j, float) / self.scale, L[self.shape] / np.sqrt(self.scale), fz])

    def unpack(self, p: np.ndarray) -> SprungModes:
        p = np.asarray(p, float)
        k = int(np.sum(self.shape))
        L = np.zeros((self.n, 3))
        L[self.shape] = p[6:6 + k] * np.sqrt(self.scale)
        fz = np.vstack([p[6 + k:].reshape(self.n_free, 2), np.reshape(np.asarray(self.fixed, float), (-1, 2))])
        return SprungModes(p[:6] * self.scale, L, fz[:, 0].copy(), fz[:, 1].copy())

    def bounds(self, frequency: tuple[float, float] = FREQUENCY_BOUNDS, damping: tuple[float, float] = DAMPING_BOUNDS
               ) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds (only f and ζ bounded)."""
        k = 6 + int(np.sum(self.shape))
        lo = np.concatenate([np.full(k, -np.inf), np.tile([frequency[0], damping[0]], self.n_free)])
        hi = np.concatenate([np.full(k, np.inf), np.tile([frequency[1], damping[1]], self.n_free)])
        return lo, hi


# --- frequency-domain errors-in-variables maximum likelihood -----------------------------------

SMOOTH_HZ = 0.25   # width of the running mean over DFT bins of the residual noise's cross-spectrum


@dataclass(frozen=True)
class Whitened:
    """The whitened frequency-domain residual of a model: e (2·3·B,) real, each DFT bin's
    residual R_b (3,) premultiplied by S_b^(−½) (S_b the residual noise's 3×3 cross-spectrum
    at that bin *under this model*, from the noise realisations), real and imaginary parts
    × √2 — unit variance each when the model is right; f (B,) Hz the bins; ok False for an
    unphysical model (frame part not positive definite, or no finite response: e None)."""

    e: np.ndarray | None
    f: np.ndarray | None
    ok: bool

    @property
    def cost(self) -> float:
        """V = Σ e² (inf when not ok): χ² with about len(e) degrees of freedom at the truth."""
        return float(self.e @ self.e) if self.ok else np.inf  # type: ignore[operator]  # e is set when ok


def band_bins(x: FitInput) -> tuple[np.ndarray, int]:
    """(B,) indices of the DFT bins of the fit window (``x.keep``) inside the band, and the
    window's length in samples."""
    n = int(x.keep.sum())
    f = np.fft.rfftfreq(n, 1.0 / x.fs)
    lo, hi = x.band_hz
    return np.nonzero((f >= lo) & (f <= hi))[0], n


def cross_spectrum(dR: np.ndarray, width: int) -> np.ndarray:
    """(B,3,3) Hermitian: the mean over the realisations and a running window of ``width``
    bins of dR dRᴴ, dR (K,B,3) the realisations' DFT (at the edges the window shrinks)."""
    P = np.einsum("kbi,kbj->bij", dR, dR.conj()) / len(dR)
    c = np.cumsum(np.concatenate([np.zeros((1, 3, 3), complex), P]), axis=0)
    B = len(P)
    h = width // 2
    a = np.clip(np.arange(B) - h, 0, B)
    b = np.clip(np.arange(B) + h + 1, 0, B)
    S: np.ndarray = (c[b] - c[a]) / (b - a)[:, None, None]
    return S


def whitened(m: SprungModes, x: FitInput, noise: InputNoise) -> Whitened:
    """The :class:`Whitened` residual of the model m on the window x: the criterion of the
    frequency-domain errors-in-variables maximum-likelihood estimator, V(θ) = Σ_b R_bᴴ
    S_b(θ)⁻¹ R_b, the noise's cross-spectrum S_b(θ) of the residual taken *at θ* — the
    input's noise (the gyro's, through the tracked pose; correlated with the output's) passed
    through the model with the output's (Pintelon & Schoukens, *System Identification: A
    Frequency Domain Approach*, 2nd ed. 2012, §10.3: the sample maximum-likelihood estimator
    with nonparametric noise models).  Least squares with fixed weights is biased toward
    models under which the input's and the output's noise cancel."""
    if not frame_inertia_definite(m):
        return Whitened(None, None, False)
    try:
        yh, dr = predict(m, x, noise)
    except (np.linalg.LinAlgError, ValueError):
        return Whitened(None, None, False)
    bins, nk = band_bins(x)
    R = np.fft.rfft((x.y - yh)[x.keep], axis=0)[bins]
    dR = np.fft.rfft(dr[:, x.keep], axis=1)[:, bins]  # type: ignore[index]  # predict gives dr with noise
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(dR))):
        return Whitened(None, None, False)
    width = max(3, int(round(SMOOTH_HZ * nk / x.fs)) | 1)
    try:
        Lc = np.linalg.cholesky(cross_spectrum(dR, width))
    except np.linalg.LinAlgError:
        return Whitened(None, None, False)
    z = np.linalg.solve(Lc, R[:, :, None])[:, :, 0]
    f = np.fft.rfftfreq(nk, 1.0 / x.fs)[bins]
    return Whitened(np.sqrt(2.0) * np.concatenate([z.real.ravel(), z.imag.ravel()]), f, True)


# --- the fit -------------------------------------------------------------------------------------

FD_STEP = 1e-6        # relative forward-difference step of the scaled parameters
BAD_RESIDUAL = 1e3    # whitened residual returned for an unphysical trial point (LM backs off)


@dataclass(frozen=True)
class ModeFit:
    """One local optimum of the criterion: modes (:class:`SprungModes`), p the scaled
    parameters, cost V, dof (the number of whitened residuals, 6 per bin), jac (M,P) the
    whitened residual's Jacobian in p at the optimum, start (f Hz per mode) it came from."""

    modes: SprungModes
    p: np.ndarray
    cost: float
    dof: int
    jac: np.ndarray | None
    start: tuple[float, ...]


def fit_modes(par: Parametrisation, start: SprungModes, x: FitInput, noise: InputNoise, free: np.ndarray | None = None,
              max_nfev: int = 200, frequency: tuple[float, float] = FREQUENCY_BOUNDS,
              damping: tuple[float, float] = DAMPING_BOUNDS) -> ModeFit:
    """Minimise V (:func:`whitened`) from ``start`` over the parameters ``free`` (bool (P,),
    default all) by trust-region least squares on the whitened residual (scipy
    ``least_squares``, forward differences, Jacobian scaling), f and ζ within the bounds."""
    p0 = par.pack(start)
    free = np.ones(len(p0), bool) if free is None else np.asarray(free, bool)
    lo, hi = par.bounds(frequency, damping)
    lo, hi = lo[free], hi[free]
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    q0 = np.clip(p0[free], lo + 1e-9 * span, hi - 1e-9 * span)
    size: list[Any] = [None]

    def full(q: np.ndarray) -> np.ndarray:
        p = p0.copy()
        p[free] = q
        return p

    def fun(q: np.ndarray) -> np.ndarray:
        w = whitened(par.unpack(full(q)), x, noise)
        if not w.ok:
            return np.full(size[0], BAD_RESIDUAL)
        size[0] = len(w.e)  # type: ignore[arg-type]  # w.e is set when w.ok
        return w.e  # type: ignore[return-value]

    first = whitened(par.unpack(full(q0)), x, noise)
    if not first.ok:
        return ModeFit(start, p0, np.inf, 0, None, tuple(start.frequency))
    size[0] = len(first.e)  # type: ignore[arg-type]  # first.e is set when first.ok
    sol = least_squares(fun, q0, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=max_nfev,
                        diff_step=FD_STEP)
    p = full(sol.x)
    m = par.unpack(p)
    return ModeFit(m, p, float(2 * sol.cost), size[0], sol.jac, tuple(start.frequency))


SEARCH_FREQUENCIES = tuple(float(f) for f in np.round(np.geomspace(0.9, 3.6, 7), 3))
"""Hz: the grid of starting frequencies per mode (every pair: roll × pitch) of :func:`search`."""
SEARCH_DAMPING = (0.1, 0.3)   # starting damping ratios (both modes alike)
LOCK_START_SHARE = 0.05  # starting participation of the locked directions' mode (about z: yaw)
SEARCH_SHARE = 0.3       # starting participation: ℓ² = this share of the rigid fit's moment about the mode's axis
SEARCH_KEEP = 10         # grid points refined with every parameter free
SEARCH_COARSE_NFEV = 15  # evaluations per grid point (frequencies held)
SAME_OPTIMUM = 1e-3      # two refined optima whose scaled parameters differ by less than this are one


def start_modes(J_rigid: np.ndarray, frequencies: Sequence[float], f_dominant: float, shape: np.ndarray = ALIGNED,
                damping: float = 0.2) -> SprungModes:
    """A starting point: participation ℓ_k of :data:`SEARCH_SHARE` of the rigid-body fit's
    moment about the mode's main axis, ζ ``damping``, and the tensor at rest that gives the
    rigid-body fit's tensor as the apparent one at the dominant frequency f_dominant Hz
    (J = J_rigid − Σ ℓℓᵀ Re G(j2πf)), or J_rigid if that leaves no frame."""
    n = len(shape)
    L = np.zeros((n, 3))
    for k in range(n):
        a = k if k < 3 and shape[k][k] else int(np.argmax(shape[k]))
        share = SEARCH_SHARE if k < len(frequencies) else LOCK_START_SHARE
        L[k, a] = np.sqrt(share * J_rigid[a, a])
    fz = np.asarray(list(frequencies) + [LOCK_HZ] * (n - len(frequencies)), float)
    m = SprungModes(np.zeros(6), L, fz,
                    np.array([damping] * len(frequencies) + [LOCK_DAMPING] * (n - len(frequencies))))
    A = (m.apparent(f_dominant) - m.tensor).real
    for J in (J_rigid - A, J_rigid):
        cand = SprungModes(np.array([J[i, j] for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))]), L,
                           m.frequency, m.damping_ratio)
        if frame_inertia_definite(cand):
            return cand
    return cand


def search(par: Parametrisation, J_rigid: np.ndarray, f_dominant: float, x: FitInput, noise: InputNoise,
           frequencies: Sequence[float] = SEARCH_FREQUENCIES, keep: int = SEARCH_KEEP,
           frequency: tuple[float, float] = FREQUENCY_BOUNDS, damping: tuple[float, float] = DAMPING_BOUNDS,
           starts: tuple[SprungModes, ...] = ()) -> list[ModeFit]:
    """The global search for the minimum of V: every pair of starting frequencies
    (:data:`SEARCH_FREQUENCIES`, one per mode) and damping ratio (:data:`SEARCH_DAMPING`)
    fitted with the frequencies held (:data:`SEARCH_COARSE_NFEV` evaluations), then the
    ``keep`` best, and any further ``starts`` (:class:`SprungModes`), refined with every
    parameter free (f and ζ within ``frequency``, ``damping``).  Returns the distinct refined
    optima, lowest V first."""
    n = par.n_free
    coarse = []
    held = np.ones(par.size, bool)
    held[6 + int(np.sum(par.shape))::2] = False                     # the frequencies
    for fs_ in itertools.product(frequencies, repeat=n):
        for z in SEARCH_DAMPING:
            st = start_modes(J_rigid, fs_, f_dominant, par.shape, z)
            coarse.append(fit_modes(par, st, x, noise, free=held, max_nfev=SEARCH_COARSE_NFEV, frequency=frequency,
                                    damping=damping))
    coarse.sort(key=lambda c: c.cost)
    out: list[ModeFit] = []
    for st, origin in [(c.modes, c.start) for c in coarse[:keep]] + [(m, tuple(m.frequency)) for m in starts]:
        r = fit_modes(par, st, x, noise, frequency=frequency, damping=damping)
        if np.isfinite(r.cost) and not any(np.max(np.abs(r.p - o.p)) < SAME_OPTIMUM for o in out):
            out.append(ModeFit(r.modes, r.p, r.cost, r.dof, r.jac, origin))
    out.sort(key=lambda c: c.cost)
    return out
