"""The library of physics beyond the rigid-body, rigid-cable model (issue "diagnose").

One name per effect, used by the simulator (``effects:`` in an experiment file, which conceals
the effect in a simulated recording and lists it in truth.yaml); the rig model's diagnosis
(:mod:`~rig_identification.diagnosis.rig_diagnosis`) names those of them it models by the same
names.  Parameters (SI):

=====================  ==================================================================
name                   parameters
=====================  ==================================================================
viscous_damping        ``linear`` N·s/m (force −c v on the CG, world), ``angular``
                       N·m·s/rad (moment −c ω, body axes) — the reference simulator's
                       damped recording uses these two names
air_drag               ``linear`` N·s²/m² (force −c |v| v), ``angular`` N·m·s²/rad²
                       (moment −c |ω| ω)
pivot_friction         ``mu_r`` m (friction coefficient × pin radius; e.g. 0.08 × 12 mm):
                       dry friction in the ceiling anchors' pins (spring cables only). Each pin
                       resists its cable's swing with the moment μ r T; the straight cable
                       passes it on as the force μ r T / l across the cable at the body
                       anchor, against the anchor's velocity across the cable, regularised
                       over ``velocity_scale`` (default 1e-4 m/s)
cable_elasticity       ``stiffness`` N/m: the cables' true axial stiffness, which rig.yaml
                       gets wrong: it states ``declared_stiffness`` N/m, or (default) none —
                       then the tool assumes steel cables stretching 1–2 mm, so a much
                       softer cable (e.g. 5e5 N/m, ~9 mm) is the mismatch
cable_mass             ``mass`` kg per cable: the load cells sit at the ceiling anchors;
                       half of each cable's mass hangs on its body anchor and moves with it
body_mass              ``mass_error`` kg: the body weighs this much more than rig.yaml's
                       body.mass states (a weighing error; centre of gravity unchanged)
exciter_rotor          ``unbalance`` kg·m (unbalanced mass × eccentricity; default: the
                       rotating force's amplitude / (2π f)², i.e. the mass that makes it),
                       ``rotor_inertia`` kg·m² (polar, about the spin axis; default 0),
                       ``rotor_mass`` kg (default 0): the rotor's weight, turning with it,
                       its spin angular momentum, and its mass, carried on the exciter's
                       bearing at exciter.position (the cables carry it; rig.yaml's body
                       and truth.yaml's are the body without it; the exciter's load cells
                       read the bearing's force, the rotor's inertial force −m_r a among it)
cg_offset              ``offset`` (3,) m, body axes: the body's centre of gravity is at
                       rig.yaml's body.center_of_gravity + offset (rig.yaml's CG is off: a
                       static test's error)
imu_offset             ``offset`` (3,) m, body axes: the IMU is at rig.yaml's position + offset
imu_misalignment       ``rpy`` (3,) rad: the IMU axes are turned by this (fixed-axis XYZ)
                       beyond rig.yaml's imu.rpy
sensor_delay           ``stream`` (load_cells | exciter | inclinometer), ``delay`` s: that
                       stream's stamps lag the IMU's (stamp = sample time + delay)
gyro_bias              ``bias`` (3,) rad/s, IMU axes
accelerometer_bias     ``bias`` (3,) m/s², IMU axes
load_cell_scale        ``cable`` name, ``scale`` (reading / true tension, e.g. 1.03)
gyroscopic_coupling    none: ω × Jω is always in the simulated physics; a model that leaves
                       it out (the thesis's eq. 3.10: ``rig-identify thesis-table``'s thesis method) misses it
gyro_bias_drift        ``random_walk`` rad/s/√s: each gyro axis (IMU axes) gets its own
                       random-walk bias, b(0) = 0, b(t_k+1) = b(t_k) + random_walk √dt N(0, 1)
                       on the IMU's sample grid; drawn from the experiment's seeded generator
                       after every other noise draw (the other streams' noise is unchanged)
gyro_scale             ``scale`` (3,), IMU axes: gyro reading / true angular rate per axis
                       (e.g. [1.0, 1.005, 1.0]), applied BEFORE the noise and biases are added
structural_mode        ``sensor`` (imu | load_cells), ``frequency`` Hz (7–9 typical),
                       ``damping_ratio``, ``participation`` (default 1): a flexible mode of the
                       carrying frame between the rigid body and that sensor (its mount).  Each
                       reading u gets e = participation · G(s) (u − u(0)), G(s) = −s² / (s² +
                       2ζω s + ω²), ω = 2π frequency.  IMU: the mount is a base-excited
                       oscillator (relative displacement x, rotation θ): the accelerometer
                       reads the specific force + ẍ, the gyro ω + θ̇ (the mount's tilt θ × f,
                       ~1e-4 of f, is left out); load cells: each sits under a flexible anchor
                       (modal mass m, stiffness k = m ω²) driven by the cable's tension and
                       reads the anchor's spring force k x + c ẋ = T − m ẍ.  With participation
                       1 that is the physical oscillator: at the exciter's ~1 Hz the reading is
                       (f/frequency)² ≈ 1.7 % high (8 Hz), and transients ring at ``frequency``
compliant_body         ``mass_share`` (0 < share < 1), ``frequencies`` (3,) Hz [roll, pitch,
                       heave], ``damping_ratio`` (number or (3,)): a sprung body of mass
                       share · m on an unlocked suspension inside the carrying frame: a second
                       rigid body joined to the frame by a linear 6-DOF spring–damper at its CG
                       (frame axes).  Optional: ``sprung_cg`` (3,) body frame m (default: the
                       CG raised by min(0.2 m, half the largest raise the mass distribution
                       allows)), ``sprung_inertia_share`` (default mass_share),
                       ``lock_frequency`` Hz (default 25: x, y, yaw, practically locked),
                       ``lock_damping_ratio`` (default 0.1).  rig.yaml's mass, CG and the
                       experiment's inertia stay the WHOLE body's at rest (see
                       :func:`~rig_identification.model.simulator.split_body`)
=====================  ==================================================================
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

EFFECT_NAMES = ("viscous_damping", "air_drag", "pivot_friction", "cable_elasticity", "cable_mass", "body_mass",
                "exciter_rotor", "cg_offset", "imu_offset", "imu_misalignment", "sensor_delay", "gyro_bias",
                "accelerometer_bias", "load_cell_scale", "gyroscopic_coupling", "gyro_bias_drift", "gyro_scale",
                "structural_mode", "compliant_body")

# parameter name -> (size, required)   size 0 = scalar, -1 = text, n = a list of n numbers,
# EITHER_3 = a number or a list of 3 (kept as given: float or (3,) array)
EITHER_3 = (0, 3)
PARAMETERS: dict[str, dict[str, tuple[int | tuple[int, int], bool]]] = {
    "viscous_damping": {"linear": (0, False), "angular": (0, False)},
    "air_drag": {"linear": (0, False), "angular": (0, False)},
    "pivot_friction": {"mu_r": (0, True), "velocity_scale": (0, False)},
    "cable_elasticity": {"stiffness": (0, True), "declared_stiffness": (0, False)},
    "cable_mass": {"mass": (0, True)},
    "body_mass": {"mass_error": (0, True)},
    "exciter_rotor": {"unbalance": (0, False), "rotor_inertia": (0, False), "rotor_mass": (0, False)},
    "cg_offset": {"offset": (3, True)},
    "imu_offset": {"offset": (3, True)},
    "imu_misalignment": {"rpy": (3, True)},
    "sensor_delay": {"stream": (-1, True), "delay": (0, True)},
    "gyro_bias": {"bias": (3, True)},
    "accelerometer_bias": {"bias": (3, True)},
    "load_cell_scale": {"cable": (-1, True), "scale": (0, True)},
    "gyroscopic_coupling": {},
    "gyro_bias_drift": {"random_walk": (0, True)},
    "gyro_scale": {"scale": (3, True)},
    "structural_mode": {"sensor": (-1, True), "frequency": (0, True), "damping_ratio": (0, True),
                        "participation": (0, False)},
    "compliant_body": {"mass_share": (0, True), "frequencies": (3, True), "damping_ratio": (EITHER_3, True),
                       "sprung_cg": (3, False), "sprung_inertia_share": (0, False), "lock_frequency": (0, False),
                       "lock_damping_ratio": (0, False)},
}
DELAY_STREAMS = ("load_cells", "exciter", "inclinometer")
MODE_SENSORS = ("imu", "load_cells")
DEFAULT_LOCK_FREQUENCY = 25.0     # Hz: compliant_body's x, y, yaw "locked" directions (suspension links)
DEFAULT_LOCK_DAMPING_RATIO = 0.1  # ζ of those directions (rubber bushings: a few to ~10 %)


@dataclass(frozen=True)
class Effect:
    """One effect: ``name`` from :data:`EFFECT_NAMES`, ``parameters`` (validated mapping)."""

    name: str
    parameters: dict[str, Any] = field(default_factory=dict)

    def get(self, key: str, default: Any = 0.0) -> Any:
        return self.parameters.get(key, default)

    def truth_entry(self) -> dict[str, Any]:
        """truth.yaml form: ``{name: ..., <parameter>: <value>, ...}`` (as the reference simulator)."""
        out: dict[str, Any] = {"name": self.name}
        for k, v in self.parameters.items():
            out[k] = v.tolist() if isinstance(v, np.ndarray) else v
        return out


def _parameter(size: int | tuple[int, int], v: Any, w: str) -> Any:
    """One parameter's value ``v`` of ``size`` (-1 text, 0 a number, n a list of n numbers,
    :data:`EITHER_3` a number or three) checked and converted; ValueError naming ``w`` (its field)."""
    if size == EITHER_3:
        size = 3 if isinstance(v, (list, tuple, np.ndarray)) else 0
    if size == -1:
        if not isinstance(v, str):
            raise ValueError(f"{w}: must be text, got {v!r}")
        return v
    if size == 0:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise ValueError(f"{w}: must be a number, got {v!r}") from None
        if not np.isfinite(x):
            raise ValueError(f"{w}: must be finite, got {v!r}")
        return x
    try:
        a = np.asarray(v, float)
    except (TypeError, ValueError):
        raise ValueError(f"{w}: must be a list of {size} numbers, got {v!r}") from None
    if a.shape != (size,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{w}: must be a list of {size} finite numbers, got {v!r}")
    return a


def _check_values(name: str, params: dict[str, Any], w: str, cable_names: list[str]) -> None:
    """The checks of one effect's values beyond their types (streams, cables, signs,
    :func:`_check_ranges`); ValueError naming ``w``.field."""
    if name == "sensor_delay" and params["stream"] not in DELAY_STREAMS:
        raise ValueError(f"{w}.stream: must be one of {', '.join(DELAY_STREAMS)}, got {params['stream']!r}")
    if name == "load_cell_scale":
        if params["cable"] not in cable_names:
            raise ValueError(f"{w}.cable: no cable {params['cable']!r} in the rig ({', '.join(cable_names)})")
        if params["scale"] <= 0:
            raise ValueError(f"{w}.scale: must be > 0")
    if name in ("cable_elasticity",) and params["stiffness"] <= 0:
        raise ValueError(f"{w}.stiffness: must be > 0")
    if name == "cable_mass" and params["mass"] < 0:
        raise ValueError(f"{w}.mass: must be >= 0")
    _check_ranges(name, params, w)


def parse_effects(raw: Any, where: str, cable_names: list[str]) -> tuple[Effect, ...]:
    """Validate an ``effects`` list: each item ``{name: ..., <parameter>: <value>}``.

    Raises ValueError naming ``where`` (the file and field) and the offending entry.
    """
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise ValueError(f"{where}: must be a list of {{name: ..., parameters...}}")
    out: list[Effect] = []
    for i, item in enumerate(raw):
        w = f"{where}[{i}]"
        if not isinstance(item, dict) or "name" not in item:
            raise ValueError(f"{w}: must be a mapping with a name")
        name = item["name"]
        if name not in PARAMETERS:
            raise ValueError(f"{w}.name: unknown effect {name!r} (known: {', '.join(EFFECT_NAMES)})")
        spec = PARAMETERS[name]
        params: dict[str, Any] = {}
        for k, v in item.items():
            if k == "name":
                continue
            if k not in spec:
                raise ValueError(f"{w}.{k}: not a parameter of {name} (parameters: {', '.join(spec) or 'none'})")
            params[k] = _parameter(spec[k][0], v, f"{w}.{k}")
        for k, (_, required) in spec.items():
            if required and k not in params:
                raise ValueError(f"{w}: {name} needs the parameter {k}")
        _check_values(name, params, w, cable_names)
        if name == "structural_mode":
            if any(o.name == name and o.parameters["sensor"] == params["sensor"] for o in out):
                raise ValueError(f"{w}: structural_mode of sensor {params['sensor']} listed twice")
        elif any(o.name == name and name not in ("load_cell_scale", "sensor_delay") for o in out):
            raise ValueError(f"{w}: effect {name} listed twice")
        out.append(Effect(name, params))
    return tuple(out)


def _check_ranges(name: str, params: dict[str, Any], w: str) -> None:
    """Range checks of the newer effects' parameters; ValueError naming ``w``.field."""
    def at_least(key: str, low: float, strict: bool = False) -> None:
        if key in params:
            x = np.atleast_1d(params[key])
            if np.any(x <= low) if strict else np.any(x < low):
                raise ValueError(f"{w}.{key}: must be {'>' if strict else '>='} {low}, got {_text(params[key])}")

    if name == "gyro_bias_drift":
        at_least("random_walk", 0.0)
    elif name == "pivot_friction":
        at_least("mu_r", 0.0)
        at_least("velocity_scale", 0.0, strict=True)
    elif name == "gyro_scale":
        at_least("scale", 0.0, strict=True)
    elif name == "structural_mode":
        if params["sensor"] not in MODE_SENSORS:
            raise ValueError(f"{w}.sensor: must be one of {', '.join(MODE_SENSORS)}, got {params['sensor']!r}")
        at_least("frequency", 0.0, strict=True)
        at_least("damping_ratio", 0.0)
        at_least("participation", 0.0)
    elif name == "compliant_body":
        share = params["mass_share"]
        if not 0.0 < share < 1.0:
            raise ValueError(f"{w}.mass_share: must be between 0 and 1 (exclusive), got {share}")
        s = params.get("sprung_inertia_share")
        if s is not None and not 0.0 < s < 1.0:
            raise ValueError(f"{w}.sprung_inertia_share: must be between 0 and 1 (exclusive), got {s}")
        at_least("frequencies", 0.0, strict=True)
        at_least("damping_ratio", 0.0)
        at_least("lock_frequency", 0.0, strict=True)
        at_least("lock_damping_ratio", 0.0)


def _text(v: Any) -> str:
    return str(v.tolist()) if isinstance(v, np.ndarray) else str(v)
