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

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .tracker import PoseEstimate, PoseTrack

if TYPE_CHECKING:
    from ..io.recording import SensorData


@dataclass(frozen=True)
class Wrench:
    """Generalized wrench at stamp t: force (3,) N and torque (3,) N·m about the CG, body axes."""

    t: float
    force: np.ndarray
    torque: np.ndarray


@dataclass(frozen=True)
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
    Raises :class:`~rig_identification.io.rig.RigError` if rig.yaml has no CG.
    """
    return _WrenchGeometry(rig)(position, rotation, tensions, exciter_xy)


def _cross_sum(a: np.ndarray, f: np.ndarray) -> np.ndarray:
    """sum_n a_n x f_mn: a (N,3), f (M,N,3) -> (M,3) (np.cross(a, f).sum(1), written out)."""
    f0, f1, f2 = f[..., 0], f[..., 1], f[..., 2]
    return np.stack([(a[:, 1] * f2 - a[:, 2] * f1).sum(1), (a[:, 2] * f0 - a[:, 0] * f2).sum(1),
                     (a[:, 0] * f1 - a[:, 1] * f0).sum(1)], axis=1)


class _WrenchGeometry:
    """The rig constants of :func:`generalized_wrench`, computed once."""

    def __init__(self, rig: Rig):
        c = rig.require_cg()
        self.b = rig.body_anchors
        self.A = rig.ceiling_anchors
        self.arm = self.b - c
        self.exc = None
        if rig.exciter is not None:
            self.exc = (rig.exciter.rotation.as_matrix()[:, :2].T, np.asarray(rig.exciter.position - c, float))

    def __call__(self, position: np.ndarray, rotation: np.ndarray, tensions: np.ndarray,
                 exciter_xy: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        R = np.asarray(rotation, float)
        if R.ndim == 2:
            R = Rotation.from_quat(R).as_matrix()
        # ceiling anchors seen from the body: R^T (A - p) - b, (M, N, 3)
        rel = np.einsum("mji,mnj->mni", R, self.A[None, :, :] - position[:, None, :]) - self.b[None]
        u = rel / np.sqrt(np.einsum("mni,mni->mn", rel, rel))[:, :, None]
        f_cables = tensions[:, :, None] * u
        force = f_cables.sum(1)
        torque = _cross_sum(self.arm, f_cables)
        if exciter_xy is not None and self.exc is not None:
            E, e = self.exc
            fe = exciter_xy @ E
            force = force + fe
            torque = torque + np.stack([e[1] * fe[:, 2] - e[2] * fe[:, 1], e[2] * fe[:, 0] - e[0] * fe[:, 2],
                                        e[0] * fe[:, 1] - e[1] * fe[:, 0]], axis=1)
        return force, torque


class _Samples:
    """One input stream of :class:`WrenchPreprocessor`: stamps (n,) and values (n, k), with
    single samples collected in lists and joined into the arrays on demand."""

    __slots__ = ("t", "v", "_pt", "_pv", "last", "k", "_chunks")

    def __init__(self, k: int):
        self.k = k
        self.t = np.empty(0)
        self.v = np.empty((0, k))
        self._pt: list[Any] = []
        self._pv: list[Any] = []
        self._chunks = False  # _pt/_pv hold arrays (chunks) rather than single samples
        self.last = -math.inf  # latest stamp

    def __len__(self) -> int:
        return len(self.t) + (sum(len(c) for c in self._pt) if self._chunks else len(self._pt))

    def add(self, t: float, *values: float) -> None:
        if self._chunks:
            self.join()
        self._pt.append(t)
        self._pv.append(values)
        self.last = t

    def extend(self, t: np.ndarray, v: np.ndarray) -> None:
        self.join_pending()
        self._pt.append(t)
        self._pv.append(np.asarray(v, float).reshape(len(t), self.k))
        self.last = float(t[-1])
        self._chunks = True

    def join_pending(self) -> None:
        """Single samples -> one chunk."""
        if self._pt and not self._chunks:
            self._pt, self._pv = [np.array(self._pt)], [np.array(self._pv, float).reshape(-1, self.k)]
            self._chunks = True

    def join(self) -> None:
        if self._pt:
            self.join_pending()
            self.t = np.concatenate([self.t, *self._pt])
            self.v = np.concatenate([self.v, *self._pv])
            self._pt, self._pv = [], []
            self._chunks = False

    def drop_before(self, i: int) -> None:
        if i > 0:
            self.t, self.v = self.t[i:], self.v[i:]


class WrenchPreprocessor:
    """Streaming preprocessor: feed poses, tensions and exciter samples in any interleaving.

    Per sample, each ``add_*`` returns the list of :class:`Wrench` that became computable;
    in batches (the node), :meth:`add_poses`, :meth:`add_tension_samples` and
    :meth:`add_exciter_samples` take arrays and :meth:`process` returns a
    :class:`WrenchSeries` — the same numbers either way, and the same interpolation
    (``np.interp``) and formulas (:func:`generalized_wrench`) as the offline
    :func:`preprocess`.  A pose is processed once every stream has a sample at or after
    its stamp.  Poses that cannot be aligned are dropped and counted in ``dropped``:
    older than a stream's first sample, or (``gaps``) between two samples of a stream
    more than ``max_gap`` s apart (a sensor that stopped: no interpolation over the hole).
    ``max_buffer`` bounds the samples kept per stream (oldest dropped).
    """

    def __init__(self, rig: Rig, max_buffer: int = 20000, max_gap: float = 0.1):
        self.rig = rig
        rig.require_cg()
        self.names = rig.cable_names
        self.max_buffer = max_buffer
        self.max_gap = max_gap
        self._cells = {n: _Samples(1) for n in self.names}
        self._exc = _Samples(2) if rig.exciter is not None else None
        self._streams = list(self._cells.values()) + ([self._exc] if self._exc is not None else [])
        self._poses = _Samples(12)  # position (3), rotation matrix (9, row-major)
        self.dropped = 0
        self.gaps = 0
        self._geometry = _WrenchGeometry(rig)

    # --- single samples -------------------------------------------------------------
    def add_pose(self, pose: PoseEstimate) -> list[Wrench]:
        if pose.t <= self._poses.last:
            raise ValueError(f"pose: stamp {pose.t:.6f} s not after the previous one")
        self._poses.add(pose.t, *np.asarray(pose.position, float).tolist(),
                        *np.asarray(pose.matrix, float).ravel().tolist())
        return self._flush()

    def add_tension(self, name: str, t: float, tension: float) -> list[Wrench]:
        q = self._cell(name)
        if t <= q.last:
            raise ValueError(f"load cell {name}: stamp {t:.6f} s not after the previous one")
        q.add(t, float(tension))
        return self._flush()

    def add_exciter(self, t: float, fx: float, fy: float) -> list[Wrench]:
        if self._exc is None:
            return []
        if t <= self._exc.last:
            raise ValueError(f"exciter: stamp {t:.6f} s not after the previous one")
        self._exc.add(t, float(fx), float(fy))
        return self._flush()

    def _flush(self) -> list[Wrench]:
        # cheap test first: a pose waits until every stream has reached its stamp
        p = self._poses
        if not len(p):
            return []
        p.join()
        first = p.t[0]
        if min(s.last for s in self._streams) < first:
            return []
        w = self.process()
        return [Wrench(t, f, m) for t, f, m in zip(w.t.tolist(), w.force, w.torque)]

    # --- batches ----------------------------------------------------------------------
    def _cell(self, name: str) -> _Samples:
        if name not in self._cells:
            raise KeyError(f"cable {name!r} is not in the rig description ({', '.join(self.names)})")
        return self._cells[name]

    @staticmethod
    def _check_increasing(what: str, last: float, t: np.ndarray) -> None:
        if len(t) and (t[0] <= last or (len(t) > 1 and not (t[1:] > t[:-1]).all())):
            raise ValueError(f"{what}: stamps not increasing")

    def add_poses(self, t: np.ndarray, position: np.ndarray, matrix: np.ndarray) -> None:
        """Poses: t (M,) s, position (M,3) world m, matrix (M,3,3) body -> world."""
        t = np.asarray(t, float)
        self._check_increasing("pose", self._poses.last, t)
        if len(t):
            self._poses.extend(t, np.column_stack([position, np.asarray(matrix, float).reshape(len(t), 9)]))

    def add_tension_samples(self, name: str, t: np.ndarray, tension: np.ndarray) -> None:
        """Tensions of one cable: t (M,) s, tension (M,) N."""
        q = self._cell(name)
        t = np.asarray(t, float)
        self._check_increasing(f"load cell {name}", q.last, t)
        if len(t):
            q.extend(t, tension)

    def add_exciter_samples(self, t: np.ndarray, force_xy: np.ndarray) -> None:
        """Exciter force: t (M,) s, force_xy (M,2) N in the exciter frame."""
        if self._exc is None:
            return
        t = np.asarray(t, float)
        self._check_increasing("exciter", self._exc.last, t)
        if len(t):
            self._exc.extend(t, force_xy)

    def process(self) -> WrenchSeries:
        """The wrenches at every buffered pose that all streams now cover (see the class)."""
        for s in self._streams + [self._poses]:
            s.join()
            if len(s.t) > self.max_buffer:
                if s is self._poses:
                    self.dropped += len(s.t) - self.max_buffer
                s.drop_before(len(s.t) - self.max_buffer)
        P = self._poses
        empty = WrenchSeries(np.empty(0), np.empty((0, 3)), np.empty((0, 3)))
        if not len(P.t) or any(not len(s.t) for s in self._streams):
            return empty
        n = int(np.searchsorted(P.t, min(s.t[-1] for s in self._streams), side="right"))
        if n == 0:
            return empty
        tp, pv = P.t[:n], P.v[:n]
        P.drop_before(n)
        ok = None
        vals = []
        for s in self._streams:
            st = s.t
            bad = None
            if tp[0] < st[0]:  # poses before the stream's first sample
                bad = tp < st[0]
            if len(st) > 1 and float((st[1:] - st[:-1]).max()) > self.max_gap:
                j = np.searchsorted(st, tp)  # st[j-1] < tp <= st[j]
                jj = np.minimum(j, len(st) - 1)
                hole = (st[jj] != tp) & (j > 0) & (st[jj] - st[np.maximum(j - 1, 0)] > self.max_gap)
                self.gaps += int(np.count_nonzero(hole if bad is None else hole & ~bad))
                bad = hole if bad is None else bad | hole
            if bad is not None:
                ok = ~bad if ok is None else ok & ~bad
            vals.append([np.interp(tp, st, s.v[:, c]) for c in range(s.k)])
        if ok is not None:
            self.dropped += int(n - np.count_nonzero(ok))
        # keep one sample at or before the last pose for the next interpolation
        for s in self._streams:
            s.drop_before(int(np.searchsorted(s.t, tp[-1], side="right")) - 1)
        if ok is not None and not ok.all():
            tp, pv = tp[ok], pv[ok]
            vals = [[c[ok] for c in v] for v in vals]
        if not len(tp):
            return empty
        tens = np.column_stack([v[0] for v in vals[:len(self.names)]])
        exc = np.column_stack(vals[-1]) if self._exc is not None else None
        f, m = self._geometry(pv[:, :3], pv[:, 3:].reshape(-1, 3, 3), tens, exc)
        return WrenchSeries(tp, f, m)


def preprocess(rig: Rig, track: PoseTrack, sensors: SensorData) -> WrenchSeries:
    """Offline: wrench at every tracked pose stamp that all streams cover.

    Same formulas as :class:`WrenchPreprocessor` (both call :func:`generalized_wrench`),
    vectorised over the recording.  sensors: :class:`~rig_identification.io.recording.SensorData`.
    """
    t = track.t
    lo = max([s.t[0] for s in sensors.load_cells.values()]
             + ([sensors.exciter.t[0]] if sensors.exciter is not None and rig.exciter is not None else []))
    hi = min([s.t[-1] for s in sensors.load_cells.values()]
             + ([sensors.exciter.t[-1]] if sensors.exciter is not None and rig.exciter is not None else []))
    m = (t >= lo) & (t <= hi)
    t = t[m]
    tens = np.column_stack([np.interp(t, sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0])
                            for n in rig.cable_names])
    exc = None
    if rig.exciter is not None and sensors.exciter is not None:
        exc = sensors.exciter.interp(t)
    f, tq = generalized_wrench(rig, track.position[m], track.quaternion[m], tens, exc)
    return WrenchSeries(t, f, tq)
