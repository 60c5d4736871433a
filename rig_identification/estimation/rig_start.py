"""Where the rig model's fit starts: its parameters before any dynamics are fitted.

rig.yaml's geometry, the prior's mass, CG and cable stiffness (:class:`~.rig_unknowns.Prior`),
and, from the recording, the unstretched lengths and the CG's position that the measured mean
tensions imply (:func:`start_geometry`).  A hanging rig with more than three nearly vertical
cables is statically indeterminate: a cable length off by a survey's millimetre moves
kilonewtons between the cables (k ≈ 5·10⁶ N/m), and a fit that starts there can meet a slack
cable or start far from the recording.  The mean tensions pin each length to their σ over k
(~1 µm at a load cell's 0.1 % gain class).  The fit's priors stay centred on rig.yaml's survey:
only its start moves.
"""
from __future__ import annotations

import logging

import numpy as np
from scipy.optimize import least_squares

from ..io.rig import Rig
from ..model.cables import DEFAULT_DAMPING_RATIO
from ..model.linear_rig import RestPose, RigParameters, rest_pose
from ..model.rigid_body import SimulationError
from .rig_record import Record, RigFitError
from .rig_unknowns import Prior

log = logging.getLogger(__name__)

#: σ of a mean tension as a share of it where rig.yaml's survey states exact load-cell gains
#: (a load cell's zero: ~0.5 N of 5 kN).
MEAN_TENSION_SHARE = 1e-4
#: The CG coordinates without a prior σ move in steps of this scale, m (x and y only: the
#: tensions do not see the CG's height on a level body).
FREE_CG_SCALE = 1e-3
#: The unit of the tensions' common scale in the least squares (no prior: free).
SCALE_UNIT = 1e-3
#: The residual's every row where a trial geometry has no rest pose.
OUTSIDE = 1e6


def start_parameters(rig: Rig, prior: Prior, inertia0: np.ndarray, rec: Record | None = None,
                     damping_time: float | None = None, stiffness: np.ndarray | None = None
                     ) -> tuple[RigParameters, RestPose]:
    """The parameters a fit starts from and their rest pose: rig.yaml's geometry, the prior's
    mass and CG, the cables' ``stiffness`` (N,) N/m (default the prior's centre), the tensor
    entries ``inertia0`` (6,) kg·m² about the CG, τ ``damping_time`` s (default the default
    cable's, 2 ζ sqrt(m / (N k)) with that stiffness); with ``rec`` the lengths and CG its mean
    tensions imply (:func:`start_geometry`: where rig.yaml's geometry leaves a cable slack, from the
    linear springs' equilibrium there).  Raises :class:`~.rig_record.RigFitError` when the rig as
    described has no rest pose and the mean tensions give none either."""
    n = len(rig.cables)
    k = prior.stiffness if stiffness is None else np.broadcast_to(np.asarray(stiffness, float), (n,))
    tau = default_damping_time(prior.mass, k) if damping_time is None else damping_time
    start = RigParameters.from_rig(rig, np.zeros(6), k, tau, prior.mass, prior.cg)
    surveyed = start.length
    tensions = None if rec is None else rec.y[rec.start:, :n].mean(axis=0)
    slack: SimulationError | None = None
    try:
        rest = rest_pose(start)
    except SimulationError as e:
        if tensions is None or not np.all(tensions > 0):
            raise RigFitError(f"{rig.source}: the rig as described has no rest pose ({e})") from None
        try:
            rest = rest_pose(start, taut=False)
        except SimulationError as e2:
            raise RigFitError(f"{rig.source}: the rig as described has no rest pose ({e}; {e2})") from None
        slack = e
        log.info("rig fit: rig.yaml's geometry has no rest pose (%s): the lengths start from the mean tensions", e)
    if tensions is not None:
        start, rest = start_geometry(start, rest, tensions, prior, surveyed)
    if rest.tensions.min() <= 0:
        raise RigFitError(f"{rig.source}: the rig as described has no rest pose ({slack}), nor with the lengths its "
                          f"mean tensions imply ({np.round(np.asarray(tensions, float), 1)} N)")
    return start.replace(inertia=np.asarray(inertia0, float)), rest


def default_damping_time(mass: float, stiffness: np.ndarray) -> float:
    """τ, s, of the default cable's damping for a body of ``mass`` kg on cables of ``stiffness``
    (N,) N/m: 2 ζ sqrt(m / (N k̄)), ζ :data:`~rig_identification.model.cables.DEFAULT_DAMPING_RATIO`."""
    return float(2 * DEFAULT_DAMPING_RATIO * np.sqrt(mass / (len(stiffness) * np.mean(stiffness))))


