"""The rigid-body model of a diagnosis window, extended by effect columns (see
:mod:`~rig_identification.diagnosis.selection` for the method as a whole).

:class:`~rig_identification.diagnosis.window.Window` (its own module): everything a
diagnosis needs on the IMU stamps of its window.  :class:`Model`: its band-passed
residual groups — the rotational output error ``y = F ω`` vs ``ŷ = F P ∫(M − ω × Jω)``
(as the identifier), the translational (the accelerometer vs Newton's law at the IMU) and
the mean levels (mean gyro vs the net rotation, mean specific force, mean moment, and the
load cells' mean vertical force vs rig.yaml's weight, σ :data:`WEIGHT_SIGMA`) — and
:func:`fit_model`: the tensor fitted jointly with effect columns that are linear in their
parameters (:class:`Column`), by variable projection (Levenberg–Marquardt, scipy
``least_squares``, on the physically consistent log-Cholesky parameters), each group
weighted per axis by its residual scale and effective sample count, so that the cost is
−2 log L up to a constant; σ of the columns: the sandwich (batch-means) covariance.

Reference: Ljung, *System Identification* (2nd ed., 1999), §16.4–16.6.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from dataclasses import replace as _replace

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from ..estimation.signals import auto_band, cumulative_integral, step_indices
from ..io.noise import white_sigma
from ..model.parametrisation import basis, consistent_from_params, params_from_consistent, to_tensor
from .window import Window

ALPHA_LP = 3.0        # angular acceleration: gyro low-passed at this multiple of the band's upper edge
GRAM_RCOND = 1e-7     # relative singular value below which a combination of effect columns is not fitted
DCM_FLOOR = 2.0       # N·m: systematic floor of the mean-moment residual (pose and lever-arm errors)
WEIGHT_SIGMA = 5e-4   # relative σ of the load cells' mean vertical force against rig.yaml's weight:
                      # the cells' calibration (class C3 cells: 0.02–0.05 % of their load)
ROT, TR = ("gyro_x", "gyro_y", "gyro_z"), ("accel_x", "accel_y", "accel_z")


# --- the extended model ---------------------------------------------------------------------

@dataclass
class Column:
    """One linear parameter of an effect: its contributions to the model (see module doc).

    rot_D (N,3): moment added to the Euler equation per unit parameter, N·m, body;
    rot_O (N,3): correction added to the band-passed measured ω (already filtered);
    tr_D (N,3): specific force added to Newton's prediction, m/s², body;
    tr_O (N,3): correction added to the band-passed measured specific force (filtered);
    dcg (3,), dca (3,): change of the mean-level residuals per unit parameter.
    """

    name: str
    rot_D: np.ndarray | None = None
    rot_O: np.ndarray | None = None
    tr_D: np.ndarray | None = None
    tr_O: np.ndarray | None = None
    dcg: np.ndarray | None = None
    dca: np.ndarray | None = None


@dataclass
class Candidate:
    """An effect hypothesis: ``name`` (effects.EFFECT_NAMES), its columns, and how to turn
    the fitted column values (and covariance) into the effect's reported parameters."""

    name: str
    columns: list
    report: callable
    label: str = ""
    gyroscopic: bool = False     # frees the scale of ω × Jω instead of adding columns
    stream: str | None = None    # sensor_delay: the stream, re-aligned exactly once selected
    exact: bool = False          # a sensor or rig error: once selected, the data are corrected and re-tracked

    @property
    def key(self) -> tuple:
        return (self.name, self.label)


