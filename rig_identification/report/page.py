"""HTML report of an inertia identification (``rig-identify inertia … --report DIR``).

One folder, written atomically (:func:`~rig_identification.io.atomic.atomic_directory`: it appears whole or
not at all) with ``index.html``, PNG figures (matplotlib, Agg, no pyplot state) linked
relatively, and ``report.json`` with the page's numbers.  The page, in the order a test
engineer signs it:

* the validation verdict in words (:attr:`~rig_identification.io.verdict.Validation.summary`) and what it means
  for the numbers (:mod:`rig_identification.report.verdict`): ``model_error`` — the tensor is not trustworthy,
  σ widened; ``not_identifiable`` — the undetermined entries shown as "not determined", with
  what to change;
* date, package version, recordings, rig, method, frame (rig.yaml's body axes, right-handed; where the vehicle's
  front and top lie in them when rig.yaml's ``body.vehicle`` says) and units (SI);
  mass and the centre of gravity the tensor is about;
* the moments and products of inertia about the CG (products with the vehicle-dynamics sign,
  the convention stated once), their σ, the errors against ``truth.yaml`` when there is one,
  the same about the body frame's origin (parallel-axis theorem), the tensor as matrices,
  the principal moments and axes, the equimomental ellipsoid on the body (:mod:`rig_identification.report.mass`);
* the validation checks as a table;
* the identifiability table (:mod:`rig_identification.report.identifiability`), the uncertainty ellipses, per
  recording the fit of the reported model (measured vs predicted angular velocity, as the
  thesis's "comparison of the identified and measured systems"), its residuals and their
  spectrum (:mod:`rig_identification.report.figures`), and the natural modes from the geometry beside those
  in the recording (:mod:`rig_identification.report.modes`).

No number on the page or in report.json is ``nan`` or ``inf``: what does not exist is "—"
on the page and null in the JSON, an undetermined entry "not determined".
``report.json``: ``result`` (:meth:`~rig_identification.estimation.inertia_result.InertiaResult.to_dict`, tensor entries
as geometry_msgs/Inertia), ``report`` (date, version, recordings, rig), ``mass_properties``
(the page's table, products with the vehicle-dynamics sign), ``identifiability``, ``modes``.
"""
from __future__ import annotations

import json
import os
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..estimation.inertia_result import InertiaResult
from ..io.atomic import atomic_directory
from ..io.export import Axes, axes_for
from ..io.package import PACKAGE, package_version
from ..io.recording import Recording, recording_labels
from ..io.rig import Rig
from ..io.vehicle import VEHICLE_AXES, Vehicle, common_vehicle
from ..io.verdict import KEYS
from .figures import edge_seconds, ellipse_figure, ellipsoid_figure, fit_figure, residual_figure
from .folder import Job, ReportError, check_report_dir, rig_label
from .html import bullets, esc, json_safe, num, page, table
from .identifiability import axis_signal, identifiability, identifiability_html
from .mass import (
    axes_html,
    convention,
    mass_properties,
    matrices_html,
    moments_table,
    principal_html,
    to_json,
    truth_rows,
)
from .modes import modes_section
from .verdict import checks_table, verdict_html


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


