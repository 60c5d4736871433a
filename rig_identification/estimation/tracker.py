"""Tracker: pose of the suspended body in ``world`` from the IMU and the rig geometry.

The thesis's tracker (section 3.4, "Tracker" block) integrated noise-free body
signals.  Integrating a real gyro drifts (random walk, bias), so this tracker is a
causal complementary filter that uses everything the rig gives:

* **orientation**: strapdown integration of the gyro (third-order Adams–Moulton
  quadrature of ω over each interval, exact rotation exponential) — accurate in the
  band where the rig moves;
* **tilt** (roll, pitch w.r.t. gravity): the inclinometer's two elevations when the
  rig has one, else the accelerometer's gravity direction, blended in with a time
  constant ``tau_tilt``;
* **yaw and position**: the cables' length constraints ``|A_i - p - R b_i| = L_i (+ T_i/k_i)``
  (thesis eqs. 2.13–2.19; stretch T/k when rig.yaml gives the stiffness), blended
  in with ``tau_yaw`` and a second-order filter of natural frequency ``f_position``
  on the accelerometer-integrated position.

Above the crossover frequencies (well below the rig's pendulum modes) the pose
follows the inertial sensors exactly; below them the absolute references remove the
drift, so the pose does not wander over long recordings.

Stepped inputs (the thesis's force pulses, cases 1–8): where the specific force jumps
between two samples — a second difference above ``step_accel`` followed by its opposite
(:func:`~rig_identification.estimation.gyro_fit.step_indices`) — the quadratures do not
interpolate across the jump.  The step is placed at the first
sample that shows it (zero-order hold: an input switched on the sampling clock, as the
thesis's 0.01 s Simulink pulses) — the interval before it is integrated from the samples
before, the interval after it by the trapezoidal rule.  Interpolating across it instead
puts the step half a sample early, which moved Ixx of thesis case 2 by +0.27 %.  The jump
is recognised one sample late (it needs the next sample), so the velocity and position
of that sample are corrected then.

The per-sample filter is compiled with numba
(:mod:`~rig_identification.estimation.tracker_kernel`); offline replay over a recording
(merged streams, one compiled loop): :mod:`~rig_identification.estimation.tracker_replay`.

Frames: ``position`` is the world position of the body-frame origin (m); the
quaternion (x, y, z, w) rotates body axes to world axes; ``omega`` is the angular
velocity in body axes (rad/s); ``velocity`` is the origin's velocity in world (m/s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from . import tracker_kernel as kernel

Z = np.array([0.0, 0.0, 1.0])
YAW_PRIOR = 1e-3   # yaw regularisation of the cable-length correction, relative to the position information


class TrackerError(ValueError):
    """The tracker cannot find a pose consistent with the rig geometry."""


class PoseEstimate:
    """One tracked pose.

    t: stamp, s.  position: (3,) world, m, of the body origin.  matrix: (3,3) rotation
    body -> world; quaternion: (4,) xyzw of the same rotation (computed on first use when
    not given).  omega: (3,) body axes, rad/s.  velocity: (3,) world, m/s.
    """

    __slots__ = ("t", "position", "matrix", "omega", "velocity", "_quat")

    def __init__(self, t: float, position: np.ndarray, matrix: np.ndarray, omega: np.ndarray,
                 velocity: np.ndarray, quaternion: np.ndarray | None = None):
        self.t, self.position, self.matrix, self.omega, self.velocity = t, position, matrix, omega, velocity
        self._quat = quaternion

    @property
    def quaternion(self) -> np.ndarray:
        if self._quat is None:
            self._quat = Rotation.from_matrix(self.matrix).as_quat()
        return self._quat

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_matrix(self.matrix)


@dataclass(frozen=True)
class PoseTrack:
    """A tracked trajectory: t (N,), position (N,3), quaternion (N,4) xyzw, omega (N,3), velocity (N,3)."""

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    omega: np.ndarray
    velocity: np.ndarray

    @classmethod
    def from_estimates(cls, poses: "list[PoseEstimate] | PoseTrack") -> "PoseTrack":
        """The track of a list of poses; a :class:`PoseTrack` (what
        :func:`~rig_identification.estimation.tracker_replay.replay` returns) is returned as it is."""
        if isinstance(poses, PoseTrack):
            return poses
        quat = Rotation.from_matrix(np.array([p.matrix for p in poses])).as_quat()
        return cls(np.array([p.t for p in poses]), np.array([p.position for p in poses]), quat,
                   np.array([p.omega for p in poses]), np.array([p.velocity for p in poses]))


def inclinometer_elevations(rotation: Rotation, incl_to_body: Rotation) -> np.ndarray:
    """Elevations (2,) rad of the inclinometer's x and y axes above the horizontal.

    ``asin(z_world . x_incl)``, ``asin(z_world . y_incl)`` (docs/recording_format.md).
    """
    m = (rotation * incl_to_body).as_matrix()
    elevations: np.ndarray = np.arcsin(np.clip(m[2, :2], -1.0, 1.0))
    return elevations


def cable_vectors(rig: Rig, position: np.ndarray, rotation: Rotation) -> np.ndarray:
    """Vectors (N, 3) world, m, from each body anchor to its ceiling anchor."""
    vectors: np.ndarray = rig.ceiling_anchors - (position + rotation.apply(rig.body_anchors))
    return vectors


@dataclass(frozen=True)
class StaticPose:
    """Pose at rest: position (3,) world m, rotation body->world, cable compliance (N,) m/N
    (1/stiffness; fitted when rig.yaml gives none), effective unstretched lengths (N,) m
    consistent with that pose, and the normalised residuals of the fit."""

    position: np.ndarray
    rotation: Rotation
    compliance: np.ndarray
    lengths: np.ndarray
    residuals: np.ndarray


COMPLIANCE_PRIOR = 2e-7  # m/N: a steel cable of a few metres (k = 5e6 N/m), static_pose's prior


@dataclass(frozen=True)
class _PoseProblem:
    """The weighted least squares of :func:`static_pose` in x = (rotation vector body -> world
    (3,) rad, position (3,) world m[, common compliance of the cables without stiffness, 1e-7
    m/N]).

    L (N,) m unstretched lengths; T (N,) N tensions (zeros when ``has_tensions`` is false);
    elevations (2,) rad or None; incl the inclinometer -> body rotation or None; up_imu (3,)
    the accelerometer's up direction in IMU axes, used when the elevations are not; f_up (3,)
    m/s² the specific force in body axes or None; f_exc (3,) N body axes; cg (3,) body m or
    None; known (N,) whether rig.yaml gives each stiffness k (N,) N/m; use_moment: the moment
    balance about cg is a residual; fit_c: x holds the common compliance; sigma_len m: the
    length residuals' σ.
    """

    rig: Rig
    L: np.ndarray
    T: np.ndarray
    has_tensions: bool
    elevations: np.ndarray | None
    incl: Rotation | None
    up_imu: np.ndarray | None
    f_up: np.ndarray | None
    f_exc: np.ndarray
    cg: np.ndarray | None
    at_rest: bool
    known: np.ndarray
    k: np.ndarray
    use_moment: bool
    fit_c: bool
    sigma_len: float

    def compliance(self, x: np.ndarray) -> np.ndarray:
        """Cable compliances (N,) m/N at x: 1/k where known, else the fitted one (``fit_c``),
        :data:`COMPLIANCE_PRIOR` with tensions, 0 without."""
        c = np.where(self.known, 1.0 / np.where(self.known, self.k, 1.0),
                     0.0 if not self.has_tensions else COMPLIANCE_PRIOR)
        if self.fit_c:
            c = np.where(self.known, c, x[6] * 1e-7)
        return c

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Normalised residuals at x: the cable lengths, the tilt (:meth:`tilt`), with tensions
        the force and moment balance (:meth:`balance`), and the compliance's prior."""
        rot = Rotation.from_rotvec(x[:3])
        v = cable_vectors(self.rig, x[3:6], rot)
        lv = np.linalg.norm(v, axis=1)
        r = [(lv - self.L - self.T * self.compliance(x)) / self.sigma_len]
        tilt = self.tilt(rot)
        if tilt is not None:
            r.append(tilt)
        if self.has_tensions:
            r.extend(self.balance(rot, v, lv))
        if self.fit_c:
            r.append([(x[6] * 1e-7 - COMPLIANCE_PRIOR) / 1e-6])
        return np.concatenate(r)

    def tilt(self, rot: Rotation) -> np.ndarray | None:
        """Tilt residuals of the pose ``rot``: the inclinometer's elevations (2,), else the
        accelerometer's up direction (3,), each with σ 1e-4; None with neither."""
        if self.elevations is not None and self.incl is not None:
            elevations: np.ndarray = (inclinometer_elevations(rot, self.incl) - self.elevations) / 1e-4
            return elevations
        if self.up_imu is not None:
            up: np.ndarray = ((rot * self.rig.imu.rotation).inv().apply(Z) - self.up_imu) / 1e-4
            return up
        return None

    def balance(self, rot: Rotation, v: np.ndarray, lv: np.ndarray) -> list[np.ndarray]:
        """Horizontal force balance (2,) (at rest or without specific force: the weight, σ 1 N;
        else Newton's law with the accelerometer, σ 5 % of the weight) and, with
        ``use_moment``, the moment balance (3,) about cg (σ 0.2 N m) of the pose ``rot``, cable
        vectors v (N, 3) world m of lengths lv (N,) m."""
        rig = self.rig
        f_b = self.T[:, None] * rot.inv().apply(v / lv[:, None])
        if self.at_rest or self.f_up is None:  # weight, exact
            r = [(rot.apply(f_b.sum(0) + self.f_exc) - [0.0, 0.0, rig.mass * rig.gravity])[:2] / 1.0]
        else:  # Newton's law with the accelerometer (its bias, ~0.05 m/s^2, sets the weight)
            r = [(rot.apply(f_b.sum(0) + self.f_exc - rig.mass * self.f_up))[:2] / (0.05 * rig.mass)]
        if self.use_moment:
            m = np.cross(rig.body_anchors - self.cg, f_b).sum(0)
            if rig.exciter is not None:
                m = m + np.cross(rig.exciter.position - self.cg, self.f_exc)
            r.append(m / 0.2)
        return r


