"""An identified inertia tensor as a lab uses it: conventions, derived quantities, exports.

Conventions (every output states them):

* Frame: the body frame of rig.yaml (right-handed, as REP-103; origin at the reference point
  rig.yaml's geometry is given from).  Where the vehicle lies in it is rig.yaml's
  ``body.vehicle`` (:mod:`~rig_identification.io.vehicle`): with it, ``--axes sae`` and ``--axes
  iso8855`` turn every printed and exported quantity to the SAE J670 (x forward, y right, z down)
  or ISO 8855 (x forward, y left, z up) vehicle axes, J' = R J Rᵀ, and the moments are called
  roll, pitch and yaw; without it neither (:func:`axes_for`, :class:`Axes`).
* Units: SI — kg, m, kg·m².
* The tensor ``J`` about the centre of gravity (CG) has the entries ``ixx … izz`` of
  ``geometry_msgs/Inertia``, URDF's ``<inertia>``, truth.yaml and the JSON: its
  off-diagonal entries are the *negated* products of inertia.  Vehicle dynamics (SAE J670,
  ISO 8855) uses the products themselves: ``Ixy = ∫ x y dm = −ixy``, ``Ixz = −ixz``,
  ``Iyz = −iyz``; the moments are the diagonal entries (``Ixx = ixx``).

Derived quantities (:class:`Expressed`): the tensor about the body frame's origin (parallel-axis
theorem, ``J_O = J + m (|c|² I − c cᵀ)``, c the CG), the principal moments (ascending) and axes
(eigen-decomposition; each axis with its largest component positive).  Entries the validation
did not determine stay undetermined in everything derived from them: ``None`` in JSON and YAML,
"not determined" in text; the principal moments need every entry.

Exports: :func:`urdf_inertial` (a URDF ``<inertial>`` element) and :func:`yaml_text` (the
YAML file of ``rig-identify inertia --yaml``).  Pure numpy; no ROS.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np
import yaml
from numpy.typing import ArrayLike

from .vehicle import MOTIONS, VEHICLE_AXES, AxesError, Vehicle, vehicle_rotation
from .verdict import KEYS

EXPORT_SCHEMA = "rig_identification.inertia_export"     # the YAML file of rig-identify inertia --yaml
EXPORT_SCHEMA_VERSION = 1

ORDER = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
"""The entry order of every table and every option that takes a tensor (the vehicle-dynamics
habit: the moments, then the products).  The JSON's dictionaries are keyed by name."""
MOMENTS = ("ixx", "iyy", "izz")
PRODUCTS = {"ixy": "Ixy", "ixz": "Ixz", "iyz": "Iyz"}   # tensor entry -> vehicle-dynamics product (its negation)
VEHICLE_SIGN = np.array([1.0, -1.0, -1.0, 1.0, -1.0, 1.0])   # KEYS order: tensor entry -> moment / product
SYMBOL = {"ixx": "Ixx", "iyy": "Iyy", "izz": "Izz", "ixy": "Ixy", "ixz": "Ixz", "iyz": "Iyz"}   # an entry in text
ENTRY_NAMES = {"ixx": "moment Ixx", "iyy": "moment Iyy", "izz": "moment Izz",
               "ixy": "product Ixy", "ixz": "product Ixz", "iyz": "product Iyz"}
"""An entry in words where the axes' vehicle is not at hand (the weakly determined directions)."""
INDEX = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2), "izz": (2, 2)}
NOT_DETERMINED = "not determined"
#: The convention of every main table of the tensor (console and report), as their captions name it.
PRODUCTS_SIGN = "products with the vehicle-dynamics sign, SAE J670 / ISO 8855: Ixy = ∫xy dm = −ixy"
#: The caption of the console's main table.
TABLE_CAPTION = f"moments and products of inertia about the CG, kg·m² ({PRODUCTS_SIGN}):"


def tensor_from_option(values: Iterable[float]) -> np.ndarray:
    """(3,3) tensor from an option's six numbers in :data:`ORDER` (ixx iyy izz ixy ixz iyz)."""
    d = dict(zip(ORDER, (float(v) for v in values)))
    J = np.empty((3, 3))
    for k, (i, j) in INDEX.items():
        J[i, j] = J[j, i] = d[k]
    return J