class Model:
    """The band-passed model terms of one window (precomputed), evaluated for a tensor,
    a gyroscopic scale and effect columns."""

    def __init__(self, w: Window, band: tuple[float, float] | None = None):
        self.w = w
        t = w.t
        dt = np.diff(t)
        self.fs = fs = 1.0 / float(np.median(dt))
        if band is None:
            lo, hi = auto_band(w.omega, fs)
            lo = max(lo, 2.0 / (t[-1] - t[0]))
        else:
            lo, hi = band
        self.band = (lo, min(hi, 0.4 * fs))
        self.sos = butter(4, list(self.band), btype="bandpass", fs=fs, output="sos")
        self.n_eff = max(10.0, len(t) * 2 * (self.band[1] - self.band[0]) / fs)
        self.n_eff_group: dict = {}   # per residual group, from the baseline fit (effective_samples)
        self.y = self.filt(w.omega)
        self.steps = step_indices(w.torque)   # stepped inputs: integrated without interpolation across them
        self.IM = self.integ(w.torque)
        self.G = np.stack([self.integ(np.cross(w.omega, w.omega @ Em.T)) for Em in basis()])
        # angular acceleration from the gyro low-passed at ALPHA_LP × the band's upper edge:
        # the derivative of the raw gyro noise (×ρ) would swamp the accelerometer's own
        # noise, and a cut-off at the edge itself (−3 dB there, −2 % of α in the band, then
        # band-passed again) left an in-band error of α × ρ that looked like an IMU offset
        # of ~8 mm on clean recordings and biased a load cell's gain by 15–25 %
        lp = butter(4, min(ALPHA_LP * self.band[1], 0.4 * fs), fs=fs, output="sos")
        self.alpha = np.gradient(sosfiltfilt(lp, w.omega, axis=0), t, axis=0)
        a_rel = np.cross(self.alpha, w.rho) + np.cross(w.omega, np.cross(w.omega, w.rho))
        newton = w.force / w.mass + a_rel
        self.ya = self.filt(w.f)
        self.A = self.filt(newton)
        T = t[-1] - t[0]
        net = Rotation.from_matrix(w.R[0].T @ w.R[-1]).as_rotvec()
        self.dcg0 = w.omega.mean(0) - w.R[0].T @ w.R[0] @ net / T
        self.dca0 = (w.f - newton).mean(0)
        # mean moment: over the window, J mean(ω̇) + mean(ω × Jω) = mean(M)
        self.dcm_M = w.torque.mean(0)
        self.dcm_G = np.stack([np.cross(w.omega, w.omega @ Em.T).mean(0) for Em in basis()])   # (6,3)
        self.dcm_W = (w.omega[-1] - w.omega[0]) / T
        n = len(t)
        sg = white_sigma(w.omega)
        sa = white_sigma(w.f)
        self.sigma_dcg = np.sqrt((sg / np.sqrt(n)) ** 2 + 1e-4 ** 2)
        self.sigma_dca = np.sqrt((sa / np.sqrt(n)) ** 2 + 2e-3 ** 2)
        self.sigma_dcm = DCM_FLOOR
        # weight: the cells' (and exciter's) mean vertical force, world axes, against rig.yaml's
        # m g plus the mean vertical acceleration (Newton's second law over the window), in
        # σ of the cells' calibration.  The accelerometer does not enter it: a body heavier than
        # rig.yaml says, or cables hanging on it, fail it; an accelerometer bias does not
        fz = np.einsum("nj,nj->n", w.R[:, 2, :], w.force)
        vz = np.einsum("j,j->", w.R[-1, 2, :], w.v[-1]) - np.einsum("j,j->", w.R[0, 2, :], w.v[0])
        self.dcw = float((fz.mean() / w.mass - w.g - vz / T) / (WEIGHT_SIGMA * w.g))

    def filt(self, x):
        return sosfiltfilt(self.sos, x, axis=0)

    def integ(self, x):
        return self.filt(cumulative_integral(x, self.w.t, self.steps))

    # rot residual: y + Σβ O − P (IM − κ G j + Σβ I(D))
    def residuals(self, j, kappa, beta, cols, prepared):
        P = np.linalg.inv(to_tensor(j))
        u = self.IM - kappa * np.einsum("m,mni->ni", j, self.G)
        yc = self.y.copy()
        ya = self.ya.copy()
        A = self.A.copy()
        dcg = self.dcg0.copy()
        dca = self.dca0.copy()
        Jt = to_tensor(j)
        dcm = self.dcm_M - kappa * j @ self.dcm_G - Jt @ self.dcm_W
        for b, c, p in zip(beta, cols, prepared):
            if p["rot_ID"] is not None:
                u = u + b * p["rot_ID"]
                dcm = dcm + b * p["rot_mean"]
            if c.rot_O is not None:
                yc = yc + b * c.rot_O
            if p["tr_FD"] is not None:
                A = A + b * p["tr_FD"]
            if c.tr_O is not None:
                ya = ya + b * c.tr_O
            if c.dcg is not None:
                dcg = dcg + b * c.dcg
            if c.dca is not None:
                dca = dca + b * c.dca
        yhat = u @ P.T
        return yc - yhat, ya - A, dcg, dca, dcm, P, yhat, u

    def prepare(self, cols):
        return [{"rot_ID": None if c.rot_D is None else self.integ(c.rot_D),
                 "rot_mean": None if c.rot_D is None else c.rot_D.mean(0),
                 "tr_FD": None if c.tr_D is None else self.filt(c.tr_D)} for c in cols]


