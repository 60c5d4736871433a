"""ROS-free simulator of the suspended-body rig: the thesis's "experiment" (chapters 3 and 4).

A rigid body of mass ``m`` and inertia tensor ``J`` (about its CG, body axes) hangs from
the ceiling on N >= 3 cables and is shaken by an unbalanced-mass exciter or by force
pulses.  The simulator integrates the full Newton–Euler equations (gyroscopic term
included, unlike thesis eq. 3.10)::

    m a_cg = sum_i T_i u_i + m g + F_ext                      (world axes)
    J dω/dt + ω × (J ω) = sum_i r_i × T_i u_i + M_ext         (body axes, about the CG)
    dR/dt = R skew(ω),   dp_cg/dt = v_cg

with scipy's DOP853 (rtol 1e-10, atol 1e-12, dense output), then samples the dense
solution at each sensor's own times and writes the sensor streams of
``RECORDING_FORMAT.md`` (IMU, load cells, exciter, inclinometer).

The ``compliant_body`` effect makes the body two: the carrying frame (hung on the cables,
carrying the sensors, the exciter and any dummy or cable mass) and a sprung body joined to
it by a 6-DOF spring–damper (:class:`Suspension`, :func:`split_body`); both are integrated
together (state 36), at rtol 1e-9, atol 1e-11 (:data:`COMPLIANT_RTOL`).  The sensor-level
effects (``gyro_scale``, ``gyro_bias_drift``, ``structural_mode``) act on the sampled
readings (:func:`mode_response`, :func:`random_walk`).

Frames and conventions
----------------------
* ``world``: z up, gravity (0, 0, -g), g = ``rig.gravity``.
* ``body``: origin = any reference point; the CG is at ``c`` (body frame).  A pose is
  ``position`` p = world position of the BODY-FRAME ORIGIN and ``R`` = rotation body -> world
  (scipy ``Rotation``).  ω is in body axes.  Internally the state is
  ``[p_cg (3), R row-major (9), v_cg (3), ω (3)]`` (with ``compliant_body``: the frame's,
  then the sprung body's).
* Inertia tensor entries as ``geometry_msgs/Inertia`` / ``truth.yaml``: off-diagonal entries
  are the NEGATED products of inertia (thesis eqs. 3.6–3.9: ixy = -Jxy = -∫xy dm).
* Cable i runs from the ceiling anchor A_i (world) to the body anchor b_i (body frame).
  Its tension T_i >= 0 pulls the body along u_i = (A_i - P_i)/|A_i - P_i|, P_i = p_cg + R (b_i - c).

Cable models (``cable_model``)
------------------------------
* ``spring``: T_i = max(0, k_i (l_i - L_i) + c_i dl_i/dt) (tension-only spring-damper, as
  the reference simulator).  Default k_i: the cable's ``stiffness`` in rig.yaml, else 5e6 N/m.
  Default damping c_i = 2 ζ sqrt(k_i m / N) with ζ = ``damping_ratio`` = 0.01, which is
  the reference simulator's value (e.g. 951.3 N·s/m for m = 1810 kg, N = 4, k = 5e6).
* ``inextensible``: holonomic constraints |A_i - P_i| = L_i (thesis eqs. 2.13–2.16).
  The tensions are the Lagrange multipliers, solved from the KKT system at every
  right-hand-side call, with Baumgarte stabilisation
  φ'' + 2β φ' + β² φ = 0, φ_i = (l_i² - L_i²)/2.  N > 6 is rejected (tensions statically
  indeterminate); a negative tension (a cable going slack) raises :class:`SimulationError`
  unless ``compression: true`` makes the cables rigid two-way links (negative "tension" =
  compression), like rigid links in a multibody model; the thesis's SimMechanics model
  presumably was one: its cases 7 and 8 need compression with inextensible cables.

Experiment file schema (YAML)
-----------------------------
::

    name: case16                    # [a-zA-Z0-9_.-]+, default: the file stem
    description: "..."              # free text
    source: {thesis_section: "4.16", table: "4.16"}   # free mapping (provenance)
    rig: {...}                      # exactly a rig.yaml mapping (RECORDING_FORMAT.md);
                                    # body.center_of_gravity is REQUIRED (it is the truth)
    inertia_about_cg: {ixx: 2894, ixy: 0, ixz: 0, iyy: 695, iyz: -102, izz: 3101}  # kg m^2
    cable_model:                    # default {type: spring}
      type: spring                  # or inextensible
      stiffness: 5.0e6              # N/m, number or one per cable (spring only)
      damping: 951.3                # N s/m, number or per cable; default 2 ζ sqrt(k m / N)
      damping_ratio: 0.01           # ζ of the default damping
      baumgarte: 20.0               # 1/s (inextensible only)
      compression: false            # inextensible only: true = rigid links that may push,
                                    # no slack error
    initial:                        # default {equilibrium: true}: static equilibrium, at rest
      equilibrium: true
      displacement: {position: [dx, dy, dz], rpy: [r, p, y]}   # optional, from equilibrium:
                                    # CG moved by position (world, m), body turned about its CG
                                    # by the fixed-axis XYZ rpy (world axes, rad)
      pose: {cg_position: [x, y, z], rpy: [r, p, y]}            # OR an absolute pose:
                                    # CG world position, body->world fixed-axis XYZ rpy
      project: true                 # move the displaced/absolute pose the least distance
                                    # onto the cable lengths L_i (+ equilibrium stretch for
                                    # springs) so the body starts with taut, unstrained cables
    excitation:                     # default: none
      rotating: {amplitude: 200, frequency: 1.05, ramp_time: 2.0, ramp_shape: linear,
                 phase: 0.0, direction: 1, start_time: 0.0, stop_time: null}
      pulses:                       # constant forces, on for start <= t < end
        - {force: [fx, fy, fz], point: [x, y, z], start: 0.1, end: 1.1,
           frame: body,             # force axes: body (default) or world; point: body frame
           measured: true}          # reported by the exciter load cells (x, y in the
                                    # exciter frame); must then act at rig.exciter.position
    duration: 120.0                 # s
    sensors:
      rates_hz: {imu: 100, load_cells: 100, exciter: 100, inclinometer: 50}
      noise: {gyro: 0, accelerometer: 0, load_cell: 0, exciter: 0, inclinometer: 0}  # σ
      bias: {gyro: [0,0,0], accelerometer: [0,0,0], load_cell: 0, exciter: [0,0],
             inclinometer: [0,0]}   # constant; load_cell: number or one per cable
    seed: 16                        # numpy default_rng seed of the sensor noise (static recordings
                                    # use default_rng([seed, 1 baseline | 2 dummy]): independent noise)
    stamp_origin: 1.75e9            # header stamp (s) of t = 0
    static: {kind: baseline, duration: 10.0}   # optional: a static CG recording instead
                                    # (kind baseline or dummy; dummy uses rig.dummy_mass)
    thesis: {...}                   # free mapping, carried for the comparison tables
    effects:                        # physics beyond the rigid-body model, concealed in the
      - {name: viscous_damping, linear: 150.0, angular: 300.0}   # recording and listed in
                                    # truth.yaml (names and parameters: rig_identification.effects)

The rotating force (exciter frame, z = spin axis) is
F = A(t) [cos θ, direction sin θ, 0], θ = 2π f (t - start_time) + phase,
A(t) = amplitude min(1, (t - start_time)/ramp_time), zero before start_time and from
stop_time on (``ramp_shape: linear``).  ``ramp_shape: spin_up`` ramps the motor speed
instead, as the reference simulator does (see :class:`RotatingForce`).  It acts at
``rig.exciter.position``, exciter axes given by ``rig.exciter.rpy``.

Sensors (each at its own rate, samples t_k = k / rate for k = 0 .. floor(duration rate),
header stamp = stamp_origin + t_k, white Gaussian noise σ plus constant bias):
gyro = R_imuᵀ ω; accelerometer = specific force R_imuᵀ Rᵀ (a_imu - g_world) at the IMU
point (reads +g along the up axis at rest); load cells = T_i; exciter = x, y of the
exciter force (rotating + measured pulses) in the exciter frame; inclinometer =
(asin(z_world · x_incl), asin(z_world · y_incl)), incl axes = R R_incl.  Order on the
gyro: true rate (+ structural mode) × gyro_scale, + noise, + biases, + gyro_bias_drift
(drawn after every other stream's noise, so adding it changes no other reading).

Public API
----------
* :func:`load_experiment` (path) / :func:`experiment_from_dict` (mapping, source) ->
  :class:`Experiment`; ``Experiment.with_overrides`` applies the ``rig-sim`` options.
* :func:`simulate` (experiment) -> :class:`SimResult` with ``rig``, ``sensors``
  (:class:`~.recording.SensorData`), ``truth`` (truth.yaml mapping), ``states``
  (:class:`States` at the IMU sample times) and ``states_at(t)`` (dense true motion).
* :func:`equilibrium` (rig, mass, cg, cable_model) -> (position, Rotation, tensions).

Errors: :class:`ExperimentError` (a ``ValueError``) for a bad experiment file, naming the
file and the field; :class:`SimulationError` (a ``RuntimeError``) for physics that the
chosen model cannot represent (slack inextensible cable, no equilibrium, ...).
"""
from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.linalg.lapack import dposv
from scipy.optimize import minimize, root
from scipy.signal import cont2discrete, lfilter
from scipy.spatial.transform import Rotation

from .effects import DEFAULT_LOCK_DAMPING_RATIO, DEFAULT_LOCK_FREQUENCY, Effect, parse_effects
from .recording import SensorData, TimeSeries
from .rig import DummyMass, Rig, RigError, load_rig, read_yaml, rig_from_dict

DEFAULT_STIFFNESS = 5.0e6          # N/m, reference simulator's cable stiffness
DEFAULT_DAMPING_RATIO = 0.01       # ζ of the default cable damping (reference simulator)
DEFAULT_BAUMGARTE = 20.0           # 1/s
DEFAULT_STAMP_ORIGIN = 1.75e9      # s
DEFAULT_STATIC_DURATION = 10.0     # s
STATIC_STREAMS = {"baseline": 1, "dummy": 2}   # static recordings: noise from default_rng([seed, stream])
RTOL, ATOL = 1e-10, 1e-12
COMPLIANT_RTOL, COMPLIANT_ATOL = 1e-9, 1e-11   # compliant_body: its light frame rings faster on the stiff
                                   # cables; a 90 s random rig needs ~2.3x the rigid run's right-hand-side calls
                                   # at 1e-10, ~1.6x at 1e-9 (~1.5-2x the time), and its noise-free readings
                                   # differ from the 1e-10 ones by < 1e-5 of the reference sensor noise
                                   # (gyro 6e-11 rad/s, accelerometer 3e-8 m/s², load cells 2e-6 N)
