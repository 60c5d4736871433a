"""The report's figures (matplotlib, Agg, object API: no pyplot state), each written as a PNG.

* :func:`channels_figure` — every channel of the rig model measured and predicted over the fit's
  span, the thesis's "comparison of the identified and measured systems" (sections 4.x);
* :func:`ellipsoid_figure` — the equimomental ellipsoid (the uniform solid ellipsoid with the
  body's mass and tensor) and the principal axes drawn on the body: the rig's body anchors,
  IMU, exciter and CG, three projections and a 3-D view.

Products of inertia carry the vehicle-dynamics sign (Ixy = ∫xy dm, the negated off-diagonal
entry of the tensor; :mod:`rig_identification.report.mass`).  matplotlib is imported lazily (an optional heavy
dependency of the package).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..io.rig import Rig
from .mass import MassProperties

AXES = "xyz"
AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")    # body x, y, z (as RViz draws axes)


def figure(w: float, h: float):
    """A matplotlib Figure (w × h inches, 100 dpi, constrained layout), not registered with pyplot."""
    from matplotlib.figure import Figure
    return Figure(figsize=(w, h), dpi=100, layout="constrained")


CHANNEL_GROUPS = (("tension:", "tensions", "N", 1.0), ("gyro_", "gyro", "mrad/s", 1e3),
                  ("accel_", "accelerometer", "m/s²", 1.0), ("incl_", "inclinometer", "mrad", 1e3),
                  ("exciter_", "exciter force", "N", 1.0))


def channels_figure(path: Path, t: np.ndarray, measured: np.ndarray, predicted: np.ndarray,
                    channels: tuple[str, ...], prefix: str, title: str) -> bool:
    """Measured vs predicted for the channels whose names start with ``prefix`` (a group of
    :data:`CHANNEL_GROUPS`), one row each: the whole span and 10 s in its middle.  t (m,) s;
    measured, predicted (m, n_out) in SI units, ``channels`` (n_out,) their names.  Returns False
    (nothing written) when no channel has the prefix."""
    cols = [i for i, c in enumerate(channels) if c.startswith(prefix)]
    if not cols:
        return False
    label, unit, scale = next((lab, u, k) for p, lab, u, k in CHANNEL_GROUPS if p == prefix)
    fig = figure(11, 1.0 + 1.45 * len(cols))
    ax = np.atleast_2d(fig.subplots(len(cols), 2, sharex="col", width_ratios=(2, 1), squeeze=False))
    tt = t - t[0]
    mid = tt[len(tt) // 2]
    zoom = (tt >= mid - 5) & (tt <= mid + 5)
    for r, i in enumerate(cols):
        for c, m in ((0, slice(None)), (1, zoom)):
            a = ax[r, c]
            a.plot(tt[m], scale * measured[m, i], color="0.55", lw=1.8, label="measured (in the fit's band)")
            a.plot(tt[m], scale * predicted[m, i], color="tab:red", lw=0.8, ls="--", label="the model at the estimate")
            a.grid(alpha=0.3)
        ax[r, 0].set_ylabel(f"{channels[i].removeprefix(prefix)}, {unit}", fontsize=8)
    ax[0, 0].set_title("whole span")
    ax[0, 1].set_title("10 s in the middle")
    for c in (0, 1):
        ax[-1, c].set_xlabel("time from the span's start, s")
    fig.legend(*ax[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=2, fontsize=9)
    fig.suptitle(f"{title}: {label}, measured vs the rig model")
    fig.savefig(path)
    return True


def rig_points(rig: Rig | None) -> dict:
    """Named points of the rig in body axes, m: body anchors, IMU, exciter (when in rig.yaml)."""
    if rig is None:
        return {}
    pts = {"body anchors": np.asarray(rig.body_anchors, float).reshape(-1, 3), "IMU": rig.imu.position[None]}
    if rig.exciter is not None:
        pts["exciter"] = rig.exciter.position[None]
    return pts


def ellipse_2d(A: np.ndarray, n: int = 100) -> np.ndarray:
    """(n, 2) outline of {x : xᵀ A⁻¹ x = 1} for a 2×2 positive semi-definite A."""
    ev, V = np.linalg.eigh(A)
    u = np.linspace(0, 2 * np.pi, n)
    return (V * np.sqrt(np.clip(ev, 0, None))) @ np.array([np.cos(u), np.sin(u)])


def ellipsoid_figure(path: Path, mp: MassProperties, rig: Rig | None) -> bool:
    """The equimomental ellipsoid (semi-axes ``mp.semi_axes`` along the principal axes, about
    the CG) and the principal axes, on the rig's body points (anchors, IMU, exciter, the box
    they span): the x–y, x–z and y–z projections and a 3-D view, rig.yaml's body axes, m (no view is called
    top, side or front: rig.yaml's body frame need not have x forward and z up).
    Returns False (nothing written) when the tensor is not determined."""
    if not mp.determined:
        return False
    # set together with principal (mass_properties_of)
    assert mp.principal is not None and mp.principal_axes is not None and mp.semi_axes is not None
    from matplotlib.lines import Line2D
    fig = figure(11, 9.2)
    axs = [fig.add_subplot(2, 2, k) for k in (1, 2, 3)] + [fig.add_subplot(2, 2, 4, projection="3d")]
    c, R, a = mp.cg, mp.principal_axes, mp.semi_axes
    near = [int(np.argmax(np.abs(R[:, k]))) for k in range(3)]
    # each principal axis in the colour of its nearest body axis (when they are three different ones)
    colors = [AXIS_COLORS[n] for n in near] if len(set(near)) == 3 else ["tab:red", "tab:purple", "tab:cyan"]
    A = R @ np.diag(a**2) @ R.T
    pts = rig_points(rig)
    allp = np.vstack([c[None]] + list(pts.values()))
    lo, hi = allp.min(0), allp.max(0)
    markers = {"body anchors": ("s", "0.3"), "IMU": ("D", "tab:purple"), "exciter": ("^", "tab:orange")}
    views = ((0, 1, "x–y plane (seen along z)"), (0, 2, "x–z plane (seen along y)"), (1, 2, "y–z plane (seen along x)"))
    for ax, (i, j, name) in zip(axs, views):
        box = np.array([[lo[i], lo[j]], [hi[i], lo[j]], [hi[i], hi[j]], [lo[i], hi[j]], [lo[i], lo[j]]])
        if pts:
            ax.plot(box[:, 0], box[:, 1], color="0.6", ls=":", lw=1)
        e = ellipse_2d(A[np.ix_([i, j], [i, j])])
        ax.fill(c[i] + e[0], c[j] + e[1], color="tab:blue", alpha=0.12, lw=0)
        ax.plot(c[i] + e[0], c[j] + e[1], color="tab:blue", lw=1.2)
        for k in range(3):
            d = a[k] * R[:, k]
            ax.plot([c[i] - d[i], c[i] + d[i]], [c[j] - d[j], c[j] + d[j]], color=colors[k], lw=2)
        for nm, p in pts.items():
            m, col = markers[nm]
            ax.plot(p[:, i], p[:, j], m, color=col, ms=6, ls="")
        ax.plot(c[i], c[j], "o", color="k", ms=5)
        ax.plot(0, 0, "+", color="0.3", ms=10, mew=1)
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel(f"body {AXES[i]}, m")
        ax.set_ylabel(f"body {AXES[j]}, m")
        ax.set_title(name, fontsize=10)
        ax.grid(alpha=0.3)
    ax = axs[3]
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 32), np.linspace(0, np.pi, 16))
    sph = np.stack([np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)], -1)
    X = c + (sph * a) @ R.T
    ax.plot_wireframe(X[..., 0], X[..., 1], X[..., 2], color="tab:blue", lw=0.4, alpha=0.5)
    for k in range(3):
        d = a[k] * R[:, k]
        ax.plot(*np.array([c - d, c + d]).T, color=colors[k], lw=2.5)
    for nm, p in pts.items():
        m, col = markers[nm]
        ax.plot(p[:, 0], p[:, 1], p[:, 2], m, color=col, ms=5, ls="")
    ax.plot(*c, "o", color="k", ms=4)
    span = max(float(np.max(a)), float(np.max(hi - lo)) / 2, 0.1)
    mid = 0.5 * (np.minimum(lo, c - a.max()) + np.maximum(hi, c + a.max()))
    for setlim, m in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), mid):
        setlim(m - span, m + span)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x, m")
    ax.set_ylabel("y, m")
    ax.set_zlabel("z, m")
    ax.set_title("3-D view", fontsize=10)
    handles = [Line2D([], [], color=colors[k], lw=2.5, label=f"principal axis {k + 1}: I{k + 1} = "
                      f"{mp.principal[k]:.1f} kg·m² (near body {AXES[near[k]]})") for k in range(3)]
    handles += [Line2D([], [], color="tab:blue", lw=1.2, label="equimomental ellipsoid (same mass and tensor)"),
                Line2D([], [], color="k", marker="o", ls="", ms=5, label="CG"),
                Line2D([], [], color="0.3", marker="+", ls="", ms=10, label="body-frame origin")]
    handles += [Line2D([], [], color=markers[nm][1], marker=markers[nm][0], ls="", ms=6, label=nm) for nm in pts]
    if pts:
        handles.append(Line2D([], [], color="0.6", ls=":", label="box spanned by the rig points and the CG"))
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=9)
    fig.suptitle("principal axes and the equimomental ellipsoid on the body (rig.yaml's body axes)")
    fig.savefig(path)
    return True


__all__ = ["ellipsoid_figure", "figure", "channels_figure", "CHANNEL_GROUPS"]
