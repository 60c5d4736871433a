"""Preprocessor: cable tensions + tracked pose + exciter force -> generalized wrench.

The thesis's pre-processor (section 3.4, Figure 3.3) turns the load-cell magnitudes
into force vectors using the tracked pose and sums them into the generalized force
vector.  Here, for each pose stamp:

* cable i pulls the body anchor ``b_i`` toward the ceiling anchor ``A_i`` with the
  measured tension ``T_i``; its direction in body axes is
  ``u_i = R^T (A_i - p - R b_i) / |.|`` (thesis eqs. 2.13–2.19 geometry);
* the exciter force is measured in the exciter frame (x, y) and rotated to body axes
  with ``rig.exciter.rotation``; it acts at ``rig.exciter.position``;
* force ``F = sum T_i u_i + F_exc`` (body axes, N) and moment about the centre of
  gravity ``M = sum (b_i - c) x T_i u_i + (e - c) x F_exc`` (body axes, N·m).

Gravity acts at the CG: it adds no moment and is not included in ``F``, so that
``F / m`` is the specific force of the CG (what an accelerometer at the CG reads).
Measurements are aligned by header stamp: tensions and exciter force are linearly
interpolated to each pose stamp; a pose is processed once every stream has a sample
at or after its stamp.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .rig import Rig
from .tracker import PoseEstimate, PoseTrack


@dataclass
class Wrench:
    """Generalized wrench at stamp t: force (3,) N and torque (3,) N·m about the CG, body axes."""

    t: float
    force: np.ndarray
    torque: np.ndarray


@dataclass
class WrenchSeries:
    """t (N,) s, force (N,3) N, torque (N,3) N·m — body axes, moment about the CG."""

    t: np.ndarray
    force: np.ndarray
    torque: np.ndarray


def generalized_wrench(rig: Rig, position: np.ndarray, rotation: np.ndarray, tensions: np.ndarray,
                       exciter_xy: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised wrench on the body about its CG (see module docstring).

    position: (M,3) world m; rotation: (M,3,3) matrices or (M,4) xyzw quaternions, body ->
    world; tensions: (M,N) N in rig cable order; exciter_xy: (M,2) N in the exciter frame,
    or None.  Returns force (M,3) N and torque (M,3) N·m, body axes.
    Raises :class:`~rig_identification.rig.RigError` if rig.yaml has no CG.
    """
    c = rig.require_cg()
    R = np.asarray(rotation, float)
    if R.ndim == 2:
        R = Rotation.from_quat(R).as_matrix()
    b = rig.body_anchors
    # ceiling anchors seen from the body: R^T (A - p) - b, (M, N, 3)
    rel = np.einsum("mji,mnj->mni", R, rig.ceiling_anchors[None, :, :] - position[:, None, :]) - b[None]
    u = rel / np.sqrt(np.einsum("mni,mni->mn", rel, rel))[:, :, None]
    f_cables = tensions[:, :, None] * u
    force = f_cables.sum(1)
    torque = np.cross(b - c, f_cables).sum(1)
    if exciter_xy is not None and rig.exciter is not None:
        fe = exciter_xy @ rig.exciter.rotation.as_matrix()[:, :2].T
        force = force + fe
        torque = torque + np.cross(rig.exciter.position - c, fe)
    return force, torque


class WrenchPreprocessor:
    """Streaming preprocessor: feed poses, tensions and exciter samples in any interleaving.

    Each ``add_*`` returns the list of :class:`Wrench` that became computable.  Poses
    older than every buffered stream's first sample cannot be aligned and are dropped
    (counted in ``dropped``).
    """

    def __init__(self, rig: Rig, max_buffer: int = 20000):
        self.rig = rig
        rig.require_cg()
        self.names = rig.cable_names
        self._cells = {n: deque(maxlen=max_buffer) for n in self.names}
        self._exc = deque(maxlen=max_buffer) if rig.exciter is not None else None
        self._poses: deque[PoseEstimate] = deque(maxlen=max_buffer)
        self.dropped = 0

    def add_pose(self, pose: PoseEstimate) -> list[Wrench]:
        self._poses.append(pose)
        return self._flush()

    def add_tension(self, name: str, t: float, tension: float) -> list[Wrench]:
        if name not in self._cells:
            raise KeyError(f"cable {name!r} is not in the rig description ({', '.join(self.names)})")
        q = self._cells[name]
        if q and t <= q[-1][0]:
            raise ValueError(f"load cell {name}: stamp {t:.6f} s not after the previous one")
        q.append((t, float(tension)))
        return self._flush()

    def add_exciter(self, t: float, fx: float, fy: float) -> list[Wrench]:
        if self._exc is None:
            return []
        if self._exc and t <= self._exc[-1][0]:
            raise ValueError(f"exciter: stamp {t:.6f} s not after the previous one")
        self._exc.append((t, float(fx), float(fy)))
        return self._flush()

    @staticmethod
    def _interp(q: deque, t: float) -> tuple | None:
        """Linear interpolation in a deque of (t, values...) rows; None if t is out of range."""
        if not q or q[-1][0] < t or q[0][0] > t:
            return None
        # search from the end: poses lag the streams by a few samples at most
        i = len(q) - 1
        while i > 0 and q[i - 1][0] >= t:
            i -= 1
        if q[i][0] == t or i == 0:
            return q[i][1:]
        (t0, *a), (t1, *b) = q[i - 1], q[i]
        w = (t - t0) / (t1 - t0)
        return tuple((1 - w) * x + w * y for x, y in zip(a, b))

    def _flush(self) -> list[Wrench]:
        out = []
        streams = list(self._cells.values()) + ([self._exc] if self._exc is not None else [])
        while self._poses:
            pose = self._poses[0]
            if any(not s or s[-1][0] < pose.t for s in streams):
                break  # wait for every stream to reach this stamp
            self._poses.popleft()
            vals = [self._interp(s, pose.t) for s in streams]
            if any(v is None for v in vals):
                self.dropped += 1
                continue
            tens = np.array([v[0] for v in vals[:len(self.names)]])
            exc = np.array([vals[-1]]) if self._exc is not None else None
            f, m = generalized_wrench(self.rig, pose.position[None], pose.matrix[None], tens[None], exc)
            out.append(Wrench(pose.t, f[0], m[0]))
            # keep one sample at or before the next pose for interpolation
            for s in streams:
                while len(s) > 2 and s[1][0] <= pose.t:
                    s.popleft()
        return out


def preprocess(rig: Rig, track: PoseTrack, sensors) -> WrenchSeries:
    """Offline: wrench at every tracked pose stamp that all streams cover.

    Same formulas as :class:`WrenchPreprocessor` (both call :func:`generalized_wrench`),
    vectorised over the recording.  sensors: :class:`~rig_identification.recording.SensorData`.
    """
    t = track.t
    lo = max([s.t[0] for s in sensors.load_cells.values()] + ([sensors.exciter.t[0]] if sensors.exciter is not None and rig.exciter is not None else []))
    hi = min([s.t[-1] for s in sensors.load_cells.values()] + ([sensors.exciter.t[-1]] if sensors.exciter is not None and rig.exciter is not None else []))
    m = (t >= lo) & (t <= hi)
    t = t[m]
    tens = np.column_stack([np.interp(t, sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0]) for n in rig.cable_names])
    exc = None
    if rig.exciter is not None and sensors.exciter is not None:
        exc = sensors.exciter.interp(t)
    f, tq = generalized_wrench(rig, track.position[m], track.quaternion[m], tens, exc)
    return WrenchSeries(t, f, tq)