SENSOR_RATES = {"imu": 100.0, "load_cells": 100.0, "exciter": 100.0, "inclinometer": 50.0}
NOISE_KEYS = ("gyro", "accelerometer", "load_cell", "exciter", "inclinometer")
BIAS_SIZES = {"gyro": 3, "accelerometer": 3, "exciter": 2, "inclinometer": 2}   # load_cell: N
SPRUNG_RAISE = 0.2                 # m: compliant_body's default sprung-CG height above the CG (at most half
                                   # the largest raise the body's mass distribution allows, see split_body)
MODE_FILTER_RATE = 2000.0          # Hz: structural_mode's filter runs at >= this rate (and >= 40 x the
                                   # mode frequency), on a cubic spline of the sensor's samples
NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
FLOAT_TEXT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


class ExperimentError(ValueError):
    """An experiment file with a missing or wrong field (message names file and field)."""


class SimulationError(RuntimeError):
    """The chosen physical model cannot represent the experiment (or a solver failed)."""


# --- experiment description ----------------------------------------------------------

@dataclass(frozen=True)
class CableModel:
    """How the cables are modelled.

    type: ``"spring"`` or ``"inextensible"``.  stiffness, damping: (N,) N/m and N·s/m
    (spring only, else ``None``).  baumgarte: β, 1/s, and compression: links that may push
    (inextensible only).
    """

    type: str
    stiffness: np.ndarray | None = None
    damping: np.ndarray | None = None
    baumgarte: float = DEFAULT_BAUMGARTE
    compression: bool = False

    @staticmethod
    def spring(rig: Rig, mass: float, stiffness=None, damping=None,
               damping_ratio: float = DEFAULT_DAMPING_RATIO) -> "CableModel":
        """Spring-damper cables.  ``stiffness``/``damping``: scalar, (N,) or None (defaults:
        rig.yaml stiffness else 5e6 N/m; c = 2 ζ sqrt(k m / N))."""
        n = len(rig.cables)
        if stiffness is None:
            k = np.array([DEFAULT_STIFFNESS if c.stiffness is None else c.stiffness for c in rig.cables])
        else:
            k = np.broadcast_to(np.asarray(stiffness, float), (n,)).copy()
        if damping is None:
            c = 2.0 * damping_ratio * np.sqrt(k * mass / n)
        else:
            c = np.broadcast_to(np.asarray(damping, float), (n,)).copy()
        return CableModel("spring", k, c)

    @staticmethod
    def inextensible(baumgarte: float = DEFAULT_BAUMGARTE, compression: bool = False) -> "CableModel":
        return CableModel("inextensible", baumgarte=baumgarte, compression=compression)

    def describe(self) -> dict:
        if self.type == "spring":
            return {"type": "spring", "cable_stiffness": self.stiffness.tolist(),
                    "cable_damping": self.damping.tolist(),
                    "cable_tension_model": "max(0, stiffness*(length-length0) + damping*d(length)/dt), "
                                           "along the cable"}
        return {"type": "inextensible", "baumgarte": self.baumgarte, "compression": self.compression,
                "cable_tension_model": "Lagrange multipliers of |ceiling_anchor - body_anchor| = length "
                                       "(KKT each step, Baumgarte stabilisation)"}


@dataclass(frozen=True)
class RotatingForce:
    """Unbalanced-mass force in the exciter frame (see module docstring).  SI units.

    ramp_shape ``linear``: the amplitude ramps linearly over ramp_time at constant frequency.
    ``spin_up``: the motor speed ramps linearly from 0, so the phase is its integral and the
    amplitude grows with the speed squared (the reference simulator's ramp):
    θ = π f τ²/ramp_time + phase and A = amplitude (τ/ramp_time)² for τ < ramp_time, then
    θ = 2π f (τ - ramp_time/2) + phase (τ = t - start_time).
    """

    amplitude: float
    frequency: float
    ramp_time: float = 0.0
    phase: float = 0.0
    direction: int = 1
    start_time: float = 0.0
    stop_time: float | None = None
    ramp_shape: str = "linear"

    def force(self, t: float) -> np.ndarray:
        """Exciter-frame force (3,) N at time t s."""
        tau = t - self.start_time
        if tau < 0 or (self.stop_time is not None and t >= self.stop_time):
            return np.zeros(3)
        T, f = self.ramp_time, self.frequency
        if tau >= T:
            amp = self.amplitude
            theta = 2 * math.pi * f * (tau - (T / 2 if self.ramp_shape == "spin_up" else 0.0))
        elif self.ramp_shape == "spin_up":
            amp = self.amplitude * (tau / T) ** 2
            theta = math.pi * f * tau ** 2 / T
        else:
            amp = self.amplitude * tau / T
            theta = 2 * math.pi * f * tau
        theta += self.phase
        return np.array([amp * math.cos(theta), self.direction * amp * math.sin(theta), 0.0])

    def angle_and_speed(self, t: float) -> tuple[float, float, float]:
        """Rotor angle θ (rad, exciter frame, signed by ``direction``), spin speed dθ/dt
        (rad/s) and spin acceleration (rad/s²) at time t s; (0, 0, 0) when the motor is off."""
        tau = t - self.start_time
        if tau < 0 or (self.stop_time is not None and t >= self.stop_time):
            return 0.0, 0.0, 0.0
        T, w = self.ramp_time, 2 * math.pi * self.frequency
        if self.ramp_shape == "spin_up" and tau < T:
            theta, speed, acc = math.pi * self.frequency * tau ** 2 / T, w * tau / T, w / T
        elif self.ramp_shape == "spin_up":
            theta, speed, acc = w * (tau - T / 2), w, 0.0
        else:
            theta, speed, acc = w * tau, w, 0.0
        d = self.direction
        return d * (theta + self.phase), d * speed, d * acc

    def breakpoints(self) -> list[float]:
        out = [self.start_time, self.start_time + self.ramp_time]
        return out + ([self.stop_time] if self.stop_time is not None else [])


@dataclass(frozen=True)
class Pulse:
    """A constant force (3,) N on for start <= t < end, acting at ``point`` (3,) body frame."""

    force: np.ndarray
    point: np.ndarray
    start: float
    end: float
    frame: str = "body"
    measured: bool = False


@dataclass(frozen=True)
class Excitation:
    rotating: RotatingForce | None = None
    pulses: tuple[Pulse, ...] = ()

    def describe(self) -> dict | None:
        if self.rotating is None and not self.pulses:
            return None
        out: dict[str, Any] = {}
        if self.rotating is not None:
            r = self.rotating
            out.update(type="rotating", amplitude=r.amplitude, frequency=r.frequency, ramp_time=r.ramp_time,
                       ramp_shape=r.ramp_shape, phase=r.phase, direction=r.direction, start_time=r.start_time,
                       stop_time=r.stop_time)
        else:
            out["type"] = "pulses"
        out["pulses"] = [{"force": p.force.tolist(), "point": p.point.tolist(), "start": p.start, "end": p.end,
                          "frame": p.frame, "measured": p.measured} for p in self.pulses]
        return out


@dataclass(frozen=True)
class Initial:
    """Start pose at rest: equilibrium (+ optional displacement) or an absolute CG pose."""

    displacement_position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    displacement_rpy: np.ndarray = field(default_factory=lambda: np.zeros(3))
    pose_cg_position: np.ndarray | None = None
    pose_rpy: np.ndarray | None = None
    project: bool = True

    def describe(self) -> str:
        if self.pose_cg_position is not None:
            return (f"at rest, CG at {self.pose_cg_position.tolist()} m, rpy {self.pose_rpy.tolist()} rad"
                    + (" (projected onto the cable lengths)" if self.project else ""))
        if np.any(self.displacement_position) or np.any(self.displacement_rpy):
            return (f"static equilibrium displaced by {self.displacement_position.tolist()} m, "
                    f"rpy {self.displacement_rpy.tolist()} rad, at rest"
                    + (" (projected onto the cable lengths)" if self.project else ""))
        return "static equilibrium, at rest"


@dataclass(frozen=True)
class SensorSpec:
    """rates: Hz per stream (imu, load_cells, exciter, inclinometer); noise: σ per
    NOISE_KEYS; bias: constant offsets, gyro/accelerometer (3,), exciter/inclinometer (2,),
    load_cell (N,)."""

    rates: dict
    noise: dict
    bias: dict


@dataclass(frozen=True)
class StaticSpec:
    """A static CG recording: ``kind`` baseline (no dummy) or dummy (rig.dummy_mass added)."""

    kind: str
    duration: float = DEFAULT_STATIC_DURATION


@dataclass(frozen=True)
class Experiment:
    """A validated experiment file.  ``rig`` carries the true CG; ``inertia``: (3, 3) kg m²
    tensor about the CG, body axes."""

    name: str
    rig: Rig
    inertia: np.ndarray
    cable_model: CableModel
    initial: Initial
    excitation: Excitation
    duration: float
    sensors: SensorSpec
    seed: int = 0
    stamp_origin: float = DEFAULT_STAMP_ORIGIN
    static: StaticSpec | None = None
    description: str = ""
    reference: dict = field(default_factory=dict)
    thesis: dict = field(default_factory=dict)
    path: str = "<memory>"
    effects: tuple = ()

    def effect(self, name: str) -> Effect | None:
        """The first effect called ``name``, or None."""
        return next((e for e in self.effects if e.name == name), None)

    @property
    def mass(self) -> float:
        return self.rig.mass

    @property
    def cg(self) -> np.ndarray:
        return self.rig.center_of_gravity

    def with_overrides(self, duration: float | None = None, seed: int | None = None, noise_free: bool = False,
                       static: str | None = None, dummy: DummyMass | None = None) -> "Experiment":
        """A copy with command-line overrides applied (see :func:`~.sim_cli.sim_main`).

        ``static``: ``"baseline"``/``"dummy"`` turns it into a static recording (its duration is
        ``duration`` if given, else the config's static duration, else 10 s).  ``dummy``
        replaces ``rig.dummy_mass``.  Raises :class:`ExperimentError` for a dummy recording
        without a dummy mass.
        """
        exp = self
        if dummy is not None:
            exp = replace(exp, rig=replace(exp.rig, dummy_mass=dummy))
        if static is not None:
            base = exp.static.duration if exp.static is not None else DEFAULT_STATIC_DURATION
            exp = replace(exp, static=StaticSpec(static, base))
        if duration is not None:
            if exp.static is not None:
                exp = replace(exp, static=replace(exp.static, duration=duration))
            else:
                exp = replace(exp, duration=duration)
        if seed is not None:
            exp = replace(exp, seed=seed)
        if noise_free:
            exp = replace(exp, sensors=replace(exp.sensors, noise={k: 0.0 for k in NOISE_KEYS}))
        if exp.static is not None and exp.static.kind == "dummy" and exp.rig.dummy_mass is None:
            raise ExperimentError(f"{exp.path}: a dummy static recording needs rig.dummy_mass "
                                  "(or --dummy-mass and --dummy-position)")
        return exp


# --- experiment file parsing ---------------------------------------------------------

