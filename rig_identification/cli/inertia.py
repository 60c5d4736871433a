"""``rig-identify inertia`` with the gyro-only prediction-error fit of one recording: ``--model pem|thesis``
or ``--quick`` (:func:`~rig_identification.cli.arg_types.resolve_model`; the default, the rig model,
and the joint fit of several recordings are :mod:`rig_identification.cli.rig_model`'s).  Its output,
in this order: the verdict
(:attr:`~rig_identification.io.verdict.Validation.summary`), the recording, the conventions
(frame, units, sign: :func:`~rig_identification.io.export.convention_lines`), mass and CG, the
window, the tensor about the CG with σ (and the truth when truth.yaml is there), the products
of inertia with the vehicle-dynamics sign, the principal moments and axes, the tensor about the
body frame's origin, what σ is, the precision against ``--target``
(:mod:`~rig_identification.estimation.precision`), the bias correction, the
validation's checks and the most weakly determined combination.  ``--json`` prints
:meth:`~rig_identification.estimation.inertia_result.InertiaResult.to_dict`
instead; ``--urdf`` adds a URDF ``<inertial>`` element and ``--yaml FILE`` writes
:func:`~rig_identification.io.export.export_dict` (atomically).
"""
from __future__ import annotations

import json
import sys
from dataclasses import replace
from datetime import datetime, timezone

import numpy as np

from ..estimation.gyro_fit import IdentificationError
from ..estimation.inertia_result import InertiaResult, compare_to_truth
from ..io.atomic import atomic_write_text
from ..io.export import (
    Axes,
    axes_block,
    axes_for,
    convention_lines,
    entries_from_option,
    export_dict,
    urdf_inertial,
    yaml_text,
)
from ..io.package import package_version
from ..io.vehicle import common_vehicle
from ..io.verdict import KEYS
from ..pipeline.offline import (
    identify_recording,
    with_cg_uncertainty,
)
from ..report.folder import ReportError
from ..report.page import write_report
from ..statics.handover import load_cg_result
from .arg_types import UsageError
from .progress import heading, step, warn
from .recordings import check_common, output_axes, read_all
from .rig_model import job_of
from .text import (
    TABLE_CAPTION,
    fmt,
    origin_line,
    principal_lines,
    tensor_entries_line,
    tensor_table,
)


def truth_columns(result: InertiaResult, truth: dict | None, axes: Axes) -> dict | None:
    """truth.yaml's comparison (:func:`~rig_identification.estimation.inertia_result.compare_to_truth`) in
    ``axes``: each column turned as the entries (:attr:`~rig_identification.io.export.Axes.entry_map`, a signed
    permutation: an entry's truth, error % and error / σ are those of the body entry it is)."""
    if not truth or "inertia_about_cg" not in truth:
        return None
    cmp = compare_to_truth(result, truth)
    T = axes.entry_map
    cols = {f: T @ np.array([cmp[k][f] for k in KEYS], float) for f in ("truth", "error_percent", "error_sigma")}
    return {k: {f: float(cols[f][r]) + 0.0 for f in cols} for r, k in enumerate(KEYS)}


def window_line(result: InertiaResult, t0: float) -> str:
    """The fit window in seconds from the first IMU sample (as --start/--end take them)."""
    return (f"window: {result.t_start - t0:.1f}–{result.t_end - t0:.1f} s from the first IMU sample "
            f"({result.t_end - result.t_start:.1f} s, {result.n_samples} samples); "
            f"band {fmt(result.band_hz[0])}–{fmt(result.band_hz[1])} Hz")


#: what σ leaves out, said with every tensor (a CG error moves the tensor: the tutorial's step 6)
GIVEN_EXACT = ("σ leaves out the mass and centre of gravity given above: they are taken as exact; the tensor's "
               "error from an error of the CG is not in σ (docs/tutorial.md, step 6)")


def cg_in_sigma_line(result: InertiaResult) -> str:
    """What the CG's σ adds to the tensor's σ (``cg_contribution_std``), per entry."""
    c = result.cg_contribution_std
    assert c is not None
    return ("σ includes the centre of gravity's σ (the tensor refitted with the CG ±1 σ along each principal axis "
            "of its covariance); its share, kg·m²: " + ", ".join(f"{k} {fmt(x, '.3g')}" for k, x in zip(KEYS, c))
            + "; the mass is taken as exact")


