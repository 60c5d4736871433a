"""Know before you shake: predicted inertia uncertainty of a planned run, and experiment design.

Prediction
----------
The identifier (:mod:`.identification`) fits ``J`` by weighted least squares on the
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
:class:`~.tracker.PoseTracker`), ``D_φ(t)``, ``D_p(t)`` and the load cells' lever arms are
differentiated from :func:`~.preprocessor.generalized_wrench` at every sample (so a slow
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

Design
------
:func:`plan_experiment` searches the exciter frequency, mounting point (corners of the box
spanned by the body anchors and the rig's exciter position), spin axis (body x, y, z or a
diagonal between two of them, :data:`SPIN_AXES`), sense of rotation and force amplitude: a fast screen of the linearised rig (:func:`linear_rig`)
driven from rest by the spinning-up force and the stationary form of the noise model, then
simulations of the best candidates with the full predictor; the amplitude is the largest for
which the simulated run keeps every cable above ``min_tension_ratio`` of its static tension,
the rotation (start-up included) below ``max_rotation_deg``, the force below ``max_force``
and the swing from growing.  Frequencies near a mode, its double or a sum of two modes are
skipped (:func:`resonances`).  A single steady harmonic cannot determine all six entries
(the body's angular velocity then stays in one plane: the moment of inertia about its normal
is seen only through the start-up transients), so a second run — complementary, or the same
again — is added when allowed; it may also use another cable geometry (``geometries``: the
lab's own, or :func:`geometry_variants`, the ceiling anchors moved), which changes the modes
and so the directions the rig moves in.  Pairs are ranked on short simulations and the best
few confirmed by full-length ones before one is chosen.  Objective: ``"baseline"`` (the least-improved entry as much
better than a baseline run as possible) or ``"relative"`` (the largest σ relative to the
entry: diagonals to themselves, products to the largest diagonal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.signal import butter, sosfilt, sosfilt_zi, sosfreqz
from scipy.spatial.transform import Rotation

from .identification import KEYS, _prepare_segment, auto_band, basis, from_tensor, to_tensor, weak_directions
from .preprocessor import generalized_wrench
from .rig import Rig

REFERENCE_NOISE = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 0.0002}
"""σ of the reference recordings' white sensor noise (``/work/shared/recordings/*/truth.yaml``):
rad/s, m/s², N, N, rad."""
REFERENCE_RATES = {"imu": 200.0, "load_cells": 200.0, "exciter": 200.0, "inclinometer": 50.0}
"""Sample rates of the reference recordings, Hz."""
SOURCES = ("gyro", "accelerometer", "inclinometer", "load_cell", "exciter")
"""Noise sources of the prediction (the tracker's compliance estimate enters through them)."""
DIAG = (0, 3, 5)  # ixx, iyy, izz in KEYS order
_DIAGONALS = {"x+y": (1, 1, 0), "x-y": (1, -1, 0), "x+z": (1, 0, 1), "x-z": (1, 0, -1), "y+z": (0, 1, 1),
              "y-z": (0, 1, -1)}


def _spin_rpy(v) -> tuple:
    """Exciter rpy (extrinsic xyz, rad) whose z axis is the body-frame direction ``v``."""
    v = np.asarray(v, float) / np.linalg.norm(v)
    R, _ = Rotation.align_vectors([v], [[0.0, 0.0, 1.0]])
    return tuple(float(a) for a in R.as_euler("xyz"))


SPIN_AXES = {"x": (0.0, math.pi / 2, 0.0), "y": (-math.pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0),
             **{k: _spin_rpy(v) for k, v in _DIAGONALS.items()}}
"""Exciter rpy (body -> exciter frame) whose z axis (the spin axis) is body x, y, z or the
diagonal between two of them ("x+y": along (1, 1, 0)/√2, "x-y": along (1, −1, 0)/√2, …).
A diagonal axis turns the force in a plane that holds one body axis and the other two's
diagonal: on the thesis rig it drives roll and pitch in phase, which the products of
inertia need (case 16: Ixy's σ 3.1× below the thesis excitation's, against 2.8× with the
body axes alone)."""
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
    of :func:`~.identification.identify_inertia_joint`): information (AᵀWA) and noise
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


# --- the linear noise model --------------------------------------------------------------

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
        nz = np.ones(len(f), bool)
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
        out[nz, :3] = Phi
        out[nz, 3:] = (Xphi + _skew(self.r_imu_w)) @ Phi + Xd           # origin = IMU point + r × φ
        return out


def tracker_model(rig: Rig, position: np.ndarray, R0: np.ndarray, tracker_params: dict | None = None,
                  ) -> _TrackerModel:
    """Linearise :class:`~.tracker.PoseTracker` (default parameters, or ``tracker_params``)
    about the pose (origin ``position`` (3,) world m, ``R0`` (3,3) body -> world)."""
    from .tracker import PoseTracker
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
    L = np.linalg.solve(GtG + 1e-12 * np.trace(GtG) * np.eye(4), G.T)
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
    return _TrackerModel(R0, R_imu, r_imu_w, C_phi, C_noise, LV, L, u, V, tp.tau_tilt / tp.tau_bias**2,
                         2 * np.pi * tp.f_position, g)


def wrench_jacobians(rig: Rig, position: np.ndarray, R: np.ndarray, tensions: np.ndarray,
                     exciter_xy: np.ndarray | None, h: float = 1e-6):
    """Torque sensitivities of :func:`~.preprocessor.generalized_wrench` at every sample.

    position (M,3) world m; R (M,3,3) body -> world; tensions (M,N) N; exciter_xy (M,2) N or
    None.  Returns D_phi (M,3,3) N·m/rad (world-frame rotation of the pose), D_p (M,3,3)
    N·m/m (world position), W_T (M,3,N) m (per newton of tension), W_e (M,3,2) m (per
    newton of exciter force), by central / forward differences (the torque is linear in
    the forces)."""
    def tq(p, Rm, T, e):
        return generalized_wrench(rig, p, Rm, T, e)[1]
    M = len(position)
    D_phi = np.zeros((M, 3, 3))
    D_p = np.zeros((M, 3, 3))
    for j in range(3):
        d = np.zeros(3)
        d[j] = h
        Rp, Rm = Rotation.from_rotvec(d).as_matrix(), Rotation.from_rotvec(-d).as_matrix()
        D_phi[:, :, j] = (tq(position, Rp @ R, tensions, exciter_xy) - tq(position, Rm @ R, tensions, exciter_xy)) / (2 * h)
        D_p[:, :, j] = (tq(position + d, R, tensions, exciter_xy) - tq(position - d, R, tensions, exciter_xy)) / (2 * h)
    base = tq(position, R, tensions, None)
    n = tensions.shape[1]
    W_T = np.zeros((M, 3, n))
    for i in range(n):
        T = tensions.copy()
        T[:, i] += 1.0
        W_T[:, :, i] = tq(position, R, T, None) - base
    W_e = np.zeros((M, 3, 2))
    if exciter_xy is not None and rig.exciter is not None:
        c = rig.require_cg()
        Re = rig.exciter.rotation.as_matrix()[:, :2]
        for i in range(2):
            W_e[:, :, i] = np.cross(rig.exciter.position - c, Re[:, i])
    return D_phi, D_p, W_T, W_e


def _sosfiltfilt_adjoint(sos: np.ndarray, v: np.ndarray) -> np.ndarray:
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


