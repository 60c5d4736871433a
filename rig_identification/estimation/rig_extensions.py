"""The rig model's extensions tested at its estimate: the score (Lagrange-multiplier) test of each
physics or sensor trait of :data:`~.rig_unknowns.EXTENSIONS`, the non-nested comparison of two,
and their cross-validation, all on the residual linearised about the fitted rigid-body model.

At the estimate x̂ the weighted residual is r(x̂ + S z) ≈ r̂ + J z (:class:`~.rig_problem.RigProblem`,
the fit's own weights).  An extension adds columns E (its unknowns at their value in the fit:
none).  With every base unknown refitted — the columns projected off the base Jacobian's range,
Ẽ = (I − Π) E, r̃ = (I − Π) r̂ — the extension's linearised estimate is θ = −Ẽ⁺ r̃ and the fall of
χ² it gives is S = ‖Π_Ẽ r̃‖², χ² with as many degrees of freedom as it has unknowns where the
extension is absent (Rao's score test; Engle 1984, *Handbook of Econometrics* II, ch. 13).  Two
extensions that each explain the misfit are compared by Vuong's test for non-nested models
(Vuong 1989, *Econometrica* 57): the sum over the record of the difference of their squared
residuals over its standard error, the residual's blocks as independent batches (it is filtered,
so its rows are correlated within a block).  Cross-validation: the extension fitted on one half
of the record lowers χ² on the other.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np
from scipy.linalg import qr

from .rig_fit import SANDWICH_BLOCKS, RigFit
from .rig_problem import RigPoint, RigProblem
from .rig_record import Record
from .rig_unknowns import EXTENSIONS, Layout, Prior, in_layout, positions

#: A base Jacobian column whose pivot is below this share of the largest is left out of the
#: projection (the unknowns the residual does not see).
RANK_TOLERANCE = 1e-10


@dataclass(frozen=True)
class ExtensionFit:
    """One set of extensions fitted to the linearised residual.

    names: the extensions.  statistic: the fall of χ² (the score statistic), dof its degrees of
    freedom.  change: (dof,) the unknowns' linearised change from their value in the fit, std:
    (dof,) their σ (:data:`~.rig_unknowns.EXTENSIONS` units).  values: (dof,) the value in the fit
    plus the change.  held_out: (2,) the fall of χ² on each half of the record of the extension
    fitted on the other (cross-validation).  residual: (data rows,) the residual after it.
    """

    names: tuple[str, ...]
    statistic: float
    dof: int
    change: np.ndarray
    std: np.ndarray
    values: np.ndarray
    held_out: np.ndarray
    residual: np.ndarray

    def of(self, name: str) -> np.ndarray:
        """The values of extension ``name`` (its units)."""
        start = sum(EXTENSIONS[e][0] for e in self.names[:self.names.index(name)])
        return self.values[start:start + EXTENSIONS[name][0]]


class LinearisedRig:
    """The fitted rig model's residual about its estimate, linearised in every unknown and every
    extension of ``names`` (module docstring; those the fit already holds are base unknowns): one
    Jacobian of the model with every tested extension at its value in ``fit`` — the fit's own
    columns where it carries them, the tested ones new — made once; the tests are linear algebra
    on it."""

    def __init__(self, rec: Record, prior: Prior, fit: RigFit, names: tuple[str, ...]):
        if fit.unknowns is None or fit.bases is None or fit.rest is None:
            raise ValueError("the fit carries no estimate to linearise about")
        lay = fit.layout.extended(names)
        x = in_layout(fit.unknowns, fit.layout, lay, fit.parameters)
        prob = RigProblem(rec, RigPoint(x, fit.parameters, fit.rest, fit.bases), lay, prior, fit.noise_scale,
                          len(rec.y) - rec.start)
        tested = [i for e in self.names_of(lay, names) for i in range(*lay.extension_of(e).indices(lay.size))]
        if fit.jacobian is not None and fit.jacobian.shape[1] == fit.layout.size:
            # the fit's own Jacobian at the estimate for every other unknown: only the tested columns are new
            self.J = np.zeros((fit.jacobian.shape[0], lay.size))
            self.J[:, positions(fit.layout, lay)] = fit.jacobian
            self.J[:, tested] = prob.jacobian(np.zeros(lay.size), tested)
        else:
            self.J = prob.jacobian(np.zeros(lay.size))
        self.r_hat = prob.residual(np.zeros(lay.size))
        self.rows = prob.data_rows
        self.channels = len(rec.channels)
        self.names = self.names_of(lay, names)
        self.columns = {e: lay.extension_of(e) for e in self.names}
        self.scale = prob.scale
        self.x = x
        self.extension = np.zeros(lay.size, bool)          # the tested columns; the fit's own are the base's
        for c in self.columns.values():
            self.extension[c] = True
        self._based(np.zeros(lay.size, bool), self.r_hat)

    @staticmethod
    def names_of(lay: Layout, names: tuple[str, ...]) -> tuple[str, ...]:
        """The extensions of ``names`` in ``lay``'s order."""
        return tuple(e for e in lay.extensions if e in names)

    def _based(self, dropped: np.ndarray, r: np.ndarray) -> None:
        """The projection off the base columns less ``dropped`` (mask), and ``r`` projected."""
        base = self.J[:, ~self.extension & ~dropped]
        base = base[:, np.any(base, axis=0)]
        q, rr, _ = qr(base, mode="economic", pivoting=True)
        d = np.abs(np.diag(rr))
        self.q = q[:, :int(np.sum(d > RANK_TOLERANCE * d[0]))]
        self.r = self.projected(r)

    def projected(self, v: np.ndarray) -> np.ndarray:
        """``v`` (rows,) or (rows, k) less its part in the base Jacobian's range."""
        out: np.ndarray = v - self.q @ (self.q.T @ v)
        return out

    def fitted(self, names: tuple[str, ...]) -> ExtensionFit:
        """The extensions ``names`` fitted together, every base unknown refitted (module docstring)."""
        E = self.projected(self._cols(names))
        r = self.r
        theta, cov = _least_squares(E, r)
        after = r + E @ theta
        statistic = float(r @ r - after @ after)
        scale = np.concatenate([self.scale[self.columns[e]] for e in names])
        value = np.concatenate([self.x[self.columns[e]] for e in names])
        change = theta * scale
        return ExtensionFit(tuple(names), statistic, len(theta), change, np.sqrt(np.diag(cov)) * scale,
                            value + change, self._held_out(E, r), after[:self.rows])

    def _held_out(self, E: np.ndarray, r: np.ndarray) -> np.ndarray:
        """(2,) the fall of ‖r‖² on each half of the record of the columns ``E`` fitted on the other."""
        half = self._halves()
        held_out = []
        for fit_rows, test_rows in ((half[0], half[1]), (half[1], half[0])):
            t, _ = _least_squares(E[fit_rows], r[fit_rows])
            e = r[test_rows]
            moved = e + E[test_rows] @ t
            held_out.append(float(e @ e - moved @ moved))
        return np.array(held_out)

    def held_out(self, index: slice) -> np.ndarray:
        """(2,) the fall of χ² on each half of the record of the base unknowns ``index`` fitted on
        the other, every other base unknown refitted: the model without them (:meth:`without`)
        against the model with them, cross-validated like an extension (:meth:`fitted`)."""
        out = self.without(index)
        return self._held_out(out.projected(self.J[:, index]), out.r)

    def base(self) -> ExtensionFit:
        """The model without extensions as an :class:`ExtensionFit` (its residual r̃)."""
        empty = np.zeros(0)
        return ExtensionFit((), 0.0, 0, empty, empty, empty, np.zeros(2), self.r[:self.rows])

    def vuong(self, a: ExtensionFit, b: ExtensionFit) -> float:
        """Vuong's z of ``a`` against ``b`` (positive: ``a`` fits better): the difference of their
        χ² over its standard error, :data:`~.rig_fit.SANDWICH_BLOCKS` blocks of the record as batches."""
        d = b.residual ** 2 - a.residual ** 2
        per = d.reshape(-1, self.channels).sum(axis=1)
        blocks = np.array([c.sum() for c in np.array_split(per, SANDWICH_BLOCKS)])
        spread = np.sqrt(SANDWICH_BLOCKS * np.var(blocks, ddof=1))
        return float(blocks.sum() / spread) if spread > 0 else 0.0

    def without(self, index: slice) -> "LinearisedRig":
        """This linearisation with the base unknowns ``index`` at zero instead of their estimate
        (the residual moved there, r̂ − J x̂/S, and their columns out of the projection): a model
        that leaves them out, to compare with one that replaces them by an extension."""
        out = copy.copy(self)
        dropped = np.zeros(len(self.x), bool)
        dropped[index] = True
        out._based(dropped, self.r_hat - self.J[:, index] @ (self.x[index] / self.scale[index]))
        return out

    def _cols(self, names: tuple[str, ...]) -> np.ndarray:
        return np.column_stack([self.J[:, self.columns[e]] for e in names])

    def _halves(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.rows // self.channels
        cut = (n // 2) * self.channels
        return np.arange(cut), np.arange(cut, self.rows)


def _least_squares(E: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """θ minimising ‖r + E θ‖ and its covariance (EᵀE)⁻¹ (unit-variance rows)."""
    cov = np.linalg.pinv(E.T @ E, rcond=1e-13, hermitian=True)
    theta: np.ndarray = -cov @ (E.T @ r)
    return theta, cov


__all__ = ["ExtensionFit", "LinearisedRig", "RANK_TOLERANCE"]
