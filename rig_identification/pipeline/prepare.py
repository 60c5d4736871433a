"""A recording prepared for the fit: cleaned, replayed through the tracker, the yaw anchoring and the
preprocessor, cut to the fit window (:func:`prepare_recording`, :class:`PreparedRecording`); the one
replay every fit of a recording makes (:func:`replay_window`).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from ..estimation.preprocessor import preprocess
from ..estimation.quality import check_motion, check_units, clean_sensors
from ..estimation.tracker_replay import track
from ..estimation.yaw_anchor import YawAnchor, anchor_yaw
from ..io.recording import Recording, RecordingError

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them


@dataclass(frozen=True)
class PreparedRecording:
    """A recording replayed through the cleaning, the tracker and the preprocessor, cut
    to the fit window: the identifier's input.

    rec: the recording; t (N,) s (absolute stamps, uniform; tracked pose stamps); gyro_body
    (N,3) rad/s, body axes; torque (N,3) N·m about the CG, body axes; force (N,3) N, body
    axes (the generalized force, weight excluded); warnings: the excluded spans etc.
    (the recording's own reader warnings stay in ``rec.warnings``).
    """

    rec: Recording
    t: np.ndarray
    gyro_body: np.ndarray
    torque: np.ndarray
    warnings: list[str] = field(default_factory=list)
    sensors: object = None      # the cleaned SensorData that was tracked
    poses: object = None        # the tracker's PoseTrack over it
    window: tuple = (0.0, 0.0)  # (lo, hi) absolute stamps, s, of the fit window
    force: np.ndarray | None = None
    yaw_anchor: YawAnchor | None = None     # what the yaw anchoring did (yaw_anchor.anchor_yaw)


@dataclass(frozen=True)
class Replay:
    """One pass of tracker, yaw anchoring and preprocessor over a recording
    (:func:`replay_window`): poses (the whole :class:`~rig_identification.estimation.tracker.PoseTrack`); t (N,) s the
    window's pose stamps; gyro_body (N,3) rad/s; torque (N,3) N·m about the CG; force (N,3)
    N, body axes; anchor (:class:`~rig_identification.estimation.yaw_anchor.YawAnchor`)."""

    poses: object
    t: np.ndarray
    gyro_body: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    anchor: YawAnchor


def replay_window(rig, s, lo: float, hi: float) -> Replay:
    """Tracker -> yaw anchoring (:func:`~rig_identification.estimation.yaw_anchor.anchor_yaw`: where
    the cables leave the
    yaw free) -> preprocessor over the cleaned sensors ``s``; the window [lo, hi] (absolute
    stamps, s): the pass the gyro-only fit makes of a recording.  Returns a :class:`Replay`."""
    poses, anchor = anchor_yaw(rig, track(rig, s), s, lo, hi)
    wrench = preprocess(rig, poses, s)
    m = (wrench.t >= lo) & (wrench.t <= hi)
    gyro = s.imu.interp(wrench.t[m])[:, :3]
    return Replay(poses, wrench.t[m], rig.imu.rotation.apply(gyro), wrench.torque[m], wrench.force[m], anchor)


def prepare_recording(rec: Recording, start: float | None = None, end: float | None = None,
                      settle: float = 5.0) -> PreparedRecording:
    """Clean a dynamic recording, run the tracker and the preprocessor, cut the window.

    start/end: window in seconds from the first IMU stamp (default: the whole
    recording after ``settle`` s, the tracker's convergence time, at most a tenth of
    the recording).  Raises :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError` (no CG in rig.yaml),
    :class:`~rig_identification.estimation.tracker.TrackerError`.
    """
    rig, s = rec.rig, rec.sensors
    rig.require_cg()
    if rig.exciter is not None and s.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no "
                             "/rig/exciter/wrench topic")
    check_units(rec)
    warnings: list[str] = []
    s = clean_sensors(rec, warnings)
    check_motion(rec, s)
    t0 = rec.sensors.t_start  # --start/--end count from the recording's first IMU sample
    settle = min(settle, 0.1 * (s.t_end - s.t_start))
    lo = s.t_start + settle if start is None else max(t0 + start, s.t_start + settle)
    hi = s.t_end if end is None else min(t0 + end, s.t_end)
    for w in warnings:
        log.warning(w)
    log.info("tracking the pose and computing the generalized wrench")
    r = replay_window(rig, s, lo, hi)
    poses, t, gyro_body, torque, force = r.poses, r.t, r.gyro_body, r.torque, r.force
    if r.anchor.applied:
        log.info("yaw anchored by the moment balance (%.2f mrad): the cables' lengths leave it free",
                 1e3 * r.anchor.offset)
    if len(t) < 10:
        raise RecordingError(f"{rec.path}: no samples in the window [{lo - t0:.1f}, {hi - t0:.1f}] s")
    return PreparedRecording(rec, t, gyro_body, torque, warnings, s, poses, (lo, hi), force, yaw_anchor=r.anchor)
