"""HTML report of an inertia identification (``rig-identify inertia … --report DIR``).

One folder, written atomically (:func:`~.atomic.atomic_directory`: it appears whole or
not at all) with ``index.html``, PNG figures (matplotlib, Agg, no pyplot state) linked
relatively, and ``report.json`` (the page's numbers: ``result`` as
:meth:`InertiaResult.to_dict`, ``identifiability`` as :func:`identifiability`, ``modes`` per
recording).  Contents:

* the tensor with its standard deviations (what the result reports, the bound of the
  propagated sensor noise, the fit's own sandwich) and,
  when the recordings carry ``truth.yaml``, the errors against it;
* the identifiability table: all six eigen-directions of the covariance (the inverse of
  the information matrix) of the tensor entries in the tensor's Frobenius metric
  (:func:`~.identification.weak_directions`), weakest first, with their relative σ and a
  sentence a lab engineer reads ("yaw inertia Izz is weakly determined: the body hardly
  turned about z …"), explained by the signal-to-residual ratio of the band-passed gyro
  about each body axis;
* 1σ/2σ uncertainty ellipses of pairs of entries (the 2-D marginals of the covariance;
  the 1σ ellipse is Mahalanobis distance 1, holding 39 % of a 2-D Gaussian, 2σ 86 %);
* per recording, the fit's output — measured vs predicted band-passed angular velocity
  per body axis, as the thesis's "comparison of the identified and measured systems"
  figures (thesis sections 4.x) — and the residuals in time and their spectrum;
* per recording, the natural modes from the geometry (:func:`~.modes.natural_modes` with the
  identified tensor, and with the true one when known) beside those estimated from the
  recording (:func:`~.modes.estimate_modes`).
"""
from __future__ import annotations

import html
import json
import os
from pathlib import Path

import numpy as np

from .atomic import atomic_directory
from .identification import KEYS, IdentificationError, InertiaResult, from_tensor, weak_directions

ENTRY_NAMES = {"ixx": "roll inertia Ixx", "iyy": "pitch inertia Iyy", "izz": "yaw inertia Izz",
               "ixy": "product Ixy", "ixz": "product Ixz", "iyz": "product Iyz"}
SHORT = {"ixx": "Ixx", "iyy": "Iyy", "izz": "Izz", "ixy": "Ixy", "ixz": "Ixz", "iyz": "Iyz"}
ENTRY_AXES = {"ixx": (0,), "iyy": (1,), "izz": (2,), "ixy": (0, 1), "ixz": (0, 2), "iyz": (1, 2)}
ELLIPSE_PAIRS = (("ixx", "iyy"), ("iyy", "izz"), ("ixx", "izz"), ("ixy", "ixz"), ("ixy", "iyz"), ("ixz", "iyz"))
AXES = "xyz"
LEVER = {"x": "an exciter force with a longer lever arm about the x axis",
         "y": "an exciter force with a longer lever arm about the y axis",
         "z": "a horizontal exciter force offset sideways from the CG"}

# relative σ (of tr J / 3) of a tensor direction: below WELL "well determined", below FAIR "fairly well"
WELL, FAIR = 1e-3, 1e-2


class ReportError(IdentificationError):
    """The result cannot be reported (the thesis baseline has no fit output series), or
    the report folder would replace something that is not an earlier report."""


GENERATOR = '<meta name="generator" content="rig-identify report">'


def check_report_dir(out: Path) -> None:
    """Refuse to replace a file, or a non-empty folder that is not an earlier report."""
    if not out.exists():
        return
    if not out.is_dir():
        raise ReportError(f"{out}: exists and is not a folder (refusing to replace it with the report)")
    index = out / "index.html"
    if any(out.iterdir()) and not (index.is_file() and GENERATOR in index.read_text(errors="replace")[:2000]):
        raise ReportError(f"{out}: exists and is not an earlier rig-identify report (refusing to replace it); "
                          "give a new folder")


