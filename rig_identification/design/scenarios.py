"""Random rigs for off-nominal tests and benchmarks: vehicles, carrying frames, cable geometries.

A real rig never matches the thesis's four splayed cables exactly.  This module draws
experiment files (:mod:`~rig_identification.model.simulator` schema) for rigs and bodies the
package has not been tuned on:

* a road vehicle from NHTSA's inertial-parameter database (``data/nhtsa_inertial_parameters.csv``:
  204 vehicles, mass, CG height, roll/pitch/yaw moments and, for 41 of them, the roll–yaw
  product; SAE J670 axes, z down — converted here to the package's z-up body axes, which
  flips the sign of the xz product) fixed in a carrying frame (a box of steel tubes, its mass
  and tensor those of a thin box shell), the body frame's origin at the frame's floor centre
  (off the CG);
* 3 to 6 cables from the frame's top to the ceiling: ``layout`` ``"wide"`` (the ceiling
  anchors' rectangle 1.8–2.5 times the body anchors' — the thesis's rigs: the cables' lines
  cross near the CG, so roll and pitch are low pendulum modes the exciter moves),
  ``"splayed"`` (ceiling anchors 0.3–0.8 m outward of the body anchors: roll and pitch
  ride on the cables' stretch, stiff modes well above the forcing, and are weakly
  determined), ``"parallel"`` (2 cm of splay over the cable length: roll and pitch hardly
  restored by the geometry), ``"mixed"`` (each cable its own splay, the ceiling anchors at
  different heights) or ``"random"`` (the whole range: a splay drawn log-uniformly from
  near-parallel, 0.008 m per m of cable, to wide, 0.8 m per m, each cable within ±30 % of
  it, the ceiling anchors at heights within ±0.3 m); the unstretched lengths are set so that at the level reference pose
  the cables share the weight as evenly as static equilibrium allows (non-negative least
  squares, scipy ``lsq_linear``), as a lab adjusts its turnbuckles;
* the exciter (``exciter`` ``"corner"``, a lab's choice: at a bottom corner of the frame,
  its spin axis vertical or along a horizontal body axis; ``"anywhere"``: a random point
  of the frame's surface, spin axis along a random body axis; ``"top_corner"``: a top
  corner of the frame, spinning about body x; ``"random"``: a random point of the frame's
  surface, spin axis a uniformly random direction), a rotating force of
  180–220 N at a frequency 10 % away from every natural frequency, its double and every
  sum of two (:func:`~rig_identification.design.planning.resonances`), preferably 1.15–1.4 Hz;
:func:`random_experiment` returns the experiment mapping; :func:`simulate_random` simulates
it, lowering the force until every cable keeps 20 % of its static tension (the planner's
default limit), and returns the mapping and the :class:`~rig_identification.model.simulator.SimResult`.
"""
from __future__ import annotations

import copy
import csv
from dataclasses import dataclass
from importlib import resources

import numpy as np
from scipy.optimize import lsq_linear
from scipy.spatial.transform import Rotation

from ..io.rig import rig_from_dict
from ..model.experiment import REFERENCE_NOISE, REFERENCE_RATES, experiment_from_dict
from ..model.modes import natural_modes
from ..model.parametrisation import joined
from ..model.rigid_body import SimulationError
from ..model.simulator import SimResult, simulate
from .planning import resonances

LAYOUTS = ("wide", "splayed", "parallel", "mixed", "random")
EXCITER_PLACEMENTS = ("corner", "anywhere", "top_corner", "random")
CABLE_STIFFNESS = 5.0e6          # N/m: steel cables of the simulated rigs (rig.yaml states none)
FRAME_MASS = (150.0, 300.0)      # kg: the carrying frame
FORCE = (180.0, 220.0)           # N: the rotating force's amplitude
PREFERRED_HZ = (1.15, 1.4)       # the exciter's frequency, when the modes leave room there
MODE_MARGIN = 0.10               # relative distance of the exciter frequency from every resonance
MIN_TENSION = 0.2                # every cable keeps this fraction of its static tension
MIN_SHARE = 0.25                 # every cable carries at least this fraction of an even share at rest
SLACK_SHARE = 0.05               # a cable below this fraction of the mean tension at rest is slack: no rig
MIXED_TRIES = 50                 # draws of a "mixed"/"random" layout until the level pose is an equilibrium
RANDOM_SPLAY = (0.008, 0.8)      # m per m of cable: the "random" layout's splay, near-parallel to wide
HEIGHTS = 0.3                    # m: the ceiling anchors' heights differ by up to ± this ("mixed", "random")


