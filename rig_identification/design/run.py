"""The inputs of an experiment design: a planned exciter run (:class:`Run`, spinning about one
of :data:`SPIN_AXES`) and the nominal body it shakes (:class:`Body`, from the command line's
numbers by :func:`make_body`, on the rig :func:`load_plan_input` reads).

The search over runs is :mod:`~rig_identification.design.planning`; the linearised screen it
ranks candidates with, :mod:`~rig_identification.design.screen`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..io.recording import RecordingError
from ..io.rig import Rig, RigError, inertia_entries, load_rig, read_yaml
from ..model.cables import DEFAULT_STIFFNESS
from ..model.experiment import REFERENCE_NOISE, REFERENCE_RATES, ExperimentError, experiment_from_dict, load_experiment
from ..model.parametrisation import physically_consistent, to_tensor


class PlanError(ValueError):
    """The planned experiment cannot be designed (bad limits or body, no run that determines the tensor)."""


_DIAGONALS = {"x+y": (1, 1, 0), "x-y": (1, -1, 0), "x+z": (1, 0, 1), "x-z": (1, 0, -1), "y+z": (0, 1, 1),
              "y-z": (0, 1, -1)}


def _spin_rpy(v) -> tuple:
    """Exciter rpy (extrinsic xyz, rad) whose z axis is the body-frame direction ``v``."""
    v = np.asarray(v, float) / np.linalg.norm(v)
    R, _ = Rotation.align_vectors([v], [[0.0, 0.0, 1.0]])
    return tuple(float(a) for a in R.as_euler("xyz"))


SPIN_AXES = {"x": (0.0, math.pi / 2, 0.0), "y": (-math.pi / 2, 0.0, 0.0), "z": (0.0, 0.0, 0.0),
             **{k: _spin_rpy(v) for k, v in _DIAGONALS.items()}}
"""Exciter rpy (body -> exciter frame) whose z axis (the spin axis) is body x, y, z or the
diagonal between two of them ("x+y": along (1, 1, 0)/√2, "x-y": along (1, −1, 0)/√2, …).
A diagonal axis turns the force in a plane that holds one body axis and the other two's
diagonal: on the thesis rig it drives roll and pitch in phase, which the products of
inertia need (case 16: Ixy's σ 3.1× below the thesis excitation's, against 2.8× with the
body axes alone)."""


@dataclass(frozen=True)
class Run:
    """One planned exciter run: rotating force ``amplitude`` N at ``frequency`` Hz, acting at
    ``position`` (3,) body frame m, spinning about body ``spin_axis`` (a key of :data:`SPIN_AXES`),
    for ``duration`` s (spin-up ramp ``ramp_time`` s, as the reference simulator)."""

    frequency: float
    amplitude: float
    position: tuple
    spin_axis: str
    duration: float = 120.0
    ramp_time: float = 2.0
    rpy: tuple | None = None    # exciter rpy if not one of SPIN_AXES (e.g. the rig's own)
    direction: int = 1          # sense of rotation about the spin axis (+1: x toward y of the exciter frame)

    @property
    def exciter_rpy(self) -> tuple:
        return tuple(self.rpy) if self.rpy is not None else SPIN_AXES[self.spin_axis]

    def to_dict(self) -> dict:
        return {"frequency_hz": float(self.frequency), "amplitude_n": float(self.amplitude),
                "exciter_position_body_m": [float(x) for x in self.position], "spin_axis_body": self.spin_axis,
                "spin_axis_unit_body": [round(float(x), 6) + 0.0 for x in
                                        Rotation.from_euler("xyz", self.exciter_rpy).apply([0, 0, 1])],
                "exciter_rpy": [float(x) for x in self.exciter_rpy], "direction": int(self.direction),
                "duration_s": float(self.duration),
                "ramp_time_s": float(self.ramp_time), "ramp_shape": "spin_up"}


@dataclass(frozen=True)
class Body:
    """The rig and the nominal body: rig (CG from rig.yaml), mass kg, inertia (3,3) kg·m²
    about the CG, body axes; cable stiffness (N,) N/m of the simulation (rig.yaml's, else
    the simulator's 5e6); rates Hz and noise σ of the sensors."""

    rig: Rig
    mass: float
    inertia: np.ndarray
    stiffness: np.ndarray
    rates: dict
    noise: dict

    def experiment(self, run: Run, seed: int = 0):
        """The noise-free :class:`~rig_identification.model.simulator.Experiment` of ``run``."""
        rig = self.rig.to_dict()
        rig.pop("dummy_mass", None)
        rig["body"]["mass"] = float(self.mass)
        rig["body"]["center_of_gravity"] = [float(x) for x in self.rig.require_cg()]
        rig["exciter"] = {"position": [float(x) for x in run.position], "rpy": [float(x) for x in run.exciter_rpy]}
        d = {"name": "plan", "rig": rig, "inertia_about_cg": inertia_entries(self.inertia),
             "cable_model": {"type": "spring", "stiffness": [float(k) for k in self.stiffness]},
             "initial": {"equilibrium": True},
             "excitation": {"rotating": {"amplitude": float(run.amplitude), "frequency": float(run.frequency),
                                         "ramp_time": float(run.ramp_time), "ramp_shape": "spin_up", "phase": 0.0,
                                         "direction": int(run.direction), "start_time": 0.0}},
             "duration": float(run.duration),
             "sensors": {"rates_hz": dict(self.rates), "noise": {k: 0.0 for k in REFERENCE_NOISE}},
             "seed": seed}
        return experiment_from_dict(d, "planned run")


def load_plan_input(path) -> tuple[Rig, dict | None, np.ndarray | None]:
    """The rig of ``path`` — a rig.yaml, an experiment file (config/cases, config/rigs) or a
    recording folder — with its cable stiffness if known (rig.yaml ``stiffness`` or the
    experiment's spring ``cable_model``) and, for an experiment file, its rotating
    excitation ({amplitude, frequency, ramp_time}) as the baseline.  Raises
    :class:`~rig_identification.io.rig.RigError`,
    :class:`~rig_identification.io.recording.RecordingError`, FileNotFoundError."""
    p = Path(path)
    if p.is_dir():
        if not (p / "rig.yaml").exists():
            raise RecordingError(f"{p}: no rig.yaml in the recording folder")
        p = p / "rig.yaml"
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    d = read_yaml(p, RigError, "rig description")
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        try:
            exp = load_experiment(p)
        except ExperimentError as e:
            raise RigError(str(e)) from None
        k = exp.cable_model.stiffness if exp.cable_model.type == "spring" else None
        rot = exp.excitation.rotating
        base = None if rot is None else {"amplitude": rot.amplitude, "frequency": rot.frequency,
                                         "ramp_time": rot.ramp_time}
        return exp.rig, base, None if k is None else np.asarray(k, float)
    rig = load_rig(p)
    k = rig.cable_stiffness
    return rig, None, (k if np.all(np.isfinite(k)) else None)


def make_body(rig: Rig, mass: float | None, inertia_entries, stiffness=None, noise: dict | None = None,
              rates: dict | None = None) -> Body:
    """A :class:`Body` from the command line's numbers: mass kg (default rig.yaml's),
    inertia_entries (6,) in :data:`~rig_identification.io.verdict.KEYS` order, kg·m² (tensor entries: products negated).
    Raises :class:`PlanError` for a non-positive mass, a missing CG or a tensor that is not
    physically consistent."""
    if rig.center_of_gravity is None:
        raise PlanError(f"{rig.source}: body.center_of_gravity is required (estimate it first: rig-identify cg)")
    m = float(rig.mass if mass is None else mass)
    if not (math.isfinite(m) and m > 0):
        raise PlanError(f"--mass must be > 0 kg, got {mass}")
    J = to_tensor(np.asarray(inertia_entries, float))
    if not np.all(np.isfinite(J)) or not physically_consistent(J):
        raise PlanError("--inertia: the tensor is not physically consistent (it must be positive definite and "
                        "each principal moment at most the sum of the other two); order IXX IYY IZZ IXY IXZ IYZ, "
                        "kg·m², products negated as in truth.yaml")
    n = len(rig.cables)
    k = np.full(n, DEFAULT_STIFFNESS) if stiffness is None else np.broadcast_to(np.asarray(stiffness, float), (n,))
    return Body(replace(rig, mass=m), m, J, np.array(k, float), dict(rates or REFERENCE_RATES),
                dict(noise or REFERENCE_NOISE))