@dataclass
class Fit:
    """A fitted model: tensor (3,3), gyroscopic scale, effect column values and covariance,
    residuals per group, RMS per channel."""

    J: np.ndarray
    kappa: float
    beta: np.ndarray
    cov: np.ndarray            # (6 + k (+1)) covariance: tensor entries, columns, [kappa]
    rot: np.ndarray
    tr: np.ndarray
    dcg: np.ndarray
    dca: np.ndarray
    dcm: np.ndarray
    yhat: np.ndarray
    u: np.ndarray
    cols: list = field(default_factory=list)
    free_kappa: bool = False
    dcw: float = 0.0           # the weight's mean-level residual in its σ (Model.dcw)

    def cost(self, scales) -> dict:
        """Per-group residual sums of squares in units of the baseline scales."""
        sr, sa, sg, sa_dc, sm = scales
        return {"rot": float(np.sum((self.rot / sr) ** 2)), "tr": float(np.sum((self.tr / sa) ** 2)),
                "dcg": float(np.sum((self.dcg / sg) ** 2)), "dca": float(np.sum((self.dca / sa_dc) ** 2)),
                "dcm": float(np.sum((self.dcm / sm) ** 2)), "dcw": self.dcw ** 2}


class _Compressed:
    """The band-passed arrays of a :class:`Model` and of a fit's columns with their sample
    rows compressed (see :func:`fit_model`): each group's arrays (N,3) side by side are
    F = Q R (thin QR, numpy ``qr``), and each is replaced by its block of R (p,3), p the
    group's number of columns.  Any linear combination ``F X`` then has ``‖F X‖ = ‖R X‖``
    and the same inner products, so the least-squares cost, its gradient and the
    Gauss–Newton matrix of the fit are unchanged — over p rows instead of N."""

    residuals = Model.residuals

    def __init__(self, model: Model, cols: list, prepared: list):
        rot = [model.y, model.IM, *model.G] + [c.rot_O for c in cols if c.rot_O is not None] + \
              [p["rot_ID"] for p in prepared if p["rot_ID"] is not None]
        tr = [model.ya, model.A] + [c.tr_O for c in cols if c.tr_O is not None] + \
             [p["tr_FD"] for p in prepared if p["tr_FD"] is not None]
        rr = iter(np.split(np.linalg.qr(np.concatenate(rot, axis=1), mode="r"), len(rot), axis=1))
        ra = iter(np.split(np.linalg.qr(np.concatenate(tr, axis=1), mode="r"), len(tr), axis=1))
        self.y, self.IM = next(rr), next(rr)
        self.G = np.stack([next(rr) for _ in range(len(model.G))])
        self.ya, self.A = next(ra), next(ra)
        rot_O = [next(rr) if c.rot_O is not None else None for c in cols]
        tr_O = [next(ra) if c.tr_O is not None else None for c in cols]
        self.prepared = [{"rot_ID": next(rr) if p["rot_ID"] is not None else None, "rot_mean": p["rot_mean"],
                          "tr_FD": next(ra) if p["tr_FD"] is not None else None} for p in prepared]
        self.cols = [_replace(c, rot_D=None, tr_D=None, rot_O=o, tr_O=a) for c, o, a in zip(cols, rot_O, tr_O)]
        for name in ("dcg0", "dca0", "dcm_M", "dcm_G", "dcm_W"):
            setattr(self, name, getattr(model, name))

    @staticmethod
    def worthwhile(model: Model, cols: list) -> bool:
        """Whether the compression has fewer rows than the samples (by a margin)."""
        p = 3 * (2 + len(model.G) + 2 * len(cols))
        return 4 * p < len(model.w.t)


