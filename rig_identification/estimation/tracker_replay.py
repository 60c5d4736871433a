"""Offline replay of the tracker over a recording (:func:`track`, :func:`replay`).

The streams of a recording are merged in stamp order (:func:`merge_events`) and fed to a
:class:`~rig_identification.estimation.tracker.PoseTracker` as the tracker node feeds them; after the
initialisation (Python) the per-sample filter runs compiled with numba
(:mod:`~rig_identification.estimation.tracker_kernel`, the same arithmetic, ~30x faster); without
numba, or with ``compiled=False``, the :class:`~rig_identification.estimation.tracker.PoseTracker`
methods run per sample — the reference, which the tests hold the compiled filter to (1e-9).
The compiled filter takes the tracker's state over through
:meth:`~rig_identification.estimation.tracker.PoseTracker.filter_state` and hands it back through
:meth:`~rig_identification.estimation.tracker.PoseTracker.load_filter_state`.

Frames and units as :mod:`~rig_identification.estimation.tracker`.
"""
from __future__ import annotations

import importlib
import math
import warnings
from dataclasses import dataclass, replace
from types import ModuleType

import numpy as np

from ..io.rig import Rig
from .tracker import YAW_PRIOR, PoseEstimate, PoseTrack, PoseTracker, TrackerError

# kinds of merged events, also their rank among equal stamps (as the tracker node merges them)
EVENT_INCLINOMETER, EVENT_TENSIONS, EVENT_IMU, EVENT_EXCITER = 0, 1, 2, 3


@dataclass(frozen=True)
class Events:
    """The samples of a recording merged in stamp order, as the tracker takes them.

    t: (E,) s, header stamps, ascending; among equal stamps by ``kind`` (EVENT_INCLINOMETER,
    EVENT_TENSIONS, EVENT_IMU, EVENT_EXCITER: the tracker node's ranks), then by ``index``.
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


def merge_events(rig: Rig, sensors, init_time: float) -> Events:
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


def track(rig: Rig, sensors, *, compiled: bool | None = None, **params) -> PoseTrack:
    """Run :class:`PoseTracker` over recorded sensor data (offline replay, same filter as the node).

    sensors: :class:`~rig_identification.io.recording.SensorData`, merged in header-stamp
    order (:func:`merge_events`).  When rig.yaml gives no cable stiffness, a first pass
    refines the cables' compliance online (as the node does); the replay is then run
    again with the pass's least-squares compliance over its second half fixed
    (:func:`pass_compliance`), so that the start of the recording is tracked as well as its
    end.  compiled: as :func:`replay`.  params: :class:`PoseTracker`'s.  Returns the
    :class:`PoseTrack` at the IMU stamps after initialisation.  Raises :class:`TrackerError`.
    """
    poses, tracker = replay(rig, sensors, compiled=compiled, **params)
    c = pass_compliance(tracker, poses)
    if c is not None:
        poses, _ = replay(with_compliance(rig, c), sensors, compiled=compiled, **params)
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


def replay(rig: Rig, sensors, *, compiled: bool | None = None, **params) -> tuple[PoseTrack, PoseTracker]:
    """One pass of a :class:`PoseTracker` over recorded sensor data.

    sensors: :class:`~rig_identification.io.recording.SensorData`, merged by
    :func:`merge_events`.  compiled: None — the compiled filter when numba imports, else
    the Python methods with a warning; True — compiled (ImportError without numba); False —
    the Python methods (the reference).  params: :class:`PoseTracker`'s.  Returns the poses
    at the IMU stamps from the initialisation on and the tracker after the last sample (its
    ``steps``, ``compliance_history``, ``compliance_sums`` and state are the same either
    way).  Raises :class:`TrackerError` when the recording is shorter than the
    initialisation or an IMU stamp does not increase.
    """
    tracker = PoseTracker(rig, **params)
    events = merge_events(rig, sensors, tracker.init_time)
    kernel = None if compiled is False else compiled_kernel(required=bool(compiled))
    out: list[PoseEstimate] = []
    k = 0
    if kernel is None:   # the Python methods for every sample
        for t, kind, row in zip(events.t.tolist(), events.kind.tolist(), events.index.tolist()):
            pose = _feed(tracker, events, t, kind, row)
            if pose is not None:
                out.append(pose)
    else:   # the Python methods up to the initialisation (its least-squares pose), then compiled
        while k < len(events.t) and not out:
            pose = _feed(tracker, events, float(events.t[k]), int(events.kind[k]), int(events.index[k]))
            if pose is not None:
                out.append(pose)
            k += 1
    if not out:
        raise TrackerError("the recording is shorter than the tracker's initialisation time")
    if kernel is None:
        return PoseTrack.from_estimates(out), tracker
    return _run_kernel(kernel, tracker, events, k, out[0]), tracker


def _feed(tracker: PoseTracker, events: Events, t: float, kind: int, row: int) -> PoseEstimate | None:
    """Hand one merged event to the tracker's Python methods; the pose of an IMU sample."""
    if kind == EVENT_IMU:
        return tracker.add_imu(t, events.imu[row, :3], events.imu[row, 3:])
    if kind == EVENT_TENSIONS:
        tracker.add_tensions(t, events.tensions[row])
    elif kind == EVENT_EXCITER:
        tracker.add_exciter(t, events.exciter[row])
    else:
        tracker.add_inclinometer(t, events.inclinometer[row])
    return None