def std_line(result: InertiaResult) -> str:
    """What σ is: the gyro-only fit's sandwich, from its residuals."""
    return (f"σ: from the fit's residuals ({result.uncertainty}; the gyro-only fit does not propagate the sensors' "
            "noise: the rig model's σ, rig-identify inertia without --model pem/--quick, is the Cramér–Rao bound's)")


BRIEF_TAIL = ("(-q: the short result; without -q also the tensor entries, principal axes, σ's source and "
              "every check; --json gives everything)")


def print_inertia(result: InertiaResult, truth: dict | None, paths: list, t0s: list[float], axes: str | Axes,
                  cg_source: str, brief: bool = False) -> None:
    """The text output of ``rig-identify inertia`` (see the module docstring); ``axes``: of
    :func:`output_axes` (a name: made without the vehicle's orientation).  ``brief`` (``-q``): the
    verdict, the conventions, the mass and CG, the table, whether σ carries the CG's, and the
    checks that failed, then a line that says where the rest is."""
    axes = axes_for(axes) if isinstance(axes, str) else axes
    d = result.to_dict(t0=t0s[0] if len(t0s) == 1 else t0s)
    ex = result.expressed(axes)
    print(result.validation.summary if result.validation is not None else
          "verdict: none — this fit has no model validation (the thesis's baseline)")
    print(f"recording: {paths[0]}")
    for line in convention_lines(axes):
        print(line)
    print(f"mass {ex.mass:.2f} kg (rig.yaml body.mass) and centre of gravity ({', '.join(f'{x:.4f}' for x in ex.cg)}) "
          f"m ({cg_source}): given, not identified by the dynamic test")
    print(window_line(result, t0s[0]))
    print(TABLE_CAPTION)
    for line in tensor_table(ex, truth_columns(result, truth, axes)):
        print(line)
    if brief:
        print(GIVEN_EXACT if result.cg_contribution_std is None else cg_in_sigma_line(result))
        for c in result.validation.checks if result.validation is not None else []:
            if c.passed is False:
                print(f"check FAIL {c.name}: {c.detail}")
        print(BRIEF_TAIL)
        return
    print(tensor_entries_line(ex))
    for line in principal_lines(ex):
        print(line)
    print(origin_line(ex))
    print(std_line(result))
    print(result.precision.text())
    print(GIVEN_EXACT if result.cg_contribution_std is None else cg_in_sigma_line(result))
    if result.validation is not None:
        for c in result.validation.checks:
            mark = "pass" if c.passed else ("FAIL" if c.passed is False else "n/a ")
            print(f"check {mark} {c.name}: {c.detail}")
    for w in d["weakly_determined"][:1]:
        print("note: " + w["text"])


def with_saved_cg(recs: list, cg_file: str) -> tuple[list, str, np.ndarray]:
    """The recordings with the CG of a saved ``rig-identify cg --json`` result, the note, and the
    CG's covariance (3, 3) m²."""
    saved = load_cg_result(cg_file)
    out = []
    for r in recs:
        own = r.rig.center_of_gravity
        if own is not None and np.any(np.abs(own - saved.center_of_gravity) > 3 * saved.center_of_gravity_std):
            warn(f"{r.path}: rig.yaml's body.center_of_gravity {np.round(own, 4).tolist()} m differs from "
                 f"{cg_file}'s {np.round(saved.center_of_gravity, 4).tolist()} m by more than 3 σ; using {cg_file}")
        out.append(replace(r, rig=r.rig.with_cg(saved.center_of_gravity)))
    note = f"centre of gravity from {cg_file} (σ " + ", ".join(f"{1e3 * x:.2g}" for x in
                                                               saved.center_of_gravity_std) + " mm)"
    if saved.verdict == "model_error":
        note += ": its static fit's verdict was model_error, the CG may be off"
    return out, note, np.asarray(saved.covariance, float)


def check_options(args) -> None:
    """Refuse option combinations the gyro-only fit cannot run, before reading any bag
    (``args.model``: ``pem`` or ``thesis``, :func:`~rig_identification.cli.arg_types.resolve_model`)."""
    paths = args.recording
    if len(paths) > 1:
        raise UsageError(f"--model {args.model}{' / --quick' if args.quick else ''} fits one recording at a time: "
                         "several recordings of one body are fitted at once by the rig model (the default: "
                         "leave out --model and --quick)")
    if args.report and args.model == "thesis":
        raise IdentificationError("--report needs --model rig or pem (the thesis baseline has no predicted "
                                  "output to plot)")
    check_common(args)


