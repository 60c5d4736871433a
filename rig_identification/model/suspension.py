"""The ``compliant_body`` effect of the simulator (:mod:`~rig_identification.model.effects`): the
body split into a sprung body and the rest (:func:`split_body`, which together are the body
at rest), joined by a linear 6-DOF spring–damper (:class:`Suspension`) that conserves
momentum, angular momentum and, without damping, energy exactly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from ..io.rig import inertia_entries
from .effects import DEFAULT_LOCK_DAMPING_RATIO, DEFAULT_LOCK_FREQUENCY, Effect
from .parametrisation import parted

SPRUNG_RAISE = 0.2                 # m: compliant_body's default sprung-CG height above the CG (at most half
                                   # the largest raise the body's mass distribution allows, see split_body)


# --- compliant body: the sprung body and its suspension ----------------------------------

@dataclass(frozen=True)
class RigidPart:
    """One rigid body: ``mass`` kg, ``cg`` (3,) body frame m, ``inertia`` (3, 3) kg m² about
    its own CG in body axes (entries as ``inertia_about_cg``)."""

    mass: float
    cg: np.ndarray
    inertia: np.ndarray


def _second_moment(J: np.ndarray) -> np.ndarray:
    """S = ∫ r rᵀ dm (3, 3) of an inertia tensor J = tr(S) I − S (about the same point)."""
    S: np.ndarray = 0.5 * np.trace(J) * np.eye(3) - J
    return S


def split_body(mass: float, cg: ArrayLike, inertia: ArrayLike, effect: Effect,
               where: str = "compliant_body") -> tuple[RigidPart, RigidPart]:
    """compliant_body: split a body (mass kg, cg (3,) body frame m, inertia (3, 3) about the
    CG) into the sprung body and the rest, which together are the body at rest.

    Sprung mass m_s = mass_share · m at ``sprung_cg`` (default: the CG raised by
    min(:data:`SPRUNG_RAISE`, h_max / 2), h_max the largest raise that leaves a physical rest,
    below); the rest m_u = m − m_s sits at c_u = c − (m_s/m_u)(c_s − c), keeping the CG.  With
    S = tr(J)/2 I − J the body's second moment about its CG, the two CG offsets take
    m (m_s/m_u) d dᵀ (d = c_s − c) from it; the remaining spread S_r is shared:
    S_s = σ S_r, S_u = (1 − σ) S_r (σ = ``sprung_inertia_share``, default mass_share: each
    part as spread out per kg as the other), and J_part = tr(S_part) I − S_part.  Both tensors
    are then positive semi-definite and satisfy the triangle inequalities exactly when S_r is
    positive semi-definite; h_max² = (m_u/m_s) / (m (S⁻¹)_zz).

    Returns (sprung, rest) :class:`RigidPart`.  Raises ValueError naming ``where``.sprung_cg
    when the sprung CG is too far from the CG for the body's mass distribution.
    """
    cg, J = np.asarray(cg, float), np.asarray(inertia, float)
    share = float(effect.get("mass_share"))
    m_s = share * mass
    ratio = share / (1.0 - share)                   # m_s / m_u
    S = _second_moment(J)
    if "sprung_cg" in effect.parameters:
        c_s = np.asarray(effect.parameters["sprung_cg"], float)
    else:
        s_zz = np.linalg.solve(S, [0.0, 0.0, 1.0])[2] if np.linalg.eigvalsh(S)[0] > 0 else np.inf
        h_max = math.sqrt(1.0 / (mass * ratio * s_zz)) if s_zz > 0 else 0.0
        c_s = cg + np.array([0.0, 0.0, min(SPRUNG_RAISE, 0.5 * h_max)])
    d = c_s - cg
    S_rest = S - mass * ratio * np.outer(d, d)
    low = np.linalg.eigvalsh(S_rest)[0]
    if low < -1e-9 * np.trace(S):
        h = math.sqrt(1.0 / (mass * ratio * (d / np.linalg.norm(d)) @ np.linalg.solve(S, d / np.linalg.norm(d))))
        raise ValueError(f"{where}.sprung_cg: {np.round(c_s, 4).tolist()} m is {np.linalg.norm(d):.3f} m from the CG "
                         f"{np.round(cg, 4).tolist()}; with mass_share {share} the body's mass distribution (its "
                         f"inertia_about_cg) allows at most {h:.3f} m in that direction (the rest's inertia tensor "
                         "would not be physical)")
    sigma = float(effect.get("sprung_inertia_share", share))

    def tensor(S_part: np.ndarray) -> np.ndarray:
        J_part: np.ndarray = np.trace(S_part) * np.eye(3) - S_part
        return J_part

    sprung = RigidPart(m_s, c_s, tensor(sigma * S_rest))
    rest = RigidPart(mass - m_s, cg - ratio * d, tensor((1.0 - sigma) * S_rest))
    for part, name in ((sprung, "sprung body"), (rest, "rest of the body")):
        if np.linalg.eigvalsh(part.inertia)[0] <= 0:
            raise ValueError(f"{where}.sprung_cg: the {name}'s inertia tensor is singular (all its mass on a line)")
    return sprung, rest


def without(mass: float, cg: np.ndarray, J: np.ndarray, part: RigidPart) -> RigidPart:
    """The rigid body (mass kg, cg (3,) m, J (3, 3) about cg) less ``part``
    (:func:`~rig_identification.model.parametrisation.parted`)."""
    return RigidPart(*parted(mass, cg, J, part.mass, part.cg, part.inertia))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two (3,) vectors (np.cross is slow on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class Suspension:
    """compliant_body: the sprung body (6 DOF) on a linear 6-DOF spring–damper to the frame.

    The joint acts at the sprung body's CG, in the frame's axes.  Relative displacement
    δ = R_fᵀ(p_s − p_f) − a (frame axes, m; a = nominal sprung CG − frame CG, body frame) and
    relative attitude R_rel = R_fᵀ R_s (identity at the nominal pose).  Force on the sprung
    body (frame axes) f = f_pre − K_t δ − C_t dδ/dt, moment on it (its own axes)
    τ = −vee(G R_rel − R_relᵀ G) − R_relᵀ C_r ω_rel with G = tr(K_r)/2 I − K_r, which is the
    exact moment of the potential tr(G (I − R_rel)) ≈ ½ θᵀ K_r θ (θ: rotation vector), and
    ω_rel = R_rel ω_s − ω_f (frame axes); the frame gets −f at the sprung CG and −R_rel τ.  So
    the joint conserves momentum, angular momentum and (without damping) energy exactly.

    Stiffness (Hz -> N/m, N·m/rad): roll, pitch k = J_s,xx|yy (2π f)², heave k = m_s (2π f)²,
    x, y k = m_s (2π f_lock)², yaw k = J_s,zz (2π f_lock)²; damping c = 2 ζ sqrt(k · m or J).
    f_pre = m_s g R_eqᵀ e_z (frame axes, N) is the springs' pre-load: it holds the sprung body
    at its nominal pose in the frame at the static equilibrium attitude R_eq, so that the whole
    body at rest has the experiment's mass, CG and inertia.

    Sprung state (18,) = [p_s world m, R_s sprung->world row-major, v_s world m/s, ω_s sprung
    axes rad/s]; at the nominal pose the sprung axes are the body axes.
    """

    def __init__(self, sprung: RigidPart, frame_cg: np.ndarray, effect: Effect, gravity: float, R_eq: np.ndarray):
        self.m, self.J = sprung.mass, sprung.inertia
        self.Jinv = np.linalg.inv(self.J)
        self.a = sprung.cg - np.asarray(frame_cg, float)
        f_roll, f_pitch, f_heave = effect.get("frequencies")
        f_lock = effect.get("lock_frequency", DEFAULT_LOCK_FREQUENCY)
        z_lock = effect.get("lock_damping_ratio", DEFAULT_LOCK_DAMPING_RATIO)
        z_roll, z_pitch, z_heave = np.broadcast_to(effect.get("damping_ratio"), (3,))
        Jd = np.diag(self.J)
        self.k_t = self.m * (2 * math.pi * np.array([f_lock, f_lock, f_heave])) ** 2
        self.k_r = Jd * (2 * math.pi * np.array([f_roll, f_pitch, f_lock])) ** 2
        self.c_t = 2 * np.array([z_lock, z_lock, z_heave]) * np.sqrt(self.k_t * self.m)
        self.c_r = 2 * np.array([z_roll, z_pitch, z_lock]) * np.sqrt(self.k_r * Jd)
        self.G = 0.5 * self.k_r.sum() * np.eye(3) - np.diag(self.k_r)
        self.g = np.array([0.0, 0.0, -gravity])
        self.preload = self.m * gravity * np.asarray(R_eq).T[:, 2]
        # plain floats for :meth:`coupling`
        self._kt, self._ct, self._a, self._pre = (tuple(x.tolist()) for x in (self.k_t, self.c_t, self.a, self.preload))
        self._g, self._cr = tuple(np.diag(self.G).tolist()), tuple(self.c_r.tolist())
        self._J, self._Jinv, self._gravity = self.J.tolist(), self.Jinv.tolist(), float(gravity)

    def coupling(self, y: np.ndarray, p: np.ndarray, R: np.ndarray, v: np.ndarray,
                 w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint forces of state y (36,) (the frame's p_cg, R, v_cg, ω are y[:18]).

        Returns (force on the frame (3,) world N, moment on the frame about its CG (3,) body
        axes N·m, derivative of the sprung state (18,)).  The class docstring's formulas,
        written out in scalars (G, K, C diagonal): numpy's per-call cost on 3-vectors would
        double the right-hand side's time.
        """
        (px, py, pz, a00, a01, a02, a10, a11, a12, a20, a21, a22, vx, vy, vz, wx, wy, wz,
         sx, sy, sz, b00, b01, b02, b10, b11, b12, b20, b21, b22, ux, uy, uz, ox, oy, oz) = y.tolist()
        (kx, ky, kz), (cx, cy, cz), (nx, ny, nz), (fx0, fy0, fz0) = self._kt, self._ct, self._a, self._pre
        (g0, g1, g2), (dx, dy, dz) = self._g, self._cr
        # q = Rᵀ(p_s − p) and dδ/dt = Rᵀ(v_s − v) − ω × q, frame axes
        ex, ey, ez = sx - px, sy - py, sz - pz
        qx, qy, qz = a00 * ex + a10 * ey + a20 * ez, a01 * ex + a11 * ey + a21 * ez, a02 * ex + a12 * ey + a22 * ez
        ex, ey, ez = ux - vx, uy - vy, uz - vz
        rx = a00 * ex + a10 * ey + a20 * ez - (wy * qz - wz * qy)
        ry = a01 * ex + a11 * ey + a21 * ez - (wz * qx - wx * qz)
        rz = a02 * ex + a12 * ey + a22 * ez - (wx * qy - wy * qx)
        fx = fx0 - kx * (qx - nx) - cx * rx               # force on the sprung body, frame axes
        fy = fy0 - ky * (qy - ny) - cy * ry
        fz = fz0 - kz * (qz - nz) - cz * rz
        # R_rel = Rᵀ R_s; ω_rel = R_rel ω_s − ω; τ = −vee(G R_rel − R_relᵀ G) − R_relᵀ C_r ω_rel
        c00, c01, c02 = (a00 * b00 + a10 * b10 + a20 * b20, a00 * b01 + a10 * b11 + a20 * b21,
                         a00 * b02 + a10 * b12 + a20 * b22)
        c10, c11, c12 = (a01 * b00 + a11 * b10 + a21 * b20, a01 * b01 + a11 * b11 + a21 * b21,
                         a01 * b02 + a11 * b12 + a21 * b22)
        c20, c21, c22 = (a02 * b00 + a12 * b10 + a22 * b20, a02 * b01 + a12 * b11 + a22 * b21,
                         a02 * b02 + a12 * b12 + a22 * b22)
        mx = dx * (c00 * ox + c01 * oy + c02 * oz - wx)
        my = dy * (c10 * ox + c11 * oy + c12 * oz - wy)
        mz = dz * (c20 * ox + c21 * oy + c22 * oz - wz)
        tx = g1 * c12 - g2 * c21 - (c00 * mx + c10 * my + c20 * mz)      # on the sprung body, its axes
        ty = g2 * c20 - g0 * c02 - (c01 * mx + c11 * my + c21 * mz)
        tz = g0 * c01 - g1 * c10 - (c02 * mx + c12 * my + c22 * mz)
        Fx, Fy, Fz = a00 * fx + a01 * fy + a02 * fz, a10 * fx + a11 * fy + a12 * fz, a20 * fx + a21 * fy + a22 * fz
        Tx, Ty, Tz = c00 * tx + c01 * ty + c02 * tz, c10 * tx + c11 * ty + c12 * tz, c20 * tx + c21 * ty + c22 * tz
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._J
        hx, hy, hz = j00 * ox + j01 * oy + j02 * oz, j10 * ox + j11 * oy + j12 * oz, j20 * ox + j21 * oy + j22 * oz
        tx, ty, tz = tx - (oy * hz - oz * hy), ty - (oz * hx - ox * hz), tz - (ox * hy - oy * hx)
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._Jinv
        im = 1.0 / self.m
        dys = np.array([ux, uy, uz,
                        b01 * oz - b02 * oy, b02 * ox - b00 * oz, b00 * oy - b01 * ox,       # R_s skew(ω_s)
                        b11 * oz - b12 * oy, b12 * ox - b10 * oz, b10 * oy - b11 * ox,
                        b21 * oz - b22 * oy, b22 * ox - b20 * oz, b20 * oy - b21 * ox,
                        Fx * im, Fy * im, Fz * im - self._gravity,
                        i00 * tx + i01 * ty + i02 * tz, i10 * tx + i11 * ty + i12 * tz, i20 * tx + i21 * ty + i22 * tz])
        return (np.array([-Fx, -Fy, -Fz]),
                np.array([qz * fy - qy * fz - Tx, qx * fz - qz * fx - Ty, qy * fx - qx * fy - Tz]), dys)

    def relative(self, Y: np.ndarray) -> np.ndarray:
        """(K, 6) of states Y (K, 36): δ (frame axes, m) and the rotation vector of R_rel
        (frame axes, rad) of the sprung body from its nominal pose in the frame."""
        R = Y[:, 3:12].reshape(-1, 3, 3)
        delta = np.einsum("kji,kj->ki", R, Y[:, 18:21] - Y[:, 0:3]) - self.a
        R_rel = np.einsum("kji,kjl->kil", R, Y[:, 21:30].reshape(-1, 3, 3))
        return np.hstack([delta, Rotation.from_matrix(R_rel).as_rotvec()])

    def energy(self, Y: np.ndarray) -> np.ndarray:
        """(K,) J: the sprung body's kinetic and gravity energy plus the joint's potential
        ½ δᵀK_tδ − f_pre·δ + tr(G (I − R_rel)) at states Y (K, 36) (for tests)."""
        rel = Y[:, 18:21] - Y[:, 0:3]
        R = Y[:, 3:12].reshape(-1, 3, 3)
        delta = np.einsum("kji,kj->ki", R, rel) - self.a
        R_rel = np.einsum("kji,kjl->kil", R, Y[:, 21:30].reshape(-1, 3, 3))
        ws = Y[:, 33:36]
        kinetic = 0.5 * self.m * (Y[:, 30:33] ** 2).sum(1) + 0.5 * np.einsum("ki,ij,kj->k", ws, self.J, ws)
        spring = (0.5 * (self.k_t * delta ** 2).sum(1) - delta @ self.preload
                  + np.trace(self.G) - np.einsum("ij,kji->k", self.G, R_rel))
        total: np.ndarray = kinetic - self.m * (Y[:, 18:21] @ self.g) + spring
        return total

    def state_from_whole(self, y: np.ndarray, cg: np.ndarray, frame_cg: np.ndarray) -> np.ndarray:
        """(36,) state of frame and sprung body from a whole-body rigid state y (18,) (CG
        ``cg``, body frame): both move with the whole body, the sprung body at its nominal pose."""
        p, R, v, w = y[0:3], y[3:12].reshape(3, 3), y[12:15], y[15:18]
        out = np.empty(36)
        for k, c in ((0, frame_cg), (18, frame_cg + self.a)):
            r = R @ (c - cg)
            out[k:k + 3], out[k + 3:k + 12] = p + r, y[3:12]
            out[k + 12:k + 15], out[k + 15:k + 18] = v + _cross(R @ w, r), w
        return out

    def describe(self, frame: RigidPart, sprung: RigidPart) -> dict[str, Any]:
        """truth.yaml's simulator.compliant_body: the two bodies and the joint (SI)."""
        return {"sprung_mass": float(sprung.mass), "sprung_cg": sprung.cg.tolist(),
                "sprung_inertia_about_cg": inertia_entries(sprung.inertia),
                "frame_mass": float(frame.mass), "frame_cg": frame.cg.tolist(),
                "frame_inertia_about_cg": inertia_entries(frame.inertia),
                "stiffness_translation": self.k_t.tolist(), "stiffness_rotation": self.k_r.tolist(),
                "damping_translation": self.c_t.tolist(), "damping_rotation": self.c_r.tolist(),
                "preload": self.preload.tolist(),
                "joint": "6-DOF linear spring-damper at the sprung CG, frame axes: translation x y z, rotation "
                         "roll pitch yaw; the frame (rest of the body + dummy/cable masses) carries the sensors"}
