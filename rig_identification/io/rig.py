"""Rig description: geometry and known quantities of the suspended-body rig.

Loads and validates ``rig.yaml`` exactly as specified in ``docs/recording_format.md``
(shared with the rig and the reference simulator).  Every length is in metres,
masses in kg, angles in rad.  Frames (REP-103, right-handed):

* ``world``: z up, gravity along -z, origin at a reference point on the ceiling.
* ``body``: fixed to the carrying frame, origin at any reference point on it
  (not necessarily the centre of gravity); where the vehicle's front and top lie in it is
  ``body.vehicle`` (optional: :class:`~rig_identification.io.vehicle.Vehicle`), never assumed.
* ``imu``, ``exciter``, ``inclinometer``: sensor frames given by a position (body
  frame) and roll-pitch-yaw (fixed-axis XYZ) relative to the body axes.

Errors: :class:`RigError` (a ``ValueError``) naming the file and the field.
"""
from __future__ import annotations

import difflib
import itertools
import math
import re
from collections.abc import Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import ArrayLike
from scipy.spatial.transform import Rotation

from .export import AXES
from .vehicle import SIGNED_AXES, VEHICLE_AXES, Vehicle

CABLE_NAME = re.compile(r"^[a-z0-9_]+$")
TOPIC_NAME = re.compile(r"^/[A-Za-z0-9_/]+$")


class RigError(ValueError):
    """A rig description that is missing a field or holds a wrong value."""


@dataclass(frozen=True)
class Cable:
    """One suspension cable.

    ceiling_anchor: (3,) world frame, m.  body_anchor: (3,) body frame, m.
    length: unstretched length, m.  stiffness: axial stiffness EA/L in N/m, or
    ``None`` for an inextensible cable.
    """

    name: str
    ceiling_anchor: np.ndarray
    body_anchor: np.ndarray
    length: float
    stiffness: float | None = None


@dataclass(frozen=True)
class Mount:
    """A sensor or actuator frame on the body: position (3,) m and rotation to body axes.
    max_force: the exciter's largest force amplitude, N (rig.yaml ``exciter.max_force``; None:
    not stated; other mounts have none)."""

    position: np.ndarray
    rpy: np.ndarray
    max_force: float | None = None

    @property
    def rotation(self) -> Rotation:
        """Rotation from the mount's axes to the body axes (fixed-axis XYZ rpy)."""
        return Rotation.from_euler("xyz", self.rpy)


@dataclass(frozen=True)
class DummyMass:
    """A point mass fixed on the body: mass kg, position (3,) body frame m (its own CG)."""

    mass: float
    position: np.ndarray


#: σ of the scale's mass reading as a share of it when rig.yaml's survey does not say (a floor scale).
SCALE_STD_SHARE = 1e-3


@dataclass(frozen=True)
class Survey:
    """How well the lab knows its rig, 1 σ (rig.yaml ``survey``, each optional).

    anchors: each coordinate of every ceiling anchor (world) and body anchor (body), m.
    lengths: every unstretched cable length, m.  dummy_position: each coordinate of the dummy
    mass's centre of gravity, m.  The defaults, 1 mm, are a careful survey: a class II steel tape
    (EN ISO 8764 / EC class II: ±(0.3 + 0.2 L/m) mm, ±1.1 mm over 4 m) or a laser distance meter
    (±1–1.5 mm).  mass: body.mass's σ, kg (None: :data:`SCALE_STD_SHARE` of it).
    load_cell_gain: each load cell's gain as a share (default 0.1 %: a calibrated load cell's
    accuracy class; 0: exact).  Every fit that takes the geometry, the mass or the gains as a
    prior uses these (``cg``, ``cg-plan``, the rig model); ``cg``'s --anchor-std and kin
    override them for one run.
    """

    anchors: float = 1e-3
    lengths: float = 1e-3
    dummy_position: float = 1e-3
    mass: float | None = None
    load_cell_gain: float = 1e-3

    def mass_std(self, mass: float) -> float:
        """σ of the body's mass, kg."""
        return SCALE_STD_SHARE * mass if self.mass is None else self.mass