def _pose_problem(rig: Rig, tensions: np.ndarray | None, elevations: np.ndarray | None,
                  specific_force: np.ndarray | None, exciter_force_body: np.ndarray | None,
                  cg: np.ndarray | None, at_rest: bool) -> _PoseProblem:
    """The least squares of :func:`static_pose` for these readings (its parameters)."""
    k = rig.cable_stiffness
    known = np.isfinite(k)
    use_moment = tensions is not None and cg is not None and at_rest
    fit_c = use_moment and not known.all()
    incl = rig.inclinometer.rotation if rig.inclinometer is not None else None
    up_imu = None
    if (elevations is None or incl is None) and specific_force is not None:
        up_imu = np.asarray(specific_force, float) / np.linalg.norm(specific_force)
    f_up = None
    if specific_force is not None:
        f_up = rig.imu.rotation.apply(np.asarray(specific_force, float))  # body axes
    return _PoseProblem(
        rig=rig, L=rig.cable_lengths, T=np.zeros(len(rig.cables)) if tensions is None else np.asarray(tensions, float),
        has_tensions=tensions is not None, elevations=elevations, incl=incl, up_imu=up_imu, f_up=f_up,
        f_exc=np.zeros(3) if exciter_force_body is None else np.asarray(exciter_force_body, float), cg=cg,
        at_rest=at_rest, known=known, k=k, use_moment=use_moment, fit_c=fit_c,
        sigma_len=1e-4 if (fit_c or known.all() or tensions is None) else 5e-4)


