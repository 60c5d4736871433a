"""Mass properties as a vehicle-dynamics test engineer reads them (the report's tensor section).

Frame: the body frame of rig.yaml (right-handed, as REP-103), SI units (kg, m, kg·m²).  The moments
are called roll, pitch and yaw only where rig.yaml's ``body.vehicle`` says where the vehicle's front
and top lie (:meth:`~rig_identification.io.export.Axes.meaning`: front +y makes Iyy the roll moment);
otherwise "moment about x".

Sign convention, stated once on the page: the *products of inertia* are
``Ixy = ∫ x y dm``, ``Ixz = ∫ x z dm``, ``Iyz = ∫ y z dm`` (SAE J670 / ISO 8855, as vehicle
dynamics uses them); the inertia tensor is ::

    J = [[ Ixx, −Ixy, −Ixz],
         [−Ixy,  Iyy, −Iyz],
         [−Ixz, −Iyz,  Izz]]

so its off-diagonal entries — what ``geometry_msgs/Inertia``, the rig model's result and
``report.json``'s ``result`` hold as ``ixy``, ``ixz``, ``iyz`` — are the negated products.
:func:`mass_properties_of` turns a result into the
page's numbers: the moments and products about the CG with their σ, the same about the body
frame's origin (parallel-axis theorem, J_O = J_G + m (|c|² I − c cᵀ), c the CG), the principal
moments (σ by the delta method, dλ = vᵀ dJ v) and axes, and the semi-axes of the equimomental
ellipsoid (the uniform solid ellipsoid of the same mass and tensor: a² = 5 (I₂ + I₃ − I₁) / 2m).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..io.export import BODY, MOMENTS, PRODUCTS_SIGN, SYMBOL, Axes, Expressed, axes_for
from ..io.export import VEHICLE_SIGN as SIGN
from ..io.vehicle import Vehicle
from ..io.verdict import KEYS
from ..model.parametrisation import from_tensor
from .html import MISSING, NOT_DETERMINED, Cell, esc, finite, num, table

ORDER = (0, 3, 5, 1, 2, 4)                           # display order: Ixx, Iyy, Izz, Ixy, Ixz, Iyz


def convention(axes: Axes = BODY) -> str:
    """The page's convention note: the frame (``axes``' label: rig.yaml's body axes, with where the
    vehicle lies when rig.yaml says), units, the products' sign."""
    where = ("" if axes.vehicle is not None else " The vehicle's orientation in them is not stated (rig.yaml "
             "body.vehicle): the moments are named by the body axes they are about.")
    return (f"Axes: {axes.label}; SI units.{where} Products of inertia as vehicle dynamics uses them (SAE J670 / "
            "ISO 8855): Ixy = ∫xy dm, Ixz = ∫xz dm, Iyz = ∫yz dm. The inertia tensor is J = [[Ixx, −Ixy, −Ixz], "
            "[−Ixy, Iyy, −Iyz], [−Ixz, −Iyz, Izz]]: its off-diagonal entries — what geometry_msgs/Inertia and "
            "report.json's \"result\" hold as ixy, ixz, iyz — are the negated products.")


@dataclass(frozen=True)
class MassProperties:
    """The report's mass properties of one result.

    mass kg; cg (3,) m, body axes (the point the tensor is about); values (6,) kg·m² the
    moments and products of inertia about the CG in :data:`~rig_identification.io.verdict.KEYS` order,
    products with the vehicle-dynamics sign (:data:`SIGN`); std (6,) and crb_std (6,) or None
    their σ (the result's, and the propagated sensor noise's); about_origin (6,) the same
    about the body frame's origin; tensor_cg and tensor_origin (3,3) the tensors (off-diagonals
    the negated products); principal (3,) kg·m² ascending, principal_std (3,) or None,
    principal_axes (3,3) unit columns in body axes (each with its largest component
    positive); semi_axes (3,) m of the equimomental ellipsoid along those axes;
    undetermined: entries (KEYS) the recording does not determine; nothing derived from
    them (principal moments, ellipsoid) is given then (``determined`` False).  axes: rig.yaml's body
    axes with the vehicle's orientation when known (the entries' words,
    :meth:`~rig_identification.io.export.Axes.meaning`)."""

    mass: float
    cg: np.ndarray
    values: np.ndarray
    std: np.ndarray
    crb_std: np.ndarray | None
    about_origin: np.ndarray
    tensor_cg: np.ndarray
    tensor_origin: np.ndarray
    principal: np.ndarray | None
    principal_std: np.ndarray | None
    principal_axes: np.ndarray | None
    semi_axes: np.ndarray | None
    undetermined: frozenset
    axes: Axes = BODY

    @property
    def determined(self) -> bool:
        """True when every entry is determined and finite (principal moments exist)."""
        return self.principal is not None


