"""A least-squares solve's Jacobian reused while it predicts the steps: :class:`ReusedJacobian`
(scipy.optimize.least_squares takes its ``jacobian`` as ``jac``; ``runs`` counts the residual's
evaluations, a fresh Jacobian's columns included)."""
from __future__ import annotations

from typing import Callable

import numpy as np


class ReusedJacobian:
    """The Jacobian of ``residual`` (z (size,) → (m,)) for a least-squares solve, computed afresh only where the
    linear model it makes mispredicted a tried step: otherwise the last one with Broyden's rank-one
    update along the accepted step (Broyden 1965; Dennis & Schnabel, *Numerical Methods for
    Unconstrained Optimization and Nonlinear Equations*, §8.2).  A step whose cost fell by less than
    ``ratio`` of the fall the Jacobian predicted asks for a fresh one at the next
    accepted point.  Each fresh Jacobian costs a model run per unknown, an update none.  Without
    ``reuse`` (a short stage from a far start, where the model is far from linear and steps
    mispredicted are the rule), every Jacobian is fresh."""

    def __init__(self, residual: Callable[[np.ndarray], np.ndarray], jacobian: Callable[[np.ndarray], np.ndarray],
                 size: int, reuse: bool, at_x0: tuple[np.ndarray, np.ndarray] | None = None, ratio: float = 0.5):
        self._residual, self._jacobian, self.size, self.reuse, self.ratio = residual, jacobian, size, reuse, ratio
        self.z: np.ndarray | None = None
        self.J = np.zeros((0, 0))
        self.r = np.zeros(0)
        self.fresh = False
        self.stale_model = True
        if at_x0 is not None:               # a fresh Jacobian and the residual at z = 0, the solve starting elsewhere
            self.z, self.stale_model = np.zeros(size), False
            self.J, self.r = at_x0
        self.last: tuple[np.ndarray, np.ndarray] | None = None    # the last residual evaluated away from z
        self.runs = 0
        self.jacobians = 0

    def residual(self, z: np.ndarray) -> np.ndarray:
        r = self._residual(z)
        self.runs += 1
        if self.z is None:
            self.last = (z.copy(), r)
        elif not np.array_equal(z, self.z):
            predicted = self.r @ self.r - np.sum((self.r + self.J @ (z - self.z)) ** 2)
            if predicted > 0 and self.r @ self.r - r @ r < self.ratio * predicted:
                self.stale_model = True
            self.last = (z.copy(), r)
        return r

    def refresh(self, z: np.ndarray) -> np.ndarray:
        """A fresh Jacobian at ``z`` (a model run per unknown)."""
        self.J = self._jacobian(z)
        known = self.last is not None and np.array_equal(self.last[0], z)
        self.r = self.last[1] if self.last is not None and known else self._residual(z)
        self.z = z.copy()
        self.fresh, self.stale_model = True, False
        self.runs += self.size + 1 + int(not known)
        self.jacobians += 1
        return self.J

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        if (not self.reuse or self.z is None or self.stale_model or self.last is None
                or not np.array_equal(self.last[0], z)):
            return self.refresh(z)
        s = z - self.z
        r = self.last[1]
        self.J = self.J + np.outer(r - self.r - self.J @ s, s / (s @ s))
        self.z, self.r, self.fresh = z.copy(), r, False
        return self.J


__all__ = ["ReusedJacobian"]
