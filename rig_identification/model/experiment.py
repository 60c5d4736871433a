"""Experiment files of the simulator (:mod:`~rig_identification.model.simulator`): what to
simulate, read and validated into an :class:`Experiment`.

:func:`load_experiment` (path) / :func:`experiment_from_dict` (mapping, source) ->
:class:`Experiment`; ``Experiment.with_overrides`` applies the ``rig-sim`` options;
:func:`load_rig_or_experiment` takes a rig.yaml or an experiment file's rig.  A bad file
raises :class:`ExperimentError` (a ``ValueError``) naming the file and the field.  The parts an
experiment is made of beside the rig: the cable model (:mod:`~rig_identification.model.cables`),
the forcing (:mod:`~rig_identification.model.excitation`: the rotating force's law and the
pulses), the effects (:mod:`~rig_identification.model.effects`).

Experiment file schema (YAML)
-----------------------------
::

    name: case16                    # [a-zA-Z0-9_.-]+, default: the file stem
    description: "..."              # free text
    source: {thesis_section: "4.16", table: "4.16"}   # free mapping (provenance)
    rig: {...}                      # exactly a rig.yaml mapping (docs/recording_format.md);
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
                                    # truth.yaml (names and parameters: rig_identification.model.effects)

"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..io.rig import INERTIA_KEYS, DummyMass, Rig, RigError, inertia_tensor, load_rig, read_yaml, rig_from_dict
from .cables import DEFAULT_BAUMGARTE, DEFAULT_DAMPING_RATIO, CableModel
from .effects import Effect, parse_effects
from .excitation import Excitation, Pulse, RotatingForce
from .suspension import split_body

#: σ of the reference recordings' white sensor noise (``../shared/recordings/*/truth.yaml``):
#: rad/s, m/s², N, N, rad; the default of an experiment made from a rig.yaml (:func:`experiment_for_rig`).
REFERENCE_NOISE = {"gyro": 0.002, "accelerometer": 0.01, "load_cell": 0.5, "exciter": 0.5, "inclinometer": 0.0002}
#: Sample rates of the reference recordings, Hz.
REFERENCE_RATES = {"imu": 200.0, "load_cells": 200.0, "exciter": 200.0, "inclinometer": 50.0}

DEFAULT_STAMP_ORIGIN = 1.75e9      # s
DEFAULT_STATIC_DURATION = 10.0     # s
SENSOR_RATES = {"imu": 100.0, "load_cells": 100.0, "exciter": 100.0, "inclinometer": 50.0}
NOISE_KEYS = ("gyro", "accelerometer", "load_cell", "exciter", "inclinometer")
BIAS_SIZES = {"gyro": 3, "accelerometer": 3, "exciter": 2, "inclinometer": 2}   # load_cell: N
NAME = re.compile(r"^[A-Za-z0-9_.-]+$")
FLOAT_TEXT = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")



class ExperimentError(ValueError):
    """An experiment file with a missing or wrong field (message names file and field)."""


# --- experiment description ----------------------------------------------------------

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
            assert self.pose_rpy is not None   # given together with pose_cg_position (initial.pose)
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

    rates: dict[str, float]
    noise: dict[str, float]
    bias: dict[str, np.ndarray]


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
    reference: dict[str, Any] = field(default_factory=dict)
    thesis: dict[str, Any] = field(default_factory=dict)
    path: str = "<memory>"
    effects: tuple[Effect, ...] = ()

    def effect(self, name: str) -> Effect | None:
        """The first effect called ``name``, or None."""
        return next((e for e in self.effects if e.name == name), None)

    @property
    def mass(self) -> float:
        return self.rig.mass

    @property
    def cg(self) -> np.ndarray:
        cg = self.rig.center_of_gravity
        assert cg is not None   # experiment_from_dict requires rig.body.center_of_gravity
        return cg

    def with_overrides(self, duration: float | None = None, seed: int | None = None, noise_free: bool = False,
                       static: str | None = None, dummy: DummyMass | None = None) -> "Experiment":
        """A copy with command-line overrides applied (see :func:`~rig_identification.cli.sim.sim_main`).

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

    def mapping(self, v: Any, name: str, allowed: set[str] | None = None) -> dict[str, Any]:
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

    def number(self, v: Any, name: str, positive: bool = False, nonneg: bool = False) -> float:
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

    def vector(self, v: Any, name: str, n: int, nonneg: bool = False) -> np.ndarray:
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise self.error(name, f"must be a list of {n} numbers, got {v!r}")
        return np.array([self.number(x, f"{name}[{i}]", nonneg=nonneg) for i, x in enumerate(v)])

    def scalar_or_vector(self, v: Any, name: str, n: int, positive: bool = False, nonneg: bool = False) -> np.ndarray:
        if isinstance(v, (list, tuple)):
            out = self.vector(v, name, n, nonneg=nonneg or positive)
            if positive and np.any(out <= 0):
                raise self.error(name, f"must be > 0, got {v!r}")
            return out
        return np.full(n, self.number(v, name, positive=positive, nonneg=nonneg))

    def boolean(self, v: Any, name: str) -> bool:
        if not isinstance(v, bool):
            raise self.error(name, f"must be true or false, got {v!r}")
        return v


