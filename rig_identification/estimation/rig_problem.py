"""The rig model's weighted residual over a span of a record, as a function of the scaled unknowns:
:class:`RigProblem` (segments, their states settled, the force's correction, the Jacobian by
forward differences with each segment's state column filtered over its reach), what
:func:`~rig_identification.estimation.rig_fit.fit_rig` minimises; and that Jacobian reused by the
solve while it predicts the steps (:class:`ReusedJacobian`, Broyden's rank-one update).
"""
from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.linalg import solve_triangular
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ..model.linear_rig import RestPose, RigParameters, linearise, natural_frequencies, rest_pose
from ..model.parametrisation import physically_consistent, to_tensor
from ..model.rig_ode import (
    Drive,
    drive,
    exciter_readings,
    moved_state,
    rest_state,
    simulate,
    substeps_for,
    with_sensor_traits,
)
from ..model.rigid_body import SimulationError
from .rig_record import ChannelSeries, Record
from .rig_unknowns import Layout, Prior, body_unknowns, parameters_of, priors, relayout, unit_scale

log = logging.getLogger(__name__)

#: The residuals a :class:`CompressedResidual` keeps, the last evaluated (the trust region's rejected
#: steps between two accepted points are evaluated too).
KEPT_RESIDUALS = 32
#: A solve hands the trust region its residual compressed onto the Jacobian's columns
#: (:class:`CompressedResidual`) where it has more than this many rows per unknown.
COMPRESS_ROWS = 4
#: The decimated residual's rate over the fit's band edge (:func:`~.rig_record.band_edge`).
DECIMATED_RATE = 3.0
#: Threads that compute the Jacobian's columns (the machine's cores, at most 4).
THREADS = max(1, min(4, os.cpu_count() or 1))


def sequential_blas() -> threadpool_limits:
    """A context (``with sequential_blas(): ...``) in which BLAS, numpy's and scipy's linear
    algebra, runs on one thread, its setting before restored on leaving: a fit's own
    :data:`THREADS` threads take the cores with the model's runs, and BLAS's threads, spinning
    between calls, took the cores back from them (docs/results.md#speed).  Each fit of the rig model
    (:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`, the joint fit, the
    Cramér–Rao bound) runs in one; they nest."""
    return threadpool_limits(limits=1, user_api="blas")

#: Stopping rules of each least-squares solve (scipy.optimize.least_squares): its iterations
#: at most, and the tolerances on the step, the cost's change and the gradient.
MAX_ITERATIONS = 100
XTOL, FTOL, GTOL = 1e-10, 1e-10, 1e-10
#: The residual's every row outside the physical region or where the model diverges.
OUTSIDE = 1e6
#: Forward-difference step of the Jacobian in the unknowns' units of :func:`unit_scale`: at 1e-2 its
#: error (half the step times the curvature) turned the small gradient along the mass–moments
#: valley and the trust region stopped 9 σ short (case-16 rig); the model is smooth and
#: deterministic, so rounding stays ~1e-8 of a column at 1e-4.
JACOBIAN_STEP = 1e-4
#: A segment's change is filtered over the samples where the filter's response to an impulse
#: exceeds this share of its peak (:meth:`RigProblem.segment_change`).
IMPULSE_TAIL = 1e-12
#: Gauss–Newton steps that settle a segment's initial state alone (:meth:`RigProblem._settle_segments`), at
#: most, and the fall of the cost (½ χ²) below which they stop.
SETTLE_STEPS = 6
SETTLE_DECREMENT = 0.01
#: Extensions (:data:`~.rig_unknowns.EXTENSIONS`) whose unknowns are never negative: a damping.
NON_NEGATIVE = ("air_drag", "pivot_friction")


@dataclass(frozen=True)
class RigPoint:
    """The point a :class:`RigProblem` is made at: the unknowns ``x`` (any segment count:
    :func:`~.rig_unknowns.relayout`), the ``parameters`` they fill (:func:`~.rig_unknowns.parameters_of`:
    what the unknowns leave fixed), the ``rest`` pose (it sets the integrator's step and moves the
    segments' states with the parameters) and ``bases`` (k, 13), the segments' states before
    their unknowns (:meth:`RigProblem.bases_at`; None: from rest through the spin-up)."""

    x: np.ndarray
    parameters: RigParameters
    rest: RestPose
    bases: np.ndarray | None = None


