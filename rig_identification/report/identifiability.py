"""Which combinations of the tensor the recording determines well and poorly, in words (the
report's identifiability table).

The six eigen-directions of the covariance (the inverse of the information matrix) of the
tensor entries in the tensor's Frobenius metric (:func:`~rig_identification.estimation.directions.weak_directions`),
weakest first, each with its σ and a sentence a lab engineer reads ("moment Izz is weakly
determined: the body hardly turned about z …"; entries named by their body axes, never roll, pitch
or yaw: :data:`~rig_identification.io.export.ENTRY_NAMES`), explained by the signal-to-residual ratio of
the band-passed gyro about each body axis.  Products are named and signed as on the rest of
the page (vehicle dynamics: Ixy = ∫xy dm, the negated off-diagonal entry; :mod:`rig_identification.report.mass`).
"""
from __future__ import annotations

import numpy as np

from ..estimation.directions import ENTRY_AXES, describe_direction, weak_directions
from ..estimation.inertia_result import InertiaResult
from ..io.export import ENTRY_NAMES
from .html import Cell, esc, num, table

AXES = "xyz"
LEVER = {"x": "an exciter force with a longer lever arm about the x axis",
         "y": "an exciter force with a longer lever arm about the y axis",
         "z": "a horizontal exciter force offset sideways from the CG"}



def axis_signal(result: InertiaResult) -> tuple[np.ndarray, np.ndarray]:
    """RMS (3,) rad/s of the band-passed measured gyro and of the residual per body axis,
    pooled over the fitted segments."""
    y = np.concatenate([s.measured for s in result.series])
    r = np.concatenate([s.residual for s in result.series])
    return np.sqrt(np.mean(y**2, 0)), np.sqrt(np.mean(r**2, 0))


def explain(level: str, ax: tuple, sig: np.ndarray, snr: np.ndarray) -> str:
    """Why a direction mostly along the entry of body axes ``ax`` is determined as it is:
    the rotation about those axes (``sig`` rad/s RMS, ``snr`` over the fit residual)."""
    a = min(ax, key=lambda i: snr[i])
    best = int(np.argmax(snr))
    about = f"about {AXES[a]}" if len(ax) == 1 else \
        f"about {AXES[ax[0]]} and {AXES[ax[1]]} together (about {AXES[a]} the less)"
    motion = f"{1e3 * sig[a]:.3g} mrad/s RMS in the fit band, {snr[a]:.0f}× the fit residual"
    ratio = snr[a] / snr[best]
    if level == "well determined":
        return f"; rotation about {' and '.join(AXES[i] for i in ax)}: {motion}"
    if a != best and ratio < 0.5:
        return (f": the body {'hardly turned' if ratio < 0.25 else 'turned less'} {about} — {motion}, "
                f"against {snr[best]:.0f}× about {AXES[best]}; a recording with more rotation about "
                f"{AXES[a]} ({LEVER[AXES[a]]}) would determine it better")
    return (f": the rotation {about} was ample ({motion}); the entries are hard to tell apart with "
            "this excitation — another exciter frequency or position would separate them")


def identifiability(result: InertiaResult) -> list[dict]:
    """The six eigen-directions of the tensor's covariance (weakest first), in words; empty
    when the covariance or the tensor is not finite (nothing to say).

    Each: ``relative_std`` (σ along the unit direction / (tr J / 3)), ``std`` kg·m²,
    ``direction`` {tensor entry (KEYS, geometry_msgs sign): coefficient} (unit Frobenius norm
    of the tensor), ``mostly`` (the entry with the largest share), ``combination`` (text in
    the page's notation, products with the vehicle-dynamics sign, e.g. "+0.96 Izz −0.29 Ixz"),
    ``level`` (:func:`~rig_identification.estimation.directions.direction_level`: the CLI's and the JSON's words),
    ``text`` (:func:`~rig_identification.estimation.directions.describe_direction`'s sentence with the reason, from the
    signal-to-residual ratio per body axis).
    """
    J, C = np.asarray(result.inertia, float), np.asarray(result.covariance, float)
    if not (np.all(np.isfinite(J)) and np.all(np.isfinite(C))) or np.trace(J) <= 0:
        return []
    scale = np.trace(J) / 3
    sig, res = axis_signal(result) if result.series else (None, None)
    snr = None if sig is None else sig / np.maximum(res, 1e-300)
    rows = []
    for i, (rel, D) in enumerate(weak_directions(J, C, n=6)):
        # the one wording of the CLI, the JSON and the report (directions.describe_direction)
        d = describe_direction(rel, D, scale=scale, weakest=i == 0, undetermined=result.undetermined)
        main, level = d["mostly"], d["level"]
        text = d["text"][0].upper() + d["text"][1:]
        if snr is not None:
            text += explain(level, ENTRY_AXES[main], sig, snr)
        if not d["pure"] and level != "well determined":
            text += "; its entries are correlated: this mix of them is what is uncertain, not each alone"
        rows.append({"relative_std": float(rel), "std": float(rel * scale),
                     "direction": {k: round(float(v), 3) for k, v in d["direction"].items()}, "mostly": main,
                     "combination": d["combination"], "level": level, "text": text + "."})
    return rows


def identifiability_html(result: InertiaResult, rows: list[dict]) -> str:
    """The identifiability table and its note (``rows`` from :func:`identifiability`)."""
    if not rows:
        return ("<p>Not available: the fit's covariance is not finite (the recording does not determine the "
                "tensor).</p>")
    body = [[r["combination"], num(r["std"], ".3g"), num(100 * r["relative_std"], ".3g"), Cell(r["text"], "text")]
            for r in rows]
    out = table(["tensor direction", "σ kg·m²", "σ % of tr J/3", "in words"], body, cls="ident",
                row_cls=["weak" if r["level"] == "weakly determined" else "" for r in rows], text_cols=(3,))
    if result.series:
        sig, res = axis_signal(result)
        out += ('<p class="note">Eigen-directions of the covariance of the six entries (the inverse of the '
                "information matrix) in the tensor's own (Frobenius) metric, weakest first; products with the "
                "vehicle-dynamics sign. Band-passed gyro RMS about body x, y, z: "
                + esc(", ".join(num(1e3 * x, ".3g") for x in sig)) + " mrad/s; fit residual RMS: "
                + esc(", ".join(num(1e3 * x, ".3g") for x in res)) + " mrad/s.</p>")
    return out


__all__ = ["identifiability", "identifiability_html", "axis_signal", "ENTRY_NAMES"]