@dataclass(frozen=True)
class Topics:
    """The bag's topic names for the rig's streams (rig.yaml ``topics``, each optional; the
    defaults are docs/recording_format.md's).  load_cells: the prefix; the cable's name follows."""

    imu: str = "/rig/imu"
    load_cells: str = "/rig/load_cells/"
    exciter: str = "/rig/exciter/wrench"
    inclinometer: str = "/rig/inclinometer"


@dataclass(frozen=True)
class Rig:
    """The validated content of ``rig.yaml``.

    ``center_of_gravity`` is ``None`` when unknown (static experiment).
    ``exciter``, ``inclinometer`` and ``dummy_mass`` are ``None`` when absent.  ``extra``:
    kept for callers that build a Rig by hand; rig.yaml files cannot have other fields.
    ``name``: the rig's name (rig.yaml ``name``, optional; reports show it).  ``output_axes``:
    the axes outputs are given in by default (rig.yaml ``output_axes``: a key of
    :data:`~rig_identification.io.export.AXES`, ``body``, ``sae`` or ``iso8855``; None: not stated, ``body``) —
    rig.yaml's own geometry is always in the body frame (REP-103).  ``vehicle``: where the
    vehicle's front and top lie in the body frame (rig.yaml ``body.vehicle``,
    :class:`~rig_identification.io.vehicle.Vehicle`; None: not stated, and no output names roll, pitch or
    yaw).  ``topics``: the bag's topic names (:class:`Topics`; rig.yaml ``topics``).  ``survey``:
    the σ of the geometry and mass (:class:`Survey`; rig.yaml ``survey``).
    """

    gravity: float
    cables: tuple[Cable, ...]
    mass: float
    center_of_gravity: np.ndarray | None
    imu: Mount
    exciter: Mount | None = None
    inclinometer: Mount | None = None
    dummy_mass: DummyMass | None = None
    source: str = "<memory>"
    extra: dict[str, Any] = field(default_factory=dict)
    name: str | None = None
    output_axes: str | None = None
    topics: Topics = Topics()
    survey: Survey = Survey()
    vehicle: Vehicle | None = None

    # --- convenient stacked views -------------------------------------------------
    @property
    def cable_names(self) -> list[str]:
        return [c.name for c in self.cables]

    @property
    def ceiling_anchors(self) -> np.ndarray:
        """(N, 3) world frame, m."""
        return np.array([c.ceiling_anchor for c in self.cables])

    @property
    def body_anchors(self) -> np.ndarray:
        """(N, 3) body frame, m."""
        return np.array([c.body_anchor for c in self.cables])

    @property
    def cable_lengths(self) -> np.ndarray:
        """(N,) unstretched lengths, m."""
        return np.array([c.length for c in self.cables])

    @property
    def cable_stiffness(self) -> np.ndarray:
        """(N,) axial stiffness N/m; ``inf`` for inextensible cables."""
        return np.array([np.inf if c.stiffness is None else c.stiffness for c in self.cables])

    def require_cg(self) -> np.ndarray:
        if self.center_of_gravity is None:
            raise RigError(f"{self.source}: body.center_of_gravity is required for this job "
                           "(estimate it first with the static experiment: rig-identify cg)")
        return self.center_of_gravity

    def with_cg(self, cg: ArrayLike) -> "Rig":
        """A copy with ``body.center_of_gravity`` replaced, (3,) body frame, m."""
        return replace(self, center_of_gravity=np.asarray(cg, float))

    def to_dict(self) -> dict[str, Any]:
        """The rig.yaml mapping (inverse of :func:`rig_from_dict`)."""
        def vec(v: Iterable[float]) -> list[float]:
            return [float(x) for x in v]
        cables: list[dict[str, Any]] = []
        for c in self.cables:
            d: dict[str, Any] = {"name": c.name, "ceiling_anchor": vec(c.ceiling_anchor),
                                 "body_anchor": vec(c.body_anchor), "length": float(c.length)}
            if c.stiffness is not None:
                d["stiffness"] = float(c.stiffness)
            cables.append(d)
        out: dict[str, Any] = {} if self.name is None else {"name": self.name}
        if self.output_axes is not None:
            out["output_axes"] = self.output_axes
        out |= {"gravity": float(self.gravity), "cables": cables, "body": {"mass": float(self.mass)}}
        if self.center_of_gravity is not None:
            out["body"]["center_of_gravity"] = vec(self.center_of_gravity)
        if self.vehicle is not None:
            out["body"]["vehicle"] = self.vehicle.to_dict()
        out["imu"] = {"position": vec(self.imu.position), "rpy": vec(self.imu.rpy)}
        if self.exciter is not None:
            out["exciter"] = {"position": vec(self.exciter.position), "rpy": vec(self.exciter.rpy)}
            if self.exciter.max_force is not None:
                out["exciter"]["max_force"] = float(self.exciter.max_force)
        if self.inclinometer is not None:
            out["inclinometer"] = {"rpy": vec(self.inclinometer.rpy)}
        if self.dummy_mass is not None:
            out["dummy_mass"] = {"mass": float(self.dummy_mass.mass),
                                 "position": vec(self.dummy_mass.position)}
        if self.survey != Survey():
            out["survey"] = {k: float(v) for k, v in vars(self.survey).items()
                             if v is not None and v != getattr(Survey(), k)}
        if self.topics != Topics():
            out["topics"] = {k: v for k, v in vars(self.topics).items() if v != getattr(Topics(), k)}
        return out


