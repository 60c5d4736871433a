"""Tracker: pose of the suspended body in ``world`` from the IMU and the rig geometry.

The thesis's tracker (section 3.4, "Tracker" block) integrated noise-free body
signals.  Integrating a real gyro drifts (random walk, bias), so this tracker is a
causal complementary filter that uses everything the rig gives:

* **orientation**: strapdown integration of the gyro (midpoint rule, exact rotation
  exponential via scipy ``Rotation``) — accurate in the band where the rig moves;
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

Frames: ``position`` is the world position of the body-frame origin (m); the
quaternion (x, y, z, w) rotates body axes to world axes; ``omega`` is the angular
velocity in body axes (rad/s); ``velocity`` is the origin's velocity in world (m/s).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .rig import Rig

Z = np.array([0.0, 0.0, 1.0])


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
    def from_estimates(cls, poses: list[PoseEstimate]) -> "PoseTrack":
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
    specific force of a swinging body is vertical only on average, hence the long time).
    """

    def __init__(self, rig: Rig, tau_tilt: float = 2.0, tau_yaw: float = 2.0, f_position: float = 0.1,
                 init_time: float = 0.1, tau_bias: float = 5.0, tau_tilt_accel: float = 30.0):
        self.rig = rig
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
        self._init_incl: list[np.ndarray] = []
        self._init_tens: list[np.ndarray] = []
        self._init_exc: list[np.ndarray] = []
        self._incl_pending: np.ndarray | None = None
        self._t_incl: float | None = None
        self.compliance_history: list[tuple[float, np.ndarray]] = []
        self._t = None
        self._Rm: np.ndarray | None = None
        self._incl_m = self._incl.as_matrix() if self._incl is not None else None
        self.p = self.v = self.omega = None

    @property
    def initialised(self) -> bool:
        return self._Rm is not None

    # --- inputs -------------------------------------------------------------------
    def add_inclinometer(self, t: float, angles) -> None:
        a = np.asarray(angles, float)[:2]
        self._t_incl = t
        if self._Rm is None:
            self._init_incl.append(a)
        else:
            self._incl_pending = a

    def add_exciter(self, t: float, force_xy) -> None:
        """Exciter force (2,) N in the exciter frame; used only for the initial pose."""
        if self._Rm is None and self.rig.exciter is not None:
            self._init_exc.append(np.asarray(force_xy, float)[:2])

    def add_tensions(self, t: float, tensions) -> None:
        """tensions: dict cable name -> N, or (N,) array in rig order."""
        if isinstance(tensions, dict):
            tensions = np.array([tensions[n] for n in self.rig.cable_names], float)
        self._tensions = np.asarray(tensions, float)
        if self._Rm is None:
            self._init_tens.append(self._tensions)

    def add_imu(self, t: float, gyro, accel) -> PoseEstimate | None:
        gyro_b = self._imu_m @ np.asarray(gyro, float)
        f_b = self._imu_m @ np.asarray(accel, float)
        if self._Rm is not None:
            gyro_b = gyro_b - self.gyro_bias
        else:
            self._init.append((t, gyro_b, f_b))
            if t - self._init[0][0] < self.init_time:
                return None
            self._initialise()
            return self._estimate()
        dt = t - self._t
        if dt <= 0:
            raise TrackerError(f"IMU stamp {t:.6f} s is not after the previous one ({self._t:.6f} s)")
        self._step(dt, gyro_b, f_b)
        self._t = t
        return self._estimate()

    # --- internals ----------------------------------------------------------------
    def _initialise(self):
        t = np.array([s[0] for s in self._init])
        f_b = np.mean([s[2] for s in self._init], axis=0)
        tens = np.mean(self._init_tens, axis=0) if self._init_tens else None
        elev = np.mean(self._init_incl, axis=0) if (self._init_incl and self._incl is not None) else None
        f_imu = self._imu_to_body.inv().apply(f_b)
        quiet = np.max(np.abs([s[1] for s in self._init])) < 5e-3
        exc = None
        if self._init_exc:
            exc = self.rig.exciter.rotation.apply(np.r_[np.mean(self._init_exc, axis=0), 0.0])
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
        self._Rm = pose.rotation.as_matrix()
        self.p = pose.position + self._Rm @ self._r_imu  # the IMU point
        # constraint lengths consistent with the initial pose (absorbs the static stretch)
        self._lengths, self._compliance = pose.lengths, pose.compliance
        # online compliance refinement (only when rig.yaml gives no stiffness)
        # needs the inclinometer: without it the in-band tilt is too rough to tell stretch
        self._adapt = (tens is not None and elev is not None
                       and not np.isfinite(self.rig.cable_stiffness).all())
        self._T0 = tens if tens is not None else np.zeros(len(self._lengths))
        self._l0 = self._lengths + self._T0 * self._compliance
        self._hp_e = np.zeros(len(self._lengths))
        self._hp_T = self._T0.copy()
        self._S = np.zeros(2)
        self._t_adapt = t[-1]
        self.v = np.zeros(3)
        self._a_bias = np.zeros(3)
        self.omega = self._init[-1][1]
        a0 = self._Rm @ self._init[-1][2] + self._g
        self._a_hist = (a0, a0)
        self._v_prev = np.zeros(3)
        self._omega_prev2 = None
        self._dphi = np.zeros(3)
        self._n_steps = 0
        self.gyro_bias = np.zeros(3)
        self._t = t[-1]
        self._t_incl_used = self._t_incl if self._t_incl is not None else self._t
        self._init.clear()

    def _step(self, dt: float, gyro_b: np.ndarray, f_b: np.ndarray):
        # rotation matrices here (body->world); scipy Rotation gives the exponentials
        omega_prev = self.omega
        # rotation increment over the interval: third-order Adams–Moulton quadrature of ω
        # through the last three samples (the midpoint rule's (ωh)²/12 amplitude error
        # would bias the tensor by ~0.05 % at 100 Hz sampling)
        w2 = self._omega_prev2 if self._omega_prev2 is not None else omega_prev
        # the previous step's world-frame correction dphi is applied here, in body axes
        # (exp(dphi) R exp(theta) = R exp(R^T dphi + theta) to O(|dphi||theta|) ~ 1e-9 rad)
        theta = (5 * gyro_b + 8 * omega_prev - w2) * (dt / 12) + self._Rm.T @ self._dphi
        Rm = self._Rm @ Rotation.from_rotvec(theta).as_matrix()
        self._omega_prev2 = omega_prev
        self.omega = gyro_b
        # the filter tracks the IMU point, whose acceleration the accelerometer gives
        # without lever-arm terms: a = R f + g; each sample is rotated with its own
        # attitude, then velocity and position follow by the same third-order quadrature
        # (the trapezoidal rule's amplitude error biased Iyy by 0.01 %)
        a_k = Rm @ f_b + self._g - self._a_bias
        a_1, a_2 = self._a_hist
        v_new = self.v + (5 * a_k + 8 * a_1 - a_2) * (dt / 12)
        self.p = self.p + (5 * v_new + 8 * self.v - self._v_prev) * (dt / 12)
        self._a_hist = (a_k, a_1)
        self._v_prev = self.v
        self.v = v_new
        self._dphi = self._tilt_correction(Rm, dt, f_b) + self._constraint_correction(Rm, dt)
        # integral action: a steady correction is a gyro bias (PI complementary filter,
        # natural frequency 1/tau_bias); removes the bias x tau offset of a P-only filter
        self.gyro_bias = self.gyro_bias - (self.tau_tilt / self.tau_bias**2) * (Rm.T @ self._dphi)
        self._Rm = Rm
        self._n_steps += 1
        if self._n_steps % 200 == 0:  # re-orthonormalise now and then
            self._Rm = Rotation.from_matrix(Rm).as_matrix()

    def _tilt_correction(self, Rm: np.ndarray, dt: float, f_b: np.ndarray) -> np.ndarray:
        """World-frame rotation (3,) rad pulling the tilt toward the inclinometer/gravity."""
        if self._incl is not None:
            if self._incl_pending is None:
                return np.zeros(3)
            meas = self._incl_pending
            self._incl_pending = None
            axes = (Rm @ self._incl_m)[:, :2].T  # (2,3) world directions of incl x, y
            pred = np.arcsin(np.clip(axes[:, 2], -1, 1))
            # d elevation / d(world rotation phi) = (a x z) / cos(elevation)
            H = np.column_stack([axes[:, 1], -axes[:, 0], np.zeros(2)]) / np.cos(pred)[:, None]
            gain = min(1.0, (self._t_incl - self._t_incl_used) / self.tau_tilt)
            self._t_incl_used = self._t_incl
            return gain * (H.T @ np.linalg.solve(H @ H.T, meas - pred))
        # no inclinometer: align the measured specific force with gravity, slowly
        up = Rm @ f_b
        n = np.linalg.norm(up)
        if n < 1e-6:
            return np.zeros(3)
        return (dt / self.tau_tilt_accel) * np.array([up[1], -up[0], 0.0]) / n

    def _constraint_correction(self, Rm: np.ndarray, dt: float) -> np.ndarray:
        """Correct position (third-order complementary filter) toward the cable-length
        constraints; return the yaw correction as a world-frame rotation (3,) rad."""
        lengths = self._lengths
        if self._tensions is not None:
            lengths = lengths + self._tensions * self._compliance
        rb = self._anchors_from_imu @ Rm.T
        v = self.rig.ceiling_anchors - (self.p + rb)
        lv = np.sqrt(np.einsum("ij,ij->i", v, v))
        u = v / lv[:, None]
        resid = lv - lengths
        if self._adapt and self._tensions is not None:
            self._refine_compliance(dt, resid)
        # d l_i = -u_i . dp - (R b_i x u_i) . dphi ; unknowns dp (3) and yaw about world z
        G = np.column_stack([-u, -(rb[:, 0] * u[:, 1] - rb[:, 1] * u[:, 0])])
        GtG = G.T @ G
        delta = np.linalg.solve(GtG + 1e-12 * np.trace(GtG) * np.eye(4), -(G.T @ resid))
        # third-order complementary filter (poles at -wn): the integral state absorbs a
        # constant acceleration error (tilt error x g, accelerometer bias)
        wn = 2 * np.pi * self.f_position
        self.p = self.p + 3 * wn * dt * delta[:3]
        self.v = self.v + 3 * wn * wn * dt * delta[:3]
        self._a_bias = self._a_bias - wn**3 * dt * delta[:3]
        return np.array([0.0, 0.0, min(1.0, dt / self.tau_yaw) * delta[3]])

    def _refine_compliance(self, dt: float, resid: np.ndarray):
        """Regress the in-band cable-length residual on the tension variation.

        In the band where the pose follows the inertial sensors, a residual that
        follows the tension is unmodelled stretch: delta_c = <e T> / <T T> (both
        high-passed with a 5 s time constant, sums forgotten over ~60 s).
        """
        a = min(1.0, dt / 5.0)
        self._hp_e += a * (resid - self._hp_e)
        self._hp_T += a * (self._tensions - self._hp_T)
        e = resid - self._hp_e
        dT = self._tensions - self._hp_T
        lam = 1.0 - dt / 60.0
        self._S = lam * self._S + np.array([np.dot(e, dT), np.dot(dT, dT)])
        if self._t - self._t_adapt >= 2.0:
            self._t_adapt = self._t
            # enough tension variation: at least ~50 N RMS per cable over the horizon
            if self._S[1] > (50.0**2) * len(dT) * (60.0 / dt) * 0.1:
                dc = self._S[0] / self._S[1]
                fit = ~np.isfinite(self.rig.cable_stiffness)
                self._compliance = np.where(fit, np.clip(self._compliance + dc, 0.0, 1e-5), self._compliance)
                self._lengths = self._l0 - self._T0 * self._compliance
                self._S[:] = 0.0
                self.compliance_history.append((self._t, self._compliance.copy()))

    @property
    def R(self) -> Rotation | None:
        """Current orientation, body -> world (None before initialisation)."""
        return None if self._Rm is None else Rotation.from_matrix(self._Rm)

    def _estimate(self) -> PoseEstimate:
        r_w = self._Rm @ self._r_imu
        return PoseEstimate(self._t, self.p - r_w, self._Rm.copy(), self.omega.copy(),
                            self.v - np.cross(self._Rm @ self.omega, r_w))


