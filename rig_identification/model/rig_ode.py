"""The rig's exact equations integrated fast: every sensor's reading along a simulated run.

The same physics as :class:`~rig_identification.model.dynamics.RigDynamics` with spring-damper
cables (Newton–Euler with the gyroscopic term; tension max(0, k_i (l_i - L_i) + τ k_i dl_i/dt)
along the cable; the ceiling pins' friction, a Coulomb moment μ r T_i resisting each cable's
swing: the force μ r T_i / l_i across the cable at its body anchor, against the anchor's
velocity across it, regularised; the body's damping on the CG's velocity and the angular
velocity: viscous -c v and quadratic -c |v| v; the exciter's unbalanced mass m_u e on its arm,
toward the measured force's direction û: the moment m_u e û × (g − a_e) of its weight and of its
inertial force on the exciter axis's acceleration a_e, which a rotor whose drive holds its speed
passes to the body, and the mass's inertial force from the body's rotation at the axis,
−m_u e [ω̇ × û + ω × (ω × û) + 2 Ω ω × (ẑ × û)], Ω the force's rotation rate about the exciter's
z axis ẑ: the Coriolis term of the mass's velocity e Ω ẑ × û), driven by the measured
exciter force (its frame turning with the body), the force a cubic spline through the samples of
a uniform grid (linear interpolation of a 200 Hz force leaves 0.2 N in the tensions: they see
the motion that finely).  Classical fourth-order Runge–Kutta with a fixed step (``substeps``
per grid step, chosen by :func:`substeps_for` so that the stiffest cable mode stays inside the
method's stability region), compiled with numba (numpy's error model: a division by zero gives
inf or nan, which the fit takes as a diverged run, where Python's would raise; no check before each division,
the same bits otherwise): the
output-error fit (:mod:`~rig_identification.estimation.rig_fit`) runs it once per parameter
perturbation.

Outputs on the grid, in this order:
the N tensions times the load cells' gains, the gyro (IMU axes), the accelerometer's specific
force (IMU axes, the lever arm's tangential and centripetal terms included), the
inclinometer's two elevations asin(z_world · axis); the exciter's load cells' readings apart
(:func:`exciter_readings`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from .linear_rig import RestPose, RigParameters
from .parametrisation import to_tensor
from .rigid_body import bearing_inertial_force

#: ω_max h of the fixed step: RK4 is stable to 2.8; the cables' axial modes it integrates
#: coarsely lie above the fit's band, and the band's motion (≤ 5 Hz) is resolved to ~1e-6.
STEP_OMEGA = 0.5
#: Grid samples either side over which the exciter force's rotation rate (the rotor's spin relative
#: to the body, :func:`_spin`) is taken: the force's noise (0.5 N on 230 N) moves its direction by
#: ~2 mrad per sample, which over ±5 samples at 200 Hz is under 1 % of a 1.25 Hz spin.
SPIN_REACH = 5
#: m/s: the pins' Coulomb friction −F v/sqrt(|v|² + ε²) (v the body anchor's velocity across its
#: cable) is regularised over this speed ε, well below a swing's anchor speeds (mm/s to cm/s), so
#: that the friction is dry, not viscous, over nearly all of a swing.
PIVOT_SPEED = 1e-4


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _rhs(y: np.ndarray, u0: float, u1: float, om: float, A: np.ndarray, r: np.ndarray, L: np.ndarray, k: np.ndarray,
         c: np.ndarray, m: float, J: np.ndarray, Jinv: np.ndarray, g: float, Re: np.ndarray, re: np.ndarray,
         bd: np.ndarray, out_T: np.ndarray, dy: np.ndarray, R: np.ndarray) -> None:
    """State derivative into ``dy``; y = [p_cg 3, quaternion wxyz 4, v_cg 3, ω body 3]; the
    rotation into ``R``, the tensions into ``out_T``."""
    qw, qx, qy, qz = y[3], y[4], y[5], y[6]
    R[0, 0] = 1 - 2 * (qy * qy + qz * qz)
    R[0, 1] = 2 * (qx * qy - qw * qz)
    R[0, 2] = 2 * (qx * qz + qw * qy)
    R[1, 0] = 2 * (qx * qy + qw * qz)
    R[1, 1] = 1 - 2 * (qx * qx + qz * qz)
    R[1, 2] = 2 * (qy * qz - qw * qx)
    R[2, 0] = 2 * (qx * qz - qw * qy)
    R[2, 1] = 2 * (qy * qz + qw * qx)
    R[2, 2] = 1 - 2 * (qx * qx + qy * qy)
    wx, wy, wz = y[10], y[11], y[12]
    Fx, Fy, Fz = 0.0, 0.0, -m * g
    Mx, My, Mz = 0.0, 0.0, 0.0
    for i in range(L.shape[0]):
        rx, ry, rz = r[i, 0], r[i, 1], r[i, 2]
        # body-frame velocity of the anchor relative to the CG: ω × r
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        sx = R[0, 0] * rx + R[0, 1] * ry + R[0, 2] * rz
        sy = R[1, 0] * rx + R[1, 1] * ry + R[1, 2] * rz
        sz = R[2, 0] * rx + R[2, 1] * ry + R[2, 2] * rz
        pdx = y[7] + R[0, 0] * cx + R[0, 1] * cy + R[0, 2] * cz
        pdy = y[8] + R[1, 0] * cx + R[1, 1] * cy + R[1, 2] * cz
        pdz = y[9] + R[2, 0] * cx + R[2, 1] * cy + R[2, 2] * cz
        dx = A[i, 0] - (y[0] + sx)
        dyy = A[i, 1] - (y[1] + sy)
        dz = A[i, 2] - (y[2] + sz)
        length = math.sqrt(dx * dx + dyy * dyy + dz * dz)
        ux, uy, uz = dx / length, dyy / length, dz / length
        ldot = -(ux * pdx + uy * pdy + uz * pdz)
        T = k[i] * (length - L[i]) + c[i] * ldot
        if T < 0.0:
            T = 0.0
        out_T[i] = T
        fx, fy, fz = T * ux, T * uy, T * uz
        if bd[5] != 0.0 and T > 0.0:      # the ceiling pin's friction moment μ r T, across the cable at the anchor
            vx, vy, vz = pdx + ldot * ux, pdy + ldot * uy, pdz + ldot * uz     # the anchor's velocity across it
            sc = -bd[5] * T / (length * math.sqrt(vx * vx + vy * vy + vz * vz + PIVOT_SPEED * PIVOT_SPEED))
            fx, fy, fz = fx + sc * vx, fy + sc * vy, fz + sc * vz
        Fx += fx
        Fy += fy
        Fz += fz
        bx = R[0, 0] * fx + R[1, 0] * fy + R[2, 0] * fz
        by = R[0, 1] * fx + R[1, 1] * fy + R[2, 1] * fz
        bz = R[0, 2] * fx + R[1, 2] * fy + R[2, 2] * fz
        Mx += ry * bz - rz * by
        My += rz * bx - rx * bz
        Mz += rx * by - ry * bx
    ex = Re[0, 0] * u0 + Re[0, 1] * u1
    ey = Re[1, 0] * u0 + Re[1, 1] * u1
    ez = Re[2, 0] * u0 + Re[2, 1] * u1
    Fx += R[0, 0] * ex + R[0, 1] * ey + R[0, 2] * ez
    Fy += R[1, 0] * ex + R[1, 1] * ey + R[1, 2] * ez
    Fz += R[2, 0] * ex + R[2, 1] * ey + R[2, 2] * ez
    Mx += re[1] * ez - re[2] * ey
    My += re[2] * ex - re[0] * ez
    Mz += re[0] * ey - re[1] * ex
    fn = math.sqrt(ex * ex + ey * ey + ez * ez)
    if bd[4] != 0.0 and fn > 0.0:          # the exciter's unbalanced mass, its weight turning with it
        gx, gy, gz = -g * R[2, 0], -g * R[2, 1], -g * R[2, 2]
        Mx += bd[4] * (ey * gz - ez * gy) / fn
        My += bd[4] * (ez * gx - ex * gz) / fn
        Mz += bd[4] * (ex * gy - ey * gx) / fn
    # the body's damping: viscous bd[0:2], quadratic bd[2:4] (linear, angular); bd[4]: the exciter's
    # unbalance (above); bd[5]: the pins' μ r (in the cables' loop)
    speed = math.sqrt(y[7] * y[7] + y[8] * y[8] + y[9] * y[9])
    spin = math.sqrt(wx * wx + wy * wy + wz * wz)
    fl = bd[0] + bd[2] * speed
    fa = bd[1] + bd[3] * spin
    Fx -= fl * y[7]
    Fy -= fl * y[8]
    Fz -= fl * y[9]
    Mx -= fa * wx
    My -= fa * wy
    Mz -= fa * wz
    dy[0], dy[1], dy[2] = y[7], y[8], y[9]
    dy[3] = 0.5 * (-qx * wx - qy * wy - qz * wz)
    dy[4] = 0.5 * (qw * wx + qy * wz - qz * wy)
    dy[5] = 0.5 * (qw * wy + qz * wx - qx * wz)
    dy[6] = 0.5 * (qw * wz + qx * wy - qy * wx)
    dy[7], dy[8], dy[9] = Fx / m, Fy / m, Fz / m
    hx = J[0, 0] * wx + J[0, 1] * wy + J[0, 2] * wz
    hy = J[1, 0] * wx + J[1, 1] * wy + J[1, 2] * wz
    hz = J[2, 0] * wx + J[2, 1] * wy + J[2, 2] * wz
    tx = Mx - (wy * hz - wz * hy)
    ty = My - (wz * hx - wx * hz)
    tz = Mz - (wx * hy - wy * hx)
    dy[10] = Jinv[0, 0] * tx + Jinv[0, 1] * ty + Jinv[0, 2] * tz
    dy[11] = Jinv[1, 0] * tx + Jinv[1, 1] * ty + Jinv[1, 2] * tz
    dy[12] = Jinv[2, 0] * tx + Jinv[2, 1] * ty + Jinv[2, 2] * tz
    if bd[4] != 0.0 and fn > 0.0:
        # the unbalanced mass's inertial force on its arm: −m_u e û × a_e, a_e the exciter axis's
        # acceleration (body axes) from this derivative (one fixed-point pass: the moment is ~1 % of
        # its weight's, and moves the accelerations it depends on by ~1 % of itself)
        ax = R[0, 0] * dy[7] + R[1, 0] * dy[8] + R[2, 0] * dy[9]
        ay = R[0, 1] * dy[7] + R[1, 1] * dy[8] + R[2, 1] * dy[9]
        az = R[0, 2] * dy[7] + R[1, 2] * dy[8] + R[2, 2] * dy[9]
        px, py, pz = wy * re[2] - wz * re[1], wz * re[0] - wx * re[2], wx * re[1] - wy * re[0]
        ax += dy[11] * re[2] - dy[12] * re[1] + wy * pz - wz * py
        ay += dy[12] * re[0] - dy[10] * re[2] + wz * px - wx * pz
        az += dy[10] * re[1] - dy[11] * re[0] + wx * py - wy * px
        s_ = -bd[4] / fn
        nx, ny, nz = s_ * (ey * az - ez * ay), s_ * (ez * ax - ex * az), s_ * (ex * ay - ey * ax)
        # the unbalanced mass's inertial force from the body's rotation, at the exciter axis (body
        # axes): −m_u e [ω̇ × û + ω × (ω × û) + 2 Ω ω × (ẑ × û)], Ω the spin relative to the body
        # about the exciter's z axis ẑ (the Coriolis term: the mass's velocity e Ω ẑ × û)
        ux, uy, uz = ex / fn, ey / fn, ez / fn
        zx = Re[1, 0] * Re[2, 1] - Re[2, 0] * Re[1, 1]
        zy = Re[2, 0] * Re[0, 1] - Re[0, 0] * Re[2, 1]
        zz = Re[0, 0] * Re[1, 1] - Re[1, 0] * Re[0, 1]
        vx, vy, vz = zy * uz - zz * uy, zz * ux - zx * uz, zx * uy - zy * ux          # ẑ × û
        wux, wuy, wuz = wy * uz - wz * uy, wz * ux - wx * uz, wx * uy - wy * ux     # ω × û
        fbx = dy[11] * uz - dy[12] * uy + wy * wuz - wz * wuy + 2 * om * (wy * vz - wz * vy)
        fby = dy[12] * ux - dy[10] * uz + wz * wux - wx * wuz + 2 * om * (wz * vx - wx * vz)
        fbz = dy[10] * uy - dy[11] * ux + wx * wuy - wy * wux + 2 * om * (wx * vy - wy * vx)
        fbx, fby, fbz = -bd[4] * fbx, -bd[4] * fby, -bd[4] * fbz
        nx += re[1] * fbz - re[2] * fby
        ny += re[2] * fbx - re[0] * fbz
        nz += re[0] * fby - re[1] * fbx
        dy[7] += (R[0, 0] * fbx + R[0, 1] * fby + R[0, 2] * fbz) / m
        dy[8] += (R[1, 0] * fbx + R[1, 1] * fby + R[1, 2] * fbz) / m
        dy[9] += (R[2, 0] * fbx + R[2, 1] * fby + R[2, 2] * fbz) / m
        dy[10] += Jinv[0, 0] * nx + Jinv[0, 1] * ny + Jinv[0, 2] * nz
        dy[11] += Jinv[1, 0] * nx + Jinv[1, 1] * ny + Jinv[1, 2] * nz
        dy[12] += Jinv[2, 0] * nx + Jinv[2, 1] * ny + Jinv[2, 2] * nz


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _spin(force: np.ndarray, j: int, reach: int, h: float) -> float:
    """The force's rotation rate rad/s about the exciter's z axis at row ``j`` of the drive's
    samples (every h/2 s): the angle between the rows ``reach`` either side (clipped at the ends)
    over their time apart."""
    a = max(0, j - reach)
    b = min(force.shape[0] - 1, j + reach)
    if b == a:
        return 0.0
    cross = force[a, 0] * force[b, 1] - force[a, 1] * force[b, 0]
    dot = force[a, 0] * force[b, 0] + force[a, 1] * force[b, 1]
    rate: float = math.atan2(cross, dot) / ((b - a) * 0.5 * h)
    return rate


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _readings(y: np.ndarray, dy: np.ndarray, T: np.ndarray, R: np.ndarray, gain: np.ndarray, g: float,
              Rimu: np.ndarray, rimu: np.ndarray, Rinc: np.ndarray, has_inc: bool, out: np.ndarray) -> None:
    """Every sensor's reading (module docstring) into ``out`` from the state ``y``, its derivative
    ``dy``, the tensions ``T`` and the rotation ``R`` that :func:`_rhs` left."""
    N = T.shape[0]
    for i in range(N):
        out[i] = gain[i] * T[i]
    wx, wy, wz = y[10], y[11], y[12]
    ax, ay, az = dy[10], dy[11], dy[12]
    rx, ry, rz = rimu[0], rimu[1], rimu[2]
    # specific force at the IMU, body axes: Rᵀ (a_cg + g e_z) + ω̇ × r + ω × (ω × r)
    fx, fy, fz = dy[7], dy[8], dy[9] + g
    cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
    bx = R[0, 0] * fx + R[1, 0] * fy + R[2, 0] * fz + ay * rz - az * ry + wy * cz - wz * cy
    by = R[0, 1] * fx + R[1, 1] * fy + R[2, 1] * fz + az * rx - ax * rz + wz * cx - wx * cz
    bz = R[0, 2] * fx + R[1, 2] * fy + R[2, 2] * fz + ax * ry - ay * rx + wx * cy - wy * cx
    for j in range(3):
        out[N + j] = Rimu[0, j] * wx + Rimu[1, j] * wy + Rimu[2, j] * wz
        out[N + 3 + j] = Rimu[0, j] * bx + Rimu[1, j] * by + Rimu[2, j] * bz
    if has_inc:
        for j in range(2):
            e = R[2, 0] * Rinc[0, j] + R[2, 1] * Rinc[1, j] + R[2, 2] * Rinc[2, j]
            out[N + 6 + j] = math.asin(min(1.0, max(-1.0, e)))


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _simulate(y0: np.ndarray, force: np.ndarray, dt: float, substeps: int, A: np.ndarray, r: np.ndarray,
              L: np.ndarray, k: np.ndarray, c: np.ndarray, gain: np.ndarray, m: float, J: np.ndarray,
              Jinv: np.ndarray, g: float, Re: np.ndarray, re: np.ndarray, bd: np.ndarray, Rimu: np.ndarray,
              rimu: np.ndarray, Rinc: np.ndarray, has_inc: bool) -> tuple[np.ndarray, np.ndarray]:
    # force: sampled every half RK4 step, (n - 1) * 2 * substeps + 1 rows
    n = (force.shape[0] - 1) // (2 * substeps) + 1
    N = L.shape[0]
    n_out = N + 6 + (2 if has_inc else 0)
    out = np.empty((n, n_out))
    states = np.empty((n, 13))
    T = np.empty(N)
    R = np.empty((3, 3))
    y = y0.copy()
    yt = np.empty(13)
    k1, k2, k3, k4 = np.empty(13), np.empty(13), np.empty(13), np.empty(13)
    h = dt / substeps
    rotor = bd[4] != 0.0
    reach = SPIN_REACH * 2 * substeps
    for j in range(n):
        for s_ in range(substeps):
            b = 2 * (substeps * j + s_)
            _rhs(y, force[b, 0], force[b, 1], _spin(force, b, reach, h) if rotor else 0.0, A, r, L, k, c, m, J, Jinv,
                 g, Re, re, bd, T, k1, R)
            if s_ == 0:                    # the readings at the grid's sample: the first stage's derivative
                _readings(y, k1, T, R, gain, g, Rimu, rimu, Rinc, has_inc, out[j])
                states[j] = y
                if j == n - 1:
                    return out, states
            ub0, ub1 = force[b + 1, 0], force[b + 1, 1]
            uc0, uc1 = force[b + 2, 0], force[b + 2, 1]
            for i in range(13):
                yt[i] = y[i] + 0.5 * h * k1[i]
            om = _spin(force, b + 1, reach, h) if rotor else 0.0
            _rhs(yt, ub0, ub1, om, A, r, L, k, c, m, J, Jinv, g, Re, re, bd, T, k2, R)
            for i in range(13):
                yt[i] = y[i] + 0.5 * h * k2[i]
            _rhs(yt, ub0, ub1, om, A, r, L, k, c, m, J, Jinv, g, Re, re, bd, T, k3, R)
            for i in range(13):
                yt[i] = y[i] + h * k3[i]
            _rhs(yt, uc0, uc1, _spin(force, b + 2, reach, h) if rotor else 0.0, A, r, L, k, c, m, J, Jinv, g, Re, re,
                 bd, T, k4, R)
            for i in range(13):
                y[i] = y[i] + h / 6.0 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i])
            qn = math.sqrt(y[3] ** 2 + y[4] ** 2 + y[5] ** 2 + y[6] ** 2)
            for i in range(3, 7):
                y[i] = y[i] / qn
    return out, states


def substeps_for(omega_max: float, dt: float) -> int:
    """RK4 steps per grid step so that ω_max h ≤ :data:`STEP_OMEGA` (ω_max rad/s: the
    stiffest mode)."""
    return max(1, int(math.ceil(omega_max * dt / STEP_OMEGA)))


def rest_state(p: RigParameters, rest: RestPose) -> np.ndarray:
    """The state (13,) = [p_cg world m, quaternion wxyz, v_cg world m/s, ω body rad/s] at rest."""
    q = Rotation.from_matrix(rest.rotation).as_quat()                      # xyzw
    return np.concatenate([rest.position + rest.rotation @ p.cg, [q[3], q[0], q[1], q[2]], np.zeros(6)])


def moved_state(y: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The state ``y`` (13,) moved by ``offset`` (12,) = (δp_cg world m, δφ world rad, δv_cg world
    m/s, δω body rad/s); or k states (k, 13) each by its offset (k, 12)."""
    y, off = np.asarray(y, float), np.asarray(offset, float)
    ys, offs = np.atleast_2d(y), np.atleast_2d(off)
    qn = (Rotation.from_rotvec(offs[:, 3:6]) * Rotation.from_quat(ys[:, [4, 5, 6, 3]])).as_quat()
    out = np.column_stack([ys[:, :3] + offs[:, :3], qn[:, [3, 0, 1, 2]], ys[:, 7:10] + offs[:, 6:9],
                           ys[:, 10:13] + offs[:, 9:12]])
    return out if y.ndim == 2 else out[0]


