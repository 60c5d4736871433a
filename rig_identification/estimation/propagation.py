"""Noise propagation: the σ of the identified tensor that the sensors' noise causes along a run.

The identifier (:mod:`rig_identification.estimation.identification`) fits ``J`` by weighted least squares on the
band-passed gyro ``y = F ω`` against ``ŷ = J⁻¹ F ∫(M − ω × Jω)``.  To first order in the
sensor noise its error is ``δj = (AᵀWA)⁻¹ AᵀW e`` (A: the (N·3, 6) Jacobian of ŷ at the
nominal tensor, W: the per-axis weights 1/σ² of its Levenberg–Marquardt stage, e: the
residual the noise causes).  The noise reaches e by three paths:

* the gyro itself (the output): ``F n_g`` — the identifier's own white-noise bound
  ``crb_std`` covers only this path;
* the tracker: its pose is the integrated gyro (and accelerometer) noise, held to the
  inclinometer / cable constraints by slow complementary filters.  A pose error φ turns
  the measured cable tensions into a torque error ``δM = D_φ(t) φ + D_p(t) δp`` (the
  moment of the weight about the CG "seen" at the wrong angle: D_φ ~ m g h ~ 7·10⁴ N·m/rad
  on the thesis rig), which the identifier integrates: ``e = −J⁻¹ F ∫ δM``.  Because
  ``∫∫`` makes this path ∝ (f_pendulum / f)², it is as large as the direct gyro path
  near the rig's modes and dominates the pitch axis of thesis case 16;
* the load cells and the exciter's load cells: white torque errors, also integrated.

:func:`predict_from_trajectory` evaluates that linear map exactly for the run's true
motion (a noise-free simulation, cut to the span the identifier would fit): the tracker is
linearised about the equilibrium (its complementary filters — tilt, yaw, gyro-bias integral,
third-order position filter — as transfer functions, parameters read from
:class:`~rig_identification.estimation.tracker.PoseTracker`), ``D_φ(t)``, ``D_p(t)`` and the load cells' lever arms are
the derivatives of :func:`~rig_identification.estimation.preprocessor.generalized_wrench` at every sample (so a slow
pose error modulated by the tension swing lands at the exciter frequency), and the
identifier's own band-pass (``sosfiltfilt``, edge transients included) and integration are
applied through their transposes, so that ``Cov δj = B⁻¹ (Σ_c σ_c² Γ_cᵀΓ_c) B⁻¹`` (B = AᵀWA,
Γ_c the sensitivity of ``AᵀW e`` to noise channel c) needs no Monte Carlo.  The tracker's
online cable compliance (rig.yaml without stiffness) enters as one more linear functional
of the noise (its estimate lengthens every constraint by T(t)·δc).  Realisation by
realisation this linear model reproduces the pipeline's residual (correlation 0.995) and
estimate errors (0.99+); on thesis cases 10–17 its σ match the spread of 60 Monte Carlo
replays per case within ±20 % on 46 of 48 entries (median ratio 1.00; the pitch inertia Iyy is
predicted 10–25 % conservative on some cases), where the white-gyro bound alone is off by
−23 … +130 % (``bench/bench_plan.py``).  Second-order effects (errors in the integrated torque acting as
errors in variables) bias weakly excited runs slightly; they are not modelled.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.fft import irfft, next_fast_len, rfft
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfreqz
from scipy.spatial.transform import Rotation

from .identification import prepare_segment
from .directions import weak_directions
from .signals import auto_band
from ..io.verdict import KEYS
from ..model.parametrisation import basis, from_tensor
from .preprocessor import generalized_wrench
from ..io.rig import Rig
from .tracker import PoseTracker, YAW_PRIOR
from .quality import clean_sensors
from ..io.recording import Recording, RecordingError

FREQ_BLOCK = 4096   # frequencies per evaluation of the tracker's response (memory, not results)
DRIFT_LEAK = 1e-3   # 1/s: leak of the linearised tracker's uncorrected rotation directions (tracker_model)

REFERENCE_NOISE = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 0.0002}
"""σ of the reference recordings' white sensor noise (``/work/shared/recordings/*/truth.yaml``):
rad/s, m/s², N, N, rad."""
REFERENCE_RATES = {"imu": 200.0, "load_cells": 200.0, "exciter": 200.0, "inclinometer": 50.0}
"""Sample rates of the reference recordings, Hz."""
SOURCES = ("gyro", "accelerometer", "inclinometer", "load_cell", "exciter")
"""Noise sources of the prediction (the tracker's compliance estimate enters through them)."""
DIAG = (0, 3, 5)  # ixx, iyy, izz in KEYS order

ENTRY_NAMES = {"ixx": "roll inertia Ixx", "iyy": "pitch inertia Iyy", "izz": "yaw inertia Izz",
               "ixy": "product Ixy", "ixz": "product Ixz", "iyz": "product Iyz"}


class PlanError(ValueError):
    """The planned experiment cannot be predicted or designed (no motion, bad limits)."""


# --- result types ----------------------------------------------------------------------

@dataclass
class Prediction:
    """Predicted first-order uncertainty of the identified tensor for one run (or several
    fitted jointly).

    inertia: (3,3) nominal tensor, kg·m²; std: (6,) predicted σ in :data:`KEYS` order,
    kg·m²; covariance (6,6); gyro_white_std (6,): the white-gyro-only bound (what the
    identifier reports as ``crb_std``); contributions: {source: (6,) σ of that noise source
    alone}; weights (3,) the identifier's per-gyro-axis weights 1/σ², (rad/s)⁻²;
    residual_rms (3,) rad/s predicted residual of the band-passed fit; band_hz; duration s
    (fitted windows, summed); n_samples; runs; rotation_rms (3,) rad/s band-passed body rate
    per body axis.  axis_bread (3,6,6), axis_meats {source: (3,3,6,6)}, white_bread and
    white_meat (6,6) keep the per-axis pieces of the sandwich so that runs can be combined
    (:func:`combine`) with pooled weights: bread = Σ_a w_a B_a, meat = Σ_ab w_a w_b M_ab.
    gyro_sensitivity (K,3,6), only when asked for (:func:`predict_from_trajectory`): the
    linearised estimate error per gyro noise sample, ``δj ≈ Σ_n,d S[n,d] ν[n,d]`` for gyro
    noise ν (K,3) rad/s in IMU axes at the trajectory's samples — lets a Monte Carlo
    evaluate the first-order model on its own noise draws (a control variate).
    """

    inertia: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    gyro_white_std: np.ndarray
    contributions: dict
    weights: np.ndarray
    residual_rms: np.ndarray
    band_hz: tuple
    duration: float
    n_samples: int
    rotation_rms: np.ndarray
    axis_bread: np.ndarray
    axis_meats: dict
    white_bread: np.ndarray
    white_meat: np.ndarray
    runs: int = 1
    gyro_sensitivity: np.ndarray | None = None

    @staticmethod
    def assemble(inertia, axis_bread, axis_meats, white_bread, white_meat, residual_var, band_hz, duration,
                 n_samples, rotation_rms, runs=1) -> "Prediction":
        """Sandwich covariance from the per-axis pieces with weights 1/residual_var."""
        w = 1.0 / np.asarray(residual_var, float)
        bread = np.einsum("a,aij->ij", w, axis_bread)
        Bi = np.linalg.inv(bread)
        meats = {s: np.einsum("a,b,abij->ij", w, w, M) for s, M in axis_meats.items()}
        cov = Bi @ sum(meats.values()) @ Bi.T
        contrib = {s: np.sqrt(np.clip(np.diag(Bi @ M @ Bi.T), 0, None)) for s, M in meats.items()}
        Bu = np.linalg.inv(white_bread)
        gws = np.sqrt(np.clip(np.diag(Bu @ white_meat @ Bu), 0, None))
        return Prediction(np.asarray(inertia, float), np.sqrt(np.clip(np.diag(cov), 0, None)), cov, gws, contrib,
                          w, np.sqrt(residual_var), tuple(band_hz), float(duration), int(n_samples),
                          np.asarray(rotation_rms, float), axis_bread, axis_meats, white_bread, white_meat, runs)

    @property
    def scale(self) -> np.ndarray:
        """(6,) reference of each entry: diagonals themselves, products the largest diagonal."""
        th = from_tensor(self.inertia)
        big = max(abs(th[i]) for i in DIAG)
        return np.array([abs(th[i]) if i in DIAG else big for i in range(6)])

    @property
    def relative_std(self) -> np.ndarray:
        """(6,) σ / scale (dimensionless)."""
        return self.std / self.scale

    @property
    def objective(self) -> float:
        """The largest relative σ over the six entries."""
        return float(np.max(self.relative_std))

    def worst(self, ref: np.ndarray | None = None) -> float:
        """max_k σ_k / ref_k (ref: (6,) per-entry reference, default :attr:`scale`)."""
        return float(np.max(self.std / (self.scale if ref is None else ref)))

    def scaled(self, factor: float) -> "Prediction":
        """The same run lasting ``factor`` times as long (information × factor, σ / sqrt(factor))."""
        return Prediction.assemble(self.inertia, self.axis_bread * factor,
                                   {s: M * factor for s, M in self.axis_meats.items()}, self.white_bread * factor,
                                   self.white_meat * factor, self.residual_rms**2, self.band_hz,
                                   self.duration * factor, int(self.n_samples * factor), self.rotation_rms, self.runs)

    def weak(self, n: int = 2) -> list[dict]:
        """The ``n`` most weakly determined combinations, in words (see :func:`describe_weak`)."""
        return [describe_weak(rel, D, self.rotation_rms) for rel, D in weak_directions(self.inertia, self.covariance, n)]

    def to_dict(self) -> dict:
        return {"std": {k: float(v) for k, v in zip(KEYS, self.std)},
                "relative_std": {k: float(v) for k, v in zip(KEYS, self.relative_std)},
                "gyro_white_std": {k: float(v) for k, v in zip(KEYS, self.gyro_white_std)},
                "contributions": {s: {k: float(v) for k, v in zip(KEYS, c)} for s, c in self.contributions.items()},
                "max_relative_std": self.objective,
                "residual_rms_rad_s": [float(x) for x in self.residual_rms],
                "rotation_rms_rad_s": [float(x) for x in self.rotation_rms],
                "band_hz": [float(self.band_hz[0]), float(self.band_hz[1])],
                "duration_s": float(self.duration), "runs": int(self.runs),
                "weakly_determined": self.weak()}


def combine(preds: list[Prediction]) -> Prediction:
    """Joint prediction of independent runs fitted together with one tensor (the joint fit
    of :func:`~rig_identification.estimation.identification.identify_inertia_joint`): information (AᵀWA) and noise
    (meat) add over the runs, with the per-axis weights pooled over the runs (one gyro).
    Raises :class:`PlanError` for an empty list."""
    if not preds:
        raise PlanError("no runs to combine")
    if len(preds) == 1:
        return preds[0]
    n = np.array([p.n_samples for p in preds], float)
    var = sum(ni * p.residual_rms**2 for ni, p in zip(n, preds)) / n.sum()
    meats = {s: sum(p.axis_meats[s] for p in preds if s in p.axis_meats)
             for s in dict.fromkeys(k for p in preds for k in p.axis_meats)}
    rot = np.sqrt(sum(ni * p.rotation_rms**2 for ni, p in zip(n, preds)) / n.sum())
    return Prediction.assemble(preds[0].inertia, sum(p.axis_bread for p in preds), meats,
                               sum(p.white_bread for p in preds), sum(p.white_meat for p in preds), var,
                               (min(p.band_hz[0] for p in preds), max(p.band_hz[1] for p in preds)),
                               sum(p.duration for p in preds), int(n.sum()), rot, sum(p.runs for p in preds))


# --- identifiability in words ----------------------------------------------------------

AXIS_WORDS = {0: ("x", "roll"), 1: ("y", "pitch"), 2: ("z", "yaw")}


def describe_weak(rel_std: float, D: np.ndarray, rotation_rms: np.ndarray | None = None) -> dict:
    """A weakly determined tensor combination in a lab engineer's words.

    rel_std: σ of the combination / (tr J / 3); D (3,3) unit-norm direction.  With
    ``rotation_rms`` (3,) rad/s, body axes, the text says how much the body turned about
    the axis involved ("the body hardly turned about z").
    """
    theta = from_tensor(D)
    k = int(np.argmax(np.abs(theta)))
    key = KEYS[k]
    share = float(theta[k] ** 2 * (1 if k in DIAG else 2))
    text = f"{ENTRY_NAMES[key]} is the most weakly determined combination (σ {100 * rel_std:.3f} % of the mean " \
           f"diagonal; {100 * share:.0f} % of the direction)"
    if rotation_rms is not None:
        axes = sorted({i for i in (PAIRS_OF[key])})
        r = np.asarray(rotation_rms, float)
        weakest = min(axes, key=lambda a: r[a])
        if r[weakest] < 0.5 * np.max(r):
            ax, word = AXIS_WORDS[weakest]
            text = (f"{ENTRY_NAMES[key]} is weakly determined: the body hardly turned about {ax} ({word} rate "
                    f"{r[weakest]:.2g} rad/s RMS against {np.max(r):.2g} rad/s on the most excited axis; "
                    f"σ {100 * rel_std:.3f} % of the mean diagonal)")
    return {"relative_std": float(rel_std), "direction": {kk: round(float(v), 3) for kk, v in zip(KEYS, theta)},
            "mostly": key, "text": text}


PAIRS_OF = {"ixx": (0,), "iyy": (1,), "izz": (2,), "ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}


def _skew(a) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@dataclass
class _TrackerModel:
    """The tracker's complementary filters linearised about a pose (see module docstring).

    Inputs (8 + N): gyro noise (3, IMU axes), accelerometer noise (3, IMU axes),
    inclinometer noise (2), then an error of each cable's constraint length (N, m);
    outputs (6): world-frame rotation error φ (rad) and world position error of the body
    origin (m)."""

    R0: np.ndarray          # body -> world at equilibrium
    R_imu: np.ndarray       # IMU -> body
    r_imu_w: np.ndarray     # IMU position from the body origin, world axes
    C_phi: np.ndarray       # (3,3) correction rate per rotation error, 1/s
    C_noise: np.ndarray     # (3,8+N) correction rate per input
    LV: np.ndarray          # (4,3) constraint solution [dp (3); yaw] per rotation error
    L: np.ndarray           # (4,N) constraint solution per length error
    U: np.ndarray           # (N,3) cable directions (world, body anchor -> ceiling)
    V: np.ndarray           # (N,3) d length / d φ = -V
    k_bias: float           # bias integral gain: β' = -k_bias · correction
    w_pos: float            # position filter natural frequency, rad/s
    g: float

    def response(self, f: np.ndarray) -> np.ndarray:
        """(K, 6, 8+N) complex frequency response at f (K,) Hz."""
        f = np.asarray(f, float)
        n_in = self.C_noise.shape[1]
        out = np.zeros((len(f), 6, n_in), complex)
        s = 2j * np.pi * np.maximum(f, 1e-7)   # f = 0: the limit (finite for the length inputs, 0 for noise)
        gain = 1.0 + self.k_bias / s                                   # PI: correction + bias integral
        A = s[:, None, None] * np.eye(3) - gain[:, None, None] * self.C_phi
        Bn = np.zeros((len(s), 3, n_in), complex)
        Bn[:, :, :3] = self.R0 @ self.R_imu
        Bn += gain[:, None, None] * self.C_noise
        Phi = np.linalg.solve(A, Bn)                                    # φ per input
        wn = self.w_pos
        hp = s / (s + wn) ** 3                                          # x = hp·δa + lp·(constraint target)
        lp = 1.0 - s**3 / (s + wn) ** 3
        fw = np.array([0.0, 0.0, self.g])
        Xphi = hp[:, None, None] * (-_skew(fw)) + lp[:, None, None] * self.LV[:3]
        Xd = np.zeros((len(s), 3, n_in), complex)
        Xd[:, :, 3:6] = hp[:, None, None] * (self.R0 @ self.R_imu)
        Xd[:, :, 8:] = lp[:, None, None] * self.L[:3]
        out[:, :3] = Phi
        out[:, 3:] = (Xphi + _skew(self.r_imu_w)) @ Phi + Xd           # origin = IMU point + r × φ
        return out


def tracker_model(rig: Rig, position: np.ndarray, R0: np.ndarray, tracker_params: dict | None = None,
                  ) -> _TrackerModel:
    """Linearise :class:`~rig_identification.estimation.tracker.PoseTracker` (default parameters, or ``tracker_params``)
    about the pose (origin ``position`` (3,) world m, ``R0`` (3,3) body -> world)."""
    tp = PoseTracker(rig, **(tracker_params or {}))
    R_imu = rig.imu.rotation.as_matrix()
    r_imu_w = R0 @ rig.imu.position
    p_imu = position + r_imu_w
    rb = (rig.body_anchors - rig.imu.position) @ R0.T
    v = rig.ceiling_anchors - (p_imu + rb)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    V = np.cross(rb, u)                                  # d length / d φ = -V φ
    G = np.column_stack([-u, -V[:, 2]])
    GtG = G.T @ G
    # the tracker's regularisation (PoseTracker._constraint_correction): the yaw by YAW_PRIOR
    Lam = 1e-12 * np.trace(GtG) * np.eye(4)
    Lam[3, 3] = YAW_PRIOR * float(np.trace(GtG[:3, :3]))
    L = np.linalg.solve(GtG + Lam, G.T)
    LV = L @ V
    ez = np.array([0.0, 0.0, 1.0])
    C_phi = (1.0 / tp.tau_yaw) * np.outer(ez, LV[3])
    C_noise = np.zeros((3, 8 + len(u)))
    C_noise[:, 8:] = (1.0 / tp.tau_yaw) * np.outer(ez, L[3])
    g = rig.gravity
    if rig.inclinometer is not None:
        axes = (R0 @ rig.inclinometer.rotation.as_matrix())[:, :2].T
        pred = np.arcsin(np.clip(axes[:, 2], -1, 1))
        H = np.column_stack([axes[:, 1], -axes[:, 0], np.zeros(2)]) / np.cos(pred)[:, None]
        Hp = np.linalg.pinv(H)
        C_phi = C_phi - (1.0 / tp.tau_tilt) * Hp @ H
        C_noise[:, 6:8] = (1.0 / tp.tau_tilt) * Hp
    else:  # tilt from the accelerometer's gravity direction, slowly
        C_phi = C_phi - (1.0 / tp.tau_tilt_accel) * np.diag([1.0, 1.0, 0.0])
        C_noise[:, 3:6] = (1.0 / (tp.tau_tilt_accel * g)) * np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 0]]) @ R0 @ R_imu
    # a direction no reference corrects (the yaw of radially splayed cables) integrates the gyro
    # noise: a pole at s = 0, whose response the FFT-based adjoint of predict_from_trajectory
    # cannot represent on a finite record (the circular sawtooth of 1/s put σ 20× too large on a
    # wide-splayed rig); a leak far slower than any fit band stands in for the band-pass that
    # removes the drift
    C_phi = C_phi - DRIFT_LEAK * np.eye(3)
    return _TrackerModel(R0, R_imu, r_imu_w, C_phi, C_noise, LV, L, u, V, tp.tau_tilt / tp.tau_bias**2,
                         2 * np.pi * tp.f_position, g)


