"""Diagnosis: where a recording and the rigid-body model disagree, and which physics is missing.

The model (:mod:`~rig_identification.identification`) is the Newton–Euler equation of
a rigid body on cables, fed with the measured generalized wrench.  Three groups of
residuals test it, each on the recording's window, band-passed like the identifier
(zero-phase Butterworth, scipy ``sosfiltfilt``):

* **rotational** (gyro x, y, z): the band-limited output error of the integrated Euler
  equation, ``y = F ω`` vs ``ŷ = F P ∫(M − ω × Jω)``, as in the identifier;
* **translational** (accelerometer x, y, z): the measured specific force at the IMU vs
  Newton's law, ``F/m + α × ρ + ω × (ω × ρ)`` (ρ = IMU − CG, α = dω/dt), band-passed;
* **mean levels**: the mean gyro vs the net rotation over the window (the tracker's
  orientation), the mean specific force vs the mean F/m, the mean moment vs
  ``J mean(ω̇) + mean(ω × Jω)``, and the load cells' mean vertical force (world axes)
  vs rig.yaml's weight, m (g + mean vertical acceleration), with σ the cells' calibration
  (:data:`WEIGHT_SIGMA`): the one mean level the accelerometer does not enter, which tells
  a body heavier than rig.yaml says (or cables hanging on it) from an accelerometer bias.

Each candidate of the effect library (:mod:`~rig_identification.effects`) extends the
model by terms that are *linear in its parameters* (moment and force regressors,
output corrections, mean offsets; a sensor delay to first order, ``M(t − d) ≈ M − d Ṁ``),
so the extended model is fitted jointly with the tensor by variable projection: the
effect parameters by linear least squares for each tensor, Levenberg–Marquardt (scipy
``least_squares``) on the physically consistent log-Cholesky tensor parameters
(:func:`~rig_identification.identification.consistent_from_params`).

The wrench components (force, torque: the Newton–Euler equation errors, the torque with
the mean moment, which must vanish over a window) and each load cell (the tension
correction that best explains them, least squares) are channels too.

Each channel's residual RMS is reported twice: as it is, and time-synchronously averaged
over the exciter's revolutions (:func:`synchronous_rms`): the part locked to the forcing,
with the sensor noise averaged down by about √(revolutions).  A model error smaller than
the noise (the gyroscopic term at a planned excitation: under half the gyro noise in the
band) barely moves the plain RMS, but is most of the synchronous one.

Baseline: the rig.yaml taken literally, with the cables' stiffness from rig.yaml, or —
when it gives none — fitted by the tracker (steel cables stretch 1–2 mm; the reference
recordings need it).  ``cable_elasticity`` is a candidate when rig.yaml states a stiffness
(the tracker then re-fits it), or when the fitted static stretch exceeds
:data:`STEEL_STRETCH` (then against rigid cables).

Sensor and rig errors (``sensor_delay``, ``imu_offset``, ``imu_misalignment``, the biases,
``load_cell_scale``, ``body_mass``, ``cable_elasticity``) also move the tracked pose, which the first-order
columns do not see: the most promising of them (:data:`EXACT_SCREEN` per step) are
evaluated exactly — the error removed from the data (:func:`corrected`), the pose
re-tracked, the model refitted, Broyden iterations on the first-order remainder — and the
selected one is iterated to convergence.  A load cell's gain (one candidate per cable)
moves the tracker's static pose (it balances forces and moments with the tensions) so
much that its first-order column points the wrong way: every significant one is
evaluated exactly at ±:data:`GAIN_STEP` (:func:`_exact_screen`), and the selected one is
found by its exact profile likelihood (:func:`_exact_profile`).  So is ``cable_mass``,
always: the lower half of each cable (μ kg) hangs on its body anchor, outside the load
cell at the ceiling, so the body the tensions move is heavier, its centre of gravity
higher and its tensor larger than rig.yaml's (:func:`corrected` gives the rig that body;
:func:`body_inertia` takes the cables' share off the fitted tensor).  To first order, its
moment is nearly collinear with the tensor and its weight with an accelerometer bias and
the load-cell gains; exactly, the re-tracked pose and the mean levels separate them.  A
``body_mass`` error (rig.yaml's body.mass off by δ: a weighing error) gives the same weight
surplus without the cables' lever arms, and competes with it the same way (else a 6 kg
weighing error was named a 1.1 kg cable mass, and "corrected" Ixx by −0.34 %).  Both are
evaluated when the load cells carry more (the body's mass: or less) than the weight by
:data:`WEIGHT_SURPLUS_SIGMA`, and their trial re-tracks keep the steel stretch fitted last
(a mass changes no tension), which is fitted again once one is selected.

Weights: each axis of the rotational and translational groups by its own residual scale
(the axes' scales differ several-fold: a pooled scale biased the tensor by several per
cent on some rigs, the identifier weights per axis too); the scales of the baseline fit
during the selection, the final fit's own afterwards (iteratively reweighted).

Selection: forward stepwise, by the likelihood-ratio statistic
``Λ = Σ_g N_eff,g ln(RSS_g,0 / RSS_g,1) + Δχ²_DC`` (Gaussian residuals with the
noise scale of each group; N_eff,g is the number of independent samples of the
band-passed residual: N · 2 (f_hi − f_lo) / f_s), against the χ² quantile of the
effect's number of parameters at p = :data:`ALPHA` / (number of candidates tried)
(Bonferroni).  An effect is kept only if it also reduces the residual RMS of some
channel by at least :data:`MIN_REDUCTION`, and a sensor-pose error must exceed the
engineering resolution :data:`PRACTICAL_FLOOR` (5 mm, 1 mrad, 1 ms): a statistically but
not physically significant term is not a finding.  ``gyroscopic_coupling`` is exempt from
the residual reduction: its size is known (κ = 1), and the test is whether κ = 0 is
rejected.  Standard deviations of the effect parameters: the
sandwich (batch-means) covariance, as the identifier's.

References: Ljung, *System Identification* (2nd ed., 1999), §16.4 (model validation by
residual analysis: whiteness, cross-correlation with the inputs) and §16.6 (likelihood
ratio and information criteria for model structure selection).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from dataclasses import replace as _replace

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt, welch
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from .effects import EFFECT_NAMES
from .identification import (KEYS, IdentificationError, auto_band, basis, consistent_from_params, cumulative_integral,
                             from_tensor, params_from_consistent, step_indices, to_tensor)
from .quality import check_motion, check_units, clean_sensors
from .recording import Recording, RecordingError
from .tracker import pass_compliance, replay
from .yaw_anchor import anchor_yaw

ALPHA = 0.01          # family-wise false-alarm probability of the selection
MIN_REDUCTION = 0.05  # an effect must reduce some channel's residual RMS by at least this fraction
MAX_EFFECTS = 3
CORRECTIONS = ("sensor_delay", "load_cell_scale", "imu_offset", "imu_misalignment", "gyro_bias", "gyro_scale",
               "accelerometer_bias", "body_mass")
"""Effects that are errors of the data, not missing physics: :func:`corrected` removes them."""
EXACT_SCREEN = 3      # sensor/rig-error candidates evaluated exactly (re-tracked) per selection step
REWEIGHT_ITER = 2     # reweighting iterations of the final fit (per-axis residual scales)
ALPHA_LP = 3.0        # angular acceleration: gyro low-passed at this multiple of the band's upper edge
GAIN_STEP = 0.02      # load-cell gain steps of the exact screening (relative)
CABLE_MASS_STEP = 2e-3  # cables' mass steps of the exact screening: body anchors' share of the body's mass
MASSES = ("cable_mass", "body_mass")
"""Errors of the mass the tensions move: they change no tension (their trials keep the steel stretch)."""
PROFILED = ("load_cell_scale",) + MASSES
"""One-parameter errors placed by their exact profile likelihood (:func:`_exact_profile`)."""
WEIGHT_SURPLUS_SIGMA = 3.0   # the masses are evaluated exactly when the cells carry this many σ more (or less) than the weight
DCM_FLOOR = 2.0       # N·m: systematic floor of the mean-moment residual (pose and lever-arm errors)
WEIGHT_SIGMA = 5e-4   # relative σ of the load cells' mean vertical force against rig.yaml's weight:
                      # the cells' calibration (class C3 cells: 0.02–0.05 % of their load)
# engineering resolution: a smaller sensor-pose error is no finding, however significant
PRACTICAL_FLOOR = {"imu_offset": 0.005, "imu_misalignment": 0.001, "sensor_delay": 0.001}   # m, rad, s
STEEL_STRETCH = 4e-3  # m: static stretch beyond which cables without a rig.yaml stiffness are not "steel-like"
SYNC_BINS = 36        # exciter-phase bins of the time-synchronous average (10° each)
SYNC_MIN_REVOLUTIONS = 10   # fewer exciter revolutions in the window: no synchronous residual
ROT, TR = ("gyro_x", "gyro_y", "gyro_z"), ("accel_x", "accel_y", "accel_z")


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


def _track(rig, s, cables: str):
    """Tracked poses and the cable stiffness used (N,) N/m.  cables: ``"declared"``: the
    rig.yaml stiffness, fitted by the tracker where rig.yaml gives none (as
    :func:`~rig_identification.tracker.track`); ``"rigid"``: inextensible where rig.yaml
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
    poses, _ = anchor_yaw(rig, poses, s, lo, hi)   # as every fit's replay (pipeline.replay_window)
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
        sg = _white_sigma(w.omega, fs)
        sa = _white_sigma(w.f, fs)
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


def _white_sigma(x: np.ndarray, fs: float) -> float:
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


