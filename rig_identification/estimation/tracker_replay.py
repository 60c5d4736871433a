"""Offline replay of the tracker over a recording (:func:`track`, :func:`replay`).

The streams of a recording are merged in stamp order (:func:`merge_events`) and fed to a
:class:`~rig_identification.estimation.tracker.PoseTracker`: the samples of its initialisation
one by one, as the tracker node feeds them, the rest in one call of the compiled filter
(:meth:`~rig_identification.estimation.tracker.PoseTracker.track_events`, numba; ~30x faster
than a call per sample).  ``per_sample=True`` feeds every sample through the tracker's
``add_*`` methods instead, as the tracker node does: the same numbers (``test/test_tracker.py``).

Frames and units as :mod:`~rig_identification.estimation.tracker`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from ..io.rig import Rig
from .tracker import PoseEstimate, PoseTrack, PoseTracker, TrackerError
from .tracker_kernel import EVENT_EXCITER, EVENT_IMU, EVENT_INCLINOMETER, EVENT_TENSIONS

if TYPE_CHECKING:
    from ..io.recording import SensorData


@dataclass(frozen=True)
class Events:
    """The samples of a recording merged in stamp order, as the tracker takes them.

    t: (E,) s, header stamps, ascending; among equal stamps by ``kind`` (EVENT_INCLINOMETER,
    EVENT_TENSIONS, EVENT_IMU, EVENT_EXCITER: their rank, as the tracker node merges), then by ``index``.
    kind: (E,) int8.  index: (E,) int64, the event's row in its stream's array.  imu: (n, 6)
    gyro rad/s then specific force m/s², IMU axes.  tensions: (m, N) N in rig cable order.
    inclinometer: (k, 2) rad (zero rows without one).  exciter: (j, 2) N, exciter frame
    (zero rows without one).
    """

    t: np.ndarray
    kind: np.ndarray
    index: np.ndarray
    imu: np.ndarray
    tensions: np.ndarray
    inclinometer: np.ndarray
    exciter: np.ndarray


def merge_events(rig: Rig, sensors: SensorData, init_time: float) -> Events:
    """Merge the streams of ``sensors`` (:class:`~rig_identification.io.recording.SensorData`)
    for the tracker: every IMU, inclinometer and tension sample, and the exciter samples of
    the first ``2 init_time`` s (they only enter the initial pose).  Load cells that share
    one clock give one tension event per sample; on different clocks they are interpolated
    at the IMU stamps.  Ordering: (stamp, kind, index), see :class:`Events`."""
    imu_t = np.asarray(sensors.imu.t, float)
    streams = [(imu_t, EVENT_IMU)]   # (stamps, kind), sorted by kind below
    incl = np.zeros((0, 2))
    if sensors.inclinometer is not None:
        incl = np.ascontiguousarray(sensors.inclinometer.data[:, :2], dtype=float)
        streams.append((np.asarray(sensors.inclinometer.t, float), EVENT_INCLINOMETER))
    exc = np.zeros((0, 2))
    if sensors.exciter is not None:
        n_exc = int(np.searchsorted(sensors.exciter.t, sensors.imu.t[0] + 2 * init_time))
        exc = np.ascontiguousarray(sensors.exciter.data[:n_exc, :2], dtype=float)
        streams.append((np.asarray(sensors.exciter.t[:n_exc], float), EVENT_EXCITER))
    cells = [sensors.load_cells[n] for n in rig.cable_names]
    if all(len(c) == len(cells[0]) and np.array_equal(c.t, cells[0].t) for c in cells):
        tens = np.column_stack([c.data[:, 0] for c in cells])
        streams.append((np.asarray(cells[0].t, float), EVENT_TENSIONS))
    else:  # load cells on different clocks: sample them at the IMU stamps
        tens = np.column_stack([np.interp(imu_t, c.t, c.data[:, 0]) for c in cells])
        streams.append((imu_t, EVENT_TENSIONS))
    streams.sort(key=lambda s: s[1])
    t = np.concatenate([ts for ts, _ in streams])
    kind = np.concatenate([np.full(len(ts), k, np.int8) for ts, k in streams])
    index = np.concatenate([np.arange(len(ts), dtype=np.int64) for ts, _ in streams])
    order = np.argsort(t, kind="stable")   # equal stamps keep the (kind, index) order of the concatenation
    return Events(t[order], kind[order], index[order], np.ascontiguousarray(sensors.imu.data[:, :6], dtype=float),
                  np.ascontiguousarray(tens, dtype=float), incl, exc)


def track(rig: Rig, sensors: SensorData, *, per_sample: bool = False, **params: Any) -> PoseTrack:
    """Run :class:`PoseTracker` over recorded sensor data (offline replay, same filter as the node).

    sensors: :class:`~rig_identification.io.recording.SensorData`, merged in header-stamp
    order (:func:`merge_events`).  When rig.yaml gives no cable stiffness, a first pass
    refines the cables' compliance online (as the node does); the replay is then run
    again with the pass's least-squares compliance over its second half fixed
    (:func:`pass_compliance`), so that the start of the recording is tracked as well as its
    end.  per_sample: as :func:`replay`.  params: :class:`PoseTracker`'s.  Returns the
    :class:`PoseTrack` at the IMU stamps after initialisation.  Raises :class:`TrackerError`.
    """
    events = merge_events(rig, sensors, PoseTracker(rig, **params).init_time)   # the same for both passes
    poses, tracker = replay(rig, sensors, per_sample=per_sample, events=events, **params)
    c = pass_compliance(tracker, poses)
    if c is not None:
        del poses, tracker   # (memory: the second pass replaces them)
        poses, _ = replay(with_compliance(rig, c), sensors, per_sample=per_sample, events=events, **params)
    return poses


def pass_compliance(tracker: PoseTracker, poses: PoseTrack) -> float | None:
    """The compliance (m/N) of the cables rig.yaml gives no stiffness, from a first replay
    pass (:func:`replay`'s tracker and poses): :meth:`PoseTracker.compliance_estimate` over
    the pass's second half.  None when every stiffness is known or the pass did not adapt."""
    if np.isfinite(tracker.rig.cable_stiffness).all() or not tracker.compliance_sums or len(poses.t) == 0:
        return None
    return tracker.compliance_estimate(0.5 * (poses.t[0] + poses.t[-1]))


def with_compliance(rig: Rig, c: float) -> Rig:
    """``rig`` with the stiffness 1/c N/m on every cable rig.yaml gives none."""
    return replace(rig, cables=tuple(replace(cb, stiffness=cb.stiffness if cb.stiffness is not None
                                             else 1.0 / max(c, 1e-12)) for cb in rig.cables))


def replay(rig: Rig, sensors: SensorData, *, per_sample: bool = False, events: Events | None = None,
           **params: Any) -> tuple[PoseTrack, PoseTracker]:
    """One pass of a :class:`PoseTracker` over recorded sensor data.

    sensors: :class:`~rig_identification.io.recording.SensorData`, merged by
    :func:`merge_events` (or ``events``, its result for these sensors, this rig's cables and
    the tracker's ``init_time``).  per_sample: feed every sample through the tracker's ``add_*``
    methods (the tracker node's path) instead of one compiled loop after the
    initialisation; the same numbers.  params: :class:`PoseTracker`'s.  Returns the poses
    at the IMU stamps from the initialisation on and the tracker after the last sample (its
    ``steps``, ``compliance_history``, ``compliance_sums`` and state).  Raises
    :class:`TrackerError` when the recording is shorter than the initialisation or an IMU
    stamp does not increase.
    """
    tracker = PoseTracker(rig, **params)
    if events is None:
        events = merge_events(rig, sensors, tracker.init_time)
    out: list[PoseEstimate] = []
    k = 0
    while k < len(events.t) and (per_sample or not out):
        pose = feed(tracker, events, k)
        if pose is not None:
            out.append(pose)
        k += 1
    if not out:
        raise TrackerError("the recording is shorter than the tracker's initialisation time")
    if per_sample:
        return PoseTrack.from_estimates(out), tracker
    rest = tracker.track_events(events.t, events.kind, events.index, k, events.imu, events.tensions,
                                events.inclinometer)
    first = out[0]
    return PoseTrack(np.r_[first.t, rest.t], np.concatenate([first.position[None], rest.position]),
                     np.concatenate([first.quaternion[None], rest.quaternion]),
                     np.concatenate([first.omega[None], rest.omega]),
                     np.concatenate([first.velocity[None], rest.velocity])), tracker


def feed(tracker: PoseTracker, events: Events, k: int) -> PoseEstimate | None:
    """Hand the merged event ``k`` to the tracker's ``add_*`` method of its kind; the pose
    of an IMU sample (None for the other kinds and during the initialisation)."""
    t, kind, row = float(events.t[k]), int(events.kind[k]), int(events.index[k])
    if kind == EVENT_IMU:
        return tracker.add_imu(t, events.imu[row, :3], events.imu[row, 3:])
    if kind == EVENT_TENSIONS:
        tracker.add_tensions(t, events.tensions[row])
    elif kind == EVENT_EXCITER:
        tracker.add_exciter(t, events.exciter[row])
    else:
        tracker.add_inclinometer(t, events.inclinometer[row])
    return None
