"""The tracker and the preprocessor linearised about a run: how the sensors' noise becomes a pose
error (:func:`tracker_model`, the tracker's complementary filters as transfer functions) and a
torque error (:func:`wrench_jacobians`, the derivatives of the generalized wrench).

The linear map of :mod:`rig_identification.estimation.propagation` (the σ a run's noise causes) and
of the design's fast screen (:mod:`rig_identification.design.screen`) is built from these.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..io.rig import Rig
from ..model.dynamics import skew
from .tracker import YAW_PRIOR, PoseTracker

DRIFT_LEAK = 1e-3   # 1/s: leak of the linearised tracker's uncorrected rotation directions (tracker_model)


@dataclass
class TrackerModel:
    """The tracker's complementary filters linearised about a pose (see
    :mod:`rig_identification.estimation.propagation`).

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
        Xphi = hp[:, None, None] * (-skew(fw)) + lp[:, None, None] * self.LV[:3]
        Xd = np.zeros((len(s), 3, n_in), complex)
        Xd[:, :, 3:6] = hp[:, None, None] * (self.R0 @ self.R_imu)
        Xd[:, :, 8:] = lp[:, None, None] * self.L[:3]
        out[:, :3] = Phi
        out[:, 3:] = (Xphi + skew(self.r_imu_w)) @ Phi + Xd           # origin = IMU point + r × φ
        return out


def tracker_model(rig: Rig, position: np.ndarray, R0: np.ndarray, tracker_params: dict[str, Any] | None = None,
                  ) -> TrackerModel:
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
    return TrackerModel(R0, R_imu, r_imu_w, C_phi, C_noise, LV, L, u, V, tp.tau_tilt / tp.tau_bias**2,
                         2 * np.pi * tp.f_position, g)


def wrench_jacobians(rig: Rig, position: np.ndarray, R: np.ndarray, tensions: np.ndarray,
                     exciter_xy: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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

    def d_torque(d_rel: np.ndarray) -> np.ndarray:   # (M,N,3) or (M,1,3) -> (M,3)
        du = (d_rel - u * np.einsum("mni,mni->mn", u, d_rel)[:, :, None]) / length
        torque: np.ndarray = np.einsum("mn,mni->mi", tensions, np.cross(arm[None], du))
        return torque

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