def fit_model(model: Model, cols: list, kappa0: float, free_kappa: bool, scales, j0: np.ndarray,
              block_s: float = 4.0) -> Fit:
    """Levenberg–Marquardt fit (scipy ``least_squares``, analytic Jacobian) of the tensor
    (consistent parametrisation), the effect columns and optionally the gyroscopic scale
    κ.  Each group is weighted by its baseline scale and its effective sample count, so
    that the cost is −2 log L up to a constant (see module docstring).

    Every residual of a group is a linear combination of the same few band-passed arrays
    (N,3) — the measured ω, ∫M, the gyroscopic terms ∫ω × E_m ω, the columns' — with
    coefficients that depend on the parameters (the tensor's inverse among them).  The
    Levenberg–Marquardt iterations therefore run on those arrays' QR-compressed rows
    (:class:`_Compressed`: the cost, its gradient and Gauss–Newton matrix are the same over
    3p instead of 3N rows; Golub & Van Loan, *Matrix Computations*, 4th ed., §5.3, the QR
    solution of least squares); the residuals and the sandwich covariance, which need the
    samples, are evaluated on the N rows once, at the solution."""
    sr, sa, sg, sdc, sm = scales
    n = len(model.w.t)
    # per-axis weights (3,): the axes' residual scales differ (a weakly excited axis, a
    # pitch axis with more tracker error), and pooling them biases the tensor — the
    # identifier also weights per axis
    wr = np.broadcast_to(np.sqrt(model.n_eff / n) / np.asarray(sr, float), (3,))
    wa = np.broadcast_to(np.sqrt(model.n_eff / n) / np.asarray(sa, float), (3,))
    prepared = model.prepare(cols)
    k = len(cols)
    nlin = k + (1 if free_kappa else 0)
    E = basis()

    def unpack(x):
        j, dj = consistent_from_params(x[:6])
        beta = x[6:6 + k]
        kappa = x[6 + k] if free_kappa else kappa0
        return j, dj, beta, kappa

    def problem(src, cols, prepared):
        """The weighted residual and its Jacobians over the rows of ``src`` (the model, or
        its :class:`_Compressed` rows), as closures (fun, jac, full, fun_vp, jac_vp)."""
        nr, na = len(src.y), len(src.ya)
        nt = 3 * nr + 3 * na
        rows = nt + 9
        zeros = np.zeros((na, 3))
        # the parts of the Jacobian that do not depend on the parameters
        dTr = np.stack([(c.tr_O if c.tr_O is not None else zeros) - (p["tr_FD"] if p["tr_FD"] is not None else zeros)
                        for c, p in zip(cols, prepared)], axis=-1) if k else np.zeros((na, 3, 0))
        dG = np.array([c.dcg if c.dcg is not None else np.zeros(3) for c in cols]).T.reshape(3, k)
        dA = np.array([c.dca if c.dca is not None else np.zeros(3) for c in cols]).T.reshape(3, k)
        dMm = np.array([p["rot_mean"] if p["rot_mean"] is not None else np.zeros(3) for p in prepared]).T.reshape(3, k)

        def fun(x):
            j, _, beta, kappa = unpack(x)
            r, a, dg, da, dm, *_ = src.residuals(j, kappa, beta, cols, prepared)
            return np.concatenate([(r * wr).ravel(), (a * wa).ravel(), dg / sg, da / sdc, dm / sm])

        # the linear columns' parts that do not depend on the tensor, once (rows, nlin)
        Jl0 = np.zeros((rows, nlin))
        Jr0 = Jl0[:3 * nr].reshape(nr, 3, nlin)
        for i, c in enumerate(cols):
            if c.rot_O is not None:
                Jr0[:, :, i] = c.rot_O * wr
        Jl0[3 * nr:nt] = (dTr * wa[None, :, None]).reshape(-1, k) if k else 0.0
        Jd0 = Jl0[nt:]
        Jd0[:3, :k] = dG / sg
        Jd0[3:6, :k] = dA / sdc
        Jd0[6:, :k] = dMm / sm
        with_ID = [i for i, p in enumerate(prepared) if p["rot_ID"] is not None]

        def lin_jac(j, P):
            """Jacobian columns of the parameters the residual is linear in (β, κ): they
            depend on the tensor only, (rows, nlin)."""
            Jl = Jl0.copy()
            Jr = Jl[:3 * nr].reshape(nr, 3, nlin)
            for i in with_ID:
                Jr[:, :, i] -= (prepared[i]["rot_ID"] @ P.T) * wr
            if free_kappa:
                Jr[:, :, -1] = (np.einsum("m,mni->ni", j, src.G) @ P.T) * wr
                Jl[nt + 6:, -1] = -(j @ src.dcm_G) / sm
            return Jl

        def tensor_jac(dj, kappa, P, yhat):
            """Jacobian columns of the 6 tensor parameters, (rows, 6)."""
            Jt = np.zeros((rows, 6))
            M = (np.matmul(yhat, E.transpose(0, 2, 1)) + kappa * src.G) @ P.T     # (6, n, 3): P (E_m ŷ + κ G_m)
            Jt[:3 * nr] = ((M.transpose(1, 2, 0) * wr[None, :, None]).reshape(-1, 6) @ dj)
            E6 = np.stack([kappa * src.dcm_G[m] + E[m] @ src.dcm_W for m in range(6)], axis=1)   # (3,6)
            Jt[nt + 6:] = -(E6 @ dj) / sm
            return Jt

        def jac(x):
            j, dj, beta, kappa = unpack(x)
            _, _, _, _, _, P, yhat, _ = src.residuals(j, kappa, beta, cols, prepared)
            return np.concatenate([tensor_jac(dj, kappa, P, yhat), lin_jac(j, P)], axis=1)

        # variable projection (Golub & Pereyra 1973): the residual is linear in the effect
        # columns and in κ, so for each tensor they are solved by linear least squares and
        # Levenberg–Marquardt runs on the 6 tensor parameters alone, with Kaufman's
        # projected Jacobian (Kaufman, BIT 15, 1975)
        cache = {}

        def full(th):
            """(x, residual, tensor Jacobian, projector basis of the linear columns) at the
            tensor parameters th, with the linear parameters solved.  The basis is (A, G⁺) with
            G = AᵀA of the unit-norm columns A (their Gram matrix; its pseudo-inverse drops the
            directions below :data:`GRAM_RCOND` of the largest singular value): the projection
            A G⁺ Aᵀ costs O(rows × columns) instead of an SVD's basis of the rows."""
            key = th.tobytes()
            if key not in cache:
                x, U = np.r_[th, np.zeros(nlin)], None
                j, dj, _, _ = unpack(x)
                if nlin:
                    P = np.linalg.inv(to_tensor(j))
                    A = lin_jac(j, P)
                    norm = np.linalg.norm(A, axis=0)
                    norm = np.where(norm > 0, norm, 1.0)
                    As = A / norm
                    lam, V = np.linalg.eigh(As.T @ As)
                    keep = lam > max(lam[-1], 0.0) * GRAM_RCOND ** 2 if lam[-1] > 0 else np.zeros(len(lam), bool)
                    Ginv = (V[:, keep] / lam[keep]) @ V[:, keep].T
                    U = (As, Ginv)
                    b = -(Ginv @ (As.T @ fun(x))) / norm
                    x = np.r_[th, b]
                _, _, beta, kappa = unpack(x)
                r, a, dg, da, dm, P, yhat, _ = src.residuals(j, kappa, beta, cols, prepared)
                res = np.concatenate([(r * wr).ravel(), (a * wa).ravel(), dg / sg, da / sdc, dm / sm])
                cache.clear()
                cache[key] = (x, res, tensor_jac(dj, kappa, P, yhat), U)
            return cache[key]

        def fun_vp(th):
            return full(th)[1]

        def jac_vp(th):
            _, _, Jt, U = full(th)
            if U is None:
                return Jt
            As, Ginv = U
            return Jt - As @ (Ginv @ (As.T @ Jt))

        return jac, full, fun_vp, jac_vp

    if _Compressed.worthwhile(model, cols):
        small = _Compressed(model, cols, prepared)
        _, full_c, fun_vp, jac_vp = problem(small, small.cols, small.prepared)
    else:
        _, full_c, fun_vp, jac_vp = problem(model, cols, prepared)
    th0 = params_from_consistent(to_tensor(j0))
    sol = least_squares(fun_vp, th0, jac=jac_vp, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10,
                        max_nfev=200)
    x = full_c(sol.x)[0]
    jac, *_ = problem(model, cols, prepared)
    j, dj, beta, kappa = unpack(x)
    r, a, dg, da, dm, P, yhat, u = model.residuals(j, kappa, beta, cols, prepared)
    res = np.concatenate([(r * wr).ravel(), (a * wa).ravel(), dg / sg, da / sdc, dm / sm])
    # covariance of (tensor entries, beta, kappa): sandwich with batch means over time blocks
    T = np.eye(len(x))
    T[:6, :6] = np.linalg.pinv(dj)          # d theta / d entries
    A = jac(x) @ T                        # Jacobian with respect to (entries, beta, kappa)
    cov = _sandwich(A, res, n, 6, int(round(block_s * model.fs)))
    return Fit(to_tensor(j), float(kappa), np.asarray(beta, float), cov, r, a, dg, da, dm, yhat, u, cols,
               free_kappa, model.dcw)


def _sandwich(A: np.ndarray, res: np.ndarray, n: int, per_row: int, nb: int) -> np.ndarray:
    """Covariance (AᵀA)⁻¹ S (AᵀA)⁻¹ with S from batch means of the time rows (the first
    n·per_row rows, sample-major within each group of n·3 rows) plus the DC rows."""
    p = A.shape[1]
    bread = np.linalg.pinv(A.T @ A)
    n_time = n * per_row
    H = A[:n_time] * res[:n_time, None]
    # rows are [rot (n,3) ravel, tr (n,3) ravel]: within each group sorted by sample, so a
    # block of nb samples is a run of 3 nb rows, summed by reduceat (one pass, no scatter)
    nb = max(1, min(nb, n // 8))
    starts = np.arange(0, 3 * n, 3 * nb)
    S = sum(np.add.reduceat(Hg, starts, axis=0) for Hg in H.reshape(per_row // 3, 3 * n, p))
    meat = S.T @ S
    D = A[n_time:]
    meat += D.T @ D
    return bread @ meat @ bread
