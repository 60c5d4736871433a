"""The rigid-body model of a diagnosis window, extended by effect columns (see
:mod:`~rig_identification.diagnosis.selection` for the method as a whole).

:class:`Window`: everything a diagnosis needs on the IMU stamps of its window — the
cleaned sensors, the tracked pose (the same cleaning, tracker and yaw anchoring as
``rig-identify inertia``), the generalized wrench's parts.  :class:`Model`: its band-passed
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
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt, welch
from scipy.spatial.transform import Rotation

from ..estimation.signals import auto_band, cumulative_integral, step_indices
from ..model.parametrisation import basis, consistent_from_params, params_from_consistent, to_tensor
from ..estimation.quality import check_motion, check_units, clean_sensors
from ..io.recording import Recording, RecordingError
from ..estimation.tracker_replay import pass_compliance, replay
from ..estimation.yaw_anchor import anchor_yaw

ALPHA_LP = 3.0        # angular acceleration: gyro low-passed at this multiple of the band's upper edge
GRAM_RCOND = 1e-7     # relative singular value below which a combination of effect columns is not fitted
DCM_FLOOR = 2.0       # N·m: systematic floor of the mean-moment residual (pose and lever-arm errors)
WEIGHT_SIGMA = 5e-4   # relative σ of the load cells' mean vertical force against rig.yaml's weight:
                      # the cells' calibration (class C3 cells: 0.02–0.05 % of their load)
ROT, TR = ("gyro_x", "gyro_y", "gyro_z"), ("accel_x", "accel_y", "accel_z")
GRAM_HADAMARD = 1e-6   # det / product of the diagonal of the cables' wrench Gram matrix below which it is near-singular
WRENCH_SCALE = np.array([1, 1, 1, 1 / 1.5, 1 / 1.5, 1 / 1.5])   # force N vs torque N·m over ~1.5 m


# --- data ---------------------------------------------------------------------------------

@dataclass
class Window:
    """Everything the diagnosis needs, on the IMU stamps of the window (N samples).

    t (N,) s; omega (N,3) rad/s body axes (gyro); f (N,3) m/s² specific force at the IMU,
    body axes; R (N,3,3) body -> world; v (N,3) CG velocity, body axes, m/s;
    tensions (N,n) N; u (N,n,3) cable directions, body axes; r_cables (n,3) body anchors
    − CG, m; f_exc (N,3) exciter force, body axes, N; r_exc (3,) exciter − CG, m;
    rho (3,) IMU − CG, m; mass kg; g m/s²; imu_rot (3,3) IMU -> body.
    """

    t: np.ndarray
    omega: np.ndarray
    f: np.ndarray
    R: np.ndarray
    v: np.ndarray
    tensions: np.ndarray
    u: np.ndarray
    r_cables: np.ndarray
    f_exc: np.ndarray
    r_exc: np.ndarray
    rho: np.ndarray
    mass: float
    g: float
    imu_rot: np.ndarray
    cable_names: list
    exc_rot: np.ndarray = field(default_factory=lambda: np.eye(3))
    imu_rot_yaml: np.ndarray = field(default_factory=lambda: np.eye(3))   # rig.yaml's IMU -> body
    stiffness: np.ndarray | None = None     # cable stiffness the pose was tracked with, N/m (inf: rigid)
    stiffness_std: float | None = None      # std of the fitted stiffness (tracker's compliance fit), N/m
    sensors: object = None       # the cleaned SensorData (for exact re-alignment of a stream)
    shifts: dict = field(default_factory=dict)   # stream -> delay applied, s

    def shifted(self, stream: str, delay: float) -> "Window":
        """A copy with ``stream`` (load_cells | exciter) re-sampled at t + delay: the stream's
        stamps lag by ``delay`` s (linear interpolation of the cleaned samples)."""
        s = self.sensors
        tq = self.t + delay
        if stream == "load_cells":
            T = np.column_stack([np.interp(tq, s.load_cells[n].t, s.load_cells[n].data[:, 0]) for n in self.cable_names])
            return _replace(self, tensions=T, shifts={**self.shifts, stream: delay})
        if stream == "exciter":
            fe = s.exciter.interp(tq) @ self.exc_rot[:, :2].T
            return _replace(self, f_exc=fe, shifts={**self.shifts, stream: delay})
        raise ValueError(f"cannot re-align stream {stream!r}")

    @property
    def cable_force(self) -> np.ndarray:
        return self.tensions[:, :, None] * self.u

    @property
    def force(self) -> np.ndarray:
        return self.cable_force.sum(1) + self.f_exc

    @property
    def cable_moment(self) -> np.ndarray:
        return np.cross(self.r_cables[None], self.cable_force)       # (N,n,3)

    @property
    def torque(self) -> np.ndarray:
        return self.cable_moment.sum(1) + np.cross(self.r_exc, self.f_exc)

    @property
    def g_body(self) -> np.ndarray:
        return -self.g * self.R[:, 2, :]                               # Rᵀ (0,0,-g)

    @cached_property
    def tension_map(self) -> np.ndarray:
        """(N,n,6): per sample, the least-squares (minimum-norm) tension corrections δT (N)
        of the generalized wrench (force N, torque N·m, the torque over ~1.5 m:
        :data:`WRENCH_SCALE`), ``δT = pinv(Wᵀ) s·(F, M)`` with W's rows the cables' unit wrench
        (u_i, r_i × u_i) in body axes.  It depends on the pose only, not on any fit: computed
        once per window and kept (a copy made by :meth:`shifted` computes its own).  With at
        most six cables, ``pinv(Wᵀ) = (W Wᵀ)⁻¹ W`` (full rank: the normal equations, one
        batched solve); numpy ``pinv`` (an SVD per sample) where W Wᵀ is near-singular (its
        determinant below :data:`GRAM_HADAMARD` of its diagonal's product) or there are more
        cables than wrench components."""
        W = np.concatenate([self.u, np.cross(self.r_cables[None], self.u)], axis=2) * WRENCH_SCALE   # (N,n,6)
        if W.shape[1] > 6:
            return np.linalg.pinv(np.transpose(W, (0, 2, 1)))
        G = W @ np.transpose(W, (0, 2, 1))                                   # (N,n,n)
        weak = np.linalg.det(G) <= GRAM_HADAMARD * np.prod(np.diagonal(G, axis1=1, axis2=2), axis=1)
        out = np.empty_like(W)
        if weak.any():
            out[weak] = np.linalg.pinv(np.transpose(W[weak], (0, 2, 1)))
        if not weak.all():
            out[~weak] = np.linalg.solve(G[~weak], W[~weak])
        return out


def _track(rig, s, cables: str):
    """Tracked poses and the cable stiffness used (N,) N/m.  cables: ``"declared"``: the
    rig.yaml stiffness, fitted by the tracker where rig.yaml gives none (as
    :func:`~rig_identification.estimation.tracker_replay.track`); ``"rigid"``: inextensible where rig.yaml
    gives none; ``"fitted"``: fitted for every cable, whatever rig.yaml says."""

    if cables == "fitted":
        rig = _replace(rig, cables=tuple(_replace(c, stiffness=None) for c in rig.cables))
    known = np.isfinite(rig.cable_stiffness)
    if known.all() or cables == "rigid":
        rig_t = _replace(rig, cables=tuple(c if c.stiffness is not None else _replace(c, stiffness=1e15) for c in rig.cables))
        out, _ = replay(rig_t, s)
        return out, np.where(known, rig.cable_stiffness, np.inf), None
    out, tracker = replay(rig, s)
    hist = tracker.compliance_history
    if not hist:
        return out, np.where(known, rig.cable_stiffness, np.inf), None
    H = np.array([h[1] for h in hist[len(hist) // 2:]])
    c_ls = pass_compliance(tracker, out)
    c = np.median(H, axis=0) if c_ls is None else np.where(known, H[0], c_ls)
    # the tracker's updates are ~2 s apart, over a ~60 s forgetting horizon: ~30 updates per
    # independent estimate
    c_std = np.std(H, axis=0) / np.sqrt(max(1.0, len(H) / 30.0)) / np.sqrt(max(1, (~known).sum()))
    k = np.where(known, rig.cable_stiffness, 1.0 / np.maximum(c, 1e-12))
    rig_t = _replace(rig, cables=tuple(_replace(cb, stiffness=float(ki)) for cb, ki in zip(rig.cables, k)))
    out, _ = replay(rig_t, s)
    k_std = float(np.median(k[~known]) ** 2 * np.median(c_std[~known]))
    return out, k, k_std


ANCHOR_TURNS = 4      # at most this many turns of the yaw anchor (diagnosis trials: see anchored)
ANCHOR_CONVERGED = 2e-3   # rad: a turn this small leaves a linearisation error of ~1e-6 rad, no further turn


def anchored(rig, poses, s, lo: float, hi: float):
    """The poses with the yaw anchored by the moment balance over [lo, hi], as every fit's
    replay (:func:`~rig_identification.estimation.yaw_anchor.anchor_yaw`) — and, where the
    balance asks for a turn beyond :data:`ANCHOR_CONVERGED` (the anchor's one linearised step
    then leaves ~1 mrad) or beyond its ``MAX_OFFSET`` (which it leaves alone), turned and
    anchored again (at most :data:`ANCHOR_TURNS` turns).  A diagnosis trial of a data error can ask
    for it: where the cable lengths leave the yaw free, the tracker's initial pose at rest
    takes the yaw from the moment balance of the tensions, so a load cell's gain 0.4 % off
    turned it by 35–80 mrad on a random 4-cable rig; the pipeline's anchor leaves a turn
    beyond 50 mrad alone (not a tracker's starting error), and the trial's fit was then
    wrecked (its likelihood ratio −10⁷ beside +1.8·10⁴ 0.2 % away), and a 35 mrad turn left
    ~1 mrad, enough to move the fit's cost by thousands: the exact profile of the gain had
    holes and steps that hid the right cell and value."""
    for _ in range(ANCHOR_TURNS):
        poses, a = anchor_yaw(rig, poses, s, lo, hi)
        if not np.isfinite(a.offset):
            break
        if not a.applied:
            poses = turned(rig, poses, a.offset)
        if abs(a.offset) <= ANCHOR_CONVERGED:
            break
    return poses


def turned(rig, track, psi: float):
    """``track`` turned by ψ rad about the vertical through the centre of gravity (attitude
    and the body origin's position; the CG's position and the velocities unchanged), as
    :func:`~rig_identification.estimation.yaw_anchor.anchor_yaw` turns it."""
    cg = rig.require_cg()
    Rz = Rotation.from_rotvec([0.0, 0.0, psi])
    R_all = Rotation.from_quat(track.quaternion)
    cg_w = track.position + R_all.apply(cg)
    R_new = Rz * R_all
    return _replace(track, position=cg_w - R_new.apply(cg), quaternion=R_new.as_quat())


def prepare_window(rec: Recording, settle: float = 5.0, warnings: list | None = None,
                   cables: str = "declared", imu_rot_yaml: np.ndarray | None = None) -> Window:
    """Clean the recording, track the pose and collect the :class:`Window` (the same
    cleaning and tracker as ``rig-identify inertia``; ``cables`` as :func:`_track`).
    Raises RecordingError, RigError, TrackerError."""
    rig = rec.rig
    cg = rig.require_cg()
    if rig.exciter is not None and rec.sensors.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no /rig/exciter/wrench topic")
    check_units(rec)
    warnings = [] if warnings is None else warnings
    s = clean_sensors(rec, warnings)
    check_motion(rec, s)
    poses, stiffness, stiffness_std = _track(rig, s, cables)
    lo = max([c.t[0] for c in s.load_cells.values()] + ([s.exciter.t[0]] if s.exciter is not None else []))
    hi = min([c.t[-1] for c in s.load_cells.values()] + ([s.exciter.t[-1]] if s.exciter is not None else []))
    lo = max(lo, s.t_start + min(settle, 0.1 * (s.t_end - s.t_start)))
    poses = anchored(rig, poses, s, lo, hi)
    m = (poses.t >= lo) & (poses.t <= hi)
    t = poses.t[m]
    R = Rotation.from_quat(poses.quaternion[m]).as_matrix()
    imu = s.imu.interp(t)
    Rimu = rig.imu.rotation.as_matrix()
    omega, f = imu[:, :3] @ Rimu.T, imu[:, 3:] @ Rimu.T
    T = np.column_stack([np.interp(t, s.load_cells[n].t, s.load_cells[n].data[:, 0]) for n in rig.cable_names])
    rel = np.einsum("mji,mnj->mni", R, rig.ceiling_anchors[None] - poses.position[m][:, None]) - rig.body_anchors[None]
    u = rel / np.linalg.norm(rel, axis=2)[:, :, None]
    if rig.exciter is not None and s.exciter is not None:
        f_exc = s.exciter.interp(t) @ rig.exciter.rotation.as_matrix()[:, :2].T
        r_exc = rig.exciter.position - cg
    else:
        f_exc, r_exc = np.zeros((len(t), 3)), np.zeros(3)
    v_world = poses.velocity[m] + np.einsum("nij,nj->ni", R, np.cross(omega, cg))
    v = np.einsum("nji,nj->ni", R, v_world)
    return Window(t, omega, f, R, v, T, u, rig.body_anchors - cg, f_exc, r_exc, rig.imu.position - cg,
                  rig.mass, rig.gravity, Rimu, list(rig.cable_names),
                  rig.exciter.rotation.as_matrix() if rig.exciter is not None else np.eye(3), sensors=s,
                  imu_rot_yaml=Rimu if imu_rot_yaml is None else imu_rot_yaml, stiffness=stiffness,
                  stiffness_std=stiffness_std)


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
        sg = white_sigma(w.omega, fs)
        sa = white_sigma(w.f, fs)
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


def white_sigma(x: np.ndarray, fs: float) -> float:
    f, P = welch(x, fs=fs, nperseg=min(len(x), 1024), axis=0)
    return float(np.sqrt(np.median(P[f > fs / 4].mean(1)) * fs / 2))


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
