"""The unknowns of the rig model (:mod:`~rig_identification.estimation.rig_fit`): where each sits in
the parameter vector (:class:`Layout`), what is known of them before the fit (:class:`Prior`),
their priors' centres and σ, and their units.

The vector, in order: the inertia tensor (6 entries about the CG, kg·m²), the CG (3, body m),
the mass (kg), log(stiffness) per cable, the cables' damping time τ (s), per-load-cell gain,
the body's viscous damping (linear N·s/m, angular N·m·s), the first segment's initial state
(12: δp_cg m, δφ rad, δv_cg m/s, δω rad/s), the geometry (every ceiling anchor, body anchor and
cable length, m), the extensions the layout holds (:data:`EXTENSIONS`, in its order), the
exciter force's correction (2 K), then the later segments' initial states (12 each).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..io.rig import Rig, Survey
from ..model.cables import DEFAULT_STIFFNESS
from ..model.linear_rig import RigParameters
from ..model.parametrisation import without_point_mass
from .rig_record import RigFitError

#: The longest segment, s, of a fitted span (:mod:`~rig_identification.estimation.rig_fit`): each
#: segment starts from its own initial state (unknowns, no prior), so a swinging mode's phase is
#: never carried further.
SEGMENT = 15.0

#: The smallest σ a prior takes, m: a survey σ of 0 (exact) becomes this (the unknown then
#: stays put without dividing by zero).
EXACT_STD = 1e-7
#: The smallest σ a load cell's gain takes (a survey σ of 0, exact, becomes this).
EXACT_GAIN_STD = 1e-9
#: σ of the force's correction unknowns (:class:`Layout` ``force``, share and rad): far wider than
#: the record determines them (~3e-5); it holds those whose spline reaches past a stage's span,
#: which would otherwise drive the next stage's model off (shipped case 16: 60 kN after 40 s).
FORCE_CORRECTION_STD = 0.01
#: σ of log(stiffness) for a cable whose stiffness rig.yaml gives (a datasheet's EA) or does not
#: (the default steel cable's, a factor e either way).  Where the cables are far softer the fit's
#: start comes from the data (:func:`~.harmonic_start.stiffness_start`), not this prior, which
#: stays: on the independent simulator's 150 kN/m rig (3.5 σ below the default's centre) the
#: fitted stiffness came within 0.2 % of the truth under it, so it is not widened.  A load
#: cell's gain takes rig.yaml's ``survey.load_cell_gain``.
STIFFNESS_LOG_STD_GIVEN = 0.2
STIFFNESS_LOG_STD_DEFAULT = 1.0
#: The rig model's extensions (the physics and sensor traits the diagnosis tries,
#: :mod:`~rig_identification.diagnosis.rig_diagnosis`): name -> (unknowns, units).  Their values sit in
#: :class:`~rig_identification.model.linear_rig.RigParameters`: ``air_drag`` (quadratic damping,
#: linear and angular), ``pivot_friction`` (μ r of the ceiling pins, m), ``load_cell_delay`` and
#: ``exciter_delay`` (s, the stream's readings behind the IMU's),
#: ``imu_offset`` (the IMU's position, body m), ``gyro_scale`` (3, share) and ``gyro_bias_drift``
#: (3, rad/s²) and ``exciter_rotor`` (2: the unbalance, kg·m, whose weight turns with the force; the
#: rotor's mass, kg, whose inertial force the exciter's load cells read: the fitted mass, CG and
#: tensor are then the suspended body's, the rotor on its axis included,
#: :meth:`~.rig_fit.RigFit.body` the body's without it).
EXTENSIONS: dict[str, tuple[int, str]] = {
    "air_drag": (2, "N s^2/m^2, N m s^2/rad^2"),
    "pivot_friction": (1, "m (the ceiling pins' friction moment per newton of tension: mu r)"),
    "load_cell_delay": (1, "s"),
    "exciter_delay": (1, "s"),
    "imu_offset": (3, "m (the IMU's position, body frame)"),
    "gyro_scale": (3, "share (reading / rate - 1), IMU axes"),
    "gyro_bias_drift": (3, "rad/s^2, IMU axes"),
    "exciter_rotor": (2, "kg m (the unbalance: mass times eccentricity), kg (the rotor's mass)"),
}


@dataclass(frozen=True)
class Prior:
    """What is known before the fit: centre and σ of each unknown with a prior (σ = inf: none).

    mass, mass_std: kg.  cg: (3,) body m, cg_std: (3,) m (inf: the data alone).  stiffness: (N,)
    N/m, stiffness_log_std: (N,).  survey: the σ of every anchor coordinate, cable length and
    load-cell gain (:class:`~rig_identification.io.rig.Survey`).  geometry: (7 N,) m the surveyed
    ceiling anchors, body anchors (row-major) and cable lengths the geometry's prior is centred on
    (rig.yaml's; empty: centred on the fit's start).
    """

    mass: float
    mass_std: float
    cg: np.ndarray
    cg_std: np.ndarray
    stiffness: np.ndarray
    stiffness_log_std: np.ndarray
    survey: Survey = Survey()
    geometry: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def gain_std(self) -> float:
        """σ of each load cell's gain, share (the survey's)."""
        return self.survey.load_cell_gain

    @property
    def stiffness_given(self) -> np.ndarray:
        """(N,) bool: the cables whose stiffness rig.yaml gives (their prior's σ
        :data:`STIFFNESS_LOG_STD_GIVEN` or narrower); the others' is the default steel cable's."""
        return np.asarray(self.stiffness_log_std <= STIFFNESS_LOG_STD_GIVEN)

    @staticmethod
    def from_rig(rig: Rig, cg: ArrayLike | None = None, cg_std: ArrayLike | None = None) -> "Prior":
        """rig.yaml's mass and geometry (σ rig.yaml's ``survey``), CG (``cg``/``cg_std`` override; without a
        σ the CG is free), cable stiffness (the default steel cable's where rig.yaml has none)."""
        given = np.array([c.stiffness is not None for c in rig.cables])
        k = np.array([DEFAULT_STIFFNESS if c.stiffness is None else c.stiffness for c in rig.cables])
        c0 = rig.center_of_gravity if cg is None else np.asarray(cg, float)
        if c0 is None:
            raise RigFitError(f"{rig.source}: no centre of gravity to start from (rig.yaml body.center_of_gravity, "
                              "or the static test's: rig-identify cg)")
        return Prior(rig.mass, rig.survey.mass_std(rig.mass), np.asarray(c0, float),
                     np.full(3, np.inf) if cg_std is None else np.broadcast_to(np.asarray(cg_std, float), (3,)),
                     k, np.where(given, STIFFNESS_LOG_STD_GIVEN, STIFFNESS_LOG_STD_DEFAULT), rig.survey,
                     np.concatenate([rig.ceiling_anchors.ravel(), rig.body_anchors.ravel(), rig.cable_lengths]))


@dataclass(frozen=True)
class Layout:
    """Where each unknown sits in the parameter vector.

    n_cables: the rig's cables.  n_force: the exciter force's correction unknowns (0 or 2 K (1 + H)):
    K B-spline coefficients of its amplitude's relative change, then K of its phase's change,
    rad, over the fit's span (:meth:`Record.force_basis`), then for each of the record's H
    co-rotating harmonics K of its real and K of its imaginary part, shares of the amplitude
    (:meth:`Record.force_unknowns`).  n_segments: the span's segments
    (:data:`SEGMENT`), each after the first with its own initial state (12 unknowns, last).
    extensions: names of :data:`EXTENSIONS` whose unknowns the vector holds (after the geometry).
    """

    n_cables: int
    n_force: int = 0
    n_segments: int = 1
    extensions: tuple[str, ...] = ()

    @property
    def inertia(self) -> slice:
        return slice(0, 6)

    @property
    def cg(self) -> slice:
        return slice(6, 9)

    @property
    def mass(self) -> int:
        return 9

    @property
    def log_stiffness(self) -> slice:
        return slice(10, 10 + self.n_cables)

    @property
    def damping(self) -> int:
        return 10 + self.n_cables

    @property
    def gain(self) -> slice:
        return slice(11 + self.n_cables, 11 + 2 * self.n_cables)

    @property
    def body_damping(self) -> slice:
        return slice(11 + 2 * self.n_cables, 13 + 2 * self.n_cables)

    @property
    def initial(self) -> slice:
        return slice(13 + 2 * self.n_cables, 25 + 2 * self.n_cables)

    @property
    def geometry(self) -> slice:
        return slice(25 + 2 * self.n_cables, 25 + 9 * self.n_cables)

    @property
    def extension(self) -> slice:
        """Every extension's unknowns (:meth:`extension_of` each)."""
        start = 25 + 9 * self.n_cables
        return slice(start, start + sum(EXTENSIONS[e][0] for e in self.extensions))

    def extension_of(self, name: str) -> slice:
        """The unknowns of extension ``name`` (KeyError where the layout does not hold it)."""
        if name not in self.extensions:
            raise KeyError(name)
        start = 25 + 9 * self.n_cables + sum(EXTENSIONS[e][0] for e in self.extensions[:self.extensions.index(name)])
        return slice(start, start + EXTENSIONS[name][0])

    @property
    def force(self) -> slice:
        start = self.extension.stop
        return slice(start, start + self.n_force)

    @property
    def segments(self) -> slice:
        """The initial states (12 each) of the segments after the first, segment by segment."""
        start = self.force.stop
        return slice(start, start + 12 * (self.n_segments - 1))

    @property
    def size(self) -> int:
        return int(self.force.stop + 12 * (self.n_segments - 1))

    def state(self, k: int) -> slice:
        """Segment ``k``'s initial-state unknowns (12)."""
        if k == 0:
            return self.initial
        return slice(self.segments.start + 12 * (k - 1), self.segments.start + 12 * k)

    def for_span(self, samples: int, dt: float) -> "Layout":
        """This layout for a span of ``samples`` grid samples ``dt`` s apart: segments of at most
        :data:`SEGMENT` s."""
        n = max(1, int(np.ceil((samples - 1) * dt / SEGMENT - 1e-9)))
        return Layout(self.n_cables, self.n_force, n, self.extensions)

    def extended(self, names: tuple[str, ...]) -> "Layout":
        """This layout holding the extensions ``names`` (in :data:`EXTENSIONS` order) besides its own."""
        held = set(self.extensions) | set(names)
        return Layout(self.n_cables, self.n_force, self.n_segments, tuple(e for e in EXTENSIONS if e in held))


def labels(lay: Layout, cables: list[str]) -> list[str]:
    """A name for each unknown up to the extensions' end (``cables``: the cables' names)."""
    axes = "xyz"
    out = ["ixx", "iyy", "izz", "ixy", "ixz", "iyz"] + [f"cg {a}" for a in axes] + ["mass"]
    out += [f"stiffness {c}" for c in cables] + ["cable damping time"] + [f"load-cell gain {c}" for c in cables]
    out += ["viscous damping linear", "viscous damping angular"]
    out += [f"initial {q} {a}" for q in ("position", "rotation", "velocity", "angular velocity") for a in axes]
    out += [f"ceiling anchor {c} {a}" for c in cables for a in axes]
    out += [f"body anchor {c} {a}" for c in cables for a in axes] + [f"length {c}" for c in cables]
    for e in lay.extensions:
        n = EXTENSIONS[e][0]
        out += [e] if n == 1 else [f"{e} {i}" for i in range(n)]
    return out


def relayout(x: np.ndarray, lay: Layout) -> np.ndarray:
    """The unknowns ``x`` (of any segment count) in layout ``lay``: the segments' initial states
    kept where the count is the same, else zero (the model's own continuation)."""
    common = lay.segments.start
    if len(x) == lay.size:
        return x
    return np.concatenate([x[:common], np.zeros(lay.size - common)])


def _extension_values(p: RigParameters, name: str) -> np.ndarray:
    return np.atleast_1d(np.asarray(getattr(p, EXTENSION_FIELDS[name]), float))


def vector(p: RigParameters, initial: np.ndarray, lay: Layout) -> np.ndarray:
    """(lay.size,) the unknowns of ``p`` in the order of the module docstring: the first segment's
    initial state ``initial`` (12,), the force's correction and the later segments' states zero."""
    return np.concatenate([p.inertia, p.cg, [p.mass], np.log(p.stiffness), [p.damping_time], p.gain, p.body_damping,
                           initial, p.ceiling.ravel(), p.body.ravel(), p.length]
                          + [_extension_values(p, e) for e in lay.extensions] + [np.zeros(lay.size - lay.force.start)])


def positions(old: Layout, new: Layout) -> np.ndarray:
    """(old.size,) where each unknown of layout ``old`` sits in layout ``new`` (the same cables,
    force correction and segments; ``new`` holds every extension ``old`` does)."""
    out = np.arange(old.size)
    for e in old.extensions:
        out[old.extension_of(e)] = np.arange(new.extension_of(e).start, new.extension_of(e).stop)
    out[old.force] = np.arange(new.force.start, new.force.stop)
    out[old.segments] = np.arange(new.segments.start, new.segments.stop)
    return out


def in_layout(x: np.ndarray, old: Layout, new: Layout, p: RigParameters) -> np.ndarray:
    """The unknowns ``x`` (layout ``old``, parameters ``p``) in layout ``new`` (the same segments and
    force correction, other extensions): an extension ``old`` lacks takes its value in ``p``."""
    out = vector(p, x[old.initial], new)
    out[new.force] = x[old.force]
    out[new.segments] = x[old.segments]
    for e in old.extensions:
        if e in new.extensions:
            out[new.extension_of(e)] = x[old.extension_of(e)]
    return out


#: The :class:`~rig_identification.model.linear_rig.RigParameters` field each extension sets.
EXTENSION_FIELDS = {"air_drag": "air_drag", "pivot_friction": "pivot_friction", "load_cell_delay": "load_cell_delay",
                    "exciter_delay": "exciter_delay",
                    "imu_offset": "imu_position", "gyro_scale": "gyro_scale", "gyro_bias_drift": "gyro_drift",
                    "exciter_rotor": "rotor"}


def extension_fields(values: Mapping[str, ArrayLike]) -> dict[str, object]:
    """The :class:`~rig_identification.model.linear_rig.RigParameters` fields that the extensions'
    ``values`` (name -> its unknowns) set, for ``RigParameters.replace``."""
    out: dict[str, object] = {}
    for e, v in values.items():
        a = np.asarray(v, float)
        out[EXTENSION_FIELDS[e]] = float(a.reshape(-1)[0]) if EXTENSIONS[e][0] == 1 else a
    return out


def body_unknowns(x: np.ndarray, lay: Layout, exciter_position: ArrayLike) -> np.ndarray:
    """The unknowns ``x`` (layout ``lay``) with the body's tensor entries kg·m², CG m and mass kg in
    place of the suspended body's: where the layout holds the exciter rotor's mass m_r
    (``exciter_rotor``, 0 < m_r < the mass), the suspended body less a point mass m_r at
    ``exciter_position`` (3,) m on the rotor's axis
    (:func:`~rig_identification.model.parametrisation.without_point_mass`); ``x`` itself otherwise.
    The scale weighs the body, and rig.yaml and the static test describe it."""
    m_r = float(x[lay.extension_of("exciter_rotor")][1]) if "exciter_rotor" in lay.extensions else 0.0
    if not 0.0 < m_r < float(x[lay.mass]):
        return x
    mass, cg, theta = without_point_mass(float(x[lay.mass]), x[lay.cg], x[lay.inertia], m_r, exciter_position)
    out = x.copy()
    out[lay.inertia], out[lay.cg], out[lay.mass] = theta, cg, mass
    return out


def parameters_of(x: np.ndarray, like: RigParameters, lay: Layout) -> RigParameters:
    """``like`` with every parameter the unknowns ``x`` (layout ``lay``) hold: the inverse of
    :func:`vector` (the stiffness from its log)."""
    n = lay.n_cables
    g = x[lay.geometry]
    extra = extension_fields({e: x[lay.extension_of(e)] for e in lay.extensions})
    return like.replace(inertia=x[lay.inertia], cg=x[lay.cg], mass=float(x[lay.mass]),
                        stiffness=np.exp(x[lay.log_stiffness]), damping_time=float(x[lay.damping]),
                        gain=x[lay.gain], body_damping=x[lay.body_damping], ceiling=g[:3 * n].reshape(n, 3),
                        body=g[3 * n:6 * n].reshape(n, 3),
                        length=g[6 * n:], **extra)


def priors(prior: Prior, lay: Layout, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres and σ of the priors over the parameter vector (σ inf: none; the centre of an
    unknown without a prior is its start in ``x0``).  The geometry's centre is the survey's
    (:attr:`Prior.geometry`) in every stage, not the stage's start: centred on each stage's
    estimate, the survey's pull would weaken stage by stage."""
    centre = x0.copy()
    std = np.full(lay.size, np.inf)
    centre[lay.cg], std[lay.cg] = prior.cg, prior.cg_std
    centre[lay.mass], std[lay.mass] = prior.mass, prior.mass_std
    centre[lay.log_stiffness], std[lay.log_stiffness] = np.log(prior.stiffness), prior.stiffness_log_std
    centre[lay.gain], std[lay.gain] = 1.0, max(prior.gain_std, EXACT_GAIN_STD)
    centre[lay.force], std[lay.force] = 0.0, FORCE_CORRECTION_STD
    n = lay.n_cables
    if len(prior.geometry):
        centre[lay.geometry] = prior.geometry
    std[lay.geometry] = np.concatenate([np.full(6 * n, max(prior.survey.anchors, EXACT_STD)),
                                        np.full(n, max(prior.survey.lengths, EXACT_STD))])
    return centre, std


def unit_scale(x0: np.ndarray, lay: Layout, prior: Prior) -> np.ndarray:
    """Each unknown's unit: a change that moves the outputs by a small, comparable amount."""
    s = np.ones(lay.size)
    big = max(abs(x0[0]), abs(x0[3]), abs(x0[5]))
    s[lay.inertia] = 1e-3 * big
    s[lay.cg] = 1e-3
    s[lay.mass] = 1e-3 * prior.mass
    s[lay.log_stiffness] = 1e-2
    s[lay.damping] = 0.1 * max(abs(x0[lay.damping]), 1e-5)
    s[lay.gain] = 1e-3
    s[lay.body_damping] = (1e-3 * prior.mass, 1e-3 * big)      # ζ ≈ 1e-3 of a 1 rad/s mode
    s[lay.initial] = 1e-4
    s[lay.segments] = 1e-4
    s[lay.geometry] = 1e-4
    s[lay.force] = 1e-2
    # the extensions' units: quadratic drag as strong as the viscous unit at 0.02 m/s and rad/s (a
    # swing's typical speed); the pins' μ r whose friction, μ r m g / l on a 2 m cable, is that unit's
    units = {"air_drag": (5e-2 * prior.mass, 5e-2 * big), "pivot_friction": (4e-6,),
             "load_cell_delay": (1e-3,), "exciter_delay": (1e-3,), "imu_offset": (1e-3,) * 3, "gyro_scale": (1e-3,) * 3,
             "gyro_bias_drift": (1e-5,) * 3, "exciter_rotor": (1e-2, 1e-2)}
    for e in lay.extensions:
        s[lay.extension_of(e)] = units[e]
    return s