def entries_from_option(values: Iterable[float]) -> np.ndarray:
    """(6,) entries in :data:`~rig_identification.io.verdict.KEYS` order (ixx ixy ixz iyy iyz izz) from an option's
    six numbers in :data:`ORDER`."""
    d = dict(zip(ORDER, (float(v) for v in values)))
    return np.array([d[k] for k in KEYS])


AXES = {"body": "rig.yaml's body frame",
        **{name: f"{std} vehicle axes ({words})" for name, (std, words) in VEHICLE_AXES.items()}}
"""The axes outputs can be given in (``--axes``, rig.yaml ``output_axes``): name -> words.
:func:`axes_for` makes them; the vehicle axes need rig.yaml's ``body.vehicle``."""
JSON_KEYS = {"sae": "sae_j670", "iso8855": "iso_8855"}
"""The block of ``rig-identify inertia --json`` that holds the mass properties in vehicle axes."""
BODY_LABEL = "the body frame of rig.yaml (right-handed, as REP-103)"


@dataclass(frozen=True)
class Axes:
    """A set of axes the outputs can be given in (:func:`axes_for`): ``name`` (a key of
    :data:`AXES`), ``label`` (text for the output), ``rotation`` (3,3) proper rotation: vectors
    in these axes = rotation @ vectors in rig.yaml's body axes, the tensor rotation @ J @
    rotationᵀ; ``vehicle``: where the vehicle's front and top lie in these axes (None: unknown;
    then no entry is called roll, pitch or yaw)."""

    name: str
    label: str
    rotation: np.ndarray
    vehicle: Vehicle | None = None

    @property
    def entry_map(self) -> np.ndarray:
        """(6,6) T: the tensor entries in these axes = T @ those in the body axes (both in
        :data:`~rig_identification.io.verdict.KEYS` order), from J' = R J Rᵀ.  A covariance C of
        the entries becomes T C Tᵀ."""
        R = self.rotation
        T = np.zeros((6, 6))
        for r, k in enumerate(KEYS):
            i, j = INDEX[k]
            for c, m in enumerate(KEYS):
                a, b = INDEX[m]
                T[r, c] = R[i, a] * R[j, b] + (R[i, b] * R[j, a] if a != b else 0.0)
        return T

    def motion(self, k: str) -> str | None:
        """The vehicle's rotation entry ``k`` (KEYS name) belongs to: ``roll``, ``pitch``,
        ``yaw`` for a moment, ``roll–yaw`` etc. for a product; None when the vehicle is unknown."""
        if self.vehicle is None:
            return None
        names = sorted({self.vehicle.motion(a) for a in INDEX[k]}, key=MOTIONS.index)
        return "–".join(names)

    def meaning(self, k: str) -> str:
        """Entry ``k`` (KEYS name) in words: ``roll moment`` or ``moment about x``; ``product,
        y–z (roll–yaw)`` or ``product, y–z``."""
        i, j = INDEX[k]
        motion = self.motion(k)
        if i == j:
            return f"moment about {'xyz'[i]}" if motion is None else f"{motion} moment"
        return f"product, {'xyz'[i]}–{'xyz'[j]}" + ("" if motion is None else f" ({motion})")

    @property
    def json_key(self) -> str:
        """The JSON block these axes' mass properties go in (:data:`JSON_KEYS`; ``body``: the JSON itself)."""
        return JSON_KEYS.get(self.name, self.name)