def parallel_axis(J: np.ndarray, mass: float, c: np.ndarray) -> np.ndarray:
    """(3,3) tensor about the body frame's origin from ``J`` (3,3) kg·m² about the CG at ``c``
    (3,) m, body axes, for ``mass`` kg: J + m (|c|² I − c cᵀ) (Huygens–Steiner)."""
    c = np.asarray(c, float)
    return J + mass * (float(c @ c) * np.eye(3) - np.outer(c, c))


def principal_std(axes: np.ndarray, cov: np.ndarray) -> np.ndarray | None:
    """σ (3,) kg·m² of the principal moments from the covariance (6,6) of the tensor entries
    (KEYS order): λᵢ = vᵢᵀ J vᵢ, so dλᵢ/dJ_ab = v_a v_b (twice for a ≠ b).  None when the
    covariance is not finite."""
    if not np.all(np.isfinite(cov)):
        return None
    out = []
    for v in axes.T:
        g = from_tensor(np.outer(v, v)) * np.array([1, 2, 2, 1, 2, 1])
        out.append(np.sqrt(max(float(g @ cov @ g), 0.0)))
    return np.array(out)


def equimomental_semi_axes(principal: np.ndarray, mass: float) -> np.ndarray:
    """Semi-axes (3,) m of the uniform solid ellipsoid of ``mass`` kg with the principal
    moments ``principal`` (3,) kg·m² (Iᵢ = m (a_j² + a_k²) / 5): a_i² = 5 (I_j + I_k − I_i) / 2m,
    clipped at 0 for a tensor at the edge of physical consistency."""
    total = float(np.sum(principal))
    return np.sqrt(np.clip(5.0 * (total - 2.0 * np.asarray(principal)) / (2.0 * mass), 0.0, None))


def mass_properties_of(mass: float, cg: np.ndarray, J: np.ndarray, std: np.ndarray, covariance: np.ndarray,
                       crb: np.ndarray | None, undetermined=(), vehicle: Vehicle | None = None) -> MassProperties:
    """:class:`MassProperties` of ``mass`` kg, ``cg`` (3,) m and ``J`` (3,3) kg·m² about it (body
    axes) with σ ``std`` (6,), ``covariance`` (6,6) and the bound ``crb`` (6,) or None (KEYS order);
    ``undetermined`` entries (and those not finite) left out."""
    J = np.asarray(J, float)
    gone = set(undetermined)
    theta = from_tensor(J)
    gone |= {k for k, v, s in zip(KEYS, theta, std) if not (finite(v) and finite(s))}
    c = np.asarray(cg, float)
    Jo = parallel_axis(J, mass, c)
    crb = None if crb is None else np.asarray(crb, float)
    principal = pstd = axes = semi = None
    if not gone and np.all(np.isfinite(J)):
        principal, axes = np.linalg.eigh(0.5 * (J + J.T))
        axes = axes * np.where(axes[np.argmax(np.abs(axes), axis=0), range(3)] < 0, -1.0, 1.0)
        pstd = principal_std(axes, np.asarray(covariance, float))
        semi = equimomental_semi_axes(principal, mass)
    return MassProperties(float(mass), c, SIGN * theta, np.asarray(std, float), crb,
                          SIGN * from_tensor(Jo), J, Jo, principal, pstd, axes, semi, frozenset(gone),
                          axes_for("body", vehicle))


def entry_cell(mp: MassProperties, k: str, x, fmt: str, main: bool = False) -> Cell | str:
    """One number of entry ``k``; when the recording does not determine it, "not determined"
    in its ``main`` cell (the value) and :data:`MISSING` in the others (σ, errors)."""
    if k in mp.undetermined:
        return Cell(NOT_DETERMINED, "undet") if main else MISSING
    return num(x, fmt)


def crb_shown(mp: MassProperties) -> bool:
    """The propagated-noise σ column is shown when it exists for every determined entry."""
    return mp.crb_std is not None and all(finite(mp.crb_std[i]) for i, k in enumerate(KEYS)
                                          if k not in mp.undetermined)