# --- validation helpers -------------------------------------------------------------

def _get(d: Any, key: str, where: str, src: str, required: bool = True) -> Any:
    if not isinstance(d, dict):
        raise RigError(f"{src}: {where} must be a mapping, got {type(d).__name__}")
    if key not in d or d[key] is None:
        if required:
            raise RigError(f"{src}: missing field {where}.{key}" if where else f"{src}: missing field {key}")
        return None
    return d[key]


FLOAT_12 = re.compile(r"^[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?$")


def _number(v: Any, name: str, src: str, positive: bool = False, nonneg: bool = False) -> float:
    # PyYAML implements YAML 1.1, which reads "5.0e6" (valid YAML 1.2 float) as a string
    if isinstance(v, str) and FLOAT_12.match(v.strip()):
        v = float(v)
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise RigError(f"{src}: field {name} must be a number, got {v!r}")
    x = float(v)
    if not math.isfinite(x):
        raise RigError(f"{src}: field {name} must be finite, got {v!r}")
    if positive and x <= 0:
        raise RigError(f"{src}: field {name} must be > 0, got {v!r}")
    if nonneg and x < 0:
        raise RigError(f"{src}: field {name} must be >= 0, got {v!r}")
    return x


def _vector(v: Any, name: str, src: str, n: int = 3) -> np.ndarray:
    if not isinstance(v, (list, tuple)) or len(v) != n:
        raise RigError(f"{src}: field {name} must be a list of {n} numbers, got {v!r}")
    return np.array([_number(x, f"{name}[{i}]", src) for i, x in enumerate(v)], float)


def _mount(d: Any, name: str, src: str, with_position: bool = True) -> Mount:
    if isinstance(d, dict):
        _check_fields(d, name, name, src)
    pos = _vector(_get(d, "position", name, src), f"{name}.position", src) if with_position else np.zeros(3)
    rpy_raw = _get(d, "rpy", name, src, required=False)
    rpy = np.zeros(3) if rpy_raw is None else _vector(rpy_raw, f"{name}.rpy", src)
    force_raw = _get(d, "max_force", name, src, required=False) if name == "exciter" else None
    force = None if force_raw is None else _number(force_raw, f"{name}.max_force", src, positive=True)
    return Mount(position=pos, rpy=rpy, max_force=force)


KNOWN_TOP = {"name", "output_axes", "gravity", "cables", "body", "imu", "exciter", "inclinometer", "dummy_mass",
             "topics", "survey"}
# the fields of each mapping of rig.yaml (docs/recording_format.md); any other is an error
KNOWN_FIELDS = {"": KNOWN_TOP, "cable": {"name", "ceiling_anchor", "body_anchor", "length", "stiffness"},
                "body": {"mass", "center_of_gravity", "vehicle"}, "vehicle": {"front", "top"},
                "imu": {"position", "rpy"},
                "exciter": {"position", "rpy", "max_force"},
                "inclinometer": {"rpy"}, "dummy_mass": {"mass", "position"},
                "topics": {"imu", "load_cells", "exciter", "inclinometer"},
                "survey": {"anchors", "lengths", "dummy_position", "mass", "load_cell_gain"}}