def axes_for(name: str, vehicle: Vehicle | None = None) -> Axes:
    """The :class:`Axes` ``name`` (a key of :data:`AXES`) for a body whose vehicle lies as
    ``vehicle`` in rig.yaml's body frame (rig.yaml ``body.vehicle``; None: not stated).

    ``body``: rig.yaml's axes, labelled with the vehicle's orientation when known.  ``sae``,
    ``iso8855``: the vehicle axes (:func:`~rig_identification.io.vehicle.vehicle_rotation`).
    Raises :class:`~rig_identification.io.vehicle.AxesError` for vehicle axes without
    ``vehicle`` (naming rig.yaml's ``body.vehicle``) and for an unknown name."""
    if name == "body":
        label = BODY_LABEL if vehicle is None else f"{BODY_LABEL[:-1]}; {vehicle.text()})"
        return Axes("body", label, np.eye(3), vehicle)
    if name not in VEHICLE_AXES:
        raise AxesError(f"no axes {name!r} (known: {', '.join(AXES)})")
    std, words = VEHICLE_AXES[name]
    if vehicle is None:
        raise AxesError(f"{std} axes ({words}) need where the vehicle's front and top lie in the body frame, and "
                        "rig.yaml does not say: give its body.vehicle (e.g. body: {vehicle: {front: +x, top: +z}}) "
                        "or use the body axes")
    R = vehicle_rotation(vehicle, name)
    own = Vehicle("+x", "-z" if name == "sae" else "+z")
    return Axes(name, f"{std} vehicle axes ({words}), turned from rig.yaml's body frame ({vehicle.text()})", R,
                own)


BODY = axes_for("body")
"""rig.yaml's body axes, the vehicle's orientation not at hand."""


def convention_lines(axes: Axes) -> list[str]:
    """The lines every text output starts its numbers with: frame, units, sign convention."""
    return [f"frame: {axes.label}; origin at rig.yaml's body-frame origin; SI units (kg, m, kg·m²)",
            "tables: moments and products of inertia about the CG, in these axes, products with the vehicle-dynamics "
            "sign (SAE J670 / ISO 8855: Ixy = ∫xy dm); the tensor's off-diagonal entries ixy, ixz, iyz "
            "(geometry_msgs/Inertia, URDF, truth.yaml, the JSON) are the NEGATED products: ixy = −Ixy"]


def parallel_axis(J: np.ndarray, mass: float, c: np.ndarray) -> np.ndarray:
    """(3,3) tensor about the body frame's origin from ``J`` (3,3) kg·m² about the CG at ``c``
    (3,) m, the same axes, for ``mass`` kg: J + m (|c|² I − c cᵀ) (Huygens–Steiner)."""
    c = np.asarray(c, float)
    return np.asarray(J, float) + mass * (float(c @ c) * np.eye(3) - np.outer(c, c))