def moments_table(mp: MassProperties, errors: dict | None, crb_label: str = "σ propagated sensor noise") -> str:
    """The main table: moments and products of inertia about the CG (σ, σ %, the σ of the
    propagated noise when there is one — column ``crb_label`` —, the errors against truth.yaml
    when there is one) and about the body frame's origin; its caption names the convention
    (:data:`~rig_identification.io.export.PRODUCTS_SIGN`, as the console's main table)."""
    big = max((abs(mp.values[KEYS.index(k)]) for k in MOMENTS if k not in mp.undetermined
               and finite(mp.values[KEYS.index(k)])), default=float("nan"))
    head = ["quantity", "about the CG kg·m²", "σ kg·m²"] + ([f"{crb_label} kg·m²"] if crb_shown(mp)
                                                            else []) + ["σ %"]
    if errors:
        head += ["truth kg·m²", "error kg·m²", "error %", "error / σ"]
    head += ["about the body-frame origin kg·m²"]
    crb = mp.crb_std if crb_shown(mp) else None
    rows = []
    for i in ORDER:
        k = KEYS[i]
        ref = abs(mp.values[i]) if k in MOMENTS else big
        row = [f"{SYMBOL[k]} ({mp.axes.meaning(k)})", entry_cell(mp, k, mp.values[i], ".2f", main=True),
               entry_cell(mp, k, mp.std[i], ".3g")]
        if crb is not None:
            row.append(entry_cell(mp, k, crb[i], ".3g"))
        row.append(entry_cell(mp, k, 100 * mp.std[i] / ref if finite(ref) and ref > 0 else None, ".3g"))
        if errors:
            e = errors[k]
            row += [num(e["truth"], ".2f"), entry_cell(mp, k, e["error"], "+.3g"),
                    entry_cell(mp, k, e["error_percent"], "+.3f"), entry_cell(mp, k, e["error_sigma"], "+.2f")]
        row.append(entry_cell(mp, k, mp.about_origin[i], ".2f", main=True))
        rows.append(row)
    return table(head, rows, cls="tensor", ident="tensor-table",
                 caption=f"moments and products of inertia, kg·m² ({PRODUCTS_SIGN})")


def matrix_html(M: np.ndarray, gone: frozenset, caption: str) -> str:
    """A 3×3 tensor as a table with body-axis labels; undetermined entries as text."""
    rows = []
    for a in range(3):
        r: list[Cell | str] = [Cell("xyz"[a], "text")]
        for b in range(3):
            k = KEYS[[(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)].index((min(a, b), max(a, b)))]
            r.append(Cell(NOT_DETERMINED, "undet") if k in gone else num(M[a, b], ".2f"))
        rows.append(r)
    return table(["", "x", "y", "z"], rows, cls="matrix", caption=caption)


def matrices_html(mp: MassProperties) -> str:
    """The tensor as a matrix about the CG and about the body frame's origin, side by side."""
    same = bool(np.allclose(mp.cg, 0.0))
    return ('<div style="display:flex;gap:2em;flex-wrap:wrap">'
            + matrix_html(mp.tensor_cg, mp.undetermined,
                          "inertia tensor J about the CG, kg·m² (off-diagonal: −products)")
            + matrix_html(mp.tensor_origin, mp.undetermined,
                          "inertia tensor J about the body-frame origin, kg·m² (off-diagonal: −products)") + "</div>"
            + '<p class="note">About the origin: parallel-axis theorem, J_O = J + m (|c|² I − c cᵀ), with the mass '
            + f"{mp.mass:g} kg and the CG c = [{', '.join(num(x, '.4f') for x in mp.cg)}] m; σ as about the CG "
            "(the parallel-axis term's own uncertainty, from the mass's and the CG's, left out)."
            + (" The CG is at the origin: the two are the same." if same else "")
            + "</p>")


def principal_html(mp: MassProperties) -> str:
    """Principal moments (σ), axes (direction cosines in body axes, the nearest body axis
    and the angle to it) and the equimomental ellipsoid's semi-axes."""
    if not mp.determined:
        return (f'<p>Principal moments and axes: {NOT_DETERMINED} (they need every entry of the tensor, and the '
                "recording does not determine "
                + esc(", ".join(SYMBOL[k] for k in KEYS if k in mp.undetermined)) + ").</p>")
    # set together with principal (mass_properties_of)
    assert mp.principal is not None and mp.principal_axes is not None and mp.semi_axes is not None
    rows = []
    for i in range(3):
        v = mp.principal_axes[:, i]
        near = int(np.argmax(np.abs(v)))
        ang = np.degrees(np.arccos(min(1.0, abs(float(v[near])))))
        rows.append([f"I{i + 1}", num(mp.principal[i], ".2f"),
                     num(None if mp.principal_std is None else mp.principal_std[i], ".3g"),
                     ", ".join(num(x, "+.4f") for x in v), f"body {'xyz'[near]}" + (
                         "" if mp.axes.vehicle is None else f" ({mp.axes.vehicle.motion(near)} axis)"),
                     num(ang, ".2f"),
                     num(mp.semi_axes[i], ".3f")])
    return table(["principal moment", "kg·m²", "σ kg·m²", "axis (x, y, z components, body axes)",
                  "nearest body axis", "angle to it, deg", "equimomental ellipsoid semi-axis m"], rows,
                 ident="principal-table")


