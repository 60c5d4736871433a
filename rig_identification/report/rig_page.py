"""HTML report of the rig model's fit (``rig-identify inertia REC --report DIR``).

One folder, written atomically (:func:`~rig_identification.io.atomic.atomic_directory`) with
``index.html``, PNG figures and ``report.json``.  The page, in the order a test engineer signs it:
the verdict (:attr:`~rig_identification.pipeline.rig_model.RigModelResult.summary`); the job, date,
software, recording, rig, method, frame and units; the mass and the centre of gravity from the
static test, the run alone and both (:class:`~rig_identification.pipeline.rig_model.CentreOfGravity`);
the moments and products of inertia about the CG with σ, the Cramér–Rao bound and the errors
against ``truth.yaml`` when there is one (:mod:`rig_identification.report.mass`), the matrices,
principal moments and axes and the equimomental ellipsoid; what the model leaves out
(:func:`diagnosis_html`); every channel's residual against its
noise; the cables and load cells; the other minima the restarts found; and, per sensor group,
the measured readings beside the model's (:func:`~rig_identification.report.figures.channels_figure`).

No number on the page or in report.json is ``nan`` or ``inf``.  ``report.json``: ``result``
(:meth:`~rig_identification.pipeline.rig_model.RigModelResult.to_dict`), ``report`` (job, date,
version, recording, rig), ``mass_properties`` (the page's table, products with the
vehicle-dynamics sign).
"""
from __future__ import annotations

import json
import os
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_directory
from ..io.export import Axes, axes_for
from ..io.recording import Recording
from ..io.vehicle import VEHICLE_AXES
from ..io.verdict import KEYS, PACKAGE, package_version
from ..model.parametrisation import to_tensor
from ..pipeline.rig_model import LEVEL_LIMIT, RigModelResult
from .figures import CHANNEL_GROUPS, channels_figure, ellipsoid_figure
from .folder import Job, check_report_dir, rig_label
from .html import esc, json_safe, num, page, table
from .mass import (
    SIGN,
    axes_html,
    convention,
    mass_properties_of,
    matrices_html,
    moments_table,
    principal_html,
    to_json,
)

#: What the rig model is, as the header says it.
METHOD = ("the rig's grey-box model (rigid body on elastic cables, driven by the measured exciter force), every "
          "sensor an output — tensions, gyro, accelerometer, inclinometer — fitted by prediction error (output "
          "error, multiple shooting); mass, CG, cable stiffness and damping, load-cell gains, the initial state and "
          "the surveyed geometry fitted with their priors")


def truth_errors(res: RigModelResult, d: dict) -> dict | None:
    """The errors against truth.yaml as the main table takes them, products with the
    vehicle-dynamics sign: {key: {"truth", "error" kg·m², "error_percent", "error_sigma"}}, or None;
    ``d``: ``res.to_dict()``."""
    cmp = d.get("truth_comparison")
    if not cmp:
        return None
    out = {}
    for k, s, v in zip(KEYS, SIGN, res.fit.inertia):
        e = cmp[k]
        out[k] = {"truth": s * e["truth"], "error": s * (float(v) - e["truth"]),
                  "error_percent": s * e["error_percent"], "error_sigma": s * e["error_sigma"]}
    return out