def carried_to(p: RigParameters, rest: RestPose, stiffness: np.ndarray, surveyed: np.ndarray
               ) -> tuple[RigParameters, RestPose]:
    """``p`` (:func:`start_geometry`'s at its stiffness) carried to cables of ``stiffness`` (N,)
    N/m without a new search, and its rest pose: each unstretched length moved by
    T (1/k − 1/k') so that the cable keeps its tension at ``rest``'s stretched length, then every
    length moved by their mean offset from ``surveyed`` (N,) m (the survey's prior holds their
    common part: on softer cables the body hangs lower, the tensions' shares alike), the rest
    pose found by Newton from ``rest``; τ the default cable's (:func:`default_damping_time`).
    Raises :class:`~rig_identification.model.rigid_body.SimulationError` where it has no rest pose."""
    k = np.asarray(stiffness, float)
    length = p.length + rest.tensions * (1.0 / p.stiffness - 1.0 / k)
    q = p.replace(stiffness=k, length=length + np.mean(surveyed - length), damping_time=default_damping_time(p.mass, k))
    return q, rest_pose(q, rest)


def start_geometry(p: RigParameters, rest: RestPose, tensions: np.ndarray, prior: Prior,
                   surveyed: np.ndarray | None = None) -> tuple[RigParameters, RestPose]:
    """``p`` with the cable lengths and CG that best explain the measured mean ``tensions``
    (N,) N at rest, and its rest pose: the maximum a posteriori estimate under the prior's survey
    σ of the lengths about ``surveyed`` (N,) m (default ``p``'s) and σ of the CG about ``p``'s
    (x and y without a σ move freely, z stays), each tension
    weighted by its gain's σ (rig.yaml ``survey.load_cell_gain``, at least
    :data:`MEAN_TENSION_SHARE`), their common scale free (the gains' common part against the
    mass).  The rest tensions are the linear springs' static equilibrium (thesis eqs. 2.20–2.25
    with springs, :func:`~rig_identification.model.linear_rig.rest_pose` with ``taut=False``): a
    trial that slackens a cable gives it a negative tension, so the search moves through it, and
    ``p`` and ``rest`` may be such a pose (rig.yaml's geometry with a cable slack by a survey's
    millimetres: bench_any_rig 21135, 1.6 mm on a 5-cable rig).  Where the geometry found has no
    rest pose with every cable taut, ``p`` and ``rest`` come back unchanged and the log says so."""
    n = p.cables
    T = np.asarray(tensions, float)
    if T.shape != (n,) or not np.all(np.isfinite(T)) or np.any(T <= 0):
        log.info("rig fit: start geometry from rig.yaml (mean tensions not all positive: %s N)", np.round(T, 1))
        return p, rest
    sigma_t = max(prior.gain_std, MEAN_TENSION_SHARE) * T
    has_prior = np.isfinite(prior.cg_std)
    moves = has_prior | (np.arange(3) < 2)
    cg_scale = np.where(has_prior, prior.cg_std, FREE_CG_SCALE)[moves]
    length_std = prior.survey.lengths
    offset = np.zeros(n) if surveyed is None or length_std == 0 else (p.length - surveyed) / length_std

    def trial(v: np.ndarray) -> RigParameters:
        cg = p.cg.copy()
        cg[moves] += cg_scale * v[n:-1]
        return p.replace(length=p.length + length_std * v[:n], cg=cg)

    def residual(v: np.ndarray) -> np.ndarray:
        try:
            at = rest_pose(trial(v), rest, taut=False)
        except SimulationError:
            return np.full(2 * n + int(has_prior.sum()), OUTSIDE)
        return np.concatenate([(at.tensions - (1.0 + SCALE_UNIT * v[-1]) * T) / sigma_t, v[:n] + offset,
                               v[n:-1][has_prior[moves]]])

    before = float(np.abs(rest.tensions - T * rest.tensions.sum() / T.sum()).max())
    sol = least_squares(residual, np.zeros(n + int(moves.sum()) + 1), method="trf", diff_step=1e-4)
    q = trial(sol.x)
    try:
        at = rest_pose(q, rest)
    except SimulationError as e:
        log.info("rig fit: start geometry from rig.yaml (the tensions' lengths have no rest pose: %s)", e)
        return p, rest
    log.info("rig fit: start lengths from the mean tensions: moved %s mm, the CG %s mm; the tensions "
             "%.3g N from the measured at most (rig.yaml's: %.3g N)", np.round(1e3 * (q.length - p.length), 2),
             np.round(1e3 * (q.cg - p.cg), 2), np.abs(at.tensions - (1.0 + SCALE_UNIT * sol.x[-1]) * T).max(),
             before)
    return q, at


__all__ = ["FREE_CG_SCALE", "MEAN_TENSION_SHARE", "SCALE_UNIT", "carried_to", "default_damping_time", "start_geometry",
           "start_parameters"]