def compiled_kernel(required: bool = False) -> ModuleType | None:
    """The compiled filter (:mod:`~rig_identification.estimation.tracker_kernel`), imported on first
    use (numba is a heavy import, ~0.5 s, which the tracker node does not need).  None, with
    a warning (shown once: Python's default warning filter), when numba cannot be imported;
    ``required``: raise its ImportError then."""
    try:   # lazy: numba is an optional, heavy dependency
        return importlib.import_module(f"{__package__}.tracker_kernel")
    except ImportError as exc:
        if required:
            raise
        warnings.warn(f"numba unavailable ({exc}): the tracker replays in pure Python (~30x slower)",
                      RuntimeWarning, stacklevel=2)
        return None


def _run_kernel(kernel: ModuleType, tracker: PoseTracker, events: Events, start: int,
                first: PoseEstimate) -> PoseTrack:
    """Feed the events ``start:`` to the initialised ``tracker`` through the compiled
    filter; its state, steps and compliance updates are written back to ``tracker``.
    ``first``: the pose at the initialisation.  Returns the poses from ``first`` on."""
    f = tracker.filter_state()
    n = len(f["lengths"])
    m = int(np.count_nonzero(events.kind[start:] == EVENT_IMU))
    const = kernel.Constants(
        imu_m=np.array(f["imu_f"]), incl_m=np.array(f["incl_f"] if f["incl_f"] is not None else (0.0,) * 9),
        has_incl=f["incl_f"] is not None, anchors=np.array(f["anchors_f"], float).reshape(n, 3),
        ceiling=np.array(f["ceiling_f"], float).reshape(n, 3), r_imu=np.array(f["r_imu_f"], float),
        gravity=float(f["gravity"]), step_accel=float(tracker.step_accel), tau_tilt=float(tracker.tau_tilt),
        tau_yaw=float(tracker.tau_yaw), f_position=float(tracker.f_position), tau_bias=float(tracker.tau_bias),
        tau_tilt_accel=float(tracker.tau_tilt_accel), yaw_prior=float(YAW_PRIOR), adapt=bool(f["adapt"]),
        fit=~np.isfinite(tracker.rig.cable_stiffness), l0=np.array(f["l0"], float),
        T0=np.array(f["T0"], float))
    state = _kernel_state(kernel, f)
    out = kernel.Outputs(t=np.empty(m), position=np.empty((m, 3)), quaternion=np.empty((m, 4)),
                         omega=np.empty((m, 3)), velocity=np.empty((m, 3)), steps=np.empty(m),
                         history_t=np.empty(m), history_c=np.empty((m, n)), sums=np.empty((m, 4)),
                         counts=np.zeros(4, np.int64))
    status = kernel.run(events.t, events.kind, events.index, start, events.imu, events.tensions,
                        events.inclinometer, const, state, out)
    _load_kernel_state(kernel, tracker, state, out)
    if status >= 0:
        raise TrackerError(f"IMU stamp {events.t[status]:.6f} s is not after the previous one "
                           f"({tracker.filter_state()['t']:.6f} s)")
    k = int(out.counts[kernel.POSES])
    return PoseTrack(np.r_[first.t, out.t[:k]], np.concatenate([first.position[None], out.position[:k]]),
                     np.concatenate([first.quaternion[None], out.quaternion[:k]]),
                     np.concatenate([first.omega[None], out.omega[:k]]),
                     np.concatenate([first.velocity[None], out.velocity[:k]]))