def cg_html(res: RigModelResult, d: dict) -> str:
    """The mass and the CG from each test (mm, σ), and whether the two tests agree; ``d``:
    ``res.to_dict()``."""
    f = res.fit
    cg = res.cg
    rows = [[name, ", ".join(num(1e3 * x, ".1f") for x in v), ", ".join(num(1e3 * x, ".2g") for x in s), what]
            for name, v, s, what in (("static", cg.static, cg.static_std, cg.static_source),
                                     ("dynamic", cg.dynamic, cg.dynamic_std, "the swinging body alone"),
                                     ("combined", cg.combined, cg.combined_std,
                                      "the fit's: the tensor is about this point, its σ in the tensor's"))]
    agree = cg.difference_sigma
    words = "not compared (one of them is not determined)" if not np.any(np.isfinite(agree)) else (
        ("agree" if cg.agree else "DISAGREE") + " (" + ", ".join(num(x, "+.1f") for x in agree) + " σ)")
    return (f"<p>Mass <b>{num(f.body.mass, '.2f')} ± {num(d['mass_std'], '.2g')} kg</b> (the scale's value, "
            f"a prior of σ {num(d['survey']['mass_kg'], '.3g')} kg)"
            + (f"; the body without the exciter's rotor, its {num(d['exciter_rotor_removed_kg'], '.2f')} kg on the "
               "spin axis taken out of the suspended body's mass, CG and tensor"
               if d["exciter_rotor_removed_kg"] else "")
            + ".</p>"
            + table(["centre of gravity", "x, y, z mm (body axes)", "σ mm", "from"], rows, ident="cg-table")
            + f"<p>Static and dynamic test: {esc(words)}.</p>")


def channels_html(res: RigModelResult) -> str:
    """Each channel's residual in the band over its noise, and whether it fits."""
    f = res.fit
    rows = [[c, num(v, ".2f"), num(s, ".2f"), "yes" if v <= LEVEL_LIMIT else "NO"]
            for c, v, s in zip(f.channels, f.residual_level, f.noise_scale)]
    return (table(["channel", "residual over noise", "noise raised ×", f"fits (≤ {LEVEL_LIMIT:g})"], rows,
                  ident="channels-table")
            + '<p class="note">1: noise alone.  A channel that does not fit has its noise raised to its residual\'s '
              "level: the fit leans on those that do.</p>")


def cables_html(res: RigModelResult) -> str:
    """The cables' stiffness and the load cells' gains, the damping time."""
    p = res.fit.parameters
    rows = [[f"{i + 1}", num(k / 1e6, ".4g"), num(g, ".4f")] for i, (k, g) in enumerate(zip(p.stiffness, p.gain))]
    return (table(["cable", "stiffness MN/m", "load-cell gain"], rows, ident="cables-table")
            + f"<p>Cable damping time {num(1e3 * p.damping_time, '.3g')} ms.</p>")


def minima_html(res: RigModelResult) -> str:
    """The other minima the restarts settled in, in σ of the estimate, with their χ²."""
    f = res.fit
    rows = [[", ".join(num((a - b) / s, "+.1f") for a, b, s in zip(m, f.inertia, f.inertia_std)), num(c, ".2f"),
             "" if e is None else "settled" if e else "budget spent: no minimum"]
            for m, c, e in zip(f.other_minima, f.other_chi2, f.minima_settled)]
    return (table(["settled from the estimate, σ (ixx, ixy, ixz, iyy, iyz, izz)", "χ² over the estimate's",
                   "restart"], rows, ident="minima-table")
            + '<p class="note">The whole-record fit restarted with every entry 1 % away, once each way, 10 σ '
              "either way along the tensor's weakest direction, and from the gyro-only fit's tensor: another "
              "minimum more than 3 σ off at a χ² within 12.6 makes those entries ambiguous (verdict "
              "not_identifiable).</p>")