def common_truth(recs) -> dict | None:
    """truth.yaml of the recordings if every one has it and their ``inertia_about_cg`` agree
    (to 1e-9 relative), else None."""
    truths = [getattr(r, "truth", None) for r in recs]
    if not truths or any(not t or "inertia_about_cg" not in t for t in truths):
        return None
    ref = np.array([truths[0]["inertia_about_cg"][k] for k in KEYS], float)
    for t in truths[1:]:
        v = np.array([t["inertia_about_cg"][k] for k in KEYS], float)
        if np.any(np.abs(v - ref) > 1e-9 * np.abs(ref).max()):
            return None
    return truths[0]


def axis_signal(result: InertiaResult) -> tuple[np.ndarray, np.ndarray]:
    """RMS (3,) rad/s of the band-passed measured gyro and of the residual per body axis,
    pooled over the fitted segments."""
    y = np.concatenate([s.measured for s in result.series])
    r = np.concatenate([s.residual for s in result.series])
    return np.sqrt(np.mean(y**2, 0)), np.sqrt(np.mean(r**2, 0))


def identifiability(result: InertiaResult) -> list[dict]:
    """The six eigen-directions of the tensor's covariance (weakest first), in words.

    Each: ``relative_std`` (σ along the unit direction / (tr J / 3)), ``std`` kg·m²,
    ``direction`` {entry: coefficient} (unit Frobenius norm of the tensor), ``combination``
    (text, e.g. "+0.99 Izz"), ``level`` ("well determined", "fairly well determined",
    "weakly determined"; thresholds :data:`WELL`, :data:`FAIR`), ``text`` (a sentence
    with the reason, from the signal-to-residual ratio per body axis).
    """
    J = result.inertia
    scale = np.trace(J) / 3
    sig, res = axis_signal(result) if result.series else (None, None)
    snr = None if sig is None else sig / np.maximum(res, 1e-300)
    rows = []
    for rel, D in weak_directions(J, result.covariance, n=6):
        theta = from_tensor(D)
        # share of each entry in the unit (Frobenius) direction: products appear twice in the tensor
        share = theta * np.sqrt([1, 2, 2, 1, 2, 1])
        order = np.argsort(-np.abs(share))
        if share[order[0]] < 0:
            theta, share = -theta, -share
        main = KEYS[order[0]]
        comb = " ".join(f"{share[i]:+.2f} {SHORT[KEYS[i]]}" for i in order if abs(share[i]) >= 0.2)
        pure = share[order[0]] > 0.9
        what = ENTRY_NAMES[main] if pure else f"the combination {comb} (mostly {ENTRY_NAMES[main]})"
        level = "well determined" if rel < WELL else "fairly well determined" if rel < FAIR else "weakly determined"
        text = f"{what[0].upper() + what[1:]} is {level} (σ {rel * scale:.3g} kg·m², {100 * rel:.3g} % of tr J/3)"
        if snr is not None:
            ax = ENTRY_AXES[main]
            a = min(ax, key=lambda i: snr[i])
            best = int(np.argmax(snr))
            about = f"about {AXES[a]}" if len(ax) == 1 else \
                f"about {AXES[ax[0]]} and {AXES[ax[1]]} together (about {AXES[a]} the less)"
            motion = f"{1e3 * sig[a]:.3g} mrad/s RMS in the fit band, {snr[a]:.0f}× the fit residual"
            ratio = snr[a] / snr[best]
            if level == "well determined":
                text += f"; rotation about {' and '.join(AXES[i] for i in ax)}: {motion}"
            elif a != best and ratio < 0.5:
                text += (f": the body {'hardly turned' if ratio < 0.25 else 'turned less'} {about} — {motion}, "
                         f"against {snr[best]:.0f}× about {AXES[best]}; a recording with more rotation about "
                         f"{AXES[a]} ({LEVER[AXES[a]]}) would determine it better")
            else:
                text += (f": the rotation {about} was ample ({motion}); the entries are hard to tell apart with "
                         "this excitation — another exciter frequency or position would separate them")
        if not pure and level != "well determined":
            text += "; its entries are correlated: this mix of them is what is uncertain, not each alone"
        rows.append({"relative_std": float(rel), "std": float(rel * scale),
                     "direction": {k: round(float(v), 3) for k, v in zip(KEYS, theta)}, "mostly": main,
                     "combination": comb, "level": level, "text": text + "."})
    return rows


