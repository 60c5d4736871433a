"""The rigid body's algebra that every model of the rig shares: cross-product matrices, the sum of
the cables' moments, and :class:`SimulationError`, what a model raises where it cannot represent
the experiment."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


class SimulationError(RuntimeError):
    """The chosen physical model cannot represent the experiment (or a solver failed)."""


def skew(a: np.ndarray | Sequence[float]) -> np.ndarray:
    """Cross-product matrix [a]× (3, 3) of a vector a (3,): ``skew(a) @ x == np.cross(a, x)``.

    The rotation by a rotation vector φ (3,) rad is its matrix exponential,
    ``scipy.linalg.expm(skew(φ))`` (numerically equal to Rodrigues' formula)."""
    x, y, z = a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def skews(a: np.ndarray) -> np.ndarray:
    """Cross-product matrices (N, 3, 3) of the rows of a (N, 3): ``skews(a)[i] == skew(a[i])``."""
    out = np.zeros((len(a), 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -a[:, 2], a[:, 1]
    out[:, 1, 0], out[:, 1, 2] = a[:, 2], -a[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -a[:, 1], a[:, 0]
    return out


def moment_sum(s: np.ndarray, f: np.ndarray) -> np.ndarray:
    """sum_i s_i × f_i of two (N, 3) arrays -> (3,)."""
    X = s.T @ f
    return np.array([X[1, 2] - X[2, 1], X[2, 0] - X[0, 2], X[0, 1] - X[1, 0]])


def bearing_inertial_force(unbalance: float, u: np.ndarray, z: np.ndarray, spin: np.ndarray | float,
                           w: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """The exciter's unbalanced mass's inertial force from the body's rotation, which its bearing
    passes to the body at the exciter axis: (3,) or (n, 3) N, body axes,
    −m_u e [α × û + ω × (ω × û) + 2 Ω ω × (ẑ × û)] — the mass m_u at e û from the axis, its
    acceleration relative to the axis's in a frame turning with the body (Goldstein, *Classical
    Mechanics*, §4.10: the tangential, centripetal and Coriolis terms; its spin's centripetal
    term is the exciter's force itself).  unbalance: m_u e kg·m; u: (3,) or (n, 3) û, the
    force's direction; z: (3,) ẑ, the spin axis (the exciter's z); spin: Ω rad/s, the spin
    relative to the body about ẑ (scalar or (n,)); w, alpha: (3,) or (n, 3) the body's angular
    velocity rad/s and acceleration rad/s², body axes."""
    spin = np.asarray(spin, float)[..., None] if np.ndim(spin) else float(spin)
    coriolis = np.cross(w, np.cross(z, u))
    out: np.ndarray = -unbalance * (np.cross(alpha, u) + np.cross(w, np.cross(w, u)) + 2 * spin * coriolis)
    return out


__all__ = ["SimulationError", "bearing_inertial_force", "skew", "skews", "moment_sum"]