def diagnosis_html(res: RigModelResult) -> str:
    """What the model leaves out: the data errors, each extension tested (its fall of χ², whether
    significant, plausible, cross-validated, told apart), the damping's alternatives, the advice and
    each channel's residual before and after the refit."""
    dg = res.diagnosis
    if dg is None:
        return "<p>Not tested.</p>"
    out = []
    if dg.conflicts:
        rows = [[c.unknown, num(c.estimate, ".6g"), num(c.std, ".2g"), num(c.prior, ".6g"), num(c.prior_std, ".2g"),
                 num(c.z, "+.1f")] for c in dg.conflicts]
        out.append("<h3>Data errors</h3>" + table(["unknown", "fitted", "σ", "given", "σ given", "off, σ given"], rows,
                                                  ident="data-errors-table"))
    for i, st in enumerate(dg.steps, 1):
        rows = [[c.name, num(c.statistic, ".1f"), num(c.threshold, ".1f"), "yes" if c.plausible else "no",
                 "yes" if c.cross_validated else "no", num(st.vuong[c.name], "+.1f") if c.name in st.vuong else ""]
                for c in sorted(st.candidates, key=lambda c: -c.statistic)]
        word = ("named" if st.named else f"not told apart from {', '.join(st.indistinguishable)}; the model takes it") \
            if dg.explained else "named: the motion asks for what another sensor measures" if st.added in dg.named \
            else "not named: the model with it still does not fit"
        if st.restart:
            word += "; fitted from the value the recording gives it, where the rigid-body fit had not found the motion"
        out.append(f"<h3>Step {i}: {esc(st.added)} added ({esc(word)})</h3>"
                   + table(["extension", "χ² fall", "threshold", "plausible", "cross-validated",
                            "Vuong z of the best over it"], rows, ident=f"step-{i}-table"))
    if not dg.steps and dg.determined:
        out.append("<p>No extension is significant, plausible and cross-validated.</p>")
    if dg.damping is not None:
        out.append("<p>Viscous damping " + num(float(max(dg.damping.significance)), ".0f") + " σ; in its place "
                   + ", ".join(f"{esc(e)} Vuong z {num(z, '+.1f')}" for e, z in dg.damping.alternatives.items())
                   + " (positive: viscous fits better)"
                   + ("" if dg.damping.found else "; not named: it fails an extension's plausibility or "
                      "cross-validation (held out χ² fall " + ", ".join(num(v, ".1f") for v in dg.damping.held_out)
                      + ")") + ".</p>")
    if dg.gyro is not None and dg.gyro.found:
        out.append("<p>Gyro bias (the offset the fit removed): "
                   + ", ".join(f"{num(a, '.3g')} ± {num(b, '.1g')}" for a, b in zip(dg.gyro.values, dg.gyro.std))
                   + f" rad/s, IMU axes ({'named' if 'gyro_bias' in dg.named else 'not named'}).</p>")
    if dg.advice:
        out.append("<ul>" + "".join(f"<li>{esc(a)}</li>" for a in dg.advice) + "</ul>")
    if dg.refit is not None:
        rows = [[c, num(a, ".2f"), num(b, ".2f")] for c, a, b in zip(dg.rigid.channels, dg.rigid.residual_level,
                                                                      dg.refit.residual_level)]
        out.append(table(["channel", "residual over noise, rigid-body model", "with the extensions"], rows,
                         ident="before-after-table"))
    return "".join(out)