class _Fields:
    """Validation helpers that name the file and the field in their errors."""

    def __init__(self, src: str):
        self.src = src

    def error(self, name: str, msg: str) -> ExperimentError:
        return ExperimentError(f"{self.src}: field {name} {msg}")

    def mapping(self, v, name: str, allowed: set[str] | None = None) -> dict:
        if v is None:
            return {}
        if not isinstance(v, dict):
            raise self.error(name, f"must be a mapping, got {v!r}")
        if allowed is not None:
            unknown = sorted(set(v) - allowed)
            if unknown:
                raise self.error(name, f"has unknown key(s) {', '.join(map(str, unknown))} "
                                       f"(known: {', '.join(sorted(allowed))})")
        return v

    def number(self, v, name: str, positive=False, nonneg=False) -> float:
        if isinstance(v, str) and FLOAT_TEXT.match(v.strip()):
            v = float(v)                   # YAML 1.1 reads 5.0e6 (no exponent sign) as text
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.error(name, f"must be a number, got {v!r}")
        x = float(v)
        if not math.isfinite(x):
            raise self.error(name, f"must be finite, got {v!r}")
        if positive and x <= 0:
            raise self.error(name, f"must be > 0, got {v!r}")
        if nonneg and x < 0:
            raise self.error(name, f"must be >= 0, got {v!r}")
        return x

    def vector(self, v, name: str, n: int, nonneg=False) -> np.ndarray:
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise self.error(name, f"must be a list of {n} numbers, got {v!r}")
        return np.array([self.number(x, f"{name}[{i}]", nonneg=nonneg) for i, x in enumerate(v)])

    def scalar_or_vector(self, v, name: str, n: int, positive=False, nonneg=False) -> np.ndarray:
        if isinstance(v, (list, tuple)):
            out = self.vector(v, name, n, nonneg=nonneg or positive)
            if positive and np.any(out <= 0):
                raise self.error(name, f"must be > 0, got {v!r}")
            return out
        return np.full(n, self.number(v, name, positive=positive, nonneg=nonneg))

    def boolean(self, v, name: str) -> bool:
        if not isinstance(v, bool):
            raise self.error(name, f"must be true or false, got {v!r}")
        return v


TOP_KEYS = {"effects", "name", "description", "source", "rig", "inertia_about_cg", "cable_model", "initial", "excitation",
            "duration", "sensors", "seed", "stamp_origin", "static", "thesis"}
INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def inertia_tensor(d: dict) -> np.ndarray:
    """(3, 3) tensor from the truth.yaml entries ixx..izz (off-diagonals = negated products)."""
    xx, xy, xz, yy, yz, zz = (float(d[k]) for k in INERTIA_KEYS)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def inertia_entries(J: np.ndarray) -> dict:
    """truth.yaml entries ixx..izz of a (3, 3) tensor."""
    return {"ixx": float(J[0, 0]), "ixy": float(J[0, 1]), "ixz": float(J[0, 2]),
            "iyy": float(J[1, 1]), "iyz": float(J[1, 2]), "izz": float(J[2, 2])}


def _parse_inertia(f: _Fields, v) -> np.ndarray:
    d = f.mapping(v, "inertia_about_cg", set(INERTIA_KEYS))
    for k in INERTIA_KEYS:
        if k not in d:
            raise ExperimentError(f"{f.src}: missing field inertia_about_cg.{k}")
        f.number(d[k], f"inertia_about_cg.{k}")
    J = inertia_tensor(d)
    p = np.linalg.eigvalsh(J)
    if p[0] <= 0 or p[0] + p[1] < p[2] * (1 - 1e-12):
        raise f.error("inertia_about_cg", f"is not a rigid-body inertia tensor (principal moments "
                                          f"{np.round(p, 3).tolist()} kg m^2 must be > 0 and satisfy the "
                                          "triangle inequality)")
    return J


def _parse_cable_model(f: _Fields, v, rig: Rig) -> CableModel:
    d = f.mapping(v, "cable_model", {"type", "stiffness", "damping", "damping_ratio", "baumgarte", "compression"})
    kind = d.get("type", "spring")
    n = len(rig.cables)
    if kind == "spring":
        extra = sorted({"baumgarte", "compression"} & set(d))
        if extra:
            raise f.error(f"cable_model.{extra[0]}", "applies to inextensible cables only")
        k = None if d.get("stiffness") is None else f.scalar_or_vector(d["stiffness"], "cable_model.stiffness", n,
                                                                        positive=True)
        c = None if d.get("damping") is None else f.scalar_or_vector(d["damping"], "cable_model.damping", n,
                                                                      nonneg=True)
        zeta = f.number(d.get("damping_ratio", DEFAULT_DAMPING_RATIO), "cable_model.damping_ratio", nonneg=True)
        return CableModel.spring(rig, rig.mass, k, c, zeta)
    if kind == "inextensible":
        extra = sorted({"stiffness", "damping", "damping_ratio"} & set(d))
        if extra:
            raise f.error(f"cable_model.{extra[0]}", "applies to spring cables only")
        if n > 6:
            raise f.error("cable_model.type", f"inextensible needs at most 6 cables (the rig has {n}: their "
                                              "tensions would be statically indeterminate); use spring")
        return CableModel.inextensible(f.number(d.get("baumgarte", DEFAULT_BAUMGARTE), "cable_model.baumgarte",
                                                nonneg=True),
                                       f.boolean(d.get("compression", False), "cable_model.compression"))
    raise f.error("cable_model.type", f"must be spring or inextensible, got {kind!r}")


def _parse_initial(f: _Fields, v) -> Initial:
    d = f.mapping(v, "initial", {"equilibrium", "displacement", "pose", "project"})
    project = f.boolean(d.get("project", True), "initial.project")
    if "pose" in d:
        if d.get("equilibrium") is True or "displacement" in d:
            raise f.error("initial.pose", "excludes initial.equilibrium: true and initial.displacement")
        p = f.mapping(d["pose"], "initial.pose", {"cg_position", "rpy"})
        if "cg_position" not in p:
            raise ExperimentError(f"{f.src}: missing field initial.pose.cg_position")
        return Initial(pose_cg_position=f.vector(p["cg_position"], "initial.pose.cg_position", 3),
                       pose_rpy=f.vector(p.get("rpy", [0, 0, 0]), "initial.pose.rpy", 3), project=project)
    if not f.boolean(d.get("equilibrium", True), "initial.equilibrium"):
        raise f.error("initial.equilibrium", "is false but no initial.pose is given")
    disp = f.mapping(d.get("displacement"), "initial.displacement", {"position", "rpy"})
    return Initial(displacement_position=f.vector(disp.get("position", [0, 0, 0]),
                                                  "initial.displacement.position", 3),
                   displacement_rpy=f.vector(disp.get("rpy", [0, 0, 0]), "initial.displacement.rpy", 3),
                   project=project)


def _parse_excitation(f: _Fields, v, rig: Rig) -> Excitation:
    d = f.mapping(v, "excitation", {"rotating", "pulses"})
    rot = None
    if d.get("rotating") is not None:
        w = "excitation.rotating"
        r = f.mapping(d["rotating"], w, {"amplitude", "frequency", "ramp_time", "ramp_shape", "phase",
                                         "direction", "start_time", "stop_time"})
        for k in ("amplitude", "frequency"):
            if k not in r:
                raise ExperimentError(f"{f.src}: missing field {w}.{k}")
        direction = r.get("direction", 1)
        if direction not in (1, -1) or isinstance(direction, bool):
            raise f.error(f"{w}.direction", f"must be 1 or -1, got {direction!r}")
        start = f.number(r.get("start_time", 0.0), f"{w}.start_time", nonneg=True)
        stop = None if r.get("stop_time") is None else f.number(r["stop_time"], f"{w}.stop_time")
        if stop is not None and stop <= start:
            raise f.error(f"{w}.stop_time", f"must be after start_time ({start} s), got {stop}")
        shape = r.get("ramp_shape", "linear")
        if shape not in ("linear", "spin_up"):
            raise f.error(f"{w}.ramp_shape", f"must be linear or spin_up, got {shape!r}")
        if rig.exciter is None:
            raise f.error(w, "needs rig.exciter (where the force acts)")
        rot = RotatingForce(f.number(r["amplitude"], f"{w}.amplitude", nonneg=True),
                            f.number(r["frequency"], f"{w}.frequency", positive=True),
                            f.number(r.get("ramp_time", 0.0), f"{w}.ramp_time", nonneg=True),
                            f.number(r.get("phase", 0.0), f"{w}.phase"), int(direction), start, stop, shape)
    raw = d.get("pulses") or []
    if not isinstance(raw, list):
        raise f.error("excitation.pulses", "must be a list")
    pulses = []
    for i, p in enumerate(raw):
        w = f"excitation.pulses[{i}]"
        p = f.mapping(p, w, {"force", "point", "start", "end", "frame", "measured"})
        for k in ("force", "point", "start", "end"):
            if k not in p:
                raise ExperimentError(f"{f.src}: missing field {w}.{k}")
        frame = p.get("frame", "body")
        if frame not in ("body", "world"):
            raise f.error(f"{w}.frame", f"must be body or world, got {frame!r}")
        pulse = Pulse(f.vector(p["force"], f"{w}.force", 3), f.vector(p["point"], f"{w}.point", 3),
                      f.number(p["start"], f"{w}.start", nonneg=True), f.number(p["end"], f"{w}.end"),
                      frame, f.boolean(p.get("measured", False), f"{w}.measured"))
        if pulse.end <= pulse.start:
            raise f.error(f"{w}.end", f"must be after start ({pulse.start} s), got {pulse.end}")
        if pulse.measured and (rig.exciter is None or not np.allclose(pulse.point, rig.exciter.position)):
            raise f.error(f"{w}.measured", "is true but the pulse does not act at rig.exciter.position "
                                           "(only the exciter's load cells measure applied forces)")
        pulses.append(pulse)
    return Excitation(rot, tuple(pulses))


def _parse_sensors(f: _Fields, v, n_cables: int) -> SensorSpec:
    d = f.mapping(v, "sensors", {"rates_hz", "noise", "bias"})
    rates_raw = f.mapping(d.get("rates_hz"), "sensors.rates_hz", set(SENSOR_RATES))
    rates = {k: f.number(rates_raw.get(k, r), f"sensors.rates_hz.{k}", positive=True)
             for k, r in SENSOR_RATES.items()}
    noise_raw = f.mapping(d.get("noise"), "sensors.noise", set(NOISE_KEYS))
    noise = {k: f.number(noise_raw.get(k, 0.0), f"sensors.noise.{k}", nonneg=True) for k in NOISE_KEYS}
    bias_raw = f.mapping(d.get("bias"), "sensors.bias", set(NOISE_KEYS))
    bias = {k: (f.scalar_or_vector(bias_raw[k], f"sensors.bias.{k}", BIAS_SIZES.get(k, n_cables))
                if k in bias_raw else np.zeros(BIAS_SIZES.get(k, n_cables))) for k in NOISE_KEYS}
    return SensorSpec(rates, noise, bias)


