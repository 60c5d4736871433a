"""The body hanging at rest, and the start state of a simulation.

:func:`equilibrium` solves the static equilibrium (thesis section 2.2, eqs. 2.13–2.25) for
either cable model; :func:`initial_state` the pose a simulation starts from (at rest, or
displaced and projected back onto the cable lengths).  Frames as
:mod:`~rig_identification.model.dynamics`.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares, minimize, root
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .cables import CableModel
from .dynamics import RigDynamics, SimulationError
from .excitation import Excitation
from .experiment import Initial


class RestState(NamedTuple):
    """The body of a :class:`RigDynamics` at rest: ``p_cg`` (3,) world m, ``R`` (3, 3) body ->
    world, ``tensions`` (N,) N."""

    p_cg: np.ndarray
    R: np.ndarray
    tensions: np.ndarray


class Equilibrium(NamedTuple):
    """The body hanging at rest (:func:`equilibrium`): ``position`` (3,) world position of the
    BODY-FRAME ORIGIN m, ``rotation`` body -> world, ``tensions`` (N,) N."""

    position: np.ndarray
    rotation: Rotation
    tensions: np.ndarray


def _pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x = [p_cg (3), rotation vector (3)] -> (p_cg, R (3, 3))."""
    return x[:3], Rotation.from_rotvec(x[3:]).as_matrix()


def _lengths(model: RigDynamics, x: np.ndarray) -> np.ndarray:
    p, R = _pose(x)
    lengths: np.ndarray = np.linalg.norm(model.A - (p + model.r @ R.T), axis=1)
    return lengths


def _hanging_guess(model: RigDynamics) -> np.ndarray:
    """A start pose (body axes = world axes) with every cable within its length."""
    h = model.A - model.r                          # CG position if cable i had zero length
    xy = h[:, :2].mean(axis=0)
    rho2 = np.sum((h[:, :2] - xy) ** 2, axis=1)
    z = np.max(h[:, 2] - np.sqrt(np.maximum(model.L ** 2 - rho2, 0.0)))
    return np.array([xy[0], xy[1], z, 0.0, 0.0, 0.0])


def _solve_or_fail(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, what: str, tol: float,
                   scale: float | np.floating[Any]) -> np.ndarray:
    sol = root(fun, x0, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        sol = root(fun, sol.x, method="lm", options={"xtol": 1e-15, "ftol": 1e-15})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        # the stiff spring equations can stall both from a poor start (seen with single-threaded
        # BLAS rounding): scaled trust-region least squares from the original start, then polish
        ls = least_squares(fun, x0, method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                           max_nfev=2000)
        sol = root(fun, ls.x, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        raise SimulationError(f"{what}: no static equilibrium found ({sol.message})")
    x: np.ndarray = sol.x
    return x


def hanging_equilibrium(model: RigDynamics) -> RestState:
    """The :class:`RestState` of ``model`` at static equilibrium (thesis eqs. 2.20–2.25).
    Raises :class:`SimulationError`."""
    n = len(model.L)
    weight = model.m * np.linalg.norm(model.g)
    # 1) inextensible hanging pose: lowest CG with every cable no longer than its length
    cons = {"type": "ineq", "fun": lambda x: model.L ** 2 - _lengths(model, x) ** 2}
    opt = minimize(lambda x: x[2], _hanging_guess(model), method="SLSQP", constraints=[cons],
                   options={"ftol": 1e-14, "maxiter": 500})
    x = opt.x
    if model.cables.type == "spring":
        # 2) springs: sag by the mean stretch, then solve the 6 force/moment equations exactly
        assert model.cables.stiffness is not None   # a spring model has its stiffness
        x = x - np.array([0.0, 0.0, weight / model.cables.stiffness.sum(), 0, 0, 0])

        def residual(x: np.ndarray) -> np.ndarray:
            p, R = _pose(x)
            r: np.ndarray = model.static_wrench(p, R, model.spring_tension_at_rest(p, R)) / weight
            return r

        x = _solve_or_fail(residual, x, "spring cables", 1e-7, weight)
        p, R = _pose(x)
        return RestState(p, R, model.spring_tension_at_rest(p, R))
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

        def taut_residual(z: np.ndarray) -> np.ndarray:
            T = np.zeros(n)
            T[idx] = z[6:] * weight
            p, R = _pose(z[:6])
            return np.concatenate([model.static_wrench(p, R, T) / weight, (_lengths(model, z[:6]) - model.L)[idx]])

        z = _solve_or_fail(taut_residual, np.concatenate([x, T0[idx]]), "inextensible cables", 1e-7, weight)
        T = np.zeros(n)
        T[idx] = z[6:] * weight
        if T.min() >= 0 or model.cables.compression:
            p, R = _pose(z[:6])
            return RestState(p, R, T)
        active[np.argmin(T)] = False
        x, T0 = z[:6], T / weight
        if active.sum() < 3:
            raise SimulationError("inextensible cables: no equilibrium with at least 3 taut cables")


def _project(model: RigDynamics, p_cg: np.ndarray, R: np.ndarray,
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


def equilibrium(rig: Rig, mass: float, cg: ArrayLike, cable_model: CableModel) -> Equilibrium:
    """Static equilibrium of the body hanging at rest (thesis section 2.2, eqs. 2.13–2.25).

    rig: geometry (its own body mass/CG are ignored); mass: kg; cg: (3,) body frame, m.
    Springs include the cable stretch; inextensible cables solve the 6 equilibrium equations
    plus the length equations of the taut cables (slack cables get tension 0; with
    ``compression`` every cable keeps its length).

    Returns the :class:`Equilibrium` (position of the body-frame origin, rotation, tensions).
    The net force and the moment about the CG vanish to < 1e-6 N, N m.
    Raises :class:`SimulationError` (no equilibrium; inextensible with N > 6).
    """
    cg = np.asarray(cg, float)
    model = RigDynamics(rig, mass, cg, np.eye(3), cable_model, Excitation())
    p_cg, R, T = hanging_equilibrium(model)
    return Equilibrium(p_cg - R @ cg, Rotation.from_matrix(R), T)


def initial_state(model: RigDynamics, initial: Initial,
                  eq: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(18,) start state of the rigid ``model`` (state layout of :class:`RigDynamics`) for
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
        p, R = _project(model, p, R, target)
    return np.concatenate([p, R.ravel(), np.zeros(6)])
