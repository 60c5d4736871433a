"""The diagnosis window: everything a diagnosis needs on the IMU stamps of its window — the
cleaned sensors, the tracked pose (the same cleaning, tracker and yaw anchoring as
``rig-identify inertia``), the generalized wrench's parts, the load cells' least-squares map
(:class:`Window`, :func:`prepare_window`); the pose turned about the vertical for the yaw
anchor's trials (:func:`anchored`, :func:`turned`).  The model it feeds:
:mod:`~rig_identification.diagnosis.model_extension`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from dataclasses import replace as _replace
from functools import cached_property

import numpy as np
from scipy.spatial.transform import Rotation

from ..estimation.quality import check_motion, check_units, clean_sensors
from ..estimation.tracker_replay import pass_compliance, replay
from ..estimation.yaw_anchor import anchor_yaw
from ..io.recording import Recording, RecordingError

GRAM_HADAMARD = 1e-6   # det / product of the diagonal of the cables' wrench Gram matrix below which it is near-singular
WRENCH_SCALE = np.array([1, 1, 1, 1 / 1.5, 1 / 1.5, 1 / 1.5])   # force N vs torque N·m over ~1.5 m


@dataclass
class Window:
    """Everything the diagnosis needs, on the IMU stamps of the window (N samples).

    t (N,) s; omega (N,3) rad/s body axes (gyro); f (N,3) m/s² specific force at the IMU,
    body axes; R (N,3,3) body -> world; v (N,3) CG velocity, body axes, m/s;
    tensions (N,n) N; u (N,n,3) cable directions, body axes; r_cables (n,3) body anchors
    − CG, m; f_exc (N,3) exciter force, body axes, N; r_exc (3,) exciter − CG, m;
    rho (3,) IMU − CG, m; mass kg; g m/s²; imu_rot (3,3) IMU -> body.
    """

    t: np.ndarray
    omega: np.ndarray
    f: np.ndarray
    R: np.ndarray
    v: np.ndarray
    tensions: np.ndarray
    u: np.ndarray
    r_cables: np.ndarray
    f_exc: np.ndarray
    r_exc: np.ndarray
    rho: np.ndarray
    mass: float
    g: float
    imu_rot: np.ndarray
    cable_names: list
    exc_rot: np.ndarray = field(default_factory=lambda: np.eye(3))
    imu_rot_yaml: np.ndarray = field(default_factory=lambda: np.eye(3))   # rig.yaml's IMU -> body
    stiffness: np.ndarray | None = None     # cable stiffness the pose was tracked with, N/m (inf: rigid)
    stiffness_std: float | None = None      # std of the fitted stiffness (tracker's compliance fit), N/m

    @property
    def cable_force(self) -> np.ndarray:
        return self.tensions[:, :, None] * self.u

    @property
    def force(self) -> np.ndarray:
        return self.cable_force.sum(1) + self.f_exc

    @property
    def cable_moment(self) -> np.ndarray:
        return np.cross(self.r_cables[None], self.cable_force)       # (N,n,3)

    @property
    def torque(self) -> np.ndarray:
        return self.cable_moment.sum(1) + np.cross(self.r_exc, self.f_exc)

    @property
    def g_body(self) -> np.ndarray:
        return -self.g * self.R[:, 2, :]                               # Rᵀ (0,0,-g)

    @cached_property
    def tension_map(self) -> np.ndarray:
        """(N,n,6): per sample, the least-squares (minimum-norm) tension corrections δT (N)
        of the generalized wrench (force N, torque N·m, the torque over ~1.5 m:
        :data:`WRENCH_SCALE`), ``δT = pinv(Wᵀ) s·(F, M)`` with W's rows the cables' unit wrench
        (u_i, r_i × u_i) in body axes.  It depends on the pose only, not on any fit: computed
        once per window and kept.  With at
        most six cables, ``pinv(Wᵀ) = (W Wᵀ)⁻¹ W`` (full rank: the normal equations, one
        batched solve); numpy ``pinv`` (an SVD per sample) where W Wᵀ is near-singular (its
        determinant below :data:`GRAM_HADAMARD` of its diagonal's product) or there are more
        cables than wrench components."""
        W = np.concatenate([self.u, np.cross(self.r_cables[None], self.u)], axis=2) * WRENCH_SCALE   # (N,n,6)
        if W.shape[1] > 6:
            return np.linalg.pinv(np.transpose(W, (0, 2, 1)))
        G = W @ np.transpose(W, (0, 2, 1))                                   # (N,n,n)
        weak = np.linalg.det(G) <= GRAM_HADAMARD * np.prod(np.diagonal(G, axis1=1, axis2=2), axis=1)
        out = np.empty_like(W)
        if weak.any():
            out[weak] = np.linalg.pinv(np.transpose(W[weak], (0, 2, 1)))
        if not weak.all():
            out[~weak] = np.linalg.solve(G[~weak], W[~weak])
        return out


def _track(rig, s, cables: str):
    """Tracked poses and the cable stiffness used (N,) N/m.  cables: ``"declared"``: the
    rig.yaml stiffness, fitted by the tracker where rig.yaml gives none (as
    :func:`~rig_identification.estimation.tracker_replay.track`); ``"rigid"``: inextensible where rig.yaml
    gives none; ``"fitted"``: fitted for every cable, whatever rig.yaml says."""

    if cables == "fitted":
        rig = _replace(rig, cables=tuple(_replace(c, stiffness=None) for c in rig.cables))
    known = np.isfinite(rig.cable_stiffness)
    if known.all() or cables == "rigid":
        rig_t = _replace(rig, cables=tuple(c if c.stiffness is not None else _replace(c, stiffness=1e15)
                                           for c in rig.cables))
        out, _ = replay(rig_t, s)
        return out, np.where(known, rig.cable_stiffness, np.inf), None
    out, tracker = replay(rig, s)
    hist = tracker.compliance_history
    if not hist:
        return out, np.where(known, rig.cable_stiffness, np.inf), None
    H = np.array([h[1] for h in hist[len(hist) // 2:]])
    c_ls = pass_compliance(tracker, out)
    c = np.median(H, axis=0) if c_ls is None else np.where(known, H[0], c_ls)
    # the tracker's updates are ~2 s apart, over a ~60 s forgetting horizon: ~30 updates per
    # independent estimate
    c_std = np.std(H, axis=0) / np.sqrt(max(1.0, len(H) / 30.0)) / np.sqrt(max(1, (~known).sum()))
    k = np.where(known, rig.cable_stiffness, 1.0 / np.maximum(c, 1e-12))
    rig_t = _replace(rig, cables=tuple(_replace(cb, stiffness=float(ki)) for cb, ki in zip(rig.cables, k)))
    out, _ = replay(rig_t, s)
    k_std = float(np.median(k[~known]) ** 2 * np.median(c_std[~known]))
    return out, k, k_std


ANCHOR_TURNS = 4      # at most this many turns of the yaw anchor (diagnosis trials: see anchored)
ANCHOR_CONVERGED = 2e-3   # rad: a turn this small leaves a linearisation error of ~1e-6 rad, no further turn


def anchored(rig, poses, s, lo: float, hi: float):
    """The poses with the yaw anchored by the moment balance over [lo, hi], as every fit's
    replay (:func:`~rig_identification.estimation.yaw_anchor.anchor_yaw`) — and, where the
    balance asks for a turn beyond :data:`ANCHOR_CONVERGED` (the anchor's one linearised step
    then leaves ~1 mrad) or beyond its ``MAX_OFFSET`` (which it leaves alone), turned and
    anchored again (at most :data:`ANCHOR_TURNS` turns).  A diagnosis trial of a data error can ask
    for it: where the cable lengths leave the yaw free, the tracker's initial pose at rest
    takes the yaw from the moment balance of the tensions, so a load cell's gain 0.4 % off
    turned it by 35–80 mrad on a random 4-cable rig; the pipeline's anchor leaves a turn
    beyond 50 mrad alone (not a tracker's starting error), and the trial's fit was then
    wrecked (its likelihood ratio −10⁷ beside +1.8·10⁴ 0.2 % away), and a 35 mrad turn left
    ~1 mrad, enough to move the fit's cost by thousands: the exact profile of the gain had
    holes and steps that hid the right cell and value."""
    for _ in range(ANCHOR_TURNS):
        poses, a = anchor_yaw(rig, poses, s, lo, hi)
        if not np.isfinite(a.offset):
            break
        if not a.applied:
            poses = turned(rig, poses, a.offset)
        if abs(a.offset) <= ANCHOR_CONVERGED:
            break
    return poses


def turned(rig, track, psi: float):
    """``track`` turned by ψ rad about the vertical through the centre of gravity (attitude
    and the body origin's position; the CG's position and the velocities unchanged), as
    :func:`~rig_identification.estimation.yaw_anchor.anchor_yaw` turns it."""
    cg = rig.require_cg()
    Rz = Rotation.from_rotvec([0.0, 0.0, psi])
    R_all = Rotation.from_quat(track.quaternion)
    cg_w = track.position + R_all.apply(cg)
    R_new = Rz * R_all
    return _replace(track, position=cg_w - R_new.apply(cg), quaternion=R_new.as_quat())


def prepare_window(rec: Recording, settle: float = 5.0, warnings: list | None = None,
                   cables: str = "declared", imu_rot_yaml: np.ndarray | None = None) -> Window:
    """Clean the recording, track the pose and collect the :class:`Window` (the same
    cleaning and tracker as ``rig-identify inertia``; ``cables`` as :func:`_track`).
    Raises RecordingError, RigError, TrackerError."""
    rig = rec.rig
    cg = rig.require_cg()
    if rig.exciter is not None and rec.sensors.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no /rig/exciter/wrench topic")
    check_units(rec)
    warnings = [] if warnings is None else warnings
    s = clean_sensors(rec, warnings)
    check_motion(rec, s)
    poses, stiffness, stiffness_std = _track(rig, s, cables)
    lo = max([c.t[0] for c in s.load_cells.values()] + ([s.exciter.t[0]] if s.exciter is not None else []))
    hi = min([c.t[-1] for c in s.load_cells.values()] + ([s.exciter.t[-1]] if s.exciter is not None else []))
    lo = max(lo, s.t_start + min(settle, 0.1 * (s.t_end - s.t_start)))
    poses = anchored(rig, poses, s, lo, hi)
    m = (poses.t >= lo) & (poses.t <= hi)
    t = poses.t[m]
    R = Rotation.from_quat(poses.quaternion[m]).as_matrix()
    imu = s.imu.interp(t)
    Rimu = rig.imu.rotation.as_matrix()
    omega, f = imu[:, :3] @ Rimu.T, imu[:, 3:] @ Rimu.T
    T = np.column_stack([np.interp(t, s.load_cells[n].t, s.load_cells[n].data[:, 0]) for n in rig.cable_names])
    rel = np.einsum("mji,mnj->mni", R, rig.ceiling_anchors[None] - poses.position[m][:, None]) - rig.body_anchors[None]
    u = rel / np.linalg.norm(rel, axis=2)[:, :, None]
    if rig.exciter is not None and s.exciter is not None:
        f_exc = s.exciter.interp(t) @ rig.exciter.rotation.as_matrix()[:, :2].T
        r_exc = rig.exciter.position - cg
    else:
        f_exc, r_exc = np.zeros((len(t), 3)), np.zeros(3)
    v_world = poses.velocity[m] + np.einsum("nij,nj->ni", R, np.cross(omega, cg))
    v = np.einsum("nji,nj->ni", R, v_world)
    return Window(t, omega, f, R, v, T, u, rig.body_anchors - cg, f_exc, r_exc, rig.imu.position - cg,
                  rig.mass, rig.gravity, Rimu, list(rig.cable_names),
                  rig.exciter.rotation.as_matrix() if rig.exciter is not None else np.eye(3),
                  imu_rot_yaml=Rimu if imu_rot_yaml is None else imu_rot_yaml, stiffness=stiffness,
                  stiffness_std=stiffness_std)