def identify(args, recs: list) -> InertiaResult:
    """The fit the options ask for (of the one recording)."""
    band = tuple(args.band) if args.band else None
    heading("identifying (tracker, preprocessor, fit, validation)")
    guess = None if args.initial_guess is None else entries_from_option(args.initial_guess)
    return identify_recording(recs[0], start=args.start, end=args.end, band_hz=band, model=args.model,
                              initial_guess=guess)


def cg_uncertainty(args, recs: list, result: InertiaResult, cg_cov: np.ndarray) -> InertiaResult:
    """The CG's σ (from ``--cg``) carried into the tensor's
    (:func:`~rig_identification.pipeline.offline.with_cg_uncertainty`)."""
    heading("carrying the CG's σ into the tensor's (the tensor refitted with the CG ±1 σ)")
    return with_cg_uncertainty(recs[0], result, cg_cov, args.start, args.end)


def cmd_inertia(args) -> int:
    """``rig-identify inertia --model pem|thesis`` (also ``--quick``: the gyro-only fit) of one
    recording; returns the exit status (user errors raise, see cli.user_errors)."""
    check_options(args)
    recs = read_all(args.recording)
    cg_source = "rig.yaml body.center_of_gravity"
    cg_note = None
    cg_cov = None
    if args.cg:
        recs, cg_note, cg_cov = with_saved_cg(recs, args.cg)
        cg_source = f"from {args.cg}"
    axes, axes_notes = output_axes(args.axes, recs)
    for note in axes_notes:
        warn(note)
    result = identify(args, recs)
    if cg_cov is not None:
        result = cg_uncertainty(args, recs, result, cg_cov)
    result = replace(result, precision_target=(1.0 if args.target is None else args.target) / 100,
                     warnings=([] if cg_note is None else [cg_note]) + result.warnings)
    t0s = [float(r.sensors.t_start) for r in recs]
    # where the CG came from, as the report's header says it: "from CG.json (σ x, y, z mm)" or rig.yaml's
    cg_origin = cg_source if cg_note is None else cg_note.removeprefix("centre of gravity ")
    index = None
    if args.report:
        step(f"writing the report to {args.report}")
        try:
            # the report says where the CG came from: "from CG.json (σ x, y, z mm)"
            index = write_report(args.report, result, recs, cg_source=None if cg_note is None else cg_origin,
                                 axes=axes, job=job_of(args))
        except OSError as e:
            raise ReportError(f"{args.report}: cannot write the report ({e.strerror or e})") from None
    body = result.expressed("body")
    urdf = urdf_inertial(body) if args.urdf else None
    if args.yaml:
        ex = result.expressed(axes)
        d = result.to_dict(t0=t0s[0] if len(t0s) == 1 else t0s)
        content = export_dict(ex, verdict=None if result.validation is None else result.validation.verdict,
                              summary=None if result.validation is None else result.validation.summary,
                              std_kind=result.uncertainty, sources=[str(r.path) for r in recs],
                              window=d["window"] if len(recs) == 1 else None,
                              created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                              version=package_version())
        content["center_of_gravity_source"] = cg_origin   # an archived result says where its CG came from
        atomic_write_text(args.yaml, yaml_text(content))
    args.progress.finish()
    if args.json:
        d = result.to_dict(t0=t0s[0] if len(t0s) == 1 else t0s)
        d["center_of_gravity_source"] = cg_origin
        vehicle = common_vehicle(r.rig.vehicle for r in recs)[0]
        d["vehicle"] = None if vehicle is None else vehicle.to_dict()   # rig.yaml's body.vehicle
        if axes.name != "body":
            d[axes.json_key] = axes_block(result.expressed(axes))
        if urdf is not None:
            d["urdf_inertial"] = urdf
        print(json.dumps(d))
    else:
        print_inertia(result, recs[0].truth,
                      [r.path for r in recs], t0s, axes, cg_source, brief=bool(getattr(args, "quiet", False)))
        if urdf is not None:
            print("URDF inertial element (link frame: rig.yaml's body frame; ixy, ixz, iyz: the tensor's entries):")
            print(urdf)
    args.progress.warn_rest(result.warnings)   # those not shown as they happened; also in the JSON
    out = sys.stderr if args.json else sys.stdout
    if args.yaml:
        print(f"yaml: {args.yaml}", file=out)
    if index is not None:
        print(f"report: {index}", file=out)
    return 0
