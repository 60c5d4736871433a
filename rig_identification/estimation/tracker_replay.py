"""The nodes' tracker and preprocessor replayed offline over a recording: the poses (:func:`track`,
:func:`replay`), their yaw anchored by the moment balance where the cables leave it free
(:func:`anchor_yaw`), and the recording prepared for the gyro-only fit and the thesis's estimator —
cleaned, tracked, preprocessed into the generalized wrench, cut to the fit window
(:func:`prepare_recording`, :func:`replay_cleaned`, :class:`PreparedRecording`; the one pass
:func:`replay_window`).

The streams of a recording are merged in stamp order (:func:`merge_events`) and fed to a
:class:`~rig_identification.estimation.tracker.PoseTracker`: the samples of its initialisation
one by one, as the tracker node feeds them, the rest in one call of the compiled filter
(:meth:`~rig_identification.estimation.tracker.PoseTracker.track_events`, numba; ~30x faster
than a call per sample).  ``per_sample=True`` feeds every sample through the tracker's
``add_*`` methods instead, as the tracker node does: the same numbers (``test/test_tracker.py``).

Frames and units as :mod:`~rig_identification.estimation.tracker`.

**The yaw anchored.** The tracker (:mod:`rig_identification.estimation.tracker`) corrects position and
yaw toward the cables' length constraints.  Cables splayed radially from the body's centre — their horizontal directions
through the body anchors' centroid, a common rig — do not change length when the body turns
about the vertical, to first order: the yaw is then the gyro's integral alone
(:data:`~rig_identification.estimation.tracker.YAW_PRIOR`), and its starting error stays for the whole recording.  A
constant yaw error ψ₀ turns every cable's horizontal pull in the body axes: the torque the
preprocessor computes is off by ∂M/∂ψ · ψ₀ wherever the tensions vary — on a 3-cable rig,
1.3 mrad put three entries 4–5 σ off while every validation check passed.

The cables do hold the yaw through their *forces* (the bifilar pendulum's restoring moment,
first order in ψ).  Over a window of bounded motion the yaw moment about the CG averages to
the change of angular momentum over the window, ≈ 0 (Newton–Euler: dL/dt = M), so the
computed mean world-z moment is K ψ₀ with K = ∂M̄_z/∂ψ, evaluated by turning the tracked
poses about the vertical through the CG.  :func:`anchor_yaw` removes ψ₀ = M̄_z / K from the
poses when the lengths leave the yaw weakly determined (:func:`yaw_information` below
:data:`YAW_WEAK`); where they determine it, the tracker's yaw is kept.  On the 3-cable rig
the estimate matched the true offset to 1 % (−1.314 vs 1.327 mrad) and the three entries
came back within 2 σ.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..io.quality import check_motion, check_units, clean_sensors
from ..io.recording import Recording, RecordingError, SensorData
from ..io.rig import Rig
from .preprocessor import generalized_wrench, preprocess
from .tracker import PoseEstimate, PoseTrack, PoseTracker, TrackerError
from .tracker_kernel import EVENT_EXCITER, EVENT_IMU, EVENT_INCLINOMETER, EVENT_TENSIONS

log = logging.getLogger(__name__)   # steps (INFO) and warnings as they happen: cli_progress shows them


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


YAW_WEAK = 1e-2          # yaw information / position information below which the yaw is anchored
YAW_MAX_OFFSET = 0.05    # rad: a larger estimate is not a tracker's starting error; the poses are left as they are
YAW_STEP = 1e-4          # rad: the finite difference of K


@dataclass(frozen=True)
class YawAnchor:
    """What :func:`anchor_yaw` did: information — the yaw's information from the cable
    lengths over the position's (:func:`yaw_information`); offset rad — the yaw turned
    out of the poses (0 when not applied); stiffness N·m/rad — K = ∂M̄_z/∂ψ; applied;
    note — why not, when not."""

    information: float
    offset: float = 0.0
    stiffness: float = 0.0
    applied: bool = False
    note: str = ""


def yaw_information(rig: Rig, position: np.ndarray, rotation: Rotation) -> float:
    """How well the cable lengths determine the yaw at a pose: the Schur complement of the
    yaw in the Gauss–Newton matrix GᵀG of the length constraints (rows
    G_i = (−u_i, −(R b_i × u_i)_z), the tracker's; thesis eqs. 2.13–2.19), over the mean
    information per position coordinate (tr of the position block / 3).  Dimensionless,
    m² per m²: 0 for radially splayed cables, ~0.1 for the thesis's rigs.

    position (3,) world m of the body origin; rotation body -> world."""
    rb = rotation.apply(rig.body_anchors)
    v = rig.ceiling_anchors - (position + rb)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    G = np.column_stack([-u, -np.cross(rb, u)[:, 2]])
    A = G.T @ G
    pp, py, yy = A[:3, :3], A[:3, 3], A[3, 3]
    schur = yy - py @ np.linalg.pinv(pp) @ py
    return float(max(schur, 0.0) / max(np.trace(pp) / 3.0, 1e-300))


def anchor_yaw(rig: Rig, track: PoseTrack, sensors: SensorData, lo: float, hi: float) -> tuple[PoseTrack, YawAnchor]:
    """The poses ``track`` with the yaw anchored by the moment balance over the window
    [lo, hi] (absolute stamps, s) where the cable lengths leave it free (module docstring).

    sensors: the cleaned :class:`~rig_identification.io.recording.SensorData` the poses were tracked from (its
    tensions and exciter force give the moments).  Returns (poses, :class:`YawAnchor`): the
    poses turned about the vertical through the CG by −ψ₀ (attitude and the body origin's
    position; the CG and the velocities unchanged), or ``track`` itself when the yaw is
    determined by the lengths, the window is empty or the estimate is beyond
    :data:`YAW_MAX_OFFSET`."""
    cg = rig.require_cg()
    m = (track.t >= lo) & (track.t <= hi)
    if m.sum() < 10:
        return track, YawAnchor(float("nan"), note="no poses in the window")
    R = Rotation.from_quat(track.quaternion[m])
    info = yaw_information(rig, track.position[m].mean(axis=0), R.mean())
    if info >= YAW_WEAK:
        return track, YawAnchor(info, note="the cable lengths determine the yaw")
    t = track.t[m]
    tens = np.column_stack([np.interp(t, sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0])
                            for n in rig.cable_names])
    exc = sensors.exciter.interp(t) if (sensors.exciter is not None and rig.exciter is not None) else None
    # the mean world-z moment about the CG with the poses turned by +YAW_STEP, -YAW_STEP and 0 about
    # the vertical through the CG: the attitude R_z(ψ) R, the body origin p_cg − R_z(ψ) R cg.
    # The world z-axis is R_z's own, so the moment's world z-component is R's third row (as a
    # matrix) times the body-axes moment: R, R cg once for the three trials
    Rm = R.as_matrix()                                              # (n,3,3)
    rc = R.apply(cg)                                                # (n,3) world
    p_cg = track.position[m] + rc
    mz = np.empty(3)
    for k, Rz in enumerate(Rotation.from_rotvec(np.outer([YAW_STEP, -YAW_STEP, 0.0], [0.0, 0.0, 1.0])).as_matrix()):
        _, M = generalized_wrench(rig, p_cg - rc @ Rz.T, np.matmul(Rz, Rm), tens, exc)
        mz[k] = np.mean(np.einsum("nj,nj->n", Rm[:, 2, :], M))
    K = float((mz[0] - mz[1]) / (2 * YAW_STEP))
    if not np.isfinite(K) or K == 0.0:
        return track, YawAnchor(info, note="the cables' forces do not hold the yaw either")
    psi = -float(mz[2]) / K
    if abs(psi) > YAW_MAX_OFFSET:
        return track, YawAnchor(info, psi, K, False, f"the moment balance asks for {psi:.3g} rad: not a tracker's "
                                                    "starting error, the poses are left as they are")
    Rz = Rotation.from_rotvec([0.0, 0.0, psi])
    R_all = Rotation.from_quat(track.quaternion)
    cg_w = track.position + R_all.apply(cg)
    R_new = Rz * R_all
    return replace(track, position=cg_w - R_new.apply(cg), quaternion=R_new.as_quat()), YawAnchor(info, psi, K, True)


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
    sensors: SensorData | None = None   # the cleaned SensorData that was tracked
    poses: PoseTrack | None = None      # the tracker's PoseTrack over it
    window: tuple[float, float] = (0.0, 0.0)  # (lo, hi) absolute stamps, s, of the fit window
    force: np.ndarray | None = None
    yaw_anchor: YawAnchor | None = None     # what the yaw anchoring did (tracker_replay.anchor_yaw)


@dataclass(frozen=True)
class Replay:
    """One pass of tracker, yaw anchoring and preprocessor over a recording
    (:func:`replay_window`): poses (the whole :class:`~rig_identification.estimation.tracker.PoseTrack`); t (N,) s the
    window's pose stamps; gyro_body (N,3) rad/s; torque (N,3) N·m about the CG; force (N,3)
    N, body axes; anchor (:class:`~rig_identification.estimation.tracker_replay.YawAnchor`)."""

    poses: PoseTrack
    t: np.ndarray
    gyro_body: np.ndarray
    torque: np.ndarray
    force: np.ndarray
    anchor: YawAnchor


def replay_window(rig: Rig, s: SensorData, lo: float, hi: float) -> Replay:
    """Tracker -> yaw anchoring (:func:`~rig_identification.estimation.tracker_replay.anchor_yaw`: where
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
    """Clean a dynamic recording (:func:`~rig_identification.io.quality.check_units`,
    :func:`~rig_identification.io.quality.clean_sensors`, :func:`~rig_identification.io.quality.check_motion`;
    the cleaning's warnings logged as they happen), then :func:`replay_cleaned`.  Arguments and
    errors as :func:`replay_cleaned`'s."""
    check_units(rec)
    warnings: list[str] = []
    s = clean_sensors(rec, warnings)
    check_motion(rec, s)
    for w in warnings:
        log.warning(w)
    return replay_cleaned(rec, s, warnings, start, end, settle)


def replay_cleaned(rec: Recording, s: SensorData, warnings: list[str], start: float | None = None,
                   end: float | None = None, settle: float = 5.0) -> PreparedRecording:
    """The tracker and the preprocessor run over ``s``, the cleaned sensors of ``rec`` (their
    cleaning's ``warnings`` kept in the result), the window cut.

    start/end: window in seconds from the first IMU stamp (default: the whole
    recording after ``settle`` s, the tracker's convergence time, at most a tenth of
    the recording).  Raises :class:`~rig_identification.io.recording.RecordingError`,
    :class:`~rig_identification.io.rig.RigError` (no CG in rig.yaml),
    :class:`~rig_identification.estimation.tracker.TrackerError`.
    """
    rig = rec.rig
    rig.require_cg()
    if rig.exciter is not None and rec.sensors.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no "
                             "/rig/exciter/wrench topic")
    t0 = rec.sensors.t_start  # --start/--end count from the recording's first IMU sample
    settle = min(settle, 0.1 * (s.t_end - s.t_start))
    lo = s.t_start + settle if start is None else max(t0 + start, s.t_start + settle)
    hi = s.t_end if end is None else min(t0 + end, s.t_end)
    log.info("tracking the pose and computing the generalized wrench")
    r = replay_window(rig, s, lo, hi)
    poses, t, gyro_body, torque, force = r.poses, r.t, r.gyro_body, r.torque, r.force
    if r.anchor.applied:
        log.info("yaw anchored by the moment balance (%.2f mrad): the cables' lengths leave it free",
                 1e3 * r.anchor.offset)
    if len(t) < 10:
        raise RecordingError(f"{rec.path}: no samples in the window [{lo - t0:.1f}, {hi - t0:.1f}] s")
    return PreparedRecording(rec, t, gyro_body, torque, list(warnings), s, poses, (lo, hi), force,
                             yaw_anchor=r.anchor)
