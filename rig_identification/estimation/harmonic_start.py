"""The tensor's start for the rig model's fit, from the forced response alone.

The exact model's fit (:func:`~rig_identification.estimation.rig_fit.fit_rig`) is multimodal in
the tensor: the swinging modes are barely damped, and where a start's mode frequencies are off
their phase drifts over the record (on a 5-cable rig of near-parallel cables a start 25 % off
settled at 100× the noise).  The steady response at the exciter's frequency has no such
trap: it is a smooth function of the tensor, the frequency response of the rig linearised
about its rest pose (:func:`~rig_identification.model.linear_rig.frequency_response`; thesis
eqs. 3.1–3.10 with the cables' forces resolved).  This module fits the tensor to the measured
fundamental of every load cell and the gyro (their complex amplitudes by least squares over
the compared span, each weighted by its noise), from each of several starts, and returns the
one of least misfit: the frequency-domain start of a grey-box fit (Ljung, *System
Identification*, 2nd ed., §7.7 and ch. 14 on starts; Pintelon & Schoukens, *System
Identification: A Frequency Domain Approach*, 2012).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from ..io.rig import Rig
from ..model.dynamics import SimulationError
from ..model.linear_rig import frequency_response, linearise
from ..model.parametrisation import physically_consistent, to_tensor
from .rig_record import Record, RigFitError
from .rig_start import start_parameters
from .rig_unknowns import Prior

log = logging.getLogger(__name__)

#: Iterations of each start's least squares (each costs a 6×6 solve per evaluation).
MAX_ITERATIONS = 200


@dataclass(frozen=True)
class Harmonics:
    """The fundamental of a record's compared span.

    omega: the exciter's frequency, rad/s.  force: (2,) complex amplitude of the exciter force,
    N, exciter frame (u(t) = Re(force e^{iωt})).  readings: (N + 3,) complex amplitudes of the
    load cells (N) and the gyro (rad/s, IMU axes).  std: (N + 3,) σ of each amplitude's real
    and of its imaginary part (the channel's white noise over the span's samples).
    """

    omega: float
    force: np.ndarray
    readings: np.ndarray
    std: np.ndarray


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
    return Harmonics(omega, coef_u[0] - 1j * coef_u[1], coef_y[0] - 1j * coef_y[1],
                     rec.sigma[outputs] * np.sqrt(2.0 / samples))


def harmonic_start(rec: Record, rig: Rig, prior: Prior, starts: np.ndarray) -> tuple[np.ndarray, float]:
    """The tensor entries (6,) kg·m² whose linearised forced response best matches the record's
    fundamental (module docstring), fitted from each row of ``starts`` (k, 6); and that fit's
    RMS misfit over the amplitudes' noise (1: noise alone; the linearisation's own error adds
    to it).  Mass, CG, stiffness and geometry are the fit's start
    (:func:`~.rig_start.start_parameters`, the lengths and CG from the record's mean tensions).
    Raises :class:`RigFitError` when the rig has no rest pose."""
    h = harmonics(rec, len(rig.cables))
    p0, rest = start_parameters(rig, prior, np.asarray(starts[0], float), rec)
    weight = 1.0 / h.std
    big = np.full(2 * len(h.readings), 1e6)

    def residual(x: np.ndarray) -> np.ndarray:
        if not physically_consistent(to_tensor(x)):
            return big
        p = p0.replace(inertia=x)
        try:
            e = (h.readings - frequency_response(p, linearise(p, rest), h.omega, h.force)) * weight
        except (np.linalg.LinAlgError, SimulationError):
            return big
        return np.concatenate([e.real, e.imag])

    best = None
    for s in np.atleast_2d(starts):
        scale = np.full(6, 1e-2 * max(abs(s[0]), abs(s[3]), abs(s[5])))
        sol = least_squares(lambda z: residual(s + scale * z), np.zeros(6), method="trf",
                            max_nfev=MAX_ITERATIONS, x_scale=1.0)
        if best is None or sol.cost < best[1]:
            best = (s + scale * sol.x, sol.cost)
    assert best is not None
    level = float(np.sqrt(2 * best[1] / (2 * len(h.readings))))
    log.info("harmonic start: %s kg·m² at %.3g Hz, misfit %.3g× the noise", np.round(best[0], 1),
             h.omega / (2 * np.pi), level)
    if not np.all(np.isfinite(best[0])):
        raise RigFitError(f"{rig.source}: the forced response gives no start for the tensor")
    return best[0], level
