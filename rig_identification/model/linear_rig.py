"""The rig about its rest pose: the elastic equilibrium and the linearised equations of motion.

The rigid body (mass, centre of gravity, inertia tensor) hangs on N elastic cables (per-cable
stiffness k_i, a common damping time τ: tension k_i (l_i - L_i) + τ k_i dl_i/dt).
:func:`rest_pose` solves its static equilibrium (thesis eqs. 2.20–2.25 with springs);
:func:`linearise` gives the small motion about it (Newton–Euler linearised, thesis eqs.
3.1–3.10 with the cable forces resolved)::

    M q'' + D q' + K q = B u,      q = (δp, δφ)

with δp (3,) the displacement of the body-frame origin (world, m) and δφ (3,) the small
rotation (world, rad, R = exp([δφ]×) R0); u (2,) the exciter force in its frame (N).

* M = [[m I, -m [c]×], [m [c]×, I_o]] (c = R0 c_body; I_o the tensor about the origin by the
  parallel-axis theorem, in world axes).
* K = Σ_i G_i (k_i u_i u_iᵀ + T_i/l_i (I - u_i u_iᵀ)) G_iᵀ
  - blockdiag(0, Σ_i [T_i u_i]× [s_i]× + [m g]× [c]×), G_i = [I; [s_i]×], s_i = R0 b_i:
  the cables' axial and geometric stiffness and the moment arms turning under the forces.
* D = Σ_i τ k_i G_i u_i u_iᵀ G_iᵀ + c_lin G_c G_cᵀ + blockdiag(0, c_ang I), G_c = [I; [c]×]
  (the body's viscous damping on the CG's velocity and the angular velocity);
  B = [I; [s_e]×] R0 R_e[:, :2] (the exciter's force): :func:`frequency_response` gives the
  steady response to it at one frequency (the start of the exact model's fit).

Its natural frequencies set the step of the exact model's integrator
(:mod:`~rig_identification.model.rig_ode`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from ..io.rig import Cable, Mount, Rig
from .cables import CableModel
from .equilibrium import equilibrium
from .parametrisation import to_tensor
from .rigid_body import SimulationError, skew, skews

#: Newton iterations of :func:`rest_pose` from a nearby pose, and its tolerance on the net
#: wrench relative to the weight (N / N).
REST_ITERATIONS = 30
REST_TOLERANCE = 1e-12


@dataclass(frozen=True)
class RigParameters:
    """Every parameter of the linearised rig (SI units, frames of docs/recording_format.md).

    mass: kg.  cg: (3,) body frame, m.  inertia: (6,) tensor entries about the CG in body axes,
    kg·m², :data:`~rig_identification.io.verdict.KEYS` order (off-diagonals = -products).
    ceiling: (N, 3) world m.  body: (N, 3) body frame m.  length: (N,) unstretched m.
    stiffness: (N,) N/m.  damping_time: τ, s (cable damping τ k_i).  gain: (N,) load-cell gains.
    body_damping: (2,) the body's viscous damping: linear N·s/m on the CG's velocity, angular
    N·m·s on the angular velocity (air, joints; the ``viscous_damping`` effect).
    air_drag: (2,) quadratic damping: linear N·s²/m² (force −c |v| v on the CG), angular
    N·m·s²/rad² (moment −c |ω| ω).  pivot_friction: m, μ r of the ceiling anchors' pins (friction
    coefficient times pin radius): each pin resists its cable's swing with the Coulomb moment
    μ r T, a force μ r T / l across the cable at its body anchor against the anchor's velocity
    across it (regularised, :data:`~rig_identification.model.rig_ode.PIVOT_SPEED`).  These two
    leave the linearised equations (zero slope at rest, or none) and act in the exact model
    (:mod:`~rig_identification.model.rig_ode`).  rotor: (2,) the exciter's
    rotor (exact model only): its unbalance, kg·m (the unbalanced mass times its eccentricity:
    its weight's moment about the CG turns with the force's direction), and its mass, kg (carried
    on the exciter's bearing: the exciter's load cells read the bearing's force, the rotor's own
    inertial force −m a among it, :func:`~rig_identification.model.rig_ode.exciter_readings`).
    mass, cg and inertia are then the suspended body's, the rotor's mass on its axis included.
    load_cell_delay: s, the load cells' readings lag the IMU's by this; exciter_delay: s, the
    exciter force's readings lag the IMU's by this (the force that moves the body at t is the
    one read at t + delay).  gyro_scale: (3,) each
    gyro axis reads (1 + s) times the rate (IMU axes).  gyro_drift: (3,) rad/s² each gyro
    axis's bias grows at this rate (IMU axes).  The last three are sensor traits: they shape
    the readings, not the motion (:func:`~rig_identification.model.rig_ode.with_sensor_traits`).
    gravity: m/s².  imu_position: (3,) body m; imu_rotation, exciter_rotation,
    inclinometer_rotation: (3, 3) sensor axes -> body axes (None: no inclinometer).
    exciter_position: (3,) body m.
    """

    mass: float
    cg: np.ndarray
    inertia: np.ndarray
    ceiling: np.ndarray
    body: np.ndarray
    length: np.ndarray
    stiffness: np.ndarray
    damping_time: float
    gain: np.ndarray
    gravity: float
    imu_position: np.ndarray
    imu_rotation: np.ndarray
    exciter_position: np.ndarray
    exciter_rotation: np.ndarray
    inclinometer_rotation: np.ndarray | None
    body_damping: np.ndarray = field(default_factory=lambda: np.zeros(2))
    air_drag: np.ndarray = field(default_factory=lambda: np.zeros(2))
    pivot_friction: float = 0.0
    load_cell_delay: float = 0.0
    gyro_scale: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_drift: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotor: np.ndarray = field(default_factory=lambda: np.zeros(2))
    exciter_delay: float = 0.0

    @property
    def cables(self) -> int:
        return len(self.length)

    @staticmethod
    def from_rig(rig: Rig, inertia: ArrayLike, stiffness: ArrayLike, damping_time: float, mass: float | None = None,
                 cg: ArrayLike | None = None) -> "RigParameters":
        """The parameters of ``rig`` (geometry, sensor mounts) with the given inertia entries (6,),
        cable stiffness (scalar or (N,), N/m) and damping time τ (s); mass and CG default to
        rig.yaml's.  Raises :class:`~rig_identification.io.rig.RigError` when the CG is needed and
        rig.yaml has none, ValueError without an exciter."""
        if rig.exciter is None:
            raise ValueError(f"{rig.source}: no exciter in rig.yaml: the rig model is driven by the exciter's force")
        n = len(rig.cables)
        return RigParameters(
            mass=float(rig.mass if mass is None else mass),
            cg=np.asarray(rig.require_cg() if cg is None else cg, float),
            inertia=np.asarray(inertia, float), ceiling=rig.ceiling_anchors, body=rig.body_anchors,
            length=rig.cable_lengths, stiffness=np.broadcast_to(np.asarray(stiffness, float), (n,)).copy(),
            damping_time=float(damping_time), gain=np.ones(n), gravity=rig.gravity,
            imu_position=np.asarray(rig.imu.position, float), imu_rotation=rig.imu.rotation.as_matrix(),
            exciter_position=np.asarray(rig.exciter.position, float),
            exciter_rotation=rig.exciter.rotation.as_matrix(),
            inclinometer_rotation=None if rig.inclinometer is None else rig.inclinometer.rotation.as_matrix())

    def replace(self, **changes: Any) -> "RigParameters":
        return replace(self, **changes)


@dataclass(frozen=True)
class RestPose:
    """The body at rest: ``position`` (3,) world m of the body-frame origin, ``rotation`` (3, 3)
    body -> world, ``tensions`` (N,) N."""

    position: np.ndarray
    rotation: np.ndarray
    tensions: np.ndarray


@dataclass(frozen=True)
class LinearRig:
    """The rig linearised about its :class:`RestPose`: M, D, K (6, 6) of the module docstring;
    G (N, 6) the cables' length sensitivities, δl = -G q (rows [u_i, s_i × u_i])."""

    M: np.ndarray
    D: np.ndarray
    K: np.ndarray
    rest: RestPose
    G: np.ndarray