def fit_model(model: Model, cols: list, kappa0: float, free_kappa: bool, scales, j0: np.ndarray,
              block_s: float = 4.0) -> Fit:
    """Levenberg–Marquardt fit (scipy ``least_squares``, analytic Jacobian) of the tensor
    (consistent parametrisation), the effect columns and optionally the gyroscopic scale
    κ.  Each group is weighted by its baseline scale and its effective sample count, so
    that the cost is −2 log L up to a constant (see module docstring)."""
    sr, sa, sg, sdc, sm = scales
    n = len(model.w.t)
    # per-axis weights (3,): the axes' residual scales differ (a weakly excited axis, a
    # pitch axis with more tracker error), and pooling them biases the tensor — the
    # identifier also weights per axis
    wr = np.broadcast_to(np.sqrt(model.n_eff / n) / np.asarray(sr, float), (3,))
    wa = np.broadcast_to(np.sqrt(model.n_eff / n) / np.asarray(sa, float), (3,))
    prepared = model.prepare(cols)
    k = len(cols)
    E = basis()
    zeros = np.zeros((n, 3))
    # the parts of the Jacobian that do not depend on the parameters
    dTr = np.stack([(c.tr_O if c.tr_O is not None else zeros) - (p["tr_FD"] if p["tr_FD"] is not None else zeros)
                    for c, p in zip(cols, prepared)], axis=-1) if k else np.zeros((n, 3, 0))
    dG = np.array([c.dcg if c.dcg is not None else np.zeros(3) for c in cols]).T.reshape(3, k)
    dA = np.array([c.dca if c.dca is not None else np.zeros(3) for c in cols]).T.reshape(3, k)
    dMm = np.array([p["rot_mean"] if p["rot_mean"] is not None else np.zeros(3) for p in prepared]).T.reshape(3, k)

    def unpack(x):
        j, dj = consistent_from_params(x[:6])
        beta = x[6:6 + k]
        kappa = x[6 + k] if free_kappa else kappa0
        return j, dj, beta, kappa

    def fun(x):
        j, _, beta, kappa = unpack(x)
        r, a, dg, da, dm, *_ = model.residuals(j, kappa, beta, cols, prepared)
        return np.concatenate([(r * wr).ravel(), (a * wa).ravel(), dg / sg, da / sdc, dm / sm])

    nlin = k + (1 if free_kappa else 0)
    rows = 6 * n + 9

    def lin_jac(j, P):
        """Jacobian columns of the parameters the residual is linear in (β, κ): they
        depend on the tensor only, (rows, nlin)."""
        Jl = np.zeros((rows, nlin))
        Jr = Jl[:3 * n].reshape(n, 3, nlin)
        for i, (c, p) in enumerate(zip(cols, prepared)):
            if c.rot_O is not None:
                Jr[:, :, i] += c.rot_O
            if p["rot_ID"] is not None:
                Jr[:, :, i] -= p["rot_ID"] @ P.T
        if free_kappa:
            Jr[:, :, -1] = np.einsum("m,mni->ni", j, model.G) @ P.T
        Jr *= wr[None, :, None]
        Jl[3 * n:6 * n] = (dTr * wa[None, :, None]).reshape(-1, k) if k else 0.0
        Jd = Jl[6 * n:]
        Jd[:3, :k] = dG / sg
        Jd[3:6, :k] = dA / sdc
        Jd[6:, :k] = dMm / sm
        if free_kappa:
            Jd[6:, -1] = -(j @ model.dcm_G) / sm
        return Jl

    def tensor_jac(dj, kappa, P, yhat):
        """Jacobian columns of the 6 tensor parameters, (rows, 6)."""
        Jt = np.zeros((rows, 6))
        M = (np.matmul(yhat, E.transpose(0, 2, 1)) + kappa * model.G) @ P.T     # (6, n, 3): P (E_m ŷ + κ G_m)
        Jt[:3 * n] = ((M.transpose(1, 2, 0) * wr[None, :, None]).reshape(-1, 6) @ dj)
        E6 = np.stack([kappa * model.dcm_G[m] + E[m] @ model.dcm_W for m in range(6)], axis=1)   # (3,6)
        Jt[6 * n + 6:] = -(E6 @ dj) / sm
        return Jt

    def jac(x):
        j, dj, beta, kappa = unpack(x)
        _, _, _, _, _, P, yhat, _ = model.residuals(j, kappa, beta, cols, prepared)
        return np.concatenate([tensor_jac(dj, kappa, P, yhat), lin_jac(j, P)], axis=1)

    # variable projection (Golub & Pereyra 1973): the residual is linear in the effect
    # columns and in κ, so for each tensor they are solved by linear least squares and
    # Levenberg–Marquardt runs on the 6 tensor parameters alone, with Kaufman's
    # projected Jacobian (Kaufman, BIT 15, 1975)
    cache = {}

    def full(th):
        """(x, residual, tensor Jacobian, orthonormal basis U of the linear columns) at the
        tensor parameters th, with the linear parameters solved."""
        key = th.tobytes()
        if key not in cache:
            x, U = np.r_[th, np.zeros(nlin)], None
            j, dj, _, _ = unpack(x)
            if nlin:
                P = np.linalg.inv(to_tensor(j))
                A = lin_jac(j, P)
                Ua, sv, Vt = np.linalg.svd(A, full_matrices=False)
                keep = sv > sv[0] * max(A.shape) * np.finfo(float).eps if sv[0] > 0 else np.zeros(len(sv), bool)
                U = Ua[:, keep]
                b = -(Vt[keep].T @ ((U.T @ fun(x)) / sv[keep]))
                x = np.r_[th, b]
            _, _, beta, kappa = unpack(x)
            r, a, dg, da, dm, P, yhat, _ = model.residuals(j, kappa, beta, cols, prepared)
            res = np.concatenate([(r * wr).ravel(), (a * wa).ravel(), dg / sg, da / sdc, dm / sm])
            cache.clear()
            cache[key] = (x, res, tensor_jac(dj, kappa, P, yhat), U)
        return cache[key]

    def fun_vp(th):
        return full(th)[1]

    def jac_vp(th):
        _, _, Jt, U = full(th)
        return Jt if U is None else Jt - U @ (U.T @ Jt)

    th0 = params_from_consistent(to_tensor(j0))
    sol = least_squares(fun_vp, th0, jac=jac_vp, method="lm", x_scale="jac", xtol=1e-10, ftol=1e-10,
                        max_nfev=200)
    sol.x, sol.fun = full(sol.x)[:2]
    j, dj, beta, kappa = unpack(sol.x)
    r, a, dg, da, dm, P, yhat, u = model.residuals(j, kappa, beta, cols, prepared)
    # covariance of (tensor entries, beta, kappa): sandwich with batch means over time blocks
    T = np.eye(len(sol.x))
    T[:6, :6] = np.linalg.pinv(dj)          # d theta / d entries
    A = jac(sol.x) @ T                        # Jacobian with respect to (entries, beta, kappa)
    cov = _sandwich(A, sol.fun, n, 6, int(round(block_s * model.fs)))
    return Fit(to_tensor(j), float(kappa), np.asarray(beta, float), cov, r, a, dg, da, dm, yhat, u, cols,
               free_kappa, model.dcw)