@dataclass(frozen=True)
class Vehicle:
    """One row of the NHTSA table: name, mass kg, CG height above ground m, moments of
    inertia about the CG (roll, pitch, yaw) kg·m², roll–yaw product (SAE axes) kg·m² or None."""

    name: str
    mass: float
    cg_height: float
    ixx: float
    iyy: float
    izz: float
    ixz_sae: float | None


def vehicles() -> list[Vehicle]:
    """The 204 vehicles of NHTSA's inertial-parameter database (package data)."""
    text = resources.files("rig_identification").joinpath("data/nhtsa_inertial_parameters.csv").read_text()
    out = []
    for row in csv.DictReader(text.splitlines()):
        out.append(Vehicle(f"{row['year']} {row['make']} {row['model']}", float(row["mass_kg"]),
                           float(row["cg_height_m"]), float(row["ixx_roll_kgm2"]), float(row["iyy_pitch_kgm2"]),
                           float(row["izz_yaw_kgm2"]), float(row["ixz_kgm2"]) if row["ixz_kgm2"] else None))
    return out


def _box_shell(mass: float, size: np.ndarray) -> np.ndarray:
    """Inertia tensor (3,3) kg·m² about its centre of a thin-walled box of outer ``size``
    (3,) m with the mass spread over its surface (area-weighted faces)."""
    a, b, c = size
    faces = [(b * c, 0), (a * c, 1), (a * b, 2)]        # two faces normal to axis k, each of area A
    area = 2 * sum(A for A, _ in faces)
    J = np.zeros(3)
    for A, k in faces:
        m = mass * 2 * A / area                          # both faces
        d = size / 2
        dims = [size[i] for i in range(3) if i != k]
        for i in range(3):
            if i == k:                                   # plate normal along i: in-plane moment
                J[i] += m * (dims[0] ** 2 + dims[1] ** 2) / 12
            else:                                        # plate at distance d_k from the centre
                j = [x for x in range(3) if x not in (i, k)][0]
                J[i] += m * (size[j] ** 2 / 12 + d[k] ** 2)
    return np.diag(J)


@dataclass(frozen=True)
class Body:
    """The suspended body: mass kg, CG (3,) body frame m, tensor (3,3) about the CG kg·m²,
    frame box size (3,) m (its floor centre is the body frame's origin), vehicle name."""

    mass: float
    cg: np.ndarray
    inertia: np.ndarray
    size: np.ndarray
    vehicle: str


def random_body(rng: np.random.Generator) -> Body:
    """A random NHTSA vehicle in a carrying frame (see module docstring)."""
    v = vehicles()[int(rng.integers(len(vehicles())))]
    # the vehicle's principal moments, the roll–yaw product (SAE z down -> z up flips it)
    # or a small random one, and a small random turn of its principal axes
    ixz = -v.ixz_sae if v.ixz_sae is not None else rng.uniform(-0.05, 0.05) * np.sqrt(v.ixx * v.izz)
    Jv = np.array([[v.ixx, 0.0, -ixz], [0.0, v.iyy, 0.0], [-ixz, 0.0, v.izz]])   # entries: products negated
    R = Rotation.from_rotvec(rng.uniform(-0.03, 0.03, 3)).as_matrix()
    Jv = R @ Jv @ R.T
    # frame: the vehicle's footprint from its pitch/yaw moments (a box of the same mass),
    # plus room around it
    length = float(np.clip(np.sqrt(12 * v.iyy / v.mass) * 1.6, 3.5, 5.5))
    width = float(np.clip(length * 0.4, 1.5, 2.1))
    height = float(rng.uniform(1.6, 2.0))
    size = np.array([length + 0.4, width + 0.3, height])
    mf = float(rng.uniform(*FRAME_MASS))
    c_vehicle = np.array([rng.uniform(-0.2, 0.2), rng.uniform(-0.03, 0.03), 0.15 + v.cg_height])
    c_frame = np.array([0.0, 0.0, height / 2])
    m, cg, J = joined(v.mass, c_vehicle, Jv, mf, c_frame, _box_shell(mf, size))
    return Body(m, cg, J, size, v.name)


