"""Data quality of a recording before any fit: units, bad spans, motion.

The same rules for every path that fits a recording (``rig-identify inertia``, ``diagnose``,
the planner's confirmation runs): :func:`check_units` (the tensions against rig.yaml's
weight), :func:`clean_sensors` (gaps, saturated channels, slack cables excluded; the
longest clean span kept; single-sample spikes on the force sensors replaced) and
:func:`check_motion` (a static recording refused).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.signal import butter, sosfiltfilt

from ..io.bad_spans import SPIKE_SIGMA, fill_short_gaps, find_bad_spans, replace_spikes
from ..io.noise import white_sigma
from ..io.recording import EXCITER_TOPIC, LOAD_CELL_PREFIX, Recording, RecordingError, SensorData, TimeSeries, crop

MIN_CLEAN = 15.0  # s: shortest clean span worth fitting (tracker settling + two high-pass periods);
#                   a shorter recording (the thesis's 10 s case studies) needs 75 % of its length clean
MIN_MOTION = 2e-4  # rad/s: RMS of the low-passed gyro about its mean below which the body "hardly moved"
MOTION_SNR = 1.5   # ... or below this multiple of the gyro noise's RMS in that band: a static recording.
#                    Whether a moving body's motion determines the tensor is the validation's
#                    question (predicted σ of each entry, validation.REL_STD_LIMIT), not a gate's


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
    """Exclude bad spans (gaps, saturation, slack cables; :func:`~rig_identification.io.recording.find_bad_spans`):
    keep the longest span free of them, bridge short IMU gaps, replace single-sample spikes on the
    load cells and the exciter (:func:`~rig_identification.io.bad_spans.replace_spikes`).  Appends
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
    """``ts`` with its single-sample spikes replaced (:func:`~rig_identification.io.bad_spans.replace_spikes`),
    a warning appended where there were any."""
    out, stamps = replace_spikes(ts)
    if len(stamps):
        warnings.append(f"{topic}: {len(stamps)} single-sample spike(s) beyond {SPIKE_SIGMA:g} times the noise "
                        f"(electrical interference?) replaced by the cubic through their neighbours, first at "
                        f"t={stamps[0] - t0:.3f} s from the start")
    return out


def check_motion(rec: Recording, s: SensorData) -> None:
    """Refuse a static recording: the gyro low-passed at 10 Hz (zero-phase Butterworth,
    scipy) about its mean must stand out of the noise it would have in that band (σ from
    its third differences, io.noise.white_sigma) by :data:`MOTION_SNR`, and be at least :data:`MIN_MOTION`.
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
    if rms < threshold:
        raise RecordingError(f"{rec.path}: the body did not move (gyro RMS below 10 Hz {rms:.1e} rad/s, no more "
                             f"than its noise there, threshold {threshold:.1e} rad/s): is this a static recording? "
                             "inertia needs a dynamic one")
