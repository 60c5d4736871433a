"""Errors in variables: the sensors' noise in the fit's *input*, measured and compensated.

The output-error fit (:mod:`rig_identification.estimation.identification`) predicts the band-passed gyro ``y`` from the
band-passed integrated moment ``u`` (``y = P u``, ``P = J⁻¹``).  It is unbiased for noise on
its output, but ``u`` is noisy too, and not only from the load cells: the moment is made
with the cable directions of the tracked pose, and the pose is the integrated gyro.  The
gyro's noise reaches the input (``u`` ⊃ −K ∫∫ n, K the rig's geometric stiffness) — the
rig is a closed loop, and least squares on it is biased (Söderström, *Errors-in-Variables
Methods in System Identification*, Springer 2018, ch. 5; Ljung 1999, §13.4 on closed-loop
data).  On an axis the body hardly turns the noise is a large share of the regressor and
the bias large: a damped random rig with the true damping in the model, Ixx +15 % at
σ 2.5 % (``bench/bench_noise_paths.py``).  Its size is not a second-order term that a
linear SIMEX extrapolation finds (that saw +9.7 %: the estimate is a rational function of
the noise variance once the output and input noise are correlated).

The compensation is bias-compensated least squares (BCLS; Söderström 2018 ch. 5;
Stefanski's corrected score): the normal equations of the fit

    Σ Xᵀ W X p = Σ Xᵀ W y        (X the regressor of the symmetric P's entries p)

carry the noise's second moments E[ΔXᵀ W ΔX] and E[ΔXᵀ W Δy], which are subtracted.
They are measured, not modelled: the whole chain (tracker, preprocessor, band-pass) is
re-run with fresh white noise at the recording's estimated levels (antithetic pairs,
:func:`~rig_identification.estimation.uncertainty.add_noise`), and ``½[u(s + m) − u(s − m)]`` is a realisation of the
first-order noise of the regressor — every path (gyro → pose → moment, load cells,
exciter) included, in the right proportions.  To first order in the noise the
compensated normal equations are unbiased; the realisations' finite number leaves an
uncertainty of the correction, which the jackknife over them measures.

Everything here is plain numpy on arrays; :mod:`rig_identification.estimation.identification` uses it in its fit.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ..model.parametrisation import basis, consistent_from_params, from_tensor, params_from_consistent, to_tensor

EIV_LIMIT = 0.5
"""Largest share of a direction of the regressor that may be noise: the eigenvalues of
``A⁻¹ N`` (A the fit's information, N the noise's part of it).  Beyond it the noise is as
large as the signal along that direction and the compensation's first-order correction
cannot be trusted: the entries along it are not determined (validation's check
``errors_in_variables``).  On the random rigs of bench_noise_paths: a share of 0.29 left
Ixx +0.45 % (σ 2.5 %) after compensation; one of 0.47 left +13 % (σ 5.6 %)."""

SPECTRUM_BINS = 4
"""Frequency bins over which :func:`second_order_covariance` averages the realisations'
cross-spectra: with K realisations the estimate has K × this many complex degrees of
freedom, and its own positive bias, 1/(degrees of freedom), is removed.  Wider groups average
away the peak of the input noise's spectrum at the band's low edge: on test_errors_in_variables'
closed loop (20 s), 8 bins gave the variances 0.80–0.89 of the Monte Carlo's, 4 bins
0.96–1.03, 1 bin 0.91–0.98 (the bias correction's Wishart moments then too coarse)."""

SHARE_CAP = 0.8
"""In the validation's sub-band and segment fits, a direction whose noise share exceeds this
has its compensation capped at it (a short piece of the record can be mostly noise along a
direction the whole record determines)."""
LEAK_SHARE = 0.99
""":func:`attenuation_leak` undoes at most this share: a direction whose input is all noise
(share ≥ 1 on near-parallel cables' roll and pitch) is undone 100×, which reaches every entry
the inverse couples to it and not Izz of a rig whose yaw the cables determine."""


@dataclass(frozen=True)
class NoiseRealisations:
    """First-order noise of one fitted segment's band-passed regressor and output, from K
    antithetic replays with fresh noise (module docstring).

    du (K, N, 3) N·m·s: ½[u(s + m_k) − u(s − m_k)], u the band-passed integrated moment
    about the CG, body axes; dy (K, N, 3) rad/s: the same for the band-passed gyro."""

    du: np.ndarray
    dy: np.ndarray

    @property
    def count(self) -> int:
        """K, the number of realisations."""
        return int(self.du.shape[0])

    def __post_init__(self) -> None:
        if self.du.shape != self.dy.shape or self.du.ndim != 3 or self.du.shape[2] != 3:
            raise ValueError(f"noise realisations: du {self.du.shape} and dy {self.dy.shape} must both be (K, N, 3)")


def antithetic_realisations(plus_u: list[np.ndarray], minus_u: list[np.ndarray], plus_y: list[np.ndarray],
                            minus_y: list[np.ndarray]) -> NoiseRealisations:
    """:class:`NoiseRealisations` from K antithetic pairs: ``plus_u[k]``, ``minus_u[k]`` (N,3)
    the band-passed integrated moment of the replay with noise +m_k and −m_k; ``plus_y``,
    ``minus_y`` the band-passed gyro of the same replays.  Raises ValueError for no pair or
    mismatched lengths."""
    if not plus_u or not (len(plus_u) == len(minus_u) == len(plus_y) == len(minus_y)):
        raise ValueError("noise realisations: need K ≥ 1 complete antithetic pairs")
    du = 0.5 * (np.asarray(plus_u, float) - np.asarray(minus_u, float))
    dy = 0.5 * (np.asarray(plus_y, float) - np.asarray(minus_y, float))
    return NoiseRealisations(du, dy)


def regressor(E: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(…, N, 3, 6) regressor of the symmetric tensor's entries: ``X[n, i, k] = (E_k u_n)_i``
    for the basis E (6,3,3) and u (…, N, 3), so that ``P u = X p``."""
    X: np.ndarray = np.einsum("kij,...nj->...nik", E, u)
    return X


@dataclass(frozen=True)
class NoiseMoments:
    """The noise's part of the fit's weighted normal equations, per realisation:
    xx (K,6,6) ΣΔXᵀWΔX and xy (K,6) ΣΔXᵀWΔy over one or more segments (W the per-axis
    weights of the fit, 1/σ_i²).  Their means are the compensation's; leaving one out gives
    the jackknife."""

    xx: np.ndarray
    xy: np.ndarray

    @property
    def count(self) -> int:
        return int(self.xx.shape[0])

    def mean(self, leave_out: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(N (6,6), n (6,)): the mean over the realisations (without ``leave_out``)."""
        keep = [k for k in range(self.count) if k != leave_out]
        return self.xx[keep].mean(0), self.xy[keep].mean(0)

    def __add__(self, other: "NoiseMoments") -> "NoiseMoments":
        return NoiseMoments(self.xx + other.xx, self.xy + other.xy)


def noise_moments(E: np.ndarray, noise: NoiseRealisations, weights: np.ndarray) -> NoiseMoments:
    """:class:`NoiseMoments` of one segment's realisations with per-axis weights (3,)."""
    dX = regressor(E, noise.du)                                     # (K,N,3,6)
    w = np.asarray(weights, float)
    return NoiseMoments(np.einsum("knip,i,kniq->kpq", dX, w, dX), np.einsum("knip,i,kni->kp", dX, w, noise.dy))


def quadratic_forms(E: np.ndarray, weights: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(6,6,6) symmetric matrices H_k with ``g_k = zᵀ H_k z`` for z = (Δu, Δy) (6,), where
    g = ΔXᵀ W (Δy − P Δu) (6,) is one sample's second-order term of the fit's normal equations
    (ΔX the regressor's noise, :func:`regressor`; W = diag(weights) (3,); P (3,3) J⁻¹ in
    1/(kg·m²); E the basis (6,3,3))."""
    w = np.asarray(weights, float)
    alpha = np.zeros((6, 3, 6))                        # (k, i, z): (E_k Δu)_i as a row on z
    alpha[:, :, :3] = E
    beta = np.concatenate([-np.asarray(P, float), np.eye(3)], axis=1)      # (i, z): (Δy − P Δu)_i
    B = np.einsum("i,kia,ib->kab", w, alpha, beta)
    H: np.ndarray = 0.5 * (B + np.transpose(B, (0, 2, 1)))
    return H


def second_order_covariance(noise: list[NoiseRealisations], weights: np.ndarray, P: np.ndarray,
                            bins: int = SPECTRUM_BINS) -> np.ndarray:
    """(6,6) covariance of the second-order noise term of the fit's normal equations,
    ``Σ_n ΔX_nᵀ W (Δy_n − P Δu_n)`` summed over the segments (units of b: (N·m·s)·(rad/s)/σ²).

    Its mean is what the compensation removes (:func:`compensate`); its realisation-to-
    realisation spread is not: the recording's own noise makes one realisation of it, which
    moves the compensated estimate by (A − N)⁻¹ times its deviation from the mean.  Where the
    noise is a sizeable share of the input this is of the order of the first-order σ (bench_any_rig's
    rig 28026, share 0.36: sd 39 kg·m² on Ixx of the least-squares fit's even part over 16
    noise draws, against a propagated σ of 34.5; ``bench_validation_null.py --first-order``).

    With z_n = (Δu_n, Δy_n) jointly Gaussian and stationary, each entry is a quadratic form
    Σ_n z_nᵀ H_k z_n (:func:`quadratic_forms`) and (Isserlis; in the frequency domain, the
    Fourier coefficients Z_f of distinct bins independent, circular Gaussian)

        Cov(Q_k, Q_l) = (4 / N²) Σ_{f > 0} tr(H_k S_f H_l S_f),   S_f = E[Z_f Z_fᴴ].

    S_f is estimated from the K realisations (:class:`NoiseRealisations`, each segment's),
    averaged over groups of ``bins`` neighbouring bins; the estimate's bias (1/ν) tr(H_k S) tr(H_l S)
    (ν = K·bins complex degrees of freedom, complex Wishart moments) is subtracted.
    noise: one realisation set per segment; weights (3,) the fit's per-axis weights 1/σ²;
    P (3,3) J⁻¹ at the estimate.  Raises ValueError for no realisation or a segment of fewer
    than 3 samples."""
    H = quadratic_forms(basis(), weights, P)
    V = np.zeros((6, 6))
    for nz in noise:
        z = np.concatenate([nz.du, nz.dy], axis=2)                  # (K, N, 6)
        K, N = z.shape[:2]
        Z = np.fft.rfft(z, axis=1)[:, 1:(N + 1) // 2]                # f > 0, Nyquist left out
        if K < 1 or Z.shape[1] < 1:
            raise ValueError(f"second-order covariance: {K} realisations of {N} samples are too few")
        b = min(bins, Z.shape[1])
        G = Z.shape[1] // b
        Z = Z[:, :G * b].reshape(K, G, b, 6)
        S = np.einsum("kgfa,kgfb->gab", Z, Z.conj()) / (K * b)       # (G,6,6) Hermitian, per group of bins
        HS = np.einsum("kab,gbc->kgac", H, S)                         # H_k S_g
        trace = np.einsum("kgaa->kg", HS).real                        # tr(H_k S_g)
        quad = b * (np.einsum("kgac,lgca->kl", HS, HS).real - trace @ trace.T / (K * b))
        V += 4.0 / N**2 * quad
    return 0.5 * (V + V.T)


def _shares(A: np.ndarray, N: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The generalized eigenproblem N v = λ A v through A's Cholesky factor L (A = L Lᵀ):
    (L, λ ascending (p,), W (p,p)) with the directions v = L⁻ᵀ W — each λ the share of its
    direction of the regressor that is noise.  Raises numpy.linalg.LinAlgError when A is not
    positive definite."""
    L = np.linalg.cholesky(0.5 * (A + A.T))
    S = np.linalg.solve(L, np.linalg.solve(L, 0.5 * (N + N.T)).T)
    ev, V = np.linalg.eigh(0.5 * (S + S.T))
    return L, ev, V


def noise_share(A: np.ndarray, N: np.ndarray) -> tuple[float, np.ndarray]:
    """The largest share of a direction of the regressor that is noise: the largest
    eigenvalue of the generalized problem N v = λ A v (A, N (p,p) symmetric, A positive
    definite), and its direction v (p,) in the parameters (unit norm).  Raises
    numpy.linalg.LinAlgError when A is not positive definite."""
    L, ev, V = _shares(A, N)
    v = np.linalg.solve(L.T, V[:, -1])
    return float(ev[-1]), v / np.linalg.norm(v)


def capped(A: np.ndarray, N: np.ndarray, cap: float = SHARE_CAP) -> np.ndarray:
    """N with every generalized eigenvalue of (N, A) clipped to [0, ``cap``]: ``A − N`` then
    keeps at least 1 − cap of A along every direction (positive definite)."""
    L, ev, V = _shares(A, N)
    S = (V * np.clip(ev, 0.0, cap)) @ V.T
    Nc: np.ndarray = L @ S @ L.T
    return Nc


def compensated_residual(A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The corrected quadratic cost pᵀAp − 2pᵀb (+ const) as a sum of squares for
    Levenberg–Marquardt: with A = C Cᵀ (Cholesky), ``ρ(p) = Cᵀ p − C⁻¹ b`` has ‖ρ‖² equal to
    it up to a constant.  Returns (Cᵀ (p,p), C⁻¹ b (p,)).  Raises numpy.linalg.LinAlgError
    when A is not positive definite (the noise dominates a direction)."""
    C = np.linalg.cholesky(0.5 * (A + A.T))
    return C.T, np.linalg.solve(C, b)


@dataclass(frozen=True)
class Compensation:
    """What the errors-in-variables compensation did to a fit
    (:func:`~rig_identification.estimation.identification.fit_segments`
    with noise realisations).

    share: the largest share of a regressor direction that is noise (:func:`noise_share`;
    dimensionless, 0–1); direction (6,) the tensor entries (KEYS order, unit norm) along
    which it lies; correction (6,) kg·m²: compensated minus least-squares entries;
    correction_std (6,) kg·m²: the jackknife σ of the compensated entries over the noise
    realisations (the finite number of replays); sensitivity (6,6): d(compensated entries) /
    d(least-squares entries) for the same noise (maps the least-squares covariance onto the
    compensated estimate); count: the realisations used; applied: False when the fit could
    not be compensated (the least-squares estimate kept, :func:`compensate`); leak (6,) kg·m²,
    only when not applied: the correction the compensation would have made
    (:func:`attenuation_leak`), how far the least-squares bias may reach every entry;
    second_order (6,6) kg²·m⁴, only when applied: the covariance of the compensated entries
    that the recording's own realisation of the second-order noise term causes
    (:func:`second_order_covariance` through (A − N)⁻¹ and δJ = −J δP J) — the compensation
    removes that term's mean, not its spread."""

    share: float
    direction: np.ndarray
    correction: np.ndarray
    correction_std: np.ndarray
    sensitivity: np.ndarray
    count: int
    applied: bool = True
    leak: np.ndarray | None = None
    second_order: np.ndarray | None = None

    @property
    def second_order_std(self) -> np.ndarray | None:
        """(6,) kg·m²: the σ per entry of :attr:`second_order`, or None without it."""
        if self.second_order is None:
            return None
        std: np.ndarray = np.sqrt(np.clip(np.diag(self.second_order), 0.0, None))
        return std


def _inverse_entries(j: np.ndarray) -> np.ndarray:
    return from_tensor(np.linalg.inv(to_tensor(j)))


def _inversion_jacobian(inverse: np.ndarray) -> np.ndarray:
    """(6,6) d(entries of X⁻¹) / d(entries of X) at the point whose inverse is ``inverse`` (3,3):
    columns from_tensor(−X⁻¹ E_k X⁻¹) (δ(X⁻¹) = −X⁻¹ δX X⁻¹)."""
    return np.array([from_tensor(-inverse @ Ek @ inverse) for Ek in basis()]).T


def attenuation_leak(j: np.ndarray, A: np.ndarray, N: np.ndarray) -> np.ndarray:
    """(6,) kg·m²: how far the least-squares bias reaches each entry of J when the fit cannot be
    compensated — J(p_c) − J(p̂), with p̂ = J⁻¹'s entries of the least-squares ``j`` (6,)
    kg·m² and p_c the same with the regression dilution undone along every generalized
    eigendirection of (N, A) (A (6,6) the normal matrix, N (6,6) the noise's moment in it):
    its coordinate divided by 1 − s, s that direction's noise share (Fuller 1987, *Measurement
    Error Models*, §1.1: the least-squares slope is attenuated by the reliability ratio 1 − s).
    The inverse J = P⁻¹ spreads a bias along one direction of P over every entry of J (a
    random 5-cable rig, share 0.997: Ixx 26× its value, and Izz, with 10⁻⁴ of the direction,
    13 kg·m² off at 4.75 σ).  A share is undone at most to :data:`LEAK_SHARE` (a direction all
    noise, share ≥ 1: its coordinate ×100 — bench_trust's 4-parallel rigs keep Izz, 0.09 and
    0.18 σ off, their roll and pitch entries reached far beyond the limit).  inf for every entry
    when the corrected tensor is not finite and positive definite.  Raises
    numpy.linalg.LinAlgError when A is not positive definite."""
    L, ev, V = _shares(A, N)
    p = _inverse_entries(j)
    c = V.T @ (L.T @ p)                      # p = L⁻ᵀ V c
    pc = np.linalg.solve(L.T, V @ (c / (1.0 - np.minimum(ev, LEAK_SHARE))))
    P = to_tensor(pc)
    if not (np.all(np.isfinite(P)) and np.all(np.linalg.eigvalsh(0.5 * (P + P.T)) > 0)):
        return np.full(6, np.inf)
    leak: np.ndarray = from_tensor(np.linalg.inv(P)) - np.asarray(j, float)
    return leak


def compensate(segs: list[Any], j: np.ndarray, sigma: np.ndarray, noise: list[NoiseRealisations],
               consistent: bool = True) -> tuple[np.ndarray, Compensation, list[str]]:
    """Bias-compensated least squares (:mod:`rig_identification.estimation.errors_in_variables`): the weighted normal
    equations of the fit in P = J⁻¹'s entries, less the noise's second moments measured by
    the realisations, solved on the physically consistent parametrisation (Levenberg–
    Marquardt on the corrected quadratic cost) when ``consistent``, directly otherwise.

    segs: the prepared segments (:class:`~rig_identification.estimation.identification.Segment`: y (N,3) the band-passed
    gyro, IM (N,3) the band-passed integrated moment, G (6,N,3) the gyroscopic regressors); j (6,)
    kg·m² the least-squares estimate (start, and where
    the gyroscopic term is evaluated); sigma (3,) rad/s the fit's per-axis residual scale
    (weights 1/σ²); noise: one realisation set per segment.  Returns (entries (6,) kg·m²,
    :class:`~rig_identification.estimation.errors_in_variables.Compensation`, warnings); when the noise's share of some
    direction is beyond :data:`EIV_LIMIT`, or the corrected normal equations are not positive
    definite (a jackknife subset, the gyroscopic term re-evaluated), the least-squares j is
    returned with a warning (the correction zero, its σ NaN) and the validation reports the
    direction's entries as not determined."""
    E = basis()
    w = 1.0 / np.asarray(sigma, float) ** 2
    mom = sum((noise_moments(E, nz, w) for nz in noise[1:]), noise_moments(E, noise[0], w))
    j_ls = np.asarray(j, float).copy()

    def normal(jj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        A, b = np.zeros((6, 6)), np.zeros(6)
        for s in segs:
            X = regressor(E, s.IM - np.einsum("m,mni->ni", jj, s.G))   # (N,3,6), gyroscopic term at jj
            A += np.einsum("nip,i,niq->pq", X, w, X)
            b += np.einsum("nip,i,ni->p", X, w, s.y)
        return A, b

    def solve(A: np.ndarray, b: np.ndarray, N: np.ndarray, n: np.ndarray, start: np.ndarray) -> np.ndarray:
        if not consistent:
            return from_tensor(np.linalg.inv(to_tensor(np.linalg.solve(A - N, b - n))))
        CT, c = compensated_residual(A - N, b - n)

        def fun(th: np.ndarray) -> np.ndarray:
            r: np.ndarray = CT @ _inverse_entries(consistent_from_params(th)[0]) - c
            return r

        def jac(th: np.ndarray) -> np.ndarray:
            jj, dj = consistent_from_params(th)
            d: np.ndarray = CT @ _inversion_jacobian(np.linalg.inv(to_tensor(jj))) @ dj
            return d

        sol = least_squares(fun, params_from_consistent(to_tensor(start)), jac=jac, method="lm",
                            xtol=1e-12, ftol=1e-12)
        return consistent_from_params(sol.x)[0]

    A, b = normal(j_ls)
    N, n = mom.mean()
    try:
        share, v = noise_share(A, N)
    except np.linalg.LinAlgError:
        share, v = float("inf"), np.zeros(6)
    direction = _direction_entries(j_ls, v)

    def kept(why: str) -> tuple[np.ndarray, Compensation, list[str]]:
        try:
            leak = attenuation_leak(j_ls, A, N)
        except np.linalg.LinAlgError:
            leak = np.full(6, np.inf)
        comp = Compensation(share, direction, np.zeros(6), np.full(6, np.nan), np.eye(6), mom.count, False, leak)
        return j_ls, comp, [f"the noise makes {100 * min(share, 9.99):.3g} % of the fit's input along one direction "
                            f"({why}): the fit is not compensated for it (errors in variables); the least-squares "
                            "estimate is kept, biased along that direction, whose entries are not determined"]

    if not share <= EIV_LIMIT:
        # beyond the limit the first-order compensation is no better than least squares (and near
        # a share of 1 it divides by almost nothing): the direction is reported undetermined
        return kept(f"beyond {100 * EIV_LIMIT:g} %")
    try:
        jc = j_ls
        for _ in range(2):                  # the gyroscopic term re-evaluated at the compensated tensor
            jc = solve(A, b, N, n, jc)
            A, b = normal(jc)
        # jackknife over the realisations: the correction's own uncertainty
        K = mom.count
        if K >= 2:
            loo = np.array([solve(A, b, *mom.mean(leave_out=k), jc) for k in range(K)])
            cstd = np.sqrt((K - 1) / K * np.sum((loo - loo.mean(0)) ** 2, axis=0))
        else:
            cstd = np.full(6, np.nan)
        # first order: the same noise moves p_ls by A⁻¹δb and p_c by (A − N)⁻¹δb
        M = np.linalg.solve(A - N, A)
        Jc = to_tensor(jc)
        D = _inversion_jacobian(Jc)                    # δj = D δp at the compensated tensor
        G = D @ M @ _inversion_jacobian(np.linalg.inv(to_tensor(j_ls)))
        # the recording's own second-order noise term about its mean: δp = (A − N)⁻¹ δg
        Ai = np.linalg.inv(A - N)
        C2 = D @ Ai @ second_order_covariance(noise, w, np.linalg.inv(Jc)) @ Ai @ D.T
    except np.linalg.LinAlgError:
        # a realisation left out (the jackknife) or the gyroscopic term re-evaluated can leave the
        # corrected information indefinite: the noise is too large a share to compensate
        return kept("the corrected normal equations are not positive definite")
    if not (np.all(np.isfinite(jc)) and np.all(np.isfinite(G)) and np.all(np.isfinite(C2))):
        return kept("the compensated fit is not finite")
    return jc, Compensation(share, direction, jc - j_ls, cstd, G, K, second_order=0.5 * (C2 + C2.T)), []


def _direction_entries(j: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A direction v (6,) in P = J⁻¹'s entries as the direction of J's entries it moves
    (δJ = −J δP J), unit norm."""
    d = from_tensor(-to_tensor(j) @ to_tensor(v) @ to_tensor(j)) if np.all(np.isfinite(v)) else np.zeros(6)
    nrm = np.linalg.norm(d)
    return d / nrm if nrm > 0 else d