def body_anchors(size: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) body anchors on the frame's top (z = height), body frame m: 3 cables — the two
    front top corners and the rear top centre; 4 — the top corners; 5 — the corners and the
    front top centre; 6 — the corners and the middles of the long sides."""
    hx, hy, z = size[0] / 2, size[1] / 2, size[2]
    corners = [(hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)]
    xy = {3: [(hx, -hy), (hx, hy), (-hx, 0.0)], 4: corners, 5: corners + [(hx, 0.0)],
          6: corners + [(0.0, -hy), (0.0, hy)]}
    if n not in xy:
        raise ValueError(f"cables: {n} (3 to 6)")
    return np.array([(x, y, z) for x, y in xy[n]])


def _modes_ok(f: float, res: np.ndarray) -> bool:
    return bool(np.all(np.abs(f - res) > MODE_MARGIN * res))


def exciter_frequency(mode_f, rng: np.random.Generator) -> float:
    """A frequency (Hz) ≥ :data:`MODE_MARGIN` from every resonance of the modes ``mode_f``:
    random in :data:`PREFERRED_HZ` when there is room, else the free frequency in
    0.6–2.5 Hz nearest to it."""
    res = resonances(mode_f)
    grid = np.linspace(*PREFERRED_HZ, 51)
    ok = [f for f in grid if _modes_ok(f, res)]
    if ok:
        return float(rng.choice(ok))
    wide = np.linspace(0.6, 2.5, 381)
    ok = [f for f in wide if _modes_ok(f, res)]
    if not ok:
        raise SimulationError("no exciter frequency in 0.6–2.5 Hz is 10 % away from every resonance")
    mid = np.mean(PREFERRED_HZ)
    return float(min(ok, key=lambda f: abs(f - mid)))


def shared_lengths(ceiling: np.ndarray, anchors_world: np.ndarray, anchors_body: np.ndarray, cg: np.ndarray,
                   mass: float, gravity: float, stiffness: float) -> tuple[np.ndarray, float]:
    """Unstretched cable lengths (n,) m for which the body hangs near the level reference pose
    with the cables sharing its weight as evenly as static equilibrium allows.

    ceiling (n,3) world m; anchors_world (n,3) the body anchors at the reference pose, world
    m; anchors_body (n,3) body frame m; cg (3,) body frame m.  The tensions T ≥
    :data:`MIN_SHARE` of the even share solve the equilibrium of the weight at the CG (force
    and moment, 6 equations) in the least-squares sense, regularised toward the even share
    (scipy ``lsq_linear``; with three cables the body then tilts a little to balance); the
    length is the anchor distance less the stretch T/k (Hooke).  Returns (lengths (n,) m, the
    equilibrium's residual over the weight: 0 when the level pose is an equilibrium)."""
    n = len(ceiling)
    d = ceiling - anchors_world
    dist = np.linalg.norm(d, axis=1)
    u = d / dist[:, None]
    r = anchors_body - cg
    A = np.vstack([u.T, np.cross(r, u).T])          # (6, n): force and moment per unit tension
    w = mass * gravity
    b = np.array([0.0, 0.0, w, 0.0, 0.0, 0.0])
    share = w / max(float(u[:, 2].sum()), 1e-9)
    reg = 1e-3
    A_aug = np.vstack([A, reg * np.eye(n)])
    b_aug = np.concatenate([b, reg * np.full(n, share)])
    T = lsq_linear(A_aug, b_aug, bounds=(MIN_SHARE * share, np.inf)).x
    return dist - T / stiffness, float(np.linalg.norm(A @ T - b) / w)


def _level_offsets(rng: np.random.Generator, layout: str, body: Body, radial: np.ndarray, out: np.ndarray,
                   length: float) -> np.ndarray:
    """(n, 3) horizontal offsets, m, of the ceiling anchors from the body anchors at the reference
    pose for the ``"wide"``, ``"splayed"`` and ``"parallel"`` layouts.  radial: (n, 3) the body
    anchors' horizontal offsets from their centroid, m; out: (n, 3) the same as unit vectors;
    length: the cables' nominal length, m."""
    if layout == "wide":
        # each cable's line, seen from the front and from the side, crosses the body's plane of
        # symmetry 1–2.5 times as deep below the anchors as the CG (the thesis's rigs: about 1×)
        depth = body.size[2] - body.cg[2]
        offset = radial * (length / (rng.uniform(1.0, 2.5) * depth))
        return offset * np.minimum(1.0, 1.5 * length / np.linalg.norm(offset, axis=1))[:, None]
    if layout == "splayed":
        return out * rng.uniform(0.3, 0.8)
    return out * (0.02 * length / 2.5)


def _drawn_ceiling(rng: np.random.Generator, layout: str, body: Body, b: np.ndarray, out: np.ndarray,
                   length: float, p0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ceiling anchors (n, 3) world m, unstretched lengths (n,) m) of the ``"mixed"`` and
    ``"random"`` layouts.  b: (n, 3) body anchors, body frame m; out: (n, 3) their outward
    horizontal unit vectors; length: the cables' nominal length, m; p0: (3,) the body origin at
    the reference pose, world m.

    Each cable its own splay and ceiling height, drawn until the cables can share the weight at
    the level pose (else the body swings to where one goes slack), at most :data:`MIXED_TRIES`
    times; then the draw nearest to sharing it, as ``"splayed"`` does (three cables at different
    heights never share it exactly): the body hangs a little tilted, and :func:`simulate_random`
    checks that every cable stays taut."""
    level = float(np.exp(rng.uniform(*np.log(RANDOM_SPLAY)))) if layout == "random" else 0.0
    best: tuple[np.ndarray, np.ndarray, float] | None = None
    for _ in range(MIXED_TRIES):
        if layout == "mixed":
            offset = out * rng.uniform(0.2, 0.8, len(b))[:, None]
        else:
            offset = out * (level * length * rng.uniform(0.7, 1.3, len(b)))[:, None]
        heights = rng.uniform(-HEIGHTS, HEIGHTS, len(b))
        ceiling = p0 + b + offset
        ceiling[:, 2] = heights
        lengths, resid = shared_lengths(ceiling, p0 + b, b, body.cg, body.mass, 9.80665, CABLE_STIFFNESS)
        if best is None or resid < best[2]:
            best = (ceiling, lengths, resid)
        if resid < 1e-4:
            break
    assert best is not None    # MIXED_TRIES ≥ 1 draws
    ceiling, lengths, _ = best
    return ceiling, lengths


def _cables(rng: np.random.Generator, layout: str, body: Body, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ceiling anchors (n, 3) world m, unstretched lengths (n,) m) of a ``layout`` for the body
    anchors ``b`` (n, 3), body frame m; the reference pose: body level, its anchors' centroid
    below the ceiling anchors' centroid."""
    centre = b.mean(axis=0)
    radial = np.c_[b[:, :2] - centre[:2], np.zeros(len(b))]
    out = radial / np.linalg.norm(radial, axis=1)[:, None]
    length = rng.uniform(1.8, 3.0)
    p0 = np.array([3.0, 3.0, -length - body.size[2]])   # the body origin at the reference pose, world m
    if layout in ("mixed", "random"):
        return _drawn_ceiling(rng, layout, body, b, out, length, p0)
    ceiling = p0 + b + _level_offsets(rng, layout, body, radial, out, length)
    ceiling[:, 2] = 0.0
    lengths, _ = shared_lengths(ceiling, p0 + b, b, body.cg, body.mass, 9.80665, CABLE_STIFFNESS)
    return ceiling, lengths


def _frame_corner(rng: np.random.Generator, size: np.ndarray, height: tuple[float, float]) -> np.ndarray:
    """(3,) a random corner of the frame of ``size`` (3,) m, a little inside it, at a random
    fraction in ``height`` of its height; body frame m."""
    sx, sy = rng.choice([-1.0, 1.0], 2)
    return np.array([sx * size[0] / 2 * rng.uniform(0.85, 1.0), sy * size[1] / 2 * rng.uniform(0.85, 1.0),
                     rng.uniform(*height) * size[2]])


def _frame_face_point(rng: np.random.Generator, size: np.ndarray) -> np.ndarray:
    """(3,) a random point on a random face (±x, ±y, floor, top) of the frame of ``size`` (3,) m;
    body frame m."""
    face = int(rng.integers(6))
    pos = np.array([rng.uniform(-0.5, 0.5) * size[0], rng.uniform(-0.5, 0.5) * size[1],
                    rng.uniform(0.0, 1.0) * size[2]])
    if face < 4:
        pos[face // 2] = (1 if face % 2 else -1) * size[face // 2] / 2
    else:
        pos[2] = 0.0 if face == 4 else size[2]
    return pos


def _exciter_placement(rng: np.random.Generator, exciter: str, size: np.ndarray) -> tuple[np.ndarray, int]:
    """(position (3,) body frame m, spin axis: 0, 1, 2 for body x, y, z, 3 for a random direction)
    of an ``exciter`` placement (:data:`EXCITER_PLACEMENTS`) on the frame of ``size`` (3,) m."""
    if exciter == "corner":
        # a bottom corner of the frame (a little inside it), spinning about body z or a horizontal axis
        pos = _frame_corner(rng, size, (0.0, 0.1))
        return pos, int(rng.choice([2, 2, 0, 1]))
    if exciter == "top_corner":
        # a top corner of the frame (a little inside it), spinning about body x
        return _frame_corner(rng, size, (0.9, 1.0)), 0
    pos = _frame_face_point(rng, size)
    spin = int(rng.integers(3)) if exciter == "anywhere" else 3
    return pos, spin


def _exciter_orientation(rng: np.random.Generator, spin: int) -> tuple[list[float], str]:
    """(rpy, rad, of the exciter frame whose z (its spin axis) is along body x, y, z for ``spin``
    0, 1, 2, or for 3 a uniformly random direction; the axis in words: ``"x"``, or its unit vector)."""
    rpy = ([[0.0, np.pi / 2, 0.0], [-np.pi / 2, 0.0, 0.0], [0.0, 0.0, 0.0]][spin] if spin < 3
           else Rotation.random(rng=rng).as_euler("xyz").tolist())
    axis = "xyz"[spin] if spin < 3 else "({:+.2f}, {:+.2f}, {:+.2f})".format(
        *Rotation.from_euler("xyz", rpy).as_matrix()[:, 2])
    return rpy, axis


def _rig_mapping(rng: np.random.Generator, body: Body, b: np.ndarray, ceiling: np.ndarray, lengths: np.ndarray,
                 exciter_position: np.ndarray, exciter_rpy: list[float]) -> dict:
    """The ``rig:`` mapping (rig.yaml schema) of the random rig, its IMU drawn on the frame: b (n, 3)
    body anchors, body frame m; ceiling (n, 3) world m; lengths (n,) m; the exciter's position
    (3,) body frame m and rpy rad."""
    imu = np.array([rng.uniform(-0.4, 0.4) * body.size[0], rng.uniform(-0.4, 0.4) * body.size[1],
                    rng.uniform(0.1, 0.9) * body.size[2]])
    return {"gravity": 9.80665,
            "cables": [{"name": f"c{i}", "ceiling_anchor": ceiling[i].tolist(), "body_anchor": b[i].tolist(),
                        "length": float(lengths[i])} for i in range(len(b))],
            "body": {"mass": float(body.mass), "center_of_gravity": body.cg.tolist()},
            "imu": {"position": imu.tolist(), "rpy": [0.0, 0.0, float(rng.choice([0.0, np.pi / 2]))]},
            "exciter": {"position": exciter_position.tolist(), "rpy": exciter_rpy},
            "inclinometer": {"rpy": [0.0, 0.0, 0.0]}}


def random_experiment(seed: int, cables: int = 4, layout: str = "wide", effects: list | tuple = (),
                      duration: float = 120.0, force: float | None = None, noise: dict | None = None,
                      exciter: str = "corner") -> dict:
    """An experiment mapping (:func:`~rig_identification.model.simulator.experiment_from_dict`) of a random rig.

    seed: numpy seed of every draw (and of the sensor noise).  cables: 3–6.  layout: one
    of :data:`LAYOUTS`.  effects: the ``effects:`` list to conceal (:mod:`~rig_identification.model.effects`).
    duration: s.  force: the rotating force's amplitude, N (default random in :data:`FORCE`).
    noise: σ per sensor (default :data:`REFERENCE_NOISE`).  exciter: one of
    :data:`EXCITER_PLACEMENTS`.  Raises ValueError for a bad ``cables``/``layout``/``exciter``,
    :class:`~rig_identification.model.simulator.SimulationError` when the rig has no equilibrium or no free exciter
    frequency.
    """
    if layout not in LAYOUTS:
        raise ValueError(f"layout: {layout!r} (one of {', '.join(LAYOUTS)})")
    if exciter not in EXCITER_PLACEMENTS:
        raise ValueError(f"exciter: {exciter!r} (one of {', '.join(EXCITER_PLACEMENTS)})")
    rng = np.random.default_rng(seed)
    body = random_body(rng)
    b = body_anchors(body.size, cables)
    ceiling, lengths = _cables(rng, layout, body, b)
    pos, spin = _exciter_placement(rng, exciter, body.size)
    rpy, axis = _exciter_orientation(rng, spin)
    rig = _rig_mapping(rng, body, b, ceiling, lengths, pos, rpy)
    r = rig_from_dict(rig, f"random rig {seed}")
    f_modes = [m.frequency for m in natural_modes(r, body.mass, body.cg, body.inertia, CABLE_STIFFNESS)
               if m.frequency > 0.05]
    J = body.inertia
    return {
        "name": f"random_{seed}_{cables}{layout}",
        "description": f"{body.vehicle} in a {body.size[0]:.1f}×{body.size[1]:.1f}×{body.size[2]:.1f} m frame on "
                       f"{cables} {layout} cables, exciter at ({pos[0]:.2f}, {pos[1]:.2f}, {pos[2]:.2f}) m spinning "
                       f"about body {axis}",
        "rig": rig,
        "inertia_about_cg": {"ixx": J[0, 0], "ixy": J[0, 1], "ixz": J[0, 2], "iyy": J[1, 1], "iyz": J[1, 2],
                             "izz": J[2, 2]},
        "cable_model": {"type": "spring", "stiffness": CABLE_STIFFNESS, "damping_ratio": 0.01},
        "initial": {"equilibrium": True},
        "excitation": {"rotating": {"amplitude": float(force if force is not None else rng.uniform(*FORCE)),
                                    "frequency": exciter_frequency(f_modes, rng), "ramp_time": 2.0,
                                    "ramp_shape": "spin_up", "phase": 0.0, "direction": 1, "start_time": 0.0}},
        "duration": float(duration),
        "sensors": {"rates_hz": dict(REFERENCE_RATES), "noise": dict(REFERENCE_NOISE if noise is None else noise)},
        "seed": int(seed),
        "stamp_origin": 1.75e9,
        "effects": [dict(e) for e in effects],
    }


def simulate_random(seed: int, cables: int = 4, layout: str = "wide", effects: list | tuple = (),
                    duration: float = 120.0, noise: dict | None = None, exciter: str = "corner"
                    ) -> tuple[dict, SimResult]:
    """Simulate :func:`random_experiment`; while a cable drops below :data:`MIN_TENSION` of
    its static tension, the force is lowered by a third (at most four times).  Returns the
    experiment mapping and the :class:`~rig_identification.model.simulator.SimResult`.  Raises
    :class:`~rig_identification.model.simulator.SimulationError` if no force keeps the cables taut, or a
    cable carries less than :data:`SLACK_SHARE` of the mean tension at rest."""
    return simulate_taut(random_experiment(seed, cables, layout, effects, duration, noise=noise, exciter=exciter))


def simulate_taut(d: dict) -> tuple[dict, SimResult]:
    """Simulate the experiment mapping ``d``; while a cable drops below :data:`MIN_TENSION` of its
    static tension, the force is lowered by a third (at most four times).  Returns the mapping as
    simulated and the :class:`~rig_identification.model.simulator.SimResult`.  Raises as
    :func:`simulate_random`."""
    d = copy.deepcopy(d)
    for _ in range(5):
        sim = simulate(experiment_from_dict(d, d["name"]))
        T = np.column_stack([sim.sensors.load_cells[n].data[:, 0] for n in sim.rig.cable_names])
        static = np.median(T[: max(2, int(0.5 * REFERENCE_RATES["load_cells"]))], axis=0)
        if static.min() < SLACK_SHARE * static.mean():
            raise SimulationError(f"{d['name']}: cable {sim.rig.cable_names[int(np.argmin(static))]} carries "
                                  f"{100 * static.min() / static.mean():.1f} % of the mean tension at rest: "
                                  "slack, not the rig drawn")
        if np.all(T.min(axis=0) >= MIN_TENSION * static):
            return d, sim
        d["excitation"]["rotating"]["amplitude"] *= 2 / 3
    raise SimulationError(f"{d['name']}: a cable drops below {100 * MIN_TENSION:.0f} % of its static tension even "
                          f"at {d['excitation']['rotating']['amplitude']:.0f} N")