class RigProblem:
    """The weighted residual of ``n`` samples from the record's ``start`` as a function of the
    scaled unknowns z (x = x0 + scale z, x0 the point ``at``'s :class:`RigPoint`): the span cut into
    segments (:data:`~.rig_unknowns.SEGMENT`), each run from its own state, ``bases[k]`` moved by
    segment k's initial-state unknowns.  The point's ``bases``: (k, 13) the segments' states as a
    previous problem had them (:meth:`bases_at`): with k this span's segment count and its ``x`` of
    this layout's size, taken as they are; otherwise the first is taken and the later ones are the
    model's continuation at x0 from it; None: the first is the model's run from rest through the
    spin-up (:func:`base_state`).  ``noise_scale`` (n_out,): each channel's noise over the record's."""

    def __init__(self, rec: Record, at: RigPoint, lay: Layout, prior: Prior, noise_scale: np.ndarray, n: int):
        like, x0, rest, bases = at.parameters, at.x, at.rest, at.bases
        self.rec, self.like, self.n, self.prior = rec, like, n, prior
        self.lay = lay.for_span(n, rec.dt)
        self.x0 = relayout(x0, self.lay)
        self.scale = unit_scale(self.x0, self.lay, prior)
        self.centre, self.prior_std = priors(prior, self.lay, self.x0)
        self.sos = butter(4, rec.band, fs=1.0 / rec.dt, output="sos")
        self.step = max(1, int(1.0 / (DECIMATED_RATE * rec.band * rec.dt)))
        impulse = np.zeros(4001)
        mid = len(impulse) // 2
        impulse[mid] = 1.0
        # a decimated sample stands for the `step` grid samples around it (weighting it as an
        # independent sample of the filtered noise overstates an in-band signal's information
        # ~1.8×); `unit`: the RMS of a weighted residual of noise alone.
        response = sosfiltfilt(self.sos, impulse)
        self.unit = float(np.sqrt(self.step * np.sum(response ** 2)))
        # samples beyond which the filter's response to a change is below rounding (:meth:`segment_change`)
        tail = np.flatnonzero(np.abs(response) > IMPULSE_TAIL * np.abs(response).max())
        self.reach = int(max(tail.max() - mid, mid - tail.min())) + 1 if 0 < tail.min() and tail.max() < 2 * mid \
            else n
        self.weight = np.sqrt(self.step) / (rec.sigma * noise_scale * np.sqrt(rec.oversampling))
        self.weight_scale = np.asarray(noise_scale, float).copy()
        self.rest = rest
        self.ref = rest_state(parameters_of(self.x0, like, self.lay), rest)
        self._rest_cache: dict[bytes, tuple[np.ndarray, Rotation]] = {}
        self._rest_lock = threading.Lock()
        self._drives: dict[tuple[int, int, bytes], Drive] = {}
        self._forces: dict[bytes, np.ndarray] = {}
        lin = linearise(parameters_of(self.x0, like, self.lay), rest)
        self.substeps = substeps_for(2 * np.pi * natural_frequencies(lin).max(), rec.dt)
        self.basis = rec.force_basis()[:n] if self.lay.n_force else np.zeros((n, 0))
        z = rec.u[rec.start:rec.start + n, 0] + 1j * rec.u[rec.start:rec.start + n, 1]
        # each harmonic's correction turns k + 1 times per revolution of the force, scaled by its amplitude
        self.turns = [np.abs(z) * np.exp(1j * (h + 1) * np.angle(z)) for h in rec.force_harmonics] \
            if self.lay.n_force else []
        self.edges = np.linspace(0, n, self.lay.n_segments + 1).round().astype(int)
        if bases is not None and len(bases) == self.lay.n_segments and len(x0) == self.lay.size:
            self.bases = bases
        else:
            self.x0 = self.x0.copy()
            self.x0[self.lay.segments] = 0.0
            start = parameters_of(self.x0, like, self.lay)
            first = base_state(rec, start, rest, self.substeps) if bases is None else bases[0]
            self.bases = self._continued(first)
            self._settle_segments()

    def _continued(self, base: np.ndarray) -> np.ndarray:
        """(n_segments, 13) each segment's state on the model's run at x0 from ``base`` (moved by
        the first segment's unknowns), the later segments' unknowns zero."""
        bases = [np.asarray(base, float)]
        if self.lay.n_segments == 1:
            return np.array(bases)
        x = self.x0
        p = parameters_of(x, self.like, self.lay)
        u = self.force(x)
        y = moved_state(bases[0], x[self.lay.initial])
        for a, b in zip(self.edges[1:-1], self.edges[2:]):
            y = simulate(p, y, self.drive(x, u, self.edges[len(bases) - 1], a + 1))[1]
            bases.append(y)
        return np.array(bases)

    def _settle_segments(self) -> None:
        """Each later segment's initial state fitted alone to its own samples (the parameters
        at x0): the model's continuation carries the phase error of x0's mode frequencies into
        every later segment, and the response is nearly linear in the state (Ljung 1999, §7.3):
        Gauss–Newton steps with the Jacobian at x0 (the chord method), at most
        :data:`SETTLE_STEPS`, each taken where it lowers the cost, until one gains less than
        :data:`SETTLE_DECREMENT`.  The whole fit refines these states with every other unknown."""
        u = self.force(self.x0)
        a = self.rec.start

        def settle(k: int) -> np.ndarray:
            b, c = self.edges[k], self.edges[k + 1]
            part = self.lay.state(k)

            def residual(zk: np.ndarray) -> np.ndarray:
                x = self.x0.copy()
                x[part] += self.scale[part] * zk
                try:
                    e = self.rec.y[a + b:a + c] - self.segment_outputs(x, k, u)
                except (SimulationError, ValueError, np.linalg.LinAlgError):
                    return np.full((len(range(0, c - b, self.step)) * len(self.rec.channels)), OUTSIDE)
                return self.weighted(e).ravel()

            r = residual(np.zeros(12))
            if r[0] == OUTSIDE:
                return np.zeros(12)
            J = np.column_stack([(residual(JACOBIAN_STEP * e) - r) / JACOBIAN_STEP for e in np.eye(12)])
            z = np.zeros(12)
            for _ in range(SETTLE_STEPS):          # Gauss–Newton with the first Jacobian (the chord method)
                step = np.linalg.lstsq(J, -r, rcond=None)[0]
                r1 = residual(z + step)
                fall = r @ r - r1 @ r1
                if not fall > 0:
                    break
                z, r = z + step, r1
                if fall < 2 * SETTLE_DECREMENT:
                    break
            move: np.ndarray = self.scale[part] * z
            return move

        with ThreadPoolExecutor(THREADS) as pool:     # each segment's state alone: independent solves
            moves = list(pool.map(settle, range(1, self.lay.n_segments)))
        for k, move in enumerate(moves, 1):
            self.x0[self.lay.state(k)] += move

    @property
    def at_x0(self) -> RigPoint:
        """The point the problem holds: its x0, parameters, rest pose and segments' states."""
        return RigPoint(self.x0, self.like, self.rest, self.bases)

    def point(self, x: np.ndarray) -> RigPoint:
        """The point at the unknowns ``x`` (this layout): their parameters, the rest pose there
        (searched from this problem's; where there is none, this problem's serves: it sets only the
        integrator's step) and the segments' states moved there (:meth:`bases_at`)."""
        p = parameters_of(x, self.like, self.lay)
        rest = self.rest
        try:
            rest = rest_pose(p, rest)
        except SimulationError as e:
            log.info("rig fit: no rest pose at the estimate (%s)", e)
        return RigPoint(x, p, rest, self.bases_at(x))

    def x(self, z: np.ndarray) -> np.ndarray:
        x = self.x0.copy()
        x[:len(z)] += self.scale[:len(z)] * z
        return x

    def force(self, x: np.ndarray) -> np.ndarray:
        """(n, 2) N the exciter force over the span: the denoised one z times (1 + a(t)) e^{iφ(t)},
        plus |z| c_k(t) (z/|z|)^(k+1) for each of the record's co-rotating harmonics k
        (:attr:`~.rig_record.Record.force_harmonics`); a, φ and each complex c_k the B-splines of the
        unknowns ``force`` (:class:`Layout`)."""
        a = self.rec.start
        u = self.rec.u[a:a + self.n]
        if not self.lay.n_force:
            return u
        c = x[self.lay.force]
        key = c.tobytes()
        cached = self._forces.get(key)
        if cached is not None:
            return cached
        k = self.basis.shape[1]
        z = u[:, 0] + 1j * u[:, 1]
        out = z * (1.0 + self.basis @ c[:k]) * np.exp(1j * (self.basis @ c[k:2 * k]))
        for j, turn in enumerate(self.turns):
            first = 2 * k * (1 + j)
            out = out + turn * (self.basis @ c[first:first + k] + 1j * (self.basis @ c[first + k:first + 2 * k]))
        force = np.column_stack([out.real, out.imag])
        force.flags.writeable = False
        if len(self._forces) > 2 * THREADS:       # x0's and the columns' on the threads at once
            self._forces.clear()
        self._forces[key] = force
        return force

    def drive(self, x: np.ndarray, u: np.ndarray, a: int, b: int) -> Drive:
        """The force ``u`` (:meth:`force` at ``x``, as read) over the span's samples a to b as the
        model takes it — read ``exciter_delay`` s later where the layout holds that extension (a
        cubic spline through the span's samples, extrapolated at its end) — kept while the force's
        unknowns stay (a Jacobian's other columns)."""
        lag = float(x[self.lay.extension_of("exciter_delay")][0]) if "exciter_delay" in self.lay.extensions else 0.0
        key = (a, b, x[self.lay.force].tobytes() + np.float64(lag).tobytes())
        d = self._drives.get(key)
        if d is None:
            if len(self._drives) > 4 * self.lay.n_segments:
                self._drives.clear()
            if lag:
                t = np.arange(len(u))
                u = CubicSpline(t, u, axis=0, extrapolate=True)(t + lag / self.rec.dt)
            d = self._drives[key] = drive(u[a:b], self.rec.dt, self.substeps)
        return d

    def segment_outputs(self, x: np.ndarray, k: int, u: np.ndarray | None = None) -> np.ndarray:
        """(samples, n_out) the model's readings over segment ``k`` (the exciter's last where its
        force is an output: :func:`~rig_identification.model.rig_ode.exciter_readings`); ``u``: the
        span's force at x (:meth:`force`) where already known."""
        p = parameters_of(x, self.like, self.lay)
        return self._run(x, p, self.force(x) if u is None else u, k, self.starts(x, p, [k])[0])

    def _run(self, x: np.ndarray, p: RigParameters, u: np.ndarray, k: int, y0: np.ndarray) -> np.ndarray:
        """Segment ``k``'s readings (:meth:`segment_outputs`) at ``x``, its parameters ``p``, force
        ``u`` and start ``y0`` (13,)."""
        a, b = self.edges[k], self.edges[k + 1]
        raw = simulate(p, y0, self.drive(x, u, a, b))[0]
        out = with_sensor_traits(raw, p, a * self.rec.dt, self.rec.dt)
        return np.column_stack([out, exciter_readings(raw, u[a:b], p, self.rec.dt)]) if self.lay.n_force else out

    def starts(self, x: np.ndarray, p: RigParameters, segments: Sequence[int]) -> np.ndarray:
        """(len(segments), 13) the states the ``segments`` run from at the unknowns ``x`` (``p``
        their parameters): each one's base moved with the rest pose (:meth:`_rebased`) and by its
        initial-state unknowns (:func:`~rig_identification.model.rig_ode.moved_state`)."""
        which = list(segments)
        offsets = np.array([x[self.lay.state(k)] for k in which])
        moved: np.ndarray = moved_state(self._rebased(p, self.bases[which]), offsets)
        return moved

    def _rebased(self, p: RigParameters, bases: np.ndarray) -> np.ndarray:
        """``bases`` (k, 13) moved with the rest pose: each one's offset from the rest state at x0
        put on the rest state of ``p`` (a shifted geometry or CG moves the start with it, so the
        fit need not cancel the two against each other: each channel's offset is projected out, and
        the rest pose itself is not what the data see).  Raises
        :class:`~rig_identification.model.rigid_body.SimulationError` where ``p`` has no rest pose."""
        key = p.ceiling.tobytes() + p.body.tobytes() + p.length.tobytes() + p.cg.tobytes() + p.stiffness.tobytes() \
            + np.float64(p.mass).tobytes()
        with self._rest_lock:           # the least recently used goes first
            cached = self._rest_cache.pop(key, None)
            if cached is not None:
                self._rest_cache[key] = cached
        if cached is None:
            ref = rest_state(p, rest_pose(p, self.rest))
            turn = Rotation.from_quat(ref[[4, 5, 6, 3]]) * Rotation.from_quat(self.ref[[4, 5, 6, 3]]).inv()
            cached = (ref, turn)
            with self._rest_lock:       # the Jacobian's columns on the threads at once, and x0's
                self._rest_cache[key] = cached
                while len(self._rest_cache) > 2 * THREADS + 1:
                    del self._rest_cache[next(iter(self._rest_cache))]
        ref, turn = cached
        q = (turn * Rotation.from_quat(bases[:, [4, 5, 6, 3]])).as_quat()
        return np.column_stack([bases[:, :3] - self.ref[:3] + ref[:3], q[:, [3, 0, 1, 2]], bases[:, 7:]])

    def bases_at(self, x: np.ndarray) -> np.ndarray:
        """(n_segments, 13) the segments' states before their unknowns, moved with the rest pose
        to the parameters of ``x``: what a problem made at ``x`` takes as ``bases``."""
        return self._rebased(parameters_of(x, self.like, self.lay), self.bases)

    def outputs(self, x: np.ndarray) -> list[np.ndarray]:
        """The model's readings over the span, segment by segment ((samples, n_out) each)."""
        p = parameters_of(x, self.like, self.lay)
        u = self.force(x)
        starts = self.starts(x, p, range(self.lay.n_segments))
        return [self._run(x, p, u, k, starts[k]) for k in range(self.lay.n_segments)]

    def data_residual(self, x: np.ndarray, outputs: list[np.ndarray] | None = None) -> np.ndarray:
        """(m, n_out) weighted, low-passed and decimated to the band, each channel's offset
        projected out; ``outputs``: :meth:`outputs` at x where already known."""
        a = self.rec.start
        return self.weighted(self.rec.y[a:a + self.n] - np.concatenate(self.outputs(x) if outputs is None else outputs))

    def fitted(self, x: np.ndarray, outputs: list[np.ndarray] | None = None) -> ChannelSeries:
        """The measured and the model's readings at ``x`` over the span as the fit compares them
        (low-passed and decimated to the band), each channel's offset put on the measured one's;
        ``outputs``: :meth:`outputs` at x where already known."""
        a = self.rec.start
        measured = self.rec.y[a:a + self.n]
        predicted = np.concatenate(self.outputs(x) if outputs is None else outputs)
        predicted = predicted - predicted.mean(axis=0) + measured.mean(axis=0)
        low = [sosfiltfilt(self.sos, v - v.mean(axis=0), axis=0)[::self.step] + v.mean(axis=0)
               for v in (measured, predicted)]
        t = self.rec.dt * np.arange(a, a + self.n)[::self.step]
        return ChannelSeries(t, low[0], low[1], self.rec.channels)

    def weighted(self, e: np.ndarray) -> np.ndarray:
        """(m, n_out) the data-minus-model ``e`` (samples, n_out) with each channel's offset
        projected out, low-passed, decimated to the band and weighted by its noise."""
        filtered: np.ndarray = sosfiltfilt(self.sos, e - e.mean(axis=0), axis=0)[::self.step] * self.weight
        return filtered

    def residual(self, z: np.ndarray, outputs: list[np.ndarray] | None = None) -> np.ndarray:
        """The weighted residual (data rows, then the priors' rows); outside the physical
        region (a tensor no body has, a negative damping time or drag) or where the model's motion
        diverges, a constant large residual, which the trust region steps back from."""
        x = self.x(z)
        outside = np.full(self.size(len(z)), OUTSIDE)
        if not physically_consistent(to_tensor(x[self.lay.inertia])) or x[self.lay.damping] < 0 \
                or any(np.any(x[self.lay.extension_of(e)] < 0) for e in NON_NEGATIVE if e in self.lay.extensions):
            return outside
        try:
            r = self.data_residual(x, outputs).ravel()
        except (SimulationError, ValueError, np.linalg.LinAlgError):
            return outside
        if not np.all(np.isfinite(r)):
            return outside
        return np.concatenate([r, self.prior_rows(z)])

    def prior_rows(self, z: np.ndarray) -> np.ndarray:
        """The priors' rows of :meth:`residual`: each unknown with a prior off its centre in its σ.
        The mass's and the CG's priors (the scale's, the static test's) are the body's: where the
        layout holds the exciter rotor's mass, the suspended body's less the rotor on its axis
        (:func:`~.rig_unknowns.body_unknowns`)."""
        x = body_unknowns(self.x(z), self.lay, self.like.exciter_position)
        std = self.prior_std[:len(z)]
        finite = np.isfinite(std)
        rows: np.ndarray = (x[:len(z)][finite] - self.centre[:len(z)][finite]) / std[finite]
        return rows

    def segment_change(self, change: np.ndarray, k: int) -> np.ndarray:
        """(data_rows,) the change of :meth:`residual`'s data rows when the model's readings over
        segment ``k`` change by ``change`` (samples, n_out) and nowhere else: :meth:`weighted` is
        linear, so the change is the weighted change filtered over the segment and the filter's
        reach either side (exact to :data:`IMPULSE_TAIL`), less its mean over the span."""
        b, c = self.edges[k], self.edges[k + 1]
        lo = max(0, b - self.reach) // self.step * self.step
        hi = min(self.n, c + self.reach)
        d = np.zeros((hi - lo, change.shape[1]))
        d[b - lo:c - lo] = change
        rows = np.tile(change.sum(axis=0) / self.n, (len(range(0, self.n, self.step)), 1))
        first = lo // self.step
        local = sosfiltfilt(self.sos, d, axis=0)[::self.step]
        rows[first:first + len(local)] -= local
        out: np.ndarray = (rows * self.weight).ravel()
        return out

    @property
    def data_rows(self) -> int:
        return len(range(0, self.n, self.step)) * len(self.rec.channels)

    @property
    def seconds(self) -> float:
        """The span's length, s."""
        return self.n * self.rec.dt

    def score_edges(self, blocks: int) -> np.ndarray:
        """(blocks + 1,) the data rows' edges of ``blocks`` consecutive blocks of the span, each
        of whole decimated samples (every channel's row of a sample in one block)."""
        per_sample = len(self.rec.channels)
        edges: np.ndarray = np.linspace(0, self.data_rows // per_sample, blocks + 1).astype(int) * per_sample
        return edges

    def row_scale(self, noise_scale: np.ndarray) -> np.ndarray:
        """(data_rows,) each data row's factor of ``noise_scale`` (n_out,), one per channel."""
        return np.tile(np.asarray(noise_scale, float), self.data_rows // len(self.rec.channels))

    def noise_cost(self, nz: int) -> float:
        """The sum of squares of :meth:`residual` (``nz`` unknowns) expected of noise alone."""
        return self.data_rows * self.unit ** 2 + int(np.isfinite(self.prior_std[:nz]).sum())

    def size(self, nz: int) -> int:
        return self.data_rows + int(np.isfinite(self.prior_std[:nz]).sum())

    def owners(self) -> dict[int, tuple[int, ...]]:
        """The unknowns that move only some segments' runs, each with those segments: a segment's
        initial state its own, a B-spline coefficient of the force's correction those its
        support overlaps (each segment runs from its own state, its force a spline through its
        own samples)."""
        lay = self.lay
        out: dict[int, tuple[int, ...]] = {i: (k,) for k in range(lay.n_segments)
                                           for i in range(*lay.state(k).indices(lay.size))}
        K = self.basis.shape[1]
        for j in range(K):
            hit = tuple(k for k in range(lay.n_segments)
                        if np.any(self.basis[self.edges[k]:self.edges[k + 1], j] != 0.0))
            for block in range(lay.n_force // K):
                out[lay.force.start + block * K + j] = hit
        return out

    def jacobian(self, z: np.ndarray, columns: Sequence[int] | None = None) -> np.ndarray:
        """Forward differences (size, len(z)) of :meth:`residual` (step :data:`JACOBIAN_STEP`;
        backward where the step leaves the physical region, a zero column where both do),
        the columns on :data:`THREADS` threads (the compiled model releases the GIL); an unknown
        that moves only some segments' runs (:meth:`owners`) runs those alone again.
        ``columns``: only these unknowns' columns (size, len(columns)), in that order."""
        x = self.x(z)
        try:
            outs = self.outputs(x)
        except (SimulationError, ValueError, np.linalg.LinAlgError):
            outs = None
        base = self.residual(z, outs)
        owners = self.owners()
        u = self.force(x)

        def column(i: int) -> np.ndarray:
            e = z.copy()
            e[i] += JACOBIAN_STEP
            if outs is not None and i in owners and i < len(z) and base[0] != OUTSIDE:
                xe = self.x(e)
                ue = u if i not in range(*self.lay.force.indices(self.lay.size)) else self.force(xe)
                try:
                    rows = sum((self.segment_change(self.segment_outputs(xe, k, ue) - outs[k], k) for k in owners[i]),
                               np.zeros(self.data_rows))
                except (SimulationError, ValueError, np.linalg.LinAlgError):
                    pass
                else:
                    return np.concatenate([rows, self.prior_rows(e) - self.prior_rows(z)]) / JACOBIAN_STEP
            moved = self.residual(e)
            if moved[0] == OUTSIDE and base[0] != OUTSIDE:    # the step left the physical region: step back
                e[i] -= 2 * JACOBIAN_STEP
                back = self.residual(e)
                moved = base if back[0] == OUTSIDE else 2 * base - back    # neither: no information
            col: np.ndarray = (moved - base) / JACOBIAN_STEP
            return col

        with ThreadPoolExecutor(THREADS) as pool:
            return np.column_stack(list(pool.map(column, range(len(z)) if columns is None else columns)))


#: The unknowns the records of a joint fit share (:class:`JointProblem`): the first ten of every
#: :class:`~.rig_unknowns.Layout`, the tensor (6), the CG (3) and the mass.
BODY = 10


@dataclass(frozen=True)
class JointLayout:
    """Where the unknowns of a :class:`JointProblem` sit: the body's (:data:`BODY`: the tensor, the
    CG and the mass, as in every :class:`~.rig_unknowns.Layout`), then each record's others in turn."""

    size: int

    @property
    def inertia(self) -> slice:
        return slice(0, 6)

    @property
    def cg(self) -> slice:
        return slice(6, 9)

    @property
    def mass(self) -> int:
        return 9


class JointProblem:
    """The weighted residual of several records of one body as a function of the scaled unknowns
    z: each record's :class:`RigProblem` (its own rig, cables, load cells, geometry, segments and
    force correction), the body's unknowns (:data:`BODY`) shared.  The residual holds every
    record's data rows in turn, then every record's priors' rows; the body's priors (the scale's
    mass, the static CG) belong to one record's problem only (the caller's choice), so they count once.
    The records' problems must be made at the same body (their unit scales agree there).
    """

    def __init__(self, problems: Sequence[RigProblem]):
        self.problems = tuple(problems)
        first = self.problems[0]
        for p in self.problems[1:]:
            if not np.allclose(p.scale[:BODY], first.scale[:BODY]) or not np.allclose(p.x0[:BODY], first.x0[:BODY]):
                raise ValueError("a joint problem's records must be made at the same body")
        own = [p.lay.size - BODY for p in self.problems]
        self.starts = BODY + np.concatenate([[0], np.cumsum(own)[:-1]]).astype(int)
        self.lay = JointLayout(BODY + int(sum(own)))
        self.x0 = np.concatenate([first.x0[:BODY]] + [p.x0[BODY:] for p in self.problems])
        self.scale = np.concatenate([first.scale[:BODY]] + [p.scale[BODY:] for p in self.problems])
        self.data_rows = sum(p.data_rows for p in self.problems)
        self.seconds = sum(p.seconds for p in self.problems)

    def indices(self, k: int) -> np.ndarray:
        """(record k's layout size,) where each of record ``k``'s unknowns sits in the joint vector."""
        start = int(self.starts[k])
        return np.concatenate([np.arange(BODY), np.arange(start, start + self.problems[k].lay.size - BODY)])

    def part(self, v: np.ndarray, k: int) -> np.ndarray:
        """Record ``k``'s unknowns (its layout) out of the joint vector ``v`` (z or x)."""
        out: np.ndarray = v[self.indices(k)]
        return out

    def x(self, z: np.ndarray) -> np.ndarray:
        x: np.ndarray = self.x0 + self.scale * z
        return x

    def residual(self, z: np.ndarray) -> np.ndarray:
        """Every record's data rows, then every record's priors' rows (:meth:`RigProblem.residual`);
        all :data:`OUTSIDE` where any record's is."""
        parts = [p.residual(self.part(z, k)) for k, p in enumerate(self.problems)]
        if any(r[0] == OUTSIDE for r in parts):
            return np.full(sum(len(r) for r in parts), OUTSIDE)
        return np.concatenate([r[:p.data_rows] for r, p in zip(parts, self.problems)]
                              + [r[p.data_rows:] for r, p in zip(parts, self.problems)])

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """(rows, size) :meth:`residual`'s Jacobian: each record's (:meth:`RigProblem.jacobian`) in its
        rows and unknowns."""
        blocks = [p.jacobian(self.part(z, k)) for k, p in enumerate(self.problems)]
        rows = sum(len(b) for b in blocks)
        J = np.zeros((rows, self.lay.size))
        data, prior = 0, self.data_rows
        for k, (b, p) in enumerate(zip(blocks, self.problems)):
            cols = self.indices(k)
            J[data:data + p.data_rows, cols] = b[:p.data_rows]
            J[prior:prior + len(b) - p.data_rows, cols] = b[p.data_rows:]
            data += p.data_rows
            prior += len(b) - p.data_rows
        return J

    def score_edges(self, blocks: int) -> np.ndarray:
        """The data rows' edges of ``blocks`` blocks of each record in turn (:meth:`RigProblem.score_edges`)."""
        offsets = np.cumsum([0] + [p.data_rows for p in self.problems])
        return np.unique(np.concatenate([o + p.score_edges(blocks) for o, p in zip(offsets, self.problems)]))

    def row_scale(self, noise_scales: Sequence[np.ndarray]) -> np.ndarray:
        """(data_rows,) each data row's factor of its record's ``noise_scales`` (n_out,)
        (:meth:`RigProblem.row_scale`)."""
        return np.concatenate([p.row_scale(s) for p, s in zip(self.problems, noise_scales)])


def levels(prob: RigProblem, x: np.ndarray, outputs: list[np.ndarray] | None = None) -> np.ndarray:
    """Each channel's residual RMS in the band over its noise's (1: noise alone); ``outputs``:
    :meth:`RigProblem.outputs` at x where already known."""
    return np.asarray(np.sqrt(np.mean(prob.data_residual(x, outputs) ** 2, axis=0)) / prob.unit)


def base_state(rec: Record, p: RigParameters, rest: RestPose, substeps: int) -> np.ndarray:
    """The state at the fit's first sample: the model run from rest at the record's start
    through the spin-up (the rest state itself when the fit starts there)."""
    y = rest_state(p, rest)
    if rec.start == 0:
        return y
    return simulate(p, y, drive(rec.u[:rec.start + 1], rec.dt, substeps))[1]


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
        if np.array_equal(z, self.z):       # a solve resumed where the last Jacobian was made
            return self.J
        s = z - self.z
        r = self.last[1]
        self.J = self.J + np.outer(r - self.r - self.J @ s, s / (s @ s))
        self.z, self.r, self.fresh = z.copy(), r, False
        return self.J


class CompressedResidual:
    """The residual of a :class:`ReusedJacobian` as scipy's trust region takes it, its rows
    compressed onto the Jacobian's column space: f̃(z) = [Qᵀ r(z); (‖r‖² − ‖Qᵀ r‖²)^½] with
    Qᵀ = L⁻¹ J0ᵀ, J0 (rows, size) the Jacobian at the solve's start ``z0`` and L the Cholesky factor
    of J0ᵀJ0 (Q = J0 L⁻ᵀ spans J0's columns and is orthonormal in exact arithmetic: the
    semi-normal equations, Björck, *Numerical Methods for Least Squares Problems*, 1996, §2.2 and
    §6.6, without forming Q), and its Jacobian [Qᵀ J; (rᵀJ − (Qᵀr)ᵀ QᵀJ) / f̃_last].  ½‖f̃‖² = ½‖r‖²
    and J̃ᵀf̃ = Jᵀr hold whatever L's rounding (the terms in Q cancel), and J̃ᵀJ̃ = JᵀJ where the
    Jacobian's columns stay in J0's span (at the start; the Jacobians made later in the solve are
    near it), so the trust region takes the same steps while its SVD each iteration is of a
    (size + 1, size) matrix, not of a (rows, size) one.  A Jacobian of at most
    :data:`COMPRESS_ROWS` rows per column, or whose J0ᵀJ0 is not numerically positive definite (a
    column the residual does not see), is passed as it is.  ``full(z)`` gives the uncompressed
    residual at a point the solve evaluated."""

    def __init__(self, jac: ReusedJacobian, z0: np.ndarray):
        self.jac = jac
        self._full: dict[bytes, np.ndarray] = {}
        self.full(z0)                 # the trust region's first evaluation, then its first Jacobian
        J0 = jac.jacobian(z0)
        self.basis: tuple[np.ndarray, np.ndarray] | None = None     # J0 and L
        if J0.shape[0] > COMPRESS_ROWS * J0.shape[1]:
            try:
                self.basis = J0, np.linalg.cholesky(J0.T @ J0)
            except np.linalg.LinAlgError:
                log.info("rig fit: the Jacobian's Gram matrix is not positive definite: the residual is not compressed")

    def full(self, z: np.ndarray) -> np.ndarray:
        """(rows,) the uncompressed residual at ``z``: the one the solve evaluated there (the last
        :data:`KEPT_RESIDUALS` points), else evaluated."""
        key = np.asarray(z, float).tobytes()
        r = self._full.get(key)
        if r is None:
            while len(self._full) >= KEPT_RESIDUALS:
                del self._full[next(iter(self._full))]          # the oldest
            r = self._full[key] = self.jac.residual(z)
        return r

    def projected(self, M: np.ndarray) -> np.ndarray:
        """Qᵀ M (size, ...) of ``M`` (rows, ...) (the class docstring's Q).  Raises ValueError where
        the residual is not compressed."""
        if self.basis is None:
            raise ValueError("the residual is not compressed: no basis to project on")
        J0, L = self.basis
        out: np.ndarray = solve_triangular(L, J0.T @ M, lower=True)
        return out

    def residual(self, z: np.ndarray) -> np.ndarray:
        r = self.full(z)
        if self.basis is None:
            return r
        head = self.projected(r)
        return np.concatenate([head, [np.sqrt(max(r @ r - head @ head, 0.0))]])

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        J = self.jac.jacobian(z)
        if self.basis is None:
            return J
        r = self.full(z)
        head = self.projected(r)
        top = self.projected(J)
        tail = np.sqrt(max(r @ r - head @ head, 0.0))
        last = (r @ J - head @ top) / tail if tail > 0 else np.zeros(J.shape[1])
        return np.vstack([top, last])


__all__ = ["sequential_blas", "ReusedJacobian", "CompressedResidual", "COMPRESS_ROWS", "KEPT_RESIDUALS",
           "RigPoint", "RigProblem", "JointProblem", "JointLayout", "BODY",
           "levels", "base_state", "DECIMATED_RATE", "THREADS", "MAX_ITERATIONS", "XTOL",
           "FTOL", "GTOL", "OUTSIDE", "JACOBIAN_STEP", "IMPULSE_TAIL", "NON_NEGATIVE", "SETTLE_STEPS",
           "SETTLE_DECREMENT"]