def _cumtrapz_adjoint(g: np.ndarray, dt: float) -> np.ndarray:
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
        """From a noise-free :class:`~.simulator.SimResult` (its States at the IMU samples).
        clean: keep only the span the identifier would fit — the longest one free of slack
        cables, saturation and gaps (:func:`~.pipeline.clean_sensors`) — with its warnings.
        Raises :class:`PlanError` if less than the identifier's minimum is clean."""
        st = sim.states
        keep = np.ones(len(st.t), bool)
        warnings: list[str] = []
        if clean:
            from .pipeline import clean_sensors
            from .recording import Recording, RecordingError
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
    Hf = _stationary_e_response(tm, D, P, sos, fs, f, rig.imu.rotation.as_matrix())
    mult = np.full(len(f), 2.0)
    mult[0] = 1.0
    if n % 2 == 0:
        mult[-1] = 1.0
    return np.einsum("k,kad,d,kad->a", mult, Hf, sig**2, Hf.conj()).real / n


def _stationary_e_response(tm, D, P, sos, fs, f, R_imu):
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


def _channel_sigmas(noise: dict, rates: dict, fs: float, n_cables: int, has_incl: bool) -> tuple[np.ndarray, list]:
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
    """Whether :class:`~.tracker.PoseTracker` refines the cable compliance online (no
    stiffness in rig.yaml, an inclinometer and load cells)."""
    return rig.inclinometer is not None and not np.isfinite(rig.cable_stiffness).all()