UNKNOWN_HINTS = {"inclinometer.position": "an inclinometer's reading does not depend on where it sits: leave it out"}
# geometry that no pose can realise: for two cables i, j the ceiling anchors A_i, A_j, the body
# anchors' points P_i, P_j and the cables form a closed quadrilateral A_i-P_i-P_j-A_j, so none of
# its sides |A_i - A_j|, |B_i - B_j| (the body is rigid), L_i, L_j can exceed the sum of the other
# three when both cables are taut; allowed: REACH_SLACK of the sum (stretch under load: ~1e-3)
REACH_SLACK = 0.02
#: The largest rig the loader takes, m: a span of anchors, a cable's length or a body-frame
#: position beyond it is a rig.yaml in millimetres (a vehicle rig is metres across).
LARGEST_RIG = 30.0
#: The largest body mass, kg (a heavy truck): beyond it, grams?
LARGEST_MASS = 1.0e5
#: The largest static stretch of a cable over its length: beyond it the stiffness is in N/mm?
LARGEST_STRETCH = 0.1


def _check_fields(d: dict[Any, Any], kind: str, where: str, src: str) -> None:
    """Raise :class:`RigError` for a key of mapping ``d`` (a ``kind`` of :data:`KNOWN_FIELDS`,
    at ``where``) that rig.yaml does not have, with the closest known field (difflib)."""
    known = KNOWN_FIELDS[kind]
    for key in d:
        if key in known:
            continue
        name = f"{where}.{key}" if where else str(key)
        hint = UNKNOWN_HINTS.get(name)
        if hint is None:
            close = difflib.get_close_matches(str(key), sorted(known), n=1, cutoff=0.6)
            hint = (f"did you mean {where + '.' if where else ''}{close[0]}?" if close
                    else "known: " + ", ".join(sorted(known)))
        raise RigError(f"{src}: unknown field {name} ({hint})")


def _survey(d: Any, src: str) -> Survey:
    """rig.yaml ``survey``: each σ a number ≥ 0 (m; mass kg > 0; load_cell_gain a share ≤ 0.1),
    millimetres and per cents refused."""
    if d is None:
        return Survey()
    if isinstance(d, dict):
        _check_fields(d, "survey", "survey", src)
    vals: dict[str, float] = {}
    for key in ("anchors", "lengths", "dummy_position", "mass", "load_cell_gain"):
        v = _get(d, key, "survey", src, required=False)
        if v is None:
            continue
        x = _number(v, f"survey.{key}", src, positive=key == "mass", nonneg=key != "mass")
        if key == "load_cell_gain" and x > 0.1:
            raise RigError(f"{src}: field survey.load_cell_gain = {x:g} is more than 10 % (a share: 0.001 is "
                           "0.1 % -- per cent?)")
        if key not in ("mass", "load_cell_gain") and x > 0.1:
            raise RigError(f"{src}: field survey.{key} = {x:g} m is more than 10 cm (rig.yaml is in metres -- "
                           "millimetres?)")
        vals[key] = x
    return Survey(**vals)


def _vehicle(d: Any, src: str) -> Vehicle | None:
    """rig.yaml ``body.vehicle``: ``front`` and ``top``, each one of +x -x +y -y +z -z (a Unicode
    minus taken), on different body axes; None when absent."""
    if d is None:
        return None
    if not isinstance(d, dict):
        raise RigError(f"{src}: field body.vehicle must be a mapping such as {{front: +x, top: +z}} (where the "
                       f"vehicle's front and top point in the body frame), got {d!r}")
    _check_fields(d, "vehicle", "body.vehicle", src)
    sides = {}
    for key, what in (("front", "the body axis that points to the vehicle's front"),
                      ("top", "the body axis that points to the vehicle's top")):
        v = _get(d, key, "body.vehicle", src)
        name = v.strip().replace("\u2212", "-") if isinstance(v, str) else v
        if name not in SIGNED_AXES:
            close = {"x": "+x", "y": "+y", "z": "+z"}.get(str(name).strip().lower())
            raise RigError(f"{src}: field body.vehicle.{key} must be one of {', '.join(SIGNED_AXES)} ({what}), "
                           f"got {v!r}" + (f" (did you mean {close}?)" if close else ""))
        sides[key] = name
    if sides["front"][1] == sides["top"][1]:
        raise RigError(f"{src}: field body.vehicle: front {sides['front']} and top {sides['top']} lie on the same "
                       "body axis; the top must be perpendicular to the front")
    return Vehicle(sides["front"], sides["top"])


