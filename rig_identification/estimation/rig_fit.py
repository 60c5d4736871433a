"""The whole recording fitted by one grey-box model: every sensor an output, σ from one likelihood.

The model is the rig's exact equations (:mod:`~rig_identification.model.rig_ode`: the rigid body
on N spring-damper cables, Newton–Euler with the gyroscopic term, driven by the measured exciter
force); its outputs are the N tensions, the gyro, the accelerometer and the inclinometer.  The
fit is the output-error (prediction-error with no process noise) maximum-likelihood estimator of
the thesis's chapter 3 with every sensor an output (Ljung, *System Identification*, 2nd ed.,
ch. 4 grey-box models and ch. 7): every stream on one uniform grid over the record
(:mod:`~rig_identification.estimation.rig_record`), each channel
weighted by its white noise as estimated from the recording
(:func:`~rig_identification.io.quality.white_sigma`, counted once per sample of its own rate:
the residual, low-passed to the fit's band and decimated, weighted so that its sum of squares is
the full-rate in-band log-likelihood),
each channel's offset (a load cell's bias, the tension at rest, a gyro's bias) eliminated by
variable projection (Golub & Pereyra 1973).

Fitted (:class:`Layout`): the inertia tensor (6 entries), the centre of gravity (3), the mass
(prior: the scale's σ), per-cable stiffness (log, prior: rig.yaml's value or the default steel
cable's, wide), the cables' damping time τ, per-load-cell gain (prior: rig.yaml's
``survey.load_cell_gain``, default ±0.1 %), the body's viscous damping (linear and angular:
air, joints; no prior), the exciter force's correction (its readings an output), the initial
state (12), and the rig's geometry — every anchor coordinate and cable length — under the lab's
survey σ as prior (the load cells resolve 10⁻⁷ m of stretch: a millimetre of geometry taken as
exact would bias the tensor by percents).  The covariance is the inverse Fisher information of
the weighted residual (Gauss–Newton at the estimate, each channel's noise level raised to its
residual's where the model does not fit it), the nuisance parameters profiled out by taking
the tensor's block.  The Cramér–Rao bound of a rig and run (:func:`cramer_rao`) is the same
information at the true parameters with the sensors' own noise levels.

A fitted span is cut into segments of at most :data:`~.rig_unknowns.SEGMENT` s, each run from its own
initial state (multiple shooting without continuity, Bock & Plitt 1984: the states free, as
under an unmeasured disturbance).  The swinging modes are barely damped; carried over a whole
record, their free response's phase makes the likelihood multimodal in the tensor (minima a
fraction of a percent apart, each as sharp as its Fisher information says, at about the same
χ²).  Within a segment a phase error stays small, and what the segments lose is that ambiguous
information alone (the bound grows ≤ 1.5× on regular rigs, up to 25× on an entry of rigs whose
long-record minima are ambiguous).  Each segment's start is held as its offset from the rest
pose of the parameters tried (a changed geometry, CG or mass moves the rest pose, and a start
held fixed would become a swing the data do not show).  The fit starts on the record's first
:data:`STAGES` seconds, one segment each, then takes the whole record.  Its minimum is then checked by
restarts on the whole record (:func:`restarted`) from tensors :data:`~.restart_tensors.RESTART_SHIFT` away on
either side, from :data:`~.restart_tensors.WEAK_RESTART_SIGMA` σ along the tensor's weakest direction, from
each moment of inertia :data:`~.restart_tensors.VALLEY_SHIFT` of its scale off where the data see it coarsely
enough for a flat, rippled valley (:func:`~.restart_tensors.along_moments`), and from another estimator's tensor
where the caller gives one: where one settles
more than 3 σ off at a χ² within the tensor's 95 % likelihood-ratio region, the likelihood is
flat or multimodal where the Fisher information says it is sharp (:attr:`RigFit.ambiguous`);
the lowest of the minima is the estimate.  After the first stage the Jacobian is reused where it
predicts the trust region's steps (:class:`~.rig_problem.ReusedJacobian`); a restart starts
with the estimate's, and where its chord steps come straight back to the estimate
(:func:`came_back`) no trust region is needed.
"""
from __future__ import annotations

import logging
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import OptimizeResult, least_squares

from ..io.rig import Rig
from ..io.verdict import KEYS, entry_determined
from ..model.linear_rig import RestPose, RigParameters, linearise, natural_frequencies, rest_pose
from ..model.parametrisation import entry_scales, physically_consistent, to_tensor
from .restart_tensors import along_valleys, shifted
from .rig_problem import (
    FTOL,
    GTOL,
    JACOBIAN_STEP,
    MAX_ITERATIONS,
    OUTSIDE,
    THREADS,
    XTOL,
    CompressedResidual,
    JointProblem,
    ReusedJacobian,
    RigPoint,
    RigProblem,
    levels,
    sequential_blas,
)
from .rig_record import ChannelSeries, Record
from .rig_start import start_parameters
from .rig_unknowns import (
    EXTENSION_FIELDS,
    EXTENSIONS,
    Layout,
    Prior,
    body_unknowns,
    extension_fields,
    vector,
)

log = logging.getLogger(__name__)