def experiment_from_dict(d: Any, source: str = "<memory>") -> Experiment:
    """Validate an experiment mapping (schema in the module docstring).

    ``source`` names the file in error messages.  Raises :class:`ExperimentError`.
    """
    f = _Fields(source)
    if not isinstance(d, dict):
        raise ExperimentError(f"{source}: the experiment file must be a YAML mapping")
    f.mapping(d, "(top level)", TOP_KEYS)
    name = d.get("name", Path(source).stem if source != "<memory>" else "experiment")
    if not isinstance(name, str) or not NAME.match(name):
        raise f.error("name", f"must match [A-Za-z0-9_.-]+, got {name!r}")
    if "rig" not in d:
        raise ExperimentError(f"{source}: missing field rig")
    try:
        rig = rig_from_dict(d["rig"], f"{source}: rig")
    except RigError as e:
        raise ExperimentError(str(e)) from None
    if rig.center_of_gravity is None:
        raise ExperimentError(f"{source}: missing field rig.body.center_of_gravity (the true CG to simulate)")
    if "inertia_about_cg" not in d:
        raise ExperimentError(f"{source}: missing field inertia_about_cg")
    inertia = _parse_inertia(f, d["inertia_about_cg"])
    cable_model = _parse_cable_model(f, d.get("cable_model"), rig)
    initial = _parse_initial(f, d.get("initial"))
    excitation = _parse_excitation(f, d.get("excitation"), rig)
    if "duration" not in d:
        raise ExperimentError(f"{source}: missing field duration")
    duration = f.number(d["duration"], "duration", positive=True)
    sensors = _parse_sensors(f, d.get("sensors"), len(rig.cables))
    seed = d.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise f.error("seed", f"must be an integer >= 0, got {seed!r}")
    stamp_origin = f.number(d.get("stamp_origin", DEFAULT_STAMP_ORIGIN), "stamp_origin", nonneg=True)
    static = None
    if d.get("static") is not None:
        s = f.mapping(d["static"], "static", {"kind", "duration"})
        kind = s.get("kind", "baseline")
        if kind not in ("baseline", "dummy"):
            raise f.error("static.kind", f"must be baseline or dummy, got {kind!r}")
        static = StaticSpec(kind, f.number(s.get("duration", DEFAULT_STATIC_DURATION), "static.duration",
                                           positive=True))
        if kind == "dummy" and rig.dummy_mass is None:
            raise ExperimentError(f"{source}: missing field rig.dummy_mass (needed by static.kind: dummy)")
    description = d.get("description", "")
    if not isinstance(description, str):
        raise f.error("description", "must be text")
    try:
        effects = parse_effects(d.get("effects"), f"{source}: effects", rig.cable_names)
    except ValueError as e:
        raise ExperimentError(str(e)) from None
    if any(e.name == "exciter_rotor" for e in effects) and excitation.rotating is None:
        raise ExperimentError(f"{source}: effects: exciter_rotor needs excitation.rotating")
    for i, e in enumerate(effects):
        if e.name == "compliant_body":      # the split must be a physical pair of rigid bodies
            try:
                split_body(rig.mass, rig.center_of_gravity, inertia, e, f"{source}: effects[{i}]")
            except ValueError as err:
                raise ExperimentError(str(err)) from None
    return Experiment(name=name, rig=rig, inertia=inertia, cable_model=cable_model, initial=initial,
                      excitation=excitation, duration=duration, sensors=sensors, seed=seed,
                      stamp_origin=stamp_origin, static=static, description=description,
                      reference=f.mapping(d.get("source"), "source"), thesis=f.mapping(d.get("thesis"), "thesis"),
                      path=source, effects=effects)


def load_rig_or_experiment(path: str | Path) -> Rig:
    """The rig of a rig.yaml, or the ``rig:`` section of an experiment file (as
    ``config/rigs/default.yaml`` and ``config/cases/*.yaml``: its CG is then the simulated one).
    Raises :class:`~.rig.RigError` naming the file (unreadable, not YAML, a bad field)."""
    p = Path(path)
    d = read_yaml(p, RigError, "rig description")
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        try:
            return load_experiment(p).rig
        except ExperimentError as e:
            raise RigError(str(e)) from None
    return load_rig(p)


def load_experiment(path: str | Path) -> Experiment:
    """Load and validate an experiment YAML file.  Raises :class:`ExperimentError`."""
    from .rig import read_yaml
    return experiment_from_dict(read_yaml(path, ExperimentError, "experiment file"), str(path))


# --- compliant body: the sprung body and its suspension ----------------------------------

@dataclass(frozen=True)
class RigidPart:
    """One rigid body: ``mass`` kg, ``cg`` (3,) body frame m, ``inertia`` (3, 3) kg m² about
    its own CG in body axes (entries as ``inertia_about_cg``)."""

    mass: float
    cg: np.ndarray
    inertia: np.ndarray


def _second_moment(J: np.ndarray) -> np.ndarray:
    """S = ∫ r rᵀ dm (3, 3) of an inertia tensor J = tr(S) I − S (about the same point)."""
    return 0.5 * np.trace(J) * np.eye(3) - J


def _steiner(m: float, d: np.ndarray) -> np.ndarray:
    """Parallel-axis term (3, 3) of a mass m kg offset by d (3,) m."""
    return m * (d @ d * np.eye(3) - np.outer(d, d))


def split_body(mass: float, cg, inertia, effect: Effect, where: str = "compliant_body") -> tuple[RigidPart, RigidPart]:
    """compliant_body: split a body (mass kg, cg (3,) body frame m, inertia (3, 3) about the
    CG) into the sprung body and the rest, which together are the body at rest.

    Sprung mass m_s = mass_share · m at ``sprung_cg`` (default: the CG raised by
    min(:data:`SPRUNG_RAISE`, h_max / 2), h_max the largest raise that leaves a physical rest,
    below); the rest m_u = m − m_s sits at c_u = c − (m_s/m_u)(c_s − c), keeping the CG.  With
    S = tr(J)/2 I − J the body's second moment about its CG, the two CG offsets take
    m (m_s/m_u) d dᵀ (d = c_s − c) from it; the remaining spread S_r is shared:
    S_s = σ S_r, S_u = (1 − σ) S_r (σ = ``sprung_inertia_share``, default mass_share: each
    part as spread out per kg as the other), and J_part = tr(S_part) I − S_part.  Both tensors
    are then positive semi-definite and satisfy the triangle inequalities exactly when S_r is
    positive semi-definite; h_max² = (m_u/m_s) / (m (S⁻¹)_zz).

    Returns (sprung, rest) :class:`RigidPart`.  Raises ValueError naming ``where``.sprung_cg
    when the sprung CG is too far from the CG for the body's mass distribution.
    """
    cg, J = np.asarray(cg, float), np.asarray(inertia, float)
    share = float(effect.get("mass_share"))
    m_s = share * mass
    ratio = share / (1.0 - share)                   # m_s / m_u
    S = _second_moment(J)
    if "sprung_cg" in effect.parameters:
        c_s = np.asarray(effect.parameters["sprung_cg"], float)
    else:
        s_zz = np.linalg.solve(S, [0.0, 0.0, 1.0])[2] if np.linalg.eigvalsh(S)[0] > 0 else np.inf
        h_max = math.sqrt(1.0 / (mass * ratio * s_zz)) if s_zz > 0 else 0.0
        c_s = cg + np.array([0.0, 0.0, min(SPRUNG_RAISE, 0.5 * h_max)])
    d = c_s - cg
    S_rest = S - mass * ratio * np.outer(d, d)
    low = np.linalg.eigvalsh(S_rest)[0]
    if low < -1e-9 * np.trace(S):
        h = math.sqrt(1.0 / (mass * ratio * (d / np.linalg.norm(d)) @ np.linalg.solve(S, d / np.linalg.norm(d))))
        raise ValueError(f"{where}.sprung_cg: {np.round(c_s, 4).tolist()} m is {np.linalg.norm(d):.3f} m from the CG "
                         f"{np.round(cg, 4).tolist()}; with mass_share {share} the body's mass distribution (its "
                         f"inertia_about_cg) allows at most {h:.3f} m in that direction (the rest's inertia tensor "
                         "would not be physical)")
    sigma = float(effect.get("sprung_inertia_share", share))

    def tensor(S_part):
        return np.trace(S_part) * np.eye(3) - S_part

    sprung = RigidPart(m_s, c_s, tensor(sigma * S_rest))
    rest = RigidPart(mass - m_s, cg - ratio * d, tensor((1.0 - sigma) * S_rest))
    for part, name in ((sprung, "sprung body"), (rest, "rest of the body")):
        if np.linalg.eigvalsh(part.inertia)[0] <= 0:
            raise ValueError(f"{where}.sprung_cg: the {name}'s inertia tensor is singular (all its mass on a line)")
    return sprung, rest


def _without(mass: float, cg: np.ndarray, J: np.ndarray, part: RigidPart) -> RigidPart:
    """The rigid body (mass kg, cg (3,) m, J (3, 3) about cg) less ``part``."""
    m = mass - part.mass
    c = (mass * cg - part.mass * part.cg) / m
    return RigidPart(m, c, J - part.inertia - _steiner(part.mass, part.cg - cg) - _steiner(m, c - cg))