def _topics(d: Any, src: str) -> Topics:
    """rig.yaml ``topics``: each a ROS topic name (``/`` then [A-Za-z0-9_/]); load_cells a prefix."""
    if d is None:
        return Topics()
    if isinstance(d, dict):
        _check_fields(d, "topics", "topics", src)
    names: dict[str, str] = {}
    for key in ("imu", "load_cells", "exciter", "inclinometer"):
        v = _get(d, key, "topics", src, required=False)
        if v is None:
            continue
        if not isinstance(v, str) or not TOPIC_NAME.match(v):
            raise RigError(f"{src}: field topics.{key} must be a ROS topic name such as "
                           f"{getattr(Topics(), key)!r}, got {v!r}")
        names[key] = v
    return Topics(**names)


def check_reach(cables: Sequence[Cable], src: str) -> None:
    """Refuse cable geometry no pose of a rigid body can hold with every cable taut.

    For every pair of cables (i, j), the closed chain ceiling anchor A_i -> body anchor P_i ->
    body anchor P_j -> ceiling anchor A_j -> A_i has sides a = |A_i - A_j| (world), d = |B_i - B_j|
    (body frame: the same in every pose), L_i and L_j; each must be at most the sum of the other
    three (polygon inequality), with :data:`REACH_SLACK` for the stretch.  Catches anchors in
    other units (mm for m), a cable length in mm, anchors swapped between ceiling and body.
    Raises :class:`RigError` naming both cables."""
    for (i, ci), (j, cj) in itertools.combinations(enumerate(cables), 2):
        a = float(np.linalg.norm(ci.ceiling_anchor - cj.ceiling_anchor))
        d = float(np.linalg.norm(ci.body_anchor - cj.body_anchor))
        sides = {"their ceiling anchors' distance": a, "their body anchors' distance": d,
                 f"cable {ci.name}'s length": ci.length, f"cable {cj.name}'s length": cj.length}
        total = sum(sides.values())
        for what, x in sides.items():
            rest = total - x
            if x > (1.0 + REACH_SLACK) * rest + 1e-3:
                raise RigError(
                    f"{src}: field cables[{i}], cables[{j}]: cables {ci.name} and {cj.name} cannot both be taut in "
                    f"any pose: {what} is {x:.4g} m but the other three sides of the chain ceiling anchor - cable - "
                    f"body anchor - body anchor - cable - ceiling anchor add up to {rest:.4g} m "
                    f"(ceiling anchors {a:.4g} m apart, body anchors {d:.4g} m apart, lengths {ci.length:.4g} and "
                    f"{cj.length:.4g} m; rig.yaml is in metres -- units?)")


