"""The report's figures (matplotlib, Agg, object API: no pyplot state), each written as a PNG.

* :func:`fit_figure` — measured vs predicted band-passed angular velocity per body axis,
  the thesis's "comparison of the identified and measured systems" (sections 4.x);
* :func:`residual_figure` — the residuals in time (the band-pass filter's edge transients
  shaded and left out of the y-limits) and their Welch spectrum over the fit band;
* :func:`ellipse_figure` — 1σ/2σ uncertainty ellipses of pairs of entries (2-D marginals of
  the covariance; 1σ is Mahalanobis distance 1, holding 39 % of a 2-D Gaussian, 2σ 86 %);
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
from scipy.signal import welch

from ..estimation.inertia_result import FitSeries, InertiaResult
from ..io.rig import Rig
from ..io.verdict import KEYS
from ..model.parametrisation import from_tensor
from .mass import SIGN, SYMBOL, MassProperties

AXES = "xyz"
ELLIPSE_PAIRS = (("ixx", "iyy"), ("iyy", "izz"), ("ixx", "izz"), ("ixy", "ixz"), ("ixy", "iyz"), ("ixz", "iyz"))
AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")    # body x, y, z (as RViz draws axes)


def figure(w: float, h: float):
    """A matplotlib Figure (w × h inches, 100 dpi, constrained layout), not registered with pyplot."""
    from matplotlib.figure import Figure
    return Figure(figsize=(w, h), dpi=100, layout="constrained")


def edge_seconds(s: FitSeries) -> float:
    """Duration s at each end of the window where the zero-phase band-pass filter's start-up
    transient lives: two periods of the band's low edge, at most a tenth of the window (as the
    validation's segments)."""
    T = float(s.t[-1] - s.t[0])
    lo = float(s.band_hz[0]) if np.isfinite(s.band_hz[0]) and s.band_hz[0] > 0 else 1.0
    return min(0.1 * T, 2.0 / lo)


def robust_limit(x: np.ndarray, margin: float = 1.25) -> float:
    """Symmetric y-limit of ``x``: ``margin`` × the 99.9th percentile of |x| (positive)."""
    a = np.abs(x[np.isfinite(x)])
    v = float(np.percentile(a, 99.9)) if a.size else 1.0
    return margin * v if v > 0 else 1.0


def shade_edges(ax, T: float, edge: float, label: bool) -> None:
    """Shade the filter's edge zones [0, edge] and [T − edge, T] on time axis ``ax``."""
    for a, b in ((0.0, edge), (T - edge, T)):
        ax.axvspan(a, b, color="0.85", alpha=0.6, lw=0, label="filter edge transient" if label and a == 0 else None)


