"""Text blocks of the ``rig-identify`` printouts: the tensor table, the products, the principal
axes, the tensor about the origin.

Undetermined entries print as "not determined", never as a number or ``nan``
(:data:`~rig_identification.io.export.NOT_DETERMINED`).  Entry order everywhere:
:data:`~rig_identification.io.export.ORDER` (ixx iyy izz
ixy ixz iyz).
"""
from __future__ import annotations

import numpy as np

from ..io.export import (
    MOMENTS,
    NOT_DETERMINED,
    ORDER,
    PRODUCTS,
    TABLE_CAPTION,
    VEHICLE_SIGN,
    Expressed,
)
from ..io.verdict import KEYS


def fmt(x, spec: str = ".2f", width: int = 0) -> str:
    """A number, or "not determined" for None / not finite; right-aligned to ``width``."""
    text = NOT_DETERMINED if x is None or not np.isfinite(x) else format(float(x), spec)
    return f"{text:>{width}s}"


def tensor_table(ex: Expressed, truth: dict | None = None) -> list[str]:
    """The main table: the moments and products of inertia about the CG (products with the
    vehicle-dynamics sign, :data:`~rig_identification.io.export.VEHICLE_SIGN`), one a line in
    :data:`ORDER` (Ixx Iyy Izz Ixy Ixz Iyz): value and σ; with ``truth`` ({KEYS: {"truth",
    "error_percent", "error_sigma"}}, tensor entries in ``ex``'s axes) its columns too, signed
    as the row.  Where the axes know the vehicle's orientation (rig.yaml ``body.vehicle``), each row
    ends with its vehicle word ("roll moment", "roll–yaw product": :meth:`~rig_identification.io.export.Axes.motion`);
    otherwise no row says roll, pitch or yaw.  Its caption is :data:`TABLE_CAPTION`."""
    head = f"{'':6s} {'kg·m²':>14s} {'σ':>9s}"
    if truth:
        head += f" {'truth':>10s} {'error':>9s} {'err/σ':>7s}"
    lines = [head]
    for k in ORDER:
        sign = VEHICLE_SIGN[KEYS.index(k)]
        name = "I" + k[1:]
        v = ex.entry(k)
        if v is None:
            line = f"{name:6s} {NOT_DETERMINED:>14s} {'':>9s}"
            if truth:
                line += f" {sign * truth[k]['truth'] + 0.0:10.2f}"
        else:
            line = f"{name:6s} {sign * v + 0.0:14.2f} {fmt(ex.sigma(k), '.3g', 9)}"
            if truth:
                c = truth[k]
                line += (f" {sign * c['truth'] + 0.0:10.2f} {sign * c['error_percent'] + 0.0:+8.3f}% "
                         f"{sign * c['error_sigma'] + 0.0:+7.2f}")
        motion = ex.axes.motion(k)
        if motion is not None:
            line += f"  {motion} {'moment' if k in MOMENTS else 'product'}"
        lines.append(line)
    if truth:
        lines.append("(error: % of the entry for moments, % of the largest moment for products)")
    return lines


def tensor_entries_line(ex: Expressed, crb=None) -> str:
    """The tensor's off-diagonal entries about the CG (the negated products: what
    geometry_msgs/Inertia, URDF, truth.yaml and the JSON hold), kg·m², each with its σ and,
    with ``crb`` ((6,) kg·m², :data:`~rig_identification.io.verdict.KEYS` order: the run's
    Cramér–Rao bound), σ/CRB."""
    parts = []
    for k in PRODUCTS:
        v = ex.entry(k)
        if v is None:
            parts.append(f"{k} {NOT_DETERMINED}")
            continue
        ratio = "" if crb is None else f" (σ/CRB {fmt(_ratio(ex.sigma(k), crb[KEYS.index(k)]))})"
        parts.append(f"{k} {v:+.2f} ± {fmt(ex.sigma(k), '.3g')}{ratio}")
    return ("the inertia tensor's off-diagonal entries about the CG (= −products; geometry_msgs/Inertia, URDF, "
            "the JSON): " + ", ".join(parts) + " kg·m²")


def _ratio(a: float | None, b: float) -> float | None:
    """a / b, or None when it is not a finite number."""
    return None if a is None or not b > 0 else a / b


def principal_lines(ex: Expressed) -> list[str]:
    """Principal moments (ascending) and axes (direction cosines, nearest axis and angle to it)."""
    if ex.principal is None:
        gone = ", ".join(k for k in ORDER if k in ex.undetermined)
        return [f"principal moments and axes: {NOT_DETERMINED} (they need every entry; not determined: {gone})"]
    assert ex.principal_axes is not None   # set together with principal
    lines = ["principal moments (kg·m², ascending) and axes (unit vectors x, y, z in these axes):"]
    for i in range(3):
        v = ex.principal_axes[:, i]
        near = int(np.argmax(np.abs(v)))
        ang = float(np.degrees(np.arccos(min(1.0, abs(float(v[near]))))))
        about = "" if ex.axes.vehicle is None else f" ({ex.axes.vehicle.motion(near)} axis)"
        lines.append(f"  I{i + 1} {ex.principal[i]:10.2f}  axis ({', '.join(f'{x:+.4f}' for x in v)})  "
                     f"{ang:.2f}° from {'xyz'[near]}{about}")
    return lines


def origin_line(ex: Expressed) -> str:
    """The moments and products of inertia about the body frame's origin (parallel-axis
    theorem; products with the vehicle-dynamics sign, as the main table)."""
    same = bool(np.allclose(ex.cg, 0.0))

    def signed(k: str) -> float | None:
        v = ex.entry(k, "origin")
        return None if v is None else VEHICLE_SIGN[KEYS.index(k)] * v + 0.0
    vals = ", ".join(f"I{k[1:]} {fmt(signed(k))}" for k in ORDER)
    return ("about the body-frame origin (parallel-axis theorem, J + m (|c|² I − c cᵀ), "
            f"mass {ex.mass:g} kg, "
            f"CG c above{'; the CG is at the origin: the same' if same else ''}): {vals} kg·m²")


__all__ = ["fmt", "origin_line", "principal_lines", "TABLE_CAPTION", "tensor_entries_line",
           "tensor_table"]
