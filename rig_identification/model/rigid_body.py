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


__all__ = ["SimulationError", "skew", "skews", "moment_sum"]