def _vee_antisym(A: np.ndarray) -> np.ndarray:
    """vee(A − Aᵀ) (3,) of a (3, 3) matrix: (A − Aᵀ) b = vee(A − Aᵀ) × b."""
    return np.array([A[2, 1] - A[1, 2], A[0, 2] - A[2, 0], A[1, 0] - A[0, 1]])


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b of two (3,) vectors (np.cross is slow on single vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


class Suspension:
    """compliant_body: the sprung body (6 DOF) on a linear 6-DOF spring–damper to the frame.

    The joint acts at the sprung body's CG, in the frame's axes.  Relative displacement
    δ = R_fᵀ(p_s − p_f) − a (frame axes, m; a = nominal sprung CG − frame CG, body frame) and
    relative attitude R_rel = R_fᵀ R_s (identity at the nominal pose).  Force on the sprung
    body (frame axes) f = f_pre − K_t δ − C_t dδ/dt, moment on it (its own axes)
    τ = −vee(G R_rel − R_relᵀ G) − R_relᵀ C_r ω_rel with G = tr(K_r)/2 I − K_r, which is the
    exact moment of the potential tr(G (I − R_rel)) ≈ ½ θᵀ K_r θ (θ: rotation vector), and
    ω_rel = R_rel ω_s − ω_f (frame axes); the frame gets −f at the sprung CG and −R_rel τ.  So
    the joint conserves momentum, angular momentum and (without damping) energy exactly.

    Stiffness (Hz -> N/m, N·m/rad): roll, pitch k = J_s,xx|yy (2π f)², heave k = m_s (2π f)²,
    x, y k = m_s (2π f_lock)², yaw k = J_s,zz (2π f_lock)²; damping c = 2 ζ sqrt(k · m or J).
    f_pre = m_s g R_eqᵀ e_z (frame axes, N) is the springs' pre-load: it holds the sprung body
    at its nominal pose in the frame at the static equilibrium attitude R_eq, so that the whole
    body at rest has the experiment's mass, CG and inertia.

    Sprung state (18,) = [p_s world m, R_s sprung->world row-major, v_s world m/s, ω_s sprung
    axes rad/s]; at the nominal pose the sprung axes are the body axes.
    """

    def __init__(self, sprung: RigidPart, frame_cg: np.ndarray, effect: Effect, gravity: float, R_eq: np.ndarray):
        self.m, self.J = sprung.mass, sprung.inertia
        self.Jinv = np.linalg.inv(self.J)
        self.a = sprung.cg - np.asarray(frame_cg, float)
        f_roll, f_pitch, f_heave = effect.get("frequencies")
        f_lock = effect.get("lock_frequency", DEFAULT_LOCK_FREQUENCY)
        z_lock = effect.get("lock_damping_ratio", DEFAULT_LOCK_DAMPING_RATIO)
        z_roll, z_pitch, z_heave = np.broadcast_to(effect.get("damping_ratio"), (3,))
        Jd = np.diag(self.J)
        self.k_t = self.m * (2 * math.pi * np.array([f_lock, f_lock, f_heave])) ** 2
        self.k_r = Jd * (2 * math.pi * np.array([f_roll, f_pitch, f_lock])) ** 2
        self.c_t = 2 * np.array([z_lock, z_lock, z_heave]) * np.sqrt(self.k_t * self.m)
        self.c_r = 2 * np.array([z_roll, z_pitch, z_lock]) * np.sqrt(self.k_r * Jd)
        self.G = 0.5 * self.k_r.sum() * np.eye(3) - np.diag(self.k_r)
        self.g = np.array([0.0, 0.0, -gravity])
        self.preload = self.m * gravity * np.asarray(R_eq).T[:, 2]
        # plain floats for :meth:`coupling`
        self._kt, self._ct, self._a, self._pre = (tuple(x.tolist()) for x in (self.k_t, self.c_t, self.a, self.preload))
        self._g, self._cr = tuple(np.diag(self.G).tolist()), tuple(self.c_r.tolist())
        self._J, self._Jinv, self._gravity = self.J.tolist(), self.Jinv.tolist(), float(gravity)

    def coupling(self, y: np.ndarray, p: np.ndarray, R: np.ndarray, v: np.ndarray, w: np.ndarray):
        """Joint forces of state y (36,) (the frame's p_cg, R, v_cg, ω are y[:18]).

        Returns (force on the frame (3,) world N, moment on the frame about its CG (3,) body
        axes N·m, derivative of the sprung state (18,)).  The class docstring's formulas,
        written out in scalars (G, K, C diagonal): numpy's per-call cost on 3-vectors would
        double the right-hand side's time.
        """
        (px, py, pz, a00, a01, a02, a10, a11, a12, a20, a21, a22, vx, vy, vz, wx, wy, wz,
         sx, sy, sz, b00, b01, b02, b10, b11, b12, b20, b21, b22, ux, uy, uz, ox, oy, oz) = y.tolist()
        (kx, ky, kz), (cx, cy, cz), (nx, ny, nz), (fx0, fy0, fz0) = self._kt, self._ct, self._a, self._pre
        (g0, g1, g2), (dx, dy, dz) = self._g, self._cr
        # q = Rᵀ(p_s − p) and dδ/dt = Rᵀ(v_s − v) − ω × q, frame axes
        ex, ey, ez = sx - px, sy - py, sz - pz
        qx, qy, qz = a00 * ex + a10 * ey + a20 * ez, a01 * ex + a11 * ey + a21 * ez, a02 * ex + a12 * ey + a22 * ez
        ex, ey, ez = ux - vx, uy - vy, uz - vz
        rx = a00 * ex + a10 * ey + a20 * ez - (wy * qz - wz * qy)
        ry = a01 * ex + a11 * ey + a21 * ez - (wz * qx - wx * qz)
        rz = a02 * ex + a12 * ey + a22 * ez - (wx * qy - wy * qx)
        fx = fx0 - kx * (qx - nx) - cx * rx               # force on the sprung body, frame axes
        fy = fy0 - ky * (qy - ny) - cy * ry
        fz = fz0 - kz * (qz - nz) - cz * rz
        # R_rel = Rᵀ R_s; ω_rel = R_rel ω_s − ω; τ = −vee(G R_rel − R_relᵀ G) − R_relᵀ C_r ω_rel
        c00, c01, c02 = (a00 * b00 + a10 * b10 + a20 * b20, a00 * b01 + a10 * b11 + a20 * b21,
                         a00 * b02 + a10 * b12 + a20 * b22)
        c10, c11, c12 = (a01 * b00 + a11 * b10 + a21 * b20, a01 * b01 + a11 * b11 + a21 * b21,
                         a01 * b02 + a11 * b12 + a21 * b22)
        c20, c21, c22 = (a02 * b00 + a12 * b10 + a22 * b20, a02 * b01 + a12 * b11 + a22 * b21,
                         a02 * b02 + a12 * b12 + a22 * b22)
        mx = dx * (c00 * ox + c01 * oy + c02 * oz - wx)
        my = dy * (c10 * ox + c11 * oy + c12 * oz - wy)
        mz = dz * (c20 * ox + c21 * oy + c22 * oz - wz)
        tx = g1 * c12 - g2 * c21 - (c00 * mx + c10 * my + c20 * mz)      # on the sprung body, its axes
        ty = g2 * c20 - g0 * c02 - (c01 * mx + c11 * my + c21 * mz)
        tz = g0 * c01 - g1 * c10 - (c02 * mx + c12 * my + c22 * mz)
        Fx, Fy, Fz = a00 * fx + a01 * fy + a02 * fz, a10 * fx + a11 * fy + a12 * fz, a20 * fx + a21 * fy + a22 * fz
        Tx, Ty, Tz = c00 * tx + c01 * ty + c02 * tz, c10 * tx + c11 * ty + c12 * tz, c20 * tx + c21 * ty + c22 * tz
        (j00, j01, j02), (j10, j11, j12), (j20, j21, j22) = self._J
        hx, hy, hz = j00 * ox + j01 * oy + j02 * oz, j10 * ox + j11 * oy + j12 * oz, j20 * ox + j21 * oy + j22 * oz
        tx, ty, tz = tx - (oy * hz - oz * hy), ty - (oz * hx - ox * hz), tz - (ox * hy - oy * hx)
        (i00, i01, i02), (i10, i11, i12), (i20, i21, i22) = self._Jinv
        im = 1.0 / self.m
        dys = np.array([ux, uy, uz,
                        b01 * oz - b02 * oy, b02 * ox - b00 * oz, b00 * oy - b01 * ox,       # R_s skew(ω_s)
                        b11 * oz - b12 * oy, b12 * ox - b10 * oz, b10 * oy - b11 * ox,
                        b21 * oz - b22 * oy, b22 * ox - b20 * oz, b20 * oy - b21 * ox,
                        Fx * im, Fy * im, Fz * im - self._gravity,
                        i00 * tx + i01 * ty + i02 * tz, i10 * tx + i11 * ty + i12 * tz, i20 * tx + i21 * ty + i22 * tz])
        return (np.array([-Fx, -Fy, -Fz]),
                np.array([qz * fy - qy * fz - Tx, qx * fz - qz * fx - Ty, qy * fx - qx * fy - Tz]), dys)

    def relative(self, Y: np.ndarray) -> np.ndarray:
        """(K, 6) of states Y (K, 36): δ (frame axes, m) and the rotation vector of R_rel
        (frame axes, rad) of the sprung body from its nominal pose in the frame."""
        R = Y[:, 3:12].reshape(-1, 3, 3)
        delta = np.einsum("kji,kj->ki", R, Y[:, 18:21] - Y[:, 0:3]) - self.a
        R_rel = np.einsum("kji,kjl->kil", R, Y[:, 21:30].reshape(-1, 3, 3))
        return np.hstack([delta, Rotation.from_matrix(R_rel).as_rotvec()])

    def energy(self, Y: np.ndarray) -> np.ndarray:
        """(K,) J: the sprung body's kinetic and gravity energy plus the joint's potential
        ½ δᵀK_tδ − f_pre·δ + tr(G (I − R_rel)) at states Y (K, 36) (for tests)."""
        rel = Y[:, 18:21] - Y[:, 0:3]
        R = Y[:, 3:12].reshape(-1, 3, 3)
        delta = np.einsum("kji,kj->ki", R, rel) - self.a
        R_rel = np.einsum("kji,kjl->kil", R, Y[:, 21:30].reshape(-1, 3, 3))
        ws = Y[:, 33:36]
        kinetic = 0.5 * self.m * (Y[:, 30:33] ** 2).sum(1) + 0.5 * np.einsum("ki,ij,kj->k", ws, self.J, ws)
        spring = (0.5 * (self.k_t * delta ** 2).sum(1) - delta @ self.preload
                  + np.trace(self.G) - np.einsum("ij,kji->k", self.G, R_rel))
        return kinetic - self.m * (Y[:, 18:21] @ self.g) + spring

    def state_from_whole(self, y: np.ndarray, cg: np.ndarray, frame_cg: np.ndarray) -> np.ndarray:
        """(36,) state of frame and sprung body from a whole-body rigid state y (18,) (CG
        ``cg``, body frame): both move with the whole body, the sprung body at its nominal pose."""
        p, R, v, w = y[0:3], y[3:12].reshape(3, 3), y[12:15], y[15:18]
        out = np.empty(36)
        for k, c in ((0, frame_cg), (18, frame_cg + self.a)):
            r = R @ (c - cg)
            out[k:k + 3], out[k + 3:k + 12] = p + r, y[3:12]
            out[k + 12:k + 15], out[k + 15:k + 18] = v + _cross(R @ w, r), w
        return out

    def describe(self, frame: RigidPart, sprung: RigidPart) -> dict:
        """truth.yaml's simulator.compliant_body: the two bodies and the joint (SI)."""
        return {"sprung_mass": float(sprung.mass), "sprung_cg": sprung.cg.tolist(),
                "sprung_inertia_about_cg": inertia_entries(sprung.inertia),
                "frame_mass": float(frame.mass), "frame_cg": frame.cg.tolist(),
                "frame_inertia_about_cg": inertia_entries(frame.inertia),
                "stiffness_translation": self.k_t.tolist(), "stiffness_rotation": self.k_r.tolist(),
                "damping_translation": self.c_t.tolist(), "damping_rotation": self.c_r.tolist(),
                "preload": self.preload.tolist(),
                "joint": "6-DOF linear spring-damper at the sprung CG, frame axes: translation x y z, rotation "
                         "roll pitch yaw; the frame (rest of the body + dummy/cable masses) carries the sensors"}


# --- the mechanical model --------------------------------------------------------------

def _skew(a) -> np.ndarray:
    """(3, 3) matrix of the cross product a × ·."""
    x, y, z = a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def _moment_sum(s: np.ndarray, f: np.ndarray) -> np.ndarray:
    """sum_i s_i × f_i of two (N, 3) arrays -> (3,)."""
    X = s.T @ f
    return np.array([X[1, 2] - X[2, 1], X[2, 0] - X[0, 2], X[0, 1] - X[1, 0]])


class _Model:
    """Forces, tensions and state derivative of the suspended rigid body.

    State y (18,) = [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s];
    with a :class:`Suspension` (compliant_body) the body is the frame and y (36,) continues
    with the sprung body's state.
    """

    def __init__(self, rig: Rig, mass: float, cg: np.ndarray, inertia: np.ndarray, cables: CableModel,
                 excitation: Excitation, effects: tuple = (), suspension: Suspension | None = None):
        n = len(rig.cables)
        if cables.type == "inextensible" and n > 6:
            raise SimulationError(f"inextensible cables: {n} cables have statically indeterminate tensions "
                                  "(at most 6); use the spring model")
        self.m = float(mass)
        self.J = np.asarray(inertia, float)
        self.Jinv = np.linalg.inv(self.J)
        self.cg = np.asarray(cg, float)
        self.A = rig.ceiling_anchors
        self.r = rig.body_anchors - self.cg
        self.r_skew = np.array([_skew(r) for r in self.r])      # (N, 3, 3): r_i × ·
        self.L = rig.cable_lengths
        self.g = np.array([0.0, 0.0, -rig.gravity])
        self.cables = cables
        self.excitation = excitation
        self.suspension = suspension
        self.size = 18 if suspension is None else 36
        ex = rig.exciter
        self.R_exc = ex.rotation.as_matrix() if ex is not None else np.eye(3)
        r_exc = ex.position - self.cg if ex is not None else np.zeros(3)
        self.M_exc = _skew(r_exc) @ self.R_exc          # exciter-frame force -> moment about the CG
        self._dissipative = [e for e in effects if e.name in ("viscous_damping", "air_drag", "coulomb_friction")]
        self._rotor = next((e for e in effects if e.name == "exciter_rotor"), None)
        if self._rotor is not None:
            rot = excitation.rotating
            self._unbalance = self._rotor.get("unbalance", rot.amplitude / (2 * math.pi * rot.frequency) ** 2)
            self._rotor_inertia = self._rotor.get("rotor_inertia", 0.0)

    def effect_wrench(self, t: float, R: np.ndarray, v: np.ndarray, w: np.ndarray):
        """Force (3,) world N and moment (3,) body N·m about the CG of the concealed effects
        (:mod:`~rig_identification.effects`): dissipation and the exciter's rotor."""
        F, M = np.zeros(3), np.zeros(3)
        for e in self._dissipative:
            if e.name == "viscous_damping":
                F -= e.get("linear") * v
                M -= e.get("angular") * w
            elif e.name == "air_drag":
                F -= e.get("linear") * math.sqrt(v @ v) * v
                M -= e.get("angular") * math.sqrt(w @ w) * w
            else:
                eps = e.get("velocity_scale", 1e-3)
                F -= e.get("force") * v / math.sqrt(v @ v + eps * eps)
                M -= e.get("torque") * w / math.sqrt(w @ w + eps * eps)
        if self._rotor is not None:
            theta, speed, acc = self.excitation.rotating.angle_and_speed(t)
            z = self.R_exc[:, 2]
            u = self.R_exc @ np.array([math.cos(theta), math.sin(theta), 0.0])   # toward the unbalanced mass
            M += self._unbalance * np.cross(u, R.T @ self.g)                 # its weight, turning with it
            h = self._rotor_inertia * speed * z                                # spin angular momentum, body
            M -= np.cross(w, h) + self._rotor_inertia * acc * z
        return F, M

    def breakpoints(self) -> list[float]:
        """Times where the forcing is discontinuous (or has a kink), s."""
        out = [] if self.excitation.rotating is None else self.excitation.rotating.breakpoints()
        for p in self.excitation.pulses:
            out += [p.start, p.end]
        return out

    def external(self, t: float, R: np.ndarray):
        """Forces of the exciter and the pulses at time t (s), attitude R (3, 3).

        Returns (F (3,) world N, M (3,) about the CG in body axes N m, measured (2,) N: x, y
        of the force at the exciter's load cells in the exciter frame).
        """
        if self.excitation.rotating is not None:
            f_exc = self.excitation.rotating.force(t)
            F_body = self.R_exc @ f_exc
            M = self.M_exc @ f_exc
            measured = f_exc.copy()
        else:
            F_body, M, measured = np.zeros(3), np.zeros(3), np.zeros(3)
        F_world = R @ F_body
        for p in self.excitation.pulses:
            if p.start <= t < p.end:
                if p.frame == "world":
                    F_world += p.force
                    f = R.T @ p.force
                else:
                    f = p.force
                    F_world += R @ f
                M += _skew(p.point - self.cg) @ f
                if p.measured:
                    measured += self.R_exc.T @ f
        return F_world, M, measured[:2]

    def evaluate_one(self, t: float, y: np.ndarray):
        """State derivative (size,), cable tensions (N,) N and exciter reading (2,) N of state
        y (size,) at time t s: the Newton–Euler equations of the module docstring."""
        p, R, v, w = y[0:3], y[3:12].reshape(3, 3), y[12:15], y[15:18]
        F_ext, M_ext, exciter = self.external(t, R)
        if self._dissipative or self._rotor is not None:
            dF, dM = self.effect_wrench(t, R, v, w)
            F_ext, M_ext = F_ext + dF, M_ext + dM
        if self.suspension is not None:
            dF, dM, dy_sprung = self.suspension.coupling(y, p, R, v, w)
            F_ext, M_ext = F_ext + dF, M_ext + dM
        W = _skew(w)
        Rdot = R @ W                                    # dR/dt = R skew(ω)
        s = self.r @ R.T                                # lever arms CG -> body anchors, world
        d = self.A - p - s                              # body anchor -> ceiling anchor
        l = np.sqrt((d * d).sum(axis=1))
        u = d / l[:, None]
        Pdot = v + self.r @ Rdot.T                      # body-anchor velocities, world
        ldot = -(u * Pdot).sum(axis=1)
        M_rest = M_ext - W @ (self.J @ w)               # external moment - ω × Jω, body
        if self.cables.type == "spring":
            T = np.maximum(self.cables.stiffness * (l - self.L) + self.cables.damping * ldot, 0.0)
            Tu = T[:, None] * u
            a = (Tu.sum(axis=0) + F_ext) / self.m + self.g
            alpha = self.Jinv @ (_moment_sum(self.r, Tu @ R) + M_rest)
        else:
            a, alpha, T = self._constrained(R, Rdot, W, d, l, u, Pdot, ldot, F_ext, M_rest)
        dy = np.empty(self.size)
        dy[0:3], dy[3:12], dy[12:15], dy[15:18] = v, Rdot.ravel(), a, alpha
        if self.suspension is not None:
            dy[18:] = dy_sprung
        return dy, T, exciter

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """The integrator's right-hand side: dy/dt (size,) of y (size,) at t."""
        return self.evaluate_one(t, y)[0]

    def _constrained(self, R, Rdot, W, d, l, u, Pdot, ldot, F_ext, M_rest):
        """KKT solve for inextensible cables -> (a (3,), α (3,), T (N,)).

        Generalised accelerations q̈ = [a (world); α (body)] satisfy M q̈ = Q + B T with
        B_i = [u_i; r_i × Rᵀu_i] and, per cable, B_iᵀq̈ = (|Ṗ_i|² - d_i·(ω×(ω×s_i)) + 2β φ̇_i
        + β² φ_i) / l_i: the second derivative of φ_i = (l_i² - L_i²)/2 = 0 with Baumgarte
        stabilisation.  W = skew(ω) (body), Rdot = R W; M_rest: external moment minus
        ω × Jω (body).
        """
        beta = self.cables.baumgarte
        n = len(l)
        B, MinvB, MinvQ = np.empty((n, 6)), np.empty((n, 6)), np.empty(6)     # B: rows B_iᵀ
        B[:, :3] = u
        B[:, 3:] = (self.r_skew @ (u @ R)[:, :, None])[:, :, 0]             # r_i × Rᵀu_i, body axes
        MinvB[:, :3] = u / self.m
        MinvB[:, 3:] = B[:, 3:] @ self.Jinv
        MinvQ[:3] = F_ext / self.m + self.g
        MinvQ[3:] = self.Jinv @ M_rest
        centripetal = self.r @ (Rdot @ W).T             # R (ω × (ω × r_i)), world
        h = ((Pdot * Pdot).sum(axis=1) - (d * centripetal).sum(axis=1)
             + 2 * beta * l * ldot + 0.5 * beta ** 2 * (l ** 2 - self.L ** 2)) / l
        _, T, info = dposv(B @ MinvB.T, h - B @ MinvQ)   # B M⁻¹ Bᵀ is symmetric positive definite
        if info != 0:
            raise SimulationError("inextensible cables: the constraint Jacobian is singular "
                                  "(degenerate cable geometry)")
        qdd = MinvQ + MinvB.T @ T
        return qdd[:3], qdd[3:], T

    def evaluate(self, t: np.ndarray, Y: np.ndarray) -> dict:
        """:meth:`evaluate_one` at times t (K,) and states Y (K, size).

        Returns a dict: ``R`` (K, 3, 3) orthonormalised body->world, ``a`` (K, 3) CG
        acceleration world m/s², ``alpha`` (K, 3) dω/dt body rad/s², ``T`` (K, N) tensions N,
        ``exciter`` (K, 2) N.
        """
        out = [self.evaluate_one(tk, yk) for tk, yk in zip(np.atleast_1d(t), np.atleast_2d(Y))]
        dY = np.array([o[0] for o in out])
        return {"R": Rotation.from_matrix(np.atleast_2d(Y)[:, 3:12].reshape(-1, 3, 3)).as_matrix(),
                "a": dY[:, 12:15], "alpha": dY[:, 15:18], "T": np.array([o[1] for o in out]),
                "exciter": np.array([o[2] for o in out])}

    def static_wrench(self, p_cg: np.ndarray, R: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Net force (world, N) and moment about the CG (world, N m) of cables + weight at rest, (6,)."""
        s = self.r @ R.T
        d = self.A - (p_cg + s)
        u = d / np.linalg.norm(d, axis=1)[:, None]
        return np.concatenate([T @ u + self.m * self.g, _moment_sum(s, T[:, None] * u)])

    def spring_tension_at_rest(self, p_cg, R) -> np.ndarray:
        l = np.linalg.norm(self.A - (p_cg + self.r @ R.T), axis=1)
        return np.maximum(self.cables.stiffness * (l - self.L), 0.0)


# --- equilibrium and initial pose -----------------------------------------------------------

def _pose(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x = [p_cg (3), rotation vector (3)] -> (p_cg, R (3, 3))."""
    return x[:3], Rotation.from_rotvec(x[3:]).as_matrix()


def _lengths(model: _Model, x: np.ndarray) -> np.ndarray:
    p, R = _pose(x)
    return np.linalg.norm(model.A - (p + model.r @ R.T), axis=1)


def _hanging_guess(model: _Model) -> np.ndarray:
    """A start pose (body axes = world axes) with every cable within its length."""
    h = model.A - model.r                          # CG position if cable i had zero length
    xy = h[:, :2].mean(axis=0)
    rho2 = np.sum((h[:, :2] - xy) ** 2, axis=1)
    z = np.max(h[:, 2] - np.sqrt(np.maximum(model.L ** 2 - rho2, 0.0)))
    return np.array([xy[0], xy[1], z, 0.0, 0.0, 0.0])


def _solve_or_fail(fun, x0, what: str, tol: float, scale: float):
    sol = root(fun, x0, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        sol = root(fun, sol.x, method="lm", options={"xtol": 1e-15, "ftol": 1e-15})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        # the stiff spring equations can stall both from a poor start (seen with single-threaded
        # BLAS rounding): scaled trust-region least squares from the original start, then polish
        from scipy.optimize import least_squares
        ls = least_squares(fun, x0, method="trf", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                           max_nfev=2000)
        sol = root(fun, ls.x, method="hybr", options={"xtol": 1e-14})
    if np.max(np.abs(fun(sol.x))) * scale > tol:
        raise SimulationError(f"{what}: no static equilibrium found ({sol.message})")
    return sol.x


def _equilibrium(model: _Model) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p_cg (3,), R (3, 3), tensions (N,)) at static equilibrium (thesis eqs. 2.20–2.25)."""
    n = len(model.L)
    weight = model.m * np.linalg.norm(model.g)
    # 1) inextensible hanging pose: lowest CG with every cable no longer than its length
    cons = {"type": "ineq", "fun": lambda x: model.L ** 2 - _lengths(model, x) ** 2}
    opt = minimize(lambda x: x[2], _hanging_guess(model), method="SLSQP", constraints=[cons],
                   options={"ftol": 1e-14, "maxiter": 500})
    x = opt.x
    if model.cables.type == "spring":
        # 2) springs: sag by the mean stretch, then solve the 6 force/moment equations exactly
        x = x - np.array([0.0, 0.0, weight / model.cables.stiffness.sum(), 0, 0, 0])

        def residual(x):
            p, R = _pose(x)
            return model.static_wrench(p, R, model.spring_tension_at_rest(p, R)) / weight

        x = _solve_or_fail(residual, x, "spring cables", 1e-7, weight)
        p, R = _pose(x)
        return p, R, model.spring_tension_at_rest(p, R)
    # 2) inextensible: the 6 equilibrium equations + the length equations of the taut cables,
    #    unknowns pose + tensions; a cable whose tension comes out negative is slack.
    active = np.ones(n, bool)
    p, R = _pose(x)
    s = model.r @ R.T
    u = (model.A - (p + s)) / _lengths(model, x)[:, None]
    T0 = np.linalg.lstsq(np.vstack([u.T, np.cross(s, u).T]), -np.concatenate([model.m * model.g, np.zeros(3)]),
                         rcond=None)[0] / weight
    while True:
        idx = np.flatnonzero(active)

        def residual(z):
            T = np.zeros(n)
            T[idx] = z[6:] * weight
            p, R = _pose(z[:6])
            return np.concatenate([model.static_wrench(p, R, T) / weight, (_lengths(model, z[:6]) - model.L)[idx]])

        z = _solve_or_fail(residual, np.concatenate([x, T0[idx]]), "inextensible cables", 1e-7, weight)
        T = np.zeros(n)
        T[idx] = z[6:] * weight
        if T.min() >= 0 or model.cables.compression:
            p, R = _pose(z[:6])
            return p, R, T
        active[np.argmin(T)] = False
        x, T0 = z[:6], T / weight
        if active.sum() < 3:
            raise SimulationError("inextensible cables: no equilibrium with at least 3 taut cables")


def _project(model: _Model, p_cg: np.ndarray, R: np.ndarray, target: np.ndarray):
    """Move a pose the least distance (Gauss–Newton, minimum-norm steps in CG position and
    world rotation vector) so that the cable lengths equal ``target`` (N,) m."""
    for _ in range(50):
        s = model.r @ R.T
        d = model.A - (p_cg + s)
        l = np.linalg.norm(d, axis=1)
        err = l - target
        if np.max(np.abs(err)) < 1e-13:
            break
        u = d / l[:, None]
        Jac = np.hstack([-u, -np.cross(s, u)])               # dl / d[p, θ_world]
        step = -np.linalg.lstsq(Jac, err, rcond=None)[0]
        p_cg = p_cg + step[:3]
        R = Rotation.from_rotvec(step[3:]).as_matrix() @ R
    else:
        raise SimulationError("the initial pose cannot be projected onto the cable lengths")
    return p_cg, R


def equilibrium(rig: Rig, mass: float, cg, cable_model: CableModel) -> tuple[np.ndarray, Rotation, np.ndarray]:
    """Static equilibrium of the body hanging at rest (thesis section 2.2, eqs. 2.13–2.25).

    rig: geometry (its own body mass/CG are ignored); mass: kg; cg: (3,) body frame, m.
    Springs include the cable stretch; inextensible cables solve the 6 equilibrium equations
    plus the length equations of the taut cables (slack cables get tension 0; with
    ``compression`` every cable keeps its length).

    Returns (position (3,) world position of the BODY-FRAME ORIGIN m, Rotation body->world,
    tensions (N,) N).  The net force and the moment about the CG vanish to < 1e-6 N, N m.
    Raises :class:`SimulationError` (no equilibrium; inextensible with N > 6).
    """
    cg = np.asarray(cg, float)
    model = _Model(rig, mass, cg, np.eye(3), cable_model, Excitation())
    p_cg, R, T = _equilibrium(model)
    return p_cg - R @ cg, Rotation.from_matrix(R), T


def _initial_state(model: _Model, initial: Initial, eq: tuple | None = None) -> np.ndarray:
    """(18,) start state of the rigid ``model``; ``eq``: its :func:`_equilibrium` if known."""
    p_eq, R_eq, T_eq = _equilibrium(model) if eq is None else eq
    if initial.pose_cg_position is not None:
        p, R = initial.pose_cg_position.copy(), Rotation.from_euler("xyz", initial.pose_rpy).as_matrix()
    else:
        p = p_eq + initial.displacement_position
        R = Rotation.from_euler("xyz", initial.displacement_rpy).as_matrix() @ R_eq
    moved = initial.pose_cg_position is not None or np.any(initial.displacement_position) \
        or np.any(initial.displacement_rpy)
    if moved and initial.project:
        target = model.L + (T_eq / model.cables.stiffness if model.cables.type == "spring" else 0.0)
        p, R = _project(model, p, R, target)
    return np.concatenate([p, R.ravel(), np.zeros(6)])


# --- integration ---------------------------------------------------------------------------

class Trajectory:
    """The dense true motion: piecewise DOP853 interpolants between forcing breakpoints.

    Call with simulation times t (K,) s (0 = start) -> states (K, size)
    [p_cg world m, R body->world row-major, v_cg world m/s, ω body rad/s] (size 18), followed
    by the sprung body's (size 36, compliant_body, see :class:`Suspension`).
    """

    def __init__(self, segments: list, size: int = 18):
        self.segments = segments
        self.size = size
        self.starts = np.array([s[0] for s in segments])

    def __call__(self, t) -> np.ndarray:
        t = np.atleast_1d(np.asarray(t, float))
        idx = np.clip(np.searchsorted(self.starts, t, side="right") - 1, 0, len(self.segments) - 1)
        out = np.empty((len(t), self.size))
        for k in np.unique(idx):
            m = idx == k
            out[m] = self.segments[k][2](t[m]).T
        return out


def _integrate(model: _Model, y0: np.ndarray, duration: float, rtol: float = RTOL,
               atol: float = ATOL) -> tuple[Trajectory, int]:
    cuts = sorted({b for b in model.breakpoints() if 0 < b < duration} | {0.0, duration})
    segments, nfev, y = [], 0, y0
    for t0, t1 in zip(cuts[:-1], cuts[1:]):
        sol = solve_ivp(model.rhs, (t0, t1), y, method="DOP853", rtol=rtol, atol=atol, dense_output=True)
        if not sol.success:
            raise SimulationError(f"integration failed at t = {sol.t[-1]:.3f} s: {sol.message}")
        nfev += sol.nfev
        segments.append((t0, t1, sol.sol))
        y = sol.y[:, -1]
    return Trajectory(segments, model.size), nfev


# --- results ---------------------------------------------------------------------------------

@dataclass
class States:
    """True motion at given times.

    t (K,) header stamps s (stamp_origin + simulation time); position (K, 3) world position of
    the BODY-FRAME ORIGIN m; quaternion (K, 4) body->world, xyzw (``Rotation.as_quat``);
    velocity (K, 3) world velocity of the body-frame origin m/s; omega (K, 3) body axes rad/s;
    tensions (K, N) N.  With compliant_body these are the frame's (it carries the sensors) and
    suspension (K, 6) is the sprung body's displacement from its nominal place (frame axes, m)
    and its rotation vector relative to the frame (frame axes, rad); else None.
    """

    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    tensions: np.ndarray
    suspension: np.ndarray | None = None

    @property
    def rotation(self) -> Rotation:
        return Rotation.from_quat(self.quaternion)


@dataclass
class SimResult:
    """Output of :func:`simulate`.

    rig: the rig description to write (CG filled in for dynamic experiments, no CG for static
    ones); sensors: the sensor streams; truth: truth.yaml mapping; states: true motion at the
    IMU sample times; trajectory: dense true motion (simulation time); wall_time: s.
    """

    experiment: Experiment
    rig: Rig
    sensors: SensorData
    truth: dict
    states: States
    trajectory: Trajectory
    model: _Model
    wall_time: float
    nfev: int

    def states_at(self, t) -> States:
        """True motion at simulation times ``t`` (K,) s (0 = start; States.t holds the stamps)."""
        t = np.atleast_1d(np.asarray(t, float))
        Y = self.trajectory(t)
        return _states(self.model, self.experiment.stamp_origin, t, Y, self.model.evaluate(t, Y))


def _states(model: _Model, stamp_origin: float, t: np.ndarray, Y: np.ndarray, ev: dict) -> States:
    R, c = ev["R"], model.cg
    return States(t=stamp_origin + t, position=Y[:, 0:3] - R @ c, quaternion=Rotation.from_matrix(R).as_quat(),
                  velocity=Y[:, 12:15] - np.einsum("kij,kj->ki", R, np.cross(Y[:, 15:18], c)),
                  omega=Y[:, 15:18].copy(), tensions=ev["T"],
                  suspension=None if model.suspension is None else model.suspension.relative(Y))


def _sample_times(duration: float, rate: float) -> np.ndarray:
    return np.arange(int(math.floor(duration * rate + 1e-9)) + 1) / rate


def _sensors(exp: Experiment, model: _Model, traj: Trajectory, rig: Rig, duration: float, cache: dict) -> SensorData:
    """Sample every sensor on its own time grid; ``cache`` keeps (t, Y, evaluation) per rate."""
    spec = exp.sensors
    rng = np.random.default_rng(exp.seed if exp.static is None
                                else [exp.seed, STATIC_STREAMS[exp.static.kind]])
    noise, bias = spec.noise, spec.bias

    def at(rate: float):
        if rate not in cache:
            t = _sample_times(duration, rate)
            Y = traj(t)
            cache[rate] = (t, Y, model.evaluate(t, Y))
        return cache[rate]

    def noisy(x, key):
        return x + bias[key] + noise[key] * rng.standard_normal(x.shape)

    eff = {e.name: e for e in exp.effects}
    delay = {e.get("stream", ""): e.get("delay") for e in exp.effects if e.name == "sensor_delay"}
    mode = {e.get("sensor"): e for e in exp.effects if e.name == "structural_mode"}

    g_world = model.g
    # IMU
    t, Y, ev = at(spec.rates["imu"])
    R_imu = rig.imu.rotation.as_matrix()
    if "imu_misalignment" in eff:   # true IMU axes: turned beyond rig.yaml's imu.rpy
        R_imu = R_imu @ Rotation.from_euler("xyz", eff["imu_misalignment"].get("rpy")).as_matrix()
    omega, alpha = Y[:, 15:18], ev["alpha"]
    rho = rig.imu.position - model.cg
    if "imu_offset" in eff:         # true IMU position: rig.yaml's + offset
        rho = rho + eff["imu_offset"].get("offset")
    a_rel_body = np.cross(alpha, rho) + np.cross(omega, np.cross(omega, rho))
    a_imu = ev["a"] + np.einsum("kij,kj->ki", ev["R"], a_rel_body)
    f_body = np.einsum("kji,kj->ki", ev["R"], a_imu - g_world)
    gyro_true, acc_true = omega @ R_imu, f_body @ R_imu
    if "imu" in mode:               # the IMU's mount rings: ω + θ̇, specific force + ẍ
        gyro_true = gyro_true + mode_response(t, gyro_true, mode["imu"])
        acc_true = acc_true + mode_response(t, acc_true, mode["imu"])
    if "gyro_scale" in eff:         # scale errors act on the sensed rate, before noise and bias
        gyro_true = gyro_true * eff["gyro_scale"].get("scale")
    gyro = noisy(gyro_true, "gyro")
    acc = noisy(acc_true, "accelerometer")
    if "gyro_bias" in eff:
        gyro += eff["gyro_bias"].get("bias")
    if "accelerometer_bias" in eff:
        acc += eff["accelerometer_bias"].get("bias")
    t_imu = t
    # load cells
    t, Y, ev = at(spec.rates["load_cells"])
    if model.cables.type == "inextensible" and not model.cables.compression:
        _check_taut(rig, t, ev["T"], model.m * np.linalg.norm(g_world))
    T = ev["T"].copy()
    if "load_cells" in mode:        # each load cell reads its flexible anchor's spring force
        T = T + mode_response(t, T, mode["load_cells"])
    for e in exp.effects:
        if e.name == "load_cell_scale":
            T[:, rig.cable_names.index(e.get("cable"))] *= e.get("scale")
    T = noisy(T, "load_cell")
    t_cells = exp.stamp_origin + t + delay.get("load_cells", 0.0)
    cells = {name: TimeSeries(t_cells, T[:, i]) for i, name in enumerate(rig.cable_names)}
    # exciter
    exc = None
    if rig.exciter is not None:
        t, Y, ev = at(spec.rates["exciter"])
        exc = TimeSeries(exp.stamp_origin + t + delay.get("exciter", 0.0), noisy(ev["exciter"], "exciter"))
    # inclinometer
    inc = None
    if rig.inclinometer is not None:
        t, Y, ev = at(spec.rates["inclinometer"])
        axes = ev["R"] @ rig.inclinometer.rotation.as_matrix()
        angles = np.arcsin(np.clip(axes[:, 2, :2], -1.0, 1.0))
        inc = TimeSeries(exp.stamp_origin + t + delay.get("inclinometer", 0.0), noisy(angles, "inclinometer"))
    if "gyro_bias_drift" in eff:    # drawn last: every other stream's noise stays as without it
        gyro += random_walk(rng, len(t_imu), 1.0 / spec.rates["imu"], eff["gyro_bias_drift"].get("random_walk"))
    imu = TimeSeries(exp.stamp_origin + t_imu, np.hstack([gyro, acc]))
    return SensorData(imu, cells, exc, inc)


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
    return lfilter(np.ravel(num), den, x_fine, axis=0)[::m]


def _check_taut(rig: Rig, t: np.ndarray, T: np.ndarray, weight: float) -> None:
    bad = T < -1e-9 * weight
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise SimulationError(f"inextensible cables: cable {rig.cable_names[i]} goes slack at t = {t[k]:.3f} s "
                              f"(tension {T[k, i]:.3g} N); the inextensible model cannot represent slack "
                              "cables, use cable_model.type: spring")


def _with_dummy(mass: float, cg: np.ndarray, J: np.ndarray, dummy: DummyMass):
    """Mass (kg), CG (3,) and inertia about the new CG (3, 3) of the body plus a point-mass dummy."""
    m = mass + dummy.mass
    c = (mass * cg + dummy.mass * dummy.position) / m

    def steiner(mm, d):
        return mm * (d @ d * np.eye(3) - np.outer(d, d))

    return m, c, J + steiner(mass, cg - c) + steiner(dummy.mass, dummy.position - c)


def simulate(exp: Experiment) -> SimResult:
    """Run the experiment: equilibrium, integration (DOP853), sensor sampling with noise.

    Static experiments (``exp.static``) hold the body at rest without excitation (plus the
    dummy mass for kind ``dummy``) for ``exp.static.duration``.  Raises
    :class:`SimulationError`.
    """
    t_wall = time.perf_counter()
    mass, cg, J = exp.mass, exp.cg, exp.inertia
    excitation, duration, initial = exp.excitation, exp.duration, exp.initial
    cables = exp.cable_model
    static = exp.static
    if static is not None:
        excitation, duration, initial = Excitation(), static.duration, Initial()
        if static.kind == "dummy":
            mass, cg, J = _with_dummy(mass, cg, J, exp.rig.dummy_mass)
        rig_out = replace(exp.rig, center_of_gravity=None)
    else:
        rig_out = replace(exp.rig, dummy_mass=None)
    elastic = exp.effect("cable_elasticity")
    if elastic is not None:     # cables of another stiffness than the rig.yaml written states
        k = elastic.get("stiffness")
        cables = CableModel.spring(exp.rig, mass, np.full(len(exp.rig.cables), k))
        kd = elastic.parameters.get("declared_stiffness")
        rig_out = replace(rig_out, cables=tuple(replace(c, stiffness=kd) for c in rig_out.cables))
    body_mass = exp.effect("body_mass")
    if body_mass is not None:   # rig.yaml states a mass the body does not have
        rig_out = replace(rig_out, mass=float(exp.rig.mass - body_mass.get("mass_error")))
    cable_mass = exp.effect("cable_mass")
    if cable_mass is not None:  # half of each cable hangs on its body anchor, outside the load cell
        for b in exp.rig.body_anchors:
            mass, cg, J = _with_dummy(mass, cg, J, DummyMass(0.5 * cable_mass.get("mass"), np.asarray(b, float)))
    model = _Model(exp.rig, mass, cg, J, cables, excitation, exp.effects)
    compliant = exp.effect("compliant_body")
    rtol, atol = RTOL, ATOL
    if compliant is None:
        y0 = _initial_state(model, initial)
    else:                       # the whole body's rest pose; then frame + sprung body at it
        eq = _equilibrium(model)
        y_whole = _initial_state(model, initial, eq)
        sprung, _ = split_body(exp.mass, exp.cg, exp.inertia, compliant)
        frame = _without(mass, cg, J, sprung)     # the rest of the body + dummy and cable masses
        suspension = Suspension(sprung, frame.cg, compliant, exp.rig.gravity, eq[1])
        model = _Model(exp.rig, frame.mass, frame.cg, frame.inertia, cables, excitation, exp.effects, suspension)
        y0 = suspension.state_from_whole(y_whole, cg, frame.cg)
        rtol, atol = COMPLIANT_RTOL, COMPLIANT_ATOL
    traj, nfev = _integrate(model, y0, duration, rtol, atol)
    cache: dict[float, tuple] = {}
    sensors = _sensors(exp, model, traj, rig_out, duration, cache)
    truth = {"mass": float(exp.mass), "center_of_gravity": [float(x) for x in exp.cg],
             "inertia_about_cg": inertia_entries(exp.inertia),
             "effects": [e.truth_entry() for e in exp.effects], "scenario": exp.name,
             "seed": exp.seed}
    if static is not None:
        truth["notes"] = (f"static experiment {'WITH' if static.kind == 'dummy' else 'without'} the dummy mass"
                          + (" attached at rig.yaml dummy_mass.position; the truth values are those of the body "
                             "without the dummy mass." if static.kind == "dummy" else "."))
    truth["simulator"] = {
        "engine": "rig_identification.simulator (scipy solve_ivp)", "integrator": "DOP853",
        "rtol": rtol, "atol": atol, "duration": float(duration), **cables.describe(),
        "start": initial.describe(), "excitation": excitation.describe(),
        "sensor_noise_sigma": dict(exp.sensors.noise),
        "sensor_bias": {k: v.tolist() for k, v in exp.sensors.bias.items()},
        "sensor_rates_hz": dict(exp.sensors.rates), "stamp_origin": exp.stamp_origin}
    if compliant is not None:
        truth["simulator"]["compliant_body"] = suspension.describe(frame, sprung)
    states = _states(model, exp.stamp_origin, *cache[exp.sensors.rates["imu"]])
    return SimResult(exp, rig_out, sensors, truth, states, traj, model, time.perf_counter() - t_wall, nfev)


__all__ = ["CableModel", "Excitation", "Experiment", "ExperimentError", "Initial", "Pulse", "RigidPart",
           "RotatingForce", "SensorSpec", "SimResult", "SimulationError", "States", "StaticSpec", "Suspension",
           "Trajectory", "equilibrium", "experiment_from_dict", "inertia_entries", "inertia_tensor",
           "load_experiment", "mode_response", "random_walk", "simulate", "split_body"]