def write_rig_report(out_dir, res: RigModelResult, rec: Recording, axes: str | Axes = "body",
                     job: Job = Job()) -> Path:
    """Write the report of ``res`` (the rig model fitted to ``rec``) to the folder ``out_dir``
    (replaced if it is an earlier report).  axes: the vehicle axes the lab reads its numbers in
    (a section gives the mass properties in them when not ``body``).  Returns the path of
    ``index.html``.  Raises :class:`~rig_identification.report.folder.ReportError` (``out_dir`` a
    file or a folder that is not an earlier report), OSError (cannot write)."""
    out_dir = Path(out_dir)
    check_report_dir(out_dir)
    f = res.fit
    vehicle = rec.rig.vehicle
    shown = axes if isinstance(axes, Axes) else axes_for(axes, vehicle)
    mp = mass_properties_of(f.body.mass, f.body.cg, to_tensor(f.inertia), f.inertia_std, f.body.covariance[:6, :6],
                            f.crb, res.withheld, vehicle)
    result = res.to_dict()
    errors = truth_errors(res, result)
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    label = Path(res.path).name
    title = f"inertia identification (the rig model): {label}"
    meta = job.rows() + [["generated", when], ["software", f"{PACKAGE} {package_version()}"],
                         ["recording", str(Path(res.path).resolve())], ["rig", rig_label(rec.rig)],
                         ["span", f"{res.start_s:.1f}–{res.start_s + res.duration_s:.1f} s from the first IMU sample, "
                                  f"band 0–{res.band_hz:.2f} Hz"],
                         ["method", METHOD], ["frame and units", mp.axes.label + "; SI units (kg, m, kg·m², s, rad)"]]
    cls = {"ok": "ok", "model_error": "model_error"}.get(res.verdict, "not_identifiable")
    parts = [f"<h1>{esc(title)}</h1>",
             f'<div class="verdict {cls}" id="verdict"><p class="sentence">{esc(res.summary)}</p></div>',
             '<table class="meta"><tbody>' + "".join(f"<tr><th>{esc(a)}</th><td>{esc(b)}</td></tr>" for a, b in meta)
             + "</tbody></table>",
             "<h2>Mass and centre of gravity</h2>", cg_html(res, result),
             "<h2>Moments and products of inertia about the CG</h2>"]
    if res.verdict != "ok":
        parts.append(f'<p class="untrusted">Not an estimate to sign (verdict {esc(res.verdict)}): see the verdict.</p>')
    parts += [moments_table(mp, errors, "Cramér–Rao bound"),
              f'<p class="note" id="convention">{esc(convention(mp.axes))} σ: the larger of the inverse Fisher '
              "information and the sandwich, the CG, mass, cables, load cells and surveyed geometry fitted with their "
              "priors (their uncertainty is in it); Cramér–Rao bound: this run's at the sensors' own noise.</p>",
              "<h3>The tensor as a matrix</h3>" + matrices_html(mp),
              "<h3>Principal moments and axes</h3>" + principal_html(mp)]
    in_axes = None
    if shown.name != "body":
        ex = res.expressed(shown)
        parts.append(f"<h3>In {esc(VEHICLE_AXES[shown.name][0])} axes</h3>" + axes_html(ex))
        in_axes = {"axes": ex.axes.name, "center_of_gravity": [float(x) for x in ex.cg],
                   "inertia_about_cg": ex.entries(), "products_of_inertia": ex.products()}
    parts += ["<h2>What the model leaves out</h2>", diagnosis_html(res),
              "<h2>Every channel against its noise</h2>", channels_html(res),
              "<h2>Cables and load cells</h2>", cables_html(res),
              "<h2>Restarts: other minima</h2>", minima_html(res)]
    if res.warnings:
        parts.append('<h3>Warnings</h3><div class="warn"><ul>' + "".join(f"<li>{esc(w)}</li>" for w in res.warnings)
                     + "</ul></div>")
    with atomic_directory(out_dir) as tmp:
        os.chmod(tmp, 0o755)  # a temporary folder is private (0700); a report is for reading
        if ellipsoid_figure(tmp / "principal_axes.png", mp, rec.rig):
            parts.insert(parts.index("<h2>Every channel against its noise</h2>"),
                         '<img src="principal_axes.png" alt="principal axes and equimomental ellipsoid on the body">')
        s = f.series
        for prefix, name, _, _ in CHANNEL_GROUPS:
            png = f"fit_{name.replace(' ', '_')}.png"
            if channels_figure(tmp / png, s.t, s.measured, s.predicted, s.channels, prefix, label):
                parts.append(f"<h2>Measured vs the model: {esc(name)}</h2>"
                             f'<img src="{png}" alt="measured and predicted {esc(name)}">')
        data = {"result": result,
                "report": {**job.to_dict(), "generated": when, "software": PACKAGE, "version": package_version(),
                           "recording": str(Path(res.path).resolve()), "rig": rig_label(rec.rig), "method": METHOD,
                           "frame": mp.axes.label, "units": "SI"},
                "mass_properties": to_json(mp, errors)}
        if in_axes is not None:
            data["output_axes"] = in_axes
        (tmp / "index.html").write_text(page(title, parts), encoding="utf-8")
        (tmp / "report.json").write_text(json.dumps(json_safe(data), indent=1, allow_nan=False))
    return out_dir / "index.html"


__all__ = ["write_rig_report", "truth_errors", "diagnosis_html", "METHOD"]
