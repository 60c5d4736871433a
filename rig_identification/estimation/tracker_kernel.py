"""The per-sample filter of :class:`~rig_identification.estimation.tracker.PoseTracker`, compiled with numba.

:func:`run` takes the initialised filter over a run of merged events (inclinometer, tensions,
IMU, exciter samples in stamp order) in one compiled loop: the strapdown step, the tilt and
cable-length corrections, the online compliance refinement and the body pose of every IMU
sample.  It is the tracker's only implementation of the filter: the offline replay
(:mod:`~rig_identification.estimation.tracker_replay`) runs it once over a whole recording, the
tracker node (through ``PoseTracker.add_*``) once per sample; both give the same numbers
(``test/test_tracker.py``).  scipy's ``Rotation.from_matrix`` (Markley's quaternion) is
reproduced for the re-orthonormalisation every 200 steps and the poses' quaternions.  Numba
neither reorders nor contracts floating-point operations (no fastmath).

numba is a hard dependency; the functions compile on first use and are cached on disk
(``cache=True``: numba's cache next to this file, or its user-wide cache when that folder is
read-only).

Frames and units as :mod:`~rig_identification.estimation.tracker`: R row-major body -> world, the
filter state at the IMU point in world (m, m/s), angular rates in body axes (rad/s).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

# event kinds, also their rank among equal stamps: the one order in which the offline replay
# (tracker_replay.merge_events) and the tracker node hand a sample to the filter
EVENT_INCLINOMETER, EVENT_TENSIONS, EVENT_IMU, EVENT_EXCITER = 0, 1, 2, 3
# State.clock fields
T, T_ADAPT, T_INCL, T_INCL_USED = 0, 1, 2, 3
# State.flags fields
N_STEPS, HAS_OMEGA_PREV2, HAS_TENSIONS, INCL_PENDING = 0, 1, 2, 3
# Outputs.counts fields
POSES, STEPS, HISTORY, SUMS = 0, 1, 2, 3
REORTHONORMALISE = 200  # steps between re-orthonormalisations of the attitude


class Constants(NamedTuple):
    """What the filter does not change (N cables).

    imu_m, incl_m: (9,) row-major rotations IMU -> body, inclinometer -> body (incl_m
    unused when ``has_incl`` is false).  anchors: (N, 3) body anchors from the IMU point,
    body axes, m.  ceiling: (N, 3) ceiling anchors, world, m.  r_imu: (3,) IMU position,
    body axes, m.  gravity m/s², step_accel m/s², tau_tilt, tau_yaw, tau_bias,
    tau_tilt_accel s, f_position Hz, yaw_prior (tracker.YAW_PRIOR).  adapt: refine the
    compliance online.  fit: (N,) bool, the cables whose compliance is refined.  l0, T0:
    (N,) unstretched lengths m and tensions N at the initial pose.
    """

    imu_m: np.ndarray
    incl_m: np.ndarray
    has_incl: bool
    anchors: np.ndarray
    ceiling: np.ndarray
    r_imu: np.ndarray
    gravity: float
    step_accel: float
    tau_tilt: float
    tau_yaw: float
    f_position: float
    tau_bias: float
    tau_tilt_accel: float
    yaw_prior: float
    adapt: bool
    fit: np.ndarray
    l0: np.ndarray
    T0: np.ndarray


class State(NamedTuple):
    """The filter state, float64 arrays read at the start of :func:`run` and written back
    at its end (PoseTracker's attributes of the same names).

    R (9,) row-major body -> world.  p, v, v_prev (3,) world m, m/s of the IMU point.
    omega, omega_prev2 (3,) rad/s body.  dphi (3,) rad world.  a_hist (3, 3) world m/s²,
    newest first.  a_bias (3,) m/s² world.  gyro_bias (3,) rad/s body.  lengths,
    compliance, tensions, hp_e, hp_T (N,) m, m/N, N, m, N.  S (2,), blk (3,) the compliance
    regression sums.  clock (4,) s: [T, T_ADAPT, T_INCL, T_INCL_USED].  incl_pending (2,)
    rad.  flags (4,) int64: [N_STEPS, HAS_OMEGA_PREV2, HAS_TENSIONS, INCL_PENDING].
    """

    R: np.ndarray
    p: np.ndarray
    v: np.ndarray
    v_prev: np.ndarray
    omega: np.ndarray
    omega_prev2: np.ndarray
    dphi: np.ndarray
    a_hist: np.ndarray
    a_bias: np.ndarray
    gyro_bias: np.ndarray
    lengths: np.ndarray
    compliance: np.ndarray
    tensions: np.ndarray
    hp_e: np.ndarray
    hp_T: np.ndarray
    S: np.ndarray
    blk: np.ndarray
    clock: np.ndarray
    incl_pending: np.ndarray
    flags: np.ndarray


class Outputs(NamedTuple):
    """Preallocated results, filled from row 0; ``counts`` (4,) int64 says how many rows
    [POSES, STEPS, HISTORY, SUMS].

    t (M,) s, position (M, 3) world m of the body origin, quaternion (M, 4) xyzw body ->
    world (:func:`quaternion`), omega (M, 3) rad/s body, velocity (M, 3) world m/s: one pose
    per IMU sample.  steps (M,)
    s: stamps of the recognised stepped inputs.  history_t (K,) s, history_c (K, N) m/N:
    compliance updates.  sums (K, 4): (t, Σ e₀ ΔT, Σ ΔT², samples) per ~2 s block.
    """

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    omega: np.ndarray
    velocity: np.ndarray
    steps: np.ndarray
    history_t: np.ndarray
    history_c: np.ndarray
    sums: np.ndarray
    counts: np.ndarray


def outputs(m: int, n: int) -> Outputs:
    """Empty :class:`Outputs` for ``m`` IMU samples of a rig with ``n`` cables (counts zero)."""
    return Outputs(t=np.empty(m), position=np.empty((m, 3)), quaternion=np.empty((m, 4)), omega=np.empty((m, 3)),
                   velocity=np.empty((m, 3)), steps=np.empty(m), history_t=np.empty(m), history_c=np.empty((m, n)),
                   sums=np.empty((m, 4)), counts=np.zeros(4, np.int64))


@numba.njit(cache=True)
def quaternion_matrix(x: float, y: float, z: float, w: float) -> tuple[float, ...]:
    """Rotation matrix (row-major 9-tuple) of the unit quaternion (x, y, z, w), as scipy's
    ``Rotation.from_quat(...).as_matrix()``."""
    xx, yy, zz, ww = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return (xx - yy - zz + ww, 2 * (xy - zw), 2 * (xz + yw),
            2 * (xy + zw), -xx + yy - zz + ww, 2 * (yz - xw),
            2 * (xz - yw), 2 * (yz + xw), -xx - yy + zz + ww)


@numba.njit(cache=True)
def rotvec_matrix(x: float, y: float, z: float) -> tuple[float, ...]:
    """Rotation matrix (row-major 9-tuple) of the rotation vector (x, y, z) rad, through the
    unit quaternion as scipy ``Rotation.from_rotvec(...).as_matrix()`` (same series below
    1e-3 rad)."""
    angle2 = x * x + y * y + z * z
    angle = math.sqrt(angle2)
    if angle <= 1e-3:
        scale = 0.5 - angle2 / 48 + angle2 * angle2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    return quaternion_matrix(x * scale, y * scale, z * scale, math.cos(angle / 2))


@numba.njit(cache=True)
def solve_spd4(a00: float, a01: float, a02: float, a03: float, a11: float, a12: float, a13: float, a22: float,
               a23: float, a33: float, b0: float, b1: float, b2: float, b3: float) -> tuple[float, float, float, float]:
    """Solve A x = b, A symmetric positive-definite 4x4 (upper triangle given; Cholesky)."""
    l00 = math.sqrt(a00)
    l10, l20, l30 = a01 / l00, a02 / l00, a03 / l00
    l11 = math.sqrt(a11 - l10 * l10)
    l21 = (a12 - l20 * l10) / l11
    l31 = (a13 - l30 * l10) / l11
    l22 = math.sqrt(a22 - l20 * l20 - l21 * l21)
    l32 = (a23 - l30 * l20 - l31 * l21) / l22
    l33 = math.sqrt(a33 - l30 * l30 - l31 * l31 - l32 * l32)
    z0 = b0 / l00
    z1 = (b1 - l10 * z0) / l11
    z2 = (b2 - l20 * z0 - l21 * z1) / l22
    z3 = (b3 - l30 * z0 - l31 * z1 - l32 * z2) / l33
    x3 = z3 / l33
    x2 = (z2 - l32 * x3) / l22
    x1 = (z1 - l21 * x2 - l31 * x3) / l11
    x0 = (z0 - l10 * x1 - l20 * x2 - l30 * x3) / l00
    return x0, x1, x2, x3


@numba.njit(cache=True)
def quaternion(R: tuple[float, ...]) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of the rotation matrix R (row-major 9-tuple, orthogonal
    to rounding): Markley's method as scipy's ``Rotation.from_matrix`` (the largest of the
    diagonal and the trace chooses the formula, the first one on ties, that component > 0;
    scipy takes an SVD first only when RRᵀ is more than 1e-12 from I, which the tracker's
    attitude never is)."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = R
    tr = m00 + m11 + m22
    choice = 0
    best = m00
    if m11 > best:
        choice, best = 1, m11
    if m22 > best:
        choice, best = 2, m22
    if tr > best:
        choice = 3
    if choice == 0:
        x, y, z, w = 1 - tr + 2 * m00, m10 + m01, m20 + m02, m21 - m12
    elif choice == 1:
        x, y, z, w = m01 + m10, 1 - tr + 2 * m11, m21 + m12, m02 - m20
    elif choice == 2:
        x, y, z, w = m02 + m20, m12 + m21, 1 - tr + 2 * m22, m10 - m01
    else:
        x, y, z, w = m21 - m12, m02 - m20, m10 - m01, 1 + tr
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


@numba.njit(cache=True)
def orthonormalise(R: tuple[float, ...]) -> tuple[float, ...]:
    """The rotation matrix (row-major 9-tuple) of R's unit quaternion: scipy's
    ``Rotation.from_matrix(R).as_matrix()`` for an R orthogonal to within 1e-12."""
    x, y, z, w = quaternion(R)
    return quaternion_matrix(x, y, z, w)


@numba.njit(cache=True)
def write_pose(out: Outputs, row: int, t: float, R: tuple[float, ...], p: tuple[float, ...], v: tuple[float, ...],
               omega: tuple[float, ...], r_imu: tuple[float, ...]) -> None:
    """Write the body pose of the filter state into row ``row`` of ``out``'s poses.

    R: row-major 9-tuple body -> world.  p, v: the IMU point's world position m and
    velocity m/s.  omega: rad/s body.  r_imu: the IMU position, body axes, m.  The body
    origin is p − R r_imu, its velocity v − (R ω) × (R r_imu).
    """
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    i0, i1, i2 = r_imu
    o0, o1, o2 = omega
    qq0, qq1, qq2 = r00 * i0 + r01 * i1 + r02 * i2, r10 * i0 + r11 * i1 + r12 * i2, r20 * i0 + r21 * i1 + r22 * i2
    ss0, ss1, ss2 = r00 * o0 + r01 * o1 + r02 * o2, r10 * o0 + r11 * o1 + r12 * o2, r20 * o0 + r21 * o1 + r22 * o2
    out.t[row] = t
    out.position[row, 0] = p[0] - qq0
    out.position[row, 1] = p[1] - qq1
    out.position[row, 2] = p[2] - qq2
    out.quaternion[row, 0], out.quaternion[row, 1], out.quaternion[row, 2], out.quaternion[row, 3] = quaternion(R)
    out.omega[row, 0], out.omega[row, 1], out.omega[row, 2] = o0, o1, o2
    out.velocity[row, 0] = v[0] - (ss1 * qq2 - ss2 * qq1)
    out.velocity[row, 1] = v[1] - (ss2 * qq0 - ss0 * qq2)
    out.velocity[row, 2] = v[2] - (ss0 * qq1 - ss1 * qq0)


@numba.njit(cache=True)
def run(ev_t: np.ndarray, ev_kind: np.ndarray, ev_index: np.ndarray, start: int, imu: np.ndarray,
        tens: np.ndarray, incl: np.ndarray, c: Constants, s: State, out: Outputs) -> int:
    """Feed the events ``start:`` to the initialised filter (see the module docstring).

    ev_t (E,) s, ev_kind (E,) int8 (EVENT_INCLINOMETER, EVENT_TENSIONS, EVENT_IMU, EVENT_EXCITER), ev_index (E,)
    int64 row of the event in imu (n, 6) gyro rad/s + specific force m/s² IMU axes, tens
    (m, N) N, incl (k, 2) rad.  Exciter events are ignored (they only enter the initial
    pose).  Reads and updates ``s``, appends to ``out``.  Returns -1, or the index of the
    event whose IMU stamp is not after the previous one (``s`` then holds the state
    before it).
    """
    n = s.lengths.shape[0]
    resid = np.empty(n)
    tensions, lengths, comp, hp_e, hp_T = s.tensions, s.lengths, s.compliance, s.hp_e, s.hp_T
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = (s.R[0], s.R[1], s.R[2], s.R[3], s.R[4], s.R[5],
                                                   s.R[6], s.R[7], s.R[8])
    p0, p1, p2 = s.p[0], s.p[1], s.p[2]
    v0, v1, v2 = s.v[0], s.v[1], s.v[2]
    vp0, vp1, vp2 = s.v_prev[0], s.v_prev[1], s.v_prev[2]
    o0, o1, o2 = s.omega[0], s.omega[1], s.omega[2]
    w0, w1, w2 = s.omega_prev2[0], s.omega_prev2[1], s.omega_prev2[2]
    d0, d1, d2 = s.dphi[0], s.dphi[1], s.dphi[2]
    a10, a11_, a12_ = s.a_hist[0, 0], s.a_hist[0, 1], s.a_hist[0, 2]
    a20, a21_, a22_ = s.a_hist[1, 0], s.a_hist[1, 1], s.a_hist[1, 2]
    a30, a31_, a32_ = s.a_hist[2, 0], s.a_hist[2, 1], s.a_hist[2, 2]
    c0, c1, c2 = s.a_bias[0], s.a_bias[1], s.a_bias[2]
    gb0, gb1, gb2 = s.gyro_bias[0], s.gyro_bias[1], s.gyro_bias[2]
    S0, S1 = s.S[0], s.S[1]
    blk0, blk1, blk2 = s.blk[0], s.blk[1], s.blk[2]
    t, t_adapt, t_incl, t_incl_used = s.clock[T], s.clock[T_ADAPT], s.clock[T_INCL], s.clock[T_INCL_USED]
    m0, m1 = s.incl_pending[0], s.incl_pending[1]
    n_steps = s.flags[N_STEPS]
    has_w = s.flags[HAS_OMEGA_PREV2] != 0
    has_tens = s.flags[HAS_TENSIONS] != 0
    pending = s.flags[INCL_PENDING] != 0
    im = c.imu_m
    n00, n01, n10, n11, n20, n21 = c.incl_m[0], c.incl_m[1], c.incl_m[3], c.incl_m[4], c.incl_m[6], c.incl_m[7]
    i0, i1, i2 = c.r_imu[0], c.r_imu[1], c.r_imu[2]
    gravity = c.gravity
    k_bias = c.tau_tilt / c.tau_bias ** 2
    wn = 2 * math.pi * c.f_position
    n_pose, n_step, n_hist, n_sums = out.counts[POSES], out.counts[STEPS], out.counts[HISTORY], out.counts[SUMS]
    status = -1
    for e in range(start, ev_t.shape[0]):
        kind = ev_kind[e]
        row = ev_index[e]
        if kind == EVENT_INCLINOMETER:   # used by the next IMU sample's tilt correction
            t_incl = ev_t[e]
            m0, m1 = incl[row, 0], incl[row, 1]
            pending = True
            continue
        if kind == EVENT_TENSIONS:       # the cables' stretch T/k in the length constraints
            for i in range(n):
                tensions[i] = tens[row, i]
            has_tens = True
            continue
        if kind != EVENT_IMU:
            continue
        # --- one IMU sample: gyro and specific force in body axes, gyro bias removed ---
        t_new = ev_t[e]
        dt = t_new - t
        if dt <= 0:
            status = e
            break
        gx, gy, gz = imu[row, 0], imu[row, 1], imu[row, 2]
        ax, ay, az = imu[row, 3], imu[row, 4], imu[row, 5]
        g0 = im[0] * gx + im[1] * gy + im[2] * gz - gb0
        g1 = im[3] * gx + im[4] * gy + im[5] * gz - gb1
        g2 = im[6] * gx + im[7] * gy + im[8] * gz - gb2
        f0 = im[0] * ax + im[1] * ay + im[2] * az
        f1 = im[3] * ax + im[4] * ay + im[5] * az
        f2 = im[6] * ax + im[7] * ay + im[8] * az
        # --- the strapdown step ---
        if not has_w:
            w0, w1, w2 = o0, o1, o2
        h = dt / 12
        # a stepped input at the previous sample (tracker's module docstring): recognised now
        # that the sample after it shows the specific force stayed there; the world-frame
        # acceleration is re-derived with the previous attitude (a jump of >= 0.2 m/s² is not
        # confused with the rotation's own change)
        # (second differences D₋₁ = a₋₁ − 2a₋₂ + a₋₃ and D₀ = a₀ − 2a₋₁ + a₋₂: a step Δ at the
        # previous sample gives D₋₁ ≈ Δ, D₀ ≈ −Δ whatever the slope; see
        # gyro_fit.step_indices)
        b0 = r00 * f0 + r01 * f1 + r02 * f2 - c0
        b1 = r10 * f0 + r11 * f1 + r12 * f2 - c1
        b2 = r20 * f0 + r21 * f1 + r22 * f2 - gravity - c2
        s0, s1, s2 = a10 - 2 * a20 + a30, a11_ - 2 * a21_ + a31_, a12_ - 2 * a22_ + a32_
        n1 = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        step = (n1 > c.step_accel
                and math.sqrt((b0 - a10 - a20 + a30) ** 2 + (b1 - a11_ - a21_ + a31_) ** 2
                              + (b2 - a12_ - a22_ + a32_) ** 2) < 0.5 * n1)
        # rotation increment over the interval: third-order Adams–Moulton quadrature of ω
        # through the last three samples (the midpoint rule's (ωh)²/12 amplitude error would
        # bias the tensor by ~0.05 % at 100 Hz sampling) — the trapezoidal rule right after a
        # step, where ω has a kink; the previous step's world-frame correction dphi is applied
        # here, in body axes (exp(dphi) R exp(theta) = R exp(R^T dphi + theta) to
        # O(|dphi||theta|) ~ 1e-9 rad)
        if step:
            q0, q1, q2 = (g0 + o0) * 6 * h, (g1 + o1) * 6 * h, (g2 + o2) * 6 * h
        else:
            q0, q1, q2 = (5 * g0 + 8 * o0 - w0) * h, (5 * g1 + 8 * o1 - w1) * h, (5 * g2 + 8 * o2 - w2) * h
        e00, e01, e02, e10, e11, e12, e20, e21, e22 = rotvec_matrix(
            q0 + (r00 * d0 + r10 * d1 + r20 * d2),
            q1 + (r01 * d0 + r11 * d1 + r21 * d2),
            q2 + (r02 * d0 + r12 * d1 + r22 * d2))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
            r00 * e00 + r01 * e10 + r02 * e20, r00 * e01 + r01 * e11 + r02 * e21, r00 * e02 + r01 * e12 + r02 * e22,
            r10 * e00 + r11 * e10 + r12 * e20, r10 * e01 + r11 * e11 + r12 * e21, r10 * e02 + r11 * e12 + r12 * e22,
            r20 * e00 + r21 * e10 + r22 * e20, r20 * e01 + r21 * e11 + r22 * e21, r20 * e02 + r21 * e12 + r22 * e22)
        w0, w1, w2 = o0, o1, o2
        has_w = True
        o0, o1, o2 = g0, g1, g2
        # the filter tracks the IMU point, whose acceleration the accelerometer gives without
        # lever-arm terms: a = R f + g; each sample is rotated with its own attitude, then
        # velocity and position follow by the same third-order quadrature (the trapezoidal
        # rule's amplitude error biased Iyy by 0.01 %)
        k0 = r00 * f0 + r01 * f1 + r02 * f2 - c0
        k1 = r10 * f0 + r11 * f1 + r12 * f2 - c1
        k2 = r20 * f0 + r21 * f1 + r22 * f2 - gravity - c2
        if step:
            # the previous interval, before the step: from the samples before it
            # ((3a₋₂ − a₋₃)/2 instead of Adams–Moulton's (5a₋₁ + 8a₋₂ − a₋₃)/12 per dt), and
            # its effect on the position; this interval by the trapezoidal rule
            out.steps[n_step] = t
            n_step += 1
            cv0, cv1, cv2 = (-5 * h * (a10 - 2 * a20 + a30), -5 * h * (a11_ - 2 * a21_ + a31_),
                             -5 * h * (a12_ - 2 * a22_ + a32_))
            v0, v1, v2 = v0 + cv0, v1 + cv1, v2 + cv2
            p0, p1, p2 = p0 + 5 * h * cv0, p1 + 5 * h * cv1, p2 + 5 * h * cv2
            u0, u1, u2 = v0 + (k0 + a10) * 6 * h, v1 + (k1 + a11_) * 6 * h, v2 + (k2 + a12_) * 6 * h
            p0, p1, p2 = p0 + (u0 + v0) * 6 * h, p1 + (u1 + v1) * 6 * h, p2 + (u2 + v2) * 6 * h
        else:
            u0 = v0 + (5 * k0 + 8 * a10 - a20) * h
            u1 = v1 + (5 * k1 + 8 * a11_ - a21_) * h
            u2 = v2 + (5 * k2 + 8 * a12_ - a22_) * h
            p0 = p0 + (5 * u0 + 8 * v0 - vp0) * h
            p1 = p1 + (5 * u1 + 8 * v1 - vp1) * h
            p2 = p2 + (5 * u2 + 8 * v2 - vp2) * h
        a30, a31_, a32_ = a20, a21_, a22_
        a20, a21_, a22_ = a10, a11_, a12_
        a10, a11_, a12_ = k0, k1, k2
        vp0, vp1, vp2 = v0, v1, v2
        v0, v1, v2 = u0, u1, u2
        # --- tilt correction: world-frame rotation toward the inclinometer, else gravity ---
        t0 = t1 = 0.0
        if c.has_incl:
            if pending:
                pending = False
                ax0, ax1, ax2 = r00 * n00 + r01 * n10 + r02 * n20, r10 * n00 + r11 * n10 + r12 * n20, \
                    r20 * n00 + r21 * n10 + r22 * n20
                ay0, ay1, ay2 = r00 * n01 + r01 * n11 + r02 * n21, r10 * n01 + r11 * n11 + r12 * n21, \
                    r20 * n01 + r21 * n11 + r22 * n21
                px = math.asin(min(1.0, max(-1.0, ax2)))
                py = math.asin(min(1.0, max(-1.0, ay2)))
                # d elevation / d(world rotation phi) = (a x z) / cos(elevation);
                # H^T (H H^T)^-1 (meas - pred), H (2,3) with a zero third column
                cx, cy = math.cos(px), math.cos(py)
                h00, h01 = ax1 / cx, -ax0 / cx
                h10, h11 = ay1 / cy, -ay0 / cy
                s00, s01, s11 = h00 * h00 + h01 * h01, h00 * h10 + h01 * h11, h10 * h10 + h11 * h11
                e0, e1 = m0 - px, m1 - py
                det = s00 * s11 - s01 * s01
                y0, y1 = (s11 * e0 - s01 * e1) / det, (s00 * e1 - s01 * e0) / det
                gain = min(1.0, (t_incl - t_incl_used) / c.tau_tilt)
                t_incl_used = t_incl
                t0, t1 = gain * (h00 * y0 + h10 * y1), gain * (h01 * y0 + h11 * y1)
        else:   # no inclinometer: align the measured specific force with gravity, slowly
            z0, z1, z2 = r00 * f0 + r01 * f1 + r02 * f2, r10 * f0 + r11 * f1 + r12 * f2, r20 * f0 + r21 * f1 + r22 * f2
            nz = math.sqrt(z0 * z0 + z1 * z1 + z2 * z2)
            if not nz < 1e-6:
                ct = dt / c.tau_tilt_accel
                t0, t1 = ct * z1 / nz, ct * -z0 / nz
        # --- cable-length correction: position (third-order complementary filter) and yaw ---
        # normal equations G^T G delta = -G^T r accumulated over the cables, with the rows
        # G_i = (-u_i, -(R b_i x u_i)_z): d l_i = -u_i . dp - (R b_i x u_i) . dphi, unknowns dp (3)
        # and the yaw about world z
        A00 = A01 = A02 = A03 = A11 = A12 = A13 = A22 = A23 = A33 = 0.0
        y0 = y1 = y2 = y3 = 0.0
        for i in range(n):
            bb0, bb1, bb2 = c.anchors[i, 0], c.anchors[i, 1], c.anchors[i, 2]
            L = lengths[i]
            if has_tens:
                L = L + tensions[i] * comp[i]
            rb0, rb1 = r00 * bb0 + r01 * bb1 + r02 * bb2, r10 * bb0 + r11 * bb1 + r12 * bb2
            rb2 = r20 * bb0 + r21 * bb1 + r22 * bb2
            x0, x1, x2 = c.ceiling[i, 0] - (p0 + rb0), c.ceiling[i, 1] - (p1 + rb1), c.ceiling[i, 2] - (p2 + rb2)
            lv = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            G0, G1, G2 = -(x0 / lv), -(x1 / lv), -(x2 / lv)
            G3 = -(rb0 * -G1 - rb1 * -G0)
            r = lv - L
            resid[i] = r
            A00 += G0 * G0
            A01 += G0 * G1
            A02 += G0 * G2
            A03 += G0 * G3
            A11 += G1 * G1
            A12 += G1 * G2
            A13 += G1 * G3
            A22 += G2 * G2
            A23 += G2 * G3
            A33 += G3 * G3
            y0 -= G0 * r
            y1 -= G1 * r
            y2 -= G2 * r
            y3 -= G3 * r
        if c.adapt and has_tens:
            # --- online compliance: the in-band length residual regressed on the tension ---
            # variation (both high-passed, 5 s; sums forgotten over ~60 s): in the band where the
            # pose follows the inertial sensors, a residual that follows the tension is
            # unmodelled stretch, delta_c = <e T> / <T T>; stamp: the previous sample's
            a = min(1.0, dt / 5.0)
            s_et = s_tt = s_e0t = 0.0
            for i in range(n):
                hp_e[i] += a * (resid[i] - hp_e[i])
                hp_T[i] += a * (tensions[i] - hp_T[i])
                ei = resid[i] - hp_e[i]
                dT = tensions[i] - hp_T[i]
                s_et += ei * dT
                s_tt += dT * dT
                s_e0t += (ei + comp[i] * dT) * dT   # the residual of an inextensible cable
            lam = 1.0 - dt / 60.0
            S0 = lam * S0 + s_et
            S1 = lam * S1 + s_tt
            blk0 += s_e0t
            blk1 += s_tt
            blk2 += 1
            if t - t_adapt >= 2.0:
                t_adapt = t
                out.sums[n_sums, 0] = t
                out.sums[n_sums, 1] = blk0
                out.sums[n_sums, 2] = blk1
                out.sums[n_sums, 3] = blk2
                n_sums += 1
                blk0 = blk1 = 0.0
                blk2 = 0.0
                # enough tension variation: at least ~50 N RMS per cable over the horizon
                if S1 > (50.0 ** 2) * n * (60.0 / dt) * 0.1:
                    dc = S0 / S1
                    for i in range(n):
                        if c.fit[i]:
                            comp[i] = min(max(comp[i] + dc, 0.0), 1e-5)
                        lengths[i] = c.l0[i] - c.T0[i] * comp[i]
                        out.history_c[n_hist, i] = comp[i]
                    out.history_t[n_hist] = t
                    n_hist += 1
                    S0 = S1 = 0.0
        # regularised: (G^T G + Λ) delta = -G^T r, Λ = 1e-12 tr(G^T G) on the position and
        # YAW_PRIOR tr on the yaw: cables splayed radially from the body's centre (their
        # horizontal directions through the anchors' centroid, a common rig) leave the yaw
        # undetermined by the lengths to first order — the unregularised solve turned the
        # tilt's and the stretch's small residuals into yaw corrections and diverged (a 5.9 m
        # frame on four such cables: 0.3 rad within 2 s); there the yaw follows the gyro
        eps = 1e-12 * (A00 + A11 + A22 + A33)
        lam_yaw = c.yaw_prior * (A00 + A11 + A22)
        x0, x1, x2, x3 = solve_spd4(A00 + eps, A01, A02, A03, A11 + eps, A12, A13, A22 + eps, A23, A33 + lam_yaw,
                                    y0, y1, y2, y3)
        # third-order complementary filter (poles at -wn): the integral state absorbs a
        # constant acceleration error (tilt error x g, accelerometer bias)
        kp, kv, ka = 3 * wn * dt, 3 * wn * wn * dt, wn ** 3 * dt
        p0, p1, p2 = p0 + kp * x0, p1 + kp * x1, p2 + kp * x2
        v0, v1, v2 = v0 + kv * x0, v1 + kv * x1, v2 + kv * x2
        c0, c1, c2 = c0 - ka * x0, c1 - ka * x1, c2 - ka * x2
        yaw = min(1.0, dt / c.tau_yaw) * x3
        # --- the corrections, applied at the next step; integral action: a steady correction
        # is a gyro bias (PI complementary filter, natural frequency 1/tau_bias) ---
        d0, d1, d2 = t0, t1, 0.0 + yaw
        gb0, gb1, gb2 = (gb0 - k_bias * (r00 * d0 + r10 * d1 + r20 * d2),
                         gb1 - k_bias * (r01 * d0 + r11 * d1 + r21 * d2),
                         gb2 - k_bias * (r02 * d0 + r12 * d1 + r22 * d2))
        n_steps += 1
        if n_steps % REORTHONORMALISE == 0:
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = orthonormalise((r00, r01, r02, r10, r11, r12,
                                                                          r20, r21, r22))
        t = t_new
        write_pose(out, n_pose, t, (r00, r01, r02, r10, r11, r12, r20, r21, r22), (p0, p1, p2), (v0, v1, v2),
                   (o0, o1, o2), (i0, i1, i2))
        n_pose += 1
    # write the state back
    s.R[0], s.R[1], s.R[2], s.R[3], s.R[4], s.R[5], s.R[6], s.R[7], s.R[8] = r00, r01, r02, r10, r11, r12, r20, r21, r22
    s.p[0], s.p[1], s.p[2] = p0, p1, p2
    s.v[0], s.v[1], s.v[2] = v0, v1, v2
    s.v_prev[0], s.v_prev[1], s.v_prev[2] = vp0, vp1, vp2
    s.omega[0], s.omega[1], s.omega[2] = o0, o1, o2
    s.omega_prev2[0], s.omega_prev2[1], s.omega_prev2[2] = w0, w1, w2
    s.dphi[0], s.dphi[1], s.dphi[2] = d0, d1, d2
    s.a_hist[0, 0], s.a_hist[0, 1], s.a_hist[0, 2] = a10, a11_, a12_
    s.a_hist[1, 0], s.a_hist[1, 1], s.a_hist[1, 2] = a20, a21_, a22_
    s.a_hist[2, 0], s.a_hist[2, 1], s.a_hist[2, 2] = a30, a31_, a32_
    s.a_bias[0], s.a_bias[1], s.a_bias[2] = c0, c1, c2
    s.gyro_bias[0], s.gyro_bias[1], s.gyro_bias[2] = gb0, gb1, gb2
    s.S[0], s.S[1] = S0, S1
    s.blk[0], s.blk[1], s.blk[2] = blk0, blk1, blk2
    s.clock[T], s.clock[T_ADAPT], s.clock[T_INCL], s.clock[T_INCL_USED] = t, t_adapt, t_incl, t_incl_used
    s.incl_pending[0], s.incl_pending[1] = m0, m1
    s.flags[N_STEPS] = n_steps
    s.flags[HAS_OMEGA_PREV2] = 1 if has_w else 0
    s.flags[HAS_TENSIONS] = 1 if has_tens else 0
    s.flags[INCL_PENDING] = 1 if pending else 0
    out.counts[POSES], out.counts[STEPS], out.counts[HISTORY], out.counts[SUMS] = n_pose, n_step, n_hist, n_sums
    return status
