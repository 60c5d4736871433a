"""ROS-free simulator of the suspended-body rig: the thesis's "experiment" (chapters 3 and 4).

A rigid body of mass ``m`` and inertia tensor ``J`` (about its CG, body axes) hangs from
the ceiling on N >= 3 cables and is shaken by an unbalanced-mass exciter or by force
pulses.  :func:`simulate` finds its equilibrium (:mod:`~rig_identification.model.equilibrium`),
integrates the full Newton–Euler equations (:mod:`~rig_identification.model.dynamics`) with
scipy's DOP853 (rtol 1e-10, atol 1e-12, dense output), then samples the dense solution at
each sensor's own times and writes the sensor streams of ``docs/recording_format.md``
(:mod:`~rig_identification.model.sensors`: IMU, load cells, exciter, inclinometer).

The ``compliant_body`` effect makes the body two: the carrying frame (hung on the cables,
carrying the sensors, the exciter and any dummy or cable mass) and a sprung body joined to
it by a 6-DOF spring–damper (:class:`~rig_identification.model.suspension.Suspension`,
:func:`~rig_identification.model.suspension.split_body`); both are integrated together
(state 36), at rtol 1e-9, atol 1e-11 (:data:`COMPLIANT_RTOL`).

Frames: as :mod:`~rig_identification.model.dynamics`.  A pose is ``position`` p = world
position of the BODY-FRAME ORIGIN and ``R`` = rotation body -> world (scipy ``Rotation``).
Inertia tensor entries as ``geometry_msgs/Inertia`` / ``truth.yaml``: off-diagonal entries
are the NEGATED products of inertia (thesis eqs. 3.6–3.9: ixy = -Jxy = -∫xy dm).

Experiment files: :mod:`~rig_identification.model.experiment` (their schema there).

Public API
----------
* :func:`simulate` (experiment) -> :class:`SimResult` with ``rig``, ``sensors``
  (:class:`~rig_identification.io.recording.SensorData`), ``truth`` (truth.yaml mapping), ``states``
  (:class:`States` at the IMU sample times) and ``states_at(t)`` (dense true motion).
* :func:`~rig_identification.model.equilibrium.equilibrium` (rig, mass, cg, cable_model) ->
  (position, Rotation, tensions).

Errors: :class:`~rig_identification.model.experiment.ExperimentError` (a ``ValueError``) for a
bad experiment file, naming the file and the field;
:class:`~rig_identification.model.rigid_body.SimulationError` (a ``RuntimeError``) for physics
that the chosen model cannot represent (slack inextensible cable, no equilibrium, ...).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from ..io.recording import SensorData
from ..io.rig import Rig, inertia_entries
from .cables import CableModel
from .dynamics import Evaluation, RigDynamics
from .equilibrium import HangingBody, hanging_equilibrium
from .excitation import Excitation
from .experiment import Experiment, Initial
from .parametrisation import joined
from .rigid_body import SimulationError
from .sensors import Sampled, sample_sensors
from .suspension import Suspension, split_body, without

__all__ = ["COMPLIANT_ATOL", "COMPLIANT_RTOL", "RTOL", "ATOL", "SimResult", "States", "Trajectory", "integrate",
           "simulate", "true_states", "initial_state"]

RTOL, ATOL = 1e-10, 1e-12
COMPLIANT_RTOL, COMPLIANT_ATOL = 1e-9, 1e-11   # compliant_body: its light frame rings faster on the stiff
                                   # cables; a 90 s random rig needs ~2.3x the rigid run's right-hand-side calls
                                   # at 1e-10, ~1.6x at 1e-9 (~1.5-2x the time), and its noise-free readings
                                   # differ from the 1e-10 ones by < 1e-5 of the reference sensor noise
                                   # (gyro 6e-11 rad/s, accelerometer 3e-8 m/s², load cells 2e-6 N)


def _projected(model: HangingBody, p_cg: np.ndarray, R: np.ndarray,
             target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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


def initial_state(model: HangingBody, initial: Initial,
                  eq: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(18,) start state of the rigid body ``model`` (state layout of :class:`RigDynamics`) for
    ``initial`` (at rest, or displaced; a displaced pose is projected onto the cable lengths
    when ``initial.project``); ``eq``: its :func:`hanging_equilibrium` if known.  Raises
    :class:`SimulationError`."""
    p_eq, R_eq, T_eq = hanging_equilibrium(model) if eq is None else eq
    if initial.pose_cg_position is not None:
        p, R = initial.pose_cg_position.copy(), Rotation.from_euler("xyz", initial.pose_rpy).as_matrix()
    else:
        p = p_eq + initial.displacement_position
        R = Rotation.from_euler("xyz", initial.displacement_rpy).as_matrix() @ R_eq
    moved = initial.pose_cg_position is not None or np.any(initial.displacement_position) \
        or np.any(initial.displacement_rpy)
    if moved and initial.project:
        target = model.L + (T_eq / model.cables.stiffness if model.cables.type == "spring" else 0.0)
        p, R = _projected(model, p, R, target)
    return np.concatenate([p, R.ravel(), np.zeros(6)])