def fit_figure(path: Path, s: FitSeries, title: str) -> None:
    """Measured vs predicted band-passed angular velocity (mrad/s) per body axis: the whole
    window and 10 s in its middle."""
    fig = figure(11, 7.8)
    ax = fig.subplots(3, 2, sharex="col", width_ratios=(2, 1))
    t = s.t - s.t[0]
    mid = t[len(t) // 2]
    zoom = (t >= mid - 5) & (t <= mid + 5)
    edge = edge_seconds(s)
    for i in range(3):
        for c, m in ((0, slice(None)), (1, zoom)):
            a = ax[i, c]
            a.plot(t[m], 1e3 * s.measured[m, i], color="0.55", lw=1.8, label="measured (gyro, band-passed)")
            a.plot(t[m], 1e3 * s.predicted[m, i], color="tab:red", lw=0.8, ls="--",
                   label="predicted (the reported model)")
            a.grid(alpha=0.3)
        shade_edges(ax[i, 0], float(t[-1]), edge, label=i == 0)
        ax[i, 0].set_ylabel(f"ω{AXES[i]}, mrad/s")
    ax[0, 0].set_title("whole window")
    ax[0, 1].set_title("10 s in the middle")
    for c in (0, 1):
        ax[2, c].set_xlabel("time from the window start, s")
    fig.legend(*ax[0, 0].get_legend_handles_labels(), loc="outside lower center", ncols=3, fontsize=9)
    fig.suptitle(f"{title}: measured vs predicted angular velocity, body axes, band "
                 f"{s.band_hz[0]:.2f}–{s.band_hz[1]:.2f} Hz")
    fig.savefig(path)


def residual_figure(path: Path, s: FitSeries, title: str) -> None:
    """Residuals (measured − predicted, mrad/s) in time — y-limits from the window without the
    filter's edge transients, which are shaded — and their Welch spectrum over the fit band
    (a little beyond), the band-passed measurement faint behind."""
    fig = figure(11, 7.0)
    ax = fig.subplots(2, 1)
    t = s.t - s.t[0]
    r = 1e3 * s.residual
    fs = s.fs or 1.0 / float(np.median(np.diff(s.t)))
    edge = edge_seconds(s)
    inner = (t >= edge) & (t <= t[-1] - edge)
    for i in range(3):
        ax[0].plot(t, r[:, i], lw=0.6, label=f"ω{AXES[i]}  RMS {np.sqrt(np.mean(r[:, i] ** 2)):.3g} mrad/s")
    shade_edges(ax[0], float(t[-1]), edge, label=True)
    lim = robust_limit(r[inner] if inner.sum() > 10 else r)
    ax[0].set_ylim(-lim, lim)
    ax[0].set_xlim(0, t[-1])
    ax[0].set_xlabel("time from the window start, s")
    ax[0].set_ylabel("residual, mrad/s")
    ax[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, title="residual (whole window)",
                 title_fontsize=8)
    ax[0].grid(alpha=0.3)
    nper = int(min(len(t), 2 ** np.ceil(np.log2(20 * fs))))
    f, Pr = welch(s.residual, fs=fs, nperseg=nper, axis=0)
    _, Py = welch(s.measured, fs=fs, nperseg=nper, axis=0)
    lo, hi = float(s.band_hz[0]), float(s.band_hz[1])
    f0, f1 = max(0.0, lo - 0.3 * (hi - lo)), min(fs / 2, hi + 0.3 * (hi - lo))
    for i in range(3):
        line, = ax[1].semilogy(f, Pr[:, i], lw=0.9, label=f"residual ω{AXES[i]}")
        ax[1].semilogy(f, Py[:, i], lw=0.7, alpha=0.35, color=line.get_color(),
                       label=f"measured ω{AXES[i]} (band-passed)")
    ax[1].axvspan(lo, hi, color="tab:green", alpha=0.07, label="fit band")
    ax[1].set_xlim(f0, f1)
    view = (f >= f0) & (f <= f1)
    inb = (f >= lo) & (f <= hi)
    if inb.any():
        floor = max(float(np.percentile(Pr[inb], 2)), 1e-300)
        top = max(float(Py[view].max()), float(Pr[view].max()), 10 * floor)
        ax[1].set_ylim(0.3 * floor, 3 * top)
    ax[1].set_xlabel("frequency, Hz")
    ax[1].set_ylabel("PSD, (rad/s)²/Hz")
    ax[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    ax[1].grid(alpha=0.3)
    fig.suptitle(f"{title}: residuals (measured − predicted) and their spectrum (Welch)")
    fig.savefig(path)


#: The channel groups of :func:`channels_figure`: name prefix, label, unit, scale from SI.
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


def offset_label(sym: str, c: float) -> str:
    """Axis label of a deviation from the estimate ``c``: "Ixx − 2897.1 kg·m²", "Ixy + 0.7 kg·m²"."""
    return f"{sym} − {c:.1f} kg·m²" if c >= 0 else f"{sym} + {-c:.1f} kg·m²"


def ellipse_figure(path: Path, result: InertiaResult, truth: dict | None) -> bool:
    """1σ/2σ uncertainty ellipses of pairs of entries, deviation from the estimate, products
    with the vehicle-dynamics sign; the truth when known.  Pairs with an undetermined entry
    are left empty with a note.  Returns False (nothing written) when the covariance is not
    finite."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Ellipse
    gone = set(result.undetermined)
    C = np.asarray(result.covariance, float) * np.outer(SIGN, SIGN)
    theta = SIGN * from_tensor(result.inertia)
    ok = [k for i, k in enumerate(KEYS) if k not in gone and np.isfinite(theta[i]) and np.all(np.isfinite(C[i]))]
    if len(ok) < 2:
        return False
    fig = figure(11, 7.8)
    axs = fig.subplots(2, 3).ravel()
    tru = None if truth is None else SIGN * np.array([truth["inertia_about_cg"][k] for k in KEYS], float)
    for a, (k1, k2) in zip(axs, ELLIPSE_PAIRS):
        i, j = KEYS.index(k1), KEYS.index(k2)
        if k1 not in ok or k2 not in ok:
            a.text(0.5, 0.5, f"{SYMBOL[k1]}–{SYMBOL[k2]}:\nnot determined", ha="center", va="center",
                   transform=a.transAxes, color="0.4")
            a.set_axis_off()
            continue
        C2 = C[np.ix_([i, j], [i, j])]
        ev, V = np.linalg.eigh(C2)
        ev = np.clip(ev, 0, None)
        ang = np.degrees(np.arctan2(V[1, 1], V[0, 1]))
        for r, ls in ((1, "-"), (2, "--")):
            a.add_patch(Ellipse((0, 0), 2 * r * np.sqrt(ev[1]), 2 * r * np.sqrt(ev[0]), angle=ang,
                                fill=False, ls=ls, color="tab:blue", lw=1.2))
        a.plot(0, 0, "+", color="tab:blue", ms=10)
        lim = 2.6 * np.sqrt(np.diag(C2))
        if tru is not None:
            d = tru[[i, j]] - theta[[i, j]]
            a.plot(d[0], d[1], "x", color="tab:red", ms=9, mew=2)
            lim = np.maximum(lim, 1.2 * np.abs(d))
        lim = np.where(lim > 0, lim, 1.0)
        a.set_xlim(-lim[0], lim[0])
        a.set_ylim(-lim[1], lim[1])
        a.set_xlabel(offset_label(SYMBOL[k1], theta[i]))
        a.set_ylabel(offset_label(SYMBOL[k2], theta[j]))
        rho = C2[0, 1] / np.sqrt(max(C2[0, 0] * C2[1, 1], 1e-300))
        a.set_title(f"{SYMBOL[k1]}–{SYMBOL[k2]}  (correlation {rho:+.2f})".replace("-", "−"), fontsize=10)
        a.grid(alpha=0.3)
    handles = [Line2D([], [], color="tab:blue", ls="-", label="1σ"), Line2D([], [], color="tab:blue", ls="--",
                                                                           label="2σ"),
               Line2D([], [], color="tab:blue", marker="+", ls="", ms=10, label="estimate")]
    if tru is not None:
        handles.append(Line2D([], [], color="tab:red", marker="x", ls="", ms=9, mew=2, label="truth (truth.yaml)"))
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=9)
    fig.suptitle("uncertainty ellipses of pairs of moments and products of inertia about the CG "
                 "(deviation from the estimate)")
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


__all__ = ["fit_figure", "residual_figure", "ellipse_figure", "ellipsoid_figure", "edge_seconds", "figure",
           "channels_figure", "CHANNEL_GROUPS"]