def header_html(result: InertiaResult, recs: list[Recording], labels: list[str], truth: dict | None,
                when: str, rig: Rig | None, cg_source: str | None, body: Axes, job: Job = Job()) -> tuple[str, dict]:
    """Metadata (the job's fields first where given), mass with its σ and CG (HTML) and the same for
    report.json.  cg_source: where the CG came from when not from rig.yaml (e.g. a static test's
    result file, with its σ); body: rig.yaml's body axes (:func:`~rig_identification.io.export.axes_for`,
    with the vehicle's orientation when known).  The mass's σ is rig.yaml's ``survey.mass`` (default:
    a floor scale's share, :meth:`~rig_identification.io.rig.Survey.mass_std`)."""
    paths = [str(Path(r.path).resolve()) if r.path is not None else lab for r, lab in zip(recs, labels)] if recs \
        else labels
    rigs = sorted({rig_label(r.rig) for r in recs}) if recs else [rig_label(rig) if rig is not None else
                                                                  "not given (in-memory fit)"]
    ver = package_version()
    rows = job.rows() + [["generated", when], ["software", f"{PACKAGE} {ver}"],
            ["recording" + ("s" if len(paths) > 1 else ""), "; ".join(paths) or "not given (in-memory fit)"],
            ["rig", "; ".join(rigs)],
            ["method", result.method],
            ["frame and units", body.label + ("" if body.vehicle is not None else ", the vehicle's orientation in "
                                              "it not stated (rig.yaml body.vehicle)")
             + "; origin the body frame's; SI units (kg, m, kg·m², s, rad)"]]
    meta = "<table class=\"meta\"><tbody>" + "".join(f"<tr><th>{esc(a)}</th><td>{esc(b)}</td></tr>"
                                                    for a, b in rows) + "</tbody></table>"
    cg = ", ".join(num(x, ".4f") for x in result.center_of_gravity)
    tcg = truth.get("center_of_gravity") if truth else None
    where = esc(cg_source) if cg_source else \
        "rig.yaml body.center_of_gravity, as measured — e.g. with <code>rig-identify cg</code>"
    declared = rig.mass if rig is not None else result.mass
    msrc = "rig.yaml body.mass"
    mass_std = rig.survey.mass_std(declared) if rig is not None else None
    sd = "" if mass_std is None else f" ± {num(mass_std, '.3g')} kg (1 σ, rig.yaml survey.mass)"
    mass = (f"<p>Mass <b>{num(result.mass, 'g')} kg</b>{sd} ({esc(msrc)}), centre of gravity "
            f"<b>[{cg}] m</b> in body axes ({where}): the tensor below is about this point."
            + (f" truth.yaml: {num(truth.get('mass'), 'g')} kg at [{', '.join(num(x, '.4f') for x in tcg)}] m."
               if tcg is not None and len(tcg) == 3 else "") + "</p>")
    data = {**job.to_dict(), "mass_std": mass_std,
            "generated": when, "software": PACKAGE, "version": ver, "recordings": paths, "rigs": rigs,
            "center_of_gravity_source": cg_source or "rig.yaml body.center_of_gravity",
            "method": result.method, "frame": body.label,
            "vehicle": None if body.vehicle is None else body.vehicle.to_dict(), "units": "SI"}
    return meta + mass, data


def report_vehicle(recs: list[Recording], rig: Rig | None) -> Vehicle | None:
    """Where the vehicle lies in the body frame: the recordings' rig.yaml ``body.vehicle`` (when
    those that state one agree: :func:`~rig_identification.io.vehicle.common_vehicle`), else ``rig``'s;
    None: not stated."""
    if recs:
        return common_vehicle(r.rig.vehicle for r in recs)[0]
    return None if rig is None else rig.vehicle


def sigma_note(result: InertiaResult) -> str:
    """What the σ of the tensor table are."""
    return ("σ: the identifier's sandwich (batch-means) standard deviation, calibrated for coloured residuals"
            f" ({result.uncertainty}). σ %: of the entry for moments, of the largest moment for products (so are "
            "the error %).")


def recordings_html(result: InertiaResult, recs: list[Recording], labels: list[str]) -> str:
    """The fitted recordings: window, samples, band, residual RMS per axis; then the warnings."""
    rows = []
    for n, (lab, s) in enumerate(zip(labels, result.series)):
        rec = recs[n] if len(recs) == len(result.series) else None
        rms = np.sqrt(np.mean(s.residual ** 2, 0))
        rows.append([lab if rec is None or rec.path is None else str(Path(rec.path).resolve()),
                     num(s.t[-1] - s.t[0], ".1f"),
                     str(len(s.t)), f"{num(s.band_hz[0], '.2f')}–{num(s.band_hz[1], '.2f')}",
                     ", ".join(num(1e3 * x, ".3g") for x in rms)])
    out = table(["recording", "window s", "samples", "band Hz", "residual RMS x, y, z mrad/s"], rows) if rows else \
        "<p>No fit output: the fit could not be made.</p>"
    v = result.validation
    skip = {v.summary} if v is not None else set()
    warns = [w for w in result.warnings if w not in skip and not w.startswith(("model error diagnosed:",
                                                                              "model error not explained:"))]
    if warns:
        out += '<h3>Warnings</h3><div class="warn">' + bullets(warns) + "</div>"
    return out


