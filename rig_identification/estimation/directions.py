"""The tensor's weakly determined directions: the eigen-directions of the fit's covariance in the
tensor's Frobenius metric (:func:`weak_directions`), and their words (:func:`describe_direction`) —
the one wording of the CLI, the JSON and the report.
"""
from __future__ import annotations

from collections.abc import Container
from typing import Any

import numpy as np

from ..io.export import ENTRY_NAMES, VEHICLE_SIGN, finite_or_none
from ..io.verdict import KEYS
from ..model.parametrisation import from_tensor, to_tensor


def weak_directions(J: np.ndarray, cov_J: np.ndarray, n: int = 2) -> list[tuple[float, np.ndarray]]:
    """The ``n`` most weakly determined tensor combinations: eigen-directions of the
    covariance (equivalently of the information matrix, its inverse) in the Frobenius
    metric of the tensor, largest std first.  Returns [(std / (tr J / 3), (3,3) unit-norm
    tensor direction)]; ``n=6`` gives all of them; [] when J or the covariance is not finite.
    :func:`describe_direction` puts one in words."""
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(cov_J))):
        return []
    scale = np.trace(J) / 3
    Dm = np.diag([1, np.sqrt(2), np.sqrt(2), 1, np.sqrt(2), 1])  # Frobenius metric on the entries
    evals, evecs = np.linalg.eigh(Dm @ cov_J @ Dm)
    weak = []
    for lam, vec in sorted(zip(evals, evecs.T), key=lambda z: -z[0])[:n]:
        D = to_tensor(np.linalg.solve(Dm, vec))
        D /= np.linalg.norm(D)
        weak.append((float(np.sqrt(max(lam, 0)) / scale), D))
    return weak


DIRECTION_LEVELS = ((1e-3, "well determined"), (1e-2, "fairly well determined"))
"""Words for a tensor direction by its relative σ (σ over tr J / 3, :func:`weak_directions`):
below each limit its words; from the last limit up to :data:`DIRECTION_NOT_DETERMINED`
"weakly determined"; beyond it "not determined"."""
DIRECTION_NOT_DETERMINED = 0.10
"""Relative σ from which a direction is "not determined": validation.REL_STD_LIMIT (a test holds
them equal; this module cannot import validation, which imports it)."""


def direction_level(rel_std: float) -> str:
    """"well determined", "fairly well determined", "weakly determined" or "not determined" for a
    direction of relative σ ``rel_std`` (:data:`DIRECTION_LEVELS`, :data:`DIRECTION_NOT_DETERMINED`)."""
    if not np.isfinite(rel_std) or rel_std >= DIRECTION_NOT_DETERMINED:
        return "not determined"
    return next((words for limit, words in DIRECTION_LEVELS if rel_std < limit), "weakly determined")


ENTRY_AXES = {"ixx": (0,), "iyy": (1,), "izz": (2,), "ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}
"""The body axes (0 x, 1 y, 2 z) whose rotation determines each tensor entry."""
AXIS_WORDS = {0: "x", 1: "y", 2: "z"}
"""The body axes by name: no roll, pitch or yaw here (the vehicle's orientation is rig.yaml's
``body.vehicle``, :mod:`~rig_identification.io.vehicle`, which these words do not know)."""
HARDLY_TURNED = 0.5
"""An axis whose rotation rate (RMS) is below this share of the most excited axis's "hardly turned"."""


def hardly_turned(main: str, rotation_rms: np.ndarray) -> str:
    """The clause saying the body hardly turned about the axis entry ``main`` needs
    (rotation_rms (3,) rad/s RMS, body axes), or "" when it turned at least
    :data:`HARDLY_TURNED` of the most excited axis's rate."""
    r = np.asarray(rotation_rms, float)
    a = min(ENTRY_AXES[main], key=lambda i: r[i])
    if not r[a] < HARDLY_TURNED * np.max(r):
        return ""
    ax = AXIS_WORDS[a]
    return (f": the body hardly turned about {ax} (rate about {ax} {r[a]:.2g} rad/s RMS against {np.max(r):.2g} "
            "rad/s on the most excited axis)")


def describe_direction(rel_std: float, D: np.ndarray, scale: float | None = None, weakest: bool = False,
                       undetermined: Container[str] = (), rotation_rms: np.ndarray | None = None) -> dict[str, Any]:
    """A tensor direction (of :func:`weak_directions`) in words a lab engineer reads — the one
    wording of the CLI, the JSON and the report.

    rel_std: σ along the unit direction over tr J / 3; D (3,3) unit-norm direction; scale: tr J / 3
    kg·m² (for σ in kg·m²; None: relative only); weakest: this is the weakest direction (only it
    is called "the most weakly determined"); undetermined: entries the validation did not
    determine (a direction mostly along one of them is "not determined"); rotation_rms (3,)
    rad/s RMS about the body axes (the planner's prediction): the text adds that the body
    hardly turned about the axis the direction needs (:func:`hardly_turned`).

    Returns {"relative_std", "std" (kg·m² or None), "direction" {KEYS: coefficient, tensor
    entries}, "mostly" (the entry with the largest share), "combination" (e.g. "+0.96 Izz −0.29
    Ixz": products with the vehicle-dynamics sign, the main entry positive), "pure" (one entry
    holds over 90 % of it), "level" (:func:`direction_level`), "weakest", "text"}."""
    theta = from_tensor(D)
    share = theta * np.sqrt([1, 2, 2, 1, 2, 1])     # a product appears twice in the unit (Frobenius) tensor
    order = np.argsort(-np.abs(share))
    if (VEHICLE_SIGN * share)[order[0]] < 0:        # a direction's sign is arbitrary: its main entry positive
        theta, share = -theta, -share
    shown = VEHICLE_SIGN * share
    main = KEYS[order[0]]
    comb = " ".join(f"{shown[i]:+.2f} {ENTRY_NAMES[KEYS[i]].split()[-1]}" for i in order
                    if abs(share[i]) >= 0.2).replace("-", "−")
    pure = abs(share[order[0]]) > 0.9
    what = ENTRY_NAMES[main] if pure else f"{comb} (mostly {ENTRY_NAMES[main]})"
    level = "not determined" if main in undetermined else direction_level(rel_std)
    std = None if scale is None or not np.isfinite(rel_std) else float(rel_std * scale)
    size = (f"σ {std:.3g} kg·m², " if std is not None else "σ ") + f"{100 * rel_std:.3g} % of tr J/3"
    text = (f"the most weakly determined combination is {what}: {level} ({size})" if weakest
            else f"{what if pure else 'the combination ' + what} is {level} ({size})")
    if rotation_rms is not None and level != "well determined":
        text += hardly_turned(main, rotation_rms)
    return {"relative_std": finite_or_none(rel_std), "std": std,
            "direction": {k: round(float(v), 3) for k, v in zip(KEYS, theta)}, "mostly": main,
            "combination": comb, "pure": bool(pure), "level": level, "weakest": bool(weakest),
            "text": text[0].upper() + text[1:]}
