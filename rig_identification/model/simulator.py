"""ROS-free simulator of the suspended-body rig: the thesis's "experiment" (chapters 3 and 4).

A rigid body of mass ``m`` and inertia tensor ``J`` (about its CG, body axes) hangs from
the ceiling on N >= 3 cables and is shaken by an unbalanced-mass exciter or by force
pulses.  The simulator integrates the full Newton–Euler equations (gyroscopic term
included, unlike thesis eq. 3.10)::

    m a_cg = sum_i T_i u_i + m g + F_ext                      (world axes)
    J dω/dt + ω × (J ω) = sum_i r_i × T_i u_i + M_ext         (body axes, about the CG)
    dR/dt = R skew(ω),   dp_cg/dt = v_cg

with scipy's DOP853 (rtol 1e-10, atol 1e-12, dense output), then samples the dense
solution at each sensor's own times and writes the sensor streams of
``RECORDING_FORMAT.md`` (IMU, load cells, exciter, inclinometer).

The ``compliant_body`` effect makes the body two: the carrying frame (hung on the cables,
carrying the sensors, the exciter and any dummy or cable mass) and a sprung body joined to
it by a 6-DOF spring–damper (:class:`Suspension`, :func:`split_body`); both are integrated
together (state 36), at rtol 1e-9, atol 1e-11 (:data:`COMPLIANT_RTOL`).  The sensor-level
effects (``gyro_scale``, ``gyro_bias_drift``, ``structural_mode``) act on the sampled
readings (:func:`mode_response`, :func:`random_walk`).

Frames and conventions
----------------------
* ``world``: z up, gravity (0, 0, -g), g = ``rig.gravity``.
* ``body``: origin = any reference point; the CG is at ``c`` (body frame).  A pose is
  ``position`` p = world position of the BODY-FRAME ORIGIN and ``R`` = rotation body -> world
  (scipy ``Rotation``).  ω is in body axes.  Internally the state is
  ``[p_cg (3), R row-major (9), v_cg (3), ω (3)]`` (with ``compliant_body``: the frame's,
  then the sprung body's).
* Inertia tensor entries as ``geometry_msgs/Inertia`` / ``truth.yaml``: off-diagonal entries
  are the NEGATED products of inertia (thesis eqs. 3.6–3.9: ixy = -Jxy = -∫xy dm).
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

Experiment files: :mod:`~rig_identification.model.experiment` (their schema there); the
compliant body's suspension: :mod:`~rig_identification.model.suspension`.

Sensors (each at its own rate, samples t_k = k / rate for k = 0 .. floor(duration rate),
header stamp = stamp_origin + t_k, white Gaussian noise σ plus constant bias):
gyro = R_imuᵀ ω; accelerometer = specific force R_imuᵀ Rᵀ (a_imu - g_world) at the IMU
point (reads +g along the up axis at rest); load cells = T_i; exciter = x, y of the
exciter force (rotating + measured pulses) in the exciter frame; inclinometer =
(asin(z_world · x_incl), asin(z_world · y_incl)), incl axes = R R_incl.  Order on the
gyro: true rate (+ structural mode) × gyro_scale, + noise, + biases, + gyro_bias_drift
(drawn after every other stream's noise, so adding it changes no other reading).

Public API
----------
* :func:`load_experiment` (path) / :func:`experiment_from_dict` (mapping, source) ->
  :class:`Experiment`; ``Experiment.with_overrides`` applies the ``rig-sim`` options.
* :func:`simulate` (experiment) -> :class:`SimResult` with ``rig``, ``sensors``
  (:class:`~rig_identification.io.recording.SensorData`), ``truth`` (truth.yaml mapping), ``states``
  (:class:`States` at the IMU sample times) and ``states_at(t)`` (dense true motion).
* :func:`equilibrium` (rig, mass, cg, cable_model) -> (position, Rotation, tensions).

Errors: :class:`ExperimentError` (a ``ValueError``) for a bad experiment file, naming the
file and the field; :class:`SimulationError` (a ``RuntimeError``) for physics that the
chosen model cannot represent (slack inextensible cable, no equilibrium, ...).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.linalg.lapack import dposv
from scipy.optimize import minimize, root
from scipy.signal import cont2discrete, lfilter
from scipy.spatial.transform import Rotation

from .effects import Effect
from .experiment import (DEFAULT_STIFFNESS, CableModel, Excitation, Experiment, ExperimentError, Initial, Pulse,
                         RotatingForce, SensorSpec, StaticSpec, experiment_from_dict, load_experiment,
                         load_rig_or_experiment)
from ..io.recording import SensorData, TimeSeries
from ..io.rig import DummyMass, Rig, inertia_entries, inertia_tensor
from .suspension import RigidPart, Suspension, split_body, without

STATIC_STREAMS = {"baseline": 1, "dummy": 2}   # static recordings: noise from default_rng([seed, stream])
RTOL, ATOL = 1e-10, 1e-12
COMPLIANT_RTOL, COMPLIANT_ATOL = 1e-9, 1e-11   # compliant_body: its light frame rings faster on the stiff
                                   # cables; a 90 s random rig needs ~2.3x the rigid run's right-hand-side calls
                                   # at 1e-10, ~1.6x at 1e-9 (~1.5-2x the time), and its noise-free readings
                                   # differ from the 1e-10 ones by < 1e-5 of the reference sensor noise
                                   # (gyro 6e-11 rad/s, accelerometer 3e-8 m/s², load cells 2e-6 N)
MODE_FILTER_RATE = 2000.0          # Hz: structural_mode's filter runs at >= this rate (and >= 40 x the
                                   # mode frequency), on a cubic spline of the sensor's samples



class SimulationError(RuntimeError):
    """The chosen physical model cannot represent the experiment (or a solver failed)."""


# --- the mechanical model --------------------------------------------------------------

def _skew(a) -> np.ndarray:
    """(3, 3) matrix of the cross product a × ·."""
    x, y, z = a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _moment_sum(s: np.ndarray, f: np.ndarray) -> np.ndarray:
    """sum_i s_i × f_i of two (N, 3) arrays -> (3,)."""
    X = s.T @ f
    return np.array([X[1, 2] - X[2, 1], X[2, 0] - X[0, 2], X[0, 1] - X[1, 0]])


class _Model:
    """Forces, tensions and state derivative of the suspended rigid body.

    State y (18,) = [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s];
    with a :class:`Suspension` (compliant_body) the body is the frame and y (36,) continues
    with the sprung body's state.
    """

    def __init__(self, rig: Rig, mass: float, cg: np.ndarray, inertia: np.ndarray, cables: CableModel,
                 excitation: Excitation, effects: tuple = (), suspension: Suspension | None = None):
        n = len(rig.cables)
        if cables.type == "inextensible" and n > 6:
            raise SimulationError(f"inextensible cables: {n} cables have statically indeterminate tensions "
                                  "(at most 6); use the spring model")
        self.m = float(mass)
        self.J = np.asarray(inertia, float)
        self.Jinv = np.linalg.inv(self.J)
        self.cg = np.asarray(cg, float)
        self.A = rig.ceiling_anchors
        self.r = rig.body_anchors - self.cg
        self.r_skew = np.array([_skew(r) for r in self.r])      # (N, 3, 3): r_i × ·
        self.L = rig.cable_lengths
        self.g = np.array([0.0, 0.0, -rig.gravity])
        self.cables = cables
        self.excitation = excitation
        self.suspension = suspension
        self.size = 18 if suspension is None else 36
        ex = rig.exciter
        self.R_exc = ex.rotation.as_matrix() if ex is not None else np.eye(3)
        r_exc = ex.position - self.cg if ex is not None else np.zeros(3)
        self.M_exc = _skew(r_exc) @ self.R_exc          # exciter-frame force -> moment about the CG
        self._dissipative = [e for e in effects if e.name in ("viscous_damping", "air_drag", "coulomb_friction")]
        self._rotor = next((e for e in effects if e.name == "exciter_rotor"), None)
        if self._rotor is not None:
            rot = excitation.rotating
            self._unbalance = self._rotor.get("unbalance", rot.amplitude / (2 * math.pi * rot.frequency) ** 2)
            self._rotor_inertia = self._rotor.get("rotor_inertia", 0.0)

    def effect_wrench(self, t: float, R: np.ndarray, v: np.ndarray, w: np.ndarray):
        """Force (3,) world N and moment (3,) body N·m about the CG of the concealed effects
        (:mod:`~rig_identification.model.effects`): dissipation and the exciter's rotor."""
        F, M = np.zeros(3), np.zeros(3)
        for e in self._dissipative:
            if e.name == "viscous_damping":
                F -= e.get("linear") * v
                M -= e.get("angular") * w
            elif e.name == "air_drag":
                F -= e.get("linear") * math.sqrt(v @ v) * v
                M -= e.get("angular") * math.sqrt(w @ w) * w
            else:
                eps = e.get("velocity_scale", 1e-3)
                F -= e.get("force") * v / math.sqrt(v @ v + eps * eps)
                M -= e.get("torque") * w / math.sqrt(w @ w + eps * eps)
        if self._rotor is not None:
            theta, speed, acc = self.excitation.rotating.angle_and_speed(t)
            z = self.R_exc[:, 2]
            u = self.R_exc @ np.array([math.cos(theta), math.sin(theta), 0.0])   # toward the unbalanced mass
            M += self._unbalance * np.cross(u, R.T @ self.g)                 # its weight, turning with it
            h = self._rotor_inertia * speed * z                                # spin angular momentum, body
            M -= np.cross(w, h) + self._rotor_inertia * acc * z
        return F, M

    def breakpoints(self) -> list[float]:
        """Times where the forcing is discontinuous (or has a kink), s."""
        out = [] if self.excitation.rotating is None else self.excitation.rotating.breakpoints()
        for p in self.excitation.pulses:
            out += [p.start, p.end]
        return out

    def external(self, t: float, R: np.ndarray):
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
                M += _skew(p.point - self.cg) @ f
                if p.measured:
                    measured += self.R_exc.T @ f
        return F_world, M, measured[:2]

    def evaluate_one(self, t: float, y: np.ndarray):
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
        W = _skew(w)
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
            a = (Tu.sum(axis=0) + F_ext) / self.m + self.g
            alpha = self.Jinv @ (_moment_sum(self.r, Tu @ R) + M_rest)
        else:
            a, alpha, T = self._constrained(R, Rdot, W, d, l, u, Pdot, ldot, F_ext, M_rest)
        dy = np.empty(self.size)
        dy[0:3], dy[3:12], dy[12:15], dy[15:18] = v, Rdot.ravel(), a, alpha
        if self.suspension is not None:
            dy[18:] = dy_sprung
        return dy, T, exciter

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """The integrator's right-hand side: dy/dt (size,) of y (size,) at t."""
        return self.evaluate_one(t, y)[0]

    def _constrained(self, R, Rdot, W, d, l, u, Pdot, ldot, F_ext, M_rest):
        """KKT solve for inextensible cables -> (a (3,), α (3,), T (N,)).

        Generalised accelerations q̈ = [a (world); α (body)] satisfy M q̈ = Q + B T with
        B_i = [u_i; r_i × Rᵀu_i] and, per cable, B_iᵀq̈ = (|Ṗ_i|² - d_i·(ω×(ω×s_i)) + 2β φ̇_i
        + β² φ_i) / l_i: the second derivative of φ_i = (l_i² - L_i²)/2 = 0 with Baumgarte
        stabilisation.  W = skew(ω) (body), Rdot = R W; M_rest: external moment minus
        ω × Jω (body).
        """
        beta = self.cables.baumgarte
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

    def evaluate(self, t: np.ndarray, Y: np.ndarray) -> dict:
        """:meth:`evaluate_one` at times t (K,) and states Y (K, size).

        Returns a dict: ``R`` (K, 3, 3) orthonormalised body->world, ``a`` (K, 3) CG
        acceleration world m/s², ``alpha`` (K, 3) dω/dt body rad/s², ``T`` (K, N) tensions N,
        ``exciter`` (K, 2) N.
        """
        out = [self.evaluate_one(tk, yk) for tk, yk in zip(np.atleast_1d(t), np.atleast_2d(Y))]
        dY = np.array([o[0] for o in out])
        return {"R": Rotation.from_matrix(np.atleast_2d(Y)[:, 3:12].reshape(-1, 3, 3)).as_matrix(),
                "a": dY[:, 12:15], "alpha": dY[:, 15:18], "T": np.array([o[1] for o in out]),
                "exciter": np.array([o[2] for o in out])}

    def static_wrench(self, p_cg: np.ndarray, R: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Net force (world, N) and moment about the CG (world, N m) of cables + weight at rest, (6,)."""
        s = self.r @ R.T
        d = self.A - (p_cg + s)
        u = d / np.linalg.norm(d, axis=1)[:, None]
        return np.concatenate([T @ u + self.m * self.g, _moment_sum(s, T[:, None] * u)])

    def spring_tension_at_rest(self, p_cg, R) -> np.ndarray:
        l = np.linalg.norm(self.A - (p_cg + self.r @ R.T), axis=1)
        return np.maximum(self.cables.stiffness * (l - self.L), 0.0)


# --- equilibrium and initial pose -----------------------------------------------------------

def _pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x = [p_cg (3), rotation vector (3)] -> (p_cg, R (3, 3))."""
    return x[:3], Rotation.from_rotvec(x[3:]).as_matrix()


def _lengths(model: _Model, x: np.ndarray) -> np.ndarray:
    p, R = _pose(x)
    return np.linalg.norm(model.A - (p + model.r @ R.T), axis=1)


def _hanging_guess(model: _Model) -> np.ndarray:
    """A start pose (body axes = world axes) with every cable within its length."""
    h = model.A - model.r                          # CG position if cable i had zero length
    xy = h[:, :2].mean(axis=0)
    rho2 = np.sum((h[:, :2] - xy) ** 2, axis=1)
    z = np.max(h[:, 2] - np.sqrt(np.maximum(model.L ** 2 - rho2, 0.0)))
    return np.array([xy[0], xy[1], z, 0.0, 0.0, 0.0])


def _solve_or_fail(fun, x0, what: str, tol: float, scale: float):
    sol = root(fun, x0, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        sol = root(fun, sol.x, method="lm", options={"xtol": 1e-15, "ftol": 1e-15})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        # the stiff spring equations can stall both from a poor start (seen with single-threaded
        # BLAS rounding): scaled trust-region least squares from the original start, then polish
        from scipy.optimize import least_squares
        ls = least_squares(fun, x0, method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                           max_nfev=2000)
        sol = root(fun, ls.x, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        raise SimulationError(f"{what}: no static equilibrium found ({sol.message})")
    return sol.x


def _equilibrium(model: _Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p_cg (3,), R (3, 3), tensions (N,)) at static equilibrium (thesis eqs. 2.20–2.25)."""
    n = len(model.L)
    weight = model.m * np.linalg.norm(model.g)
    # 1) inextensible hanging pose: lowest CG with every cable no longer than its length
    cons = {"type": "ineq", "fun": lambda x: model.L ** 2 - _lengths(model, x) ** 2}
    opt = minimize(lambda x: x[2], _hanging_guess(model), method="SLSQP", constraints=[cons],
                   options={"ftol": 1e-14, "maxiter": 500})
    x = opt.x
    if model.cables.type == "spring":
        # 2) springs: sag by the mean stretch, then solve the 6 force/moment equations exactly
        x = x - np.array([0.0, 0.0, weight / model.cables.stiffness.sum(), 0, 0, 0])

        def residual(x):
            p, R = _pose(x)
            return model.static_wrench(p, R, model.spring_tension_at_rest(p, R)) / weight

        x = _solve_or_fail(residual, x, "spring cables", 1e-7, weight)
        p, R = _pose(x)
        return p, R, model.spring_tension_at_rest(p, R)
    # 2) inextensible: the 6 equilibrium equations + the length equations of the taut cables,
    #    unknowns pose + tensions; a cable whose tension comes out negative is slack.
    active = np.ones(n, bool)
    p, R = _pose(x)
    s = model.r @ R.T
    u = (model.A - (p + s)) / _lengths(model, x)[:, None]
    T0 = np.linalg.lstsq(np.vstack([u.T, np.cross(s, u).T]), -np.concatenate([model.m * model.g, np.zeros(3)]),
                         rcond=None)[0] / weight
    while True:
        idx = np.flatnonzero(active)

        def residual(z):
            T = np.zeros(n)
            T[idx] = z[6:] * weight
            p, R = _pose(z[:6])
            return np.concatenate([model.static_wrench(p, R, T) / weight, (_lengths(model, z[:6]) - model.L)[idx]])

        z = _solve_or_fail(residual, np.concatenate([x, T0[idx]]), "inextensible cables", 1e-7, weight)
        T = np.zeros(n)
        T[idx] = z[6:] * weight
        if T.min() >= 0 or model.cables.compression:
            p, R = _pose(z[:6])
            return p, R, T
        active[np.argmin(T)] = False
        x, T0 = z[:6], T / weight
        if active.sum() < 3:
            raise SimulationError("inextensible cables: no equilibrium with at least 3 taut cables")


def _project(model: _Model, p_cg: np.ndarray, R: np.ndarray, target: np.ndarray):
    """Move a pose the least distance (Gauss–Newton, minimum-norm steps in CG position and
    world rotation vector) so that the cable lengths equal ``target`` (N,) m."""
    for _ in range(50):
        s = model.r @ R.T
        d = model.A - (p_cg + s)
        l = np.linalg.norm(d, axis=1)
        err = l - target
        if np.max(np.abs(err)) < 1e-13:
            break
        u = d / l[:, None]
        Jac = np.hstack([-u, -np.cross(s, u)])               # dl / d[p, θ_world]
        step = -np.linalg.lstsq(Jac, err, rcond=None)[0]
        p_cg = p_cg + step[:3]
        R = Rotation.from_rotvec(step[3:]).as_matrix() @ R
    else:
        raise SimulationError("the initial pose cannot be projected onto the cable lengths")
    return p_cg, R


def equilibrium(rig: Rig, mass: float, cg, cable_model: CableModel) -> tuple[np.ndarray, Rotation, np.ndarray]:
    """Static equilibrium of the body hanging at rest (thesis section 2.2, eqs. 2.13–2.25).

    rig: geometry (its own body mass/CG are ignored); mass: kg; cg: (3,) body frame, m.
    Springs include the cable stretch; inextensible cables solve the 6 equilibrium equations
    plus the length equations of the taut cables (slack cables get tension 0; with
    ``compression`` every cable keeps its length).

    Returns (position (3,) world position of the BODY-FRAME ORIGIN m, Rotation body->world,
    tensions (N,) N).  The net force and the moment about the CG vanish to < 1e-6 N, N m.
    Raises :class:`SimulationError` (no equilibrium; inextensible with N > 6).
    """
    cg = np.asarray(cg, float)
    model = _Model(rig, mass, cg, np.eye(3), cable_model, Excitation())
    p_cg, R, T = _equilibrium(model)
    return p_cg - R @ cg, Rotation.from_matrix(R), T


def _initial_state(model: _Model, initial: Initial, eq: tuple | None = None) -> np.ndarray:
    """(18,) start state of the rigid ``model``; ``eq``: its :func:`_equilibrium` if known."""
    p_eq, R_eq, T_eq = _equilibrium(model) if eq is None else eq
    if initial.pose_cg_position is not None:
        p, R = initial.pose_cg_position.copy(), Rotation.from_euler("xyz", initial.pose_rpy).as_matrix()
    else:
        p = p_eq + initial.displacement_position
        R = Rotation.from_euler("xyz", initial.displacement_rpy).as_matrix() @ R_eq
    moved = initial.pose_cg_position is not None or np.any(initial.displacement_position) \
        or np.any(initial.displacement_rpy)
    if moved and initial.project:
        target = model.L + (T_eq / model.cables.stiffness if model.cables.type == "spring" else 0.0)
        p, R = _project(model, p, R, target)
    return np.concatenate([p, R.ravel(), np.zeros(6)])


# --- integration ---------------------------------------------------------------------------

class Trajectory:
    """The dense true motion: piecewise DOP853 interpolants between forcing breakpoints.

    Call with simulation times t (K,) s (0 = start) -> states (K, size)
    [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s] (size 18), followed
    by the sprung body's (size 36, compliant_body, see :class:`Suspension`).
    """

    def __init__(self, segments: list, size: int = 18):
        self.segments = segments
        self.size = size
        self.starts = np.array([s[0] for s in segments])

    def __call__(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        idx = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.segments) - 1)
        out = np.empty((len(t), self.size))
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.segments[k][2](t[m]).T
        return out


def _integrate(model: _Model, y0: np.ndarray, duration: float, rtol: float = RTOL,
               atol: float = ATOL) -> tuple[Trajectory, int]:
    cuts = sorted({b for b in model.breakpoints() if 0 < b < duration} | {0.0, duration})
    segments, nfev, y = [], 0, y0
    for t0, t1 in zip(cuts[:-1], cuts[1:]):
        sol = solve_ivp(model.rhs, (t0, t1), y, method="DOP853", rtol=rtol, atol=atol, dense_output=True)
        if not sol.success:
            raise SimulationError(f"integration failed at t = {sol.t[-1]:.3f} s: {sol.message}")
        nfev += sol.nfev
        segments.append((t0, t1, sol.sol))
        y = sol.y[:, -1]
    return Trajectory(segments, model.size), nfev


# --- results ---------------------------------------------------------------------------------

@dataclass
class States:
    """True motion at given times.

    t (K,) header stamps s (stamp_origin + simulation time); position (K, 3) world position of
    the BODY-FRAME ORIGIN m; quaternion (K, 4) body->world, xyzw (``Rotation.as_quat``);
    velocity (K, 3) world velocity of the body-frame origin m/s; omega (K, 3) body axes rad/s;
    tensions (K, N) N.  With compliant_body these are the frame's (it carries the sensors) and
    suspension (K, 6) is the sprung body's displacement from its nominal place (frame axes, m)
    and its rotation vector relative to the frame (frame axes, rad); else None.
    """

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    tensions: np.ndarray
    suspension: np.ndarray | None = None

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_quat(self.quaternion)


@dataclass
class SimResult:
    """Output of :func:`simulate`.

    rig: the rig description to write (CG filled in for dynamic experiments, no CG for static
    ones); sensors: the sensor streams; truth: truth.yaml mapping; states: true motion at the
    IMU sample times; trajectory: dense true motion (simulation time); wall_time: s.
    """

    experiment: Experiment
    rig: Rig
    sensors: SensorData
    truth: dict
    states: States
    trajectory: Trajectory
    model: _Model
    wall_time: float
    nfev: int

    def states_at(self, t) -> States:
        """True motion at simulation times ``t`` (K,) s (0 = start; States.t holds the stamps)."""
        t = np.atleast_1d(np.asarray(t, float))
        Y = self.trajectory(t)
        return _states(self.model, self.experiment.stamp_origin, t, Y, self.model.evaluate(t, Y))


def _states(model: _Model, stamp_origin: float, t: np.ndarray, Y: np.ndarray, ev: dict) -> States:
    R, c = ev["R"], model.cg
    return States(t=stamp_origin + t, position=Y[:, 0:3] - R @ c, quaternion=Rotation.from_matrix(R).as_quat(),
                  velocity=Y[:, 12:15] - np.einsum("kij,kj->ki", R, np.cross(Y[:, 15:18], c)),
                  omega=Y[:, 15:18].copy(), tensions=ev["T"],
                  suspension=None if model.suspension is None else model.suspension.relative(Y))


def _sample_times(duration: float, rate: float) -> np.ndarray:
    return np.arange(int(math.floor(duration * rate + 1e-9)) + 1) / rate


def _sensors(exp: Experiment, model: _Model, traj: Trajectory, rig: Rig, duration: float, cache: dict) -> SensorData:
    """Sample every sensor on its own time grid; ``cache`` keeps (t, Y, evaluation) per rate."""
    spec = exp.sensors
    rng = np.random.default_rng(exp.seed if exp.static is None
                                else [exp.seed, STATIC_STREAMS[exp.static.kind]])
    noise, bias = spec.noise, spec.bias

    def at(rate: float):
        if rate not in cache:
            t = _sample_times(duration, rate)
            Y = traj(t)
            cache[rate] = (t, Y, model.evaluate(t, Y))
        return cache[rate]

    def noisy(x, key):
        return x + bias[key] + noise[key] * rng.standard_normal(x.shape)

    eff = {e.name: e for e in exp.effects}
    delay = {e.get("stream", ""): e.get("delay") for e in exp.effects if e.name == "sensor_delay"}
    mode = {e.get("sensor"): e for e in exp.effects if e.name == "structural_mode"}

    g_world = model.g
    # IMU
    t, Y, ev = at(spec.rates["imu"])
    R_imu = rig.imu.rotation.as_matrix()
    if "imu_misalignment" in eff:   # true IMU axes: turned beyond rig.yaml's imu.rpy
        R_imu = R_imu @ Rotation.from_euler("xyz", eff["imu_misalignment"].get("rpy")).as_matrix()
    omega, alpha = Y[:, 15:18], ev["alpha"]
    rho = rig.imu.position - model.cg
    if "imu_offset" in eff:         # true IMU position: rig.yaml's + offset
        rho = rho + eff["imu_offset"].get("offset")
    a_rel_body = np.cross(alpha, rho) + np.cross(omega, np.cross(omega, rho))
    a_imu = ev["a"] + np.einsum("kij,kj->ki", ev["R"], a_rel_body)
    f_body = np.einsum("kji,kj->ki", ev["R"], a_imu - g_world)
    gyro_true, acc_true = omega @ R_imu, f_body @ R_imu
    if "imu" in mode:               # the IMU's mount rings: ω + θ̇, specific force + ẍ
        gyro_true = gyro_true + mode_response(t, gyro_true, mode["imu"])
        acc_true = acc_true + mode_response(t, acc_true, mode["imu"])
    if "gyro_scale" in eff:         # scale errors act on the sensed rate, before noise and bias
        gyro_true = gyro_true * eff["gyro_scale"].get("scale")
    gyro = noisy(gyro_true, "gyro")
    acc = noisy(acc_true, "accelerometer")
    if "gyro_bias" in eff:
        gyro += eff["gyro_bias"].get("bias")
    if "accelerometer_bias" in eff:
        acc += eff["accelerometer_bias"].get("bias")
    t_imu = t
    # load cells
    t, Y, ev = at(spec.rates["load_cells"])
    if model.cables.type == "inextensible" and not model.cables.compression:
        _check_taut(rig, t, ev["T"], model.m * np.linalg.norm(g_world))
    T = ev["T"].copy()
    if "load_cells" in mode:        # each load cell reads its flexible anchor's spring force
        T = T + mode_response(t, T, mode["load_cells"])
    for e in exp.effects:
        if e.name == "load_cell_scale":
            T[:, rig.cable_names.index(e.get("cable"))] *= e.get("scale")
    T = noisy(T, "load_cell")
    t_cells = exp.stamp_origin + t + delay.get("load_cells", 0.0)
    cells = {name: TimeSeries(t_cells, T[:, i]) for i, name in enumerate(rig.cable_names)}
    # exciter
    exc = None
    if rig.exciter is not None:
        t, Y, ev = at(spec.rates["exciter"])
        exc = TimeSeries(exp.stamp_origin + t + delay.get("exciter", 0.0), noisy(ev["exciter"], "exciter"))
    # inclinometer
    inc = None
    if rig.inclinometer is not None:
        t, Y, ev = at(spec.rates["inclinometer"])
        axes = ev["R"] @ rig.inclinometer.rotation.as_matrix()
        angles = np.arcsin(np.clip(axes[:, 2, :2], -1.0, 1.0))
        inc = TimeSeries(exp.stamp_origin + t + delay.get("inclinometer", 0.0), noisy(angles, "inclinometer"))
    if "gyro_bias_drift" in eff:    # drawn last: every other stream's noise stays as without it
        gyro += random_walk(rng, len(t_imu), 1.0 / spec.rates["imu"], eff["gyro_bias_drift"].get("random_walk"))
    imu = TimeSeries(exp.stamp_origin + t_imu, np.hstack([gyro, acc]))
    return SensorData(imu, cells, exc, inc)


def random_walk(rng: np.random.Generator, n: int, dt: float, sigma: float) -> np.ndarray:
    """(n, 3) random-walk (Wiener) bias on a grid of step dt s: b_0 = 0,
    b_k+1 = b_k + sigma √dt N(0, 1) per axis (sigma rad/s/√s); draws (n − 1, 3) normals."""
    steps = sigma * math.sqrt(dt) * rng.standard_normal((max(n - 1, 0), 3))
    return np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])[:n]


def mode_response(t: np.ndarray, u: np.ndarray, effect: Effect) -> np.ndarray:
    """structural_mode: the change e (K, n) of readings u (K, n) sampled at the uniform times
    t (K,) s, e = p G(s) (u − u_0), G(s) = −s² / (s² + 2ζω s + ω²), ω = 2π ``frequency``,
    ζ = ``damping_ratio``, p = ``participation`` (default 1); the mount starts at rest.

    G is the base-excited oscillator's.  IMU: the mount's displacement x and rotation θ
    relative to the frame obey ẍ + 2ζωẋ + ω²x = −p (f − f_0) (specific force, IMU axes: the
    mount feels gravity too) and θ̈ + 2ζωθ̇ + ω²θ = −p dω/dt, so the added readings are
    ẍ = p G (f − f_0) and θ̇ = p G ω.  Load cell under an anchor of modal mass m, k = m ω²,
    c = 2ζωm, m ẍ + c ẋ + k x = p (T − T_0): it reads k x + c ẋ + T_0 = T + p G (T − T_0)
    (p = 1: the anchor's spring force).

    Evaluated exactly (first-order-hold discretisation, scipy ``cont2discrete(method="foh")``,
    then ``lfilter``) on a not-a-knot cubic spline of u at a rate ≥ max(:data:`MODE_FILTER_RATE`,
    40 ω/2π), then taken at the samples, so the result does not depend on the sensor's rate
    beyond the spline's O((2π f_u / rate)⁴) error: 200 Hz and 1 kHz agree to ~0.1 % of e; a
    kink or step of u (the spin-up's end, a pulse edge) is smoothed over a sample or two.
    """
    u = np.asarray(u, float)
    p = effect.get("participation", 1.0)
    if len(t) < 2 or p == 0:
        return np.zeros_like(u)
    w, zeta = 2 * math.pi * effect.get("frequency"), effect.get("damping_ratio")
    dt = (t[-1] - t[0]) / (len(t) - 1)
    m = max(1, int(math.ceil(max(MODE_FILTER_RATE, 40 * w / (2 * math.pi)) * dt - 1e-9)))
    fine = t[0] + np.arange((len(t) - 1) * m + 1) * (dt / m)
    x = u - u[0]
    x_fine = CubicSpline(t, x, axis=0)(fine)        # two samples: a straight line
    num, den, _ = cont2discrete(([-p, 0.0, 0.0], [1.0, 2 * zeta * w, w * w]), dt / m, method="foh")
    return lfilter(np.ravel(num), den, x_fine, axis=0)[::m]


def _check_taut(rig: Rig, t: np.ndarray, T: np.ndarray, weight: float) -> None:
    bad = T < -1e-9 * weight
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise SimulationError(f"inextensible cables: cable {rig.cable_names[i]} goes slack at t = {t[k]:.3f} s "
                              f"(tension {T[k, i]:.3g} N); the inextensible model cannot represent slack "
                              "cables, use cable_model.type: spring")


def _with_dummy(mass: float, cg: np.ndarray, J: np.ndarray, dummy: DummyMass):
    """Mass (kg), CG (3,) and inertia about the new CG (3, 3) of the body plus a point-mass dummy."""
    m = mass + dummy.mass
    c = (mass * cg + dummy.mass * dummy.position) / m

    def steiner(mm, d):
        return mm * (d @ d * np.eye(3) - np.outer(d, d))

    return m, c, J + steiner(mass, cg - c) + steiner(dummy.mass, dummy.position - c)


def simulate(exp: Experiment) -> SimResult:
    """Run the experiment: equilibrium, integration (DOP853), sensor sampling with noise.

    Static experiments (``exp.static``) hold the body at rest without excitation (plus the
    dummy mass for kind ``dummy``) for ``exp.static.duration``.  Raises
    :class:`SimulationError`.
    """
    t_wall = time.perf_counter()
    mass, cg, J = exp.mass, exp.cg, exp.inertia
    excitation, duration, initial = exp.excitation, exp.duration, exp.initial
    cables = exp.cable_model
    static = exp.static
    if static is not None:
        excitation, duration, initial = Excitation(), static.duration, Initial()
        if static.kind == "dummy":
            mass, cg, J = _with_dummy(mass, cg, J, exp.rig.dummy_mass)
        rig_out = replace(exp.rig, center_of_gravity=None)
    else:
        rig_out = replace(exp.rig, dummy_mass=None)
    elastic = exp.effect("cable_elasticity")
    if elastic is not None:     # cables of another stiffness than the rig.yaml written states
        k = elastic.get("stiffness")
        cables = CableModel.spring(exp.rig, mass, np.full(len(exp.rig.cables), k))
        kd = elastic.parameters.get("declared_stiffness")
        rig_out = replace(rig_out, cables=tuple(replace(c, stiffness=kd) for c in rig_out.cables))
    body_mass = exp.effect("body_mass")
    if body_mass is not None:   # rig.yaml states a mass the body does not have
        rig_out = replace(rig_out, mass=float(exp.rig.mass - body_mass.get("mass_error")))
    cable_mass = exp.effect("cable_mass")
    if cable_mass is not None:  # half of each cable hangs on its body anchor, outside the load cell
        for b in exp.rig.body_anchors:
            mass, cg, J = _with_dummy(mass, cg, J, DummyMass(0.5 * cable_mass.get("mass"), np.asarray(b, float)))
    model = _Model(exp.rig, mass, cg, J, cables, excitation, exp.effects)
    compliant = exp.effect("compliant_body")
    rtol, atol = RTOL, ATOL
    if compliant is None:
        y0 = _initial_state(model, initial)
    else:                       # the whole body's rest pose; then frame + sprung body at it
        eq = _equilibrium(model)
        y_whole = _initial_state(model, initial, eq)
        sprung, _ = split_body(exp.mass, exp.cg, exp.inertia, compliant)
        frame = without(mass, cg, J, sprung)     # the rest of the body + dummy and cable masses
        suspension = Suspension(sprung, frame.cg, compliant, exp.rig.gravity, eq[1])
        model = _Model(exp.rig, frame.mass, frame.cg, frame.inertia, cables, excitation, exp.effects, suspension)
        y0 = suspension.state_from_whole(y_whole, cg, frame.cg)
        rtol, atol = COMPLIANT_RTOL, COMPLIANT_ATOL
    traj, nfev = _integrate(model, y0, duration, rtol, atol)
    cache: dict[float, tuple] = {}
    sensors = _sensors(exp, model, traj, rig_out, duration, cache)
    truth = {"mass": float(exp.mass), "center_of_gravity": [float(x) for x in exp.cg],
             "inertia_about_cg": inertia_entries(exp.inertia),
             "effects": [e.truth_entry() for e in exp.effects], "scenario": exp.name,
             "seed": exp.seed}
    if static is not None:
        truth["notes"] = (f"static experiment {'WITH' if static.kind == 'dummy' else 'without'} the dummy mass"
                          + (" attached at rig.yaml dummy_mass.position; the truth values are those of the body "
                             "without the dummy mass." if static.kind == "dummy" else "."))
    truth["simulator"] = {
        "engine": "rig_identification.model.simulator (scipy solve_ivp)", "integrator": "DOP853",
        "rtol": rtol, "atol": atol, "duration": float(duration), **cables.describe(),
        "start": initial.describe(), "excitation": excitation.describe(),
        "sensor_noise_sigma": dict(exp.sensors.noise),
        "sensor_bias": {k: v.tolist() for k, v in exp.sensors.bias.items()},
        "sensor_rates_hz": dict(exp.sensors.rates), "stamp_origin": exp.stamp_origin}
    if compliant is not None:
        truth["simulator"]["compliant_body"] = suspension.describe(frame, sprung)
    states = _states(model, exp.stamp_origin, *cache[exp.sensors.rates["imu"]])
    return SimResult(exp, rig_out, sensors, truth, states, traj, model, time.perf_counter() - t_wall, nfev)


__all__ = ["CableModel", "Excitation", "Experiment", "ExperimentError", "Initial", "Pulse", "RigidPart",
           "RotatingForce", "SensorSpec", "SimResult", "SimulationError", "States", "StaticSpec", "Suspension",
           "Trajectory", "equilibrium", "experiment_from_dict", "inertia_entries", "inertia_tensor",
           "load_experiment", "load_rig_or_experiment", "mode_response", "random_walk", "simulate", "split_body",
           "DEFAULT_STIFFNESS"]