# --- figures ------------------------------------------------------------------------------

def _figure(w: float, h: float):
    from matplotlib.figure import Figure
    return Figure(figsize=(w, h), dpi=100, layout="constrained")


def _fit_figure(path: Path, s, title: str) -> None:
    fig = _figure(11, 7.5)
    ax = fig.subplots(3, 2, sharex="col", width_ratios=(2, 1))
    t = s.t - s.t[0]
    mid = t[len(t) // 2]
    zoom = (t >= mid - 5) & (t <= mid + 5)
    for i in range(3):
        for c, m in ((0, slice(None)), (1, zoom)):
            a = ax[i, c]
            a.plot(t[m], 1e3 * s.measured[m, i], color="0.25", lw=0.8, label="measured (gyro, band-passed)")
            a.plot(t[m], 1e3 * s.predicted[m, i], color="tab:red", lw=0.8, ls="--", label="predicted (identified J)")
            a.grid(alpha=0.3)
        ax[i, 0].set_ylabel(f"ω{AXES[i]} mrad/s")
    ax[0, 0].set_title("whole window")
    ax[0, 1].set_title("10 s in the middle")
    ax[0, 0].legend(loc="upper right", fontsize=8)
    ax[2, 0].set_xlabel("time from the window start, s")
    ax[2, 1].set_xlabel("time from the window start, s")
    fig.suptitle(f"{title}: measured vs predicted angular velocity, body axes, "
                 f"band {s.band_hz[0]:.2f}–{s.band_hz[1]:.2f} Hz")
    fig.savefig(path)


def _residual_figure(path: Path, s, title: str) -> None:
    from scipy.signal import welch
    fig = _figure(11, 6.5)
    ax = fig.subplots(2, 1)
    t = s.t - s.t[0]
    r = s.residual
    fs = 1.0 / np.median(np.diff(s.t))
    for i in range(3):
        ax[0].plot(t, 1e3 * r[:, i], lw=0.6, label=f"ω{AXES[i]}  RMS {1e3 * np.sqrt(np.mean(r[:, i] ** 2)):.3g} mrad/s")
    ax[0].set_xlabel("time from the window start, s")
    ax[0].set_ylabel("residual mrad/s")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].grid(alpha=0.3)
    nper = int(min(len(t), 2 ** np.ceil(np.log2(20 * fs))))
    f, Pr = welch(r, fs=fs, nperseg=nper, axis=0)
    _, Py = welch(s.measured, fs=fs, nperseg=nper, axis=0)
    for i in range(3):
        line, = ax[1].semilogy(f, Pr[:, i], lw=0.8, label=f"residual ω{AXES[i]}")
        ax[1].semilogy(f, Py[:, i], lw=0.6, alpha=0.35, color=line.get_color())
    ax[1].axvspan(*s.band_hz, color="tab:green", alpha=0.08, label="fit band")
    fmax = min(fs / 2, 3 * s.band_hz[1])
    ax[1].set_xlim(0, fmax)
    inb = (f >= s.band_hz[0]) & (f <= s.band_hz[1])
    if inb.any():
        lo = max(Pr[inb].min(), 1e-300)
        ax[1].set_ylim(0.1 * lo, 3 * max(Py[f <= fmax].max(), Pr[f <= fmax].max(), 10 * lo))
    ax[1].set_xlabel("frequency, Hz")
    ax[1].set_ylabel("PSD (rad/s)²/Hz")
    ax[1].legend(loc="upper right", fontsize=8, title="faint: measured (band-passed)", title_fontsize=8)
    ax[1].grid(alpha=0.3, which="both")
    fig.suptitle(f"{title}: residuals (measured − predicted) and their spectrum (Welch)")
    fig.savefig(path)


