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
(:func:`~rig_identification.estimation.identification.step_indices`) — the quadratures do not
interpolate across the jump.  The step is placed at the first
sample that shows it (zero-order hold: an input switched on the sampling clock, as the
thesis's 0.01 s Simulink pulses) — the interval before it is integrated from the samples
before, the interval after it by the trapezoidal rule.  Interpolating across it instead
puts the step half a sample early, which moved Ixx of thesis case 2 by +0.27 %.  The jump
is recognised one sample late (it needs the next sample), so the velocity and position
of that sample are corrected then.

Offline replay over a recording (merged streams, the compiled filter):
:mod:`~rig_identification.estimation.tracker_replay`.

Frames: ``position`` is the world position of the body-frame origin (m); the
quaternion (x, y, z, w) rotates body axes to world axes; ``omega`` is the angular
velocity in body axes (rad/s); ``velocity`` is the origin's velocity in world (m/s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..io.rig import Rig

Z = np.array([0.0, 0.0, 1.0])
YAW_PRIOR = 1e-3   # yaw regularisation of the cable-length correction, relative to the position information


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two (3,) vectors (np.cross is slow for single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class TrackerError(ValueError):
    """The tracker cannot find a pose consistent with the rig geometry."""


class PoseEstimate:
    """One tracked pose.

    t: stamp, s.  position: (3,) world, m, of the body origin.  matrix: (3,3) rotation
    body -> world; quaternion: (4,) xyzw of the same rotation (computed on first use).
    omega: (3,) body axes, rad/s.  velocity: (3,) world, m/s.
    """

    __slots__ = ("t", "position", "matrix", "omega", "velocity", "_quat")

    def __init__(self, t: float, position: np.ndarray, matrix: np.ndarray, omega: np.ndarray,
                 velocity: np.ndarray):
        self.t, self.position, self.matrix, self.omega, self.velocity = t, position, matrix, omega, velocity
        self._quat = None

    @property
    def quaternion(self) -> np.ndarray:
        if self._quat is None:
            self._quat = Rotation.from_matrix(self.matrix).as_quat()
        return self._quat

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_matrix(self.matrix)


@dataclass
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

    ``asin(z_world . x_incl)``, ``asin(z_world . y_incl)`` (RECORDING_FORMAT.md).
    """
    m = (rotation * incl_to_body).as_matrix()
    return np.arcsin(np.clip(m[2, :2], -1.0, 1.0))


def cable_vectors(rig: Rig, position: np.ndarray, rotation: Rotation) -> np.ndarray:
    """Vectors (N, 3) world, m, from each body anchor to its ceiling anchor."""
    return rig.ceiling_anchors - (position + rotation.apply(rig.body_anchors))


@dataclass
class StaticPose:
    """Pose at rest: position (3,) world m, rotation body->world, cable compliance (N,) m/N
    (1/stiffness; fitted when rig.yaml gives none), effective unstretched lengths (N,) m
    consistent with that pose, and the normalised residuals of the fit."""

    position: np.ndarray
    rotation: Rotation
    compliance: np.ndarray
    lengths: np.ndarray
    residuals: np.ndarray


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
    L = rig.cable_lengths
    k = rig.cable_stiffness
    known = np.isfinite(k)
    use_moment = tensions is not None and cg is not None and at_rest
    fit_c = use_moment and not known.all()
    T = np.zeros(len(L)) if tensions is None else np.asarray(tensions, float)
    incl = rig.inclinometer.rotation if rig.inclinometer is not None else None
    up_imu = None
    if (elevations is None or incl is None) and specific_force is not None:
        up_imu = np.asarray(specific_force, float) / np.linalg.norm(specific_force)
    f_exc = np.zeros(3) if exciter_force_body is None else np.asarray(exciter_force_body, float)
    c_prior = 2e-7  # m/N: a steel cable of a few metres (k = 5e6 N/m)
    sigma_len = 1e-4 if (fit_c or known.all() or tensions is None) else 5e-4
    f_up = None
    if specific_force is not None:
        f_up = rig.imu.rotation.apply(np.asarray(specific_force, float))  # body axes

    def compliance(x):
        c = np.where(known, 1.0 / np.where(known, k, 1.0), 0.0 if tensions is None else c_prior)
        if fit_c:
            c = np.where(known, c, x[6] * 1e-7)
        return c

    def residuals(x):
        rot = Rotation.from_rotvec(x[:3])
        v = cable_vectors(rig, x[3:6], rot)
        lv = np.linalg.norm(v, axis=1)
        r = [(lv - L - T * compliance(x)) / sigma_len]
        if elevations is not None and incl is not None:
            r.append((inclinometer_elevations(rot, incl) - elevations) / 1e-4)
        elif up_imu is not None:
            r.append(((rot * rig.imu.rotation).inv().apply(Z) - up_imu) / 1e-4)
        if tensions is not None:
            f_b = T[:, None] * rot.inv().apply(v / lv[:, None])
            if at_rest or f_up is None:  # weight, exact
                r.append((rot.apply(f_b.sum(0) + f_exc) - [0.0, 0.0, rig.mass * rig.gravity])[:2] / 1.0)
            else:  # Newton's law with the accelerometer (its bias, ~0.05 m/s^2, sets the weight)
                r.append((rot.apply(f_b.sum(0) + f_exc - rig.mass * f_up))[:2] / (0.05 * rig.mass))
            if use_moment:
                m = np.cross(rig.body_anchors - cg, f_b).sum(0)
                if rig.exciter is not None:
                    m = m + np.cross(rig.exciter.position - cg, f_exc)
                r.append(m / 0.2)
        if fit_c:
            r.append([(x[6] * 1e-7 - c_prior) / 1e-6])
        return np.concatenate(r)

    if guess is None:
        rel = rig.ceiling_anchors[:, :2] - rig.body_anchors[:, :2]
        drop = np.sqrt(np.maximum(L**2 - np.sum((rel - rel.mean(0)) ** 2, 1), 0.01))
        p0 = np.r_[rel.mean(0), (rig.ceiling_anchors[:, 2] - rig.body_anchors[:, 2] - drop).mean()]
        x0 = np.r_[np.zeros(3), p0]
    else:
        x0 = np.r_[guess[1].as_rotvec(), guess[0]]
    if fit_c:
        x0 = np.r_[x0, c_prior * 1e7]
    sol = least_squares(residuals, x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=2000)
    worst = float(np.max(np.abs(sol.fun))) if sol.fun.size else 0.0
    if worst > 50.0:
        raise TrackerError(f"no pose of the body matches the cable lengths and the sensor readings "
                           f"(worst normalised residual {worst:.0f}); check the rig.yaml geometry and units")
    rot = Rotation.from_rotvec(sol.x[:3])
    c = compliance(sol.x)
    lv = np.linalg.norm(cable_vectors(rig, sol.x[3:6], rot), axis=1)
    return StaticPose(sol.x[3:6].copy(), rot, c, lv - T * c, sol.fun)


class PoseTracker:
    """Causal complementary-filter tracker (see module docstring).

    Feed samples in stamp order: :meth:`add_inclinometer`, :meth:`add_tensions`
    (optional; used for the cable stretch and the initial pose) and :meth:`add_imu`,
    which returns the pose at the IMU stamp (``None`` during the first
    ``init_time`` seconds, which are averaged to find the initial pose at rest).

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
        self._r_imu = rig.imu.position
        self._incl = rig.inclinometer.rotation if rig.inclinometer is not None else None
        self._g = np.array([0.0, 0.0, -rig.gravity])
        self._lengths = rig.cable_lengths.copy()
        self._compliance = np.zeros(len(self._lengths))
        self._tensions = None
        self._init: list[tuple[float, np.ndarray, np.ndarray]] = []
        # (stamp, reading) of the other streams during the initialisation window
        self._init_incl: list[tuple[float, np.ndarray]] = []
        self._init_tens: list[tuple[float, np.ndarray]] = []
        self._init_exc: list[tuple[float, np.ndarray]] = []
        self._incl_pending: np.ndarray | None = None
        self._t_incl: float | None = None
        self.compliance_history: list[tuple[float, np.ndarray]] = []
        # per ~2 s block: (t, Σ e₀ ΔT, Σ ΔT², samples) of the high-passed length residual of inextensible
        # cables e₀ and the tension variation ΔT (see compliance_estimate)
        self.compliance_sums: list[tuple[float, float, float, int]] = []
        self._t = None
        # filter state (plain floats, set by _initialise); R: row-major body -> world
        self._R: tuple | None = None
        self._p = self._v = self._omega = None
        self._gyro_bias = (0.0, 0.0, 0.0)
        self._gravity = float(rig.gravity)
        self._imu_f = tuple(self._imu_m.ravel().tolist())
        self._incl_f = tuple(self._incl.as_matrix().ravel().tolist()) if self._incl is not None else None
        self._anchors_f = [tuple(r) for r in self._anchors_from_imu.tolist()]
        self._ceiling_f = [tuple(r) for r in rig.ceiling_anchors.tolist()]
        self._r_imu_f = tuple(np.asarray(self._r_imu, float).tolist())

    @property
    def initialised(self) -> bool:
        return self._R is not None

    # --- inputs -------------------------------------------------------------------
    def add_inclinometer(self, t: float, angles) -> None:
        a = np.asarray(angles, float)[:2]
        self._t_incl = t
        if self._R is None:
            self._init_incl.append((t, a))
        else:
            self._incl_pending = (float(a[0]), float(a[1]))

    def add_exciter(self, t: float, force_xy) -> None:
        """Exciter force (2,) N in the exciter frame; used only for the initial pose."""
        if self._R is None and self.rig.exciter is not None:
            self._init_exc.append((t, np.asarray(force_xy, float)[:2]))

    def add_tensions(self, t: float, tensions) -> None:
        """tensions: dict cable name -> N, or (N,) array in rig order."""
        if isinstance(tensions, dict):
            tensions = [tensions[n] for n in self.rig.cable_names]
        if self._R is None:
            self._init_tens.append((t, np.asarray(tensions, float)))
        self._tensions = tuple(np.asarray(tensions, float).tolist())

    def add_imu(self, t: float, gyro, accel) -> PoseEstimate | None:
        """One IMU sample: gyro (3,) rad/s and specific force (3,) m/s^2 in IMU axes.
        Returns the pose at ``t`` (None while initialising).  Raises :class:`TrackerError`
        when ``t`` is not after the previous stamp."""
        if self._R is None:
            gyro_b = self._imu_m @ np.asarray(gyro, float)
            f_b = self._imu_m @ np.asarray(accel, float)
            self._init.append((t, gyro_b, f_b))
            if t - self._init[0][0] < self.init_time:
                return None
            self._initialise()
            return self._estimate()
        dt = t - self._t
        if dt <= 0:
            raise TrackerError(f"IMU stamp {t:.6f} s is not after the previous one ({self._t:.6f} s)")
        # plain floats from here on: ~10x faster than numpy on 3-vectors (same formulas)
        gx, gy, gz = _floats(gyro)
        ax, ay, az = _floats(accel)
        m00, m01, m02, m10, m11, m12, m20, m21, m22 = self._imu_f
        b0, b1, b2 = self._gyro_bias
        gyro_b = (m00 * gx + m01 * gy + m02 * gz - b0, m10 * gx + m11 * gy + m12 * gz - b1,
                  m20 * gx + m21 * gy + m22 * gz - b2)
        f_b = (m00 * ax + m01 * ay + m02 * az, m10 * ax + m11 * ay + m12 * az, m20 * ax + m21 * ay + m22 * az)
        self._step(dt, gyro_b, f_b)
        self._t = t
        return self._estimate()

    # the filter state, as numpy arrays (the step keeps plain floats)
    @property
    def p(self) -> np.ndarray | None:
        """World position (3,) m of the IMU point."""
        return None if self._p is None else np.array(self._p)

    @property
    def v(self) -> np.ndarray | None:
        """World velocity (3,) m/s of the IMU point."""
        return None if self._v is None else np.array(self._v)

    @property
    def omega(self) -> np.ndarray | None:
        """Angular velocity (3,) rad/s, body axes, gyro bias removed."""
        return None if self._omega is None else np.array(self._omega)

    @property
    def gyro_bias(self) -> np.ndarray:
        """Current gyro-bias estimate (3,) rad/s, body axes."""
        return np.array(self._gyro_bias)

    # the whole filter by name (attribute without its underscore), for the compiled replay
    # (tracker_replay): STATE changes with every sample, SETUP is fixed at the initialisation
    STATE = ("R", "p", "v", "v_prev", "omega", "omega_prev2", "dphi", "a_hist", "a_bias", "gyro_bias", "lengths",
             "compliance", "tensions", "hp_e", "hp_T", "S", "blk", "t", "t_adapt", "t_incl", "t_incl_used",
             "incl_pending", "n_steps")
    SETUP = ("imu_f", "incl_f", "anchors_f", "ceiling_f", "r_imu_f", "gravity", "adapt", "l0", "T0")

    def filter_state(self) -> dict:
        """{name: value} of :attr:`STATE` and :attr:`SETUP`, in the types the per-sample methods
        keep (floats, tuples, lists; R (9,) row-major body -> world; p, v the IMU point, world,
        m, m/s; t* stamps s; None where unset).  Raises :class:`TrackerError` before the
        initialisation."""
        if self._R is None:
            raise TrackerError("the tracker is not initialised yet")
        return {k: getattr(self, "_" + k) for k in self.STATE + self.SETUP}

    def load_filter_state(self, state: dict) -> None:
        """Set the filter's :attr:`STATE` from ``state`` (names and types of :meth:`filter_state`)."""
        for k in self.STATE:
            setattr(self, "_" + k, state[k])

    # --- internals ----------------------------------------------------------------
    def _initialise(self):
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
        # would lag by half the window — and the velocity from the cables' length rates below
        # (thesis case 7, fitted after a slack span: pose errors 45 mm / 3.6 mrad -> 0.6 mm /
        # 0.07 mrad, the tensor 0.43 % -> 0.006 %)
        moving = float(np.linalg.norm(gyro.mean(0))) > 5e-3

        def at_end(samples):
            ts = np.array([s[0] for s in samples])
            x = np.array([s[1] for s in samples], float)
            if not moving or len(x) < 3 or np.ptp(ts) <= 0:
                return x.mean(0)
            c = np.polynomial.polynomial.polyfit(ts - t[-1], x, 2 if len(x) >= 4 else 1)
            return c[0]

        f_b = at_end([(s[0], s[2]) for s in self._init])
        tens = at_end(self._init_tens) if self._init_tens else None
        elev = at_end(self._init_incl) if (self._init_incl and self._incl is not None) else None
        f_imu = self._imu_to_body.inv().apply(f_b)
        exc = None
        if self._init_exc:
            exc = self.rig.exciter.rotation.apply(np.r_[at_end(self._init_exc), 0.0])
        at_rest = quiet and (exc is None or np.linalg.norm(exc) < 10.0)  # N: ramping exciters start small
        # first as an equilibrium; if that does not fit (released from a displaced pose, or
        # an unmeasured force already acting), from the geometry and Newton's law alone
        pose = None
        for rest in ((True, False) if at_rest else (False,)):
            try:
                pose = static_pose(self.rig, tens, elev, f_imu, exc, cg=self.rig.center_of_gravity, at_rest=rest)
            except TrackerError:
                continue
            if np.max(np.abs(pose.residuals)) <= 5.0:
                break
        if pose is None:
            pose = static_pose(self.rig, None, elev, f_imu)
        self._R = tuple(pose.rotation.as_matrix().ravel().tolist())
        Rm = np.array(self._R).reshape(3, 3)
        self._p = tuple((pose.position + Rm @ self._r_imu).tolist())  # the IMU point
        # constraint lengths consistent with the initial pose (absorbs the static stretch)
        self._lengths, self._compliance = tuple(pose.lengths.tolist()), tuple(pose.compliance.tolist())
        # online compliance refinement (only when rig.yaml gives no stiffness)
        # needs the inclinometer: without it the in-band tilt is too rough to tell stretch
        self._adapt = (tens is not None and elev is not None
                       and not np.isfinite(self.rig.cable_stiffness).all())
        T0 = tens if tens is not None else np.zeros(len(self._lengths))
        self._T0 = T0
        self._l0 = pose.lengths + T0 * pose.compliance
        n = len(self._lengths)
        self._hp_e = [0.0] * n
        self._hp_T = T0.tolist()
        self._S = [0.0, 0.0]
        self._blk = [0.0, 0.0, 0]
        self._t_adapt = t[-1]
        self._v = (0.0, 0.0, 0.0)
        if moving:
            # taut cables keep their lengths: u_i · (v + R (ω × r_i)) = 0 for each cable
            # direction u_i and body anchor r_i from the IMU point (the time derivative of
            # thesis eqs. 2.13–2.16; the stretch rate, ~mm/s, is left out) — N equations,
            # least squares for the IMU point's velocity v
            w = at_end([(s[0], s[1]) for s in self._init])
            u = cable_vectors(self.rig, pose.position, pose.rotation)
            u = u / np.linalg.norm(u, axis=1)[:, None]
            rhs = -np.einsum("ij,ij->i", u, np.cross(w, self._anchors_from_imu) @ Rm.T)
            self._v = tuple(np.linalg.lstsq(u, rhs, rcond=None)[0].tolist())
        self._a_bias = (0.0, 0.0, 0.0)
        self._omega = tuple(self._init[-1][1].tolist())
        a0 = tuple((Rm @ self._init[-1][2] + self._g).tolist())
        self._a_hist = (a0, a0, a0)
        self._v_prev = self._v
        self._omega_prev2 = None
        self._dphi = (0.0, 0.0, 0.0)
        self._n_steps = 0
        self._gyro_bias = (0.0, 0.0, 0.0)
        self._t = t[-1]
        self._t_incl_used = self._t_incl if self._t_incl is not None else self._t
        self._init.clear()

    def _step(self, dt: float, gyro_b: tuple, f_b: tuple):
        """One strapdown + correction step (plain floats; R row-major body -> world)."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._R
        o0, o1, o2 = self._omega  # previous sample
        w0, w1, w2 = self._omega_prev2 if self._omega_prev2 is not None else self._omega
        d0, d1, d2 = self._dphi
        g0, g1, g2 = gyro_b
        h = dt / 12
        # a stepped input at the previous sample (module docstring): recognised now that
        # the sample after it shows the specific force stayed there; the world-frame
        # acceleration is re-derived with the previous attitude (a jump of ≥ 0.2 m/s²
        # is not confused with the rotation's own change)
        # (second differences D₋₁ = a₋₁ − 2a₋₂ + a₋₃ and D₀ = a₀ − 2a₋₁ + a₋₂: a step Δ at the
        # previous sample gives D₋₁ ≈ Δ, D₀ ≈ −Δ whatever the slope; see
        # identification.step_indices)
        a_1, a_2, a_3 = self._a_hist
        f0, f1, f2 = f_b
        c0, c1, c2 = self._a_bias
        b0 = r00 * f0 + r01 * f1 + r02 * f2 - c0
        b1 = r10 * f0 + r11 * f1 + r12 * f2 - c1
        b2 = r20 * f0 + r21 * f1 + r22 * f2 - self._gravity - c2
        s0, s1, s2 = a_1[0] - 2 * a_2[0] + a_3[0], a_1[1] - 2 * a_2[1] + a_3[1], a_1[2] - 2 * a_2[2] + a_3[2]
        n1 = math.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
        step = (n1 > self.step_accel
                and math.sqrt((b0 - a_1[0] - a_2[0] + a_3[0]) ** 2 + (b1 - a_1[1] - a_2[1] + a_3[1]) ** 2
                              + (b2 - a_1[2] - a_2[2] + a_3[2]) ** 2) < 0.5 * n1)
        # rotation increment over the interval: third-order Adams–Moulton quadrature of ω
        # through the last three samples (the midpoint rule's (ωh)²/12 amplitude error
        # would bias the tensor by ~0.05 % at 100 Hz sampling) — the trapezoidal rule
        # right after a step, where ω has a kink; the previous step's
        # world-frame correction dphi is applied here, in body axes
        # (exp(dphi) R exp(theta) = R exp(R^T dphi + theta) to O(|dphi||theta|) ~ 1e-9 rad)
        if step:
            q0, q1, q2 = (g0 + o0) * 6 * h, (g1 + o1) * 6 * h, (g2 + o2) * 6 * h
        else:
            q0, q1, q2 = (5 * g0 + 8 * o0 - w0) * h, (5 * g1 + 8 * o1 - w1) * h, (5 * g2 + 8 * o2 - w2) * h
        e00, e01, e02, e10, e11, e12, e20, e21, e22 = _rotvec_matrix(
            q0 + (r00 * d0 + r10 * d1 + r20 * d2),
            q1 + (r01 * d0 + r11 * d1 + r21 * d2),
            q2 + (r02 * d0 + r12 * d1 + r22 * d2))
        R = (r00 * e00 + r01 * e10 + r02 * e20, r00 * e01 + r01 * e11 + r02 * e21, r00 * e02 + r01 * e12 + r02 * e22,
             r10 * e00 + r11 * e10 + r12 * e20, r10 * e01 + r11 * e11 + r12 * e21, r10 * e02 + r11 * e12 + r12 * e22,
             r20 * e00 + r21 * e10 + r22 * e20, r20 * e01 + r21 * e11 + r22 * e21, r20 * e02 + r21 * e12 + r22 * e22)
        self._omega_prev2 = self._omega
        self._omega = gyro_b
        # the filter tracks the IMU point, whose acceleration the accelerometer gives
        # without lever-arm terms: a = R f + g; each sample is rotated with its own
        # attitude, then velocity and position follow by the same third-order quadrature
        # (the trapezoidal rule's amplitude error biased Iyy by 0.01 %)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        a_k = (r00 * f0 + r01 * f1 + r02 * f2 - c0, r10 * f0 + r11 * f1 + r12 * f2 - c1,
               r20 * f0 + r21 * f1 + r22 * f2 - self._gravity - c2)
        v = self._v
        vp = self._v_prev
        p = self._p
        if step:
            # the previous interval, before the step: from the samples before it
            # ((3a₋₂ − a₋₃)/2 instead of Adams–Moulton's (5a₋₁ + 8a₋₂ − a₋₃)/12 per dt),
            # and its effect on the position; this interval by the trapezoidal rule
            self.steps.append(self._t)
            cv = (-5 * h * (a_1[0] - 2 * a_2[0] + a_3[0]), -5 * h * (a_1[1] - 2 * a_2[1] + a_3[1]),
                  -5 * h * (a_1[2] - 2 * a_2[2] + a_3[2]))
            v = (v[0] + cv[0], v[1] + cv[1], v[2] + cv[2])
            p = (p[0] + 5 * h * cv[0], p[1] + 5 * h * cv[1], p[2] + 5 * h * cv[2])
            v_new = (v[0] + (a_k[0] + a_1[0]) * 6 * h, v[1] + (a_k[1] + a_1[1]) * 6 * h,
                     v[2] + (a_k[2] + a_1[2]) * 6 * h)
            self._p = (p[0] + (v_new[0] + v[0]) * 6 * h, p[1] + (v_new[1] + v[1]) * 6 * h,
                       p[2] + (v_new[2] + v[2]) * 6 * h)
        else:
            v_new = (v[0] + (5 * a_k[0] + 8 * a_1[0] - a_2[0]) * h, v[1] + (5 * a_k[1] + 8 * a_1[1] - a_2[1]) * h,
                     v[2] + (5 * a_k[2] + 8 * a_1[2] - a_2[2]) * h)
            self._p = (p[0] + (5 * v_new[0] + 8 * v[0] - vp[0]) * h, p[1] + (5 * v_new[1] + 8 * v[1] - vp[1]) * h,
                       p[2] + (5 * v_new[2] + 8 * v[2] - vp[2]) * h)
        self._a_hist = (a_k, a_1, a_2)
        self._v_prev = v
        self._v = v_new
        t0, t1, t2 = self._tilt_correction(R, dt, f_b)
        y = self._constraint_correction(R, dt)
        d0, d1, d2 = t0, t1, t2 + y
        self._dphi = (d0, d1, d2)
        # integral action: a steady correction is a gyro bias (PI complementary filter,
        # natural frequency 1/tau_bias); removes the bias x tau offset of a P-only filter
        k = self.tau_tilt / self.tau_bias**2
        b0, b1, b2 = self._gyro_bias
        self._gyro_bias = (b0 - k * (r00 * d0 + r10 * d1 + r20 * d2), b1 - k * (r01 * d0 + r11 * d1 + r21 * d2),
                           b2 - k * (r02 * d0 + r12 * d1 + r22 * d2))
        self._R = R
        self._n_steps += 1
        if self._n_steps % 200 == 0:  # re-orthonormalise now and then
            self._R = tuple(Rotation.from_matrix(np.array(R).reshape(3, 3)).as_matrix().ravel().tolist())

    def _tilt_correction(self, R: tuple, dt: float, f_b: tuple) -> tuple:
        """World-frame rotation (3,) rad pulling the tilt toward the inclinometer/gravity."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        if self._incl is not None:
            if self._incl_pending is None:
                return (0.0, 0.0, 0.0)
            meas = self._incl_pending
            self._incl_pending = None
            n00, n01, _, n10, n11, _, n20, n21, _ = self._incl_f
            # world directions of the inclinometer's x and y axes
            ax0, ax1, ax2 = r00 * n00 + r01 * n10 + r02 * n20, r10 * n00 + r11 * n10 + r12 * n20, \
                r20 * n00 + r21 * n10 + r22 * n20
            ay0, ay1, ay2 = r00 * n01 + r01 * n11 + r02 * n21, r10 * n01 + r11 * n11 + r12 * n21, \
                r20 * n01 + r21 * n11 + r22 * n21
            px = math.asin(min(1.0, max(-1.0, ax2)))
            py = math.asin(min(1.0, max(-1.0, ay2)))
            # d elevation / d(world rotation phi) = (a x z) / cos(elevation)
            cx, cy = math.cos(px), math.cos(py)
            h00, h01 = ax1 / cx, -ax0 / cx
            h10, h11 = ay1 / cy, -ay0 / cy
            # H^T (H H^T)^-1 (meas - pred), H (2,3) with a zero third column
            s00, s01, s11 = h00 * h00 + h01 * h01, h00 * h10 + h01 * h11, h10 * h10 + h11 * h11
            r0, r1 = meas[0] - px, meas[1] - py
            det = s00 * s11 - s01 * s01
            y0, y1 = (s11 * r0 - s01 * r1) / det, (s00 * r1 - s01 * r0) / det
            gain = min(1.0, (self._t_incl - self._t_incl_used) / self.tau_tilt)
            self._t_incl_used = self._t_incl
            return (gain * (h00 * y0 + h10 * y1), gain * (h01 * y0 + h11 * y1), 0.0)
        # no inclinometer: align the measured specific force with gravity, slowly
        f0, f1, f2 = f_b
        u0, u1, u2 = r00 * f0 + r01 * f1 + r02 * f2, r10 * f0 + r11 * f1 + r12 * f2, r20 * f0 + r21 * f1 + r22 * f2
        n = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        if n < 1e-6:
            return (0.0, 0.0, 0.0)
        c = dt / self.tau_tilt_accel
        return (c * u1 / n, c * -u0 / n, 0.0)

    def _constraint_correction(self, R: tuple, dt: float) -> float:
        """Correct position (third-order complementary filter) toward the cable-length
        constraints; return the yaw correction (rotation about world z, rad)."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
        p0, p1, p2 = self._p
        tens = self._tensions
        comp = self._compliance
        resid = []
        # normal equations G^T G delta = -G^T r accumulated over the cables, with the rows
        # G_i = (-u_i, -(R b_i x u_i)_z): d l_i = -u_i . dp - (R b_i x u_i) . dphi,
        # unknowns dp (3) and yaw about world z
        a00 = a01 = a02 = a03 = a11 = a12 = a13 = a22 = a23 = a33 = 0.0
        y0 = y1 = y2 = y3 = 0.0
        for i, ((b0, b1, b2), (A0, A1, A2), L) in enumerate(zip(self._anchors_f, self._ceiling_f, self._lengths)):
            if tens is not None:
                L = L + tens[i] * comp[i]
            rb0, rb1 = r00 * b0 + r01 * b1 + r02 * b2, r10 * b0 + r11 * b1 + r12 * b2
            rb2 = r20 * b0 + r21 * b1 + r22 * b2
            v0, v1, v2 = A0 - (p0 + rb0), A1 - (p1 + rb1), A2 - (p2 + rb2)
            lv = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
            g0, g1, g2 = -(v0 / lv), -(v1 / lv), -(v2 / lv)
            g3 = -(rb0 * -g1 - rb1 * -g0)
            r = lv - L
            resid.append(r)
            a00 += g0 * g0
            a01 += g0 * g1
            a02 += g0 * g2
            a03 += g0 * g3
            a11 += g1 * g1
            a12 += g1 * g2
            a13 += g1 * g3
            a22 += g2 * g2
            a23 += g2 * g3
            a33 += g3 * g3
            y0 -= g0 * r
            y1 -= g1 * r
            y2 -= g2 * r
            y3 -= g3 * r
        if self._adapt and tens is not None:
            self._refine_compliance(dt, resid)
        # regularised: (G^T G + Λ) delta = -G^T r, Λ = 1e-12 tr(G^T G) on the position and
        # YAW_PRIOR tr on the yaw: cables splayed radially from the body's centre (their
        # horizontal directions through the anchors' centroid, a common rig) leave the yaw
        # undetermined by the lengths to first order — the unregularised solve turned the
        # tilt's and the stretch's small residuals into yaw corrections and diverged (a 5.9 m
        # frame on four such cables: 0.3 rad within 2 s); there the yaw follows the gyro
        eps = 1e-12 * (a00 + a11 + a22 + a33)
        lam = YAW_PRIOR * (a00 + a11 + a22)
        delta = _solve_spd4(a00 + eps, a01, a02, a03, a11 + eps, a12, a13, a22 + eps, a23, a33 + lam, y0, y1, y2, y3)
        # third-order complementary filter (poles at -wn): the integral state absorbs a
        # constant acceleration error (tilt error x g, accelerometer bias)
        wn = 2 * np.pi * self.f_position
        kp, kv, ka = 3 * wn * dt, 3 * wn * wn * dt, wn**3 * dt
        p, v, ab = self._p, self._v, self._a_bias
        self._p = (p[0] + kp * delta[0], p[1] + kp * delta[1], p[2] + kp * delta[2])
        self._v = (v[0] + kv * delta[0], v[1] + kv * delta[1], v[2] + kv * delta[2])
        self._a_bias = (ab[0] - ka * delta[0], ab[1] - ka * delta[1], ab[2] - ka * delta[2])
        return min(1.0, dt / self.tau_yaw) * delta[3]

    def _refine_compliance(self, dt: float, resid: list):
        """Regress the in-band cable-length residual on the tension variation.

        In the band where the pose follows the inertial sensors, a residual that
        follows the tension is unmodelled stretch: delta_c = <e T> / <T T> (both
        high-passed with a 5 s time constant, sums forgotten over ~60 s).
        """
        a = min(1.0, dt / 5.0)
        hp_e, hp_T, tens, comp = self._hp_e, self._hp_T, self._tensions, self._compliance
        s_et = s_tt = s_e0t = 0.0
        for i in range(len(resid)):
            hp_e[i] += a * (resid[i] - hp_e[i])
            hp_T[i] += a * (tens[i] - hp_T[i])
            e = resid[i] - hp_e[i]
            dT = tens[i] - hp_T[i]
            s_et += e * dT
            s_tt += dT * dT
            s_e0t += (e + comp[i] * dT) * dT   # the residual of an inextensible cable
        lam = 1.0 - dt / 60.0
        S = self._S
        S[0] = lam * S[0] + s_et
        S[1] = lam * S[1] + s_tt
        blk = self._blk
        blk[0] += s_e0t
        blk[1] += s_tt
        blk[2] += 1
        if self._t - self._t_adapt >= 2.0:
            self._t_adapt = self._t
            self.compliance_sums.append((self._t, blk[0], blk[1], blk[2]))
            blk[0] = blk[1] = 0.0
            blk[2] = 0
            # enough tension variation: at least ~50 N RMS per cable over the horizon
            if S[1] > (50.0**2) * len(resid) * (60.0 / dt) * 0.1:
                dc = S[0] / S[1]
                fit = ~np.isfinite(self.rig.cable_stiffness)
                c = np.array(self._compliance)
                c = np.where(fit, np.clip(c + dc, 0.0, 1e-5), c)
                self._compliance = tuple(c.tolist())
                self._lengths = tuple((self._l0 - self._T0 * c).tolist())
                S[0] = S[1] = 0.0
                self.compliance_history.append((self._t, c))

    def compliance_estimate(self, since: float) -> float | None:
        """Least-squares cable compliance (m/N, common to the cables rig.yaml gives no
        stiffness) from the blocks after the stamp ``since``: ``Σ e₀ ΔT / Σ ΔT²`` — the
        in-band length residual of inextensible cables regressed on the tension variation,
        the statistic of the online updates (:meth:`_refine_compliance`) pooled over the
        whole span instead of the median of 2 s updates (smooth in the data, and a smaller
        variance).  None when the tension hardly varied there (as the online gate)."""
        S = [(a, b, n) for t, a, b, n in self.compliance_sums if t >= since]
        if not S:
            return None
        num, den, count = (sum(x[k] for x in S) for k in range(3))
        # the online gate: tension variation ≥ ~16 N RMS per cable
        if den <= 0.1 * 50.0**2 * len(self._lengths) * count:
            return None
        return float(np.clip(num / den, 0.0, 1e-5))

    @property
    def R(self) -> Rotation | None:
        """Current orientation, body -> world (None before initialisation)."""
        return None if self._R is None else Rotation.from_matrix(np.array(self._R).reshape(3, 3))

    def _estimate(self) -> PoseEstimate:
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._R
        i0, i1, i2 = self._r_imu_f
        w0, w1, w2 = self._omega
        p, v = self._p, self._v
        # lever arm r_w = R r_imu (world) and R omega (world)
        q0, q1, q2 = r00 * i0 + r01 * i1 + r02 * i2, r10 * i0 + r11 * i1 + r12 * i2, r20 * i0 + r21 * i1 + r22 * i2
        s0, s1, s2 = r00 * w0 + r01 * w1 + r02 * w2, r10 * w0 + r11 * w1 + r12 * w2, r20 * w0 + r21 * w1 + r22 * w2
        return PoseEstimate(self._t, np.array((p[0] - q0, p[1] - q1, p[2] - q2)), np.array(self._R).reshape(3, 3),
                            np.array(self._omega),
                            np.array((v[0] - (s1 * q2 - s2 * q1), v[1] - (s2 * q0 - s0 * q2),
                                      v[2] - (s0 * q1 - s1 * q0))))


def _floats(x) -> list:
    """A 3-vector as Python floats."""
    return x.tolist() if isinstance(x, np.ndarray) else [float(x[0]), float(x[1]), float(x[2])]


def _rotvec_matrix(x: float, y: float, z: float) -> tuple:
    """Rotation matrix (row-major 9-tuple) of the rotation vector (x, y, z) rad, through the
    unit quaternion as scipy ``Rotation.from_rotvec(...).as_matrix()`` (same series for
    small angles)."""
    angle2 = x * x + y * y + z * z
    angle = math.sqrt(angle2)
    if angle <= 1e-3:
        scale = 0.5 - angle2 / 48 + angle2 * angle2 / 3840
    else:
        scale = math.sin(angle / 2) / angle
    qx, qy, qz, qw = x * scale, y * scale, z * scale, math.cos(angle / 2)
    xx, yy, zz, ww = qx * qx, qy * qy, qz * qz, qw * qw
    xy, zw, xz, yw, yz, xw = qx * qy, qz * qw, qx * qz, qy * qw, qy * qz, qx * qw
    return (xx - yy - zz + ww, 2 * (xy - zw), 2 * (xz + yw),
            2 * (xy + zw), -xx + yy - zz + ww, 2 * (yz - xw),
            2 * (xz - yw), 2 * (yz + xw), -xx - yy + zz + ww)


def _solve_spd4(a00, a01, a02, a03, a11, a12, a13, a22, a23, a33, b0, b1, b2, b3) -> tuple:
    """Solve A x = b for a symmetric positive-definite 4x4 A (upper triangle given; Cholesky)."""
    l00 = math.sqrt(a00)
    l10, l20, l30 = a01 / l00, a02 / l00, a03 / l00
    l11 = math.sqrt(a11 - l10 * l10)
    l21 = (a12 - l20 * l10) / l11
    l31 = (a13 - l30 * l10) / l11
    l22 = math.sqrt(a22 - l20 * l20 - l21 * l21)
    l32 = (a23 - l30 * l20 - l31 * l21) / l22
    l33 = math.sqrt(a33 - l30 * l30 - l31 * l31 - l32 * l32)
    z0 = b0 / l00
    z1 = (b1 - l10 * z0) / l11
    z2 = (b2 - l20 * z0 - l21 * z1) / l22
    z3 = (b3 - l30 * z0 - l31 * z1 - l32 * z2) / l33
    x3 = z3 / l33
    x2 = (z2 - l32 * x3) / l22
    x1 = (z1 - l21 * x2 - l31 * x3) / l11
    x0 = (z0 - l10 * x1 - l20 * x2 - l30 * x3) / l00
    return x0, x1, x2, x3