def check_scale(rig: Rig) -> None:
    """Refuse a rig.yaml whose numbers are in the wrong units though each is possible alone:
    anchors or lengths in millimetres (a span over :data:`LARGEST_RIG`; the reach check cannot
    see every number scaled alike), a mass in grams (over :data:`LARGEST_MASS`), an angle in
    degrees (|rpy| over 2π), a stiffness in N/mm (a cable stretched by more than
    :data:`LARGEST_STRETCH` of its length under its share of the weight).  Raises
    :class:`RigError` naming the field and the likely unit."""
    src = rig.source
    mm = "rig.yaml is in metres -- millimetres?"
    spans = {"the ceiling anchors": rig.ceiling_anchors, "the body anchors": rig.body_anchors}
    for what, pts in spans.items():
        span = float(np.max(np.linalg.norm(pts[:, None] - pts[None], axis=-1)))
        if span > LARGEST_RIG:
            field = "cables[*].ceiling_anchor" if "ceiling" in what else "cables[*].body_anchor"
            raise RigError(f"{src}: field {field}: {what} span {span:.4g} m, more than a vehicle rig's "
                           f"{LARGEST_RIG:g} m ({mm})")
    for i, c in enumerate(rig.cables):
        if c.length > LARGEST_RIG:
            raise RigError(f"{src}: field cables[{i}].length = {c.length:.4g} m, longer than a vehicle rig's "
                           f"{LARGEST_RIG:g} m ({mm})")
    centre = rig.body_anchors.mean(axis=0)
    points = {"body.center_of_gravity": rig.center_of_gravity, "imu.position": rig.imu.position,
              "exciter.position": None if rig.exciter is None else rig.exciter.position,
              "dummy_mass.position": None if rig.dummy_mass is None else rig.dummy_mass.position}
    for field, x in points.items():
        if x is not None and np.linalg.norm(x - centre) > LARGEST_RIG:
            raise RigError(f"{src}: field {field} = {np.round(x, 4).tolist()} m lies "
                           f"{np.linalg.norm(x - centre):.4g} m from the body anchors' centre ({mm})")
    if rig.mass > LARGEST_MASS:
        raise RigError(f"{src}: field body.mass = {rig.mass:g} kg is more than a heavy truck's "
                       f"{LARGEST_MASS:g} kg (rig.yaml is in kg -- grams?)")
    mounts = {"imu.rpy": rig.imu, "exciter.rpy": rig.exciter, "inclinometer.rpy": rig.inclinometer}
    for field, m in mounts.items():
        if m is not None and np.max(np.abs(m.rpy)) > 2 * np.pi + 1e-9:
            raise RigError(f"{src}: field {field} = {m.rpy.tolist()} has an angle beyond 2π (rig.yaml angles are "
                           "in radians -- degrees?)")
    share = rig.mass * rig.gravity / len(rig.cables)
    for i, c in enumerate(rig.cables):
        if c.stiffness is not None and share / c.stiffness > LARGEST_STRETCH * c.length:
            raise RigError(f"{src}: field cables[{i}].stiffness = {c.stiffness:g} N/m would stretch cable {c.name} "
                           f"by {share / c.stiffness:.3g} m under {share:.0f} N, more than "
                           f"{100 * LARGEST_STRETCH:g} % of its length (EA/L is in N/m -- N/mm?)")


def _rig_name(v: Any, src: str) -> str | None:
    """rig.yaml ``name``: a non-empty one-line text, stripped (a number is taken as its text);
    None when absent."""
    if v is None:
        return None
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        v = str(v)    # name: 7 is a name
    if not isinstance(v, str) or not v.strip() or "\n" in v.strip():
        raise RigError(f"{src}: field name must be a one-line text (the rig's name), got {v!r}")
    return v.strip()


def _output_axes(v: Any, src: str) -> str | None:
    """rig.yaml ``output_axes``: a key of :data:`~rig_identification.io.export.AXES` (a wrong
    one refused with the closest key); None when absent."""
    if v is not None and (not isinstance(v, str) or v not in AXES):
        close = difflib.get_close_matches(str(v).lower(), sorted(AXES), n=1, cutoff=0.5)
        raise RigError(f"{src}: field output_axes must be one of {', '.join(AXES)} (the axes rig-identify "
                       f"prints and exports in by default), got {v!r}"
                       + (f" (did you mean {close[0]}?)" if close else ""))
    return v


def _gravity(v: Any, src: str) -> float:
    """rig.yaml ``gravity``, m/s²: a number between 9 and 10.5 (an Earth gravity)."""
    gravity = _number(v, "gravity", src, positive=True)
    if not 9.0 < gravity < 10.5:
        raise RigError(f"{src}: field gravity = {gravity} m/s^2 is not an Earth gravity (units?)")
    return gravity


