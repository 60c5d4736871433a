"""The body hanging at rest: the static equilibrium (thesis section 2.2, eqs. 2.13–2.25) of a
:class:`HangingBody` for either cable model (:func:`equilibrium`, :func:`hanging_equilibrium`).
Frames as :mod:`~rig_identification.model.dynamics`.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares, minimize, root
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .cables import CableModel
from .rigid_body import SimulationError, moment_sum


@dataclass(frozen=True)
class HangingBody:
    """The rigid body on its cables as its statics see it: ``A`` (N, 3) the ceiling anchors,
    world m; ``r`` (N, 3) the body anchors from the CG, body m; ``L`` (N,) the cables' unstretched
    lengths m; ``m`` kg; ``g`` (3,) gravity, world m/s²; ``cables`` the cable model."""

    A: np.ndarray
    r: np.ndarray
    L: np.ndarray
    m: float
    g: np.ndarray
    cables: CableModel

    @staticmethod
    def of(rig: Rig, mass: float, cg: ArrayLike, cables: CableModel) -> "HangingBody":
        """The body of ``mass`` kg with its CG at ``cg`` (3,) body m on ``rig``'s cables.  Raises
        :class:`SimulationError` for more than 6 inextensible cables (their tensions statically
        indeterminate)."""
        n = len(rig.cables)
        if cables.type == "inextensible" and n > 6:
            raise SimulationError(f"inextensible cables: {n} cables have statically indeterminate tensions "
                                  "(at most 6); use the spring model")
        return HangingBody(rig.ceiling_anchors, rig.body_anchors - np.asarray(cg, float), rig.cable_lengths,
                           float(mass), np.array([0.0, 0.0, -rig.gravity]), cables)

    def static_wrench(self, p_cg: np.ndarray, R: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Net force (world, N) and moment about the CG (world, N m) of cables + weight at rest, (6,)."""
        s = self.r @ R.T
        d = self.A - (p_cg + s)
        u = d / np.linalg.norm(d, axis=1)[:, None]
        return np.concatenate([T @ u + self.m * self.g, moment_sum(s, T[:, None] * u)])

    def spring_tension_at_rest(self, p_cg: np.ndarray, R: np.ndarray) -> np.ndarray:
        """(N,) N the spring cables' tensions at a pose (CG ``p_cg`` (3,) world m, ``R`` body -> world)."""
        assert self.cables.stiffness is not None   # a spring model has its stiffness
        l = np.linalg.norm(self.A - (p_cg + self.r @ R.T), axis=1)
        T: np.ndarray = np.maximum(self.cables.stiffness * (l - self.L), 0.0)
        return T


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


def _lengths(model: HangingBody, x: np.ndarray) -> np.ndarray:
    p, R = _pose(x)
    lengths: np.ndarray = np.linalg.norm(model.A - (p + model.r @ R.T), axis=1)
    return lengths


def _hanging_guess(model: HangingBody) -> np.ndarray:
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


def hanging_equilibrium(model: HangingBody) -> RestState:
    """The :class:`RestState` of the body ``model`` at static equilibrium (thesis eqs. 2.20–2.25).
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
    p_cg, R, T = hanging_equilibrium(HangingBody.of(rig, mass, cg, cable_model))
    return Equilibrium(p_cg - R @ cg, Rotation.from_matrix(R), T)