def wrench_jacobians(rig: Rig, position: np.ndarray, R: np.ndarray, tensions: np.ndarray,
                     exciter_xy: np.ndarray | None):
    """Torque sensitivities of :func:`~rig_identification.estimation.preprocessor.generalized_wrench` at every sample.

    position (M,3) world m; R (M,3,3) body -> world; tensions (M,N) N; exciter_xy (M,2) N or
    None.  Returns D_phi (M,3,3) N·m/rad (world-frame rotation of the pose, R -> exp(φ×) R),
    D_p (M,3,3) N·m/m (world position), W_T (M,3,N) m (per newton of tension), W_e (M,3,2) m
    (per newton of exciter force).  Analytic: the torque about the CG is
    M = Σ_i T_i (b_i − c) × u_i with u_i = r_i/|r_i|, r_i = Rᵀ(A_i − p) − b_i (body axes; the
    preprocessor's geometry, thesis eqs. 2.13–2.19), so ∂M/∂x = Σ_i T_i (b_i − c) × (I − u_i u_iᵀ)
    ∂r_i/∂x / |r_i| with ∂r_i/∂φ_j = −Rᵀ(e_j × (A_i − p)) and ∂r_i/∂p_j = −Rᵀ e_j; the exciter's
    force is measured in body axes, so the pose does not turn it."""
    c = rig.require_cg()
    b, arm = rig.body_anchors, rig.body_anchors - c
    w = rig.ceiling_anchors[None] - position[:, None, :]          # (M,N,3) world, origin -> ceiling anchor
    rel = np.einsum("mji,mnj->mni", R, w) - b[None]              # (M,N,3) body axes, anchor -> ceiling
    length = np.sqrt(np.einsum("mni,mni->mn", rel, rel))[:, :, None]
    u = rel / length

    def d_torque(d_rel):   # (M,N,3) or (M,1,3) -> (M,3)
        du = (d_rel - u * np.einsum("mni,mni->mn", u, d_rel)[:, :, None]) / length
        return np.einsum("mn,mni->mi", tensions, np.cross(arm[None], du))

    M = len(position)
    D_phi = np.zeros((M, 3, 3))
    D_p = np.zeros((M, 3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1.0
        D_phi[:, :, j] = d_torque(-np.einsum("mji,mnj->mni", R, np.cross(e, w)))
        D_p[:, :, j] = d_torque(-R[:, j, None, :])
    W_T = np.cross(arm[None], u).transpose(0, 2, 1).copy()
    W_e = np.zeros((M, 3, 2))
    if exciter_xy is not None and rig.exciter is not None:
        Re = rig.exciter.rotation.as_matrix()[:, :2]
        for i in range(2):
            W_e[:, :, i] = np.cross(rig.exciter.position - c, Re[:, i])
    return D_phi, D_p, W_T, W_e


def sosfiltfilt_adjoint(sos: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transpose of ``scipy.signal.sosfiltfilt(sos, ·, axis=0)`` (default odd padding)
    applied to v (N, k): <sosfiltfilt(x), v> = <x, adjoint(v)> for every x."""
    n_sec = sos.shape[0]
    ntaps = 2 * n_sec + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
    pad = 3 * ntaps
    N = v.shape[0]
    L = N + 2 * pad
    zi = sosfilt_zi(sos)
    r = sosfilt(sos, np.zeros(L), zi=zi)[0]              # zero-input response per unit initial value

    def causal_T(g):   # transpose of zero-state causal filtering: reverse, filter, reverse
        return sosfilt(sos, g[::-1], axis=0)[::-1]

    g3 = np.zeros((L,) + v.shape[1:])
    g3[pad:pad + N] = v
    g2 = g3[::-1]
    gw = causal_T(g2)
    gw[0] += np.tensordot(r, g2, axes=(0, 0))
    gy1 = gw[::-1]
    ge = causal_T(gy1)
    ge[0] += np.tensordot(r, gy1, axes=(0, 0))
    # odd extension: ext = [2 x0 - x[pad:0:-1], x, 2 x[-1] - x[-2:-(pad+2):-1]]
    gx = ge[pad:pad + N].copy()
    left, right = ge[:pad], ge[pad + N:]
    gx[0] += 2 * left.sum(0)
    gx[1:pad + 1] -= left[::-1]
    gx[-1] += 2 * right.sum(0)
    gx[N - 1 - pad:N - 1] -= right[::-1]
    return gx


def cumtrapz_adjoint(g: np.ndarray, dt: float) -> np.ndarray:
    """Transpose of the cumulative trapezoid integral (initial 0) along axis 0 — the
    identifier's cumulative Simpson rule to O((f dt)²) in the pass band."""
    C = np.cumsum(g[::-1], axis=0)[::-1]   # C[k] = Σ_{i≥k} g[i]
    out = np.zeros_like(g)
    out[1:] += C[1:]
    out[:-1] += C[1:]
    return 0.5 * dt * out


@dataclass
class Trajectory:
    """The true motion of a planned run at the IMU samples (noise-free simulation).

    t (K,) s from the start; omega (K,3) rad/s body; torque (K,3) N·m about the CG, body;
    position (K,3) world m of the body origin; R (K,3,3) body -> world; tensions (K,N) N;
    exciter_xy (K,2) N or None; rig; inertia (3,3) nominal tensor; rates (Hz per stream)."""

    t: np.ndarray
    omega: np.ndarray
    torque: np.ndarray
    position: np.ndarray
    R: np.ndarray
    tensions: np.ndarray
    exciter_xy: np.ndarray | None
    rig: Rig
    inertia: np.ndarray
    rates: dict

    warnings: list = field(default_factory=list)

    @staticmethod
    def from_simulation(sim, clean: bool = True) -> "Trajectory":
        """From a noise-free :class:`~rig_identification.model.simulator.SimResult` (its States at the IMU samples).
        clean: keep only the span the identifier would fit — the longest one free of slack
        cables, saturation and gaps (:func:`~rig_identification.pipeline.offline.clean_sensors`) — with its warnings.
        Raises :class:`PlanError` if less than the identifier's minimum is clean."""
        st = sim.states
        keep = np.ones(len(st.t), bool)
        warnings: list[str] = []
        if clean:
            try:
                s = clean_sensors(Recording(sim.rig, sim.sensors, sim.truth, "planned run"), warnings)
            except RecordingError as e:
                raise PlanError(str(e)) from None
            keep = (st.t >= s.t_start - 1e-9) & (st.t <= s.t_end + 1e-9)
        t = st.t[keep] - sim.experiment.stamp_origin
        rig = sim.rig
        R = st.rotation.as_matrix()[keep]
        exc = None
        if sim.sensors.exciter is not None and rig.exciter is not None:
            exc = sim.sensors.exciter.interp(st.t[keep])
        _, torque = generalized_wrench(rig, st.position[keep], R, st.tensions[keep], exc)
        return Trajectory(t, st.omega[keep].copy(), torque, st.position[keep].copy(), R, st.tensions[keep].copy(), exc,
                          rig, sim.experiment.inertia, dict(sim.experiment.sensors.rates), warnings)


def _weights_stationary(tm: _TrackerModel, rig: Rig, D: tuple, P: np.ndarray, sos, fs: float,
                        sig: np.ndarray, n: int) -> np.ndarray:
    """Per-axis variance (3,) of the residual e predicted by the stationary form of the
    noise model (time-averaged sensitivities): the identifier's LM weights are 1/σ²."""
    f = np.fft.rfftfreq(n, 1 / fs)
    mult = np.full(len(f), 2.0)
    mult[0] = 1.0
    if n % 2 == 0:
        mult[-1] = 1.0
    R_imu = rig.imu.rotation.as_matrix()
    var = np.zeros(3)
    for lo in range(0, len(f), FREQ_BLOCK):   # a block of frequencies at a time (memory)
        Hf = stationary_e_response(tm, D, P, sos, fs, f[lo:lo + FREQ_BLOCK], R_imu)
        var += np.einsum("k,kad,d,kad->a", mult[lo:lo + FREQ_BLOCK], Hf, sig**2, Hf.conj()).real
    return var / n


def stationary_e_response(tm, D, P, sos, fs, f, R_imu):
    """(K,3,d) response of the residual e to the noise channels, time-averaged sensitivities."""
    D_phi, D_p, W_T, W_e = (np.mean(x, axis=0) for x in D)
    Ht = tm.response(f)[:, :, :8]
    _, hf = sosfreqz(sos, worN=f, fs=fs)
    F = np.abs(hf) ** 2
    n_T = W_T.shape[1]
    d = 8 + n_T + 2
    H = np.zeros((len(f), 3, d), complex)
    nz = f > 0
    s = 2j * np.pi * f[nz]
    dM = np.zeros((nz.sum(), 3, d), complex)
    dM[:, :, :8] = np.einsum("ij,kjd->kid", D_phi, Ht[nz, :3]) + np.einsum("ij,kjd->kid", D_p, Ht[nz, 3:])
    dM[:, :, 8:8 + n_T] = W_T
    dM[:, :, 8 + n_T:] = W_e
    H[nz] = -np.einsum("ij,kjd->kid", P, dM) / s[:, None, None]
    H[nz, :, :3] += R_imu
    return H * F[:, None, None]


def channel_sigmas(noise: dict, rates: dict, fs: float, n_cables: int, has_incl: bool) -> tuple[np.ndarray, list]:
    """Per-IMU-sample equivalent σ of every noise channel and its source name.  A stream
    at rate r < fs has the in-band density of white noise σ·sqrt(fs/r) at fs."""
    def eq(key, rate_key):
        return noise[key] * math.sqrt(fs / rates[rate_key])
    sig = [noise["gyro"]] * 3 + [noise["accelerometer"]] * 3
    src = ["gyro"] * 3 + ["accelerometer"] * 3
    sig += [eq("inclinometer", "inclinometer") if has_incl else 0.0] * 2
    src += ["inclinometer"] * 2
    sig += [eq("load_cell", "load_cells")] * n_cables
    src += ["load_cell"] * n_cables
    sig += [eq("exciter", "exciter")] * 2
    src += ["exciter"] * 2
    return np.array(sig), src


def _adapts_compliance(rig: Rig, tracker_params: dict | None) -> bool:
    """Whether :class:`~rig_identification.estimation.tracker.PoseTracker` refines the cable compliance online (no
    stiffness in rig.yaml, an inclinometer and load cells)."""
    return rig.inclinometer is not None and not np.isfinite(rig.cable_stiffness).all()


def predict_from_trajectory(traj: Trajectory, noise: dict | None = None, settle: float = 5.0,
                            band_hz: tuple[float, float] | None = None, tracker_params: dict | None = None,
                            seed: int = 0, gyro_sensitivity: bool = False) -> Prediction:
    """Predicted σ of the identified tensor for the run ``traj`` (see module docstring).

    noise: σ per source (keys of :data:`REFERENCE_NOISE`; default the reference levels),
    at ``traj.rates``.  settle: s skipped at the start, as
    :func:`~rig_identification.pipeline.offline.identify_recording`.  band_hz: the fit's pass band (default: what
    :func:`~rig_identification.estimation.signals.auto_band` picks on the gyro with this noise, seeded by
    ``seed``).  gyro_sensitivity: also return the per-sample linear map from the gyro
    noise to the estimate error (``Prediction.gyro_sensitivity``).  Raises
    :class:`PlanError` when the body hardly moves.
    """
    noise = dict(REFERENCE_NOISE if noise is None else noise)
    rig, t = traj.rig, traj.t
    fs = 1.0 / float(np.median(np.diff(t)))
    K = len(t)
    settle = min(settle, 0.1 * (t[-1] - t[0]))
    m = t >= t[0] + max(settle, 0.1) - 1e-9  # as identify_recording: settle time (after the tracker start)
    tw = t[m]
    J = np.asarray(traj.inertia, float)
    P = np.linalg.inv(J)
    duration = tw[-1] - tw[0]
    if band_hz is None:
        rng = np.random.default_rng(seed)
        w_noisy = traj.omega[m] + noise["gyro"] * rng.standard_normal((len(tw), 3))
        lo, hi = auto_band(w_noisy, fs)
        lo = max(lo, 2.0 / duration)
        band_hz = (lo, hi)
    try:
        seg = prepare_segment(tw, traj.omega[m], traj.torque[m], band_hz, what="planned run")
    except ValueError as e:
        raise PlanError(str(e)) from None
    lo, hi = seg.band
    sos = butter(4, [lo, hi], btype="bandpass", fs=fs, output="sos")  # the identifier's prefilter
    E = basis()
    j = from_tensor(J)
    u = seg.IM - np.einsum("m,mni->ni", j, seg.G)
    yhat = u @ P.T
    A3 = -np.einsum("ij,knj->nik", P, np.einsum("kij,nj->kni", E, yhat) + seg.G)   # (Nw,3,6)
    # the tracker and preprocessor sensitivities
    R0 = Rotation.from_matrix(traj.R).mean().as_matrix()
    tm = tracker_model(rig, traj.position.mean(0), R0, tracker_params)
    D = wrench_jacobians(rig, traj.position, traj.R, traj.tensions, traj.exciter_xy)
    sig, src = channel_sigmas(noise, traj.rates, fs, traj.tensions.shape[1], rig.inclinometer is not None)
    resid_var = _weights_stationary(tm, rig, D, P, sos, fs, sig, len(tw))
    # adjoint, one gyro axis at a time: Γ_a,k = d(Σ_t A_t,aᵀ e_t,a)/d noise (unweighted);
    # the weighted estimator's Γ = Σ_a w_a Γ_a.  Column (a, k) sees the residual of axis a
    # only: the adjoints of the band-pass and of the integral (linear, column by column) act
    # once on A3's 18 columns, and the moment's path (e = −P z) scales them by P[a, ·]
    Nw = len(tw)
    i0 = K - Nw                                                  # the window: the trajectory's tail
    H1 = sosfiltfilt_adjoint(sos, A3.reshape(Nw, 18))            # d/d(gyro noise, body), direct path
    h = cumtrapz_adjoint(H1, 1.0 / fs).T.reshape(3, 6, Nw)       # (a, k, n) d/d z per unit P
    H1 = H1.T.reshape(3, 6, Nw)
    R_imu = rig.imu.rotation.as_matrix()
    D_phi, D_p, W_T, W_e = (x[i0:] for x in D)

    def through_moment(Dm):
        """Γ (c, a, k, Nw) of the c noise channels whose moment error (body axes) is Dm (Nw,3,c)
        times the channel: −(P Dm)[a, c] h[a, k]."""
        return -np.einsum("ab,nbc->can", P, Dm)[:, :, None, :] * h[None]

    # gyroscopic term: δM -= ω × J n + n × J ω (n: body-axis gyro noise)
    Om = traj.omega[i0:]
    Sk = np.zeros((Nw, 3, 3))
    Sk[:, 0, 1], Sk[:, 0, 2], Sk[:, 1, 2] = -Om[:, 2], Om[:, 1], -Om[:, 0]
    Sk -= Sk.transpose(0, 2, 1)
    JO = Om @ J.T
    SJ = np.zeros((Nw, 3, 3))
    SJ[:, 0, 1], SJ[:, 0, 2], SJ[:, 1, 2] = -JO[:, 2], JO[:, 1], -JO[:, 0]
    SJ -= SJ.transpose(0, 2, 1)
    n_T = W_T.shape[2]
    # Γ's products per channel d, Σ_n Γ[d,a,k,n] Γ[d,b,l,n] (18,18): the load cells' and the
    # exciter's (zero before the window) now, the others once Γ (channels 0-7) is complete
    meat = [None] * (8 + n_T + 2)
    for d0, Dm in ((8, W_T), (8 + n_T, W_e)):
        for c, g in enumerate(through_moment(Dm).reshape(-1, 18, Nw)):
            meat[d0 + c] = g @ g.T
    # the pose errors' channels, −(P D)[a, c] (c: rotation 3, position 3), times h[a] per weight axis
    Q_pe = -np.einsum("ab,nbc->can", P, np.concatenate([D_phi, D_p], axis=2))   # (6, a, Nw)
    # the tracker is causal LTI from the start; its adjoint is the correlation with its response,
    # by FFT over ≥ 2K samples (a fast length: 2K may be twice a prime).  Its inputs in blocks of
    # four (memory: one block's response and Γ at a time): the cable lengths' first — they give
    # the compliance's estimating equation (when the tracker adapts it) — then channels 0-7
    adapts = _adapts_compliance(rig, tracker_params)
    nfft = next_fast_len(2 * K, real=True)
    f = np.fft.rfftfreq(nfft, 1 / fs)
    blocks = ([(8, 8 + n_T)] if adapts else []) + [(0, 4), (4, 8)]
    gsens = np.zeros((3, 6))                                      # the estimating equation per unit δc
    gam_spec = None
    if adapts:
        # the tracker's cable compliance (rig.yaml without stiffness): its estimate
        # δc = <e_len, ΔT>/<ΔT, ΔT> over the first pass's second half
        # (tracker_replay.pass_compliance) is a linear function γᵀn of the noise, and lengthens
        # every constraint by ΔT(t)·δc: the static part offsets the pose for the whole run (seen
        # through the tension swing in D(t)), the dynamic part pulls the pose at the exciter
        # frequency
        dT = traj.tensions - traj.tensions[t < t[0] + 0.1 + 1e-9].mean(0)
        late = t >= t[0] + 0.5 * (t[-1] - t[0])
        S1 = float(np.sum(dT[late] ** 2))
        if S1 > 0:
            e_phi = -(tm.V - tm.U @ _skew(tm.r_imu_w))              # e_len = e_phi φ - U δp_o
            gam_pe = np.zeros((6, K))
            gam_pe[:3, late] = (dT[late] @ e_phi / S1).T
            gam_pe[3:, late] = (-dT[late] @ tm.U / S1).T
            gam_spec = rfft(gam_pe, n=nfft, axis=-1)                 # (6, F)
    x = np.zeros((6, 3, nfft))
    gyro_gam = None
    for r0, r1 in blocks:
        Hb = np.empty((len(f), r1 - r0, 6), complex)              # conjugated response (F, inputs, 6)
        for lo in range(0, len(f), FREQ_BLOCK):
            Hb[lo:lo + FREQ_BLOCK] = tm.response(f[lo:lo + FREQ_BLOCK])[:, :, r0:r1].conj().transpose(0, 2, 1)
        Gb = np.zeros((r1 - r0, 3, 6, K)) if r0 < 8 else None     # Γ (channel, a, k, n)
        if r0 == 0:   # body gyro noise = R_imu · IMU-axis noise: the direct path, the gyroscopic moment's
            Gb[:3, :, :, i0:] = R_imu.T[:, :, None, None] * H1[None] - through_moment((Sk @ J - SJ) @ R_imu)
        for a in range(3):   # a weight axis and three entries at a time
            for k in (slice(0, 3), slice(3, 6)):
                x[..., i0:K] = Q_pe[:, a, None, :] * h[a, k][None]
                S = rfft(x, axis=-1).transpose(2, 0, 1)           # (F, 6, 3)
                g_tr = irfft(np.matmul(Hb, S).transpose(1, 2, 0), n=nfft, axis=-1)[..., :K]   # (inputs, 3, K)
                if Gb is None:
                    gsens[a, k] = np.einsum("ni,ikn->k", traj.tensions, g_tr)
                else:
                    Gb[:, a, k] += g_tr
                del S, g_tr
        if Gb is not None:
            if gam_spec is not None:
                gam = irfft(np.einsum("fdo,of->df", Hb, gam_spec), n=nfft, axis=-1)[:, :K]
                Gb += gam[:, None, None, :] * gsens[None, :, :, None]
            for d, g in enumerate(Gb.reshape(r1 - r0, 18, K)):
                meat[r0 + d] = g @ g.T
            if r0 == 0 and gyro_sensitivity:
                gyro_gam = Gb[:3]
        del Hb, Gb
    del x
    axis_meats = {}
    for s_name in SOURCES:
        sel = np.nonzero((np.array(src) == s_name) & (sig > 0))[0]
        if len(sel):
            # Σ_nd σ_d² Γ[d,a,k,n] Γ[d,b,l,n]
            M = sum(sig[i] ** 2 * meat[i] for i in sel)
            axis_meats[s_name] = M.reshape(3, 6, 3, 6).transpose(0, 2, 1, 3)
    axis_bread = np.einsum("nai,naj->aij", A3, A3)
    A = A3.reshape(-1, 6)
    FA = seg.filt(A3.reshape(Nw, -1)).reshape(-1, 6)
    pred = Prediction.assemble(J, axis_bread, axis_meats, A.T @ A, noise["gyro"] ** 2 * FA.T @ FA, resid_var,
                               seg.band, float(duration), Nw, np.sqrt(np.mean(seg.y**2, axis=0)))
    if gyro_sensitivity:   # δj = B⁻¹ Σ_a w_a Γ_aᵀ ν, the same pieces as the sandwich
        Bi = np.linalg.inv(np.einsum("a,aij->ij", pred.weights, axis_bread))
        pred.gyro_sensitivity = np.einsum("kl,ndl->ndk", Bi, np.einsum("a,dakn->ndk", pred.weights, gyro_gam))
    return pred