@dataclass(frozen=True)
class Drive:
    """The exciter force (exciter frame, N) as the integrator takes it: ``fine`` ((n − 1) · 2 ·
    ``substeps`` + 1, 2) sampled at every RK4 stage (every half step) of a run over n grid samples
    ``dt`` s apart, ``substeps`` RK4 steps per grid step (:func:`drive`)."""

    fine: np.ndarray
    dt: float
    substeps: int

    @property
    def samples(self) -> int:
        return (len(self.fine) - 1) // (2 * self.substeps) + 1


def drive(force: ArrayLike, dt: float, substeps: int) -> Drive:
    """The force ``force`` (n, 2) N sampled every ``dt`` s as a :class:`Drive`: a cubic spline
    through the samples (linear interpolation of a 200 Hz force leaves 0.2 N in the tensions)."""
    u = np.asarray(force, float)
    fine = CubicSpline(np.arange(len(u)), u, axis=0)(np.linspace(0, len(u) - 1, (len(u) - 1) * 2 * substeps + 1))
    return Drive(np.ascontiguousarray(fine, dtype=float), float(dt), int(substeps))


def _arguments(p: RigParameters, y0: ArrayLike, d: Drive) -> tuple[Any, ...]:
    J = to_tensor(p.inertia)
    has_inc = p.inclinometer_rotation is not None
    Rinc = p.inclinometer_rotation if has_inc else np.eye(3)
    return (np.asarray(y0, float), d.fine, d.dt, d.substeps,
            np.ascontiguousarray(p.ceiling), np.ascontiguousarray(p.body - p.cg), p.length.astype(float),
            p.stiffness.astype(float), (p.damping_time * p.stiffness).astype(float), p.gain.astype(float),
            float(p.mass), J, np.linalg.inv(J), float(p.gravity), np.ascontiguousarray(p.exciter_rotation[:, :2]),
            p.exciter_position - p.cg,
            np.concatenate([p.body_damping, p.air_drag, p.rotor[:1], [p.pivot_friction]]).astype(float),
            np.ascontiguousarray(p.imu_rotation), p.imu_position - p.cg,
            np.ascontiguousarray(Rinc), has_inc)


