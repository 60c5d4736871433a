"""A recording's streams on one grid for the rig model (:mod:`~rig_identification.estimation.rig_fit`).

Every stream (the load cells' tensions, the IMU's gyro and accelerometer, the inclinometer, the
exciter's force) is put on one uniform grid at the fastest stream's rate, each channel's white
noise estimated from its own samples (:func:`~rig_identification.io.quality.white_sigma`); the
exciter's force is denoised (:func:`smooth_force`: a rotating vector's amplitude and phase as
least-squares splines) and, where it is a rotating vector, its readings become two output
channels of the fit.  The fit's band (:func:`band_edge`) is a multiple of the force's frequency.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline, make_lsq_spline
from scipy.signal import butter, sosfiltfilt
from scipy.stats import chi2

from ..io.quality import white_sigma
from ..io.recording import SensorData
from ..io.rig import Rig

log = logging.getLogger(__name__)

#: The fit's band edge over the exciter force's dominant frequency (:func:`band_edge`).
FORCE_BAND = 4.0
#: Knot spacing, s, of the exciter force's amplitude and phase while the motor spins up and
#: after (:func:`smooth_force`).
RAMP_KNOT = 0.25
STEADY_KNOT = 15.0
#: The record's grid is at least this many times the fit's band edge: a faster recording (1 kHz)
#: is low-passed and decimated to it (:func:`record`), since the model's cost grows with the grid's
#: samples and the fit compares only the band.
MODEL_RATE_BANDS = 25.0
#: s dropped at each end of a decimated record (:func:`record`).
DECIMATION_EDGE = 0.1
#: s after the spin-up's end (its amplitude at 90 % of the steady one, plus 1 s) where the fit starts.
SETTLE = 2.0
#: The force is a rotating vector (:func:`smooth_force`) where its fit leaves at most twice the
#: noise or this share of its amplitude: a rotor's bearing force holds the rotor's own inertial
#: force besides the rotating one (5 % of it: a 10 kg rotor on a 1.5 t body swinging 1 cm at
#: 1.2 Hz), which the fit's exciter channels model (:func:`~rig_identification.model.rig_ode.exciter_readings`).
ROTATING_SHARE = 0.1
#: The rotating force's co-rotating harmonics k (the components turning k + 1 times per revolution,
#: :func:`smooth_force`) that the denoised force may keep: a rotor whose drive holds its speed
#: against the body's swing, and an exciter's bearings, make them (the independent simulator's rotor:
#: 0.24 N at twice the spin, 0.12 N at three times, beside 230 N, ringing the yaw mode at 2.36 Hz by
#: 6 N in the tensions where the input left them out); a rotor's own inertial force on the body's
#: swing, which the load cells read too, makes them in the readings alone: the fit corrects each
#: kept harmonic with the exciter's readings as an output (:class:`Record` ``force_harmonics``).
#: The counter-rotating part (a rotor's reaction to an elliptic swing) and the constant one are not in it.
FORCE_HARMONICS = (1, 2, 3)
#: A harmonic is kept where its splines hold more than noise would, at this false-alarm probability.
HARMONIC_P = 1e-3
#: The counter-rotating part, in the rotating force's own frame (turning −2 times per revolution there).
COUNTER_ROTATING = -2


class RigFitError(ValueError):
    """A recording the rig model cannot be fitted to (no exciter, no common span, too short)."""


@dataclass(frozen=True)
class Record:
    """A recording's streams on one uniform grid over the record.

    t0: the first sample's stamp, s; dt: the grid's step, s.  y: (n, n_out) the outputs
    (channel order of :func:`channel_names`: tensions N, gyro rad/s, accelerometer m/s²,
    inclinometer rad; then, where the force is a rotating vector, the exciter's two measured
    components, N, exciter frame: the force is an output too).  u: (n, 2) the exciter force
    denoised (:func:`smooth_force`), N, exciter frame: the model's input before the fit's
    correction.  sigma: (n_out,) each
    channel's white-noise σ per sample of its own stream.  oversampling: (n_out,) the grid's
    rate over the stream's (> 1: a slower stream's samples count once, not once per grid step;
    < 1: a faster stream low-passed and decimated to the grid).
    band: Hz, the fit's band (:func:`band_edge`): the residual is low-passed and decimated
    to it.  start: the first sample the fit compares (after the exciter's spin-up, whose force
    is known less well: :func:`smooth_force`); the model runs from the record's start to it.
    force_knots: s from ``t0``, the interior knots of the denoised force's amplitude and phase
    splines after ``start`` (empty when the force is not a rotating vector): the fit corrects
    the force in that spline space (:class:`~rig_identification.estimation.rig_unknowns.Layout` ``force``).
    force_harmonics: the co-rotating harmonics k (:data:`FORCE_HARMONICS`) the denoised force
    holds (:func:`smooth_force`), each corrected in that spline space too.
    """

    t0: float
    dt: float
    y: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    sigma: np.ndarray
    oversampling: np.ndarray
    channels: tuple[str, ...]
    band: float
    start: int
    force_knots: np.ndarray = field(default_factory=lambda: np.zeros(0))
    force_harmonics: tuple[int, ...] = ()

    @property
    def duration(self) -> float:
        return self.dt * (len(self.y) - 1)

    def unbalance(self, force: np.ndarray | None = None) -> float | None:
        """The unbalance m_u e, kg·m, whose rotation makes the denoised force over the fit's span
        (or ``force`` (m, 2) N, exciter frame, from the span's start: the force a fit infers):
        its median amplitude over Ω², with Ω rad/s the mean rate of its phase (a rotating
        unbalance's force is m_u e Ω²: Rao, *Mechanical Vibrations*, 6th ed., §3.7).  None where
        the force is not a rotating vector (then it is no output: :data:`FORCE_CHANNELS`)."""
        if self.channels[-len(FORCE_CHANNELS):] != FORCE_CHANNELS:
            return None
        u = self.u[self.start:] if force is None else np.asarray(force, float)
        z = u[:, 0] + 1j * u[:, 1]
        phase = np.unwrap(np.angle(z))
        omega = abs(phase[-1] - phase[0]) / (self.dt * (len(z) - 1))
        return float(np.median(np.abs(z)) / omega ** 2) if omega > 0 else None

    def force_basis(self) -> np.ndarray:
        """(n - start, K) the cubic B-splines on :attr:`force_knots` over the fit's span, one
        column each ((n - start, 0) when the force is not an output: not a rotating vector)."""
        n = len(self.y) - self.start
        if self.channels[-len(FORCE_CHANNELS):] != FORCE_CHANNELS:
            return np.zeros((n, 0))
        t = self.dt * np.arange(self.start, len(self.y))
        inner = np.concatenate([[t[0]] * 4, self.force_knots[self.force_knots < t[-1]], [t[-1]] * 4])
        basis: np.ndarray = BSpline.design_matrix(t, inner, 3).toarray()
        return basis

    def force_unknowns(self) -> int:
        """The force correction's unknowns (:class:`~rig_identification.estimation.rig_unknowns.Layout`
        ``n_force``): 2 K for the amplitude and phase (K: :meth:`force_basis`'s columns) and 2 K for
        each of :attr:`force_harmonics` (real and imaginary part)."""
        return 2 * int(self.force_basis().shape[1]) * (1 + len(self.force_harmonics))


@dataclass(frozen=True)
class ChannelSeries:
    """Every channel over the fit's span as the fit compares it, for plots: t (m,) s from the
    record's first sample; measured, predicted (m, n_out) the readings and the model's at the
    estimate (channel units: N, rad/s, m/s², rad), low-passed to the fit's band and decimated,
    the model's offset put on the measured one's (the fit projects each channel's offset out).
    channels: (n_out,) names."""

    t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    channels: tuple[str, ...]


#: The exciter's two measured force components as outputs of the rig model (exciter frame).
FORCE_CHANNELS = ("exciter_x", "exciter_y")


def channel_names(rig: Rig, force: bool = False) -> tuple[str, ...]:
    """The outputs of the rig model, in the order of :func:`~rig_identification.model.rig_ode.simulate`,
    then (``force``) the exciter's :data:`FORCE_CHANNELS`."""
    names = [f"tension:{n}" for n in rig.cable_names] + ["gyro_x", "gyro_y", "gyro_z", "accel_x", "accel_y",
                                                          "accel_z"]
    names += ["incl_x", "incl_y"] if rig.inclinometer is not None else []
    return tuple(names + (list(FORCE_CHANNELS) if force else []))


def _streams(sensors: SensorData, rig: Rig) -> list[tuple[np.ndarray, np.ndarray]]:
    out = [(sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0]) for n in rig.cable_names]
    out += [(sensors.imu.t, sensors.imu.data[:, j]) for j in range(6)]
    if rig.inclinometer is not None:
        if sensors.inclinometer is None:
            raise RigFitError(f"{rig.source}: rig.yaml has an inclinometer but the recording has no "
                              "/rig/inclinometer stream")
        out += [(sensors.inclinometer.t, sensors.inclinometer.data[:, j]) for j in range(2)]
    return out


def _on_grid(t: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """A stream on the grid: as it is where its stamps are the grid's, else a cubic spline."""
    dt = grid[1] - grid[0]
    i = np.searchsorted(t, grid[0] - 1e-3 * dt)
    if len(t) >= i + len(grid) and np.max(np.abs(t[i:i + len(grid)] - grid)) < 1e-3 * dt:
        return x[i:i + len(grid)]
    spline: np.ndarray = make_interp_spline(t, x, k=3)(grid)
    return spline


@dataclass(frozen=True)
class Streams:
    """Every channel of a run on one uniform grid before :func:`on_model_grid`: t0 s the first
    sample's stamp, dt s the step; y (n, n_out) the readings in :func:`channel_names` order
    (tensions N, gyro rad/s, accelerometer m/s², inclinometer rad); sigma (n_out,) each channel's
    white-noise σ per sample of its own stream; rates (n_out,) Hz each channel's stream rate;
    force (n, 2) N the exciter's measured components (exciter frame), ``force_sigma`` N their σ per
    sample, ``force_rate`` Hz their stream's rate."""

    t0: float
    dt: float
    y: np.ndarray = field(repr=False)
    sigma: np.ndarray
    rates: np.ndarray
    force: np.ndarray = field(repr=False)
    force_sigma: float
    force_rate: float


def record(sensors: SensorData, rig: Rig, t0: float | None = None, t1: float | None = None) -> Record:
    """The recording's :class:`Record` over [t0, t1] (stamps, s; default the span every stream covers).

    Every stream is put on one uniform grid at the fastest stream's rate (a cubic spline where
    its stamps differ from the grid's), each channel's σ estimated from its own samples
    (:func:`~rig_identification.io.quality.white_sigma`), then :func:`on_model_grid`.  Raises
    :class:`RigFitError` without an exciter stream, or when the streams share less than 10 s.
    """
    if sensors.exciter is None or rig.exciter is None:
        raise RigFitError(f"{rig.source}: the rig model needs the exciter (rig.yaml exciter and the "
                          "/rig/exciter/wrench stream)")
    streams = _streams(sensors, rig)
    ex_t = sensors.exciter.t
    lo = max([s[0][0] for s in streams] + [ex_t[0]] + ([t0] if t0 is not None else []))
    hi = min([s[0][-1] for s in streams] + [ex_t[-1]] + ([t1] if t1 is not None else []))
    rates = [(len(s[0]) - 1) / (s[0][-1] - s[0][0]) for s in streams]
    ex_rate = (len(ex_t) - 1) / (ex_t[-1] - ex_t[0])
    dt = 1.0 / round(max(rates + [ex_rate]), 6)
    if hi - lo < 10.0:
        raise RigFitError(f"{rig.source}: the streams share {max(hi - lo, 0):.1f} s; the rig model needs ≥ 10 s")
    # the grid starts on a sample of the first stream, so streams stamped on it are used as they are
    first = streams[0][0]
    lo = first[np.searchsorted(first, lo - 1e-9)]
    n = int(np.floor((hi - lo) / dt + 1e-6)) + 1
    grid = lo + dt * np.arange(n)
    y, sig = [], []
    for t, x in streams:
        m = (t >= lo - 4 * dt) & (t <= grid[-1] + 4 * dt)
        y.append(_on_grid(t[m], x[m], grid))
        sig.append(white_sigma(x[m]))
    me = (ex_t >= lo - 4 * dt) & (ex_t <= grid[-1] + 4 * dt)
    measured = np.column_stack([_on_grid(ex_t[me], sensors.exciter.data[me, j], grid) for j in range(2)])
    # σ of the force's samples as read, like every stream's: a spline onto the grid at a fractional
    # offset smooths the noise (load cells stamped 8 ms late, the grid theirs: the force's σ from
    # the grid 0.67× the true, its channel fitted at 1.5–1.6× its noise), and one that upsamples
    # a slower stream more
    force_sigma = white_sigma(sensors.exciter.data[me, :2])
    return on_model_grid(Streams(float(lo), dt, np.column_stack(y), np.array(sig), np.array(rates), measured,
                                 force_sigma, ex_rate), rig)


def on_model_grid(s: Streams, rig: Rig) -> Record:
    """The :class:`Record` the rig model is fitted to from the streams ``s`` of ``rig``: the fit's
    band (:func:`band_edge`); where the grid's rate exceeds :data:`MODEL_RATE_BANDS` band edges
    twice or more, every channel low-passed (zero-phase 8th-order Butterworth) and decimated,
    :data:`DECIMATION_EDGE` s dropped at each end; the force denoised (:func:`smooth_force`) and,
    where it is a rotating vector, its readings two more outputs.  Raises :class:`RigFitError` with
    under 10 s after the exciter's spin-up."""
    lo, dt, n = s.t0, s.dt, len(s.y)
    y, measured = s.y, s.force
    band = band_edge(measured, dt)
    q = int(1.0 / (dt * MODEL_RATE_BANDS * band))
    if q >= 2:              # a zero-phase anti-aliasing low-pass (padded by odd extension: the
        # tensions' kilonewtons of offset stay put at the ends), then every q-th sample, less
        # DECIMATION_EDGE s at each end where the filter's transient lies (2 N at the last
        # tension sample, 1e-6 N inside: a 5-cable rig at 1 kHz)
        sos = butter(8, 0.8 * 0.5 / (q * dt), fs=1.0 / dt, output="sos")
        k = int(np.ceil(DECIMATION_EDGE / (q * dt)))
        y = sosfiltfilt(sos, y, axis=0)[::q][k:-k]
        measured = sosfiltfilt(sos, measured, axis=0)[::q][k:-k]
        lo, dt, n = lo + k * q * dt, q * dt, len(measured)
    # the force's noise per grid sample: a decimated stream's low-passed (σ² × grid rate / its rate)
    u, start, knots, harmonics = smooth_force(measured, dt, band,
                                              s.force_sigma * np.sqrt(min(1.0, 1.0 / (s.force_rate * dt))))
    # each stream's samples per grid step (a slower stream's sample counts once; a faster one's
    # low-passed noise keeps its in-band density: σ² × grid rate / stream rate per grid sample)
    over = (1.0 / dt) / s.rates
    sig = s.sigma
    if (n - start) * dt < 10.0:
        raise RigFitError(f"{rig.source}: {(n - start) * dt:.1f} s after the exciter's spin-up; the rig model "
                          "needs ≥ 10 s")
    force = start > 0
    if force:
        y = np.column_stack([y, measured])
        sig = np.append(sig, [s.force_sigma] * 2)
        over = np.append(over, [(1.0 / dt) / s.force_rate] * 2)
    return Record(float(lo), dt, y, u, sig, over, channel_names(rig, force), band, start,
                  knots[knots > start * dt] if force else np.zeros(0), harmonics if force else ())


def band_edge(u: np.ndarray, dt: float) -> float:
    """The fit's band edge, Hz: :data:`FORCE_BAND` times the exciter force's dominant frequency
    (at most 0.4 of the rate).  The measured force drives the model through a zero-phase
    4th-order Butterworth low-pass at it (its white noise would ring the cables' axial modes,
    lightly damped at 5–30 Hz, that the real smooth force does not), and the residual is
    low-passed and decimated to it: what the cables' axial modes do above it (their ringing
    from an unmeasured start or a force's sharp edge) stays out of the fit."""
    f = np.fft.rfftfreq(len(u), dt)
    power = np.abs(np.fft.rfft(u - u.mean(axis=0), axis=0)) ** 2
    dominant = f[1:][np.argmax(power[1:].sum(axis=1))]
    return float(min(FORCE_BAND * dominant, 0.4 / dt))


def _offset(z: np.ndarray, steady: np.ndarray) -> complex:
    """The constant offset, N (x + iy), of the force readings ``z`` (n,) complex: their mean over
    the whole revolutions of the ``steady`` samples (n,) bool (after the spin-up), where a
    rotating vector's own mean vanishes; the revolutions counted about a first estimate, the
    steady samples' mean."""
    zs = z[steady]
    if len(zs) < 2:
        return 0j
    c = complex(zs.mean())
    phase = np.unwrap(np.angle(zs - c))
    turns = np.floor(np.abs(phase - phase[0]) / (2 * np.pi))
    whole = int(np.flatnonzero(turns == turns[-1])[0])
    return complex(zs[:whole].mean()) if whole > 0 else c


def smooth_force(u: np.ndarray, dt: float, band: float, noise: float | None = None
                 ) -> tuple[np.ndarray, int, np.ndarray, tuple[int, ...]]:
    """The exciter's force (n, 2) N with its measurement noise removed, the first sample
    after the motor's spin-up (0 when the force is not a rotating vector), the splines'
    interior knots, s from the first sample (empty when it is not), and the co-rotating
    harmonics k it holds (:data:`FORCE_HARMONICS`).  ``noise``: the force's
    white-noise σ per sample of ``u``, N, where ``u`` was low-passed (default: estimated from ``u``).

    The load cells resolve the force's own noise (0.5 N is a load cell's too), and the model,
    driven by the measured force, would ring its barely damped swinging modes with the noise
    at their frequencies.  A rotating unbalance's force is a vector A(t) e^{iφ(t)} whose
    amplitude and phase vary slowly once the motor runs at speed: both are fitted with
    least-squares cubic splines (the phase weighted by A², its noise's inverse variance), knots
    every :data:`RAMP_KNOT` s while the motor spins up and every :data:`STEADY_KNOT` s after, so
    the noise left is within ~1/(2·STEADY_KNOT) Hz of the rotation's frequency.  A co-rotating
    harmonic (:data:`FORCE_HARMONICS`: the component turning k + 1 times per revolution) is the
    readings less the vector, turned back by k + 1 times the phase, fitted with the splines of the
    span after the spin-up (where the spin-up's knots would take in the swing itself), all of them
    at once with the counter-rotating part (:data:`COUNTER_ROTATING`, which alone would leak into
    them at the span's ends); it is kept
    where those splines hold more than noise alone would (σ² χ² with two degrees of freedom per
    coefficient, false-alarm probability :data:`HARMONIC_P`).  The readings'
    constant offset (a load cell's bias, or the weight of a rotor spinning about a horizontal axis,
    which its bearing carries: part of the suspended body's weight, not a force that moves it) is
    not part of the vector (:func:`_offset`): it is taken out of the input (the readings, an
    output, keep it: each channel's offset is eliminated).  A force that is
    not such a vector (its fit leaves more than twice the noise and :data:`ROTATING_SHARE` of the
    amplitude) is low-passed at ``band`` Hz
    instead (zero-phase 4th-order Butterworth).  The spin-up's force is the least well known
    (its noise is near the swinging modes' frequencies while the motor passes them): the fit
    starts :data:`SETTLE` s after it, from a free state.  What noise the splines keep is not
    left in the input: the rig fit corrects the force within the same splines with the exciter's
    readings as an output (:class:`~rig_identification.estimation.rig_unknowns.Layout` ``force``), so
    the load cells inform the force too and the fit is an output-error fit with no noisy input
    (no errors-in-variables bias)."""
    fallback = sosfiltfilt(butter(4, band, fs=1.0 / dt, output="sos"), u, axis=0), 0, np.zeros(0), ()
    n = len(u)
    t = dt * np.arange(n)
    z = u[:, 0] + 1j * u[:, 1]
    amp = np.abs(z)
    steady = np.median(amp[n // 2:])
    noise = white_sigma(u) if noise is None else noise
    if steady < 20 * noise:
        return fallback
    slow = sosfiltfilt(butter(2, 0.5, fs=1.0 / dt, output="sos"), amp)
    ramp_end = t[np.argmax(slow >= 0.9 * steady)] + 1.0
    z = z - _offset(z, t >= ramp_end)
    amp = np.abs(z)
    knots = np.unique(np.concatenate([np.arange(0.0, ramp_end, RAMP_KNOT),
                                      np.linspace(ramp_end, t[-1],
                                                  max(2, int(round((t[-1] - ramp_end) / STEADY_KNOT)) + 1))]))
    knots = knots[(knots > t[0]) & (knots < t[-1])]
    inner = np.concatenate([[t[0]] * 4, knots, [t[-1]] * 4])
    phase = np.unwrap(np.angle(z))
    w = np.maximum(amp, noise) ** 2
    try:
        phase_s = make_lsq_spline(t, phase, inner, k=3, w=w / w.max())(t)
        amp_s = make_lsq_spline(t, amp, inner, k=3)(t)
    except (ValueError, np.linalg.LinAlgError):
        return fallback
    zs = amp_s * np.exp(1j * phase_s)
    if np.sqrt(np.mean(np.abs(z - zs) ** 2) / 2) > max(2 * noise, ROTATING_SHARE * steady):
        return fallback
    first = int(min(n - 1, np.ceil((ramp_end + SETTLE) / dt)))
    # the harmonics over the steady span only, on its knots (the spin-up's, every RAMP_KNOT s, would
    # take in the swing's own frequencies there), fitted together with the counter-rotating part,
    # which would otherwise leak into them at the span's ends
    steady_t = t >= ramp_end
    ts, ph = t[steady_t], phase_s[steady_t]
    inner_s = np.concatenate([[ts[0]] * 4, knots[knots > ramp_end], [ts[-1]] * 4])
    try:
        basis = BSpline.design_matrix(ts, inner_s, 3).toarray()
    except ValueError:
        return np.column_stack([zs.real, zs.imag]), first, knots, ()
    m = basis.shape[1]
    turns = (COUNTER_ROTATING,) + FORCE_HARMONICS
    design = np.hstack([basis * np.exp(1j * k * ph)[:, None] for k in turns])
    coef = np.linalg.lstsq(design, ((z - zs) * np.exp(-1j * phase_s))[steady_t], rcond=None)[0]
    # a harmonic's splines fitted to noise alone hold σ² χ²(2m) (m coefficients each, real and imaginary)
    kept = chi2.isf(HARMONIC_P, 2 * m) * noise**2
    harmonics: list[int] = []
    for j, k in enumerate(turns[1:], start=1):
        b = basis @ coef[j * m:(j + 1) * m]
        if np.sum(np.abs(b) ** 2) > kept:
            log.info("exciter force: its co-rotating harmonic %d kept (%.2g N, %.3g times noise's threshold)", k + 1,
                     float(np.sqrt(np.mean(np.abs(b) ** 2))), np.sum(np.abs(b) ** 2) / kept)
            zs[steady_t] += b * np.exp(1j * (k + 1) * ph)
            harmonics.append(k)
    return np.column_stack([zs.real, zs.imag]), first, knots, tuple(harmonics)