def to_json(mp: MassProperties, errors: dict | None) -> dict:
    """The section's numbers for report.json (the page's: products with the vehicle-dynamics
    sign; undetermined entries and everything derived from them null)."""
    def entries(a):
        return None if a is None else {SYMBOL[k]: (None if k in mp.undetermined or not finite(x) else float(x))
                                       for k, x in zip(KEYS, a)}

    def matrix(M):
        return [[None if not finite(x) else float(x) for x in r] for r in M] if mp.determined else None
    out = {"convention": convention(mp.axes), "vehicle": None if mp.axes.vehicle is None else
           mp.axes.vehicle.to_dict(), "mass_kg": mp.mass, "center_of_gravity_m": [float(x) for x in mp.cg],
           "about_cg": entries(mp.values), "std": entries(mp.std), "crb_std": entries(mp.crb_std),
           "about_origin": entries(mp.about_origin), "tensor_about_cg": matrix(mp.tensor_cg),
           "tensor_about_origin": matrix(mp.tensor_origin),
           "principal_moments": None if mp.principal is None else [float(x) for x in mp.principal],
           "principal_moments_std": None if mp.principal_std is None else [float(x) for x in mp.principal_std],
           # principal_axes and semi_axes: set together with principal (None unless determined)
           "principal_axes_columns": None if mp.principal_axes is None else mp.principal_axes.T.tolist(),
           "equimomental_semi_axes_m": None if mp.semi_axes is None else [float(x) for x in mp.semi_axes],
           "undetermined": [SYMBOL[k] for k in KEYS if k in mp.undetermined]}
    if errors:
        out["errors_against_truth"] = {
            SYMBOL[k]: {f: (None if not finite(v) or (f != "truth" and k in mp.undetermined) else float(v))
                        for f, v in e.items()} for k, e in errors.items()}
    return out


__all__ = ["SIGN", "ORDER", "SYMBOL", "convention", "MassProperties", "mass_properties_of",
           "parallel_axis", "principal_std", "equimomental_semi_axes", "moments_table", "matrices_html",
           "principal_html", "to_json"]


def axes_html(ex: Expressed) -> str:
    """The mass properties in other axes than rig.yaml's body frame (rig.yaml ``output_axes``,
    ``rig-identify inertia --axes``): the frame in words, the CG, then per entry the tensor entry
    about the CG, its σ, the moment or product of inertia with the vehicle-dynamics sign and
    the entry about the body frame's origin; the principal moments.  Each entry in these axes is
    ± one entry of the body axes' (:func:`~rig_identification.io.export.express`), its σ that entry's."""
    c = ", ".join(num(x, ".4f") for x in ex.cg)
    rows = []
    for i in ORDER:
        k = KEYS[i]
        v, sg, vo = ex.entry(k), ex.sigma(k), ex.entry(k, "origin")
        if v is None:
            rows.append([SYMBOL[k], ex.axes.meaning(k), NOT_DETERMINED, MISSING, NOT_DETERMINED, MISSING])
            continue
        rows.append([SYMBOL[k], ex.axes.meaning(k), num(v, ".2f"), num(sg, ".3g"), num(SIGN[i] * v + 0.0, ".2f"),
                     num(vo, ".2f")])
    pm = ("principal moments " + ", ".join(num(x, ".2f") for x in ex.principal) + " kg·m² (the same in any axes)"
          if ex.principal is not None else "principal moments: not determined")
    return (f'<p class="note">{esc(ex.axes.label)}; SI units. Centre of gravity in these axes ({c}) m.</p>'
            + table(["entry", "meaning", "tensor entry about the CG kg·m²", "σ kg·m²",
                     "moment / product of inertia (vehicle sign) kg·m²", "tensor entry about the origin kg·m²"], rows)
            + f'<p class="note">{esc(pm)}.</p>')



