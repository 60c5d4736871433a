"""The rigid body on N cables as a dynamical system: forces, cable tensions and the state derivative.

The Newton–Euler equations (gyroscopic term included, unlike thesis eq. 3.10)::

    m a_cg = sum_i T_i u_i + m g + F_ext                      (world axes)
    J dω/dt + ω × (J ω) = sum_i r_i × T_i u_i + M_ext         (body axes, about the CG)
    dR/dt = R skew(ω),   dp_cg/dt = v_cg

:class:`RigDynamics` evaluates them for the two cable models (thesis eqs. 2.13–2.16 for the
inextensible one), the exciter's rotating force and the force pulses, the concealed effects
that act as forces (:mod:`~rig_identification.model.effects`: dissipation, the ceiling pins'
friction, the exciter's rotor)
and, with the ``compliant_body`` effect, the joint to the sprung body
(:mod:`~rig_identification.model.suspension`).

Frames and conventions
----------------------
* ``world``: z up, gravity (0, 0, -g), g = ``rig.gravity``.
* ``body``: origin = any reference point; the CG is at ``c`` (body frame).  The state is
  ``[p_cg (3), R row-major (9), v_cg (3), ω (3)]`` (with ``compliant_body``: the frame's,
  then the sprung body's): p_cg world m, R body -> world, v_cg world m/s, ω body rad/s.
* Cable i runs from the ceiling anchor A_i (world) to the body anchor b_i (body frame).
  Its tension T_i >= 0 pulls the body along u_i = (A_i - P_i)/|A_i - P_i|, P_i = p_cg + R (b_i - c).

Cable models (``cable_model``)
------------------------------
* ``spring``: T_i = max(0, k_i (l_i - L_i) + c_i dl_i/dt) (tension-only spring-damper, as
  the reference simulator).  Default k_i: the cable's ``stiffness`` in rig.yaml, else 5e6 N/m.
  Default damping c_i = 2 ζ sqrt(k_i m / N) with ζ = ``damping_ratio`` = 0.01, which is
  the reference simulator's value (e.g. 951.3 N·s/m for m = 1810 kg, N = 4, k = 5e6).
* ``inextensible``: holonomic constraints |A_i - P_i| = L_i (thesis eqs. 2.13–2.16).
  The tensions are the Lagrange multipliers, solved from the KKT system at every
  right-hand-side call, with Baumgarte stabilisation
  φ'' + 2β φ' + β² φ = 0, φ_i = (l_i² - L_i²)/2.  N > 6 is rejected (tensions statically
  indeterminate); a negative tension (a cable going slack) raises :class:`SimulationError`
  unless ``compression: true`` makes the cables rigid two-way links (negative "tension" =
  compression), like rigid links in a multibody model; the thesis's SimMechanics model
  presumably was one: its cases 7 and 8 need compression with inextensible cables.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.linalg.lapack import dposv
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .cables import CableModel
from .effects import Effect
from .equilibrium import HangingBody
from .excitation import Excitation
from .rigid_body import SimulationError, bearing_inertial_force, moment_sum, skew
from .suspension import Suspension


class CableKinematics(NamedTuple):
    """The cables at a state: ``d`` (N, 3) body anchor -> ceiling anchor, world m; ``l`` (N,) their
    lengths m; ``u`` (N, 3) the unit vectors along them; ``Pdot`` (N, 3) the body anchors'
    velocities, world m/s; ``ldot`` (N,) the lengths' rates m/s."""

    d: np.ndarray
    l: np.ndarray
    u: np.ndarray
    Pdot: np.ndarray
    ldot: np.ndarray


@dataclass(frozen=True)
class Evaluation:
    """What :meth:`RigDynamics.evaluate` finds at K states: ``R`` (K, 3, 3) orthonormalised body
    -> world, ``a`` (K, 3) CG acceleration world m/s², ``alpha`` (K, 3) dω/dt body rad/s², ``T``
    (K, N) cable tensions N, ``exciter`` (K, 2) N: the exciter's reading in its frame."""

    R: np.ndarray
    a: np.ndarray
    alpha: np.ndarray
    T: np.ndarray
    exciter: np.ndarray