def predict_from_trajectory(traj: Trajectory, noise: dict | None = None, settle: float = 5.0,
                            band_hz: tuple[float, float] | None = None, tracker_params: dict | None = None,
                            seed: int = 0, gyro_sensitivity: bool = False) -> Prediction:
    """Predicted σ of the identified tensor for the run ``traj`` (see module docstring).

    noise: σ per source (keys of :data:`REFERENCE_NOISE`; default the reference levels),
    at ``traj.rates``.  settle: s skipped at the start, as
    :func:`~.pipeline.identify_recording`.  band_hz: the fit's pass band (default: what
    :func:`~.identification.auto_band` picks on the gyro with this noise, seeded by
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
        seg = _prepare_segment(tw, traj.omega[m], traj.torque[m], band_hz, what="planned run")
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
    sig, src = _channel_sigmas(noise, traj.rates, fs, traj.tensions.shape[1], rig.inclinometer is not None)
    resid_var = _weights_stationary(tm, rig, D, P, sos, fs, sig, len(tw))
    # adjoint, one gyro axis at a time: Γ_a,k = d(Σ_t A_t,aᵀ e_t,a)/d noise (unweighted);
    # the weighted estimator's Γ = Σ_a w_a Γ_a
    Nw = len(tw)
    V = np.zeros((Nw, 3, 3, 6))                                  # (n, axis of e, weight axis a, k)
    for a in range(3):
        V[:, a, a, :] = A3[:, a, :]
    Vf = V.reshape(Nw, 54)
    g_direct = _sosfiltfilt_adjoint(sos, Vf).reshape(Nw, 3, 18)  # d/d(gyro noise, body), direct path
    gz = -np.einsum("nbx,ba->nax", V.reshape(Nw, 3, 18), P)      # e = -P z, z = F ∫ δM
    gz = _sosfiltfilt_adjoint(sos, gz.reshape(Nw, 54))
    gM = _cumtrapz_adjoint(gz, 1.0 / fs).reshape(Nw, 3, 18)      # d/d δM (window)
    gM_all = np.zeros((K, 3, 18))
    gM_all[m] = gM
    R_imu = rig.imu.rotation.as_matrix()
    # gyroscopic term: δM -= ω × J n + n × J ω (n: body-axis gyro noise)
    Om = traj.omega
    Sk = np.zeros((K, 3, 3))
    Sk[:, 0, 1], Sk[:, 0, 2], Sk[:, 1, 2] = -Om[:, 2], Om[:, 1], -Om[:, 0]
    Sk -= Sk.transpose(0, 2, 1)
    JO = Om @ J.T
    SJ = np.zeros((K, 3, 3))
    SJ[:, 0, 1], SJ[:, 0, 2], SJ[:, 1, 2] = -JO[:, 2], JO[:, 1], -JO[:, 0]
    SJ -= SJ.transpose(0, 2, 1)
    C = Sk @ J - SJ
    g_body = np.zeros((K, 3, 18))
    g_body[m] = g_direct
    g_body -= np.einsum("nai,nax->nix", C, gM_all)
    D_phi, D_p, W_T, W_e = D
    g_pe = np.concatenate([np.einsum("nai,nax->nix", D_phi, gM_all), np.einsum("nai,nax->nix", D_p, gM_all)], axis=1)
    g_T = np.einsum("nai,nax->nix", W_T, gM_all)
    g_e = np.einsum("nai,nax->nix", W_e, gM_all)
    # the tracker is causal LTI from the start; its adjoint is the correlation with its response
    nfft = 2 * K
    f = np.fft.rfftfreq(nfft, 1 / fs)
    Ht = tm.response(f)                                          # (F,6,8+N)
    g_all = np.fft.irfft(np.einsum("fod,fox->fdx", Ht.conj(), np.fft.rfft(g_pe, n=nfft, axis=0)), n=nfft,
                         axis=0)[:K]                             # (K,8+N,18)
    g_tr = g_all[:, :8]
    g_tr[:, :3] += np.einsum("ab,nax->nbx", R_imu, g_body)       # body gyro noise = R_imu · IMU-axis noise
    Gam = np.concatenate([g_tr, g_T, g_e], axis=1)               # (K, d, 18)
    if _adapts_compliance(rig, tracker_params):
        # the tracker's cable compliance (rig.yaml without stiffness): its estimate
        # δc = <e_len, ΔT>/<ΔT, ΔT> over the first pass's second half
        # (tracker.pass_compliance) is a linear function γᵀn of the noise, and lengthens
        # every constraint by ΔT(t)·δc
        dT = traj.tensions - traj.tensions[t < t[0] + 0.1 + 1e-9].mean(0)
        late = t >= t[0] + 0.5 * (t[-1] - t[0])
        S1 = float(np.sum(dT[late] ** 2))
        if S1 > 0:
            # a compliance error δc lengthens the constraints by T(t)·δc: the static part
            # offsets the pose for the whole run (seen through the tension swing in D(t)),
            # the dynamic part pulls the pose at the exciter frequency
            gsens = np.einsum("ni,nix->x", traj.tensions, g_all[:, 8:])   # estimating equation per unit δc
            e_phi = -(tm.V - tm.U @ _skew(tm.r_imu_w))              # e_len = e_phi φ - U δp_o
            gam_pe = np.zeros((K, 6))
            gam_pe[late, :3] = dT[late] @ e_phi / S1
            gam_pe[late, 3:] = -dT[late] @ tm.U / S1
            gam = np.fft.irfft(np.einsum("fod,fo->fd", Ht[:, :, :8].conj(), np.fft.rfft(gam_pe, n=nfft, axis=0)),
                               n=nfft, axis=0)[:K]               # (K,8)
            Gam[:, :8] += gam[:, :, None] * gsens[None, None, :]
    Gam = Gam.reshape(K, -1, 3, 6)                                # (K, d, a, k)
    src_arr = np.array(src)
    axis_meats = {}
    for s_name in SOURCES:
        sel = (src_arr == s_name) & (sig > 0)
        if sel.any():
            Gs = Gam[:, sel] * sig[sel][None, :, None, None]
            axis_meats[s_name] = np.einsum("ndak,ndbl->abkl", Gs, Gs)
    axis_bread = np.einsum("nai,naj->aij", A3, A3)
    A = A3.reshape(-1, 6)
    FA = seg.filt(A3.reshape(Nw, -1)).reshape(-1, 6)
    pred = Prediction.assemble(J, axis_bread, axis_meats, A.T @ A, noise["gyro"] ** 2 * FA.T @ FA, resid_var,
                               seg.band, float(duration), Nw, np.sqrt(np.mean(seg.y**2, axis=0)))
    if gyro_sensitivity:   # δj = B⁻¹ Σ_a w_a Γ_aᵀ ν, the same pieces as the sandwich
        Bi = np.linalg.inv(np.einsum("a,aij->ij", pred.weights, axis_bread))
        pred.gyro_sensitivity = np.einsum("kl,ndl->ndk", Bi, np.einsum("a,ndak->ndk", pred.weights, Gam[:, :3]))
    return pred


def predict_experiment(exp, noise: dict | None = None, settle: float = 5.0, band_hz=None,
                       tracker_params: dict | None = None):
    """Simulate ``exp`` (:class:`~.simulator.Experiment`) without sensor noise and predict
    the σ of the identified tensor at the noise levels ``noise`` (default: the reference
    recordings').  Returns (Prediction, SimResult).  Raises
    :class:`~.simulator.SimulationError`, :class:`PlanError`."""
    from .simulator import simulate
    sim = simulate(exp.with_overrides(noise_free=True))
    return predict_from_trajectory(Trajectory.from_simulation(sim), noise, settle, band_hz, tracker_params), sim


# --- experiment design --------------------------------------------------------------------

@dataclass(frozen=True)
class Run:
    """One planned exciter run: rotating force ``amplitude`` N at ``frequency`` Hz, acting at
    ``position`` (3,) body frame m, spinning about body ``spin_axis`` (a key of :data:`SPIN_AXES`),
    for ``duration`` s (spin-up ramp ``ramp_time`` s, as the reference simulator)."""

    frequency: float
    amplitude: float
    position: tuple
    spin_axis: str
    duration: float = 120.0
    ramp_time: float = 2.0
    rpy: tuple | None = None    # exciter rpy if not one of SPIN_AXES (e.g. the rig's own)
    direction: int = 1          # sense of rotation about the spin axis (+1: x toward y of the exciter frame)

    @property
    def exciter_rpy(self) -> tuple:
        return tuple(self.rpy) if self.rpy is not None else SPIN_AXES[self.spin_axis]

    def to_dict(self) -> dict:
        return {"frequency_hz": float(self.frequency), "amplitude_n": float(self.amplitude),
                "exciter_position_body_m": [float(x) for x in self.position], "spin_axis_body": self.spin_axis,
                "spin_axis_unit_body": [round(float(x), 6) + 0.0 for x in
                                        Rotation.from_euler("xyz", self.exciter_rpy).apply([0, 0, 1])],
                "exciter_rpy": [float(x) for x in self.exciter_rpy], "direction": int(self.direction),
                "duration_s": float(self.duration),
                "ramp_time_s": float(self.ramp_time), "ramp_shape": "spin_up"}


@dataclass
class Body:
    """The rig and the nominal body: rig (CG from rig.yaml), mass kg, inertia (3,3) kg·m²
    about the CG, body axes; cable stiffness (N,) N/m of the simulation (rig.yaml's, else
    the simulator's 5e6); rates Hz and noise σ of the sensors."""

    rig: Rig
    mass: float
    inertia: np.ndarray
    stiffness: np.ndarray
    rates: dict
    noise: dict

    def experiment(self, run: Run, seed: int = 0):
        """The noise-free :class:`~.simulator.Experiment` of ``run``."""
        from .simulator import experiment_from_dict, inertia_entries
        rig = self.rig.to_dict()
        rig.pop("dummy_mass", None)
        rig["body"]["mass"] = float(self.mass)
        rig["body"]["center_of_gravity"] = [float(x) for x in self.rig.require_cg()]
        rig["exciter"] = {"position": [float(x) for x in run.position], "rpy": [float(x) for x in run.exciter_rpy]}
        d = {"name": "plan", "rig": rig, "inertia_about_cg": inertia_entries(self.inertia),
             "cable_model": {"type": "spring", "stiffness": [float(k) for k in self.stiffness]},
             "initial": {"equilibrium": True},
             "excitation": {"rotating": {"amplitude": float(run.amplitude), "frequency": float(run.frequency),
                                         "ramp_time": float(run.ramp_time), "ramp_shape": "spin_up", "phase": 0.0,
                                         "direction": int(run.direction), "start_time": 0.0}},
             "duration": float(run.duration),
             "sensors": {"rates_hz": dict(self.rates), "noise": {k: 0.0 for k in REFERENCE_NOISE}},
             "seed": seed}
        return experiment_from_dict(d, "planned run")


@dataclass
class LinearRig:
    """The rig linearised about its static equilibrium (coordinates q = [dp_cg (3, world, m),
    φ (3, world rotation, rad)]): mass M, stiffness K, cable damping C (6,6); length
    Jacobian G (N,6); static tensions T0 (N,) N; cable stiffness k and damping c (N,);
    equilibrium origin position (3,) and rotation R0 (3,3) body -> world."""

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    G: np.ndarray
    T0: np.ndarray
    k: np.ndarray
    c: np.ndarray
    position: np.ndarray
    R0: np.ndarray
    cg: np.ndarray


def linear_rig(body: Body) -> LinearRig:
    """Linearise the spring-cable rig about its equilibrium (as :func:`~.modes.natural_modes`,
    plus the cables' damping), for the steady-state response of the design screen."""
    from .modes import _gradients, _length_fn, _length_hessians
    from .simulator import CableModel, equilibrium
    rig = body.rig
    cg = rig.require_cg()
    cm = CableModel.spring(rig, body.mass, stiffness=body.stiffness)
    pos, R0, T = equilibrium(rig, body.mass, cg, cm)
    p_cg = pos + R0.apply(cg)
    R = R0.as_matrix()
    M = np.zeros((6, 6))
    M[:3, :3] = body.mass * np.eye(3)
    M[3:, 3:] = R @ body.inertia @ R.T
    G, _ = _gradients(rig, p_cg, R0, cg)
    H = _length_hessians(_length_fn(rig, p_cg, R0, cg), len(rig.cables))
    taut = T > 0
    K = np.einsum("i,iab->ab", T, H) + np.einsum("i,ia,ib->ab", cm.stiffness * taut, G, G)
    C = np.einsum("i,ia,ib->ab", cm.damping * taut, G, G)
    return LinearRig(M, 0.5 * (K + K.T), C, G, T, cm.stiffness, cm.damping, pos, R, cg)


def _spin_up(f: float, t: np.ndarray, ramp: float) -> tuple[np.ndarray, np.ndarray]:
    """cos θ and sin θ times the amplitude factor of a unit rotating force with a spin-up
    ramp (as :class:`~.simulator.RotatingForce` with ramp_shape spin_up, direction +1)."""
    t = np.asarray(t, float)
    if ramp > 0:
        amp = np.where(t < ramp, (t / ramp) ** 2, 1.0)
        th = np.where(t < ramp, np.pi * f * t**2 / ramp, 2 * np.pi * f * (t - ramp / 2))
    else:
        amp, th = np.ones_like(t), 2 * np.pi * f * t
    return amp * np.cos(th), amp * np.sin(th)


class _Screen:
    """Fast design screen: the linearised rig (:func:`linear_rig`) driven by the rotating
    force from rest (spin-up, transients and steady state), sampled at ``fs_screen``, and
    the stationary form of the noise model (no filter edges, time-averaged sensitivities)."""

    def __init__(self, body: Body, lin: LinearRig, duration: float, settle: float, ramp: float = 2.0,
                 fs_screen: float = 50.0, tracker_params: dict | None = None):
        from scipy.linalg import expm
        self.body, self.lin, self.duration, self.settle, self.ramp = body, lin, duration, settle, ramp
        rig = body.rig
        self.fs = float(body.rates["imu"])
        self.fss = fs_screen
        self.t = np.arange(int(round(duration * fs_screen)) + 1) / fs_screen
        self.win = self.t >= settle
        Mi = np.linalg.inv(lin.M)
        A = np.zeros((12, 12))
        A[:6, 6:] = np.eye(6)
        A[6:, :6] = -Mi @ lin.K
        A[6:, 6:] = -Mi @ lin.C
        Z = np.zeros((18, 18))
        Z[:12, :12] = A
        Z[6:12, 12:] = Mi
        Ed = expm(Z / fs_screen)
        self.Ad, self.Bd = Ed[:12, :12], Ed[:12, 12:]
        self.D = wrench_jacobians(rig, lin.position[None], lin.R0[None], lin.T0[None], None)
        self.D = (self.D[0], self.D[1], self.D[2], np.zeros((1, 3, 2)))
        self.tm = tracker_model(rig, lin.position, lin.R0, tracker_params)
        self.P = np.linalg.inv(body.inertia)
        sig, _ = _channel_sigmas(body.noise, body.rates, self.fs, len(rig.cables), rig.inclinometer is not None)
        self.sig = sig[:8 + len(rig.cables)]
        self.R_imu = rig.imu.rotation.as_matrix()

    def responses(self, f: float) -> np.ndarray:
        """(n_t, 12, 2, 6) state response to unit wrench components driven by cos θ (…, 0, j)
        and sin θ (…, 1, j) of a unit rotating force at f Hz."""
        c, s = _spin_up(f, self.t, self.ramp)
        n = len(self.t)
        X = np.zeros((n, 12, 2, 6))
        x = np.zeros((12, 2, 6))
        Bd = self.Bd
        for i in range(1, n):
            u_c, u_s = c[i - 1], s[i - 1]
            x = np.einsum("ij,jab->iab", self.Ad, x)
            x[:, 0, :] += Bd * u_c
            x[:, 1, :] += Bd * u_s
            X[i] = x
        return X

    def band(self, f: float, rot_f) -> tuple[float, float]:
        return recommended_band(f, rot_f, self.duration - self.settle, self.fs)

    def noise_density(self, band) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per-sample (fs) residual density S (K,3,3) on the screen's rfft grid, the filter's
        |F|² there, and the per-axis residual variance (3,)."""
        nw = int(self.win.sum())
        f = np.fft.rfftfreq(nw, 1 / self.fss)
        sos = butter(4, band, btype="bandpass", fs=self.fs, output="sos")
        H = _stationary_e_response(self.tm, self.D, self.P, sos, self.fs, f, self.R_imu)[:, :, :len(self.sig)]
        S = np.einsum("kad,d,kbd->kab", H, self.sig**2, H.conj())
        _, hf = sosfreqz(sos, worN=f, fs=self.fs)
        fg = np.linspace(band[0] * 0.3, min(band[1] * 3, 0.45 * self.fs), 600)
        Hg = _stationary_e_response(self.tm, self.D, self.P, sos, self.fs, fg, self.R_imu)[:, :, :len(self.sig)]
        var = 2 * np.trapezoid(np.einsum("kad,d,kad->ka", Hg, self.sig**2, Hg.conj()).real, fg, axis=0) / self.fs
        return S, np.abs(hf) ** 2, var

    def candidate(self, X: np.ndarray, position, rpy, limits: dict, noise_dens, band, amplitude=None,
                  direction: int = 1):
        """Amplitude within the limits and the screen prediction for one mounting.
        Returns (amplitude N, binding limit, peak rotation deg, min tension ratio, Prediction)."""
        lin = self.lin
        Re = Rotation.from_euler("xyz", rpy).as_matrix()[:, :2]
        Fw = lin.R0 @ Re
        r = lin.R0 @ (np.asarray(position, float) - lin.cg)
        L = np.vstack([Fw, np.cross(r, Fw.T).T]) * np.array([1.0, float(direction)])   # (6,2) per (cos, sin)
        x = np.einsum("nicj,jc->ni", X, L)                             # (n,12) per newton
        phi = x[:, 3:6]
        rot_unit = float(np.max(np.linalg.norm(phi, axis=1)))
        dT = (lin.k * (x[:, :6] @ lin.G.T)) + lin.c * (x[:, 6:] @ lin.G.T)
        drop_unit = float(np.max(-dT / lin.T0[None, :]))
        lim = {"force": limits["max_force_n"],
               "rotation": np.radians(limits["max_rotation_deg"]) / max(rot_unit, 1e-300),
               "tension": (1 - limits["min_tension_ratio"]) / max(drop_unit, 1e-300)}
        key = min(lim, key=lim.get)
        amp = 0.95 * lim[key] if key != "force" else lim[key]
        if amplitude is not None:
            amp, key = float(amplitude), "given"
        omega = (x[self.win, 9:12] @ lin.R0) * amp                     # body rate (n,3)
        return amp, key, np.degrees(rot_unit * amp), 1 - drop_unit * amp, self.predict(omega, noise_dens, band)

    def predict(self, omega: np.ndarray, noise_dens, band) -> Prediction | None:
        """Screen prediction for the body rate ``omega`` (n,3) rad/s, body axes, sampled at
        the screen's rate over the fitted window."""
        S, F2, var = noise_dens
        nw = len(omega)
        Om = np.fft.rfft(omega, axis=0)                                # (K,3)
        E = basis()
        Ah = -F2[:, None, None] * np.einsum("ij,kjl,fl->fik", self.P, E, Om)   # (K,3,6)
        mult = np.full(len(Om), 2.0)
        mult[0] = 1.0
        if nw % 2 == 0:
            mult[-1] = 1.0
        scale = (self.fs / self.fss) / nw
        axis_bread = scale * np.einsum("f,fak,fal->akl", mult, Ah.conj(), Ah).real
        axis_meat = scale * np.einsum("f,fak,fab,fbl->abkl", mult, Ah.conj(), S, Ah).real
        white = axis_bread.sum(0)
        white_meat = scale * self.body.noise["gyro"] ** 2 * np.einsum("f,f,fak,fal->kl", mult, F2**2, Ah.conj(),
                                                                      Ah).real
        rot_rms = np.sqrt(np.mean(np.fft.irfft(Om * F2[:, None], n=nw, axis=0) ** 2, axis=0))
        try:
            return Prediction.assemble(self.body.inertia, axis_bread, {"noise": axis_meat}, white, white_meat, var,
                                       band, self.duration - self.settle, int(nw * self.fs / self.fss), rot_rms)
        except np.linalg.LinAlgError:
            return None


@dataclass
class Candidate:
    """A screened run: the run, its (screen or simulated) prediction, the binding limit."""

    run: Run
    prediction: Prediction
    limit: str
    simulated: bool = False
    peak_rotation_deg: float | None = None
    min_tension_ratio: float | None = None
    band: tuple | None = None      # identification band to use (None: the identifier's automatic band)
    geometry: str | None = None    # None: the rig's own cables; else the other cable geometry's label
    body: "Body | None" = None     # the body on that geometry (None: the plan's)

    def to_dict(self) -> dict:
        geo = None
        if self.geometry is not None and self.body is not None:
            geo = {"label": self.geometry,
                   "cables": [{"name": c.name, "ceiling_anchor": [float(x) for x in c.ceiling_anchor],
                               "body_anchor": [float(x) for x in c.body_anchor], "length": float(c.length)}
                              for c in self.body.rig.cables]}
        return {"run": self.run.to_dict(), "cable_geometry": geo, "limit": self.limit, "simulated": self.simulated,
                "identification_band_hz": None if self.band is None else [float(x) for x in self.band],
                "peak_rotation_deg": self.peak_rotation_deg, "min_tension_ratio": self.min_tension_ratio,
                "prediction": self.prediction.to_dict()}


@dataclass
class Plan:
    """The recommended runs, their joint prediction, the baseline for comparison, the rig's
    modes and the limits used."""

    runs: list[Candidate]
    prediction: Prediction
    baseline: Candidate
    modes: list
    limits: dict
    notes: list[str] = field(default_factory=list)
    other_geometries: list = field(default_factory=list)   # per other cable geometry: its best second run

    def improvement(self) -> np.ndarray:
        """(6,) baseline σ / plan σ per entry."""
        return self.baseline.prediction.std / self.prediction.std

    def to_dict(self) -> dict:
        return {"modes": [m.to_dict() for m in self.modes],
                "runs": [c.to_dict() for c in self.runs],
                "prediction": self.prediction.to_dict(),
                "baseline": self.baseline.to_dict(),
                "improvement": {k: float(v) for k, v in zip(KEYS, self.improvement())},
                "limits": dict(self.limits), "notes": list(self.notes),
                "other_geometries": [c.to_dict() for c in self.other_geometries]}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Mounting points: the corners of the box spanned by the body anchors and the rig's
    exciter position (body frame, m); a flat box (all anchors at one height, no exciter)
    keeps its two faces at the anchors' height and at the CG's."""
    pts = [*rig.body_anchors]
    if rig.exciter is not None:
        pts.append(rig.exciter.position)
    pts.append(rig.require_cg())
    pts = np.array(pts)
    lo, hi = pts.min(0), pts.max(0)
    return [np.array([x, y, z]) for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


def recommended_band(f0: float, rot_f, duration: float, fs: float) -> tuple[float, float]:
    """Pass band (Hz) around the exciter frequency ``f0`` and the rotational modes below 5 Hz
    (``rot_f``), widened like :func:`~.identification.auto_band` (0.6x below, 1.5x above)."""
    fr = [f0] + [x for x in rot_f if x < 5.0]
    return (max(0.15, 0.6 * min(fr), 2.0 / duration), min(1.5 * max(fr), 0.4 * fs))


def _sim_check(body: Body, run: Run, limits: dict, settle: float, tracker_params,
               rot_f=None) -> tuple[Candidate, object]:
    """Simulate ``run`` without noise, measure its peak rotation, lowest tension ratio and
    whether the swing keeps growing (last third against the middle third), and predict.
    Returns (Candidate, SimResult)."""
    from .simulator import simulate
    sim = simulate(body.experiment(run))
    rot = sim.states.rotation
    ang = np.linalg.norm((rot * rot[0].inv()).as_rotvec(), axis=1)
    peak = float(np.degrees(np.max(ang)))
    T = sim.states.tensions
    tmin = float(np.min(T / T[0][None, :]))
    n = len(ang)
    growing = bool(np.max(ang[2 * n // 3:]) > 1.15 * np.max(ang[n // 3: 2 * n // 3]))
    try:
        traj = Trajectory.from_simulation(sim)
    except PlanError:   # slack cables etc. leave too little to fit: scale down (see _fit_amplitude)
        cand = Candidate(run, None, "", True, peak, tmin)
        cand.growing = growing
        return cand, sim
    pred = predict_from_trajectory(traj, body.noise, settle, None, tracker_params)
    band = None
    if rot_f is not None:
        # the identifier's automatic band also takes in the weak difference tones of large
        # swings (f0 - f_mode), where the tracker's noise is large; a band around the exciter
        # and the rotational modes may do better: recommend it then
        rec = recommended_band(run.frequency, rot_f, traj.t[-1] - traj.t[0] - settle, float(body.rates["imu"]))
        pr = predict_from_trajectory(traj, body.noise, settle, rec, tracker_params)
        if pr.objective < 0.9 * pred.objective:
            pred, band = pr, rec
    cand = Candidate(run, pred, "", True, peak, tmin, band)
    cand.growing = growing
    return cand, sim


def _feasible(c: Candidate, limits: dict) -> bool:
    return (c.prediction is not None and c.peak_rotation_deg <= limits["max_rotation_deg"] * 1.001
            and c.min_tension_ratio >= limits["min_tension_ratio"] * 0.999 and not getattr(c, "growing", False))


def _fit_amplitude(body: Body, run: Run, limits: dict, settle: float, tracker_params, limit: str,
                   tries: int = 2, grow: bool = True, rot_f=None) -> Candidate | None:
    """Simulate ``run`` and bring its force amplitude to the limits: scale it linearly so
    that the simulated peak rotation and lowest tension (start-up transients and beats
    included) meet them with a 3 % margin, at most ``limits["max_force_n"]`` (up only if
    ``grow``), and simulate again.  None if the run still breaks a limit or its swing keeps
    growing (a parametric resonance)."""
    cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
    for _ in range(tries):
        if getattr(cand, "growing", False):
            return None
        s_rot = np.radians(limits["max_rotation_deg"]) / max(np.radians(cand.peak_rotation_deg), 1e-12)
        s_ten = (1 - limits["min_tension_ratio"]) / max(1 - cand.min_tension_ratio, 1e-12)
        s_force = limits["max_force_n"] / run.amplitude
        s = min(s_rot, s_ten)
        if s >= 1.0:
            s = min(0.97 * s, s_force) if grow else 1.0
            if s < 1.05:
                break
        else:
            s *= 0.97
        run = replace(run, amplitude=run.amplitude * s)
        cand, _ = _sim_check(body, run, limits, settle, tracker_params, rot_f)
        grow = False
    if not _feasible(cand, limits):
        return None
    use = {"rotation": cand.peak_rotation_deg / limits["max_rotation_deg"],
           "tension": (1 - cand.min_tension_ratio) / (1 - limits["min_tension_ratio"]),
           "force": run.amplitude / limits["max_force_n"]}
    cand.limit = max(use, key=use.get)   # the limit it comes closest to
    return cand


def amplitude_at_limits(body: Body, run: Run, max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                        max_force: float = math.inf, settle: float = 5.0) -> Candidate | None:
    """``run`` (its frequency, exciter position and spin axis kept) at the largest force
    amplitude within the limits of :func:`plan_experiment` (same defaults): peak rotation ≤
    ``max_rotation_deg``, every cable ≥ ``min_tension_ratio`` × its static tension (start-up
    and beats included, 3 % margin), force ≤ ``max_force`` N; found by noise-free
    simulation as the planner does (:func:`_fit_amplitude`).  Returns the
    :class:`Candidate` (``.run.amplitude`` N, ``.peak_rotation_deg``,
    ``.min_tension_ratio``, ``.prediction``), or None if no amplitude keeps the run within
    the limits (its swing keeps growing).  Raises :class:`PlanError` for bad limits,
    :class:`~.simulator.SimulationError`."""
    return _fit_amplitude(body, run, _limits(max_force, max_rotation_deg, min_tension_ratio), settle, None, "")


def _limits(max_force: float, max_rotation_deg: float, min_tension_ratio: float) -> dict:
    """The run limits of :func:`plan_experiment` as a mapping.  Raises :class:`PlanError`."""
    if not (0 <= min_tension_ratio < 1) or not max_rotation_deg > 0 or not max_force > 0:
        raise PlanError("limits: need 0 ≤ min tension ratio < 1, max rotation > 0, max force > 0")
    return {"max_force_n": max_force, "max_rotation_deg": max_rotation_deg, "min_tension_ratio": min_tension_ratio}


def plan_experiment(body: Body, baseline: Run, duration: float = 120.0, max_force: float = math.inf,
                    max_rotation_deg: float = 3.0, min_tension_ratio: float = 0.2,
                    frequencies: tuple[float, float] = (0.3, 4.0), positions: list | None = None,
                    max_runs: int = 2, objective: str = "baseline", refine: int = 3, settle: float = 5.0,
                    short: float = 30.0, mode_margin: float = 0.1, tracker_params: dict | None = None,
                    geometries: list | None = None, progress=None) -> Plan:
    """Recommend one or two exciter runs (see module docstring).

    body: :class:`Body`.  baseline: the run to compare with (e.g. the thesis's 200 N at
    1.05 Hz at the rig's exciter).  objective: ``"baseline"`` — make the least-improved
    entry as much better than the baseline as possible (minimise max_k σ_k / σ_k,baseline),
    or ``"relative"`` — minimise the largest relative σ (diagonals relative to themselves,
    products to the largest diagonal).  Limits: force amplitude ≤ ``max_force`` N, body
    rotation ≤ ``max_rotation_deg`` (peak, start-up included), every cable ≥
    ``min_tension_ratio`` × its static tension, no growing swing; exciter frequencies in
    ``frequencies`` Hz and at least ``mode_margin`` (relative) away from every natural
    frequency, its double and every pairwise sum (:func:`resonances`).  positions:
    candidate mounting points (body m; default :func:`candidate_positions`).  max_runs: 1
    or 2.  refine: how many screened candidates are simulated (``short`` s each).
    geometries: other cable geometries the rig can take for the second run, [(label,
    :class:`~.rig.Rig`)] with the same body (e.g. :func:`geometry_variants`); the best runs
    on each are searched like the rig's own and paired with the best run on the rig.
    progress: optional callable(str) for status lines.
    Raises :class:`PlanError`, :class:`~.simulator.SimulationError`.
    """
    from .modes import natural_modes
    from .simulator import SimulationError
    say = progress or (lambda s: None)
    limits = _limits(max_force, max_rotation_deg, min_tension_ratio)
    if not 0 < frequencies[0] < frequencies[1]:
        raise PlanError(f"frequency range {frequencies} Hz must be 0 < low < high")
    if objective not in ("baseline", "relative"):
        raise PlanError(f"objective {objective!r}: baseline or relative")
    if not duration > settle + 10.0:
        raise PlanError(f"--duration {duration:g} s: runs must last more than {settle + 10:g} s")
    short = min(short, duration)
    limits.update({"duration_s": duration, "frequency_range_hz": list(frequencies), "mode_margin": mode_margin,
                   "objective": objective})
    rig = body.rig
    modes = natural_modes(rig, body.mass, rig.require_cg(), body.inertia, body.stiffness)
    rot_f = _rotational(modes)
    rot_fs = {None: rot_f}   # per cable geometry: its rotational modes (Hz), for the identification band
    screen = _Screen(body, linear_rig(body), duration, settle, tracker_params=tracker_params)
    # --- the baseline, simulated in full and screened (each stage compares like with like)
    say(f"simulating the baseline ({baseline.amplitude:.0f} N at {baseline.frequency:.2f} Hz, {duration:.0f} s) ...")
    base, _ = _sim_check(body, replace(baseline, duration=duration), limits, settle, tracker_params)
    base.limit = "baseline"
    if base.prediction is None:
        raise PlanError(f"the baseline excitation ({baseline.amplitude:g} N at {baseline.frequency:g} Hz) slackens "
                        "cables so often that the identifier could not fit it; choose a gentler --baseline-force")
    bband = screen.band(baseline.frequency, rot_f)
    base_screen = screen.candidate(screen.responses(baseline.frequency), baseline.position, baseline.exciter_rpy,
                                   limits, screen.noise_density(bband), bband, baseline.amplitude)[4]
    if objective == "baseline":
        ref_screen = base_screen.std if base_screen is not None else base.prediction.std
        ref_sim = base.prediction.std
    else:
        ref_screen = ref_sim = base.prediction.scale
    done: dict = {}

    def search(b: Body, label: str | None, scr: _Screen | None = None, partner: Candidate | None = None):
        """Screen frequencies, mounting points and spin axes on the body ``b`` (cable
        geometry ``label``; None: the rig's own), then simulate the best distinct
        ``refine`` of them (``short`` s, amplitude brought to the limits): best alone and,
        with ``partner`` given, also best together with that run (a second run).  Returns
        (screened, simulated singles)."""
        where = "" if label is None else f" ({label})"
        ms = modes if label is None else natural_modes(b.rig, b.mass, b.rig.require_cg(), b.inertia, b.stiffness)
        mf = np.array([m.frequency for m in ms])
        rf = rot_fs.setdefault(label, _rotational(ms))
        scr = scr or _Screen(b, linear_rig(b), duration, settle, tracker_params=tracker_params)
        say(f"screening frequencies, mounting points and spin axes (linearised rig{where}) ...")
        avoid = resonances(mf)
        freqs = [f for f in np.geomspace(frequencies[0], frequencies[1], 30)
                 if np.all(np.abs(f / avoid - 1) >= mode_margin)]
        if not freqs:
            raise PlanError(f"no exciter frequency in {frequencies[0]:g}–{frequencies[1]:g} Hz is {100 * mode_margin:.0f} % "
                            f"away from the rig's modes{where} ({', '.join(f'{f:.2f}' for f in mf)} Hz), their doubles "
                            "and their pairwise sums")
        pts = [np.asarray(p, float) for p in (positions if positions else candidate_positions(b.rig))]
        screened: list[Candidate] = []
        for f in freqs:
            X = scr.responses(f)
            band = scr.band(f, rf)
            dens = scr.noise_density(band)
            for p in pts:
                for ax in SPIN_AXES:
                    for sense in (1, -1):
                        amp, lim, rot, tmin, pred = scr.candidate(X, p, SPIN_AXES[ax], limits, dens, band,
                                                                  direction=sense)
                        if pred is None or not np.all(np.isfinite(pred.std)):
                            continue
                        screened.append(Candidate(Run(float(f), float(amp), tuple(float(x) for x in p), ax, duration,
                                                      direction=sense), pred, lim, False, float(rot), float(tmin),
                                                  geometry=label, body=b))
        screened.sort(key=lambda c: c.prediction.worst(ref_screen))
        picks = _distinct(screened, refine)
        if partner is not None:   # a ranking only: the partner's prediction is simulated, the candidates' screened
            together = sorted(screened, key=lambda c: combine([partner.prediction, c.prediction]).worst(ref_sim))
            picks += [c for c in _distinct(together, refine) if all(not _same(c, o) for o in picks)]
        singles = [x for x in (simulate_short(c, "a candidate run") for c in picks) if x is not None]
        return screened, singles

    def simulate_short(c: Candidate, what: str) -> Candidate | None:
        key = _run_key(c)
        if key not in done:
            where = "" if c.geometry is None else f" ({c.geometry})"
            say(f"simulating {what}{where}: {c.run.frequency:.2f} Hz, {c.run.amplitude:.0f} N, spin axis "
                f"{c.run.spin_axis}, at {np.round(c.run.position, 2).tolist()} m ({short:.0f} s) ...")
            cs = _fit_amplitude(c.body, replace(c.run, duration=short), limits, settle, tracker_params, c.limit,
                                rot_f=rot_fs[c.geometry])
            if cs is not None:
                cs.prediction = cs.prediction.scaled((duration - settle) / cs.prediction.duration)
                cs.geometry, cs.body = c.geometry, c.body
            done[key] = cs
        return done[key]

    def worst(*cs: Candidate) -> float:
        return combine([c.prediction for c in cs]).worst(ref_sim)

    screened, singles = search(body, None, screen)
    if not screened:
        raise PlanError("no candidate run moves the body measurably")
    if not singles:
        raise PlanError("every screened candidate broke a limit in simulation (cable slack, rotation, growing "
                        "swing): lower --max-force or change the frequency range")
    singles.sort(key=worst)
    full: dict = {}

    def simulate_full(c: Candidate, what: str) -> Candidate | None:
        """``c`` simulated over the whole ``duration``, its amplitude brought to the limits
        again (a run can break a limit late: beats, slow growth).  None if it cannot."""
        key = _run_key(c)
        if key not in full:
            if short >= duration:   # already simulated in full
                full[key] = c
                return c
            where = "" if c.geometry is None else f" on cable geometry {c.geometry!r}"
            say(f"simulating {what}{where} in full ({c.run.frequency:.2f} Hz, {duration:.0f} s) ...")
            cf = _fit_amplitude(c.body, replace(c.run, duration=duration), limits, settle, tracker_params, c.limit,
                                rot_f=rot_fs[c.geometry])
            if cf is not None:
                cf.geometry, cf.body = c.geometry, c.body
            full[key] = cf
        return full[key]

    # --- the best single run, confirmed in full (falling back on the next if it breaks a limit late)
    first = None
    for n_c, c in enumerate(singles):
        first = simulate_full(c, "the best run" if n_c == 0 else "the next candidate")
        if first is not None:
            break
    if first is None:
        raise PlanError(f"every candidate run broke a limit over {duration:.0f} s in simulation (cable slack, "
                        "rotation, growing swing); lower --max-force or change the frequency range")
    chosen = [first]
    notes: list[str] = []
    others: list[Candidate] = []
    if max_runs >= 2:
        sims2 = []
        for a, b in _best_pairs(screened, max(2, refine // 2), ref_screen):
            sa, sb = simulate_short(a, "a pair, first run"), simulate_short(b, "a pair, second run")
            if sa is not None and sb is not None:
                sims2.append((sa, sb))
        sims2 += [(x, y) for k, x in enumerate(singles) for y in singles[k + 1:]]
        g_best: dict = {}
        for label, grig in (geometries or []):
            if len(grig.cables) != len(rig.cables):
                notes.append(f"cable geometry {label!r} not usable: {len(grig.cables)} cables, the rig has "
                             f"{len(rig.cables)}")
                continue
            try:
                gb = replace(body, rig=replace(grig, mass=body.mass, center_of_gravity=rig.require_cg()))
                _, gs = search(gb, label, partner=singles[0])
            except (PlanError, SimulationError) as e:
                notes.append(f"cable geometry {label!r} not usable: {e}")
                continue
            if not gs:
                notes.append(f"cable geometry {label!r}: every candidate run broke a limit in simulation")
            sims2 += [(singles[0], y) for y in gs]
            if gs:
                g_best[label] = min(gs, key=lambda y: worst(singles[0], y))
        # the short runs' predictions, scaled to the full length, only rank the pairs (beats and
        # start-up weigh differently in 30 s): the best few that promise to beat the best run done
        # twice are simulated in full and compared in full
        repeat_short = worst(singles[0]) / math.sqrt(2)
        promising = [ab for ab in sorted(sims2, key=lambda ab: worst(*ab)) if worst(*ab) < repeat_short][:3]
        repeat = worst(first) / math.sqrt(2)
        best, best_val = None, repeat
        for a, b in promising:
            fa, fb = simulate_full(a, "a pair's first run"), simulate_full(b, "a pair's second run")
            if fa is not None and fb is not None and worst(fa, fb) < best_val:
                best, best_val = (fa, fb), worst(fa, fb)
        if best is not None:
            chosen = list(best)
            other = "" if best[1].geometry is None else f" (the second on cable geometry {best[1].geometry!r})"
            notes.append(f"two complementary runs{other}: worst entry σ/reference {best_val:.3g}, against "
                         f"{repeat:.3g} for the best run done twice and {worst(first):.3g} for it alone")
        else:
            chosen = [first, first]
            notes.append(f"no other run complements the best one better than itself: do it twice (every σ / √2; "
                         f"worst entry σ/reference {repeat:.3g} against {worst(first):.3g} for one run)")
        for label, y in g_best.items():   # what each other geometry offered (full-length where simulated so)
            key = _run_key(y)
            yf = full.get(key)
            others.append(yf if yf is not None else y)
            how = ("full-length simulation" if yf is not None else
                   "short simulation; it broke a limit over the full length" if key in full else "short simulation")
            notes.append(f"cable geometry {label!r}: its best second run, {others[-1].run.amplitude:.0f} N at "
                         f"{others[-1].run.frequency:.2f} Hz, gives worst entry σ/reference "
                         f"{worst(first, others[-1]):.3g} with the best run ({how})")
    return Plan(chosen, combine([c.prediction for c in chosen]), base, modes, limits, notes, others)


def geometry_variants(body: Body, shift: float = 1.0) -> list[tuple[str, Rig]]:
    """Other cable geometries for a second run: the ceiling anchors moved ``shift`` m
    farther apart (and, where they stay more than 0.2 m outside the body anchors, closer
    together) along world x, and along world y — each anchor away from (toward) the
    anchors' mid-point on that axis — with every cable length re-set to the anchors'
    distance at the rig's own equilibrium pose (cables of the same material: the
    stiffness is kept).  The body settles near that pose: the new cable directions
    balance its weight at a slightly different one (on the thesis rig within 5 cm and
    3°).  A variant whose cables would lean inward is left out.  Returns [(label, Rig)]."""
    from .simulator import CableModel, equilibrium
    rig = body.rig
    cm = CableModel.spring(rig, body.mass, stiffness=body.stiffness)
    pos, R0, _ = equilibrium(rig, body.mass, rig.require_cg(), cm)
    B = pos + R0.apply(rig.body_anchors)                     # body anchors in world at equilibrium
    A = np.asarray(rig.ceiling_anchors, float)
    out = []
    for ax, name in ((0, "x"), (1, "y")):
        mid = 0.5 * (A[:, ax].min() + A[:, ax].max())
        side = np.sign(A[:, ax] - mid)
        for sense, word in ((1, "farther apart"), (-1, "closer together")):
            A2 = A.copy()
            A2[:, ax] += sense * shift * side
            if sense < 0 and np.any(side * (A2[:, ax] - B[:, ax]) < 0.2):
                continue        # the cables would lean inward: another rig, not a variant
            L = np.linalg.norm(A2 - B, axis=1)
            cables = tuple(replace(c, ceiling_anchor=a, length=float(l)) for c, a, l in zip(rig.cables, A2, L))
            out.append((f"ceiling anchors {shift:g} m {word} along world {name}", replace(rig, cables=cables)))
    return out


def _rotational(modes) -> list[float]:
    """Frequencies (Hz) of the modes that are mostly rotation (> 30 % of their energy)."""
    return [m.frequency for m in modes if m.energy[3:].sum() > 0.3]


def _run_key(c: Candidate) -> tuple:
    """What makes a run distinct for the simulation caches: geometry, frequency, mounting
    point, spin axis and sense (the amplitude is fitted)."""
    return (c.geometry, c.run.frequency, c.run.position, c.run.spin_axis, c.run.direction)


def _best_pairs(cands: list[Candidate], n: int, ref: np.ndarray) -> list[tuple[Candidate, Candidate]]:
    """The ``n`` best distinct pairs of screened runs for a joint fit (information and noise
    of the two runs add; each with its own weights)."""
    B = np.array([np.einsum("a,aij->ij", c.prediction.weights, c.prediction.axis_bread) for c in cands])
    M = np.array([sum(np.einsum("a,b,abij->ij", c.prediction.weights, c.prediction.weights, m)
                      for m in c.prediction.axis_meats.values()) for c in cands])
    i, j = np.triu_indices(len(cands), 1)
    out = np.full(len(i), np.inf)
    for lo in range(0, len(i), 50000):
        sl = slice(lo, lo + 50000)
        Bs = B[i[sl]] + B[j[sl]]
        ok = np.linalg.cond(Bs) < 1e12
        Bi = np.zeros_like(Bs)
        Bi[ok] = np.linalg.inv(Bs[ok])
        var = np.einsum("pkl,plm,pkm->pk", Bi, M[i[sl]] + M[j[sl]], Bi)
        obj = np.max(np.sqrt(np.clip(var, 0, None)) / ref, axis=1)
        out[sl] = np.where(ok, obj, np.inf)
    order = np.argsort(out)
    taken: list[tuple[Candidate, Candidate]] = []
    for k in order:
        if not np.isfinite(out[k]):
            break
        a, b = cands[i[k]], cands[j[k]]
        if all(not (_same(a, x) and _same(b, y)) and not (_same(a, y) and _same(b, x)) for x, y in taken):
            taken.append((a, b))
        if len(taken) >= n:
            break
    return taken


def _same(a: Candidate, b: Candidate) -> bool:
    return (a.run.spin_axis == b.run.spin_axis and a.run.direction == b.run.direction
            and np.allclose(a.run.position, b.run.position) and abs(a.run.frequency / b.run.frequency - 1) < 0.15)


def resonances(mode_f) -> np.ndarray:
    """Frequencies (Hz) an exciter must stay away from: the natural frequencies f_i (primary
    resonance), 2 f_i and f_i + f_j (parametric and combination resonances: the rotating
    force modulates the cables' geometric stiffness; on the thesis rig 2.02 Hz = 0.85 + 1.18 Hz
    makes the swing grow until a cable goes slack, even at 160 N)."""
    f = np.asarray(mode_f, float)
    i, j = np.triu_indices(len(f))
    return np.unique(np.concatenate([f, f[i] + f[j]]))


def _distinct(cands: list[Candidate], n: int) -> list[Candidate]:
    """The first ``n`` candidates that differ in mounting point / spin axis or by ≥ 15 % in
    frequency from the ones already taken."""
    out: list[Candidate] = []
    for c in cands:
        if all(not _same(c, o) for o in out):
            out.append(c)
        if len(out) >= n:
            break
    return out


def load_plan_input(path) -> tuple[Rig, dict | None, np.ndarray | None]:
    """The rig of ``path`` — a rig.yaml, an experiment file (config/cases, config/rigs) or a
    recording folder — with its cable stiffness if known (rig.yaml ``stiffness`` or the
    experiment's spring ``cable_model``) and, for an experiment file, its rotating
    excitation ({amplitude, frequency, ramp_time}) as the baseline.  Raises
    :class:`~.rig.RigError`, :class:`~.recording.RecordingError`, FileNotFoundError."""
    from pathlib import Path

    from .recording import RecordingError
    from .rig import RigError, load_rig, read_yaml
    p = Path(path)
    if p.is_dir():
        if not (p / "rig.yaml").exists():
            raise RecordingError(f"{p}: no rig.yaml in the recording folder")
        p = p / "rig.yaml"
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    d = read_yaml(p, RigError, "rig description")
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        from .simulator import ExperimentError, load_experiment
        try:
            exp = load_experiment(p)
        except ExperimentError as e:
            raise RigError(str(e)) from None
        k = exp.cable_model.stiffness if exp.cable_model.type == "spring" else None
        rot = exp.excitation.rotating
        base = None if rot is None else {"amplitude": rot.amplitude, "frequency": rot.frequency,
                                         "ramp_time": rot.ramp_time}
        return exp.rig, base, None if k is None else np.asarray(k, float)
    rig = load_rig(p)
    k = rig.cable_stiffness
    return rig, None, (k if np.all(np.isfinite(k)) else None)


def make_body(rig: Rig, mass: float | None, inertia_entries, stiffness=None, noise: dict | None = None,
              rates: dict | None = None) -> Body:
    """A :class:`Body` from the command line's numbers: mass kg (default rig.yaml's),
    inertia_entries (6,) in :data:`KEYS` order, kg·m² (tensor entries: products negated).
    Raises :class:`PlanError` for a non-positive mass, a missing CG or a tensor that is not
    physically consistent."""
    from .identification import physically_consistent
    from .simulator import DEFAULT_STIFFNESS
    if rig.center_of_gravity is None:
        raise PlanError(f"{rig.source}: body.center_of_gravity is required (estimate it first: rig-identify cg)")
    m = float(rig.mass if mass is None else mass)
    if not (math.isfinite(m) and m > 0):
        raise PlanError(f"--mass must be > 0 kg, got {mass}")
    J = to_tensor(np.asarray(inertia_entries, float))
    if not np.all(np.isfinite(J)) or not physically_consistent(J):
        raise PlanError("--inertia: the tensor is not physically consistent (it must be positive definite and "
                        "each principal moment at most the sum of the other two); order IXX IYY IZZ IXY IXZ IYZ, "
                        "kg·m², products negated as in truth.yaml")
    n = len(rig.cables)
    k = np.full(n, DEFAULT_STIFFNESS) if stiffness is None else np.broadcast_to(np.asarray(stiffness, float), (n,))
    return Body(replace(rig, mass=m), m, J, np.array(k, float), dict(rates or REFERENCE_RATES),
                dict(noise or REFERENCE_NOISE))
