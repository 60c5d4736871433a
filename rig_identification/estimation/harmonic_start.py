"""The tensor's start for the rig model's fit, from the forced response alone.

The exact model's fit (:func:`~rig_identification.estimation.rig_fit.fit_rig`) is multimodal in
the tensor: the swinging modes are barely damped, and where a start's mode frequencies are off
their phase drifts over the record (on a 5-cable rig of near-parallel cables a start 25 % off
settled at 100× the noise).  The steady response at the exciter's frequency has no such
trap: it is a smooth function of the tensor, the frequency response of the rig linearised
about its rest pose (:func:`~rig_identification.model.linear_rig.frequency_response`; thesis
eqs. 3.1–3.10 with the cables' forces resolved).  This module fits the tensor to the measured
fundamental of every load cell and the gyro (their complex amplitudes by least squares over
the compared span, each weighted by its noise and the linearisation's own error), from each of
several starts, and returns the one of least misfit: the frequency-domain start of a grey-box fit (Ljung, *System
Identification*, 2nd ed., §7.7 and ch. 14 on starts; Pintelon & Schoukens, *System
Identification: A Frequency Domain Approach*, 2012).

The same misfit gives the cables' stiffness its start where rig.yaml gives none
(:func:`forced_response_start`): soft cables bring the bounce and rocking modes near the band, and the
fundamental then depends on their stiffness as much as on the tensor.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from ..io.rig import Rig
from ..model.linear_rig import RestPose, RigParameters, frequency_response, linearise, mass_matrix
from ..model.parametrisation import physically_consistent, to_tensor
from ..model.rigid_body import SimulationError
from .rig_record import Record, RigFitError
from .rig_start import carried_to, start_parameters
from .rig_unknowns import Prior

log = logging.getLogger(__name__)

#: Iterations of each start's least squares (each costs a 6×6 solve per evaluation).
MAX_ITERATIONS = 200
#: The linearised forced response's own error, as a share of each amplitude: added in quadrature
#: to the amplitude's noise as its σ (:func:`harmonics`).  The rig's linearisation about its rest
#: pose misses the measured fundamental by several per cent of each amplitude even at the true
#: parameters (the swinging angle's second-order terms, the cables' sag): weighted by their noise
#: alone (σ over 100 s of samples is 10⁻⁴ of a tension's amplitude), the largest amplitudes'
#: linearisation error decides the fitted tensor — on bench_any_rig's rig 21138 the start landed
#: 16–48 % off the truth and the rig model's fit never found the motion; with 1 % the fit starts
#: within 3–6 % on Iyy and Izz and is ``ok``.
LINEARISATION_SHARE = 0.01
#: The logs of the factor on the default steel cable's stiffness that :func:`forced_response_start`
#: scans where rig.yaml gives none: 1/400 (12 kN/m: a soft sling or a spring suspension) to
#: e (14 MN/m: a thick steel rope), in steps of a quarter (the misfit's minimum on a soft rig
#: is about that wide: ×2/3 of it already 1.4× its misfit, ×5/3 28×).
STIFFNESS_SCAN = np.arange(-6.0, 1.0 + 1e-9, 0.25)
#: The scan's best is refined to this in log(stiffness).
STIFFNESS_SCAN_TOLERANCE = 0.01
#: The relative tolerance (on the cost, the step and the gradient) of each scan point's fit of
#: the tensor: the scan only ranks the stiffnesses (their misfits differ by factors, not per
#: cent); the two misfits the decision compares are fitted to scipy's default 1e-8.
SCAN_TOLERANCE = 1e-3
#: A scanned stiffness is the fit's start only where its misfit (RMS over the noise) is below
#: this share of the prior's (:func:`forced_response_start`): with steel cables the scan's best
#: lies near the default's (the linearisation's error and the tensor's own minima dominate the
#: misfit), with soft ones orders of magnitude below it (``python bench/bench_stiffness_start.py``).
STIFFNESS_MISFIT_SHARE = 0.5
#: Nothing is scanned where the forced response at the prior's stiffness misfits the fundamental
#: by no more than this (RMS over the amplitudes' σ: their noise and the linearisation's share):
#: the prior already explains it, and a lower misfit elsewhere would be noise.  Soft cables miss
#: by 3.1–19 600 at the default steel cable's, steel ones 0.35–12 (``python
#: bench/bench_stiffness_start.py``).
PRIOR_EXPLAINS = 1.0


@dataclass(frozen=True)
class Harmonics:
    """The fundamental of a record's compared span.

    omega: the exciter's frequency, rad/s.  force: (2,) complex amplitude of the exciter force,
    N, exciter frame (u(t) = Re(force e^{iωt})).  readings: (N + 3,) complex amplitudes of the
    load cells (N) and the gyro (rad/s, IMU axes).  std: (N + 3,) σ of each amplitude's real
    and of its imaginary part: the channel's white noise over the span's samples and
    :data:`LINEARISATION_SHARE` of the amplitude, in quadrature.
    """

    omega: float
    force: np.ndarray
    readings: np.ndarray
    std: np.ndarray


def box_tensor(rig: Rig) -> np.ndarray:
    """A rough tensor (6,) kg·m² about the CG, body axes: rig.yaml's mass spread evenly over the
    box the body anchors span, 0.1 m added on every side; diagonal (a start, not an estimate)."""
    half = np.ptp(rig.body_anchors, axis=0) / 2 + 0.1
    sx, sy, sz = half**2
    return rig.mass / 3 * np.array([sy + sz, 0.0, 0.0, sx + sz, 0.0, sx + sy])


def _peak_frequency(u: np.ndarray, dt: float) -> float:
    """rad/s: the rotating force's strongest frequency (the periodogram's peak, refined to the
    maximum of |Σ u_c e^{-iωt}|)."""
    uc = (u[:, 0] - u[:, 0].mean()) + 1j * (u[:, 1] - u[:, 1].mean())
    t = dt * np.arange(len(uc))
    spectrum = np.abs(np.fft.fft(uc))
    f = np.fft.fftfreq(len(uc), dt)
    k = int(np.argmax(spectrum[1:]) + 1)
    df = 1.0 / (len(uc) * dt)

    def minus_power(freq: float) -> float:
        return -float(np.abs(np.sum(uc * np.exp(-2j * np.pi * freq * t))))

    best = minimize_scalar(minus_power, bounds=(f[k] - df, f[k] + df), method="bounded",
                           options={"xatol": 1e-6 * max(abs(f[k]), df)})
    return float(2 * np.pi * abs(best.x))


def harmonics(rec: Record, cables: int) -> Harmonics:
    """The fundamental (:class:`Harmonics`) of ``rec`` over its compared span (from
    ``rec.start``): sinusoid, cosine and offset fitted to each channel by least squares."""
    y = rec.y[rec.start:]
    u = rec.u[rec.start:]
    omega = _peak_frequency(u, rec.dt)
    t = rec.dt * np.arange(len(y))
    X = np.column_stack([np.cos(omega * t), np.sin(omega * t), np.ones_like(t)])
    coef_u = np.linalg.lstsq(X, u, rcond=None)[0]
    outputs = np.r_[0:cables, cables:cables + 3]
    coef_y = np.linalg.lstsq(X, y[:, outputs], rcond=None)[0]
    samples = len(t) / rec.oversampling[outputs]
    readings = coef_y[0] - 1j * coef_y[1]
    noise = rec.sigma[outputs] * np.sqrt(2.0 / samples)
    return Harmonics(omega, coef_u[0] - 1j * coef_u[1], readings,
                     np.hypot(noise, LINEARISATION_SHARE * np.abs(readings)))


def _fitted(h: Harmonics, p0: RigParameters, rest: RestPose, starts: np.ndarray,
            tolerance: float = 1e-8) -> tuple[np.ndarray, float]:
    """The tensor entries (6,) whose forced response (``p0`` otherwise, about ``rest``) best
    matches ``h``, fitted from each row of ``starts`` (k, 6) to the relative ``tolerance`` (cost,
    step and gradient), and that fit's cost (½ Σ of the squared amplitudes' errors over their σ,
    real and imaginary parts)."""
    weight = 1.0 / h.std
    big = np.full(2 * len(h.readings), 1e6)
    lin0 = linearise(p0, rest)          # K, D and G do not depend on the tensor: only M is made again

    def residual(x: np.ndarray) -> np.ndarray:
        if not physically_consistent(to_tensor(x)):
            return big
        p = p0.replace(inertia=x)
        try:
            e = (h.readings - frequency_response(p, replace(lin0, M=mass_matrix(p, rest)), h.omega, h.force)) * weight
        except (np.linalg.LinAlgError, SimulationError):
            return big
        return np.concatenate([e.real, e.imag])

    best = None
    for s in np.atleast_2d(starts):
        scale = np.full(6, 1e-2 * max(abs(s[0]), abs(s[3]), abs(s[5])))
        sol = least_squares(lambda z: residual(s + scale * z), np.zeros(6), method="trf",
                            max_nfev=MAX_ITERATIONS, x_scale=1.0, ftol=tolerance, xtol=tolerance,
                            gtol=tolerance)
        if best is None or sol.cost < best[1]:
            best = (s + scale * sol.x, float(sol.cost))
    assert best is not None
    return best


def _level(cost: float, h: Harmonics) -> float:
    """The RMS misfit over the noise of a fit of cost ``cost`` to ``h``."""
    return float(np.sqrt(2 * cost / (2 * len(h.readings))))


@dataclass(frozen=True)
class ForcedResponseStart:
    """The rig model's start from the record's fundamental (:func:`forced_response_start`).

    tensor: (6,) kg·m² tensor entries about the CG (ixx, ixy, ixz, iyy, iyz, izz) whose
    linearised forced response best matches the fundamental at ``stiffness``.  level: that fit's
    RMS misfit over the amplitudes' σ (:attr:`Harmonics.std`: noise and
    :data:`LINEARISATION_SHARE` of each amplitude; about 1 where the linearised model holds).
    stiffness: (N,) N/m, the cables' stiffness the fit starts from.  log_scale: the natural log of
    the factor on the prior's stiffness of the cables rig.yaml gives none for (0: the
    prior's, the default steel cable's).  prior_level: the misfit at the prior's stiffness (nan
    where rig.yaml gives every cable's).
    """

    tensor: np.ndarray
    level: float
    stiffness: np.ndarray
    log_scale: float
    prior_level: float

    @property
    def moved(self) -> bool:
        """The stiffness's start is not the prior's."""
        return self.log_scale != 0.0


def forced_response_start(rec: Record, rig: Rig, prior: Prior, starts: np.ndarray,
                          rotor: np.ndarray | None = None) -> ForcedResponseStart:
    """The tensor and the cables' stiffness the rig model's fit starts from: the tensor entries
    whose linearised forced response best matches the record's fundamental (module docstring),
    fitted from each row of ``starts`` (k, 6) kg·m²; mass, CG and geometry the fit's start
    (:func:`~.rig_start.start_parameters`, the lengths and CG from the record's mean tensions).

    The stiffness is the prior's where rig.yaml gives every cable's
    (:attr:`~.rig_unknowns.Prior.stiffness_given`) or where the prior's forced response misfits
    the fundamental by no more than :data:`PRIOR_EXPLAINS`, else the stiffness of those it does
    not give scaled by the common factor whose linearised forced response, the tensor fitted
    beside it, best matches the record's fundamental.

    Where the cables are soft enough to bring their bounce and rocking modes near the band
    (vertical ≈ sqrt(Σk / m) / 2π: 3 Hz for 4 cables of 150 kN/m under 1.7 t, 17 Hz for steel),
    the tensions' and the gyro's amplitudes at the exciter's frequency depend on the stiffness
    (thesis eqs. 3.1–3.10: K's axial part), and a fit started at steel's never finds the motion
    (its swinging phase drifts, the bounce modes sit at the wrong frequency).  The factor is
    scanned over :data:`STIFFNESS_SCAN` (the misfit has several minima in it), each point's tensor
    fitted to :data:`SCAN_TOLERANCE`, its geometry the prior's start carried to that stiffness
    (:func:`~.rig_start.carried_to`: the tensions' shares kept, the body lower on softer
    cables).  The scan's best is taken only where its misfit is below
    :data:`STIFFNESS_MISFIT_SHARE` of the prior's (both refitted to full precision, the prior's
    also from the best's tensor: the tensor's fit has minima of its own), then refined by a
    bounded scalar search about it (its tensor fitted from the best's; the decision is the
    grid's: a refined misfit can dip within 1 % of stiffness).  On steel cables the modes lie
    far above the band and the misfit, dominated by the linearisation's error and a tensor the
    one frequency determines poorly, is no evidence: it changes by a few per cent over a factor
    10 of stiffness.  ``rotor``: (2,) the exciter rotor's unbalance kg·m and mass kg the model
    holds (None: none): an unbalance's weight turns with the force and moves the fundamental
    (:func:`~rig_identification.model.linear_rig.frequency_response`).  The stiffness's prior
    itself stays (:class:`~.rig_unknowns.Prior`): only the start moves.  Raises
    :class:`RigFitError` when the rig has no rest pose or the fit no finite tensor."""
    m = _Misfit(rec, rig, prior, np.atleast_2d(np.asarray(starts, float)),
                np.zeros(2) if rotor is None else np.asarray(rotor, float))
    # at the prior's stiffness the tensor fitted to full precision from every start
    own_level, prior_tensor = m.at(0.0, m.starts)
    if not np.any(m.free) or own_level <= PRIOR_EXPLAINS:
        return m.found(prior_tensor, own_level, 0.0, own_level if np.any(m.free) else float("nan"))
    levels, tensors = m.scan()
    prior_index = int(np.argmin(np.abs(STIFFNESS_SCAN)))
    i = int(np.argmin(levels))
    # the prior's misfit also from the best's tensor: not trapped in a minimum of its own
    best_s, best_level, best_tensor, prior_level = 0.0, own_level, prior_tensor, own_level
    if i != prior_index:
        best_s = float(STIFFNESS_SCAN[i])
        best_level, best_tensor = m.at(best_s, tensors[i][None])
        prior_level = min(own_level, m.at(0.0, best_tensor[None])[0])
    log.info("stiffness start: the forced response's misfit %s× the noise over the stiffness scaled by e^%s; "
             "least %.3g× at ×%.3g of the prior's (%.3g× there)", np.round(levels, 1), STIFFNESS_SCAN.round(2),
             best_level, np.exp(best_s), prior_level)
    if not (best_level < STIFFNESS_MISFIT_SHARE * prior_level):
        return m.found(prior_tensor, own_level, 0.0, prior_level)
    step = float(np.diff(STIFFNESS_SCAN).max())
    refined = minimize_scalar(lambda s: m.at(s, best_tensor[None])[0], bounds=(best_s - step, best_s + step),
                              method="bounded", options={"xatol": STIFFNESS_SCAN_TOLERANCE})
    if refined.fun < best_level:
        best_s = float(refined.x)
        best_level, best_tensor = m.at(best_s, best_tensor[None])
    return m.found(best_tensor, best_level, best_s, prior_level)


@dataclass(frozen=True)
class DampedStart:
    """The forced response fitted with the body's viscous damping beside the tensor
    (:func:`damped_start`): ``tensor`` (6,) kg·m², ``damping`` (2,) the body's viscous damping
    (linear N·s/m on the CG's velocity, angular N·m·s), ``level`` the misfit over the noise."""

    tensor: np.ndarray
    damping: np.ndarray
    level: float


def damped_start(rec: Record, rig: Rig, prior: Prior, start: ForcedResponseStart) -> DampedStart:
    """The tensor and the body's viscous damping whose linearised forced response best matches the
    record's fundamental (module docstring; ``start``: the undamped fit, its tensor the start and
    its stiffness the cables'), the damping bounded below by 0.  Where the body is damped far beyond
    the cables' own damping (air drag on a large body, a damper), the undamped fundamental misses
    the measured one by orders of magnitude (bench_trust's air-drag row: 320× the noise) and the
    rig model's fit, started without damping, does not find the motion; the damping the
    fundamental asks for is its start then (an equivalent viscous damping: quadratic drag and
    friction at this amplitude).  The linear rig's damping matrix is affine in the body's damping
    (:func:`~rig_identification.model.linear_rig.linearise`: D = D₀ + c_lin G_cG_cᵀ + c_ang E_φ).
    Raises :class:`RigFitError` when the rig has no rest pose."""
    h = harmonics(rec, len(rig.cables))
    p0, rest = start_parameters(rig, prior, start.tensor, rec, stiffness=start.stiffness)
    p0 = p0.replace(body_damping=np.zeros(2))
    lin0 = linearise(p0, rest)
    parts = [linearise(p0.replace(body_damping=np.eye(2)[i]), rest).D - lin0.D for i in range(2)]
    weight = 1.0 / h.std
    big = np.full(2 * len(h.readings), 1e6)
    moment = max(abs(start.tensor[0]), abs(start.tensor[3]), abs(start.tensor[5]))
    scale = np.r_[np.full(6, 1e-2 * moment), 1e-2 * h.omega * np.array([prior.mass, moment])]

    def residual(z: np.ndarray) -> np.ndarray:
        x = np.r_[start.tensor, 0.0, 0.0] + scale * z
        if not physically_consistent(to_tensor(x[:6])):
            return big
        p = p0.replace(inertia=x[:6], body_damping=x[6:])
        lin = replace(lin0, M=mass_matrix(p, rest), D=lin0.D + x[6] * parts[0] + x[7] * parts[1])
        try:
            e = (h.readings - frequency_response(p, lin, h.omega, h.force)) * weight
        except (np.linalg.LinAlgError, SimulationError):
            return big
        return np.concatenate([e.real, e.imag])

    lower = np.r_[np.full(6, -np.inf), 0.0, 0.0]
    sol = least_squares(residual, np.zeros(8), method="trf", bounds=(lower, np.inf), max_nfev=MAX_ITERATIONS)
    x = np.r_[start.tensor, 0.0, 0.0] + scale * sol.x
    level = _level(float(sol.cost), h)
    log.info("damped forced-response start: %s kg·m², body damping %s (N·s/m, N·m·s), misfit %.3g× the noise "
             "(undamped %.3g×)", np.round(x[:6], 1), np.round(x[6:], 1), level, start.level)
    return DampedStart(x[:6], x[6:], level)


def drag_start(rec: Record, damped: DampedStart) -> np.ndarray:
    """(2,) the quadratic drag (linear N·s²/m², angular N·m·s²) that dissipates over a cycle what
    ``damped``'s viscous damping does at the record's amplitudes — the equivalent linearisation
    c_eq = (8 / 3π) c_q V of a quadratic damping at velocity amplitude V (Den Hartog, *Mechanical
    Vibrations*, 4th ed., §8.2; Rao, *Mechanical Vibrations*, 6th ed., §3.10): V the fundamental's
    amplitude of the body's angular velocity (the gyro) and of its CG's velocity (the
    accelerometer's over ω, its gravity tilt included: a start, not an estimate)."""
    y = rec.y[rec.start:]
    t = rec.dt * np.arange(len(y))
    omega = _peak_frequency(rec.u[rec.start:], rec.dt)
    X = np.column_stack([np.cos(omega * t), np.sin(omega * t), np.ones_like(t)])

    def amplitude(prefix: str) -> float:
        c = np.linalg.lstsq(X, y[:, [i for i, n in enumerate(rec.channels) if n.startswith(prefix)]], rcond=None)[0]
        return float(np.linalg.norm(np.hypot(c[0], c[1])))

    velocity = np.array([amplitude("accel") / omega, amplitude("gyro")])
    out: np.ndarray = np.asarray(damped.damping, float) / (8.0 / (3.0 * np.pi) * np.maximum(velocity, 1e-12))
    return out


class _Misfit:
    """The forced response's misfit as a function of the log factor on the stiffness of the
    cables rig.yaml gives none for (``free``), the tensor fitted from ``starts`` (k, 6), the
    exciter's rotor ``rotor`` (2,) (:func:`forced_response_start`)."""

    def __init__(self, rec: Record, rig: Rig, prior: Prior, starts: np.ndarray, rotor: np.ndarray):
        self.rec, self.rig, self.prior, self.starts, self.rotor = rec, rig, prior, starts, rotor
        self.free = ~prior.stiffness_given
        self.h = harmonics(rec, len(rig.cables))
        self._at_prior: tuple[RigParameters, RestPose] | None = None

    def prior_start(self) -> tuple[RigParameters, RestPose]:
        """The start's parameters and rest pose at the prior's stiffness (searched once)."""
        if self._at_prior is None:
            p, rest = start_parameters(self.rig, self.prior, self.starts[0], self.rec)
            self._at_prior = p.replace(rotor=self.rotor), rest
        return self._at_prior

    def stiffness(self, s: float) -> np.ndarray:
        return np.asarray(self.prior.stiffness * np.exp(s * self.free), float)

    def at(self, s: float, tensors: np.ndarray, tolerance: float = 1e-8) -> tuple[float, np.ndarray]:
        """The misfit (RMS over the noise) at e^s and its tensor, the start's geometry searched at that
        stiffness (:func:`~.rig_start.start_parameters`; inf where it has no rest pose)."""
        try:
            p0, rest = self.prior_start() if s == 0.0 else \
                start_parameters(self.rig, self.prior, self.starts[0], self.rec, stiffness=self.stiffness(s))
        except RigFitError:
            return float("inf"), tensors[0]
        p0 = p0.replace(rotor=self.rotor)            # the prior's start holds it already; a searched one not
        tensor, cost = _fitted(self.h, p0, rest, tensors, tolerance)
        return _level(cost, self.h), tensor

    def scan(self) -> tuple[np.ndarray, np.ndarray]:
        """The misfits (len(STIFFNESS_SCAN),) and tensors (len(STIFFNESS_SCAN), 6) over the scan, each
        tensor fitted to :data:`SCAN_TOLERANCE`, the geometry the prior's start carried to each
        stiffness (:func:`~.rig_start.carried_to`; inf where it has no rest pose)."""
        at_prior = self.prior_start()
        levels, tensors = [], []
        for s in STIFFNESS_SCAN:
            try:
                p0, rest = carried_to(*at_prior, self.stiffness(float(s)), self.rig.cable_lengths)
            except SimulationError:
                levels.append(float("inf"))
                tensors.append(self.starts[0])
                continue
            tensor, cost = _fitted(self.h, p0, rest, self.starts, SCAN_TOLERANCE)
            levels.append(_level(cost, self.h))
            tensors.append(tensor)
        return np.array(levels), np.array(tensors)

    def found(self, tensor: np.ndarray, level: float, log_scale: float, prior_level: float) -> ForcedResponseStart:
        """The start (tensor at e^log_scale), logged.  Raises :class:`RigFitError` where the tensor is not finite."""
        if not np.all(np.isfinite(tensor)):
            raise RigFitError(f"{self.rig.source}: the forced response gives no start for the tensor")
        log.info("forced-response start: %s kg·m² at %.3g Hz, misfit %.3g× the noise, the cables' stiffness ×%.4g "
                 "of the prior's", np.round(tensor, 1), self.h.omega / (2 * np.pi), level, np.exp(log_scale))
        return ForcedResponseStart(tensor, level, self.stiffness(log_scale), log_scale, prior_level)