def _ellipse_figure(path: Path, result: InertiaResult, truth: dict | None) -> None:
    from matplotlib.patches import Ellipse
    fig = _figure(11, 7.5)
    axs = fig.subplots(2, 3).ravel()
    theta = from_tensor(result.inertia)
    C = result.covariance
    tru = None if truth is None else np.array([truth["inertia_about_cg"][k] for k in KEYS], float)
    for a, (k1, k2) in zip(axs, ELLIPSE_PAIRS):
        i, j = KEYS.index(k1), KEYS.index(k2)
        C2 = C[np.ix_([i, j], [i, j])]
        ev, V = np.linalg.eigh(C2)
        ev = np.clip(ev, 0, None)
        ang = np.degrees(np.arctan2(V[1, 1], V[0, 1]))
        for r, ls in ((1, "-"), (2, "--")):
            a.add_patch(Ellipse((0, 0), 2 * r * np.sqrt(ev[1]), 2 * r * np.sqrt(ev[0]), angle=ang,
                                fill=False, ls=ls, color="tab:blue", lw=1.2, label=f"{r}σ"))
        a.plot(0, 0, "+", color="tab:blue", ms=10, label="estimate")
        lim = 2.6 * np.sqrt(np.diag(C2))
        if tru is not None:
            d = tru[[i, j]] - theta[[i, j]]
            a.plot(d[0], d[1], "x", color="tab:red", ms=9, mew=2, label="truth")
            lim = np.maximum(lim, 1.2 * np.abs(d))
        lim = np.where(lim > 0, lim, 1.0)
        a.set_xlim(-lim[0], lim[0])
        a.set_ylim(-lim[1], lim[1])
        a.set_xlabel(f"{SHORT[k1]} − {theta[i]:.1f}  kg·m²")
        a.set_ylabel(f"{SHORT[k2]} − {theta[j]:.1f}  kg·m²")
        rho = C2[0, 1] / np.sqrt(max(C2[0, 0] * C2[1, 1], 1e-300))
        a.set_title(f"{SHORT[k1]}–{SHORT[k2]}  (correlation {rho:+.2f})", fontsize=10)
        a.grid(alpha=0.3)
    axs[0].legend(loc="upper right", fontsize=8)
    fig.suptitle("uncertainty ellipses of pairs of tensor entries (1σ solid, 2σ dashed; deviation from the "
                 "estimate)")
    fig.savefig(path)


# --- tables -------------------------------------------------------------------------------

def _table(head: list[str], rows: list[list], cls: str = "") -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(x))}</td>" for x in r) + "</tr>" for r in rows)
    return f'<table class="{cls}"><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>'


def _tensor_rows(result: InertiaResult, truth: dict | None) -> tuple[list[str], list[list]]:
    from .pipeline import compare_to_truth
    refined = result.sandwich_std is not None
    head = ["entry", "value kg·m²", "σ kg·m²",
            "σ propagated noise (CRB) kg·m²" if refined else "σ white gyro noise kg·m²", "σ % of entry"]
    cmp = compare_to_truth(result, truth) if truth else None
    if cmp:
        head += ["truth kg·m²", "error kg·m²", "error %", "error / σ"]
    crb = result.crb_std if result.crb_std is not None else np.full(6, np.nan)
    rows = []
    for k, v, s, c in zip(KEYS, from_tensor(result.inertia), result.inertia_std, crb):
        rel = f"{100 * s / abs(v):.3g}" if k in ("ixx", "iyy", "izz") else "–"
        row = [k, f"{v:.2f}", f"{s:.3g}", f"{c:.3g}", rel]
        if cmp:
            e = cmp[k]
            row += [f"{e['truth']:.2f}", f"{e['error']:+.3g}", f"{e['error_percent']:+.3f}", f"{e['error_sigma']:+.2f}"]
        rows.append(row)
    return head, rows


def _z(x: float) -> float:
    """x rounded to 4 decimals without a negative zero (for printing)."""
    return round(float(x), 4) + 0.0