def write_report(out_dir, result: InertiaResult, recs, truth: dict | None = None, title: str | None = None,
                 modes: bool = True, rig: Rig | None = None, cg_source: str | None = None,
                 axes: str | Axes = "body", job: Job = Job()) -> Path:
    """Write the HTML report of ``result`` to the folder ``out_dir`` (replaced if it exists).

    result: from :func:`~rig_identification.pipeline.offline.identify_recording` or
    :func:`~rig_identification.pipeline.offline.identify_recordings` (model pem: it needs ``result.series`` — except a
    fit that could not be made at all, whose page says so); recs: the Recording(s) it was
    fitted to, in the same order (may be empty for an in-memory fit).  truth: truth.yaml
    mapping (default: :func:`common_truth` of the recordings).  modes: include the
    geometry-vs-recording modes table (about 2 s per recording).  rig: the rig drawn under the
    principal axes and named in the header (default: the first recording's).  cg_source: where
    the CG came from when not from rig.yaml (``rig-identify inertia --cg FILE``: the static
    test's file and σ), said beside the CG.  axes: the axes the lab reads its numbers in
    (rig.yaml ``output_axes``, ``--axes``: an :class:`~rig_identification.io.export.Axes` or a name of
    :data:`~rig_identification.io.export.AXES`, made with the vehicle's orientation of the recordings' rig.yaml,
    else of ``rig``): other than ``body``, a section gives the mass properties in them too (the page's tables
    stay in rig.yaml's body axes, as the JSON).  The moments are called roll, pitch and yaw only when rig.yaml
    says where the vehicle lies (``body.vehicle``).  job: the vehicle, customer and operator the header
    names (:class:`Job`).  Returns the path of ``index.html``.  Raises
    :class:`ReportError` (no fit series: the thesis baseline; ``out_dir`` is a file or a non-empty folder that
    is not an earlier report), :class:`~rig_identification.io.vehicle.AxesError` (vehicle axes without
    ``body.vehicle``), OSError (cannot write).
    """
    recs = list(recs)
    vehicle = report_vehicle(recs, rig)
    shown = axes if isinstance(axes, Axes) else axes_for(axes, vehicle)
    if not result.series and np.all(np.isfinite(result.inertia)):
        raise ReportError("--report needs the prediction-error fit (--model pem): the thesis baseline has no "
                          "predicted output to plot")
    if truth is None:
        truth = common_truth(recs)
    matched = bool(recs) and len(recs) == len(result.series)
    labels = recording_labels(recs) if (matched or not result.series) and recs else \
        [s.label or f"recording {i + 1}" for i, s in enumerate(result.series)]
    title = title or ("inertia identification" + (": " + ", ".join(labels) if labels else ""))
    out_dir = Path(out_dir)
    check_report_dir(out_dir)
    when = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    mp = mass_properties(result, vehicle)
    errors = truth_rows(result, truth)
    parts: list[str] = [f"<h1>{esc(title)}</h1>", verdict_html(result)]
    rig = rig if rig is not None else recs[0].rig if recs else None
    head, head_data = header_html(result, recs, labels, truth, when, rig, cg_source, mp.axes, job)
    parts.append(head)
    with atomic_directory(out_dir) as tmp:
        os.chmod(tmp, 0o755)  # a temporary folder is private (0700); a report is for reading
        v = result.validation
        untrusted = v is not None and v.verdict == "model_error"
        parts.append("<h2>Moments and products of inertia about the CG</h2>")
        if untrusted:
            parts.append('<p class="untrusted">Not trustworthy (verdict model_error): the σ are a lower bound of '
                         "the error.</p>")
        parts.append(moments_table(mp, errors, "σ white gyro noise alone"))
        parts.append(f'<p class="note" id="convention">{esc(convention(mp.axes))} {esc(sigma_note(result))}</p>')
        parts.append("<h3>The tensor as a matrix</h3>" + matrices_html(mp))
        parts.append("<h3>Principal moments and axes</h3>" + principal_html(mp))
        in_axes = None
        if shown.name != "body":
            ex = result.expressed(shown)
            parts.append(f"<h3>In {esc(VEHICLE_AXES[shown.name][0])} axes</h3>" + axes_html(ex))
            in_axes = {"axes": ex.axes.name, "label": ex.axes.label, "center_of_gravity": [float(x) for x in ex.cg],
                       "inertia_about_cg": ex.entries(), "products_of_inertia": ex.products(),
                       "inertia_about_origin": ex.entries("origin")}
        if ellipsoid_figure(tmp / "principal_axes.png", mp, rig):
            parts.append('<p class="note">Principal axes about the CG, each drawn as the semi-axis of the equimomental '
                         "ellipsoid along it (the uniform solid ellipsoid with the body's mass and tensor: the mass is "
                         "spread farthest along the axis of the smallest moment).</p>"
                         '<img src="principal_axes.png" alt="principal axes and equimomental ellipsoid on the body">')

        parts.append("<h2>Validation checks</h2>")
        parts.append(checks_table(v) if v is not None and v.checks else "<p>No validation was run on this fit.</p>")

        parts.append("<h2>Recordings fitted</h2>" + recordings_html(result, recs, labels))

        parts.append("<h2>Identifiability: which combinations the recording determines well and poorly</h2>")
        ident = identifiability(result)
        parts.append(identifiability_html(result, ident))

        parts.append("<h2>Uncertainty ellipses</h2>")
        if ellipse_figure(tmp / "ellipses.png", result, truth):
            parts.append('<img src="ellipses.png" alt="uncertainty ellipses of pairs of moments and products">'
                         '<p class="note">2-D marginals of the covariance: the 1σ ellipse holds 39 % of a 2-D '
                         "Gaussian, the 2σ 86 %.</p>")
        else:
            parts.append("<p>Not drawn: the covariance is not determined.</p>")

        for n, (lab, s) in enumerate(zip(labels, result.series), 1):
            fit_figure(tmp / f"fit_{n}.png", s, lab)
            residual_figure(tmp / f"residuals_{n}.png", s, lab)
            parts.append(f"<h2>Measured vs predicted: {esc(lab)}</h2>")
            parts.append(f'<img src="fit_{n}.png" alt="measured and predicted angular velocity, {esc(lab)}">')
            parts.append('<p class="note">The model whose tensor this page reports'
                         f". Shaded: the band-pass filter's edge transients ({edge_seconds(s):.1f} s at each "
                         "end).</p>")
            parts.append(f"<h2>Residuals: {esc(lab)}</h2>")
            parts.append(f'<img src="residuals_{n}.png" alt="residuals and their spectrum, {esc(lab)}">')

        mode_data = []
        if modes and matched:
            for lab, rec in zip(labels, recs):
                parts.append(f"<h2>Natural modes: {esc(lab)} — geometry vs recording</h2>")
                sec, notes, mdata = modes_section(rec, result, truth, cg_source)
                mode_data.append({"recording": lab, **mdata})
                parts.append(sec)
                parts.extend(f'<p class="note">note: {esc(w)}</p>' for w in notes)

        report_data = {"result": result.to_dict(), "report": head_data, "mass_properties": to_json(mp, errors),
                       "identifiability": ident, "modes": mode_data}
        if in_axes is not None:
            report_data["output_axes"] = in_axes
        (tmp / "index.html").write_text(page(title, parts), encoding="utf-8")
        (tmp / "report.json").write_text(json.dumps(json_safe(report_data), indent=1, allow_nan=False))
    return out_dir / "index.html"


__all__ = ["write_report", "identifiability", "common_truth", "axis_signal", "json_safe", "package_version"]
