"""The sensors of a simulated run: the true motion sampled at each sensor's rate, with noise,
biases and the sensor-level effects.

Each sensor at its own rate, samples t_k = k / rate for k = 0 .. floor(duration rate),
header stamp = stamp_origin + t_k, white Gaussian noise σ plus constant bias:
gyro = R_imuᵀ ω; accelerometer = specific force R_imuᵀ Rᵀ (a_imu - g_world) at the IMU
point (reads +g along the up axis at rest); load cells = T_i; exciter = x, y of the
exciter force (rotating + measured pulses) in the exciter frame, less the rotor's inertial
force m_r f_e where ``exciter_rotor`` gives it a mass (f_e the specific force at the exciter); inclinometer =
(asin(z_world · x_incl), asin(z_world · y_incl)), incl axes = R R_incl.  Order on the
gyro: true rate (+ structural mode) × gyro_scale, + noise, + biases, + gyro_bias_drift
(drawn after every other stream's noise, so adding it changes no other reading).  The
sensor-level effects (``gyro_scale``, ``gyro_bias_drift``, ``structural_mode``, ...) act on
the sampled readings (:func:`mode_response`, :func:`random_walk`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import cont2discrete, lfilter
from scipy.spatial.transform import Rotation

from ..io.recording import SensorData, TimeSeries
from ..io.rig import Rig
from .dynamics import Evaluation, RigDynamics
from .effects import Effect
from .experiment import Experiment
from .rigid_body import SimulationError, bearing_inertial_force

STATIC_STREAMS = {"baseline": 1, "dummy": 2}   # static recordings: noise from default_rng([seed, stream])
MODE_FILTER_RATE = 2000.0          # Hz: structural_mode's filter runs at >= this rate (and >= 40 x the
                                   # mode frequency), on a cubic spline of the sensor's samples


class Sampled(NamedTuple):
    """The true motion at one sensor rate: simulation times t (K,) s, states Y (K, size)
    (:class:`~rig_identification.model.dynamics.RigDynamics`'s layout) and their evaluation."""

    t: np.ndarray
    Y: np.ndarray
    evaluation: Evaluation


def sample_times(duration: float, rate: float) -> np.ndarray:
    """Sample times (K,) s of a sensor at ``rate`` Hz over ``duration`` s: k / rate, k = 0 .. floor(duration rate)."""
    return np.arange(int(math.floor(duration * rate + 1e-9)) + 1) / rate


def sample_sensors(exp: Experiment, model: RigDynamics, traj: Callable[[np.ndarray], np.ndarray], rig: Rig,
                   duration: float, cache: dict[float, Sampled]) -> SensorData:
    """Sample every sensor of ``exp`` on its own time grid (module docstring) from the true
    motion ``traj`` (simulation times (K,) s -> states (K, size)) of ``model``; ``rig``: the
    rig.yaml written (sensor placement).  ``cache`` keeps the :class:`Sampled` motion per rate.
    Returns the streams with stamps ``exp.stamp_origin + t``.  Raises :class:`SimulationError`
    when an inextensible cable goes slack."""
    spec = exp.sensors
    rng = np.random.default_rng(exp.seed if exp.static is None
                                else [exp.seed, STATIC_STREAMS[exp.static.kind]])
    run = _Run(exp, model, traj, rig, duration, cache, rng, eff={e.name: e for e in exp.effects},
               delay={e.get("stream", ""): e.get("delay") for e in exp.effects if e.name == "sensor_delay"},
               mode={e.get("sensor"): e for e in exp.effects if e.name == "structural_mode"})
    # the streams' noise drawn in this order from the one generator
    t_imu, gyro, acc = _imu_readings(run)
    cells = _load_cell_readings(run)
    exc = _exciter_readings(run)
    inc = _inclinometer_readings(run)
    if "gyro_bias_drift" in run.eff:    # drawn last: every other stream's noise stays as without it
        gyro += random_walk(rng, len(t_imu), 1.0 / spec.rates["imu"], run.eff["gyro_bias_drift"].get("random_walk"))
    imu = TimeSeries(exp.stamp_origin + t_imu, np.hstack([gyro, acc]))
    return SensorData(imu, cells, exc, inc)


@dataclass(frozen=True)
class _Run:
    """What each sensor of :func:`sample_sensors` samples from: ``exp``, ``model``, its true
    motion ``traj``, ``rig`` (the rig.yaml written), ``duration`` s, the :class:`Sampled` motion
    per rate (``cache``), the seeded generator ``rng`` every stream's noise is drawn from in
    turn, the effects by name (``eff``), the delays s by stream (``delay``, sensor_delay) and
    the structural modes by sensor (``mode``)."""

    exp: Experiment
    model: RigDynamics
    traj: Callable[[np.ndarray], np.ndarray]
    rig: Rig
    duration: float
    cache: dict[float, Sampled]
    rng: np.random.Generator
    eff: dict[str, Effect]
    delay: dict[str, Any]
    mode: dict[Any, Effect]

    def at(self, rate: float) -> Sampled:
        """The true motion sampled at ``rate`` Hz (:func:`sample_times`), cached."""
        if rate not in self.cache:
            t = sample_times(self.duration, rate)
            Y = self.traj(t)
            self.cache[rate] = Sampled(t, Y, self.model.evaluate(t, Y))
        return self.cache[rate]

    def noisy(self, x: np.ndarray, key: str) -> np.ndarray:
        """Readings x (K, n) plus the sensor ``key``'s bias and white noise (drawn from ``rng``)."""
        spec = self.exp.sensors
        reading: np.ndarray = x + spec.bias[key] + spec.noise[key] * self.rng.standard_normal(x.shape)
        return reading


def _specific_force(ev: Evaluation, omega: np.ndarray, alpha: np.ndarray, rho: np.ndarray,
                    g: np.ndarray) -> np.ndarray:
    """(K, 3) m/s², body axes: the specific force R^T (a_p − g) at the body point ``rho`` (3,) m
    from the CG, a_p = a_cg + R (α × ρ + ω × (ω × ρ)); ``omega``, ``alpha`` (K, 3) body rad/s and
    rad/s², ``g`` (3,) world m/s²."""
    a_p = ev.a + np.einsum("kij,kj->ki", ev.R, np.cross(alpha, rho) + np.cross(omega, np.cross(omega, rho)))
    f: np.ndarray = np.einsum("kji,kj->ki", ev.R, a_p - g)
    return f


def _imu_readings(run: _Run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The IMU's sample times t (K,) s, gyro (K, 3) rad/s and accelerometer (K, 3) m/s², IMU
    axes (module docstring: imu_misalignment, imu_offset, structural_mode, gyro_scale, the
    noise (gyro's drawn first), gyro_bias, accelerometer_bias; not gyro_bias_drift)."""
    rig, model, eff, mode = run.rig, run.model, run.eff, run.mode
    t, Y, ev = run.at(run.exp.sensors.rates["imu"])
    R_imu = rig.imu.rotation.as_matrix()
    if "imu_misalignment" in eff:   # true IMU axes: turned beyond rig.yaml's imu.rpy
        R_imu = R_imu @ Rotation.from_euler("xyz", eff["imu_misalignment"].get("rpy")).as_matrix()
    omega, alpha = Y[:, 15:18], ev.alpha
    rho = rig.imu.position - model.cg
    if "imu_offset" in eff:         # true IMU position: rig.yaml's + offset
        rho = rho + eff["imu_offset"].get("offset")
    gyro_true, acc_true = omega @ R_imu, _specific_force(ev, omega, alpha, rho, model.g) @ R_imu
    if "imu" in mode:               # the IMU's mount rings: ω + θ̇, specific force + ẍ
        gyro_true = gyro_true + mode_response(t, gyro_true, mode["imu"])
        acc_true = acc_true + mode_response(t, acc_true, mode["imu"])
    if "gyro_scale" in eff:         # scale errors act on the sensed rate, before noise and bias
        gyro_true = gyro_true * eff["gyro_scale"].get("scale")
    gyro = run.noisy(gyro_true, "gyro")
    acc = run.noisy(acc_true, "accelerometer")
    if "gyro_bias" in eff:
        gyro += eff["gyro_bias"].get("bias")
    if "accelerometer_bias" in eff:
        acc += eff["accelerometer_bias"].get("bias")
    return t, gyro, acc


def _load_cell_readings(run: _Run) -> dict[str, TimeSeries]:
    """Each cable's load cell (K, 1) N by name (structural_mode, load_cell_scale, noise,
    sensor_delay).  Raises :class:`SimulationError` when an inextensible cable goes slack."""
    rig, model, exp = run.rig, run.model, run.exp
    t, Y, ev = run.at(exp.sensors.rates["load_cells"])
    if model.cables.type == "inextensible" and not model.cables.compression:
        check_taut(rig, t, ev.T, model.m * np.linalg.norm(model.g))
    T = ev.T.copy()
    if "load_cells" in run.mode:    # each load cell reads its flexible anchor's spring force
        T = T + mode_response(t, T, run.mode["load_cells"])
    for e in exp.effects:
        if e.name == "load_cell_scale":
            T[:, rig.cable_names.index(e.get("cable"))] *= e.get("scale")
    T = run.noisy(T, "load_cell")
    t_cells = exp.stamp_origin + t + run.delay.get("load_cells", 0.0)
    return {name: TimeSeries(t_cells, T[:, i]) for i, name in enumerate(rig.cable_names)}


def _exciter_readings(run: _Run) -> TimeSeries | None:
    """The exciter's load cells (K, 2) N, exciter frame: the force less the rotor's m_r f_e
    (exciter_rotor with a rotor_mass) and with its unbalanced mass's inertial force from the body's
    rotation (:func:`~rig_identification.model.rigid_body.bearing_inertial_force`), noise,
    sensor_delay; None without an exciter."""
    rig, model, eff = run.rig, run.model, run.eff
    if rig.exciter is None:
        return None
    t, Y, ev = run.at(run.exp.sensors.rates["exciter"])
    force = ev.exciter
    Re = rig.exciter.rotation.as_matrix()
    if "exciter_rotor" in eff and eff["exciter_rotor"].get("rotor_mass") > 0:
        # the load cells hold the rotor's bearing: they read the force less the rotor's m_r f_e
        f_e = _specific_force(ev, Y[:, 15:18], ev.alpha, rig.exciter.position - model.cg, model.g) @ Re
        force = force - eff["exciter_rotor"].get("rotor_mass") * f_e[:, :2]
    if "exciter_rotor" in eff:
        rotating = run.exp.excitation.rotating
        assert rotating is not None             # the experiment refuses exciter_rotor without it
        angles = np.array([rotating.angle_and_speed(ti)[:2] for ti in t])
        u = np.column_stack([np.cos(angles[:, 0]), np.sin(angles[:, 0]), np.zeros(len(t))]) @ Re.T
        f = bearing_inertial_force(model.unbalance, u, Re[:, 2], angles[:, 1], Y[:, 15:18], ev.alpha)
        force = force + (f @ Re)[:, :2]
    return TimeSeries(run.exp.stamp_origin + t + run.delay.get("exciter", 0.0), run.noisy(force, "exciter"))


def _inclinometer_readings(run: _Run) -> TimeSeries | None:
    """The inclinometer's elevations (K, 2) rad (noise, sensor_delay); None without one."""
    rig = run.rig
    if rig.inclinometer is None:
        return None
    t, Y, ev = run.at(run.exp.sensors.rates["inclinometer"])
    axes = ev.R @ rig.inclinometer.rotation.as_matrix()
    angles = np.arcsin(np.clip(axes[:, 2, :2], -1.0, 1.0))
    return TimeSeries(run.exp.stamp_origin + t + run.delay.get("inclinometer", 0.0), run.noisy(angles, "inclinometer"))

def random_walk(rng: np.random.Generator, n: int, dt: float, sigma: float) -> np.ndarray:
    """(n, 3) random-walk (Wiener) bias on a grid of step dt s: b_0 = 0,
    b_k+1 = b_k + sigma √dt N(0, 1) per axis (sigma rad/s/√s); draws (n − 1, 3) normals."""
    steps = sigma * math.sqrt(dt) * rng.standard_normal((max(n - 1, 0), 3))
    return np.vstack([np.zeros((1, 3)), np.cumsum(steps, axis=0)])[:n]


def mode_response(t: np.ndarray, u: np.ndarray, effect: Effect) -> np.ndarray:
    """structural_mode: the change e (K, n) of readings u (K, n) sampled at the uniform times
    t (K,) s, e = p G(s) (u − u_0), G(s) = −s² / (s² + 2ζω s + ω²), ω = 2π ``frequency``,
    ζ = ``damping_ratio``, p = ``participation`` (default 1); the mount starts at rest.

    G is the base-excited oscillator's.  IMU: the mount's displacement x and rotation θ
    relative to the frame obey ẍ + 2ζωẋ + ω²x = −p (f − f_0) (specific force, IMU axes: the
    mount feels gravity too) and θ̈ + 2ζωθ̇ + ω²θ = −p dω/dt, so the added readings are
    ẍ = p G (f − f_0) and θ̇ = p G ω.  Load cell under an anchor of modal mass m, k = m ω²,
    c = 2ζωm, m ẍ + c ẋ + k x = p (T − T_0): it reads k x + c ẋ + T_0 = T + p G (T − T_0)
    (p = 1: the anchor's spring force).

    Evaluated exactly (first-order-hold discretisation, scipy ``cont2discrete(method="foh")``,
    then ``lfilter``) on a not-a-knot cubic spline of u at a rate ≥ max(:data:`MODE_FILTER_RATE`,
    40 ω/2π), then taken at the samples, so the result does not depend on the sensor's rate
    beyond the spline's O((2π f_u / rate)⁴) error: 200 Hz and 1 kHz agree to ~0.1 % of e; a
    kink or step of u (the spin-up's end, a pulse edge) is smoothed over a sample or two.
    """
    u = np.asarray(u, float)
    p = effect.get("participation", 1.0)
    if len(t) < 2 or p == 0:
        return np.zeros_like(u)
    w, zeta = 2 * math.pi * effect.get("frequency"), effect.get("damping_ratio")
    dt = (t[-1] - t[0]) / (len(t) - 1)
    m = max(1, int(math.ceil(max(MODE_FILTER_RATE, 40 * w / (2 * math.pi)) * dt - 1e-9)))
    fine = t[0] + np.arange((len(t) - 1) * m + 1) * (dt / m)
    x = u - u[0]
    x_fine = CubicSpline(t, x, axis=0)(fine)        # two samples: a straight line
    num, den, _ = cont2discrete(([-p, 0.0, 0.0], [1.0, 2 * zeta * w, w * w]), dt / m, method="foh")
    e: np.ndarray = lfilter(np.ravel(num), den, x_fine, axis=0)[::m]
    return e


def check_taut(rig: Rig, t: np.ndarray, T: np.ndarray, weight: float | np.floating[Any]) -> None:
    """Raise :class:`SimulationError` naming the cable and the time where a tension of T (K, N)
    N at times t (K,) s is negative beyond rounding (1e-9 of the weight N)."""
    bad = T < -1e-9 * weight
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise SimulationError(f"inextensible cables: cable {rig.cable_names[i]} goes slack at t = {t[k]:.3f} s "
                              f"(tension {T[k, i]:.3g} N); the inextensible model cannot represent slack "
                              "cables, use cable_model.type: spring")