class Trajectory:
    """The dense true motion: piecewise DOP853 interpolants between forcing breakpoints.

    Call with simulation times t (K,) s (0 = start) -> states (K, size)
    [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s] (size 18), followed
    by the sprung body's (size 36, compliant_body, see :class:`Suspension`).
    """

    def __init__(self, segments: list[tuple[float, float, Callable[[np.ndarray], np.ndarray]]], size: int = 18):
        self.segments = segments
        self.size = size
        self.starts = np.array([s[0] for s in segments])

    def __call__(self, t: ArrayLike) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        idx = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.segments) - 1)
        out = np.empty((len(t), self.size))
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.segments[k][2](t[m]).T
        return out


def integrate(model: RigDynamics, y0: np.ndarray, duration: float, rtol: float = RTOL,
              atol: float = ATOL) -> tuple[Trajectory, int]:
    """Integrate ``model`` from the state y0 (size,) over [0, duration] s with DOP853, cut at the
    forcing's breakpoints.  Returns the dense :class:`Trajectory` and the number of
    right-hand-side calls.  Raises :class:`SimulationError` when the integrator fails."""
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

@dataclass(frozen=True)
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


@dataclass(frozen=True)
class SimResult:
    """Output of :func:`simulate`.

    rig: the rig description to write (CG filled in for dynamic experiments, no CG for static
    ones); sensors: the sensor streams; truth: truth.yaml mapping; states: true motion at the
    IMU sample times; trajectory: dense true motion (simulation time); wall_time: s.
    """

    experiment: Experiment
    rig: Rig
    sensors: SensorData
    truth: dict[str, Any]
    states: States
    trajectory: Trajectory
    model: RigDynamics
    wall_time: float
    nfev: int

    def states_at(self, t: ArrayLike) -> States:
        """True motion at simulation times ``t`` (K,) s (0 = start; States.t holds the stamps)."""
        t = np.atleast_1d(np.asarray(t, float))
        Y = self.trajectory(t)
        return true_states(self.model, self.experiment.stamp_origin, t, Y, self.model.evaluate(t, Y))


def true_states(model: RigDynamics, stamp_origin: float, t: np.ndarray, Y: np.ndarray, ev: Evaluation) -> States:
    """The :class:`States` of ``model`` at simulation times t (K,) s from its states Y (K, size)
    and their evaluation ``ev`` (:meth:`RigDynamics.evaluate`); stamps ``stamp_origin + t``."""
    R, c = ev.R, model.cg
    return States(t=stamp_origin + t, position=Y[:, 0:3] - R @ c, quaternion=Rotation.from_matrix(R).as_quat(),
                  velocity=Y[:, 12:15] - np.einsum("kij,kj->ki", R, np.cross(Y[:, 15:18], c)),
                  omega=Y[:, 15:18].copy(), tensions=ev.T,
                  suspension=None if model.suspension is None else model.suspension.relative(Y))


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
            assert exp.rig.dummy_mass is not None   # a dummy static experiment has one (experiment_from_dict)
            mass, cg, J = joined(mass, cg, J, exp.rig.dummy_mass.mass, exp.rig.dummy_mass.position)
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
    cg_offset = exp.effect("cg_offset")
    if cg_offset is not None and static is None:   # rig.yaml states a CG the body does not have
        rig_out = replace(rig_out, center_of_gravity=np.asarray(cg, float) - cg_offset.get("offset"))
    cable_mass = exp.effect("cable_mass")
    if cable_mass is not None:  # half of each cable hangs on its body anchor, outside the load cell
        for b in exp.rig.body_anchors:
            mass, cg, J = joined(mass, cg, J, 0.5 * cable_mass.get("mass"), b)
    rotor = exp.effect("exciter_rotor")
    if rotor is not None and rotor.get("rotor_mass") > 0:     # the rotor rides on the body, on its axis
        assert exp.rig.exciter is not None      # the experiment refuses exciter_rotor without excitation
        mass, cg, J = joined(mass, cg, J, rotor.get("rotor_mass"), exp.rig.exciter.position)
    model = RigDynamics(exp.rig, mass, cg, J, cables, excitation, exp.effects)
    compliant = exp.effect("compliant_body")
    rtol, atol = RTOL, ATOL
    if compliant is None:
        y0 = initial_state(model.hanging, initial)
    else:                       # the whole body's rest pose; then frame + sprung body at it
        eq = hanging_equilibrium(model.hanging)
        y_whole = initial_state(model.hanging, initial, eq)
        sprung, _ = split_body(exp.mass, exp.cg, exp.inertia, compliant)
        frame = without(mass, cg, J, sprung)     # the rest of the body + dummy and cable masses
        suspension = Suspension(sprung, frame.cg, compliant, exp.rig.gravity, eq.R)
        model = RigDynamics(exp.rig, frame.mass, frame.cg, frame.inertia, cables, excitation, exp.effects, suspension)
        y0 = suspension.state_from_whole(y_whole, cg, frame.cg)
        rtol, atol = COMPLIANT_RTOL, COMPLIANT_ATOL
    traj, nfev = integrate(model, y0, duration, rtol, atol)
    cache: dict[float, Sampled] = {}
    sensors = sample_sensors(exp, model, traj, rig_out, duration, cache)
    truth: dict[str, Any] = {"mass": float(exp.mass), "center_of_gravity": [float(x) for x in exp.cg],
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
    states = true_states(model, exp.stamp_origin, *cache[exp.sensors.rates["imu"]])
    return SimResult(exp, rig_out, sensors, truth, states, traj, model, time.perf_counter() - t_wall, nfev)