def _cable_geometry(p: RigParameters, position: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    s = p.body @ R.T                           # anchor offsets from the origin, world
    d = p.ceiling - (position + s)
    length = np.linalg.norm(d, axis=1)
    return s, d / length[:, None], length


def net_wrench(p: RigParameters, position: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The net force (3,) N and moment (3,) N·m about the body origin (world) of the cables
    (static tensions k_i (l_i - L_i)) and gravity at a pose (origin ``position`` (3,) world m,
    ``R`` (3, 3) body -> world): (6,), and the tensions (N,) N."""
    s, u, length = _cable_geometry(p, position, R)
    T = p.stiffness * (length - p.length)
    f = T[:, None] * u
    weight = np.array([0.0, 0.0, -p.mass * p.gravity])
    c = R @ p.cg
    return np.concatenate([f.sum(0) + weight, np.cross(s, f).sum(0) + np.cross(c, weight)]), T


def stiffness_matrix(p: RigParameters, position: np.ndarray, R: np.ndarray, axial: bool = True) -> np.ndarray:
    """K (6, 6) of the module docstring at a pose (the negated Jacobian of the net wrench about
    the origin with respect to q = (δp, δφ)).  ``axial=False``: without the cables' axial
    stiffness k_i u_i u_iᵀ (the part a measured tension already holds), the tensions as at the pose."""
    s, u, length = _cable_geometry(p, position, R)
    T = p.stiffness * (length - p.length)
    uu = u[:, :, None] * u[:, None, :]
    Ka = (T / length)[:, None, None] * (np.eye(3) - uu)
    if axial:
        Ka = Ka + p.stiffness[:, None, None] * uu
    S = skews(s)
    G = np.concatenate([np.broadcast_to(np.eye(3), S.shape), S], axis=1)        # (N, 6, 3)
    K: np.ndarray = np.einsum("nij,njk,nlk->il", G, Ka, G)
    F = skews(T[:, None] * u)
    geo = np.einsum("nij,njk->ik", F, S) + skew([0.0, 0.0, -p.mass * p.gravity]) @ skew(R @ p.cg)
    K[3:, 3:] -= geo
    return K


def rest_pose(p: RigParameters, near: RestPose | None = None, taut: bool = True) -> RestPose:
    """The static equilibrium of the elastic rig (thesis eqs. 2.20–2.25 with springs): Newton on
    the net wrench from ``near`` (a nearby rest pose), else from
    :func:`~rig_identification.model.equilibrium.equilibrium`.  ``taut=False``: the linear
    springs' equilibrium even where a cable would push (a negative tension: a pose to start
    from, not a rig).  Raises :class:`~rig_identification.model.rigid_body.SimulationError` (no
    equilibrium; a slack cable unless ``taut`` is False)."""
    if near is None:
        rig = _as_rig(p)
        eq = equilibrium(rig, p.mass, p.cg, CableModel("spring", p.stiffness, np.zeros(p.cables)))
        position, R = np.asarray(eq.position, float), eq.rotation.as_matrix()
    else:
        position, R = near.position.copy(), near.rotation.copy()
    weight = p.mass * p.gravity
    for _ in range(REST_ITERATIONS):
        W, T = net_wrench(p, position, R)
        if np.max(np.abs(W)) < REST_TOLERANCE * weight:
            break
        step = np.linalg.solve(stiffness_matrix(p, position, R), W)
        position = position + step[:3]
        R = Rotation.from_rotvec(step[3:]).as_matrix() @ R
    else:
        raise SimulationError("the elastic rig has no rest pose near the one given (Newton did not converge)")
    if taut and T.min() <= 0:
        raise SimulationError(f"cable {int(np.argmin(T))} is slack at rest (tension {T.min():.1f} N)")
    return RestPose(position, R, T)


def _as_rig(p: RigParameters) -> Rig:
    cables = tuple(Cable(f"c{i}", p.ceiling[i], p.body[i], float(p.length[i]), float(p.stiffness[i]))
                   for i in range(p.cables))
    return Rig(p.gravity, cables, p.mass, p.cg, Mount(p.imu_position, np.zeros(3)))


def mass_matrix(p: RigParameters, rest: RestPose) -> np.ndarray:
    """M (6, 6) of the module docstring: the rigid body's mass matrix about the body origin at
    ``rest``, world axes (the only part of :func:`linearise` that depends on the tensor)."""
    R0 = rest.rotation
    c = R0 @ p.cg
    Jcg = R0 @ to_tensor(p.inertia) @ R0.T
    Io = Jcg + p.mass * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
    M: np.ndarray = np.block([[p.mass * np.eye(3), -p.mass * skew(c)], [p.mass * skew(c), Io]])
    return M


def linearise(p: RigParameters, rest: RestPose) -> LinearRig:
    """The :class:`LinearRig` of ``p`` about ``rest`` (module docstring)."""
    R0 = rest.rotation
    s, u, _ = _cable_geometry(p, rest.position, R0)
    Gu = np.hstack([u, np.cross(s, u)])                                       # (N, 6): -∂l_i/∂q
    c = R0 @ p.cg
    M = mass_matrix(p, rest)
    K = stiffness_matrix(p, rest.position, R0)
    Gc = np.vstack([np.eye(3), skew(c)])                                      # CG velocity -> generalized force
    D = p.damping_time * np.einsum("n,ni,nj->ij", p.stiffness, Gu, Gu) + p.body_damping[0] * Gc @ Gc.T
    D[3:, 3:] += p.body_damping[1] * np.eye(3)
    return LinearRig(M, D, K, rest, Gu)


def frequency_response(p: RigParameters, lin: LinearRig, omega: float, force: np.ndarray) -> np.ndarray:
    """The steady response of the linearised rig to the exciter force ``force`` (2,) complex N
    (exciter frame; u(t) = Re(force e^{iωt})) at ``omega`` rad/s: the complex amplitudes of the
    load cells' readings (N,) N and the gyro's (3,) rad/s (IMU axes), concatenated (N + 3,).

    Q = (K − ω² M + iω D)⁻¹ B u (module docstring); a tension moves by -g_i k_i (1 + iωτ) G_i Q,
    the gyro reads R_imuᵀ R0ᵀ iω Q_φ.  Where ``p`` gives the exciter's rotor an unbalance m_u e
    (``p.rotor[0]``), its weight turns with the force and adds the moment m_u e (u × g), u the
    force's direction (:mod:`~rig_identification.model.rig_ode`): (m_u e / |F|) F × g, |F| the
    rotating force's amplitude.  The fundamental of the exact model's readings to first
    order in the motion (its quadratic terms fall at 0 and 2ω)."""
    R0 = lin.rest.rotation
    s_e = R0 @ p.exciter_position
    f_world = R0 @ p.exciter_rotation[:, :2] @ np.asarray(force, complex)
    B = np.concatenate([f_world, np.cross(s_e, f_world)])
    if p.rotor[0] > 0.0:        # the unbalance's weight, turning with the force (rig_ode: m_u e u × g)
        amplitude = np.sqrt(0.5 * np.sum(np.abs(force) ** 2))
        B[3:] += p.rotor[0] / amplitude * np.cross(f_world, np.array([0.0, 0.0, -p.gravity]))
    Q = np.linalg.solve(lin.K - omega ** 2 * lin.M + 1j * omega * lin.D, B)
    tensions = -p.gain * p.stiffness * (1 + 1j * omega * p.damping_time) * (lin.G @ Q)
    gyro = p.imu_rotation.T @ R0.T @ (1j * omega * Q[3:])
    out: np.ndarray = np.concatenate([tensions, gyro])
    return out


def natural_frequencies(lin: LinearRig) -> np.ndarray:
    """The undamped natural frequencies (6,) Hz of the linearised rig, ascending (the
    generalized eigenvalues of K and M)."""
    w2 = np.linalg.eigvals(np.linalg.solve(lin.M, lin.K)).real
    return np.sort(np.sqrt(np.maximum(w2, 0.0))) / (2 * np.pi)