def track(rig: Rig, sensors, **params) -> PoseTrack:
    """Run :class:`PoseTracker` over recorded sensor data (offline replay, same code as the node).

    sensors: :class:`~rig_identification.recording.SensorData`.  Streams are merged
    in header-stamp order.  When rig.yaml gives no cable stiffness, a first pass
    refines the cables' compliance online (as the node does); the replay is then run
    again with the median compliance of the pass's second half fixed, so that the
    start of the recording is tracked as well as its end.  Returns the
    :class:`PoseTrack` at the IMU stamps after initialisation.
    """
    out, tracker = _replay(rig, sensors, **params)
    if tracker.compliance_history and not np.isfinite(rig.cable_stiffness).all():
        hist = tracker.compliance_history
        c = np.median([h[1] for h in hist[len(hist) // 2:]], axis=0)
        from dataclasses import replace
        cables = tuple(replace(cb, stiffness=cb.stiffness if cb.stiffness is not None else 1.0 / max(ci, 1e-12))
                       for cb, ci in zip(rig.cables, c))
        out, _ = _replay(replace(rig, cables=cables), sensors, **params)
    return PoseTrack.from_estimates(out)


def _replay(rig: Rig, sensors, **params) -> tuple[list[PoseEstimate], PoseTracker]:
    tracker = PoseTracker(rig, **params)
    events = [(t, 2, i) for i, t in enumerate(sensors.imu.t)]
    if sensors.inclinometer is not None:
        events += [(t, 0, i) for i, t in enumerate(sensors.inclinometer.t)]
    if sensors.exciter is not None:
        n_exc = int(np.searchsorted(sensors.exciter.t, sensors.imu.t[0] + 2 * tracker.init_time))
        events += [(t, 3, i) for i, t in enumerate(sensors.exciter.t[:n_exc])]
    names = rig.cable_names
    cells = [sensors.load_cells[n] for n in names]
    if all(len(c) == len(cells[0]) and np.array_equal(c.t, cells[0].t) for c in cells):
        tens = np.column_stack([c.data[:, 0] for c in cells])
        events += [(t, 1, i) for i, t in enumerate(cells[0].t)]
    else:  # load cells on different clocks: sample them at the IMU stamps
        tens = np.column_stack([np.interp(sensors.imu.t, c.t, c.data[:, 0]) for c in cells])
        events += [(t, 1, i) for i, t in enumerate(sensors.imu.t)]
    events.sort()
    imu = sensors.imu.data
    incl = sensors.inclinometer.data if sensors.inclinometer is not None else None
    out = []
    for t, kind, i in events:
        if kind == 2:
            pose = tracker.add_imu(t, imu[i, :3], imu[i, 3:])
            if pose is not None:
                out.append(pose)
        elif kind == 1:
            tracker.add_tensions(t, tens[i])
        elif kind == 3:
            tracker.add_exciter(t, sensors.exciter.data[i])
        else:
            tracker.add_inclinometer(t, incl[i])
    if not out:
        raise TrackerError("the recording is shorter than the tracker's initialisation time")
    return out, tracker