#: The record's lengths, s, stage by stage before the whole record (module docstring).
STAGES = (5.0, 15.0)
#: A channel whose residual in the band exceeds its noise by this factor does not fit (the
#: verdict ``model_error``).
LEVEL_LIMIT = 1.5
#: Re-weighting rounds: each channel's noise level replaced by its residual's where the
#: residual is larger (a channel the model does not fit at its noise level is leaned on less).
REWEIGHT_ROUNDS = 2
#: No re-weighting where a channel's residual exceeds this many times its noise: the fit has not
#: found the motion there, and raising the channel's noise would hide it, not lean on the rest.
REWEIGHT_LIMIT = 10.0
#: Blocks of the record whose scores make the sandwich covariance's meat (:func:`covariance`).
SANDWICH_BLOCKS = 12
#: A solve stops where the Gauss–Newton step would lower the cost (½ χ²) by less than this: the
#: estimate is then within sqrt(2 · 0.01) = 0.14 σ of the minimum in every direction.
NEWTON_DECREMENT = 0.01
#: Where the Gauss–Newton model misjudges the cost at that scale (its decrement stays ~1.5 while
#: each step gains ~2e-3: the same rig's 40 s stage) a solve stops when this many iterations
#: together gained less than :data:`NEWTON_DECREMENT`.
STALL_ITERATIONS = 5
#: A whole-record solve stops where the Gauss–Newton step would move every tensor entry, CG
#: coordinate and the mass by less than this share of its σ (:func:`solve`).
RESULT_STEP = 0.25
#: Gauss–Newton steps with the estimate's Jacobian that finish the fit (:func:`polished`), at most.
POLISH_STEPS = 4
#: s over which the initial state is fitted alone before each start's first stage (:func:`_settled`).
INITIAL_SPAN = 3.0
#: A start that fits the first stage within this RMS over the noise (the priors' rows counted)
#: is taken without trying the next (:func:`fit_rig`).
START_LEVEL = 1.5
#: 95 % quantile of χ² with 6 degrees of freedom: a second minimum whose χ² exceeds the fit's by
#: less lies inside the tensor's 95 % likelihood-ratio region.
CHI2_95_6 = 12.592
#: A solve's Jacobian is made afresh where a tried step lowered the cost by less than this share
#: of what the Jacobian's linear model predicted (:class:`~.rig_problem.ReusedJacobian`).
REUSE_RATIO = 0.5
#: A solve that stops within this many σ (tensor, CG, mass) of the point whose Jacobian it was
#: given judges its stop with that Jacobian (:func:`solve`): the model is linear that near.
ANCHOR_SIGMA = 1.0
#: A restart's chord steps with the estimate's Jacobian (:func:`came_back`), at most.
CHORD_STEPS = 8
#: A solve, its Jacobian reused, may run this many times :data:`MAX_ITERATIONS` model
#: evaluations (each an iteration without a Jacobian costs one).
REUSED_EVALUATIONS = 3
#: scipy's least_squares statuses of a stop by its tolerances (ftol, xtol, gtol): the Gauss–Newton
#: decrement of a fresh Jacobian checks it, as it checks a stall (:func:`solve`).
TOLERANCE_STOPS = (2, 3, 4)

# --- the fit -------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Body:
    """The body's mass properties as a fit gives them: ``mass`` kg, ``cg`` (3,) m and ``inertia``
    (6,) kg·m² about it (body frame, KEYS order), ``covariance`` (10, 10) of (inertia, cg, mass)
    in that order; ``rotor`` kg the exciter rotor's mass taken out (0: none)."""

    mass: float
    cg: np.ndarray
    inertia: np.ndarray
    covariance: np.ndarray
    rotor: float = 0.0

    @property
    def std(self) -> np.ndarray:
        """(10,) σ of (inertia, cg, mass)."""
        out: np.ndarray = np.sqrt(np.diag(self.covariance))
        return out


