"""One body, several recordings: the rig model fitted to every record at once (:func:`fit_jointly`).

Each record keeps its own rig model (:class:`~.rig_problem.RigProblem`: its cables' stiffness,
load cells, geometry under the survey's prior, body damping, segments' initial states and the
exciter force's correction); the body's mass, CG and tensor are one set of unknowns that every
record's model shares (:class:`~.rig_problem.JointProblem`).  The likelihood is the product of the
records' (their noise independent), so the information adds; a run that alone leaves a direction
of the tensor undetermined (its exciter in a plane that hardly turns the body about it) is completed
by a run that determines it, and the fit is one minimum of the joint likelihood, not a fusion of
each run's estimate (an undetermined run's estimate is not Gaussian about the truth: its
likelihood may hold another minimum as high).

The fit starts from each record fitted alone (:func:`~.rig_fit.fit_rig`): the nuisance of each
at its own estimate, the body of the record whose tensor is best determined.  It solves the
joint problem on the whole records and re-weights each channel by its residual as the single fit
does; where a record's channels then misfit beyond :data:`~.rig_fit.LEVEL_LIMIT` and beyond what
that record reached alone, it solves again from the next record's body (the least misfit kept:
two undetermined runs' likelihood may hold a minimum that explains one run only).  It then
restarts from every other record's tensor, 1 % either way and 10 σ either way along the joint
tensor's weakest direction (the lowest minimum is the estimate; another within the 95 %
likelihood-ratio region more than 3 σ off makes the entries ambiguous), polishes, and takes the
covariance from the joint Jacobian (:func:`~.rig_fit.covariance`: the Fisher information and the
sandwich with each record's blocks; Ljung, *System Identification*, 2nd ed., §7.3 and §9.2 for
the product likelihood of independent experiments).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..model.linear_rig import linearise, natural_frequencies
from ..model.parametrisation import entry_scales, physically_consistent, to_tensor
from .restart_tensors import along_valleys, shifted
from .rig_fit import (
    LEVEL_LIMIT,
    REWEIGHT_LIMIT,
    REWEIGHT_ROUNDS,
    Body,
    RigFit,
    channel_offsets,
    covariance,
    gauss_newton_gain,
    jacobian_near,
    larger_of,
    polished,
    restarted,
    solve,
)
from .rig_problem import BODY, JointProblem, RigPoint, RigProblem, levels
from .rig_record import Record
from .rig_unknowns import Prior

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class JointFit:
    """The rig model fitted to several records of one body (:func:`fit_jointly`).

    fits: each record's :class:`~.rig_fit.RigFit` at the joint estimate — its own parameters,
    channels, levels and series; the body (mass, CG, tensor) the same in each, its covariance the
    joint fit's over that record's unknowns (so every fit's :attr:`~.rig_fit.RigFit.body`,
    :attr:`~.rig_fit.RigFit.ambiguous` and :attr:`~.rig_fit.RigFit.undetermined` are the joint
    estimate's).  singles: each record fitted alone (its tensor and σ, for comparison).
    """

    fits: tuple[RigFit, ...]
    singles: tuple[RigFit, ...]

    @property
    def body(self) -> Body:
        return self.fits[0].body

    @property
    def nfev(self) -> int:
        """Model runs of the joint fit (the single fits' not counted)."""
        return self.fits[0].nfev


def _determinacy(fit: RigFit) -> float:
    """The largest σ of ``fit``'s tensor entries over their scale (inf where not finite)."""
    share = np.asarray(fit.inertia_std / entry_scales(fit.inertia), float)
    return float(np.max(share)) if np.all(np.isfinite(share)) else np.inf


def _problem(rec: Record, at: RigPoint, fit: RigFit, prior: Prior, noise_scale: np.ndarray) -> RigProblem:
    """Record ``rec``'s whole-record problem at ``at`` in ``fit``'s layout."""
    return RigProblem(rec, at, fit.layout, prior, noise_scale, len(rec.y) - rec.start)


def _joint(recs: Sequence[Record], singles: Sequence[RigFit], priors: Sequence[Prior], points: Sequence[RigPoint],
           noise_scales: Sequence[np.ndarray]) -> JointProblem:
    made = zip(recs, points, singles, priors, noise_scales)
    return JointProblem([_problem(r, pt, f, p, s) for r, pt, f, p, s in made])


def _points(joint: JointProblem, x: np.ndarray) -> list[RigPoint]:
    """Each record's point at the joint unknowns ``x`` (:meth:`~.rig_problem.RigProblem.point`)."""
    return [p.point(joint.part(x, k)) for k, p in enumerate(joint.problems)]


@dataclass(frozen=True)
class _Descent:
    """A joint solve from one body (:func:`_descent`): each record's point, the noise factors,
    the worst channel's level over all records, ``misfit``: the largest over the records of its
    worst channel over the larger of :data:`~.rig_fit.LEVEL_LIMIT` and what it reached alone
    (≤ 1: every run fits as well as alone), the model runs, and whether its last solve settled
    (:func:`~.rig_fit.solve`)."""

    points: list[RigPoint]
    noise_scales: list[np.ndarray]
    worst: float
    misfit: float
    nfev: int
    settled: bool


def _descent(recs: Sequence[Record], singles: Sequence[RigFit], own: Sequence[Prior], body: np.ndarray) -> _Descent:
    """The joint problem solved from ``body`` (:data:`~.rig_problem.BODY`,) with each record's
    other unknowns at its single fit's, re-weighted as the single fit is (each channel's noise
    raised to its residual's, :data:`~.rig_fit.REWEIGHT_ROUNDS` rounds at most)."""
    points = []
    for rec, f, prior in zip(recs, singles, own):
        assert f.unknowns is not None and f.rest is not None
        alone = _problem(rec, RigPoint(f.unknowns, f.parameters, f.rest, f.bases), f, prior, f.noise_scale)
        x = f.unknowns.copy()
        x[:BODY] = body
        points.append(alone.point(x))
    noise_scales = [np.asarray(f.noise_scale, float) for f in singles]
    nfev = 0
    found: list[np.ndarray] = []
    for _ in range(REWEIGHT_ROUNDS + 1):
        joint = _joint(recs, singles, own, points, noise_scales)
        sol, runs, _ = solve(joint, True)
        nfev += runs
        points = _points(joint, joint.x(sol.x))
        found = [levels(_problem(r, pt, f, p, np.ones(len(r.channels))), pt.x)
                 for r, pt, f, p in zip(recs, points, singles, own)]
        new = [np.maximum(v, 1.0) for v in found]
        if max(float(np.max(v)) for v in found) > REWEIGHT_LIMIT or \
                all(np.allclose(a, b, rtol=0.05) for a, b in zip(new, noise_scales)):
            break
        noise_scales = new
    misfit = max(float(np.max(v)) / max(LEVEL_LIMIT, float(np.max(f.residual_level))) for v, f in zip(found, singles))
    return _Descent(points, noise_scales, max(float(np.max(v)) for v in found), misfit, nfev, bool(sol.settled))


def fit_jointly(recs: Sequence[Record], singles: Sequence[RigFit], priors: Sequence[Prior]) -> JointFit:
    """Fit the rig model to the records ``recs`` of one body at once (module docstring).

    singles: each record fitted alone (:func:`~.rig_fit.fit_rig`, the rigid-body model: no
    extensions), whose estimate each record's unknowns start from.  priors: each record's
    :class:`~.rig_unknowns.Prior`; the body's (mass, CG) taken from the first, once.  Returns a
    :class:`JointFit`.  Raises ValueError where fewer than two records are given or a single fit
    holds extensions.
    """
    if len(recs) < 2 or not len(recs) == len(singles) == len(priors):
        raise ValueError("a joint fit takes two records or more, each with its single fit and prior")
    if any(f.layout.extensions for f in singles):
        raise ValueError("a joint fit starts from the rigid-body rig model's single fits (no extensions)")
    if any(f.unknowns is None or f.rest is None for f in singles):
        raise ValueError("a joint fit needs each single fit's unknowns and rest pose")
    inf = np.full(3, np.inf)
    own = [priors[0]] + [replace(p, mass_std=np.inf, cg_std=inf) for p in priors[1:]]
    order = sorted(range(len(singles)), key=lambda k: _determinacy(singles[k]))
    nfev = 0
    descents = []
    for k in order:           # from the best-determined run's body; another's where a run's channels then misfit
        d = _descent(recs, singles, own, np.asarray(singles[k].unknowns, float)[:BODY])
        nfev += d.nfev
        descents.append(d)
        if d.misfit <= 1.0:
            break
        log.info("joint fit: from run %d's body a run's channels misfit (%.2f× what it reached alone or %g): "
                 "the next run's body", k, d.misfit, LEVEL_LIMIT)
    chosen = min(descents, key=lambda d: d.misfit)
    points, noise_scales, worst = chosen.points, chosen.noise_scales, chosen.worst
    last = _joint(recs, singles, own, points, noise_scales)
    J, r = last.jacobian(np.zeros(last.lay.size)), last.residual(np.zeros(last.lay.size))
    gain = gauss_newton_gain(J)
    nfev += last.lay.size + 2
    tensor = last.x0[last.lay.inertia]
    minima = [(0.5 * float(r @ r), last.x0, chosen.settled)]
    if worst <= REWEIGHT_LIMIT:            # the motion found: the minimum checked by restarts
        others = [np.asarray(f.unknowns, float)[:6] for f in singles]
        tries = [t for t in others if not np.allclose(t, tensor) and physically_consistent(to_tensor(t))]
        tries += [shifted(tensor, 1.0), shifted(tensor, -1.0)] + along_valleys(last, J, tensor)
        for t in tries:
            x2, cost2, runs, ended = restarted(last, (J, r), gain, t)
            nfev += runs
            minima.append((cost2, x2, ended))
    descent = tensor
    best = min(range(len(minima)), key=lambda i: minima[i][0])
    cost = minima[best][0]
    if best != 0:                          # a restart settled lower: the estimate's problem and Jacobian
        moved = _joint(recs, singles, own, _points(last, minima[best][1]), noise_scales)
        J, runs = jacobian_near(last, moved, J)
        gain = gauss_newton_gain(J)
        last = moved
        r = last.residual(np.zeros(last.lay.size))
        nfev += runs + 1
    estimate = minima[best][1][last.lay.inertia]
    others_x = [m for i, m in enumerate(minima) if i != best]
    settled = np.array([m[1][last.lay.inertia] for m in others_x]).reshape(-1, 6)
    other_chi2 = np.array([2 * (m[0] - cost) for m in others_x])
    log.info("joint fit: the other minima settled %s from the estimate, χ² %s", np.round(settled - estimate, 3),
             np.round(other_chi2, 2))
    z, runs = polished(last, gain, r)
    nfev += runs
    points = _points(last, last.x(z)) if np.any(z) else [p.at_x0 for p in last.problems]
    fisher, sandwich, bound = covariance(last, J, last.row_scale(noise_scales))
    cov = larger_of(fisher, sandwich)
    crb = np.sqrt(np.diag(bound)[last.lay.inertia])
    fits = []
    for k, (rec, pt, f, prior) in enumerate(zip(recs, points, singles, own)):
        idx = last.indices(k)
        unit = _problem(rec, pt, f, prior, np.ones(len(rec.channels)))
        outputs = unit.outputs(pt.x)
        offsets, offset_std = channel_offsets(rec.y[rec.start:rec.start + unit.n] - np.concatenate(outputs))
        fits.append(RigFit(pt.parameters, pt.x[unit.lay.initial], cov[np.ix_(idx, idx)], crb,
                           levels(unit, pt.x, outputs), noise_scales[k], rec.channels,
                           natural_frequencies(linearise(pt.parameters, pt.rest)), unit.lay, nfev, settled,
                           other_chi2, unit.fitted(pt.x, outputs), descent, pt.x, pt.bases, pt.rest, offsets,
                           offset_std=offset_std, other_settled=np.array([m[2] for m in others_x], bool)))
    return JointFit(tuple(fits), tuple(singles))


__all__ = ["JointFit", "fit_jointly"]
