"""The spans of a recording a fit must leave out: gaps (dropped messages), saturated channels,
slack cables; short gaps bridged by interpolation; single-sample spikes replaced.

:func:`find_bad_spans` finds them (the offline rule; the identifier node's gap rule is the
same, :class:`~rig_identification.nodes.inputs.InputGuard`), :func:`fill_short_gaps` bridges
the gaps up to :data:`SHORT_GAP`, :func:`replace_spikes` replaces isolated samples far off their
neighbours (electrical interference on a force sensor's cable).  Stamps in s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import median_filter

from .noise import white_sigma
from .recording import EXCITER_TOPIC, IMU_TOPIC, LOAD_CELL_PREFIX, SensorData, TimeSeries
from .rig import Rig

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
    channel's extreme, in a channel that is noisy elsewhere — :func:`~rig_identification.io.noise.white_sigma`
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
    to the spikes; at least the channel's white-noise σ, :func:`~rig_identification.io.noise.white_sigma`,
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