TOP_KEYS = {"effects", "name", "description", "source", "rig", "inertia_about_cg", "cable_model", "initial",
            "excitation", "duration", "sensors", "seed", "stamp_origin", "static", "thesis"}
def _parse_inertia(f: _Fields, v: Any) -> np.ndarray:
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


def _parse_cable_model(f: _Fields, v: Any, rig: Rig) -> CableModel:
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


def _parse_initial(f: _Fields, v: Any) -> Initial:
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


def _parse_excitation(f: _Fields, v: Any, rig: Rig) -> Excitation:
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


def _parse_sensors(f: _Fields, v: Any, n_cables: int) -> SensorSpec:
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
    if any(e.name == "pivot_friction" for e in effects) and cable_model.type != "spring":
        raise ExperimentError(f"{source}: effects: pivot_friction needs spring cables (cable_model.type: spring): "
                              "the pins' friction scales with tensions that inextensible cables solve for")
    for i, eff in enumerate(effects):
        if eff.name == "compliant_body":    # the split must be a physical pair of rigid bodies
            try:
                split_body(rig.mass, rig.center_of_gravity, inertia, eff, f"{source}: effects[{i}]")
            except ValueError as err:
                raise ExperimentError(str(err)) from None
    return Experiment(name=name, rig=rig, inertia=inertia, cable_model=cable_model, initial=initial,
                      excitation=excitation, duration=duration, sensors=sensors, seed=seed,
                      stamp_origin=stamp_origin, static=static, description=description,
                      reference=f.mapping(d.get("source"), "source"), thesis=f.mapping(d.get("thesis"), "thesis"),
                      path=source, effects=effects)


def is_experiment(d: Any) -> bool:
    """Whether a parsed YAML mapping is an experiment file (a ``rig:`` section) rather than a rig.yaml."""
    return isinstance(d, dict) and "rig" in d and "gravity" not in d


@dataclass(frozen=True)
class RigRun:
    """What a run of a bare rig.yaml needs beside it (``rig-sim RIG.yaml --inertia …``).

    inertia: (6,) tensor entries about the CG, body axes, kg·m² (``ixx ixy ixz iyy iyz izz``, as
    truth.yaml).  force: the rotating force's amplitude, N; frequency: Hz; ramp: its spin-up, s.
    duration: s.  The sensors run at :data:`REFERENCE_RATES` with :data:`REFERENCE_NOISE`.
    """

    inertia: tuple[float, ...]
    force: float = 200.0
    frequency: float = 1.05
    ramp: float = 2.0
    duration: float = 120.0


def load_simulation(path: str | Path, run: RigRun | None = None) -> Experiment:
    """The experiment to simulate: an experiment file as it is (``run`` must be None), or a
    rig.yaml with ``run`` (required then): its body (mass, CG) with ``run.inertia``, the
    rotating force of ``run`` at rig.yaml's exciter, spring cables (rig.yaml's stiffness, else
    the default steel cable's), the reference sensors.  Raises :class:`ExperimentError` naming
    the file (a rig.yaml without ``run``, an experiment file with one, a bad field)."""
    p = Path(path)
    d = read_yaml(p, ExperimentError, "experiment file or rig.yaml")
    if is_experiment(d):
        if run is not None:
            raise ExperimentError(f"{p}: an experiment file states its body and excitation; --inertia, --force, "
                                  "--frequency and --ramp are for a rig.yaml")
        return experiment_from_dict(d, str(p))
    if run is None:
        raise ExperimentError(f"{p}: a rig.yaml, not an experiment file: give the body's inertia tensor "
                              "(--inertia IXX IXY IXZ IYY IYZ IZZ, kg m^2) to simulate it")
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", p.parent.name if p.stem == "rig" and p.parent.name else p.stem) or "rig"
    exp = {"name": name, "description": f"{p} with a rotating force of {run.force:g} N at {run.frequency:g} Hz",
           "rig": d, "inertia_about_cg": dict(zip(INERTIA_KEYS, (float(v) for v in run.inertia))),
           "excitation": {"rotating": {"amplitude": run.force, "frequency": run.frequency, "ramp_time": run.ramp}},
           "duration": run.duration,
           "sensors": {"rates_hz": dict(REFERENCE_RATES), "noise": dict(REFERENCE_NOISE)}}
    return experiment_from_dict(exp, str(p))


def load_rig_or_experiment(path: str | Path) -> Rig:
    """The rig of a rig.yaml, or the ``rig:`` section of an experiment file (as
    ``config/rigs/default.yaml`` and ``config/cases/*.yaml``: its CG is then the simulated one).
    Raises :class:`~rig_identification.io.rig.RigError` naming the file (unreadable, not YAML, a bad field)."""
    p = Path(path)
    d = read_yaml(p, RigError, "rig description")
    if is_experiment(d):
        try:
            return load_experiment(p).rig
        except ExperimentError as e:
            raise RigError(str(e)) from None
    return load_rig(p)


def load_experiment(path: str | Path) -> Experiment:
    """Load and validate an experiment YAML file.  Raises :class:`ExperimentError`."""
    return experiment_from_dict(read_yaml(path, ExperimentError, "experiment file"), str(path))