def _cable(c: Any, where: str, taken: Collection[str], src: str) -> Cable:
    """rig.yaml ``cables[i]`` (at ``where``): a name matching :data:`CABLE_NAME` and not among
    ``taken`` (the names of the cables before it), the two anchors (3,) m, the length m > 0
    and the optional stiffness N/m > 0."""
    name = _get(c, "name", where, src)
    _check_fields(c, "cable", where, src)
    if not isinstance(name, str) or not CABLE_NAME.match(name):
        raise RigError(f"{src}: field {where}.name must match [a-z0-9_]+, got {name!r}")
    if name in taken:
        raise RigError(f"{src}: field {where}.name: duplicate cable name {name!r}")
    ca = _vector(_get(c, "ceiling_anchor", where, src), f"{where}.ceiling_anchor", src)
    ba = _vector(_get(c, "body_anchor", where, src), f"{where}.body_anchor", src)
    length = _number(_get(c, "length", where, src), f"{where}.length", src, positive=True)
    k_raw = _get(c, "stiffness", where, src, required=False)
    k = None if k_raw is None else _number(k_raw, f"{where}.stiffness", src, positive=True)
    return Cable(name, ca, ba, length, k)


def _cables(raw: Any, src: str) -> list[Cable]:
    """rig.yaml ``cables``: a list of at least 3 cables (:func:`_cable`), their body anchors not
    collinear, their geometry one pose can hold taut (:func:`check_reach`)."""
    if not isinstance(raw, list):
        raise RigError(f"{src}: field cables must be a list")
    if len(raw) < 3:
        raise RigError(f"{src}: field cables lists {len(raw)} cable(s); at least 3 are needed")
    cables: list[Cable] = []
    for i, c in enumerate(raw):
        cables.append(_cable(c, f"cables[{i}]", [x.name for x in cables], src))
    anchors = np.array([c.body_anchor for c in cables])
    if np.linalg.matrix_rank(anchors - anchors.mean(0), tol=1e-6) < 2:
        raise RigError(f"{src}: field cables: the body anchors are collinear; the body could spin freely")
    check_reach(cables, src)
    return cables


def _body(body: Any, output_axes: str | None, src: str) -> tuple[float, np.ndarray | None, Vehicle | None]:
    """rig.yaml ``body``: (mass kg > 0, center_of_gravity (3,) m body frame or None, vehicle
    (:func:`_vehicle`) or None); vehicle axes as ``output_axes`` need the vehicle."""
    if isinstance(body, dict):
        _check_fields(body, "body", "body", src)
    mass = _number(_get(body, "mass", "body", src), "body.mass", src, positive=True)
    cg_raw = _get(body, "center_of_gravity", "body", src, required=False)
    cg = None if cg_raw is None else _vector(cg_raw, "body.center_of_gravity", src)
    vehicle = _vehicle(_get(body, "vehicle", "body", src, required=False), src)
    if output_axes in VEHICLE_AXES and vehicle is None:
        raise RigError(f"{src}: field output_axes: {output_axes} (vehicle axes) needs field body.vehicle, where the "
                       "vehicle's front and top point in the body frame (e.g. body: {vehicle: {front: +x, top: +z}}); "
                       "without it only output_axes: body")
    return mass, cg, vehicle


def _dummy_mass(d: Any, src: str) -> DummyMass | None:
    """rig.yaml ``dummy_mass``: mass kg > 0 and position (3,) m body frame; None when absent."""
    if d is None:
        return None
    if isinstance(d, dict):
        _check_fields(d, "dummy_mass", "dummy_mass", src)
    return DummyMass(_number(_get(d, "mass", "dummy_mass", src), "dummy_mass.mass", src, positive=True),
                     _vector(_get(d, "position", "dummy_mass", src), "dummy_mass.position", src))