def _modes_section(rec, result: InertiaResult, truth: dict | None) -> tuple[str, list[str], dict]:
    """HTML, notes and data of the modes table of one recording: each geometric mode (with the
    identified and the true tensor) beside the nearest free-vibration peak of the recording
    within 10 % (each peak used once)."""
    from .modes import estimate_modes, natural_modes
    from .simulator import SimulationError
    rig = rec.rig
    if all(c.stiffness is not None for c in rig.cables):
        k, kname = rig.cable_stiffness, "spring cables (rig.yaml stiffness)"
    else:
        k, kname = None, "inextensible cables"
    notes = []
    data = {"cable_model": kname, "modes": [], "unmatched_estimated_hz": []}
    try:
        geo = natural_modes(rig, rig.mass, rig.require_cg(), result.inertia, k)
    except SimulationError as e:
        return f"<p>geometric modes: not available ({html.escape(str(e))})</p>", notes, data
    geo_t = None
    if truth is not None:
        from .simulator import inertia_tensor
        try:
            geo_t = natural_modes(rig, rig.mass, rig.require_cg(), inertia_tensor(truth["inertia_about_cg"]), k)
        except SimulationError:
            geo_t = None
    est = estimate_modes(rec)
    notes += est.warnings
    used = set()
    head = ["geometry Hz (identified J)"] + (["geometry Hz (true J)"] if geo_t else []) + \
        ["mode shape (world axes)", "recording Hz", "difference %", "damping ratio", "seen on"]
    rows = []
    for n, m in enumerate(geo):
        cand = [e for e in est.modes if id(e) not in used]
        best = min(cand, key=lambda e: abs(e.frequency - m.frequency), default=None)
        row = [f"{m.frequency:.4f}"] + ([f"{geo_t[n].frequency:.4f}"] if geo_t else []) + [m.description]
        item = {"geometric_hz": m.frequency, "geometric_true_hz": geo_t[n].frequency if geo_t else None,
                "description": m.description, "estimated_hz": None, "difference_percent": None,
                "damping_ratio": None, "axes": None}
        if best is not None and abs(best.frequency - m.frequency) <= 0.1 * m.frequency:
            used.add(id(best))
            diff = 100 * (best.frequency - m.frequency) / m.frequency
            row += [f"{best.frequency:.4f}", f"{diff:+.2f}", f"{_z(best.damping_ratio):.4f}", best.axes]
            item.update(estimated_hz=best.frequency, difference_percent=diff, damping_ratio=best.damping_ratio,
                        axes=best.axes)
        else:
            row += ["–", "", "", ""]
        rows.append(row)
        data["modes"].append(item)
    for e in est.modes:
        if id(e) not in used:
            rows.append(["–"] + (["–"] if geo_t else []) + ["(no geometric mode)", f"{e.frequency:.4f}", "",
                                                             f"{_z(e.damping_ratio):.4f}", e.axes])
            data["unmatched_estimated_hz"].append(e.frequency)
    data["exciter_frequency_hz"] = est.exciter_frequency
    fex = "" if est.exciter_frequency is None else \
        f" Exciter at {est.exciter_frequency:.4f} Hz (excluded with its harmonics)."
    intro = f"<p>Model: mass {rig.mass:g} kg, CG from rig.yaml, {kname}.{fex}</p>"
    return intro + _table(head, rows), notes, data


# --- the page -----------------------------------------------------------------------------

CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1150px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: right; }
th { background: #f0f0f0; } td:first-child, th:first-child { text-align: left; }
table.ident td:last-child, table.ident th:last-child { text-align: left; max-width: 640px; }
td.text { text-align: left; }
td.weak, tr.weak td { background: #fff1f0; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.4em 0; }
.note { color: #555; font-size: 0.9em; } .warn { color: #a40; }
"""

LOAD_CHECK_JS = """
window.addEventListener('load', function () {
  var imgs = document.images, ok = 0;
  for (var i = 0; i < imgs.length; i++) { if (imgs[i].complete && imgs[i].naturalWidth > 0) ok++; }
  document.body.setAttribute('data-images-loaded', String(ok));
  document.body.setAttribute('data-images-total', String(imgs.length));
  var s = document.getElementById('load-status');
  if (s) s.textContent = ok + ' of ' + imgs.length + ' figures loaded';
});
"""


def write_report(out_dir, result: InertiaResult, recs, truth: dict | None = None, title: str | None = None,
                 modes: bool = True) -> Path:
    """Write the HTML report of ``result`` to the folder ``out_dir`` (replaced if it exists).

    result: from :func:`~.pipeline.identify_recording` or
    :func:`~.pipeline.identify_recordings` (model pem: it needs ``result.series``);
    recs: the Recording(s) it was fitted to, in the same order.  truth: truth.yaml
    mapping (default: :func:`common_truth` of the recordings).  modes: include the
    geometry-vs-recording modes table (about 2 s per recording).  Returns the path of
    ``index.html``.  Raises :class:`ReportError` (no fit series: the thesis baseline; ``out_dir``
    is a file or a non-empty folder that is not an earlier report), OSError (cannot write).
    """
    recs = list(recs)
    if not result.series:
        raise ReportError("--report needs the prediction-error fit (--model pem): the thesis baseline has no "
                          "predicted output to plot")
    if truth is None:
        truth = common_truth(recs)
    from .pipeline import recording_labels
    labels = recording_labels(recs) if len(recs) == len(result.series) else [s.label for s in result.series]
    title = title or ("inertia identification: " + ", ".join(labels))
    out_dir = Path(out_dir)
    check_report_dir(out_dir)
    parts: list[str] = []
    esc = html.escape
    with atomic_directory(out_dir) as tmp:
        os.chmod(tmp, 0o755)  # a temporary folder is private (0700); a report is for reading
        report_data = {"result": result.to_dict(), "identifiability": [], "modes": []}
        _ellipse_figure(tmp / "ellipses.png", result, truth)
        parts.append(f"<h1>{esc(title)}</h1>")
        parts.append('<p class="note" id="load-status">figures loading…</p>')
        cg = ", ".join(f"{x:.4f}" for x in result.center_of_gravity)
        rows = []
        for lab, s, rec in zip(labels, result.series, recs if len(recs) == len(result.series) else [None] * 99):
            rms = np.sqrt(np.mean(s.residual ** 2, 0))
            rows.append([lab if rec is None else str(rec.path), f"{s.t[-1] - s.t[0]:.1f}", f"{len(s.t)}",
                         f"{s.band_hz[0]:.2f}–{s.band_hz[1]:.2f}",
                         ", ".join(f"{1e3 * x:.3g}" for x in rms)])
        parts.append(f"<p>Mass {result.mass:g} kg, centre of gravity (body) [{cg}] m (rig.yaml). "
                     f"Method: {esc(result.method)}.</p>")
        parts.append(_table(["recording", "window s", "samples", "band Hz", "residual RMS x, y, z mrad/s"], rows))
        for w in result.warnings:
            parts.append(f'<p class="warn">warning: {esc(w)}</p>')

        parts.append("<h2>Inertia tensor about the CG, body axes</h2>")
        head, rows = _tensor_rows(result, truth)
        parts.append(_table(head, rows))
        refined = result.sandwich_std is not None
        parts.append('<p class="note">Entries as geometry_msgs/Inertia: off-diagonals are negated products of '
                     + ("inertia. σ: the sensors' noise, estimated from the recording, propagated through tracker, "
                        "preprocessor and identifier (the CRB column); where the residual shows model error, the "
                        f"fit's own sandwich σ instead (here: {esc(result.uncertainty)}). Second-order bias removed. "
                        if refined else
                        "inertia. σ: sandwich (batch-means) standard deviation, calibrated for coloured residuals; "
                        "the last σ column: the white gyro noise alone. ")
                     + ("Error %: of the entry for diagonals, of the largest diagonal for products. "
                        if truth else "")
                     + "Principal moments: " + ", ".join(f"{x:.1f}" for x in np.linalg.eigvalsh(result.inertia))
                     + " kg·m².</p>")

        if result.diagnosis is not None:
            from .diagnosis import effect_parameters_text
            rb = result.rigid_body["inertia_about_cg"]
            parts.append("<h2>Model error, diagnosed</h2>")
            removed = result.diagnosis["handled"] == "removed from the data"
            parts.append("<p>The rigid-body fit's residual exceeded what the sensors' noise explains; "
                         "<code>rig-identify diagnose</code> named what is below, and "
                         + ("these errors of the data were removed and the recording identified again: the tensor "
                            "above and the plots below are that fit's.</p>" if removed else
                            "the tensor above is the fit with this physics added (σ from its residuals). The plots "
                            "below are the rigid-body fit's.</p>"))
            parts.append(_table(["effect", "parameters", "likelihood ratio"],
                                [[e["name"], effect_parameters_text(e), f"{e['evidence']['likelihood_ratio']:.1f}"]
                                 for e in result.diagnosis["effects"]]))
            parts.append("<p>Rigid-body fit, kg·m²: " + ", ".join(f"{k} {v:.2f}" for k, v in rb.items()) + ".</p>")

        parts.append("<h2>Identifiability: which combinations the recording determines well and poorly</h2>")
        ident = identifiability(result)
        report_data["identifiability"] = ident
        trs = []
        for r in ident:
            cls = ' class="weak"' if r["level"] == "weakly determined" else ""
            trs.append(f"<tr{cls}><td>{esc(r['combination'])}</td><td>{r['std']:.3g}</td>"
                       f"<td>{100 * r['relative_std']:.3g}</td><td>{esc(r['text'])}</td></tr>")
        parts.append('<table class="ident"><thead><tr><th>tensor direction</th><th>σ kg·m²</th>'
                     "<th>σ % of tr J/3</th><th>in words</th></tr></thead><tbody>" + "".join(trs) + "</tbody></table>")
        sig, res = axis_signal(result)
        parts.append('<p class="note">Eigen-directions of the covariance of the six entries (the inverse of the '
                     "information matrix) in the tensor's own (Frobenius) metric, weakest first. Band-passed gyro "
                     "RMS about body x, y, z: " + ", ".join(f"{1e3 * x:.3g}" for x in sig)
                     + " mrad/s; fit residual RMS: " + ", ".join(f"{1e3 * x:.3g}" for x in res) + " mrad/s.</p>")

        parts.append("<h2>Uncertainty ellipses</h2>")
        parts.append('<img src="ellipses.png" alt="uncertainty ellipses of pairs of tensor entries">')

        for n, (lab, s) in enumerate(zip(labels, result.series), 1):
            _fit_figure(tmp / f"fit_{n}.png", s, lab)
            _residual_figure(tmp / f"residuals_{n}.png", s, lab)
            parts.append(f"<h2>Measured vs predicted: {esc(lab)}</h2>")
            parts.append(f'<img src="fit_{n}.png" alt="measured and predicted angular velocity, {esc(lab)}">')
            parts.append(f"<h2>Residuals: {esc(lab)}</h2>")
            parts.append(f'<img src="residuals_{n}.png" alt="residuals and their spectrum, {esc(lab)}">')

        if modes and len(recs) == len(result.series):
            for lab, rec in zip(labels, recs):
                parts.append(f"<h2>Natural modes: {esc(lab)} — geometry vs recording</h2>")
                sec, notes, mdata = _modes_section(rec, result, truth)
                report_data["modes"].append({"recording": lab, **mdata})
                parts.append(sec)
                for w in notes:
                    parts.append(f'<p class="note">note: {esc(w)}</p>')

        page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">" + GENERATOR +
                f"<title>{esc(title)}</title><style>{CSS}</style>"
                f"<script>{LOAD_CHECK_JS}</script></head>\n<body>\n" + "\n".join(parts) + "\n</body></html>\n")
        (tmp / "index.html").write_text(page, encoding="utf-8")
        (tmp / "report.json").write_text(json.dumps(report_data, indent=1))
    return out_dir / "index.html"


__all__ = ["write_report", "check_report_dir", "identifiability", "common_truth", "axis_signal", "ReportError"]