def with_sensor_traits(out: np.ndarray, p: RigParameters, t0: float, dt: float) -> np.ndarray:
    """The readings ``out`` (n, n_out) of :func:`simulate` over samples ``dt`` s apart, the first
    ``t0`` s after the fit's start, with the sensor traits of ``p`` applied: the load cells' delay
    (their columns read at t − delay, a cubic spline through the segment's samples, extrapolated
    at its start), each gyro axis's scale (1 + s) and its bias drift (rate × t).  ``out`` itself
    where ``p`` has none."""
    n_c = p.cables
    delayed = p.load_cell_delay != 0.0
    if not (delayed or np.any(p.gyro_scale) or np.any(p.gyro_drift)):
        return out
    out = out.copy()
    t = np.arange(len(out)) * dt
    if delayed:
        out[:, :n_c] = CubicSpline(t, out[:, :n_c], axis=0, extrapolate=True)(t - p.load_cell_delay)
    out[:, n_c:n_c + 3] = out[:, n_c:n_c + 3] * (1.0 + p.gyro_scale) + np.outer(t0 + t, p.gyro_drift)
    return out


def exciter_readings(out: np.ndarray, force: np.ndarray, p: RigParameters, dt: float) -> np.ndarray:
    """(n, 2) N what the exciter's two load cells read (exciter frame) while the model runs under
    ``force`` (n, 2) N, its readings ``out`` (n, n_out) of :func:`simulate` (before
    :func:`with_sensor_traits`) on samples ``dt`` s apart: the force on the body, less the
    rotor's own inertial force where ``p`` gives the rotor a mass.  The load cells hold the
    rotor's bearing, so they read F − m_r f_e (Newton's second law on the rotor: the bearing
    carries its weight and accelerates it with the body), f_e the specific force at the exciter
    (body axes: the accelerometer's, moved by ω̇ × d + ω × (ω × d), d the IMU-to-exciter arm, ω̇
    the gyro's central differences), the x and y of the exciter frame; and the unbalanced mass's
    inertial force from the body's rotation (:func:`~.rigid_body.bearing_inertial_force`, as in the
    model's equations; Ω the force's rotation rate, :func:`spin_rate`).  ``force`` itself
    without a rotor."""
    m_r, unbalance = float(p.rotor[1]), float(p.rotor[0])
    if m_r == 0.0 and unbalance == 0.0:
        return force
    n_c = p.cables
    w = out[:, n_c:n_c + 3] @ p.imu_rotation.T                     # body axes
    dw = np.gradient(w, dt, axis=0, edge_order=2)
    Re = p.exciter_rotation
    readings: np.ndarray = np.asarray(force, float).copy()
    if m_r != 0.0:
        f_imu = out[:, n_c + 3:n_c + 6] @ p.imu_rotation.T
        d = p.exciter_position - p.imu_position
        f_e = f_imu + np.cross(dw, d) + np.cross(w, np.cross(w, d))
        readings -= m_r * (f_e @ Re)[:, :2]
    if unbalance != 0.0:
        size = np.linalg.norm(force, axis=1, keepdims=True)
        u = np.divide(force, size, out=np.zeros_like(readings), where=size > 0) @ Re[:, :2].T     # û, body axes
        inertial = bearing_inertial_force(unbalance, u, Re[:, 2], spin_rate(force, dt), w, dw)
        readings += (inertial @ Re)[:, :2]
    return readings