def principal(J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) kg·m², ascending, and axes (3,3): unit columns in the tensor's
    axes, each with its largest component positive (numpy ``eigh`` of the symmetric part)."""
    moments, axes = np.linalg.eigh(0.5 * (J + J.T))
    axes = axes * np.where(axes[np.argmax(np.abs(axes), axis=0), range(3)] < 0, -1.0, 1.0)
    return moments, axes


def finite_or_none(x: float | np.floating | None) -> float | None:
    """A float for JSON/YAML: None when ``x`` is None or not finite (never NaN)."""
    return None if x is None or not np.isfinite(x) else float(x)


@dataclass(frozen=True)
class Expressed:
    """An identified result's mass properties in one set of :class:`Axes`.

    mass kg; cg (3,) m, from the body frame's origin; tensor_cg and tensor_origin (3,3)
    kg·m² about the CG and about the body frame's origin; std (6,) kg·m² σ of the entries
    (:data:`~rig_identification.io.verdict.KEYS` order); undetermined: the entries (KEYS) the recording does not
    determine, or that are not finite; principal (3,) kg·m² ascending and principal_axes
    (3,3) unit columns, None unless every entry is determined."""

    axes: Axes
    mass: float
    cg: np.ndarray
    tensor_cg: np.ndarray
    tensor_origin: np.ndarray
    std: np.ndarray
    undetermined: frozenset[str]
    principal: np.ndarray | None
    principal_axes: np.ndarray | None

    def entry(self, k: str, about: str = "cg") -> float | None:
        """Tensor entry ``k`` (KEYS name) about the CG or the ``origin``; None when undetermined."""
        if k in self.undetermined:
            return None
        i, j = INDEX[k]
        v = finite_or_none((self.tensor_cg if about == "cg" else self.tensor_origin)[i, j])
        return None if v is None else v + 0.0     # + 0.0: a sign flip of 0 prints no "-0.00"

    def entries(self, about: str = "cg") -> dict[str, float | None]:
        """{ixx … iyz: value or None} in :data:`ORDER`."""
        return {k: self.entry(k, about) for k in ORDER}

    def sigma(self, k: str) -> float | None:
        """σ of entry ``k`` (the same for the product, whose sign alone differs); None when undetermined."""
        return None if k in self.undetermined else finite_or_none(self.std[KEYS.index(k)])

    def products(self, about: str = "cg") -> dict[str, float | None]:
        """Products of inertia with the vehicle-dynamics sign: {"Ixy": −ixy, "Ixz", "Iyz"} (None
        when undetermined)."""
        out: dict[str, float | None] = {}
        for k, name in PRODUCTS.items():
            v = self.entry(k, about)
            out[name] = None if v is None else -v + 0.0    # + 0.0: no negative zero
        return out

    def principal_dict(self) -> dict[str, Any] | None:
        """{"moments": [3] ascending, "axes": [[x, y, z] per moment]} or None (not determined)."""
        if self.principal is None:
            return None
        assert self.principal_axes is not None   # set together with principal
        return {"moments": [float(x) for x in self.principal],
                "axes": [[float(x) for x in self.principal_axes[:, i]] for i in range(3)]}


def express(mass: float, cg: ArrayLike, J: ArrayLike, std: ArrayLike, undetermined: Iterable[str] = (),
            axes: str | Axes = "body") -> Expressed:
    """The mass properties (``mass`` kg, ``cg`` (3,) m and ``J`` (3,3) kg·m² about it in rig.yaml's
    body axes, ``std`` (6,) KEYS order, ``undetermined`` entries) in ``axes`` (an :class:`Axes`
    of :func:`axes_for`, or a name, made without the vehicle): see :class:`Expressed`.

    The one way to other axes: c' = R c, J' = R J Rᵀ, the entries by :attr:`Axes.entry_map` T,
    σ'² = diag(T C Tᵀ) — exact from σ alone, as every T here is a signed permutation (each
    entry of J' is ± one entry of J, so its σ is that entry's).  An entry of J' is undetermined
    where an entry it is made of is (undetermined or not finite)."""
    ax = axes_for(axes) if isinstance(axes, str) else axes
    R = ax.rotation
    T = ax.entry_map
    J = np.asarray(J, float)
    std = np.asarray(std, float)
    theta = np.array([J[INDEX[k]] for k in KEYS])
    bad = np.array([k in set(undetermined) or not np.isfinite(v) for k, v in zip(KEYS, theta)])
    uses = np.abs(T) > 1e-12
    gone_here = uses[:, bad].any(axis=1)
    turned = T @ np.where(bad, 0.0, theta)
    turned[gone_here] = np.nan
    Jr = np.empty((3, 3))
    for k, v in zip(KEYS, turned):
        i, j = INDEX[k]
        Jr[i, j] = Jr[j, i] = v
    s2 = np.where(uses, T ** 2, 0.0) * np.where(uses, std[None, :] ** 2, 0.0)
    std_here = np.sqrt(s2.sum(axis=1))
    std_here[uses[:, ~np.isfinite(std)].any(axis=1)] = np.nan
    gone = {k for k, g in zip(KEYS, gone_here) if g}
    c = R @ np.asarray(cg, float)
    Jo = parallel_axis(Jr, mass, c)
    pm = pa = None
    if not gone:
        pm, pa = principal(Jr)
    return Expressed(ax, float(mass), c, Jr, Jo, std_here, frozenset(gone), pm, pa)


def urdf_inertial(ex: Expressed, fmt: str = ".7g") -> str:
    """A URDF ``<inertial>`` element for a link whose frame is rig.yaml's body frame (URDF frames
    are REP-103: pass an :class:`Expressed` in the ``body`` axes): origin at the CG, axes parallel
    to the link's, mass, and the tensor's entries — URDF's ``ixy`` etc. are the matrix's
    off-diagonal entries (the negated products), as geometry_msgs/Inertia.  When the recording
    does not determine some entry, an XML comment saying so instead (no numbers)."""
    if ex.axes.name != "body":
        raise ValueError("a URDF <inertial> is in the link's (REP-103) axes: express it in the 'body' axes")
    if ex.undetermined:
        gone = ", ".join(k for k in ORDER if k in ex.undetermined)
        return f"<!-- no URDF <inertial>: the recording does not determine {gone} -->"
    xyz = " ".join(format(float(x), fmt) for x in ex.cg)
    ent = " ".join(f"{k}={quoteattr(format(ex.entry(k), fmt))}" for k in KEYS)
    return (f"<inertial>\n  <origin xyz=\"{xyz}\" rpy=\"0 0 0\"/>\n  <mass value=\"{format(ex.mass, fmt)}\"/>\n"
            f"  <inertia {ent}/>\n</inertial>")


def axes_block(ex: Expressed) -> dict[str, Any]:
    """The mass properties of ``ex`` for a JSON block in other axes (``"sae_j670"`` of
    ``rig-identify inertia --json --axes sae``, ``"iso_8855"`` of ``--axes iso8855``:
    :attr:`Axes.json_key`): the same fields as the body-axes ones."""
    pm = ex.principal_dict()
    return {"axes": ex.axes.label, "center_of_gravity": [float(x) for x in ex.cg],
            "inertia_about_cg": {k: ex.entry(k) for k in KEYS}, "inertia_std": {k: ex.sigma(k) for k in KEYS},
            "products_of_inertia": ex.products(), "inertia_about_origin": {k: ex.entry(k, "origin") for k in KEYS},
            "principal_moments": None if pm is None else pm["moments"],
            "principal_axes": None if pm is None else pm["axes"]}


def export_dict(ex: Expressed, *, verdict: str | None, summary: str | None, std_kind: str, sources: list[str],
                window: dict[str, Any] | None, created: str, version: str) -> dict[str, Any]:
    """The content of the YAML export (:func:`yaml_text`): schema, conventions, the mass
    properties in ``ex``'s axes (tensor about the CG and the origin, σ, products with the
    vehicle-dynamics sign, principal moments and axes; undetermined entries null), the verdict,
    the recordings, the window, when and with which version."""
    return {
        "schema": EXPORT_SCHEMA, "schema_version": EXPORT_SCHEMA_VERSION,
        "created": created, "tool": f"rig_identification {version}",
        "axes": ex.axes.name, "frame": ex.axes.label,
        "convention": "tensor entries ixx..izz as geometry_msgs/Inertia and URDF: off-diagonal entries are the "
                      "negated products of inertia; products_of_inertia carry the vehicle-dynamics sign "
                      "(Ixy = integral of x*y dm = -ixy)",
        "units": {"mass": "kg", "center_of_gravity": "m", "inertia": "kg*m^2"},
        "verdict": verdict, "verdict_summary": summary, "sources": list(sources), "window_s": window,
        "mass": ex.mass, "center_of_gravity": [float(x) for x in ex.cg],
        "inertia_about_cg": ex.entries("cg"), "inertia_std": {k: ex.sigma(k) for k in ORDER}, "std_is": std_kind,
        "products_of_inertia_about_cg": ex.products("cg"),
        "inertia_about_origin": ex.entries("origin"), "principal": ex.principal_dict(),
        "undetermined": [k for k in ORDER if k in ex.undetermined],
    }


def yaml_text(content: dict[str, Any]) -> str:
    """YAML of :func:`export_dict`'s content, with a comment line naming the schema."""
    text: str = (f"# {content['schema']} v{content['schema_version']}: mass properties identified by rig-identify "
                 "inertia\n" + yaml.safe_dump(content, sort_keys=False, allow_unicode=True, default_flow_style=None))
    return text


__all__ = ["AXES", "Axes", "AxesError", "BODY", "BODY_LABEL", "ENTRY_NAMES", "EXPORT_SCHEMA",
           "EXPORT_SCHEMA_VERSION", "Expressed", "JSON_KEYS",
           "NOT_DETERMINED", "ORDER", "PRODUCTS", "PRODUCTS_SIGN", "SYMBOL", "TABLE_CAPTION",
           "VEHICLE_SIGN", "axes_block", "axes_for", "convention_lines", "entries_from_option", "export_dict",
           "express", "finite_or_none", "parallel_axis", "principal", "tensor_from_option", "urdf_inertial",
           "yaml_text"]
