"""The identifier node's fit over its buffered streams, and its model validation, with the offline core.

:class:`StreamBuffer` keeps the last ``max_seconds`` of what the fit and its validation read, as the
identifier node receives it (``/rig/imu``, ``/rig/generalized_wrench``, ``/rig/pose``);
:func:`identify_window` fits a window of it (:func:`~rig_identification.estimation.identification.identify_inertia`
on the wrench samples in the window, the gyro interpolated to their stamps), and
:func:`validate_stream_fit` validates the fit.

``rig-identify inertia`` validates every fit (:func:`~rig_identification.pipeline.fit_validation.validate_fit`:
the verdict ok | model_error | not_identifiable, σ widened, undetermined entries null).  Besides
the fit's own gyro and torque, the ``weight`` check reads two streams the fit does not use: the
generalized force and the tracked orientation.  :func:`validate_stream_fit` cuts them to the
fit's window as :func:`identify_window` cuts it and hands them to the same core function the
offline path runs (:func:`~rig_identification.pipeline.fit_validation.apply_validation`, the
surplus from :func:`~rig_identification.pipeline.fit_validation.force_weight_surplus`): its
validation is that of ``rig-identify inertia --quick``.

ROS-free (plain numpy), in the core: the identifier node only feeds it.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..estimation.identification import IdentificationError, identify_inertia
from ..estimation.inertia_result import InertiaResult
from ..io.rig import Rig
from .fit_validation import apply_validation, force_weight_surplus, weight_warning

STAMP_MATCH = 1e-6   # s: a pose and a wrench sample are the same instant (the wrench carries the pose's stamp)


class StampedRows:
    """Stamped rows of one stream (stamps strictly increasing, as the node's input guard
    accepts them), kept as the batches they arrive in; batches older than ``max_seconds``
    before the newest stamp are dropped.  ``width``: values per row."""

    def __init__(self, width: int, max_seconds: float):
        self.width = width
        self.max_seconds = float(max_seconds)
        self.batches: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, t, rows) -> None:
        """Append stamps ``t`` (n,) s and rows (n, width)."""
        t = np.asarray(t, float)
        if not len(t):
            return
        rows = np.asarray(rows, float).reshape(len(t), self.width)
        self.batches.append((t.copy(), rows.copy()))
        newest = float(t[-1])
        while len(self.batches) > 1 and self.batches[0][0][-1] < newest - self.max_seconds:
            self.batches.pop(0)

    def between(self, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        """The rows stamped in [lo, hi] s: stamps (n,) and rows (n, width), copies."""
        keep = [(t, v) for t, v in self.batches if t[-1] >= lo and t[0] <= hi]
        if not keep:
            return np.empty(0), np.empty((0, self.width))
        t = np.concatenate([k[0] for k in keep])
        v = np.concatenate([k[1] for k in keep])
        m = (t >= lo) & (t <= hi)
        return t[m], v[m]


@dataclass(frozen=True)
class StreamWindow:
    """The fit's and the validation's streams around a fit window (:meth:`StreamBuffer.snapshot`).

    imu_t (n,) s, imu (n,6): gyro rad/s and specific force m/s², IMU axes; wrench_t (m,) s,
    wrench (m,6): generalized force N and torque N·m about the CG, body axes; pose_t (k,) s,
    quaternion (k,4) x, y, z, w: the tracked orientation, body to world."""

    imu_t: np.ndarray
    imu: np.ndarray
    wrench_t: np.ndarray
    wrench: np.ndarray
    pose_t: np.ndarray
    quaternion: np.ndarray


class StreamBuffer:
    """What the identifier node keeps for its fits and their validation (see module docstring):
    the IMU (gyro and accelerometer), the generalized wrench and the tracked orientation, the
    last ``max_seconds`` s of each."""

    def __init__(self, max_seconds: float = 900.0):
        self.imu = StampedRows(6, max_seconds)
        self.wrench = StampedRows(6, max_seconds)
        self.pose = StampedRows(4, max_seconds)

    def add_imu(self, t, rows) -> None:
        """IMU samples: stamps (n,) s, rows (n,6) gyro rad/s then specific force m/s², IMU axes."""
        self.imu.add(t, rows)

    def add_wrench(self, t, rows) -> None:
        """Generalized wrench samples: stamps (n,) s, rows (n,6) force N then torque N·m, body axes."""
        self.wrench.add(t, rows)

    def add_pose(self, t, quaternion) -> None:
        """Tracked orientations: stamps (n,) s, quaternions (n,4) x, y, z, w, body to world."""
        self.pose.add(t, quaternion)

    def snapshot(self, lo: float, hi: float, margin: float = 1.0) -> StreamWindow:
        """Copies of the streams over [lo − margin, hi + margin] s (take it under the node's
        lock)."""
        a, b = lo - margin, hi + margin
        (ti, vi), (tw, vw), (tp, vp) = (s.between(a, b) for s in (self.imu, self.wrench, self.pose))
        return StreamWindow(ti, vi, tw, vw, tp, vp)


def fit_samples(win: StreamWindow, lo: float, hi: float) -> np.ndarray:
    """The (m,) mask of the wrench samples a fit over [lo, hi] (stamps s) uses: stamped in the
    window and inside the IMU's span (their gyro is interpolated, never extrapolated)."""
    tw, ti = win.wrench_t, win.imu_t
    m = (tw >= lo) & (tw <= hi)
    if len(ti):
        m &= (tw >= ti[0]) & (tw <= ti[-1])
    return m