def _initial_guess(rig: Rig, guess: tuple[np.ndarray, Rotation] | None, fit_c: bool) -> np.ndarray:
    """Starting x of :func:`static_pose`: ``guess`` (position (3,) world m, rotation), else no
    rotation and the body hanging below the ceiling anchors' mean offset by the cables' mean
    drop; with ``fit_c`` the compliance's prior appended."""
    if guess is None:
        L = rig.cable_lengths
        rel = rig.ceiling_anchors[:, :2] - rig.body_anchors[:, :2]
        drop = np.sqrt(np.maximum(L**2 - np.sum((rel - rel.mean(0)) ** 2, 1), 0.01))
        p0 = np.r_[rel.mean(0), (rig.ceiling_anchors[:, 2] - rig.body_anchors[:, 2] - drop).mean()]
        x0: np.ndarray = np.r_[np.zeros(3), p0]
    else:
        x0 = np.r_[guess[1].as_rotvec(), guess[0]]
    if fit_c:
        x0 = np.r_[x0, COMPLIANCE_PRIOR * 1e7]
    return x0


def static_pose(rig: Rig, tensions: np.ndarray | None = None, elevations: np.ndarray | None = None,
                specific_force: np.ndarray | None = None, exciter_force_body: np.ndarray | None = None,
                cg: np.ndarray | None = None, guess: tuple[np.ndarray, Rotation] | None = None,
                at_rest: bool = True) -> StaticPose:
    """Pose of the body at rest from the cable geometry and what the sensors say.

    Weighted least squares (scipy) on:

    * the N cable-length constraints (thesis eqs. 2.13–2.16), stretched by ``T/k``
      — with rig.yaml's stiffness, or with one common compliance fitted here when the
      stiffness is unknown and tensions are given (steel cables stretch 1–2 mm, which
      otherwise shows up as a yaw error of ~0.5 mrad and a large spurious moment);
    * the inclinometer elevations (thesis: direction cosines c31, c32), or else the
      accelerometer's gravity direction;
    * with tensions, the horizontal force balance (thesis eqs. 2.20–2.21; with the
      specific force, Newton's law ``sum T u + F_exc = m R f`` so that it also holds
      when a step force starts the motion) and, when the body is ``at_rest`` (no
      exciter force, no rotation) and the CG ``cg`` (3,) body m is known, the moment
      balance about it (eqs. 2.23–2.25) with one fitted cable compliance.

    tensions: (N,) N.  elevations: (2,) rad.  specific_force: (3,) m/s^2, IMU axes.
    exciter_force_body: (3,) N.  Raises :class:`TrackerError` if no consistent pose exists.
    """
    problem = _pose_problem(rig, tensions, elevations, specific_force, exciter_force_body, cg, at_rest)
    x0 = _initial_guess(rig, guess, problem.fit_c)
    sol = least_squares(problem.residuals, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    worst = float(np.max(np.abs(sol.fun))) if sol.fun.size else 0.0
    if worst > 50.0:
        raise TrackerError(f"no pose of the body matches the cable lengths and the sensor readings "
                           f"(worst normalised residual {worst:.0f}); check the rig.yaml geometry and units")
    rot = Rotation.from_rotvec(sol.x[:3])
    c = problem.compliance(sol.x)
    lv = np.linalg.norm(cable_vectors(rig, sol.x[3:6], rot), axis=1)
    return StaticPose(sol.x[3:6].copy(), rot, c, lv - problem.T * c, sol.fun)

def _vec(x: ArrayLike) -> np.ndarray:
    """A fresh float64 array of ``x`` (the compiled filter updates its arrays in place)."""
    return np.array(x, float)


def _at_end(samples: list[tuple[float, np.ndarray]], t_end: float, moving: bool) -> np.ndarray:
    """The value of (stamp s, reading (k,)) ``samples`` at the stamp ``t_end`` s: their mean
    at rest; when ``moving``, a quadratic (a line under 4 samples) through them taken at
    ``t_end`` (their mean under 3 samples or when their stamps do not differ)."""
    ts = np.array([s[0] for s in samples])
    x = np.array([s[1] for s in samples], float)
    if not moving or len(x) < 3 or np.ptp(ts) <= 0:
        mean: np.ndarray = x.mean(0)
        return mean
    c = np.polynomial.polynomial.polyfit(ts - t_end, x, 2 if len(x) >= 4 else 1)
    c0: np.ndarray = c[0]
    return c0


@dataclass(frozen=True)
class _InitWindow:
    """What the samples of :class:`PoseTracker`'s initialisation window say, each at the
    window's last IMU stamp ``t_end`` s (:func:`_at_end`): specific force ``f_imu`` (3,) m/s²
    IMU axes, ``tensions`` (N,) N, inclinometer ``elevations`` (2,) rad, exciter force
    ``exciter`` (3,) N body axes (each None without its stream); ``at_rest``: the gyro reads
    only noise and the exciter less than 10 N; ``gyro`` (3,) rad/s body axes when the body
    already moves (None at rest)."""

    t_end: float
    f_imu: np.ndarray
    tensions: np.ndarray | None
    elevations: np.ndarray | None
    exciter: np.ndarray | None
    at_rest: bool
    gyro: np.ndarray | None


class PoseTracker:
    """Causal complementary-filter tracker (see module docstring).

    Feed samples in stamp order: :meth:`add_inclinometer`, :meth:`add_tensions`
    (optional; used for the cable stretch and the initial pose) and :meth:`add_imu`,
    which returns the pose at the IMU stamp (``None`` during the first
    ``init_time`` seconds, which are averaged to find the initial pose at rest).
    The initial pose is a least-squares fit (:func:`static_pose`); from then on every
    sample goes through the compiled filter
    (:func:`~rig_identification.estimation.tracker_kernel.run`), one event per call here
    (the tracker node) or a whole recording per call (:meth:`track_events`, the offline
    replay): the same numbers either way.

    Parameters: ``tau_tilt`` s (tilt correction time constant), ``tau_yaw`` s,
    ``f_position`` Hz (position correction bandwidth), ``init_time`` s, ``tau_bias`` s
    (gyro-bias estimation; ``gyro_bias`` (3,) rad/s body axes is the current estimate),
    ``tau_tilt_accel`` s (tilt from gravity when the rig has no inclinometer: the
    specific force of a swinging body is vertical only on average, hence the long time),
    ``step_accel`` m/s² (smallest jump of the specific force between two samples treated
    as a stepped input, see the module docstring; 0.2 m/s² is 20× the reference
    accelerometer noise σ — 8× that of a second difference, which white noise does not
    reach).
    """

    def __init__(self, rig: Rig, tau_tilt: float = 2.0, tau_yaw: float = 2.0, f_position: float = 0.1,
                 init_time: float = 0.1, tau_bias: float = 5.0, tau_tilt_accel: float = 30.0,
                 step_accel: float = 0.2):
        self.rig = rig
        self.step_accel = float(step_accel)
        self.steps: list[float] = []  # stamps (s) of the samples where a stepped input was recognised
        self.tau_tilt, self.tau_yaw, self.f_position, self.init_time = tau_tilt, tau_yaw, f_position, init_time
        self.tau_bias, self.tau_tilt_accel = tau_bias, tau_tilt_accel
        self._imu_to_body = rig.imu.rotation
        self._imu_m = self._imu_to_body.as_matrix()
        self._anchors_from_imu = rig.body_anchors - rig.imu.position
        self._incl = rig.inclinometer.rotation if rig.inclinometer is not None else None
        self._g = np.array([0.0, 0.0, -rig.gravity])
        self._tensions: np.ndarray | None = None   # the latest tensions before the initialisation
        self._init: list[tuple[float, np.ndarray, np.ndarray]] = []
        # (stamp, reading) of the other streams during the initialisation window
        self._init_incl: list[tuple[float, np.ndarray]] = []
        self._init_tens: list[tuple[float, np.ndarray]] = []
        self._init_exc: list[tuple[float, np.ndarray]] = []
        self._t_incl: float | None = None
        self.compliance_history: list[tuple[float, np.ndarray]] = []
        # per ~2 s block: (t, Σ e₀ ΔT, Σ ΔT², samples) of the high-passed length residual of inextensible
        # cables e₀ and the tension variation ΔT (see compliance_estimate)
        self.compliance_sums: list[tuple[float, float, float, int]] = []
        # the compiled filter's constants and state, set by the initialisation
        self._const: kernel.Constants | None = None
        self._state: kernel.State | None = None
        # one event at a time (add_*): its arrays, reused
        n = len(rig.cables)
        self._one_t, self._one_kind = np.zeros(1), np.zeros(1, np.int8)
        self._one_index = np.zeros(1, np.int64)
        self._one_imu, self._one_tens, self._one_incl = np.zeros((1, 6)), np.zeros((1, n)), np.zeros((1, 2))
        self._one_out = kernel.outputs(1, n)

    @property
    def initialised(self) -> bool:
        return self._state is not None

    @property
    def t(self) -> float | None:
        """Stamp (s) of the last IMU sample filtered (None before the initialisation)."""
        return None if self._state is None else float(self._state.clock[kernel.T])

    @property
    def filter_state(self) -> kernel.State | None:
        """The compiled filter's state (:class:`~rig_identification.estimation.tracker_kernel.State`,
        arrays the filter updates in place; None before the initialisation)."""
        return self._state

    # --- inputs -------------------------------------------------------------------
    def add_inclinometer(self, t: float, angles: ArrayLike) -> None:
        """Inclinometer elevations (2,) rad (docs/recording_format.md) at stamp ``t`` s."""
        a = np.asarray(angles, float)[:2]
        if self._state is None:
            self._t_incl = t
            self._init_incl.append((t, a))
        else:
            self._one_incl[0] = a
            self._feed_one(t, kernel.EVENT_INCLINOMETER)

    def add_exciter(self, t: float, force_xy: ArrayLike) -> None:
        """Exciter force (2,) N in the exciter frame; used only for the initial pose."""
        if self._state is None and self.rig.exciter is not None:
            self._init_exc.append((t, np.asarray(force_xy, float)[:2]))

    def add_tensions(self, t: float, tensions: dict[str, float] | ArrayLike) -> None:
        """tensions: dict cable name -> N, or (N,) array in rig order."""
        if isinstance(tensions, dict):
            tensions = [tensions[n] for n in self.rig.cable_names]
        T = np.asarray(tensions, float)
        if self._state is None:
            self._init_tens.append((t, T))
            self._tensions = T
        else:
            self._one_tens[0] = T
            self._feed_one(t, kernel.EVENT_TENSIONS)

    def add_imu(self, t: float, gyro: ArrayLike, accel: ArrayLike) -> PoseEstimate | None:
        """One IMU sample: gyro (3,) rad/s and specific force (3,) m/s^2 in IMU axes.
        Returns the pose at ``t`` (None while initialising).  Raises :class:`TrackerError`
        when ``t`` is not after the previous stamp."""
        if self._state is None:
            gyro_b = self._imu_m @ np.asarray(gyro, float)
            f_b = self._imu_m @ np.asarray(accel, float)
            self._init.append((t, gyro_b, f_b))
            if t - self._init[0][0] < self.init_time:
                return None
            self._initialise()
            out = self._one_out
            # _state and _const are set by _initialise (mypy keeps self._state narrowed to None here)
            s = cast(kernel.State, self._state)
            kernel.write_pose(out, 0, float(s.clock[kernel.T]), tuple(s.R.tolist()), tuple(s.p.tolist()),
                              tuple(s.v.tolist()), tuple(s.omega.tolist()),
                              tuple(self._const.r_imu.tolist()))  # type: ignore[union-attr]
        else:
            self._one_imu[0, :3] = gyro
            self._one_imu[0, 3:] = accel
            out = self._feed_one(t, kernel.EVENT_IMU)
        return PoseEstimate(float(out.t[0]), out.position[0].copy(),
                            self._state.R.reshape(3, 3).copy(),  # type: ignore[union-attr]  # initialised above
                            out.omega[0].copy(), out.velocity[0].copy(), out.quaternion[0].copy())

    def track_events(self, t: np.ndarray, kind: np.ndarray, index: np.ndarray, start: int, imu: np.ndarray,
                     tensions: np.ndarray, inclinometer: np.ndarray) -> PoseTrack:
        """Feed the merged events ``start:`` to the initialised filter in one compiled loop
        (the offline replay; the same numbers as feeding them one by one to the ``add_*``
        methods).

        t (E,) s ascending, kind (E,) int8 (``tracker_kernel.EVENT_*``), index (E,) int64: the
        event's row in imu (n, 6) gyro rad/s + specific force m/s² IMU axes, tensions (m, N) N
        in rig cable order, inclinometer (k, 2) rad; exciter events are skipped (they only
        enter the initial pose).  Returns the poses of the IMU events.  Raises
        :class:`TrackerError` before the initialisation or when an IMU stamp is not after the
        previous one (the state is then the one before it).
        """
        if self._state is None:
            raise TrackerError("the tracker is not initialised yet")
        m = int(np.count_nonzero(kind[start:] == kernel.EVENT_IMU))
        out = kernel.outputs(m, len(self.rig.cables))
        status = kernel.run(t, kind, index, start, imu, tensions, inclinometer,
                            self._const, self._state, out)  # type: ignore[arg-type]  # _const: set with _state
        self._record(out)
        if status >= 0:
            raise TrackerError(f"IMU stamp {t[status]:.6f} s is not after the previous one ({self.t:.6f} s)")
        k = int(out.counts[kernel.POSES])
        return PoseTrack(out.t[:k], out.position[:k], out.quaternion[:k], out.omega[:k], out.velocity[:k])

    # the filter's state as numpy arrays (copies)
    @property
    def p(self) -> np.ndarray | None:
        """World position (3,) m of the IMU point."""
        return None if self._state is None else self._state.p.copy()

    @property
    def v(self) -> np.ndarray | None:
        """World velocity (3,) m/s of the IMU point."""
        return None if self._state is None else self._state.v.copy()

    @property
    def omega(self) -> np.ndarray | None:
        """Angular velocity (3,) rad/s, body axes, gyro bias removed."""
        return None if self._state is None else self._state.omega.copy()

    @property
    def gyro_bias(self) -> np.ndarray:
        """Current gyro-bias estimate (3,) rad/s, body axes."""
        return np.zeros(3) if self._state is None else self._state.gyro_bias.copy()

    @property
    def R(self) -> Rotation | None:
        """Current orientation, body -> world (None before initialisation)."""
        return None if self._state is None else Rotation.from_matrix(self._state.R.reshape(3, 3))

    def compliance_estimate(self, since: float) -> float | None:
        """Least-squares cable compliance (m/N, common to the cables rig.yaml gives no
        stiffness) from the blocks after the stamp ``since``: ``Σ e₀ ΔT / Σ ΔT²`` — the
        in-band length residual of inextensible cables regressed on the tension variation,
        the statistic of the online updates (``tracker_kernel.run``) pooled over the
        whole span instead of the median of 2 s updates (smooth in the data, and a smaller
        variance).  None when the tension hardly varied there (as the online gate)."""
        S = [(a, b, n) for t, a, b, n in self.compliance_sums if t >= since]
        if not S:
            return None
        num, den, count = (sum(x[k] for x in S) for k in range(3))
        # the online gate: tension variation ≥ ~16 N RMS per cable
        if den <= 0.1 * 50.0**2 * len(self.rig.cables) * count:
            return None
        return float(np.clip(num / den, 0.0, 1e-5))

    # --- internals ----------------------------------------------------------------
    def _feed_one(self, t: float, kind: int) -> kernel.Outputs:
        """One event (its reading already in the ``_one_*`` arrays) through the compiled filter."""
        self._one_t[0] = t
        self._one_kind[0] = kind
        out = self._one_out
        out.counts[:] = 0
        # (called once initialised: _state and _const are set)
        t_before = float(self._state.clock[kernel.T])  # type: ignore[union-attr]
        status = kernel.run(self._one_t, self._one_kind, self._one_index, 0, self._one_imu, self._one_tens,
                            self._one_incl, self._const, self._state, out)  # type: ignore[arg-type]
        if status >= 0:
            raise TrackerError(f"IMU stamp {t:.6f} s is not after the previous one ({t_before:.6f} s)")
        if out.counts[kernel.STEPS] or out.counts[kernel.HISTORY] or out.counts[kernel.SUMS]:
            self._record(out)
        return out

    def _record(self, out: kernel.Outputs) -> None:
        """Append the filter's recognised steps and compliance records in ``out`` to
        :attr:`steps`, :attr:`compliance_history` and :attr:`compliance_sums`."""
        counts = out.counts.tolist()
        self.steps.extend(out.steps[:counts[kernel.STEPS]].tolist())
        k = counts[kernel.HISTORY]
        self.compliance_history.extend((t, c.copy()) for t, c in zip(out.history_t[:k].tolist(), out.history_c[:k]))
        self.compliance_sums.extend((t, a, b, int(n)) for t, a, b, n in out.sums[:counts[kernel.SUMS]].tolist())

    def _initialise(self) -> None:
        """Set the compiled filter's constants and state from the samples buffered over the
        initialisation window: the pose from :func:`static_pose` (:meth:`_initial_pose`), the
        velocity from the cables' length rates when the body already moves."""
        w = self._init_window()
        pose = self._initial_pose(w)
        Rm = pose.rotation.as_matrix()
        # online compliance refinement (only when rig.yaml gives no stiffness)
        # needs the inclinometer: without it the in-band tilt is too rough to tell stretch
        adapt = bool(w.tensions is not None and w.elevations is not None
                     and not np.isfinite(self.rig.cable_stiffness).all())
        T0 = w.tensions if w.tensions is not None else np.zeros(len(pose.lengths))
        v = np.zeros(3) if w.gyro is None else self._initial_velocity(pose, Rm, w.gyro)
        self._const = self._constants(pose, T0, adapt)
        self._state = self._initial_state(pose, Rm, v, T0, float(w.t_end))
        self._init.clear()

    def _init_window(self) -> _InitWindow:
        """What the buffered initialisation samples say (:class:`_InitWindow`)."""
        t = np.array([s[0] for s in self._init])
        gyro = np.array([s[1] for s in self._init])
        # at rest: the gyro's RMS about zero is its noise (σ from the first differences: the
        # motion is smooth over 0.1 s, the noise white) or below 5 mrad/s — not its largest
        # sample, which the noise alone exceeds on a noisier IMU (then the initial pose came from
        # the geometry alone, whose yaw radially splayed cables leave free: 0.16 rad off)
        noise = float(np.std(np.diff(gyro, axis=0))) / math.sqrt(2.0) if len(gyro) > 2 else 0.0
        quiet = float(np.sqrt(np.mean(gyro**2))) < max(5e-3, 2.0 * noise)
        # a body already swinging (a recording, or a span after an excluded one, that starts
        # in motion; the mean gyro over the window is far above its noise): the readings at
        # the window's last IMU stamp, from a quadratic through the window — their mean
        # would lag by half the window — and the velocity from the cables' length rates
        # (thesis case 7, fitted after a slack span: pose errors 45 mm / 3.6 mrad -> 0.6 mm /
        # 0.07 mrad, the tensor 0.43 % -> 0.006 %)
        moving = float(np.linalg.norm(gyro.mean(0))) > 5e-3
        t_end = t[-1]
        f_b = _at_end([(s[0], s[2]) for s in self._init], t_end, moving)
        tens = _at_end(self._init_tens, t_end, moving) if self._init_tens else None
        elev = _at_end(self._init_incl, t_end, moving) if (self._init_incl and self._incl is not None) else None
        exc = None
        if self._init_exc:   # (only filled when the rig has an exciter: add_exciter)
            exc = self.rig.exciter.rotation.apply(  # type: ignore[union-attr]
                np.r_[_at_end(self._init_exc, t_end, moving), 0.0])
        return _InitWindow(
            t_end=t_end, f_imu=self._imu_to_body.inv().apply(f_b), tensions=tens, elevations=elev, exciter=exc,
            at_rest=bool(quiet and (exc is None or np.linalg.norm(exc) < 10.0)),  # N: ramping exciters start small
            gyro=_at_end([(s[0], s[1]) for s in self._init], t_end, moving) if moving else None)

    def _initial_pose(self, w: _InitWindow) -> StaticPose:
        """The initial pose: first as an equilibrium; if that does not fit (released from a
        displaced pose, or an unmeasured force already acting), from the geometry and Newton's
        law alone (:func:`static_pose`).  Raises :class:`TrackerError` when neither fits."""
        pose = None
        for rest in ((True, False) if w.at_rest else (False,)):
            try:
                pose = static_pose(self.rig, w.tensions, w.elevations, w.f_imu, w.exciter,
                                   cg=self.rig.center_of_gravity, at_rest=rest)
            except TrackerError:
                continue
            if np.max(np.abs(pose.residuals)) <= 5.0:
                break
        if pose is None:
            pose = static_pose(self.rig, None, w.elevations, w.f_imu)
        return pose

    def _initial_velocity(self, pose: StaticPose, Rm: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """World velocity (3,) m/s of the IMU point of a body moving at ``omega`` (3,) rad/s,
        body axes, in ``pose`` (rotation matrix ``Rm``): taut cables keep their lengths, u_i ·
        (v + R (ω × r_i)) = 0 for each cable direction u_i and body anchor r_i from the IMU
        point (the time derivative of thesis eqs. 2.13–2.16; the stretch rate, ~mm/s, is left
        out) — N equations, least squares for v."""
        u = cable_vectors(self.rig, pose.position, pose.rotation)
        u = u / np.linalg.norm(u, axis=1)[:, None]
        rhs = -np.einsum("ij,ij->i", u, np.cross(omega, self._anchors_from_imu) @ Rm.T)
        v: np.ndarray = np.linalg.lstsq(u, rhs, rcond=None)[0]
        return v

    def _constants(self, pose: StaticPose, T0: np.ndarray, adapt: bool) -> kernel.Constants:
        """The compiled filter's constants for the initial ``pose``, tensions ``T0`` (N,) N and
        whether the compliance is refined online (``adapt``)."""
        return kernel.Constants(
            imu_m=_vec(self._imu_m.ravel()), incl_m=_vec(self._incl.as_matrix().ravel() if self._incl is not None
                                                         else np.zeros(9)),
            has_incl=self._incl is not None, anchors=_vec(self._anchors_from_imu),
            ceiling=_vec(self.rig.ceiling_anchors), r_imu=_vec(self.rig.imu.position),
            gravity=float(self.rig.gravity), step_accel=self.step_accel, tau_tilt=float(self.tau_tilt),
            tau_yaw=float(self.tau_yaw), f_position=float(self.f_position), tau_bias=float(self.tau_bias),
            tau_tilt_accel=float(self.tau_tilt_accel), yaw_prior=float(YAW_PRIOR), adapt=adapt,
            fit=~np.isfinite(self.rig.cable_stiffness), l0=_vec(pose.lengths + T0 * pose.compliance), T0=_vec(T0))

    def _initial_state(self, pose: StaticPose, Rm: np.ndarray, v: np.ndarray, T0: np.ndarray,
                       t_end: float) -> kernel.State:
        """The compiled filter's state at the initialisation window's last IMU stamp ``t_end`` s:
        ``pose`` (rotation matrix ``Rm``), the IMU point's velocity ``v`` (3,) m/s world and the
        tensions ``T0`` (N,) N."""
        n = len(pose.lengths)
        a0 = Rm @ self._init[-1][2] + self._g
        clock = np.zeros(4)
        clock[kernel.T], clock[kernel.T_ADAPT] = t_end, t_end
        clock[kernel.T_INCL] = np.nan if self._t_incl is None else self._t_incl
        clock[kernel.T_INCL_USED] = t_end if self._t_incl is None else self._t_incl
        flags = np.zeros(4, np.int64)
        flags[kernel.HAS_TENSIONS] = self._tensions is not None
        return kernel.State(
            R=_vec(Rm.ravel()), p=_vec(pose.position + Rm @ self.rig.imu.position),   # the IMU point
            v=_vec(v), v_prev=_vec(v), omega=_vec(self._init[-1][1]), omega_prev2=np.zeros(3), dphi=np.zeros(3),
            a_hist=_vec([a0, a0, a0]), a_bias=np.zeros(3), gyro_bias=np.zeros(3),
            # constraint lengths consistent with the initial pose (absorbs the static stretch)
            lengths=_vec(pose.lengths), compliance=_vec(pose.compliance),
            tensions=_vec(self._tensions if self._tensions is not None else np.zeros(n)),
            hp_e=np.zeros(n), hp_T=_vec(T0), S=np.zeros(2), blk=np.zeros(3), clock=clock,
            incl_pending=np.zeros(2), flags=flags)