def spin_rate(force: ArrayLike, dt: float) -> np.ndarray:
    """(n,) rad/s the rotation rate of the exciter force ``force`` (n, 2) N (exciter frame, samples
    ``dt`` s apart) about the exciter's z axis: the angle between the samples :data:`SPIN_REACH`
    either side (clipped at the ends) over their time apart, as the compiled model takes it."""
    f = np.asarray(force, float)
    n = len(f)
    i = np.arange(n)
    a, b = np.maximum(i - SPIN_REACH, 0), np.minimum(i + SPIN_REACH, n - 1)
    cross = f[a, 0] * f[b, 1] - f[a, 1] * f[b, 0]
    dot = f[a, 0] * f[b, 0] + f[a, 1] * f[b, 1]
    span = np.maximum(b - a, 1) * dt
    rate: np.ndarray = np.where(b > a, np.arctan2(cross, dot) / span, 0.0)
    return rate


def simulate(p: RigParameters, y0: np.ndarray, force: Drive) -> tuple[np.ndarray, np.ndarray]:
    """Every sensor's reading (n, n_out) on the grid (module docstring) from the state ``y0``
    (13,) (:func:`rest_state`, :func:`moved_state`) under the exciter force ``force``
    (:func:`drive`: n grid samples).  Returns the readings and the state (13,) at the last sample."""
    out, states = _simulate(*_arguments(p, y0, force))
    return out, states[-1]


def trajectory(p: RigParameters, y0: np.ndarray, force: Drive) -> tuple[np.ndarray, np.ndarray]:
    """As :func:`simulate`, with the state at every grid sample: the readings (n, n_out) and the
    states (n, 13) = [p_cg world m, quaternion wxyz body → world, v_cg world m/s, ω body rad/s]."""
    out, states = _simulate(*_arguments(p, y0, force))
    return out, states