def identify_window(rig: Rig, win: StreamWindow, lo: float, hi: float, **fit_params) -> InertiaResult:
    """The node's fit over [lo, hi] (stamps s):
    :func:`~rig_identification.estimation.identification.identify_inertia` on the wrench samples
    of :func:`fit_samples` (torque N·m about the CG, body axes) and the gyro interpolated to
    their stamps, turned to body axes.  fit_params: identify_inertia's.  Raises
    :class:`~rig_identification.estimation.identification.IdentificationError` with fewer than
    10 samples."""
    m = fit_samples(win, lo, hi)
    if m.sum() < 10 or len(win.imu_t) < 10:
        raise IdentificationError(f"identifier: no samples in the window [{lo:.3f}, {hi:.3f}] s")
    t = win.wrench_t[m]
    gyro = np.column_stack([np.interp(t, win.imu_t, win.imu[:, k]) for k in range(3)])
    return identify_inertia(rig, t, rig.imu.rotation.apply(gyro), win.wrench[m, 3:], **fit_params)


def validate_stream_fit(rig: Rig, result: InertiaResult, win: StreamWindow, lo: float,
                        hi: float) -> InertiaResult:
    """Validate the node's fit ``result`` over the window [lo, hi] (absolute stamps, s) with the
    offline core (:func:`~rig_identification.pipeline.fit_validation.apply_validation`).

    The samples are those of the fit (:func:`fit_samples`).  The weight check uses the poses
    stamped as the wrench samples; with fewer than 90 % of them matched (no
    ``/rig/pose`` received) it is skipped and a warning says so.  Sets ``result.validation``,
    ``result.weight_surplus``; widens σ; adds the verdict's and the weight's warnings.
    Returns the validated result (a new record).  Never raises on bad numbers (the core does not)."""
    m = fit_samples(win, lo, hi)
    t = win.wrench_t[m]
    surplus = None
    if len(t) >= 10 and len(win.pose_t):
        i = np.clip(np.searchsorted(win.pose_t, t), 0, len(win.pose_t) - 1)
        same = np.abs(win.pose_t[i] - t) <= STAMP_MATCH
        if same.mean() >= 0.9:
            surplus = force_weight_surplus(rig, win.quaternion[i[same]], win.wrench[m][same, :3])
    skipped = [] if surplus is not None else \
        ["the weight check did not run: no tracked orientation (/rig/pose) at the fit's samples"]
    result = apply_validation(replace(result, warnings=result.warnings + skipped, weight_surplus=surplus), surplus,
                              rig)
    note = weight_warning(surplus, rig)
    return result if note is None else replace(result, warnings=result.warnings + [note])