def _sandwich(A: np.ndarray, res: np.ndarray, n: int, per_row: int, nb: int) -> np.ndarray:
    """Covariance (AᵀA)⁻¹ S (AᵀA)⁻¹ with S from batch means of the time rows (the first
    n·per_row rows, sample-major within each group of n·3 rows) plus the DC rows."""
    p = A.shape[1]
    bread = np.linalg.pinv(A.T @ A)
    n_time = n * per_row
    H = A[:n_time] * res[:n_time, None]
    # rows are [rot (n,3) ravel, tr (n,3) ravel]: sample index of each row
    idx = np.concatenate([np.repeat(np.arange(n), 3)] * (per_row // 3))
    nb = max(1, min(nb, n // 8))
    blk = idx // nb
    S = np.zeros((blk.max() + 1, p))
    np.add.at(S, blk, H)
    meat = S.T @ S
    D = A[n_time:]
    meat += D.T @ D
    return bread @ meat @ bread


# --- the effect library ---------------------------------------------------------------

def _unit(x, floor_frac=0.1):
    nrm = np.linalg.norm(x, axis=1)
    floor = floor_frac * max(np.percentile(nrm, 95), 1e-12)
    return np.where(nrm[:, None] > floor, x / np.maximum(nrm, 1e-300)[:, None], 0.0)


def _lowpass(model: Model, x: np.ndarray) -> np.ndarray:
    """x zero-phase low-passed at the band's upper edge: the regressors that are nonlinear in
    a noisy signal (|ω| ω, sign ω) are formed from it, so the noise does not bias them."""
    sos = butter(4, model.band[1], fs=model.fs, output="sos")
    return sosfiltfilt(sos, x, axis=0)


def _vec(vals, stds, key, applied=None):
    a = np.zeros(len(vals)) if applied is None else np.asarray(applied, float)
    return {key: [float(x) for x in a + np.asarray(vals, float)]}, {key: [float(x) for x in stds]}


def candidates(w: Window, model: Model, base_kappa: float, applied: dict | None = None,
               allow_elasticity: bool = False, profiled: dict | None = None) -> list[Candidate]:
    """The effect library as model extensions for this window (names: effects.EFFECT_NAMES).

    applied: corrections already made to the data (key -> accumulated value, see
    :func:`corrected`), added to the reported parameters.  profiled: keys whose value was
    found by the exact profile likelihood (key -> σ, :func:`_exact_profile`): they carry
    no column and report the applied value."""
    applied = applied or {}
    profiled = profiled or {}
    m = w.mass
    om, v = w.omega, w.v
    E = np.eye(3)
    out = []

    def scal(keys):
        def rep(vals, stds):
            return ({k: float(x) for k, x in zip(keys, vals)}, {k: float(s) for k, s in zip(keys, stds)})
        return rep

    # viscous damping: M = -c_a ω, F = -c_l v
    out.append(Candidate("viscous_damping", [Column("angular", rot_D=-om), Column("linear", tr_D=-v / m)],
                         scal(["angular", "linear"])))
    # air drag (quadratic) and Coulomb friction (regularised sign, as the simulator), from
    # the low-passed motion
    om_s, v_s = _lowpass(model, om), _lowpass(model, v)
    nw, nv = np.linalg.norm(om_s, axis=1)[:, None], np.linalg.norm(v_s, axis=1)[:, None]
    out.append(Candidate("air_drag", [Column("angular", rot_D=-nw * om_s), Column("linear", tr_D=-nv * v_s / m)],
                         scal(["angular", "linear"])))
    eps = 1e-3
    out.append(Candidate("coulomb_friction",
                         [Column("torque", rot_D=-om_s / np.sqrt(nw**2 + eps**2)),
                          Column("force", tr_D=-v_s / np.sqrt(nv**2 + eps**2) / m)],
                         scal(["torque", "force"])))
    # the exciter's rotor: its weight turning with the unbalanced mass, M = U û × g
    if np.any(w.f_exc):
        uh = _unit(w.f_exc)
        out.append(Candidate("exciter_rotor", [Column("unbalance", rot_D=np.cross(uh, w.g_body))],
                             scal(["unbalance"])))
    # sensor delays (first order): the stream lags by d -> true = measured + d d/dt(measured)
    # (only the readings lag, not the pose: d/dt of the tension, not of T u)
    t = w.t
    Fd = np.gradient(w.tensions, t, axis=0)[:, :, None] * w.u
    streams = [("load_cells", Fd.sum(1), np.cross(w.r_cables[None], Fd).sum(1))]
    if np.any(w.f_exc):
        dfe = np.gradient(w.f_exc, t, axis=0)
        streams.append(("exciter", dfe, np.cross(w.r_exc, dfe)))
    for stream, F, Mo in streams:
        done = float(applied.get(("sensor_delay", stream), 0.0))

        def rep_d(vals, stds, stream=stream, done=done):
            return {"stream": stream, "delay": done + float(vals[0])}, {"delay": float(stds[0])}
        out.append(Candidate("sensor_delay", [Column("delay", rot_D=Mo, tr_D=F / m)], rep_d, label=stream,
                             stream=stream, exact=True))
    # load-cell gains, one candidate per cable (a gain error is one cell's fault; the four
    # gains together are nearly collinear with an accelerometer bias and the static pose):
    # true T_i = T_meas,i (1 - e_i) -> -e_i times cable i's wrench
    for i, name in enumerate(w.cable_names):
        Fi = w.cable_force[:, i]
        done_e = float(applied.get(("load_cell_scale", name), 0.0))

        if ("load_cell_scale", name) in profiled:   # σ looked up when reported: the profile sets it last
            out.append(Candidate("load_cell_scale", [], lambda vals, stds, name=name, e=done_e: (
                {"cable": name, "scale": 1.0 / (1.0 - e)},
                {"scale": profiled[("load_cell_scale", name)] / (1.0 - e) ** 2}), label=name, exact=True))
            continue

        def rep_scale(vals, stds, name=name, done_e=done_e):
            keep = (1.0 - done_e) * (1.0 - float(vals[0]))      # true / measured
            return {"cable": name, "scale": 1.0 / keep}, {"scale": float(stds[0]) / keep}
        out.append(Candidate("load_cell_scale", [Column(f"gain_error_{name}", rot_D=-w.cable_moment[:, i],
                                                        tr_D=-Fi / m, dca=(Fi / m).mean(0))],
                             rep_scale, label=name, exact=True))
    # IMU offset δ (body axes): the specific force at the true point is α×δ + ω×(ω×δ) more
    cols = []
    for k in range(3):
        d = np.cross(model.alpha, E[k]) + np.cross(om, np.cross(om, E[k]))
        cols.append(Column(f"offset_{'xyz'[k]}", tr_D=d, dca=-d.mean(0)))
    out.append(Candidate("imu_offset", cols,
                         lambda vals, stds: _vec(vals, stds, "offset", applied.get(("imu_offset", ""))),
                         exact=True))
    # IMU misalignment δ (body axes, small): true ω = ω_meas + δ × ω_meas, same for f
    cols = [Column(f"rot_{'xyz'[k]}", rot_O=np.cross(E[k], model.y), tr_O=np.cross(E[k], model.ya),
                   dcg=np.cross(E[k], w.omega.mean(0)), dca=np.cross(E[k], w.f.mean(0))) for k in range(3)]
    done_rv = np.asarray(applied.get(("imu_misalignment", ""), np.zeros(3)), float)
    R0 = w.imu_rot_yaml

    def rep_mis(vals, stds):
        Rb = Rotation.from_rotvec(np.asarray(vals, float)) * Rotation.from_rotvec(done_rv)   # body axes
        Rd = Rotation.from_matrix(R0.T @ Rb.as_matrix() @ R0)                               # IMU axes
        return {"rpy": [float(x) for x in Rd.as_euler("xyz")]}, {"rpy": [float(s) for s in stds]}
    out.append(Candidate("imu_misalignment", cols, rep_mis, exact=True))
    # biases (IMU axes): mean-level offsets
    Rimu = w.imu_rot
    cols = [Column(f"bias_{'xyz'[k]}", dcg=-(Rimu @ E[k])) for k in range(3)]
    out.append(Candidate("gyro_bias", cols,
                         lambda vals, stds: _vec(vals, stds, "bias", applied.get(("gyro_bias", ""))), exact=True))
    # (no gyro_scale candidate: a scale factor on the gyro is the tensor scaled, to first order —
    # ω_meas = S P ∫M — and only the asymmetry of S P tells them apart; the exact iteration ran
    # off to a zero gyro on clean rigs.  corrected() removes a known one; the validation flags one)
    cols = [Column(f"bias_{'xyz'[k]}", dca=-(Rimu @ E[k])) for k in range(3)]
    out.append(Candidate("accelerometer_bias", cols,
                         lambda vals, stds: _vec(vals, stds, "bias", applied.get(("accelerometer_bias", ""))),
                         exact=True))
    # cable mass: half of each cable (mass μ per anchor) moves with the body, outside the load cell
    f_cg = w.force / m
    Dm = np.zeros_like(om)
    Fm = np.zeros_like(om)
    for r in w.r_cables:
        a_i = f_cg + np.cross(model.alpha, r) + np.cross(om, np.cross(om, r))   # anchor specific force
        Dm -= np.cross(r, a_i)
        Fm -= a_i
    # (the first-order column is no guide: the selection evaluates the mass exactly, the rig's
    # body given the cables' lower halves, :func:`corrected`, and places it by its profile)
    key, done_mu = ("cable_mass", ""), float(applied.get(("cable_mass", ""), 0.0))
    if key in profiled:
        out.append(Candidate("cable_mass", [], lambda vals, stds, mu=done_mu: (
            {"mass": 2 * mu}, {"mass": 2 * profiled[("cable_mass", "")]}), exact=True))
    else:
        out.append(Candidate("cable_mass", [Column("mass_half", rot_D=Dm, tr_D=Fm / m, dca=-(Fm / m).mean(0))],
                             lambda vals, stds, mu=done_mu: ({"mass": 2 * (mu + float(vals[0]))},
                                                             {"mass": 2 * float(stds[0])}), exact=True))
    # body mass: rig.yaml's body.mass is off by δ kg (a weighing error; evaluated exactly, as
    # the cables' mass, which it competes with: the same weight surplus, without the cables'
    # lever arms)
    key_b, done_b = ("body_mass", ""), float(applied.get(("body_mass", ""), 0.0))
    if key_b in profiled:
        out.append(Candidate("body_mass", [], lambda vals, stds, d=done_b: (
            {"mass_error": d}, {"mass_error": profiled[("body_mass", "")]}), exact=True))
    else:
        out.append(Candidate("body_mass", [Column("mass_error", tr_D=-f_cg / m, dca=(f_cg / m).mean(0))],
                             lambda vals, stds, d=done_b: ({"mass_error": d + float(vals[0])},
                                                           {"mass_error": float(stds[0])}), exact=True))
    # cable elasticity: the pose re-tracked with stretching cables (compliance fitted by the tracker)
    if allow_elasticity:
        out.append(Candidate("cable_elasticity", [], lambda vals, stds: ({"stiffness": float(vals[0])},
                                                                         {"stiffness": float(stds[0])}),
                             exact=True))
    # gyroscopic coupling: only a model without it can miss it
    if base_kappa == 0.0:
        out.append(Candidate("gyroscopic_coupling", [], lambda vals, stds: ({"scale": float(vals[0])},
                                                                            {"scale": float(stds[0])}),
                             gyroscopic=True))
    return out


def corrected(rec: Recording, applied: dict) -> Recording:
    """The recording with the sensor and rig errors of ``applied`` removed (key -> value):
    ("sensor_delay", stream) s: the stream's stamps − d; ("load_cell_scale", cable) e:
    the cable's tension T (1 − e); ("imu_offset", "") (3,) m body: imu.position + δ; ("imu_misalignment", "")
    (3,) rotation vector, body axes: IMU axes turned by it; ("gyro_scale", "") (3,) ε per IMU
    axis: the gyro divided by 1 + ε (after the bias); ("gyro_bias" | "accelerometer_bias",
    "") (3,) IMU axes: subtracted; ("body_mass", "") δ kg: body.mass + δ; ("cable_mass", "") μ kg: the rig's body carries μ at each
    body anchor (the lower half of each cable, outside its load cell at the ceiling): mass
    + n μ, the centre of gravity moved to the combined one (the tensor fitted is then the
    combined body's, :func:`body_inertia` gives the body's).  ("cable_elasticity", "") is
    handled by the tracker."""

    from .recording import SensorData, TimeSeries
    rig, s = rec.rig, rec.sensors
    imu = s.imu.data.copy()
    imu[:, :3] -= np.asarray(applied.get(("gyro_bias", ""), np.zeros(3)))
    imu[:, :3] /= 1.0 + np.asarray(applied.get(("gyro_scale", ""), np.zeros(3)))
    imu[:, 3:] -= np.asarray(applied.get(("accelerometer_bias", ""), np.zeros(3)))
    cells = {}
    d_cells = applied.get(("sensor_delay", "load_cells"), 0.0)
    gains = np.array([float(applied.get(("load_cell_scale", n), 0.0)) for n in rig.cable_names])
    for n, ts in s.load_cells.items():
        cells[n] = TimeSeries(ts.t - d_cells, ts.data * (1.0 - gains[rig.cable_names.index(n)]))
    exc = s.exciter
    if exc is not None and ("sensor_delay", "exciter") in applied:
        exc = TimeSeries(exc.t - applied[("sensor_delay", "exciter")], exc.data)
    s2 = SensorData(TimeSeries(s.imu.t, imu), cells, exc, s.inclinometer)
    imu_m = rig.imu
    if ("imu_offset", "") in applied:
        imu_m = _replace(imu_m, position=imu_m.position + np.asarray(applied[("imu_offset", "")]))
    if ("imu_misalignment", "") in applied:
        Rb = Rotation.from_rotvec(np.asarray(applied[("imu_misalignment", "")], float))
        imu_m = _replace(imu_m, rpy=(Rb * imu_m.rotation).as_euler("xyz"))
    rig = _replace(rig, imu=imu_m, mass=rig.mass + float(applied.get(("body_mass", ""), 0.0)))
    mu = float(applied.get(("cable_mass", ""), 0.0))
    if mu:
        rig = _replace(rig, mass=rig.mass + mu * len(rig.cables), center_of_gravity=_combined_cg(rig, mu))
    return _replace(rec, rig=rig, sensors=s2)


def _combined_cg(rig, mu: float) -> np.ndarray:
    """Centre of gravity (3,) m, body frame, of the rig's body with μ kg at each body anchor."""
    m, b = rig.mass, rig.body_anchors
    return (m * rig.require_cg() + mu * b.sum(0)) / (m + mu * len(b))


def with_stiffness(rec: Recording, k: np.ndarray) -> Recording:
    """``rec`` with every cable's axial stiffness (n,) N/m set in its rig."""
    return _replace(rec, rig=_replace(rec.rig, cables=tuple(_replace(c, stiffness=float(ki))
                                                            for c, ki in zip(rec.rig.cables, k))))


def body_inertia(J: np.ndarray, rig, mu: float) -> np.ndarray:
    """The body's inertia tensor about its own centre of gravity (3,3) kg·m² from ``J``
    (3,3), that of the body with μ kg at each body anchor about their combined centre of
    gravity (:func:`corrected`'s cable mass): parallel-axis theorem (Huygens–Steiner),
    J_b = J − m S(c_b − c) − μ Σ S(r_i − c), S(d) = |d|² I − d dᵀ; ``rig`` the rig.yaml's
    (with the body's mass as diagnosed)."""
    if not mu:
        return J
    m, cb, b = rig.mass, rig.require_cg(), rig.body_anchors
    c = _combined_cg(rig, mu)
    S = lambda d: float(d @ d) * np.eye(3) - np.outer(d, d)  # noqa: E731
    return J - m * S(cb - c) - mu * sum(S(r - c) for r in b)


# --- diagnosis ------------------------------------------------------------------------------

@dataclass(frozen=True)
class EffectWrench:
    """The generalized wrench that the diagnosed physics adds to the measured one (the
    extended model's moment and force columns times their fitted parameters; Newton–Euler:
    J ω̇ + ω × Jω = M + M_effect, m a = F + F_effect).

    t (N,) s, absolute stamps of the diagnosis window; torque (N,3) N·m about the CG and force
    (N,3) N, body axes; names: the effects it holds."""

    t: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    names: tuple

    def at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(torque (M,3), force (M,3)) at the stamps ``t`` (M,) s: linear interpolation, the
        end values held outside the window."""
        tq = np.column_stack([np.interp(t, self.t, self.torque[:, k]) for k in range(3)])
        fc = np.column_stack([np.interp(t, self.t, self.force[:, k]) for k in range(3)])
        return tq, fc


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`; :meth:`to_dict` is the JSON of ``rig-identify diagnose``."""

    mismatch: bool
    effects: list
    located: dict
    rms_before: dict
    rms_after: dict
    inertia_before: np.ndarray
    inertia_after: np.ndarray
    inertia_std_before: np.ndarray
    inertia_std_after: np.ndarray
    tried: list
    band: tuple
    model: str
    warnings: list = field(default_factory=list)
    series: dict = field(default_factory=dict)
    covariance_after: np.ndarray | None = None   # (6,6) of the entries of inertia_after, KEYS order
    # the sensor and rig errors removed from the data (key -> value, as :func:`corrected` takes)
    corrections: dict = field(default_factory=dict)
    # time-synchronous residual RMS per channel (None: no rotating exciter), and the revolutions averaged
    rms_sync_before: dict | None = None
    rms_sync_after: dict | None = None
    revolutions: float | None = None
    # the physics added to the model (not errors of the data), as the generalized wrench it
    # adds to the measured one along the window: :class:`EffectWrench` or None
    effect_wrench: "EffectWrench | None" = None
    # every correction made to the data or the rig (key -> value, :func:`corrected`; the
    # cables' mass included), and the cables' stiffness (n,) N/m when their elasticity was found
    applied: dict = field(default_factory=dict)
    stiffness: np.ndarray | None = None

    def to_dict(self) -> dict:
        ent = lambda J: {k: float(x) for k, x in zip(KEYS, from_tensor(J))}  # noqa: E731
        return {"mismatch": self.mismatch, "effects": self.effects, "located": self.located,
                "residual_rms_before": self.rms_before, "residual_rms_after": self.rms_after,
                "inertia_about_cg_before": ent(self.inertia_before),
                "inertia_about_cg_after": ent(self.inertia_after),
                "inertia_std_before": {k: float(x) for k, x in zip(KEYS, self.inertia_std_before)},
                "inertia_std_after": {k: float(x) for k, x in zip(KEYS, self.inertia_std_after)},
                "candidates": self.tried, "band_hz": [float(x) for x in self.band], "model": self.model,
                "warnings": self.warnings,
                "residual_rms_synchronous_before": self.rms_sync_before,
                "residual_rms_synchronous_after": self.rms_sync_after,
                "synchronous_revolutions": self.revolutions}


PLAUSIBLE = {
    "viscous_damping": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "air_drag": {"angular": (0.0, np.inf), "linear": (0.0, np.inf)},
    "coulomb_friction": {"torque": (0.0, np.inf), "force": (0.0, np.inf)},
    "sensor_delay": {"delay": (-0.1, 0.1)},
    "load_cell_scale": {"scale": (0.8, 1.25)},
    "gyro_bias": {"bias": (-0.05, 0.05)},
    "gyro_scale": {"scale": (0.9, 1.1)},
    "accelerometer_bias": {"bias": (-0.5, 0.5)},
    "imu_misalignment": {"rpy": (-0.1, 0.1)},
    "imu_offset": {"offset": (-1.0, 1.0)},
    "cable_elasticity": {"stiffness": (1e4, 1e9)},
    "gyroscopic_coupling": {"scale": (0.5, 1.5)},
}
"""The range (SI) each effect's parameters must fall in to be named: a fit that needs a
dissipation of the wrong sign, a sensor delay of a tenth of a second or an IMU a metre from
where rig.yaml puts it has found a stand-in for other physics, not the effect.  Besides:
``cable_mass`` between 0 and 5 % of the body's mass per cable, ``body_mass`` within 10 %
of rig.yaml's, the exciter's rotor ``unbalance`` within 0.3–3× the mass that makes the
measured force (F / (2π f)²), and a dissipative effect's moment at most
:data:`MAX_EFFECT_SHARE` of the measured moment (RMS in the band: a rig's damping is small)."""
MAX_EFFECT_SHARE = 0.3


def implausible(entry: dict, rig, effect_share: float | None = None, unbalance: float | None = None) -> str | None:
    """Why the effect ``entry`` (of :attr:`Diagnosis.effects`) cannot be the physics in the
    recording (see :data:`PLAUSIBLE`), or None when it is plausible.  effect_share: the RMS
    of its moment over the measured moment's; unbalance: kg·m that makes the measured
    exciter force."""
    name, par = entry["name"], entry["parameters"]
    for k, (lo, hi) in PLAUSIBLE.get(name, {}).items():
        v = np.atleast_1d(np.asarray(par.get(k, 0.0), float))
        if np.any(v < lo) or np.any(v > hi):
            return f"{k} = {fmt_value(par.get(k))} outside {lo:g}…{hi:g}"
    if name == "cable_mass" and not 0.0 <= par.get("mass", 0.0) <= 0.05 * rig.mass:
        return f"mass {par['mass']:.3g} kg per cable outside 0…{0.05 * rig.mass:.3g} kg"
    if name == "body_mass" and abs(par.get("mass_error", 0.0)) > 0.1 * rig.mass:
        return f"mass error {par['mass_error']:.3g} kg beyond 10 % of rig.yaml's {rig.mass:.6g} kg"
    if name == "exciter_rotor" and unbalance:
        u = par.get("unbalance", 0.0)
        if not 0.3 * unbalance <= u <= 3.0 * unbalance:
            return f"unbalance {u:.3g} kg·m outside 0.3–3× the {unbalance:.3g} kg·m that makes the measured force"
    if name in ("viscous_damping", "air_drag", "coulomb_friction") and effect_share is not None \
            and effect_share > MAX_EFFECT_SHARE:
        return f"its moment is {100 * effect_share:.0f} % of the measured moment (at most {100 * MAX_EFFECT_SHARE:.0f} %)"
    return None


def unexplained(located: dict, duration: float, limit: int = 6) -> list[dict]:
    """Where the rigid-body fit's residuals show the mismatch, from :func:`locate`'s
    analysis: one entry per spectral line of a channel's residual (the largest first)
    ``{"channel", "band_hz": [lo, hi] Hz, "time_s": [start, end] s from the window's start,
    "size": power over the residual's median in-band level, "is": what the frequency is}``;
    a channel with no line but a residual that is not white (Ljung–Box p < 1e-3) gives one
    entry over the whole band (size: its RMS).  ``time_s`` is the tenth of the window where
    the channel's residual is largest when that is over twice the median tenth, else the
    whole window.  At most ``limit`` entries."""
    out = []
    for ch, a in located.items():
        seg = np.asarray(a.get("rms_by_tenth") or [0.0])
        med = float(np.median(seg))
        i = int(np.argmax(seg))
        span = [i * duration / 10, (i + 1) * duration / 10] if med > 0 and seg[i] > 2 * med else [0.0, duration]
        for pk in a.get("peaks", []):
            out.append({"channel": ch, "band_hz": [round(max(pk["hz"] - 0.05, 0.0), 3), round(pk["hz"] + 0.05, 3)],
                        "time_s": [round(x, 1) for x in span], "size": pk["power_over_floor"], "is": pk["is"]})
        if not a.get("peaks") and a.get("whiteness_p", 1.0) < 1e-3:
            out.append({"channel": ch, "band_hz": None, "time_s": [round(x, 1) for x in span],
                        "size": a.get("rms"), "is": "a coloured residual (not white)"})
    out.sort(key=lambda e: -(e["size"] or 0.0) if e["band_hz"] is not None else 0.0)
    return out[:limit]


def fmt_value(v) -> str:
    """A parameter value of an effect's JSON as text (numbers to 4 digits; lists, dicts)."""
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {fmt_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(fmt_value(x) for x in v) + "]"
    if isinstance(v, (float, np.floating)):
        return f"{v:.4g}"
    return str(v)


def effect_parameters_text(e: dict) -> str:
    """``k = v ± σ, …`` of one entry of :attr:`Diagnosis.effects`."""
    std = e.get("parameters_std", {})
    return ", ".join(f"{k} = {fmt_value(v)}" + (f" ± {fmt_value(std[k])}" if k in std else "")
                     for k, v in e["parameters"].items())


def channel_residuals(model: Model, fit: Fit) -> dict:
    """Residual time series (N,) per channel: gyro and accelerometer (band-passed, plus
    the mean-level residual), torque and force (Newton–Euler equation errors, N·m and N),
    and each load cell (least-squares tension correction, N)."""
    w = model.w
    out = {}
    for k in range(3):
        out[ROT[k]] = fit.rot[:, k] + fit.dcg[k]
        out[TR[k]] = fit.tr[:, k] + fit.dca[k]
    # Newton–Euler equation errors, band-passed: torque = J α + ω×Jω − M − ΔM  (in-band)
    J = fit.J
    # torque residual from the output error: J (d/dt) of the rotational residual
    torque = np.gradient(fit.rot, w.t, axis=0) @ J.T + fit.dcm
    force = fit.tr * w.mass
    for k, a in enumerate("xyz"):
        out[f"torque_{a}"] = torque[:, k]
        out[f"force_{a}"] = force[:, k]
    # load cells: tension corrections δT that best explain the wrench residual
    W = np.concatenate([w.u, np.cross(w.r_cables[None], w.u)], axis=2)      # (N,n,6)
    wr = np.concatenate([force, torque], axis=1)                             # (N,6)
    scale = np.array([1, 1, 1, 1 / 1.5, 1 / 1.5, 1 / 1.5])                   # N vs N·m over ~1.5 m
    Ws = W * scale
    dT = np.einsum("nij,nj->ni", np.linalg.pinv(np.transpose(Ws, (0, 2, 1))), wr * scale)
    for i, name in enumerate(w.cable_names):
        out[f"load_cell_{name}"] = dT[:, i]
    return out


def _rms(d: dict) -> dict:
    return {k: float(np.sqrt(np.mean(v**2))) for k, v in d.items()}


def exciter_phase(w: Window) -> np.ndarray | None:
    """The rotating exciter force's phase (N,) rad, unwrapped, from its two components in the
    exciter's spin plane (``f_exc`` in the exciter frame); NaN where the force is below a
    fifth of its median magnitude (stopped, spinning up).  None without a rotating exciter:
    no exciter, or fewer than :data:`SYNC_MIN_REVOLUTIONS` turns in the window."""
    fe = w.f_exc @ w.exc_rot[:, :2]
    mag = np.linalg.norm(fe, axis=1)
    if not np.any(mag > 0):
        return None
    ph = np.unwrap(np.arctan2(fe[:, 1], fe[:, 0]))
    ph[mag < 0.2 * np.median(mag)] = np.nan
    ok = np.isfinite(ph)
    if ok.sum() < 2 or abs(ph[ok][-1] - ph[ok][0]) < 2 * np.pi * SYNC_MIN_REVOLUTIONS:
        return None
    return ph


def synchronous_rms(series: dict, phase: np.ndarray, bins: int = SYNC_BINS) -> dict:
    """RMS per channel of the time-synchronous average of its residual (N,): the mean over the
    exciter's revolutions in ``bins`` bins of its phase (N,) rad (NaN: left out), RMS over the
    bins weighted by their samples.  What is locked to the forcing (its frequency, harmonics
    and the mean) stays; the sensor noise and the free modes average out, by about √(number
    of revolutions) for the noise: the model error under a noise floor becomes measurable.
    Source: Braun, "The extraction of periodic waveforms by time domain averaging", Acustica
    32 (1975); McFadden, Mech. Syst. Signal Process. 1 (1987) 83–95."""
    from scipy.stats import binned_statistic
    ok = np.isfinite(phase)
    th = np.mod(phase[ok], 2 * np.pi)
    names = list(series)
    means = binned_statistic(th, [np.asarray(series[k])[ok] for k in names], "mean", bins=bins,
                             range=(0.0, 2 * np.pi)).statistic                      # (channels, bins)
    n = np.histogram(th, bins=bins, range=(0.0, 2 * np.pi))[0]
    filled = n > 0
    return {k: float(np.sqrt(np.sum(n[filled] * means[i, filled] ** 2) / n[filled].sum()))
            for i, k in enumerate(names)}


def _sync(model: "Model", ch: dict) -> tuple:
    """(synchronous RMS per channel or None, revolutions or None) of a window's residuals."""
    ph = exciter_phase(model.w)
    if ph is None:
        return None, None
    ok = np.isfinite(ph)
    return synchronous_rms(ch, ph), float(abs(ph[ok][-1] - ph[ok][0]) / (2 * np.pi))


def locate(model: Model, fit: Fit, rig, inertia) -> dict:
    """Where the residuals of the fit show a mismatch: in time (RMS per tenth of the window,
    and while the exciter runs vs not), in frequency (Welch peaks, each named: the forcing,
    its harmonics, a natural frequency of the rig, or unexplained), whiteness (Ljung–Box on
    the residual decimated to the band) and correlation with the inputs and states."""
    from scipy.stats import chi2 as _chi2
    w = model.w
    ch = channel_residuals(model, fit)
    fs = model.fs
    lo, hi = model.band
    # exciter frequency from the exciter force direction's rotation
    f_exc = None
    if np.any(w.f_exc):
        ang = np.unwrap(np.arctan2(w.f_exc[:, 1], w.f_exc[:, 0]))
        on = np.linalg.norm(w.f_exc, axis=1) > 0.5 * np.percentile(np.linalg.norm(w.f_exc, axis=1), 95)
        if on.sum() > 10:
            f_exc = abs(float(np.polyfit(w.t[on], ang[on], 1)[0])) / (2 * np.pi)
    try:
        from .modes import natural_modes
        k = rig.cable_stiffness if np.isfinite(rig.cable_stiffness).all() else None
        nat = [m.frequency for m in natural_modes(rig, rig.mass, rig.require_cg(), inertia, k)]
    except Exception:  # noqa: BLE001 — the modes are an aid to naming peaks, not required
        nat = []
    states = {"omega_x": w.omega[:, 0], "omega_y": w.omega[:, 1], "omega_z": w.omega[:, 2],
              "|omega|": np.linalg.norm(w.omega, axis=1), "v_x": w.v[:, 0], "v_y": w.v[:, 1], "v_z": w.v[:, 2],
              "|v|": np.linalg.norm(w.v, axis=1)}
    for i, n in enumerate(w.cable_names):
        states[f"tension_{n}"] = w.tensions[:, i]
    if f_exc is not None:
        states["exciter_force_x"] = w.f_exc[:, 0]
        states["exciter_force_y"] = w.f_exc[:, 1]
    filt_states = {k: model.filt(v - v.mean()) for k, v in states.items()}
    step = max(1, int(fs / (2 * hi)))
    out = {}
    for name, r in ch.items():
        rr = r - r.mean()
        tenths = np.array_split(rr, 10)
        seg = [float(np.sqrt(np.mean(x**2))) for x in tenths]
        f, P = welch(rr, fs=fs, nperseg=min(len(rr), int(2 ** np.ceil(np.log2(20 * fs)))))
        inb = (f >= lo) & (f <= hi)
        peaks = []
        if inb.sum() > 3:
            Pi = P[inb]
            fl = np.median(Pi)
            order = np.argsort(Pi)[::-1]
            for i in order[:40]:
                if Pi[i] < 10 * fl or len(peaks) >= 3:
                    break
                fr = float(f[inb][i])
                if any(abs(fr - p["hz"]) < 0.1 for p in peaks):
                    continue
                peaks.append({"hz": round(fr, 3), "power_over_floor": round(float(Pi[i] / fl), 1),
                              "is": _name_peak(fr, f_exc, nat)})
        d = rr[::step]
        nlag = 10
        ac = np.array([np.corrcoef(d[:-L], d[L:])[0, 1] for L in range(1, nlag + 1)])
        q = len(d) * (len(d) + 2) * np.sum(ac**2 / (len(d) - np.arange(1, nlag + 1)))
        corr = sorted(((abs(float(np.corrcoef(rr, s)[0, 1])), k)
                       for k, s in filt_states.items() if np.std(s) > 0), reverse=True)[:3]
        out[name] = {"rms": float(np.sqrt(np.mean(r**2))), "mean": float(r.mean()),
                     "rms_by_tenth": [round(x, 9) for x in seg],
                     "grows_at": _grows(seg, w.t),
                     "peaks": peaks, "whiteness_p": float(_chi2.sf(q, nlag)),
                     "correlates_with": [{"signal": k, "correlation": round(c, 3)} for c, k in corr]}
    return out


def _name_peak(fr, f_exc, nat) -> str:
    if f_exc:
        for h in range(1, 6):
            if abs(fr - h * f_exc) < 0.03 * h * f_exc + 0.02:
                return "forcing" if h == 1 else f"forcing harmonic {h}"
    for i, fn in enumerate(nat):
        if abs(fr - fn) < 0.03 * fn + 0.02:
            return f"natural frequency {fn:.3f} Hz"
    if f_exc and nat:
        for fn in nat:
            if abs(fr - (fn + f_exc)) < 0.04 or abs(fr - abs(fn - f_exc)) < 0.04:
                return "intermodulation of the forcing and a mode"
    return "unexplained (no rigid-body mode or forcing harmonic)"


def _grows(seg, t) -> str | None:
    seg = np.asarray(seg)
    med = np.median(seg)
    if med <= 0:
        return None
    i = int(np.argmax(seg))
    if seg[i] > 2 * med:
        T = t[-1] - t[0]
        return f"{i * T / 10:.0f}–{(i + 1) * T / 10:.0f} s into the window ({seg[i] / med:.1f}× the median RMS)"
    return None


def effective_samples(r: np.ndarray) -> float:
    """Number of independent samples in a residual series (N, k): N over the integrated
    autocorrelation time τ = 1 + 2 Σ ρ_k, summed over the initial positive sequence of
    lag pairs (Geyer, Statistical Science 7, 1992), averaged over the columns."""
    n = len(r)
    taus = []
    for x in np.atleast_2d(r.T):
        x = x - x.mean()
        f = np.fft.rfft(x, 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[:n]
        ac = ac / ac[0]
        pairs = ac[1:-1:2] + ac[2::2]
        stop = np.argmax(pairs <= 0) if np.any(pairs <= 0) else len(pairs)
        taus.append(max(1.0, 1.0 + 2.0 * (ac[1:2 * stop + 1].sum())))
    return float(n / np.mean(taus))


def _lr(cost0: dict, cost1: dict, model: Model) -> float:
    lam = 0.0
    for g in ("rot", "tr"):
        # costs are in units of the baseline scales over n·3 samples; per-group likelihood
        # ratio with the group's effective number of independent samples
        if cost0[g] > 0 and cost1[g] > 0:
            lam += model.n_eff_group.get(g, model.n_eff) * 3 * np.log(cost0[g] / cost1[g])
    lam += sum(cost0[k] - cost1[k] for k in ("dcg", "dca", "dcm", "dcw"))
    return float(lam)


def _scales(M: Model, f0: Fit) -> tuple:
    """The residual scales of the fit ``f0`` (the baseline's during the selection): per
    axis (3,) for the rotational and translational groups, scalars for the mean levels."""
    return (np.sqrt(np.mean(f0.rot**2, 0)), np.sqrt(np.mean(f0.tr**2, 0)),
            float(np.mean(M.sigma_dcg)), float(np.mean(M.sigma_dca)), float(M.sigma_dcm))


def _columns(cands: list, keys: list) -> list:
    by = {c.key: c for c in cands}
    return [col for k in keys if k in by for col in by[k].columns]


def _exact_iterate(key, state: dict, build, keys: list, fit: Fit, n_iter: int, kappa0: float,
                  free_kappa: bool, scales) -> tuple:
    """Remove a selected sensor or rig error from the data and re-track, iterating its
    value x so that the first-order column's fitted remainder β(x) vanishes: Broyden's
    method (quasi-Newton; the starting Jacobian dβ/dx = −I is the first-order model, the
    tracker's response updates it).  Returns (applied, w, M, cands, fit)."""
    applied = dict(state["applied"])
    beta = _beta_of(fit, None, keys, key, state)
    x = np.zeros(len(beta)) + np.asarray(applied.get(key, 0.0), float)
    B = -np.eye(len(x))
    cands = None
    w = M = None
    for it in range(n_iter):
        dx = -np.linalg.solve(B, beta)
        x_new = x + dx
        applied[key] = float(x_new[0]) if len(x_new) == 1 else x_new.copy()
        w, M, cands = build(applied, state["elastic"])
        fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, from_tensor(fit.J))
        beta_new = _beta_of(fit, cands, keys, key, state)
        dbeta = beta_new - beta
        B = B + np.outer(dbeta - B @ dx, dx) / max(float(dx @ dx), 1e-300)
        x, beta = x_new, beta_new
        k0 = len(_columns(cands, keys[:keys.index(key)]))
        n = len(beta)
        std = np.sqrt(np.clip(np.diag(fit.cov)[6 + k0:6 + k0 + n], 0, None))
        if np.all(np.abs(beta) <= 0.1 * std):
            break
    return applied, w, M, cands, fit


def _beta_of(fit: Fit, cands, keys: list, key, state) -> np.ndarray:
    """The fitted values of the columns of ``key`` in ``fit`` (columns ordered by ``keys``)."""
    by = {c.key: c for c in (cands if cands is not None else state["cands"])}
    k0 = sum(len(by[k].columns) for k in keys[:keys.index(key)] if k in by)
    return np.asarray(fit.beta[k0:k0 + len(by[key].columns)], float)


def _profile_steps(key, w: Window) -> tuple:
    """(screening step, lower bound, curvature step) of the exact one-parameter evaluation
    of ``key``: a load cell's gain error (relative) :data:`GAIN_STEP`, unbounded; the
    half-cable mass per body anchor (kg) :data:`CABLE_MASS_STEP` of the body's mass shared
    by the anchors, at least 0; the body's mass error (kg) that share of the body's mass,
    unbounded."""
    if key[0] == "cable_mass":
        h = CABLE_MASS_STEP * w.mass / len(w.cable_names)
        return h, 0.0, 0.1 * h
    if key[0] == "body_mass":
        h = CABLE_MASS_STEP * w.mass
        return h, -np.inf, 0.1 * h
    return GAIN_STEP, -np.inf, 2e-3


def _builder(build, key):
    """The re-track of ``key``'s trial values: a mass (the cables', the body's) changes no
    tension, so its trials keep the steel stretch fitted last (one tracker pass, not two); a gain or a
    delay changes what the stretch is fitted to, so theirs fit it again."""
    if key[0] not in MASSES:
        return build
    return lambda applied, elastic, profiled=None: build(applied, elastic, profiled, keep_stretch=True)


def _weight_surplus(M: Model, fit: Fit) -> float:
    """How much more than the body's weight the load cells carry, in σ of the mean level:
    the mean cable and exciter force / mass minus the mean specific force, along gravity
    (body axes) — what the cables' mass does (each cable's lower half hangs on the body,
    outside its load cell), or a body heavier than rig.yaml says; beyond
    :data:`WEIGHT_SURPLUS_SIGMA` they are worth an exact evaluation.  ``fit.dca`` is the
    mean measured minus modelled specific force."""
    g_hat = -M.w.g_body.mean(0)
    g_hat = g_hat / np.linalg.norm(g_hat)
    return -float(fit.dca @ g_hat) / float(np.mean(M.sigma_dca))


def _exact_screen(e: dict, state: dict, build, keys: list, cost_ref: dict, rms_ref: dict, kappa0: float,
                  free_kappa: bool, scales, j0: np.ndarray, w: Window) -> None:
    """Exact evidence of a one-parameter rig or data error (a load cell's gain, the cables'
    or the body's mass; screening entry ``e``, updated in place): the error applied at two trial values
    about its current one (±h, or +h and +2h at its lower bound; :func:`_profile_steps`),
    the pose re-tracked and the model refitted; the likelihood ratio against ``cost_ref``
    through those two points and the current fit (Λ = 0) is a parabola, whose maximum (at
    most 3h away) is the evidence and the starting point of :func:`_exact_profile`."""
    key = e["c"].key
    h, lower, _ = _profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    offsets = (-h, h) if x0 - h >= lower else (h, 2 * h)
    lams, fits = [], []
    for d in offsets:
        w1, M, cands = build({**state["applied"], key: x0 + d}, state["elastic"])
        fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, j0)
        lams.append(_lr(cost_ref, fit.cost(scales), M))
        fits.append((fit, M))
    (p1, p2), (l1, l2) = offsets, lams
    A = (l2 / p2 - l1 / p1) / (p2 - p1)       # Λ(d) = A d² + B d through (0, 0), (p1, l1), (p2, l2)
    B = l1 / p1 - A * p1
    best = int(l2 >= l1)
    if A < 0:
        d = float(np.clip(-B / (2 * A), max(-3 * h, lower - x0), 3 * h))
        lam = A * d * d + B * d
    else:
        d, lam = offsets[best], max(lams)
    fit, M = fits[best]
    rms1 = _rms(channel_residuals(M, fit))
    e.update(lam=float(lam), fit=fit, red={k: 1 - rms1[k] / rms_ref[k] for k in rms1 if rms_ref[k] > 0},
             exact_state=({**state["applied"], key: x0 + d}, None, None, None))


def _exact_profile(key, state: dict, build, keys: list, cost_ref: dict, kappa0: float, free_kappa: bool, scales,
                   j0: np.ndarray, w: Window) -> tuple:
    """The exact profile likelihood of a one-parameter rig or data error (a load cell's
    gain, the cables' or the body's mass): the error applied at trial values x (:func:`corrected`), the
    pose re-tracked and the model (without the error's first-order column) refitted; x
    maximises the likelihood ratio against ``cost_ref`` (scipy ``minimize_scalar``,
    bounded, ± a screening step about the current value and above the lower bound of
    :func:`_profile_steps`, to 1 % of a step), σ from its curvature (Λ(x) ≈ Λ̂ − (x − x̂)²/σ²).
    They move the tracker's static pose, so the first-order column's zero
    (:func:`_exact_iterate`) is not the optimum.  Returns (applied, w, M, cands, fit, σ)."""
    from scipy.optimize import minimize_scalar
    others = [k for k in keys if k != key]
    prof = {**state.get("profiled", {}), key: np.nan}
    memo = {}

    def evaluate(x):
        x = float(x)
        if x not in memo:
            applied = {**state["applied"], key: x}
            w, M, cands = build(applied, state["elastic"], prof)
            fit = fit_model(M, _columns(cands, others), kappa0, free_kappa, scales, j0)
            memo[x] = (_lr(cost_ref, fit.cost(scales), M), (applied, w, M, cands, fit))
        return memo[x]

    step, lower, h = _profile_steps(key, w)
    x0 = float(state["applied"].get(key, 0.0))
    sol = minimize_scalar(lambda x: -evaluate(x)[0], bounds=(max(lower, x0 - step), x0 + step),
                          method="bounded", options={"xatol": 0.01 * step})
    xh = max(float(sol.x), lower + h)
    curv = 2 * evaluate(xh)[0] - evaluate(xh + h)[0] - evaluate(xh - h)[0]
    sd = float(np.sqrt(2 * h * h / curv)) if curv > 0 else float("nan")
    prof[key] = sd
    state["profiled"] = prof
    applied, w, M, cands, fit = evaluate(xh)[1]
    return applied, w, M, cands, fit, sd


def log_sf(x: float, dof: int) -> float:
    """ln P(χ²_dof > x), finite however large x: scipy's ``chi2.logsf``, and where that
    underflows its asymptotic form −x/2 + (dof/2 − 1) ln(x/2) − ln Γ(dof/2) (the upper
    incomplete gamma function's leading term; Abramowitz & Stegun 6.5.32)."""
    x = max(float(x), 0.0)
    v = float(chi2.logsf(x, dof))
    if np.isfinite(v):
        return v
    return -x / 2 + (dof / 2 - 1) * math.log(x / 2) - math.lgamma(dof / 2)


def diagnose(rec: Recording, model: str = "pem", max_effects: int = MAX_EFFECTS, alpha: float = ALPHA,
             band_hz: tuple[float, float] | None = None) -> Diagnosis:
    """Diagnose a dynamic recording (see module docstring).

    model: ``"pem"`` (ours, with the gyroscopic term) or ``"thesis"`` (the thesis's model:
    no ω × Jω).  The baseline is the rig.yaml taken literally: cables without a stiffness
    are inextensible.  Sensor and rig errors (delays, gains, biases, IMU pose, cable
    elasticity), once selected, are removed from the data and the pose re-tracked
    (:func:`corrected`), iterating the first-order estimate to convergence.
    Returns a :class:`Diagnosis`.  Raises RecordingError, RigError, TrackerError,
    IdentificationError for recordings no fit can be made of.
    """
    from .identification import identify_inertia
    if model not in ("pem", "thesis"):
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    warnings: list[str] = []
    kappa0 = 1.0 if model == "pem" else 0.0
    R_yaml = rec.rig.imu.rotation.as_matrix()
    state = {"applied": {}, "elastic": False, "band": band_hz, "candidate": True}
    declared = np.isfinite(rec.rig.cable_stiffness).all()

    def build(applied, elastic, profiled=None, keep_stretch=False):
        mode = "fitted" if elastic else ("declared" if declared else "rigid")
        # keep_stretch: the steel stretch fitted last is kept (one tracker pass, not two)
        src = with_stiffness(rec, state["steel"]) if keep_stretch and "steel" in state else rec
        w = prepare_window(corrected(src, applied), warnings=[] if state["band"] else warnings,
                           cables=mode, imu_rot_yaml=R_yaml)
        M = Model(w, state["band"])
        M.n_eff_group = state.get("n_eff_group", {})
        state["band"] = M.band
        return w, M, candidates(w, M, kappa0, applied, allow_elasticity=state["candidate"] and not elastic,
                                profiled=state.get("profiled") if profiled is None else profiled)

    if not declared:
        # rig.yaml gives no stiffness: steel cables stretch 1-2 mm, which the baseline fits
        # (the tracker's compliance); only a stretch beyond STEEL_STRETCH makes the cables'
        # elasticity a candidate, against the rigid-cable model
        w, M, cands = build({}, True)
        k = w.stiffness
        stretch = float(np.median(np.median(w.tensions, axis=0) / k))
        if stretch <= STEEL_STRETCH:
            state["candidate"] = False
            declared = True          # the fitted stiffness is the baseline's
            state["steel"] = k       # the last fitted (N/m per cable)
            cands = candidates(w, M, kappa0, {}, allow_elasticity=False)
        else:
            warnings.append(f"the cables stretch {1e3 * stretch:.1f} mm under the static load (fitted stiffness "
                            f"{np.median(k):.3g} N/m), more than steel cables' 1-2 mm: cable elasticity is tested "
                            "against rigid cables")
            w, M, cands = build({}, False)
    else:
        w, M, cands = build({}, False)
    band = M.band
    j0 = from_tensor(identify_inertia(rec.rig, w.t, w.omega, w.torque, band_hz=band).inertia)
    scales = _scales(M, fit_model(M, [], kappa0, False, (1.0, 1.0, 1.0, 1.0, 1e9), j0))
    base = fit_model(M, [], kappa0, False, scales, j0)
    state["n_eff_group"] = M.n_eff_group = {"rot": min(M.n_eff, effective_samples(base.rot)),
                                            "tr": min(M.n_eff, effective_samples(base.tr))}
    M0, ch0 = M, channel_residuals(M, base)
    rms0 = _rms(ch0)
    threshold_p = alpha / max(1, len(cands))
    keys: list = []
    entries: list = []
    free_kappa = False
    cur_fit = base
    tried = []
    elastic_cache = None
    state["cands"] = cands
    for step in range(1, max_effects + 1):
        cost_cur = cur_fit.cost(scales)
        rms_cur = _rms(channel_residuals(M, cur_fit))
        base_cols = _columns(cands, keys)
        screened = []
        for c in cands:
            if c.key in keys:
                continue
            fk = free_kappa or c.gyroscopic
            Mc = M
            try:
                if c.name == "cable_elasticity":
                    if elastic_cache is None or elastic_cache[0] != repr(state["applied"]):
                        we, Me, ce = build(state["applied"], True)
                        elastic_cache = (repr(state["applied"]), we, Me, ce)
                    _, we, Mc, ce = elastic_cache
                    fit = fit_model(Mc, _columns(ce, keys), kappa0, fk, scales, from_tensor(cur_fit.J))
                else:
                    fit = fit_model(M, base_cols + c.columns, kappa0, fk, scales, from_tensor(cur_fit.J))
            except (np.linalg.LinAlgError, ValueError) as e:
                warnings.append(f"candidate {c.name} {c.label}: fit failed ({e})")
                continue
            lam = _lr(cost_cur, fit.cost(scales), M)
            dof = len(c.columns) + (1 if c.gyroscopic else 0) + (1 if c.name == "cable_elasticity" else 0)
            if c.name in PRACTICAL_FLOOR:
                k0 = len(base_cols)
                size = float(np.linalg.norm(fit.beta[k0:k0 + len(c.columns)]))
                if size + float(np.linalg.norm(np.atleast_1d(state["applied"].get(c.key, 0.0)))) < \
                        PRACTICAL_FLOOR[c.name]:
                    tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(lam),
                                  "dof": dof, "p_value": float(chi2.sf(max(lam, 0.0), dof)),
                                  "max_rms_reduction": 0.0, "exact": False,
                                  "below_practical_floor": PRACTICAL_FLOOR[c.name]})
                    continue
            rms1 = _rms(channel_residuals(Mc, fit))
            red = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
            screened.append({"c": c, "lam": lam, "fit": fit, "red": red, "dof": dof, "exact_state": None})
        # sensor and rig errors move the tracked pose too: the most promising ones are
        # evaluated exactly (data corrected, re-tracked, two Broyden steps) before choosing
        promising = sorted((e for e in screened if e["c"].exact and e["c"].name not in PROFILED
                            and e["c"].name != "cable_elasticity"
                            and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p), key=lambda e: -e["lam"])
        # a load cell's gain and the cables' or the body's mass move the tracker's static pose,
        # so their first-order columns are no guide to their size or evidence: every
        # significant gain, and the masses when the cells carry more (or less) than the weight
        # (the cables' column is nearly collinear with the tensor), are evaluated exactly
        surplus = _weight_surplus(M, cur_fit)
        for e in screened:
            if (e["c"].name == "cable_mass" and surplus > WEIGHT_SURPLUS_SIGMA) or (
                    e["c"].name == "body_mass" and abs(surplus) > WEIGHT_SURPLUS_SIGMA) or (
                    e["c"].name == "load_cell_scale" and chi2.sf(max(e["lam"], 0.0), e["dof"]) < threshold_p):
                try:
                    _exact_screen(e, state, _builder(build, e["c"].key), keys, cost_cur, rms_cur, kappa0,
                                  free_kappa, scales, from_tensor(cur_fit.J), w)
                except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
                    warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
                    e["lam"] = -np.inf
        for e in promising[:EXACT_SCREEN]:
            keys_e = keys + [e["c"].key]
            try:
                applied, we, Me, ce, fe = _exact_iterate(e["c"].key, state, build, keys_e, e["fit"], 2, kappa0,
                                                         free_kappa, scales)
            except (np.linalg.LinAlgError, ValueError, RecordingError) as err:
                warnings.append(f"candidate {e['c'].name} {e['c'].label}: exact correction failed ({err})")
                e["lam"] = -np.inf
                continue
            e["lam"] = _lr(cost_cur, fe.cost(scales), Me)
            rms1 = _rms(channel_residuals(Me, fe))
            e["red"] = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
            e["fit"] = fe
            e["exact_state"] = (applied, we, Me, ce)
        best = None
        for e in screened:
            c = e["c"]
            p = float(chi2.sf(max(e["lam"], 0.0), e["dof"])) if np.isfinite(e["lam"]) else 1.0
            best_red = max(e["red"].values())
            tried.append({"name": c.name, "label": c.label, "step": step, "likelihood_ratio": float(e["lam"]),
                          "dof": e["dof"], "p_value": p, "max_rms_reduction": best_red,
                          "exact": e["exact_state"] is not None})
            if c.exact and c.name != "cable_elasticity" and e["exact_state"] is None:
                continue   # not evaluated exactly: its first-order fit is no evidence
            # the gyroscopic term is physics of known size (κ = 1), missing from the model
            # by construction: its test is κ = 0 rejected, however small the residual's change
            practical = best_red >= MIN_REDUCTION or c.gyroscopic
            # the strongest evidence, its parameters counted: the smallest p-value (log, so that
            # underflowing ones still rank) — a 3-parameter accelerometer bias with a likelihood
            # ratio 3 above a 1-parameter body mass error is the weaker explanation
            e["log_p"] = log_sf(e["lam"], e["dof"]) if np.isfinite(e["lam"]) else 0.0
            if p < threshold_p and practical and (best is None or e["log_p"] < best[0]["log_p"]):
                best = (e, p)
        if best is None:
            break
        e, p = best
        c, dof = e["c"], e["dof"]
        keys.append(c.key)
        free_kappa = free_kappa or c.gyroscopic
        fit = e["fit"]
        if c.name == "cable_elasticity":
            state["elastic"] = True
            _, w, M, cands = elastic_cache
        elif c.name in PROFILED:
            state["applied"] = e["exact_state"][0]
            state["applied"], w, M, cands, fit, _ = _exact_profile(c.key, state, _builder(build, c.key), keys,
                                                                   cost_cur, kappa0,
                                                                   free_kappa, scales, from_tensor(fit.J), w)
        elif c.exact:
            state["applied"], w, M, cands = e["exact_state"]
            state["applied"], w, M, cands, fit = _exact_iterate(c.key, {**state, "cands": cands}, build, keys,
                                                                fit, 3, kappa0, free_kappa, scales)
        if c.name in MASSES and "steel" in state:
            # its trial re-tracks kept the steel stretch: fitted again with the mass in place
            w, M, cands = build(state["applied"], False)
            fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, scales, from_tensor(fit.J))
        state["cands"] = cands
        if "steel" in state:
            state["steel"] = w.stiffness
        rms1 = _rms(channel_residuals(M, fit))
        red = {k: 1 - rms1[k] / rms_cur[k] for k in rms1 if rms_cur[k] > 0}
        lam = _lr(cost_cur, fit.cost(scales), M)
        cur_fit = fit
        affected = sorted((k for k, r in red.items() if r >= 0.1), key=lambda k: -red[k])
        entries.append({"name": c.name, "parameters": {}, "parameters_std": {},
                        "evidence": {"likelihood_ratio": lam, "dof": dof, "p_value": p, "threshold_p": threshold_p,
                                     "step": step, "rms_reduction": {k: round(red[k], 4) for k in affected[:8]}}})
    # backward elimination: forward selection can pick a stand-in first (drag for a delay's
    # quadrature) and keep it once the real effect is in; each physics effect (the first-order
    # ones: the data corrections are tested again by the validation of the corrected fit) is
    # dropped when the others explain the recording as well without it
    by_key = {c.key: c for c in cands}
    for key in [k for k in keys if k in by_key and not by_key[k].exact and not by_key[k].gyroscopic]:
        if len(keys) < 2:
            break
        others = [k for k in keys if k != key]
        try:
            fit_wo = fit_model(M, _columns(cands, others), kappa0, free_kappa, scales, from_tensor(cur_fit.J))
        except (np.linalg.LinAlgError, ValueError):
            continue
        lam = _lr(fit_wo.cost(scales), cur_fit.cost(scales), M)
        dof = len(by_key[key].columns)
        if chi2.sf(max(lam, 0.0), dof) >= threshold_p:
            i = keys.index(key)
            keys.pop(i)
            dropped = entries.pop(i)
            warnings.append(f"{dropped['name']} dropped: with the other effects in the model it adds nothing "
                            f"(likelihood ratio {lam:.3g}, {dof} dof)")
            cur_fit = fit_wo
    # the selection weighted each axis by the baseline's residual scale, which the missing
    # physics inflated on some axes: the final fit is reweighted by its own residual scales
    # (iteratively reweighted least squares: the maximum-likelihood estimate with unknown
    # per-axis noise levels)
    for _ in range(REWEIGHT_ITER if entries else 0):
        sr, sa = _scales(M, cur_fit)[:2]
        cur_fit = fit_model(M, _columns(cands, keys), kappa0, free_kappa, (sr, sa) + tuple(scales[2:]),
                            from_tensor(cur_fit.J))
    # the parameters of every selected effect, from the final joint fit
    pos = 0
    by = {cc.key: cc for cc in cands}
    for e, key in zip(entries, keys):
        if key[0] == "cable_elasticity":
            k = w.stiffness[np.isfinite(w.stiffness)]
            e["parameters"], e["parameters_std"] = {"stiffness": float(np.median(k))}, \
                {"stiffness": float(w.stiffness_std) if w.stiffness_std is not None else float("nan")}
            continue
        c = by[key]
        if c.gyroscopic:
            vals, stds = [cur_fit.kappa], [float(np.sqrt(max(cur_fit.cov[-1, -1], 0.0)))]
        else:
            vals = cur_fit.beta[pos:pos + len(c.columns)]
            stds = np.sqrt(np.clip(np.diag(cur_fit.cov)[6 + pos:6 + pos + len(c.columns)], 0, None))
            pos += len(c.columns)
        e["parameters"], e["parameters_std"] = c.report(vals, stds)
    # the physics the model lacks (not an error of the data), as the wrench it adds
    pos = 0
    tq_add, f_add, phys, share = np.zeros_like(w.omega), np.zeros_like(w.omega), [], {}
    for key in keys:
        c = by.get(key)
        if c is None or c.gyroscopic:
            continue
        vals = cur_fit.beta[pos:pos + len(c.columns)]
        pos += len(c.columns)
        if c.exact:
            continue
        phys.append(c.name)
        tq_c = np.zeros_like(w.omega)
        for b, col in zip(vals, c.columns):
            if col.rot_D is not None:
                tq_c += b * col.rot_D
            if col.tr_D is not None:
                f_add += b * w.mass * col.tr_D
        tq_add += tq_c
        share[c.name] = float(np.sqrt(np.mean(M.filt(tq_c) ** 2)) / max(np.sqrt(np.mean(M.filt(w.torque) ** 2)),
                                                                        1e-12))
    effect_wrench = EffectWrench(w.t.copy(), tq_add, f_add, tuple(phys)) if phys else None
    phase = exciter_phase(w)
    unbalance = None
    if phase is not None:
        ok = np.isfinite(phase)
        f_hz = abs(float(np.polyfit(w.t[ok], phase[ok], 1)[0])) / (2 * np.pi)
        unbalance = float(np.median(np.linalg.norm(w.f_exc, axis=1))) / (2 * np.pi * f_hz) ** 2
    for e in entries:
        why = implausible(e, rec.rig, share.get(e["name"]), unbalance)
        e["plausible"] = why is None
        if why is not None:
            e["implausible"] = why
        if e["name"] in share:
            e["evidence"]["moment_share"] = round(share[e["name"]], 4)
    entries.sort(key=lambda e: -e["evidence"]["likelihood_ratio"])
    located = locate(M0, base, rec.rig, base.J)
    std_of = lambda f: np.sqrt(np.clip(np.diag(f.cov)[:6], 0, None))  # noqa: E731
    ch1 = channel_residuals(M, cur_fit)
    (sync0, revs), (sync1, _) = _sync(M0, ch0), _sync(M, ch1)
    return Diagnosis(bool(entries), entries, located, rms0, _rms(ch1), base.J,
                     body_inertia(cur_fit.J, _replace(rec.rig, mass=rec.rig.mass + float(state["applied"].get(
                         ("body_mass", ""), 0.0))), float(state["applied"].get(("cable_mass", ""), 0.0))),
                     std_of(base), std_of(cur_fit), tried, band, model, warnings + list(rec.warnings),
                     series={"t": w.t - w.t[0], "fs": M.fs, "before": ch0, "after": ch1},
                     covariance_after=np.array(cur_fit.cov[:6, :6]),
                     corrections={k: v for k, v in state["applied"].items() if k[0] in CORRECTIONS},
                     rms_sync_before=sync0, rms_sync_after=sync1, revolutions=revs, effect_wrench=effect_wrench,
                     applied=dict(state["applied"]), stiffness=w.stiffness.copy() if state["elastic"] else None)


__all__ = ["Diagnosis", "diagnose", "prepare_window", "candidates", "locate", "EFFECT_NAMES", "IdentificationError"]