@dataclass(frozen=True)
class RigFit:
    """The rig model fitted to a whole recording.

    parameters: the estimate (:class:`~rig_identification.model.linear_rig.RigParameters`);
    initial: (12,) the initial state's offset at the fit's start.  covariance: (n, n) of the
    unknowns (:class:`Layout` order; inertia kg·m², CG m, mass kg, log stiffness, τ s, gains,
    body damping N·s/m and N·m·s, initial state (δp_cg m, δφ rad, v_cg m/s, ω rad/s), geometry m):
    each σ the larger of the
    Fisher information's (each channel's noise raised to its residual's level) and the
    sandwich's (:func:`covariance`), the correlations the Fisher information's.
    crb: (6,) the Cramér–Rao bound of the tensor entries at the estimate with the sensors' own
    noise levels, the nuisance unknowns under their priors, kg·m².
    residual_level: (n_out,) each channel's residual RMS over its noise's.  noise_scale: (n_out,)
    the factor the fit put on each channel's noise (≥ 1).  channels: names.
    natural_frequencies: (6,) Hz, linearised about the rest pose.  nfev: model runs.
    other_minima: (k, 6) kg·m² the suspended body's tensors (:attr:`parameters`) where the other
    whole-record fits settled (the staged fit, its two restarts :data:`~.restart_tensors.RESTART_SHIFT` away and
    those from ``restarts``, :func:`fit_rig`: the lowest is the estimate; none where a channel is
    beyond :data:`REWEIGHT_LIMIT` of its noise: the motion not found), other_chi2: (k,) their χ²
    less the estimate's (≥ 0), other_settled: (k,) bool, False where that fit's trust region spent
    its budget of model runs first (:func:`solve`): its end is where the runs ran out, not a
    minimum (its χ² still counts in :attr:`ambiguous`: a point that low and that far shows the
    likelihood flat whether or not it is a minimum); None: not recorded.  series:
    every channel at the estimate (:class:`ChannelSeries`).  descent: (6,) kg·m² where the staged
    fit's own descent ended (the estimate unless a restart settled lower).  unknowns: (size,) every
    unknown at the estimate (``layout``), bases: (segments, 13) the segments' states before their
    unknowns, rest: the rest pose — what the model is linearised about
    (:mod:`~rig_identification.estimation.rig_extensions`).  offsets: (n_out,) each channel's
    offset the fit eliminated, the mean of reading − model over the span (a load cell's bias N, a
    gyro's rad/s, an accelerometer's m/s², an inclinometer's rad; the exciter's N), offset_std:
    (n_out,) their σ (:func:`channel_offsets`).  jacobian:
    (rows, size) the weighted residual's Jacobian the covariance was made from (per unit of each
    unknown's scale), reused where the model is linearised again at the estimate.
    """

    parameters: RigParameters
    initial: np.ndarray
    covariance: np.ndarray
    crb: np.ndarray
    residual_level: np.ndarray
    noise_scale: np.ndarray
    channels: tuple[str, ...]
    natural_frequencies: np.ndarray
    layout: Layout
    nfev: int
    other_minima: np.ndarray
    other_chi2: np.ndarray
    series: ChannelSeries
    descent: np.ndarray | None = None
    unknowns: np.ndarray | None = None
    bases: np.ndarray | None = None
    rest: RestPose | None = None
    offsets: np.ndarray | None = None
    jacobian: np.ndarray | None = None
    offset_std: np.ndarray | None = None
    other_settled: np.ndarray | None = None

    @property
    def minima_settled(self) -> list[bool | None]:
        """(k,) :attr:`other_settled` per other minimum, None for each where it was not recorded."""
        if self.other_settled is None:
            return [None] * len(self.other_chi2)
        return [bool(e) for e in self.other_settled]

    @property
    def ambiguous(self) -> list[int]:
        """The tensor entries (indices, KEYS order) on which another minimum differs from the
        estimate by more than 3 σ while its χ² is within :data:`CHI2_95_6` of the estimate's, or
        on which the staged fit's own descent ended more than 3 σ away (a restart found the
        estimate: the descent was trapped, and a lower minimum may lie where no start went):
        the likelihood is flat or multimodal where the Fisher information says it is sharp, and
        σ is not the estimate's uncertainty."""
        d = np.abs(self.other_minima - self.parameters.inertia) / self.inertia_std      # the suspended body's
        close = np.asarray(self.other_chi2) < CHI2_95_6
        trapped = np.zeros(6, bool) if self.descent is None else \
            np.abs(self.descent - self.parameters.inertia) > 3.0 * self.inertia_std
        return [i for i in range(6) if np.any(close & (d[:, i] > 3.0)) or trapped[i]]

    @property
    def undetermined(self) -> list[str]:
        """The tensor entries (KEYS names) not :func:`~rig_identification.io.verdict.entry_determined`:
        their 95 % half-width beyond its share of their scale (a moment's own, the largest
        moment's for a product)."""
        scale = entry_scales(self.inertia)
        return [k for k, s, c in zip(KEYS, self.inertia_std, scale) if not entry_determined(s / c)]

    @property
    def determined(self) -> bool:
        """Every entry determined (:attr:`undetermined` empty) and none :attr:`ambiguous`."""
        return not self.undetermined and not self.ambiguous

    @cached_property
    def body(self) -> Body:
        """The body's mass, CG and tensor with their covariance.  The model's are the suspended
        body's; where it holds the exciter rotor's mass m_r (``exciter_rotor``), the body is that
        less the rotor, a point mass on its axis at the exciter's position
        (:func:`~.rig_unknowns.body_unknowns`; the ring it turns
        on, m_r e² ≈ 1 kg·m² on the shared recording's 11 kg rotor, stays in the tensor), the
        covariance carried through the map's Jacobian (central differences)."""
        lay, p = self.layout, self.parameters
        m_r = float(p.rotor[1]) if "exciter_rotor" in lay.extensions else 0.0
        cov = self.covariance[:10, :10]
        if m_r == 0.0:
            return Body(float(p.mass), p.cg, p.inertia, cov)
        where = np.r_[np.arange(10), lay.extension_of("exciter_rotor").start + 1]
        x = vector(p, self.initial, lay)

        def body_of(v: np.ndarray) -> np.ndarray:
            y = x.copy()
            y[where] = v
            return body_unknowns(y, lay, p.exciter_position)[:10]

        v = x[where]
        h = 1e-6 * np.maximum(np.abs(v), 1.0)
        D = np.column_stack([(body_of(v + e) - body_of(v - e)) / (2 * e[i]) for i, e in enumerate(np.diag(h))])
        b = body_of(v)
        return Body(float(b[9]), b[6:9], b[:6], D @ self.covariance[np.ix_(where, where)] @ D.T, m_r)

    @property
    def inertia(self) -> np.ndarray:
        """(6,) the body's tensor entries about its CG, body axes, kg·m² (KEYS order; :attr:`body`)."""
        return self.body.inertia

    @property
    def inertia_std(self) -> np.ndarray:
        return self.body.std[:6]

    @property
    def cg_std(self) -> np.ndarray:
        return self.body.std[6:9]

    def extension(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """The fitted values and σ of extension ``name`` (units of :data:`~.rig_unknowns.EXTENSIONS`;
        KeyError where the model does not hold it)."""
        index = self.layout.extension_of(name)
        value = np.atleast_1d(np.asarray(getattr(self.parameters, EXTENSION_FIELDS[name]), float))
        return value, np.sqrt(np.diag(self.covariance)[index])


def covariance(prob: RigProblem | JointProblem, J: np.ndarray, row_scale: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unknowns' covariance (size, size) in x units at ``prob``'s x0, ``J`` its Jacobian there
    (:meth:`RigProblem.jacobian`): the inverse Fisher information of the weighted residual (the
    priors' rows included), the sandwich (Huber 1967; White 1982)
    H⁻¹ (Σ_b s_b s_bᵀ + P) H⁻¹, its meat the data's scores summed over :data:`SANDWICH_BLOCKS`
    blocks of each record (batch means: a residual that is not white — a model error — is
    correlated within a block) plus the priors' information P, and the inverse Fisher information
    with each channel's noise at its own level: the data rows' weights times ``row_scale``
    (data_rows,), the factors ``prob`` put on them (:meth:`RigProblem.row_scale`; None: the first again)."""
    r = prob.residual(np.zeros(prob.lay.size))
    rows = prob.data_rows
    H = J.T @ J
    Hinv = np.linalg.pinv(H, rcond=1e-13, hermitian=True)
    Jd, rd = J[:rows], r[:rows]
    edges = prob.score_edges(SANDWICH_BLOCKS)
    scores = np.array([Jd[a:b].T @ rd[a:b] for a, b in zip(edges[:-1], edges[1:]) if b > a])
    scores -= scores.mean(axis=0)
    blocks = len(scores)
    meat = scores.T @ scores * blocks / (blocks - 1) + J[rows:].T @ J[rows:]
    S = np.outer(prob.scale, prob.scale)
    unit = Hinv
    if row_scale is not None and not np.all(row_scale == 1):
        Ju = J.copy()
        Ju[:rows] *= row_scale[:, None]
        unit = np.linalg.pinv(Ju.T @ Ju, rcond=1e-13, hermitian=True)
    dead = ~np.any(J, axis=0)                     # unknowns the residual does not see: σ inf

    def in_x(M: np.ndarray) -> np.ndarray:
        M = M * S
        M[dead, :] = M[:, dead] = 0.0
        M[dead, dead] = np.inf
        return M

    return in_x(Hinv), in_x(Hinv @ meat @ Hinv), in_x(unit)


def larger_of(fisher: np.ndarray, sandwich: np.ndarray) -> np.ndarray:
    """The covariance (size, size) whose σ is, per unknown, the larger of the Fisher information's and the
    sandwich's (:func:`covariance`), its correlations the Fisher information's; an unknown the
    residual does not see (σ inf, or a zero column: pinv's null space) uncorrelated."""
    sd = np.sqrt(np.maximum(np.diag(fisher), np.diag(sandwich)))
    fd = np.sqrt(np.diag(fisher))
    seen = np.isfinite(sd) & (fd > 0)
    cov = np.diag(sd ** 2)
    both = np.ix_(seen, seen)
    cov[both] = fisher[both] / np.outer(fd[seen], fd[seen]) * np.outer(sd[seen], sd[seen])
    return cov


def solve(prob: RigProblem | JointProblem, whole: bool = False, z0: np.ndarray | None = None,
          at_x0: tuple[np.ndarray, np.ndarray] | None = None, reuse: bool = True
          ) -> tuple[OptimizeResult, int, np.ndarray | None]:
    """One least-squares solve of ``prob`` from ``z0`` (default 0: its x0; ``at_x0``: the Jacobian
    and the residual at 0 where known) (scipy's trust region; with ``reuse`` the Jacobian reused where
    it predicts the steps, :class:`~.rig_problem.ReusedJacobian`, else made afresh every
    iteration: the first stage, from a far start, where steps mispredicted are the rule), stopped
    where the Gauss–Newton decrement ½ gᵀ (JᵀJ)⁺ g of a fresh Jacobian falls below :data:`NEWTON_DECREMENT` (Boyd &
    Vandenberghe, *Convex Optimization*, §9.5.1: the cost the Gauss–Newton step would still
    gain), where the last :data:`STALL_ITERATIONS` iterations gained less than that together,
    or by the tolerances — these two checked by that decrement at a fresh Jacobian: where the
    Gauss–Newton step still gains more, it is taken (where it lowers the cost) and the trust
    region starts anew from there (mispredicted steps shrink it far below the step to the
    minimum: bench_any_rig 21096); on the ``whole`` record (no stage after it) also where the Gauss–Newton
    step would move no tensor entry, CG coordinate or the mass by :data:`RESULT_STEP` of its σ
    (the trust region then crawls along a valley of the nuisance unknowns: the segments' states
    and the force's correction).  A stop within :data:`ANCHOR_SIGMA` of the point ``at_x0`` gives
    (a restart that came back to the estimate) is judged with that point's Jacobian, updated on
    the way, not a fresh one.  With ``reuse`` the trust region takes the residual compressed onto
    the Jacobian's columns (:class:`~.rig_problem.CompressedResidual`: the same cost and gradient,
    its SVD per iteration of a square matrix).  Returns the solution (its ``fun`` the whole
    residual; ``settled`` False where the budget of :data:`MAX_ITERATIONS` model runs (times
    :data:`REUSED_EVALUATIONS` with ``reuse``) ran out before a stop above: its end is where the runs
    ran out, not a minimum), the model runs it took and the fresh Jacobian at the solution where
    the stop made one (else None)."""
    jac = ReusedJacobian(prob.residual, prob.jacobian, prob.lay.size, reuse, at_x0, REUSE_RATIO)
    costs: list[float] = []
    result = np.r_[prob.lay.inertia, prob.lay.cg, prob.lay.mass]
    # where the solve ends within ANCHOR_SIGMA of the point whose Jacobian it was given, that one serves its stop
    anchor_std = None if at_x0 is None else \
        np.sqrt(np.diag(np.linalg.pinv(at_x0[0].T @ at_x0[0], rcond=1e-13, hermitian=True))[result])

    def done(f: np.ndarray) -> bool:
        g = jac.J.T @ f
        Hinv = np.linalg.pinv(jac.J.T @ jac.J, rcond=1e-13, hermitian=True)
        step = Hinv @ g
        decrement = 0.5 * g @ step
        return bool(decrement < NEWTON_DECREMENT
                    or whole and decrement < 0.5 * CHI2_95_6
                    and np.all(np.abs(step[result]) < RESULT_STEP * np.sqrt(np.diag(Hinv)[result])))

    def converged(intermediate_result: OptimizeResult) -> None:
        costs.append(float(intermediate_result.cost))
        z = intermediate_result.x
        stalled = len(costs) > STALL_ITERATIONS and costs[-1 - STALL_ITERATIONS] - costs[-1] < NEWTON_DECREMENT
        if jac.z is None or not np.array_equal(jac.z, z):
            return
        f = intermediate_result.fun if packed is None else packed.full(z)
        if not (stalled or done(f)):
            return
        near = anchor_std is not None and bool(np.all(np.abs(z[result]) < ANCHOR_SIGMA * anchor_std))
        if not (jac.fresh or near):         # a stale Jacobian's stall or decrement: checked with a fresh one
            jac.refresh(z)
            costs.clear()
            if not done(f):
                return
        short[0] = jac.fresh and not done(f)
        raise StopIteration

    budget = MAX_ITERATIONS * (REUSED_EVALUATIONS if reuse else 1)
    z, iterations, short = np.zeros(prob.lay.size) if z0 is None else z0, 0, [False]
    packed: CompressedResidual | None = None
    while True:
        packed = CompressedResidual(jac, z) if reuse else None
        sol = least_squares(jac.residual if packed is None else packed.residual, z,
                            jac=jac.jacobian if packed is None else packed.jacobian, method="trf", x_scale=1.0,
                            xtol=XTOL, ftol=FTOL, gtol=GTOL, max_nfev=budget - iterations, callback=converged)
        if packed is not None:
            sol.fun = packed.full(sol.x)
        iterations += sol.nfev
        if sol.status in TOLERANCE_STOPS and iterations < budget:
            if not (jac.fresh and jac.z is not None and np.array_equal(jac.z, sol.x)):
                jac.refresh(sol.x)
            short[0] = not done(sol.fun)
        if not short[0] or iterations + 1 >= budget:      # the step and a resumed solve need a run each
            settled = sol.status != 0 and not short[0]
            break
        # the trust region stalled (or stopped by its tolerances) where a fresh Jacobian's Gauss–Newton step
        # still gains more than NEWTON_DECREMENT: steps the model mispredicted shrank the region far below
        # that step.  The step is taken where it lowers the cost, and the solve goes on from there.
        step = -gauss_newton_gain(jac.J) @ sol.fun
        r1 = jac.residual(sol.x + step)
        iterations += 1
        if not r1 @ r1 < sol.fun @ sol.fun:        # neither the trust region nor the step gains: a minimum
            settled = True
            break
        z, short[0] = sol.x + step, False
        costs.clear()
        log.info("rig fit: the trust region stalled at cost %.6g; a Gauss–Newton step to %.6g", sol.cost,
                 0.5 * float(r1 @ r1))
    sol.nfev, sol.settled = iterations, settled
    log.info("rig fit: %.0f s of record, %d iterations, %d Jacobians, cost %.6g%s", prob.seconds, sol.nfev,
             jac.jacobians, sol.cost, "" if settled else " (its budget of model runs spent: not settled)")
    fresh = jac.fresh and jac.z is not None and np.array_equal(jac.z, sol.x)
    return sol, jac.runs, jac.J if fresh else None


def _settled(prob: RigProblem, lay: Layout) -> np.ndarray:
    """``prob``'s unknowns with the initial state fitted alone over the first
    :data:`INITIAL_SPAN` s, every parameter at its start (over so short a span the swinging
    modes' phase hardly depends on the parameters: the state is found before the parameters
    make the likelihood multimodal; Ljung 1999, §7.3 on the initial state)."""
    rec = prob.rec
    n = min(prob.n, int(round(INITIAL_SPAN / rec.dt)) + 1)
    short = RigProblem(rec, prob.at_x0, lay, prob.prior, np.ones(len(rec.channels)), n)
    part = lay.initial

    def residual(zi: np.ndarray) -> np.ndarray:
        z = np.zeros(lay.size)
        z[part] = zi
        return short.residual(z)

    sol = least_squares(residual, np.zeros(part.stop - part.start), method="trf", diff_step=JACOBIAN_STEP,
                        xtol=XTOL, ftol=FTOL, gtol=GTOL, max_nfev=MAX_ITERATIONS)
    x = prob.x0.copy()
    x[part] += short.scale[part] * sol.x
    log.info("rig fit: initial state over %.0f s, %d iterations, cost %.4g → %.4g", n * rec.dt, sol.nfev,
             0.5 * np.sum(residual(np.zeros(part.stop - part.start)) ** 2), sol.cost)
    return x


def _jacobian_at_x0(prob: RigProblem, solved: RigProblem, J: np.ndarray | None, weights: np.ndarray
                    ) -> tuple[np.ndarray, int]:
    """``prob``'s Jacobian at its x0 and the model runs it took: ``J``, fresh at the solution of
    ``solved`` (weighted by ``weights``), in ``prob``'s units where the residual is the same, else computed."""
    if (J is not None and solved.lay.size == prob.lay.size and solved.n == prob.n
            and solved.substeps == prob.substeps and np.array_equal(weights, prob.weight_scale)):
        return J * (prob.scale / solved.scale)[None, :], 0
    return prob.jacobian(np.zeros(prob.lay.size)), prob.lay.size + 1


def jacobian_near(prob: RigProblem | JointProblem, moved: RigProblem | JointProblem, J: np.ndarray
                  ) -> tuple[np.ndarray, int]:
    """The Jacobian of ``moved`` at its x0 and the model runs it took: ``J``, ``prob``'s fresh at its
    x0, in ``moved``'s units where ``moved`` lies within :data:`ANCHOR_SIGMA` σ of it in every tensor
    entry, CG coordinate and the mass (the model is linear that near: the rule :func:`solve` stops
    by; the Fisher information changes by the share σ is of the parameters), else computed."""
    body = np.r_[prob.lay.inertia, prob.lay.cg, prob.lay.mass]
    std = prob.scale[body] * np.sqrt(np.diag(np.linalg.pinv(J.T @ J, rcond=1e-13, hermitian=True))[body])
    if np.all(np.abs(moved.x0[body] - prob.x0[body]) < ANCHOR_SIGMA * std):
        return J * (moved.scale / prob.scale)[None, :], 0
    return moved.jacobian(np.zeros(moved.lay.size)), moved.lay.size + 1


def gauss_newton_gain(J: np.ndarray) -> np.ndarray:
    """(size, rows) the Gauss–Newton gain (JᵀJ)⁺Jᵀ of the Jacobian ``J`` (rows, size): the step to the
    linearised residual's minimum is ``-gain @ r``."""
    gain: np.ndarray = np.linalg.pinv(J.T @ J, rcond=1e-13, hermitian=True) @ J.T
    return gain


def polished(prob: RigProblem | JointProblem, gain: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, int]:
    """The estimate after Gauss–Newton steps from ``prob``'s x0 with the gain of its Jacobian there
    (``gain``: :func:`gauss_newton_gain`; the chord method; ``r``: the residual at x0), each taken
    where it lowers the cost, at most :data:`POLISH_STEPS`: a solve stops within :data:`RESULT_STEP`
    σ of the minimum, and the steps carry it to the minimum wherever in that neighbourhood it
    stopped (the estimate then does not depend on the rounding that steered the iterations).
    Returns the scaled unknowns z there and the model runs."""
    z = np.zeros(prob.lay.size)
    runs = 0
    for _ in range(POLISH_STEPS):
        step = -gain @ r
        r1 = prob.residual(z + step)
        runs += 1
        if not r1 @ r1 < r @ r:
            break
        z, r = z + step, r1
    return z, runs


def came_back(prob: RigProblem | JointProblem, J: np.ndarray, gain: np.ndarray, z0: np.ndarray
              ) -> tuple[np.ndarray | None, float, int]:
    """Where the restart of ``prob`` from the scaled unknowns ``z0`` comes back to the estimate
    (x0; ``J`` (rows, size) its Jacobian there, ``gain`` (size, rows) its Gauss–Newton gain,
    :func:`gauss_newton_gain`): the chord method's steps (:func:`polished`) from ``z0``, each
    lowering the cost, at most :data:`CHORD_STEPS`, until the next would move no tensor entry, CG
    coordinate or the mass by :data:`RESULT_STEP` of its σ and would lower the cost by less than
    ½ :data:`CHI2_95_6` (the Gauss–Newton decrement ½ ‖J step‖²: the whole record's stop in
    :func:`solve`; the nuisance unknowns settled too); they came back where they end within
    :data:`ANCHOR_SIGMA` σ of x0 and the cost falls along the straight path from ``z0`` to that end
    at each of its quarter points (no ridge between them that a step jumped).  Returns the scaled
    unknowns z there (None where the restart did not come back so: the trust region's descent from
    ``z0`` then decides, :func:`restarted`), the cost (½ χ²) and the model runs."""
    body = np.r_[prob.lay.inertia, prob.lay.cg, prob.lay.mass]
    std = np.sqrt(np.sum(gain[body] ** 2, axis=1))         # (JᵀJ)⁺ = gain gainᵀ
    z, r = z0, prob.residual(z0)
    start = float(r @ r)
    runs = 1
    for _ in range(CHORD_STEPS):
        step = -gain @ r
        if np.all(np.abs(step[body]) < RESULT_STEP * std) and 0.5 * np.sum((J @ step) ** 2) < 0.5 * CHI2_95_6:
            break
        r1 = prob.residual(z + step)
        runs += 1
        if not r1 @ r1 < r @ r:
            return None, 0.0, runs
        z, r = z + step, r1
    else:
        return None, 0.0, runs
    if not np.all(np.abs(z[body]) < ANCHOR_SIGMA * std):
        return None, 0.0, runs
    costs = [float(ri @ ri) for ri in (prob.residual(z0 + t * (z - z0)) for t in (0.25, 0.5, 0.75))]
    runs += 3
    if not all(a >= b for a, b in zip([start] + costs, costs + [float(r @ r)])):
        return None, 0.0, runs
    return z, 0.5 * float(r @ r), runs


def restarted(prob: RigProblem | JointProblem, at_x0: tuple[np.ndarray, np.ndarray], gain: np.ndarray,
              tensor: np.ndarray) -> tuple[np.ndarray, float, int, bool]:
    """The whole-record fit ``prob`` (its x0 the estimate, ``at_x0`` its Jacobian and residual there,
    ``gain`` its Gauss–Newton gain) restarted from the tensor entries ``tensor`` (6,) kg·m², every
    other unknown at the estimate: the unknowns x it settles at, its cost (½ χ², the same weights),
    the model runs and whether it settled (False: the trust region's budget ran out first, the end
    no minimum: :func:`solve`).  A well-determined minimum draws the restart back within its σ (found by
    :func:`came_back` where its chord steps show it); where the likelihood is flat or multimodal
    along some direction of the tensor, the trust region's descent settles elsewhere at a χ² about
    as low."""
    lay = prob.lay
    z0 = np.zeros(lay.size)
    z0[lay.inertia] = (tensor - prob.x0[lay.inertia]) / prob.scale[lay.inertia]
    back, cost, tried = came_back(prob, at_x0[0], gain, z0)
    if back is not None:
        return prob.x(back), cost, tried, True
    sol, runs, _ = solve(prob, True, z0, at_x0)
    return prob.x(sol.x), float(sol.cost), tried + runs, bool(sol.settled)


def fit_rig(rec: Record, rig: Rig, prior: Prior, inertia0: ArrayLike, restarts: ArrayLike = (),
            extensions: Mapping[str, ArrayLike] | None = None, stiffness: ArrayLike | None = None) -> RigFit:
    """Fit the rig model to a :class:`Record` (module docstring).

    rig: rig.yaml (geometry, mounts).  prior: :class:`Prior` (its CG is the start).
    inertia0: starts of the tensor entries, (6,) or (k, 6) kg·m² about the CG, tried in order
    over the first stage until one fits it within :data:`START_LEVEL` of the noise (else the one
    of least cost goes on): the swinging modes make the likelihood multimodal where a start's
    frequencies are far off.  restarts: (k, 6) kg·m² tensors the whole-record fit is restarted
    from besides the two :data:`~.restart_tensors.RESTART_SHIFT` away (another estimator's: a minimum it found is
    one the likelihood may hold too); a tensor no body has is left out.
    τ starts at the default cable's (:func:`~.rig_start.default_damping_time`).
    extensions: the model's extensions (:data:`~.rig_unknowns.EXTENSIONS`: name -> the start of
    its unknowns; None: the rigid-body rig model).  stiffness: the cables' start (N,) N/m (default
    the prior's centre; :func:`~.harmonic_start.stiffness_start`'s where rig.yaml gives none).
    Raises :class:`~.rig_record.RigFitError` when the rig has no rest pose.
    """
    extensions = extensions or {}
    lay = Layout(len(rig.cables), rec.force_unknowns(),
                 extensions=tuple(e for e in EXTENSIONS if e in extensions))
    n_all = len(rec.y) - rec.start
    channels = len(rec.channels)
    noise_scale = np.ones(channels)
    lengths = [int(round(s / rec.dt)) + 1 for s in STAGES if s < 0.8 * n_all * rec.dt]
    rounds = [(n, False) for n in lengths] + [(n_all, True)] * (REWEIGHT_ROUNDS + 1)
    best = None
    nfev = 0
    problems = []
    geometry, rest0 = start_parameters(rig, prior, np.zeros(6), rec,
                                       stiffness=None if stiffness is None else np.asarray(stiffness, float))
    geometry = geometry.replace(**extension_fields(extensions))
    for start in np.atleast_2d(np.asarray(inertia0, float)):
        p0 = geometry.replace(inertia=start)
        n0 = rounds[0][0]
        prob = RigProblem(rec, RigPoint(vector(p0, np.zeros(12), lay), p0, rest0), lay, prior, noise_scale, n0)
        prob = RigProblem(rec, RigPoint(_settled(prob, lay), p0, rest0, prob.bases), lay, prior, noise_scale, n0)
        problems.append(prob)
        if np.all(prob.residual(np.zeros(prob.lay.size)) == OUTSIDE):
            log.info("rig fit: the start %s leaves the physical region or diverges: the next", np.round(start, 1))
            continue
        sol, runs, J_end = solve(prob, reuse=False)
        nfev += runs
        if best is None or sol.cost < best[1].cost:
            best = (prob, sol)
            solved = (prob, J_end, noise_scale)
        if 2 * sol.cost <= START_LEVEL ** 2 * prob.noise_cost(prob.lay.size):
            break
    if best is None:                # every start outside: the first, which the verdict will call failed
        prob = problems[0]
        sol, _, J_end = solve(prob, reuse=False)
        best, solved = (prob, sol), (prob, J_end, noise_scale)
    prob, sol = best
    at = prob.point(prob.x(sol.x))
    for i, (n, final) in enumerate(rounds):
        if i > 0:
            prob = RigProblem(rec, at, lay, prior, noise_scale, n)
            sol, runs, J_end = solve(prob, final)
            solved = (prob, J_end, noise_scale)
            nfev += runs
            at = prob.point(prob.x(sol.x))
        if final:
            level = levels(RigProblem(rec, at, lay, prior, np.ones(channels), n_all), at.x)
            new_scale = np.maximum(level, 1.0)
            if np.allclose(new_scale, noise_scale, rtol=0.05) or np.max(level) > REWEIGHT_LIMIT:
                break
            noise_scale = new_scale
    if np.max(level) > REWEIGHT_LIMIT:     # the motion not found: no minimum to check by restarts
        log.info("rig fit: a channel %.0f× its noise: no restarts", np.max(level))
        restarts, check = (), False
    else:
        check = True
    last = RigProblem(rec, at, lay, prior, noise_scale, n_all)
    return _concluded(last, solved, restarts, nfev, check, bool(sol.settled))


def _concluded(last: RigProblem, solved: tuple[RigProblem, np.ndarray | None, np.ndarray], restarts: ArrayLike,
               nfev: int, check: bool = True, descent_settled: bool = True) -> RigFit:
    """The whole-record fit ``last`` (its x0 the estimate; its last solve ``solved``: problem,
    fresh Jacobian or None, weights; ``descent_settled``: that solve's ``settled``, :func:`solve`) checked by restarts
    (``check``: False where a channel is beyond :data:`REWEIGHT_LIMIT` of its noise, the motion not
    found), polished, its covariance and levels: the :class:`RigFit`."""
    rec, prior, lay, noise_scale = last.rec, last.prior, last.lay, last.weight_scale
    x = last.x0
    n_all = last.n
    channels = len(rec.channels)
    J, runs = _jacobian_at_x0(last, *solved)
    r = last.residual(np.zeros(last.lay.size))
    nfev += runs + 1
    minima = [(0.5 * float(r @ r), last.at_x0, descent_settled)]
    given = list(np.asarray(restarts, float).reshape(-1, 6)) + along_valleys(last, J, x[lay.inertia])
    others = [t for t in given if physically_consistent(to_tensor(t))]
    tried = [shifted(x[lay.inertia], 1.0), shifted(x[lay.inertia], -1.0)] + others if check else []
    gain = gauss_newton_gain(J)
    with ThreadPoolExecutor(THREADS) as pool:         # independent solves from one estimate: the cores share them
        for x2, cost2, runs, ended in pool.map(lambda t: restarted(last, (J, r), gain, t), tried):
            nfev += runs
            minima.append((cost2, last.point(x2), ended))
    minima_costs = [m[0] for m in minima]
    descent = minima[0][1].x[lay.inertia]
    minima.sort(key=lambda m: m[0])
    cost, at, _ = minima[0]
    x = at.x
    settled = np.array([m[1].x[lay.inertia] for m in minima[1:]]).reshape(-1, 6)
    other_chi2 = np.array([2 * (m[0] - cost) for m in minima[1:]])
    other_settled = np.array([m[2] for m in minima[1:]], bool)
    log.info("rig fit: the other minima settled %s from the estimate, χ² %s", np.round(settled - x[lay.inertia], 3),
             np.round(other_chi2, 2))
    if cost != minima_costs[0]:           # a restart settled lower: the estimate's problem and Jacobian
        moved = RigProblem(rec, at, lay, prior, noise_scale, n_all)
        J, runs = jacobian_near(last, moved, J)
        gain = gauss_newton_gain(J)
        last = moved
        r = last.residual(np.zeros(last.lay.size))
        nfev += runs + 1
    z, runs = polished(last, gain, r)
    at = last.point(last.x(z)) if np.any(z) else last.at_x0
    x, p, rest, bases = at.x, at.parameters, at.rest, at.bases
    nfev += runs
    fisher, sandwich, bound = covariance(last, J, last.row_scale(noise_scale))
    cov = larger_of(fisher, sandwich)
    unit = RigProblem(rec, at, lay, prior, np.ones(channels), n_all)
    outputs = unit.outputs(x)             # one model run for the levels and the plotted series
    level = levels(unit, x, outputs)
    offsets, offset_std = channel_offsets(rec.y[rec.start:rec.start + n_all] - np.concatenate(outputs))
    freqs = natural_frequencies(linearise(p, rest))
    return RigFit(p, x[lay.initial], cov, np.sqrt(np.diag(bound)[lay.inertia]), level, noise_scale, rec.channels,
                  freqs, last.lay, nfev, settled, other_chi2, unit.fitted(x, outputs), descent, x, bases, rest,
                  offsets, J, offset_std, other_settled)




def fitted_force(rec: Record, prior: Prior, fit: RigFit) -> np.ndarray:
    """(m, 2) N, exciter frame: the exciter's force on the body over the fit's span as ``fit``
    (made from ``rec`` and ``prior``) infers it — the denoised readings with the fit's correction
    (:meth:`~.rig_problem.RigProblem.force`), which takes in what the exciter's load cells read
    beside it (a rotor's own inertial force, which its bearing passes).  Raises ValueError where
    the fit carries no estimate."""
    if fit.unknowns is None or fit.rest is None:
        raise ValueError("the fit carries no estimate")
    n = len(rec.y) - rec.start
    prob = RigProblem(rec, RigPoint(fit.unknowns, fit.parameters, fit.rest, fit.bases), fit.layout, prior,
                      fit.noise_scale, n)
    return prob.force(prob.x0)


def channel_offsets(residual: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each channel's offset the fit eliminates and its σ: ``residual`` (m, n_out) reading − model
    over the fit's span (channel units).  The offset is the residual's mean; its σ the scatter of
    the means of :data:`SANDWICH_BLOCKS` consecutive blocks over √blocks (Student's t with
    blocks − 1 degrees of freedom), so a slow misfit or a drift widens it where the white noise's
    σ/√m would not (the batch-means estimate of a mean's variance: Law & Kelton, *Simulation
    Modeling and Analysis*, 3rd ed., §9.5.3).  Returns (offsets (n_out,), σ (n_out,))."""
    means = np.array([b.mean(axis=0) for b in np.array_split(residual, SANDWICH_BLOCKS)])
    return residual.mean(axis=0), means.std(axis=0, ddof=1) / np.sqrt(SANDWICH_BLOCKS)


def cramer_rao(rec: Record, rig: Rig, prior: Prior, truth: RigParameters) -> np.ndarray:
    """The bound (size, size) on the unknowns (:class:`Layout` order) for the recording's input
    and noise levels at the true parameters ``truth``: the inverse Fisher information of the
    weighted residual (Gaussian white noise per channel, in the fit's band), the priors of
    ``prior``, the initial state at the fit's start free."""
    with sequential_blas():
        lay = Layout(len(rig.cables), rec.force_unknowns())
        x = vector(truth, np.zeros(12), lay)
        rest = rest_pose(truth)
        prob = RigProblem(rec, RigPoint(x, truth, rest), lay, prior, np.ones(len(rec.channels)), len(rec.y) - rec.start)
        return covariance(prob, prob.jacobian(np.zeros(prob.lay.size)))[0]