def rig_from_dict(d: Any, source: str = "<memory>") -> Rig:
    """Validate a rig.yaml mapping and build a :class:`Rig`.

    Refused, each with a :class:`RigError` naming ``source`` and the field: a missing field; a
    field rig.yaml does not have (with the closest known one: ``body.centre_of_gravity`` ->
    did you mean ``body.center_of_gravity``?); a value that is not a finite number (or list of
    3); gravity outside 9–10.5 m/s²; fewer than 3 cables, a duplicate or malformed cable name;
    a length, stiffness, body mass or dummy mass <= 0; collinear body anchors; cable geometry
    no pose can hold with every cable taut (:func:`check_reach`: e.g. one anchor in mm); numbers
    each possible alone but in the wrong units together (:func:`check_scale`: the whole rig in
    mm, a mass in g, angles in degrees, a stiffness in N/mm); a ``name``
    that is not a non-empty one-line text; an ``output_axes`` that is not a key of
    :data:`~rig_identification.io.export.AXES` (with the closest one); a ``body.vehicle`` whose
    ``front`` or ``top`` is not a signed body axis, or whose two lie on one axis; vehicle axes
    as ``output_axes`` without ``body.vehicle``.
    """
    src = source
    if not isinstance(d, dict):
        raise RigError(f"{src}: the rig description must be a YAML mapping")
    _check_fields(d, "", "", src)
    rig_name = _rig_name(_get(d, "name", "", src, required=False), src)
    output_axes = _output_axes(_get(d, "output_axes", "", src, required=False), src)
    gravity = _gravity(_get(d, "gravity", "", src), src)
    cables = _cables(_get(d, "cables", "", src), src)
    mass, cg, vehicle = _body(_get(d, "body", "", src), output_axes, src)
    imu = _mount(_get(d, "imu", "", src), "imu", src)
    ex_raw = _get(d, "exciter", "", src, required=False)
    exciter = None if ex_raw is None else _mount(ex_raw, "exciter", src)
    inc_raw = _get(d, "inclinometer", "", src, required=False)
    incl = None if inc_raw is None else _mount(inc_raw, "inclinometer", src, with_position=False)
    dummy = _dummy_mass(_get(d, "dummy_mass", "", src, required=False), src)
    topics = _topics(_get(d, "topics", "", src, required=False), src)
    survey = _survey(_get(d, "survey", "", src, required=False), src)
    rig = Rig(gravity, tuple(cables), mass, cg, imu, exciter, incl, dummy, src, name=rig_name, output_axes=output_axes,
              topics=topics, survey=survey, vehicle=vehicle)
    check_scale(rig)
    return rig


def read_text(path: str | Path, error: type[ValueError], what: str) -> str:
    """The text of a UTF-8 file; an unreadable or non-UTF-8 file raises ``error`` naming it
    and ``what`` it should hold."""
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except OSError as e:
        raise error(f"{p}: cannot read the {what} ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise error(f"{p}: not a text file (byte {e.start} is not UTF-8)") from None


def read_yaml(path: str | Path, error: type[ValueError], what: str) -> Any:
    """Parse a YAML file; an unreadable, non-UTF-8 or invalid file raises ``error`` naming it."""
    p = Path(path)
    text = read_text(p, error, what)
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise error(f"{p}: not valid YAML ({str(e).splitlines()[0]})") from None


def load_rig(path: str | Path) -> Rig:
    """Load and validate a ``rig.yaml`` file.  Raises :class:`RigError`."""
    return rig_from_dict(read_yaml(path, RigError, "rig description"), str(path))


def dump_rig(rig: Rig, comment: str | None = None) -> str:
    """rig.yaml text for ``rig`` (flow-style vectors, as in the format spec), headed by
    ``comment`` (each of its lines a ``# `` comment line)."""
    head = "".join(f"# {line}\n" for line in comment.splitlines()) if comment else ""
    body: str = yaml.safe_dump(rig.to_dict(), sort_keys=False, default_flow_style=None)
    return head + body


# --- inertia entries (truth.yaml, experiment files) ---------------------------------------------

INERTIA_KEYS = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")


def inertia_tensor(d: Mapping[str, Any]) -> np.ndarray:
    """(3, 3) tensor from the truth.yaml entries ixx..izz (off-diagonals = negated products)."""
    xx, xy, xz, yy, yz, zz = (float(d[k]) for k in INERTIA_KEYS)
    return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])


def inertia_entries(J: np.ndarray) -> dict[str, float]:
    """truth.yaml entries ixx..izz of a (3, 3) tensor."""
    return {"ixx": float(J[0, 0]), "ixy": float(J[0, 1]), "ixz": float(J[0, 2]),
            "iyy": float(J[1, 1]), "iyz": float(J[1, 2]), "izz": float(J[2, 2])}