def _kernel_state(kernel: ModuleType, f: dict):
    """The initialised tracker's filter state ``f`` (:meth:`PoseTracker.filter_state`) as
    :class:`~rig_identification.estimation.tracker_kernel.State`."""
    n = len(f["lengths"])
    clock = np.array([f["t"], f["t_adapt"], np.nan if f["t_incl"] is None else f["t_incl"], f["t_incl_used"]], float)
    flags = np.array([f["n_steps"], f["omega_prev2"] is not None, f["tensions"] is not None,
                      f["incl_pending"] is not None], np.int64)
    vec = lambda x: np.array(x, float)  # noqa: E731
    return kernel.State(
        R=vec(f["R"]), p=vec(f["p"]), v=vec(f["v"]), v_prev=vec(f["v_prev"]),
        omega=vec(f["omega"]), omega_prev2=vec(f["omega_prev2"] or (0.0, 0.0, 0.0)), dphi=vec(f["dphi"]),
        a_hist=vec(f["a_hist"]).reshape(3, 3), a_bias=vec(f["a_bias"]), gyro_bias=vec(f["gyro_bias"]),
        lengths=vec(f["lengths"]), compliance=vec(f["compliance"]),
        tensions=vec(f["tensions"] if f["tensions"] is not None else (0.0,) * n),
        hp_e=vec(f["hp_e"]), hp_T=vec(f["hp_T"]), S=vec(f["S"]), blk=vec(f["blk"]), clock=clock,
        incl_pending=vec(f["incl_pending"] or (0.0, 0.0)), flags=flags)


def _load_kernel_state(kernel: ModuleType, tracker: PoseTracker, s, out) -> None:
    """Write the compiled filter's state ``s`` and records ``out`` back into ``tracker``
    (:meth:`PoseTracker.load_filter_state`: in the types its Python methods keep)."""
    tup = lambda x: tuple(x.tolist())  # noqa: E731
    flags, clock = s.flags.tolist(), s.clock.tolist()
    tracker.load_filter_state(dict(
        R=tup(s.R), p=tup(s.p), v=tup(s.v), v_prev=tup(s.v_prev), omega=tup(s.omega),
        omega_prev2=tup(s.omega_prev2) if flags[kernel.HAS_OMEGA_PREV2] else None,
        dphi=tup(s.dphi), a_hist=tuple(tup(a) for a in s.a_hist), a_bias=tup(s.a_bias), gyro_bias=tup(s.gyro_bias),
        lengths=tup(s.lengths), compliance=tup(s.compliance),
        tensions=tup(s.tensions) if flags[kernel.HAS_TENSIONS] else None,
        hp_e=s.hp_e.tolist(), hp_T=s.hp_T.tolist(), S=s.S.tolist(),
        blk=[float(s.blk[0]), float(s.blk[1]), int(s.blk[2])],
        t=clock[kernel.T], t_adapt=clock[kernel.T_ADAPT],
        t_incl=None if math.isnan(clock[kernel.T_INCL]) else clock[kernel.T_INCL],
        t_incl_used=clock[kernel.T_INCL_USED],
        incl_pending=tup(s.incl_pending) if flags[kernel.INCL_PENDING] else None,
        n_steps=flags[kernel.N_STEPS]))
    counts = out.counts.tolist()
    tracker.steps.extend(out.steps[:counts[kernel.STEPS]].tolist())
    tracker.compliance_history.extend((t, c.copy()) for t, c in zip(out.history_t[:counts[kernel.HISTORY]].tolist(),
                                                                   out.history_c[:counts[kernel.HISTORY]]))
    tracker.compliance_sums.extend((t, a, b, int(k)) for t, a, b, k in out.sums[:counts[kernel.SUMS]].tolist())
