"""A recording's data quality before any fit: the noise level of a channel, the spans a fit must
leave out, the units of the tensions and whether the body moved.

- :func:`white_sigma`: the white-noise level of a sampled signal, estimated from the signal itself
  (the package's one noise estimator: the reader's saturation rule, the validation, every stream's σ).
- The spans a fit must leave out: gaps (dropped messages), saturated channels, slack cables
  (:func:`find_bad_spans`, the offline rule; the identifier node's gap rule is the same,
  :class:`~rig_identification.nodes.inputs.InputGuard`); :func:`fill_short_gaps` bridges the gaps up
  to :data:`SHORT_GAP`, :func:`replace_spikes` replaces isolated samples far off their neighbours
  (electrical interference on a force sensor's cable).  Stamps in s.
- The same rules for every path that fits a recording (``rig-identify inertia``, ``diagnose``, the
  planner's confirmation runs): :func:`check_units` (the tensions against rig.yaml's weight),
  :func:`clean_sensors` (gaps, saturated channels, slack cables excluded; the longest clean span
  kept; single-sample spikes on the force sensors replaced) and :func:`check_motion` (a static
  recording refused).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import median_filter
from scipy.signal import butter, sosfiltfilt

from .recording import (
    EXCITER_TOPIC,
    IMU_TOPIC,
    LOAD_CELL_PREFIX,
    Recording,
    RecordingError,
    SensorData,
    TimeSeries,
    crop,
)
from .rig import Rig

THIRD_DIFF_NORM = math.sqrt(20.0)   # ‖(1, −3, 3, −1)‖: σ of the third difference of white noise / σ
MAD_NORM = 1.482602218505602        # σ / median absolute deviation of a normal variable


def white_sigma(x: np.ndarray) -> float:
    """White-noise σ of a sampled signal ``x`` (N,) or (N, k) (pooled over columns), from the
    median absolute deviation of its third differences: a smooth motion sampled ≥ 20× faster
    than it varies contributes < 1 % (its third difference is (2π f/fs)³ times its amplitude),
    and isolated steps do not move a median.  Returns 0.0 for fewer than 8 samples."""
    x = np.asarray(x, float)
    if x.ndim == 1:
        x = x[:, None]
    if len(x) < 8:
        return 0.0
    d = np.diff(x, n=3, axis=0)
    d = d[np.isfinite(d).all(axis=1)]
    if not len(d):
        return 0.0
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return float(np.sqrt(np.mean((MAD_NORM * mad / THIRD_DIFF_NORM) ** 2)))


SHORT_GAP = 0.1          # s: gaps up to this are bridged by interpolation, longer ones are excluded
SATURATION_RUN = 5       # identical samples at a channel's extreme that make a saturated run
SLACK_FRACTION = 0.05    # tension below this fraction of the cable's share of the weight = slack
SPIKE_WINDOW = 41        # samples over which a spike's local scale is the running median (replace_spikes)
SPIKE_SIGMA = 20.0       # a sample this many local scales off the cubic through its neighbours is a spike
SPIKE_PEAK = 1.3         # an isolated sample's departure is 1.5× its neighbours'; an edge's or a pulse's
#                          of two samples or more is about theirs (replace_spikes)
SPIKE_RESOLUTION = 1e-3  # the local scale's floor as a share of the channel's level: a noise-free
#                          simulated force's kink (0.3 N of 300 N where a spin-up ramp ends) is no spike


@dataclass(frozen=True)
class BadSpan:
    """A span of one topic where the data cannot be trusted (``reason``); stamps in s."""

    topic: str
    t0: float
    t1: float
    reason: str


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [i, j] (inclusive) of consecutive True in ``mask``."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0] - 1))


def find_bad_spans(rig: Rig, sensors: SensorData) -> list[BadSpan]:
    """Spans to exclude from a fit: gaps longer than :data:`SHORT_GAP` (dropped messages),
    saturated channels (runs of >= :data:`SATURATION_RUN` identical samples at the
    channel's extreme, in a channel that is noisy elsewhere — :func:`~rig_identification.io.quality.white_sigma`
    of the other samples above zero) and slack cables (tension below :data:`SLACK_FRACTION` of the
    cable's share of the weight)."""
    spans: list[BadSpan] = []
    streams = [(IMU_TOPIC, sensors.imu)] + [(LOAD_CELL_PREFIX + n, s) for n, s in sensors.load_cells.items()]
    if sensors.exciter is not None and rig.exciter is not None:
        streams.append((EXCITER_TOPIC, sensors.exciter))
    for topic, s in streams:
        if len(s) < 3:
            continue
        dt = np.diff(s.t)
        med = float(np.median(dt))
        for g in np.nonzero(dt > max(SHORT_GAP, 1.5 * med))[0]:
            spans.append(BadSpan(topic, float(s.t[g]), float(s.t[g + 1]),
                                 f"gap of {dt[g]:.2f} s (dropped messages)"))
        for k, col in enumerate(s.data.T):
            if np.ptp(col) == 0:
                continue
            runs = [(ext, i, j) for ext in (col.max(), col.min()) for i, j in _runs(col == ext)
                    if j - i + 1 >= SATURATION_RUN]
            if not runs:
                continue
            # a sensor that saturates is noisy elsewhere; a noise-free stream (a simulation:
            # stepped forces, say) may hold a value exactly and is not saturated
            inside = np.zeros(len(col), bool)
            for _, i, j in runs:
                inside[i:j + 1] = True
            if white_sigma(col[~inside]) == 0.0:
                continue
            for ext, i, j in runs:
                spans.append(BadSpan(topic, float(s.t[i]), float(s.t[j]),
                                     f"saturated (channel {k} stuck at {ext:.6g} for {j - i + 1} samples)"))
    share = rig.mass * rig.gravity / len(rig.cables)
    for name, s in sensors.load_cells.items():
        for i, j in _runs(s.data[:, 0] < SLACK_FRACTION * share):
            spans.append(BadSpan(LOAD_CELL_PREFIX + name, float(s.t[max(i - 1, 0)]),
                                 float(s.t[min(j + 1, len(s) - 1)]),
                                 f"cable {name} slack (tension below {SLACK_FRACTION * share:.0f} N; "
                                 "the rigid-cable model does not hold)"))
    return spans


def fill_short_gaps(ts: TimeSeries) -> tuple[TimeSeries, list[tuple[float, float]]]:
    """Insert linearly interpolated samples into gaps of a nearly uniform stream.

    Returns the filled series and the filled spans (t0, t1)."""
    if len(ts) < 3:
        return ts, []
    dt = np.diff(ts.t)
    med = float(np.median(dt))
    idx = np.nonzero(dt > 1.5 * med)[0]
    if not len(idx):
        return ts, []
    new = [np.arange(ts.t[i] + med, ts.t[i + 1] - 0.5 * med, med) for i in idx]
    t = np.sort(np.concatenate([ts.t, *new]))
    return TimeSeries(t, ts.interp(t)), [(float(ts.t[i]), float(ts.t[i + 1])) for i in idx]


def replace_spikes(ts: TimeSeries) -> tuple[TimeSeries, np.ndarray]:
    """Replace single-sample spikes by the cubic through the two samples on each side.

    A sample's departure from that cubic, d_k = x_k − (−x_{k−2} + 4 x_{k−1} + 4 x_{k+1} − x_{k+2})/6,
    is what no smooth motion gives (its error is (h⁴/36)·x⁗: 0.01 N for a 300 N tension swing at
    1 Hz sampled at 200 Hz); a spike is a sample whose |d_k| exceeds :data:`SPIKE_SIGMA` times the
    local scale of d (1.4826 × the running median of |d| over :data:`SPIKE_WINDOW` samples, robust
    to the spikes; at least the channel's white-noise σ, :func:`~rig_identification.io.quality.white_sigma`,
    and :data:`SPIKE_RESOLUTION` of its median absolute value)
    and :data:`SPIKE_PEAK` times its neighbours' |d| (a spike at k moves d_{k±1} by 2/3 of itself;
    a step's edge or a pulse of two samples or more moves two neighbouring d alike).  Two or more
    bad samples in a row are not single-sample spikes and stay.  Returns the series (a copy where any was
    replaced) and the stamps (k,) s of the replaced samples."""
    x = ts.data
    if len(x) < SPIKE_WINDOW:
        return ts, np.zeros(0)
    pred = np.copy(x)
    pred[2:-2] = (-x[:-4] + 4 * x[1:-3] + 4 * x[3:-1] - x[4:]) / 6.0
    d = np.abs(x - pred)
    floor = np.array([max(white_sigma(c), SPIKE_RESOLUTION * np.median(np.abs(c))) for c in x.T])[None, :]
    scale = np.maximum(1.4826 * median_filter(d, size=(SPIKE_WINDOW, 1), mode="nearest"), floor)
    peak = np.zeros_like(d, dtype=bool)
    peak[1:-1] = d[1:-1] > SPIKE_PEAK * np.maximum(d[:-2], d[2:])
    bad = peak & (d > SPIKE_SIGMA * scale)
    if not bad.any():
        return ts, np.zeros(0)
    return TimeSeries(ts.t, np.where(bad, pred, x)), ts.t[bad.any(axis=1)]


MIN_CLEAN = 15.0  # s: shortest clean span worth fitting (tracker settling + two high-pass periods);
#                   a shorter recording (the thesis's 10 s case studies) needs 75 % of its length clean
MIN_MOTION = 2e-4  # rad/s: RMS of the low-passed gyro about its mean below which the body "hardly moved"
MOTION_SNR = 1.5   # ... or below this multiple of the gyro noise's RMS in that band, and every tension
#                    below TENSION_SNR: a static recording.
#                    Whether a moving body's motion determines the tensor is the validation's
#                    question (predicted σ of each entry, validation.REL_STD_LIMIT), not a gate's
TENSION_BAND = (0.1, 10.0)  # Hz: a tension's motion; its load cell's drift and zero below, the cables' ringing above
#: A tension's RMS in TENSION_BAND over its noise's there below which it did not move: band-passed
#: white noise reads ~1 (a static record's 0.9–1.8, a settling swing among them); a shaken rig's
#: 20–500 (bench_any_rig 21057, whose gyro stayed within its noise).
TENSION_SNR = 5.0


def check_units(rec: Recording) -> None:
    """Refuse tensions whose sum is not the body's weight within a factor 0.5–50 (kN for N,
    g for kg).  Raises :class:`RecordingError` naming the recording."""
    rig, s = rec.rig, rec.sensors
    total = np.sum([np.median(s.load_cells[n].data[:, 0]) for n in rig.cable_names])
    weight = rig.mass * rig.gravity
    if not 0.5 <= total / weight <= 50.0:
        raise RecordingError(f"{rec.path}: the load-cell tensions (median sum {total:.4g} N) do not match the "
                             f"weight in rig.yaml (body.mass × gravity = {weight:.4g} N): check the units of the "
                             "tensions (N, not kN) and body.mass (kg)")


def clean_sensors(rec: Recording, warnings: list[str]) -> SensorData:
    """Exclude bad spans (gaps, saturation, slack cables; :func:`find_bad_spans`):
    keep the longest span free of them, bridge short IMU gaps, replace single-sample spikes on the
    load cells and the exciter (:func:`~rig_identification.io.quality.replace_spikes`).  Appends
    one warning per excluded span and per force sensor with spikes.  Raises
    :class:`RecordingError` if less than :data:`MIN_CLEAN` s (in a shorter recording, 75 % of its
    length) remain.  Returns the cleaned
    :class:`~rig_identification.io.recording.SensorData` (a new object; ``rec`` is not changed)."""
    s = rec.sensors
    t0, t_end = s.t_start, s.t_end
    spans = sorted(find_bad_spans(rec.rig, s), key=lambda b: b.t0)
    a, b = t0, t_end
    if spans:
        edges, cur = [], t0
        for sp in spans:
            if sp.t0 > cur:
                edges.append((cur, sp.t0))
            cur = max(cur, sp.t1)
        if cur < t_end:
            edges.append((cur, t_end))
        a, b = max(edges, key=lambda e: e[1] - e[0]) if edges else (t0, t0)
        what = "; ".join(f"{sp.topic}: {sp.reason} at t={sp.t0 - t0:.2f}–{sp.t1 - t0:.2f} s" for sp in spans[:5])
        if len(spans) > 5:
            what += f"; and {len(spans) - 5} more"
        need = min(MIN_CLEAN, 0.75 * (t_end - t0))
        if b - a < need:
            raise RecordingError(f"{rec.path}: after excluding the bad spans ({what}) the longest clean span is "
                                 f"{b - a:.1f} s (t={a - t0:.1f}–{b - t0:.1f} s), less than the {need:.3g} s "
                                 "needed for a trustworthy fit")
        for sp in spans:
            warnings.append(f"{sp.topic}: {sp.reason} at t={sp.t0 - t0:.2f}–{sp.t1 - t0:.2f} s from the start; "
                            f"span excluded, fit on the longest clean span t={a - t0:.2f}–{b - t0:.2f} s")
        s = crop(s, a, b)
    imu, filled = fill_short_gaps(s.imu)
    if filled:
        s = replace(s, imu=imu)     # a copy: the recording given is not changed
        warnings.append(f"{'/rig/imu'}: {len(filled)} short gap(s) (≤ 0.1 s) bridged by linear interpolation, "
                        f"first at t={filled[0][0] - t0:.2f}–{filled[0][1] - t0:.2f} s from the start")
    cells = dict(s.load_cells)
    for name, ts in s.load_cells.items():
        cells[name] = _despiked(ts, LOAD_CELL_PREFIX + name, t0, warnings)
    s = replace(s, load_cells=cells)
    if s.exciter is not None:
        s = replace(s, exciter=_despiked(s.exciter, EXCITER_TOPIC, t0, warnings))
    return s


def _despiked(ts: TimeSeries, topic: str, t0: float, warnings: list[str]) -> TimeSeries:
    """``ts`` with its single-sample spikes replaced (:func:`~rig_identification.io.quality.replace_spikes`),
    a warning appended where there were any."""
    out, stamps = replace_spikes(ts)
    if len(stamps):
        warnings.append(f"{topic}: {len(stamps)} single-sample spike(s) beyond {SPIKE_SIGMA:g} times the noise "
                        f"(electrical interference?) replaced by the cubic through their neighbours, first at "
                        f"t={stamps[0] - t0:.3f} s from the start")
    return out


def check_motion(rec: Recording, s: SensorData) -> None:
    """Refuse a static recording: neither the gyro nor any load cell moved out of its noise.
    The gyro low-passed at 10 Hz (zero-phase Butterworth, scipy) about its mean must stand out of
    the noise it would have in that band (σ from its third differences,
    io.quality.white_sigma) by :data:`MOTION_SNR`, and be at least :data:`MIN_MOTION`; or a
    tension band-passed at :data:`TENSION_BAND` Hz (its drift and zero left out; the lower edge at
    least four cycles over the record) must stand out of
    its noise there by :data:`TENSION_SNR`: through the stiff cables the load cells see a motion
    the gyro's noise hides (the tensions are the rig model's outputs).
    A body that moved, however little, is fitted: whether that motion determines each
    entry is the validation's verdict (``not_identifiable``), from the entries' σ.
    Raises :class:`RecordingError`."""
    g = s.imu.data[:, :3]
    fs = 1.0 / np.median(np.diff(s.imu.t))
    f_lp = min(10.0, 0.4 * fs)
    sm = sosfiltfilt(butter(4, f_lp, fs=fs, output="sos"), g - g.mean(0), axis=0)
    rms = float(np.sqrt(np.mean(np.sum(sm**2, axis=1))))
    noise = white_sigma(g) * np.sqrt(3 * 2 * f_lp / fs)
    threshold = max(MOTION_SNR * noise, MIN_MOTION)
    if rms >= threshold:
        return
    snr = 0.0
    for c in s.load_cells.values():
        fc = 1.0 / np.median(np.diff(c.t))
        x = c.data[:, 0]
        band = (max(TENSION_BAND[0], 4 * fc / len(x)), min(TENSION_BAND[1], 0.4 * fc))
        sigma = white_sigma(x) * np.sqrt(2 * (band[1] - band[0]) / fc)
        if band[0] < band[1] and sigma > 0:
            swing = sosfiltfilt(butter(2, band, btype="bandpass", fs=fc, output="sos"), x - x.mean())
            snr = max(snr, float(np.sqrt(np.mean(swing**2))) / sigma)
    if snr < TENSION_SNR:
        raise RecordingError(f"{rec.path}: the body did not move (gyro RMS below 10 Hz {rms:.1e} rad/s, no more "
                             f"than its noise there, threshold {threshold:.1e} rad/s; the tensions at most "
                             f"{snr:.2g}× their noise below {TENSION_BAND[1]:g} Hz, threshold {TENSION_SNR:g}×): "
                             "is this a static recording? inertia needs a dynamic one")