class RigDynamics:
    """Forces, tensions and state derivative of the suspended rigid body.

    State y (18,) = [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s];
    with a :class:`~rig_identification.model.suspension.Suspension` (compliant_body) the body
    is the frame and y (36,) continues with the sprung body's state.  Raises
    :class:`SimulationError` (inextensible cables: more than 6, a singular constraint
    Jacobian).
    """

    def __init__(self, rig: Rig, mass: float, cg: np.ndarray, inertia: np.ndarray, cables: CableModel,
                 excitation: Excitation, effects: tuple[Effect, ...] = (), suspension: Suspension | None = None):
        self.hanging = HangingBody.of(rig, mass, cg, cables)
        self.m = self.hanging.m
        self.J = np.asarray(inertia, float)
        self.Jinv = np.linalg.inv(self.J)
        self.cg = np.asarray(cg, float)
        self.A = self.hanging.A
        self.r = self.hanging.r
        self.r_skew = np.array([skew(r) for r in self.r])      # (N, 3, 3): r_i × ·
        self.L = self.hanging.L
        self.g = self.hanging.g
        self.cables = cables
        self.excitation = excitation
        self.suspension = suspension
        self.size = 18 if suspension is None else 36
        ex = rig.exciter
        self.R_exc = ex.rotation.as_matrix() if ex is not None else np.eye(3)
        r_exc = ex.position - self.cg if ex is not None else np.zeros(3)
        self.M_exc = skew(r_exc) @ self.R_exc          # exciter-frame force -> moment about the CG
        self.r_exc = r_exc
        self._dissipative = [e for e in effects if e.name in ("viscous_damping", "air_drag")]
        pins = next((e for e in effects if e.name == "pivot_friction"), None)
        self._pins = None if pins is None else (float(pins.get("mu_r")), float(pins.get("velocity_scale", 1e-4)))
        self._rotor = next((e for e in effects if e.name == "exciter_rotor"), None)
        if self._rotor is not None:
            rot = excitation.rotating
            assert rot is not None   # the experiment refuses exciter_rotor without excitation.rotating
            self._unbalance = self._rotor.get("unbalance", rot.amplitude / (2 * math.pi * rot.frequency) ** 2)
            self._rotor_inertia = self._rotor.get("rotor_inertia", 0.0)

    @property
    def unbalance(self) -> float:
        """The exciter rotor's unbalance m_u e, kg·m (0 without the ``exciter_rotor`` effect)."""
        return float(self._unbalance) if self._rotor is not None else 0.0

    def effect_wrench(self, t: float, R: np.ndarray, v: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Force (3,) world N and moment (3,) body N·m about the CG of the concealed effects
        (:mod:`~rig_identification.model.effects`): dissipation and the exciter's rotor."""
        F, M = np.zeros(3), np.zeros(3)
        for e in self._dissipative:
            if e.name == "viscous_damping":
                F -= e.get("linear") * v
                M -= e.get("angular") * w
            else:
                F -= e.get("linear") * math.sqrt(v @ v) * v
                M -= e.get("angular") * math.sqrt(w @ w) * w
        if self._rotor is not None:
            assert self.excitation.rotating is not None   # as in __init__
            theta, speed, acc = self.excitation.rotating.angle_and_speed(t)
            z = self.R_exc[:, 2]
            u = self.R_exc @ np.array([math.cos(theta), math.sin(theta), 0.0])   # toward the unbalanced mass
            M += self._unbalance * np.cross(u, R.T @ self.g)                 # its weight, turning with it
            h = self._rotor_inertia * speed * z                                # spin angular momentum, body
            M -= np.cross(w, h) + self._rotor_inertia * acc * z
        return F, M

    def unbalance_inertia(self, t: float, R: np.ndarray, a: np.ndarray, alpha: np.ndarray, w: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray]:
        """The exciter's unbalanced mass's inertial wrench on the body: force (3,) world N and moment
        (3,) body N·m about the CG.  The moment of its inertial force on its arm, −m_u e û × a_e: the
        unbalance m_u e (kg·m) toward û (the force's direction, body), a_e the exciter axis's
        acceleration (body axes) for the CG's acceleration ``a`` (3,) world m/s² and the angular
        acceleration ``alpha`` (3,) and velocity ``w`` (3,) body; its weight's moment is
        :meth:`effect_wrench`'s, the two make m_u e û × (g − a_e), what the rotor, its speed held by
        the drive, passes to the body about its arm (the part about the spin axis through the
        drive).  And the mass's inertial force from the body's rotation, at the axis,
        f = −m_u e [α × û + ω × (ω × û) + 2 Ω ω × (ẑ × û)] (Ω the spin relative to the body about
        the exciter's z axis ẑ; the last the Coriolis term of the mass's velocity e Ω ẑ × û), with
        its moment r_e × f (:func:`~.rigid_body.bearing_inertial_force`; the exciter's load cells read it too)."""
        assert self._rotor is not None and self.excitation.rotating is not None
        theta, speed, _ = self.excitation.rotating.angle_and_speed(t)
        u = self.R_exc @ np.array([math.cos(theta), math.sin(theta), 0.0])
        a_e = R.T @ a + np.cross(alpha, self.r_exc) + np.cross(w, np.cross(w, self.r_exc))
        f = bearing_inertial_force(self._unbalance, u, self.R_exc[:, 2], speed, w, alpha)
        moment: np.ndarray = -self._unbalance * np.cross(u, a_e) + np.cross(self.r_exc, f)
        return R @ f, moment

    def pin_friction(self, T: np.ndarray, l: np.ndarray, u: np.ndarray, Pdot: np.ndarray) -> np.ndarray:
        """(N, 3) world N: the force of each ceiling pin's dry friction on the body anchor (the
        ``pivot_friction`` effect): the pin resists the cable's swing with the moment μ r T_i, which the
        straight cable passes on as μ r T_i / l_i across it, against the anchor's velocity across it
        (v⊥ = Ṗ_i − (Ṗ_i·u_i) u_i), regularised: −μ r T_i / l_i · v⊥ / sqrt(|v⊥|² + ε²).  T (N,) N,
        l (N,) m, u (N, 3) unit vectors toward the ceiling, Pdot (N, 3) m/s the anchors' velocities."""
        assert self._pins is not None
        mu_r, eps = self._pins
        across = Pdot - (u * Pdot).sum(axis=1)[:, None] * u
        speed = np.sqrt((across * across).sum(axis=1) + eps * eps)
        out: np.ndarray = -(mu_r * T / (l * speed))[:, None] * across
        return out

    def breakpoints(self) -> list[float]:
        """Times where the forcing is discontinuous (or has a kink), s."""
        out = [] if self.excitation.rotating is None else self.excitation.rotating.breakpoints()
        for p in self.excitation.pulses:
            out += [p.start, p.end]
        return out

    def external(self, t: float, R: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Forces of the exciter and the pulses at time t (s), attitude R (3, 3).

        Returns (F (3,) world N, M (3,) about the CG in body axes N m, measured (2,) N: x, y
        of the force at the exciter's load cells in the exciter frame).
        """
        if self.excitation.rotating is not None:
            f_exc = self.excitation.rotating.force(t)
            F_body = self.R_exc @ f_exc
            M = self.M_exc @ f_exc
            measured = f_exc.copy()
        else:
            F_body, M, measured = np.zeros(3), np.zeros(3), np.zeros(3)
        F_world = R @ F_body
        for p in self.excitation.pulses:
            if p.start <= t < p.end:
                if p.frame == "world":
                    F_world += p.force
                    f = R.T @ p.force
                else:
                    f = p.force
                    F_world += R @ f
                M += skew(p.point - self.cg) @ f
                if p.measured:
                    measured += self.R_exc.T @ f
        return F_world, M, measured[:2]

    def evaluate_one(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """State derivative (size,), cable tensions (N,) N and exciter reading (2,) N of state
        y (size,) at time t s: the Newton–Euler equations of the module docstring."""
        p, R, v, w = y[0:3], y[3:12].reshape(3, 3), y[12:15], y[15:18]
        F_ext, M_ext, exciter = self.external(t, R)
        if self._dissipative or self._rotor is not None:
            dF, dM = self.effect_wrench(t, R, v, w)
            F_ext, M_ext = F_ext + dF, M_ext + dM
        if self.suspension is not None:
            dF, dM, dy_sprung = self.suspension.coupling(y, p, R, v, w)
            F_ext, M_ext = F_ext + dF, M_ext + dM
        W = skew(w)
        Rdot = R @ W                                    # dR/dt = R skew(ω)
        s = self.r @ R.T                                # lever arms CG -> body anchors, world
        d = self.A - p - s                              # body anchor -> ceiling anchor
        l = np.sqrt((d * d).sum(axis=1))
        u = d / l[:, None]
        Pdot = v + self.r @ Rdot.T                      # body-anchor velocities, world
        ldot = -(u * Pdot).sum(axis=1)
        M_rest = M_ext - W @ (self.J @ w)               # external moment - ω × Jω, body
        if self.cables.type == "spring":
            T = np.maximum(self.cables.stiffness * (l - self.L) + self.cables.damping * ldot, 0.0)
            Tu = T[:, None] * u
            if self._pins is not None:
                Tu = Tu + self.pin_friction(T, l, u, Pdot)
            a = (Tu.sum(axis=0) + F_ext) / self.m + self.g
            alpha = self.Jinv @ (moment_sum(self.r, Tu @ R) + M_rest)
            if self._rotor is not None:        # one fixed-point pass: the moment is ~1 % of the weight's
                f, moment = self.unbalance_inertia(t, R, a, alpha, w)
                a, alpha = a + f / self.m, alpha + self.Jinv @ moment
        else:
            cab = CableKinematics(d, l, u, Pdot, ldot)
            a, alpha, T = self._constrained(R, Rdot, W, cab, F_ext, M_rest)
            if self._rotor is not None:
                f, moment = self.unbalance_inertia(t, R, a, alpha, w)
                a, alpha, T = self._constrained(R, Rdot, W, cab, F_ext + f, M_rest + moment)
        dy = np.empty(self.size)
        dy[0:3], dy[3:12], dy[12:15], dy[15:18] = v, Rdot.ravel(), a, alpha
        if self.suspension is not None:
            dy[18:] = dy_sprung
        return dy, T, exciter

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """The integrator's right-hand side: dy/dt (size,) of y (size,) at t."""
        return self.evaluate_one(t, y)[0]

    def _constrained(self, R: np.ndarray, Rdot: np.ndarray, W: np.ndarray, cab: CableKinematics, F_ext: np.ndarray,
                     M_rest: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """KKT solve for inextensible cables -> (a (3,), α (3,), T (N,)), the cables at the
        state ``cab``.

        Generalised accelerations q̈ = [a (world); α (body)] satisfy M q̈ = Q + B T with
        B_i = [u_i; r_i × Rᵀu_i] and, per cable, B_iᵀq̈ = (|Ṗ_i|² - d_i·(ω×(ω×s_i)) + 2β φ̇_i
        + β² φ_i) / l_i: the second derivative of φ_i = (l_i² - L_i²)/2 = 0 with Baumgarte
        stabilisation.  W = skew(ω) (body), Rdot = R W; M_rest: external moment minus
        ω × Jω (body).
        """
        beta = self.cables.baumgarte
        d, l, u, Pdot, ldot = cab
        n = len(l)
        B, MinvB, MinvQ = np.empty((n, 6)), np.empty((n, 6)), np.empty(6)     # B: rows B_iᵀ
        B[:, :3] = u
        B[:, 3:] = (self.r_skew @ (u @ R)[:, :, None])[:, :, 0]             # r_i × Rᵀu_i, body axes
        MinvB[:, :3] = u / self.m
        MinvB[:, 3:] = B[:, 3:] @ self.Jinv
        MinvQ[:3] = F_ext / self.m + self.g
        MinvQ[3:] = self.Jinv @ M_rest
        centripetal = self.r @ (Rdot @ W).T             # R (ω × (ω × r_i)), world
        h = ((Pdot * Pdot).sum(axis=1) - (d * centripetal).sum(axis=1)
             + 2 * beta * l * ldot + 0.5 * beta ** 2 * (l ** 2 - self.L ** 2)) / l
        _, T, info = dposv(B @ MinvB.T, h - B @ MinvQ)   # B M⁻¹ Bᵀ is symmetric positive definite
        if info != 0:
            raise SimulationError("inextensible cables: the constraint Jacobian is singular "
                                  "(degenerate cable geometry)")
        qdd = MinvQ + MinvB.T @ T
        return qdd[:3], qdd[3:], T

    def evaluate(self, t: np.ndarray, Y: np.ndarray) -> Evaluation:
        """:meth:`evaluate_one` at times t (K,) and states Y (K, size): an :class:`Evaluation`."""
        out = [self.evaluate_one(tk, yk) for tk, yk in zip(np.atleast_1d(t), np.atleast_2d(Y))]
        dY = np.array([o[0] for o in out])
        return Evaluation(R=Rotation.from_matrix(np.atleast_2d(Y)[:, 3:12].reshape(-1, 3, 3)).as_matrix(),
                          a=dY[:, 12:15], alpha=dY[:, 15:18], T=np.array([o[1] for o in out]),
                          exciter=np.array([o[2] for o in out]))
