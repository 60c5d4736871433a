"""``rig-identify inertia``: the whole recording read by the rig's grey-box model.

Prints the fit's span and band, the tensor about the CG with σ, the Cramér–Rao bound and σ/CRB
(and the truth when truth.yaml is there), the mass, the centre of gravity the dynamic test
gives beside the static one, the cables' stiffness and damping, the load cells' gains, each
channel's residual against its noise, and what the numbers assume.  ``--json`` prints
:meth:`~rig_identification.pipeline.rig_model.RigModelResult.to_dict` instead.
"""
from __future__ import annotations

import json
import sys
from datetime import datetime, timezone
from typing import TYPE_CHECKING

import numpy as np

from ..diagnosis.rig_diagnosis import RigDiagnosis
from ..estimation.rig_fit import REWEIGHT_LIMIT, RigFit
from ..estimation.rig_unknowns import EXTENSIONS
from ..io.atomic import atomic_write_text
from ..io.export import (
    BODY,
    NOT_DETERMINED,
    ORDER,
    VEHICLE_SIGN,
    Axes,
    axes_block,
    convention_lines,
    export_dict,
    urdf_inertial,
    yaml_text,
)
from ..io.recording import Recording
from ..io.verdict import KEYS, package_version
from ..pipeline.rig_model import (
    CONSISTENCY_SIGMA,
    LEVEL_LIMIT,
    CentreOfGravity,
    RigModelResult,
    fit_whole_recording,
)
from ..report.folder import Job, ReportError
from .arg_types import JOB_OPTIONS
from .progress import heading, step, warn
from .recordings import check_common, output_axes, read_all
from .text import TABLE_CAPTION, origin_line, principal_lines, tensor_entries_line, tensor_table

if TYPE_CHECKING:                     # the joint fit's modules load only for several recordings (cli.joint)
    from ..pipeline.joint import JointResult

#: What the σ of the rig model are (the YAML export's ``std_is``).
STD_IS = ("the larger of the inverse Fisher information and the sandwich, the CG, mass, cables, load cells and "
          "surveyed geometry fitted with their priors")


def job_of(args) -> Job:
    """The report's :class:`~rig_identification.report.folder.Job` from ``--vehicle-name``,
    ``--customer`` and ``--operator`` (each one line; stripped)."""
    return Job(*(getattr(args, k, None) and getattr(args, k).strip() or None for _, k, _ in JOB_OPTIONS))


#: The last line of ``-q``'s short result: what the full output adds.
BRIEF_TAIL = ("(-q: the short result; without -q also the model, span and band, the principal moments and axes, the "
              "tensor about the origin, what the model leaves out, cables, damping, modes, each channel's residual "
              "and what σ holds; --json gives everything)")


def print_rig_model(res: RigModelResult, axes: Axes = BODY, brief: bool = False) -> None:
    """The text output of ``rig-identify inertia`` (the rig model); ``axes``: the vehicle axes
    the tensor is given in too (``--axes``, rig.yaml ``output_axes``).  The main table gives the
    moments and products of inertia (:data:`TABLE_CAPTION`'s convention, as the report's), the
    line below it the tensor's off-diagonal entries (−products) with σ and σ/CRB.  ``brief``
    (``-q``): the verdict, the recording, the conventions (frame, units, the products' sign), the
    tensor table and entries, the mass and the CG, the channels the fit leans less on, then
    :data:`BRIEF_TAIL`."""
    d = res.to_dict()
    _print_head(res, brief)
    for line in convention_lines(res.expressed(BODY).axes):
        print(line)
    print_tensor(res, d.get("truth_comparison"))
    body = res.expressed(BODY)
    print(tensor_entries_line(body, res.fit.crb))
    print_other_axes(res, axes)
    if brief:
        print_mass_and_cg(res, d)
        if res.diagnosis is not None and res.diagnosis.extensions:
            print(f"added to the model: {', '.join(res.diagnosis.extensions)} (rig-identify diagnose says why)")
        print_leaned_less(res)
        print(BRIEF_TAIL)
        return
    for line in principal_lines(body) + [origin_line(body)]:
        print(line)
    if res.diagnosis is not None:
        print_diagnosis(res.diagnosis)
    print_mass_and_cg(res, d)
    print_nuisance(res.fit, d)
    print_leaned_less(res)
    sv = d["survey"]
    print("σ: the inverse Fisher information (each channel's noise as estimated from the recording, raised where "
          "it does not fit) or the sandwich over 12 blocks, whichever is larger; the CG, mass, cables, gains and "
          f"the geometry as surveyed (anchors {1e3 * sv['anchors_m']:g} mm, lengths {1e3 * sv['lengths_m']:g} mm, "
          f"load-cell gains {100 * sv['load_cell_gain']:g} %: rig.yaml survey) are in it.  CRB: the bound of this "
          "run at the sensors' own noise.  σ holds the noise and the priors; physics the model lacks shows as a "
          f"channel beyond {LEVEL_LIMIT:g}× its noise (verdict model_error), not in σ")
    print(f"time: {res.seconds:.1f} s")


def _print_head(res: RigModelResult, brief: bool) -> None:
    """The verdict, the recording and its warnings; without ``brief`` the model, span and band."""
    print(f"verdict: {res.summary}")
    print(f"recording: {res.path}")
    for w in res.warnings:
        print(f"warning: {w}")
    if not brief:
        print("model: the rig's grey-box model, every sensor an output (tensions, gyro, accelerometer, "
              "inclinometer); mass, CG, cable stiffness and damping, load-cell gains, the initial state and the "
              "surveyed geometry fitted with their priors")
        print(f"span: {res.start_s:.1f}–{res.start_s + res.duration_s:.1f} s from the first IMU sample "
              f"({res.duration_s:.1f} s, after the exciter's spin-up); band 0–{res.band_hz:.2f} Hz; "
              f"started from {res.start_source}")


def print_other_axes(res: RigModelResult | JointResult, axes: Axes) -> None:
    """The CG and the tensor of ``res`` in ``axes`` where they are not the body's: the text output of
    one recording and of several alike."""
    if axes.name != "body":
        expressed = res.expressed(axes)
        print(f"in {axes.label}:")
        print(f"  centre of gravity ({', '.join(f'{x:.4f}' for x in expressed.cg)}) m")
        print("\n".join("  " + line for line in tensor_table(expressed)))


def print_tensor(res: RigModelResult, truth: dict | None, withheld: tuple[str, ...] | None = None) -> None:
    """The moments and products of inertia (body axes) with σ, the CRB and σ/CRB, and against the
    truth where the recording has one (``truth``: the JSON's ``truth_comparison``); ``withheld``:
    the entries given as not determined (default: ``res``'s)."""
    f = res.fit
    withheld = res.withheld if withheld is None else withheld
    print(TABLE_CAPTION[:-1] + "; body axes:")
    head = f"{'':<7}{'kg·m²':>14}{'σ':>10}{'CRB':>10}{'σ/CRB':>7}"
    if truth:
        head += f"{'truth':>11}{'error':>10}{'err/σ':>7}"
    print(head)
    for k in ORDER:
        i = KEYS.index(k)
        sign = VEHICLE_SIGN[i]
        value = NOT_DETERMINED if k in withheld else f"{sign * f.inertia[i] + 0.0:.2f}"
        line = (f"{'I' + k[1:]:<7}{value:>14}{f.inertia_std[i]:>#10.3g}{f.crb[i]:>#10.3g}"
                f"{f.inertia_std[i] / f.crb[i]:>7.2f}")
        if truth:
            t = truth[k]
            line += (f"{sign * t['truth'] + 0.0:>11.2f}{sign * t['error_percent'] + 0.0:>+9.3f}%"
                     f"{sign * t['error_sigma'] + 0.0:>+7.1f}")
        print(line)


def print_mass_and_cg(res: RigModelResult, d: dict) -> None:
    """The mass with σ, the exciter's rotor taken out, the CG (``d``: the JSON)."""
    print(f"mass {d['mass']:.2f} ± {d['mass_std']:.2f} kg (the scale's value a prior of σ "
          f"{d['survey']['mass_kg']:.3g} kg)")
    print_rotor(d)
    print_cg(res.cg)


def print_leaned_less(res: RigModelResult) -> None:
    if res.poorly_fitted:
        print(f"the fit leans less on {', '.join(res.poorly_fitted)} (their noise raised to their residual's)")


def print_nuisance(f: RigFit, d: dict) -> None:
    """The cables, the body's damping, the natural frequencies, each channel's residual level and
    the offsets the fit eliminated (``d``: the JSON)."""
    p = f.parameters
    print("cables: stiffness " + ", ".join(f"{k / 1e6:.3f}" for k in p.stiffness) + " MN/m, damping time "
          f"{1e3 * p.damping_time:.3f} ms; load-cell gains " + ", ".join(f"{g:.4f}" for g in p.gain))
    bd = d["body_damping"]
    print(f"body's viscous damping: linear {bd['linear']:.3g} ± {bd['linear_std']:.2g} N·s/m, angular "
          f"{bd['angular']:.3g} ± {bd['angular_std']:.2g} N·m·s")
    print("natural frequencies (linearised at rest): " + ", ".join(f"{x:.3g}" for x in f.natural_frequencies) + " Hz")
    print("residual in the band over the noise (1: noise alone): "
          + ", ".join(f"{c} {v:.2f}" for c, v in zip(f.channels, f.residual_level)))
    if f.offsets is not None:
        n = len(p.stiffness)
        o = f.offsets
        print("offsets eliminated (reading − model, mean): load cells " + ", ".join(f"{v:.2f}" for v in o[:n])
              + " N; gyro " + ", ".join(f"{v:.5f}" for v in o[n:n + 3]) + " rad/s (its bias); accelerometer "
              + ", ".join(f"{v:.4f}" for v in o[n + 3:n + 6]) + " m/s²")


def _fitted(fit: RigFit, name: str) -> str:
    """An extension's fitted values with σ in ``fit``."""
    v, s = fit.extension(name)
    return ", ".join(f"{a:.4g} ± {b:.2g}" for a, b in zip(v, s)) + f" {EXTENSIONS[name][1]}"


def print_diagnosis(dg: RigDiagnosis) -> None:
    """What the rigid-body rig model left out (:class:`~rig_identification.diagnosis.rig_diagnosis.RigDiagnosis`):
    the data errors, each extension added and whether the recording told it apart, what would
    tell the rest apart, and each channel's residual before and after."""
    print("what the model leaves out (each extension tested at the estimate, every other unknown refitted):")
    if dg.conflicts:
        print("  data errors (the fit pulls these off rig.yaml's or the static test's values):")
        for c in dg.conflicts[:6]:
            print(f"    {c.unknown}: {c.estimate:.6g} ± {c.std:.2g}, given {c.prior:.6g} ± {c.prior_std:.2g} "
                  f"({c.z:+.1f} σ of the given)")
    for st in dg.steps:
        if st.restart:
            print(f"  the rigid-body fit did not find the motion; fitted again with {st.added} from the value the "
                  "recording gives it, the fit found it; tested there:")
        cand = next(c for c in st.candidates if c.name == st.best)
        word = ("named" if st.named else f"not told apart from {', '.join(st.indistinguishable)}") if dg.explained \
            else "named: the force measures it (below)" if st.added in dg.named else "added, not named"
        print(f"  {st.best}: χ² falls {cand.statistic:.0f} (threshold {cand.threshold:.1f}), cross-validated; {word}"
              + ("" if st.added == st.best else f"; the model takes {st.added}, the class's simplest"))
        if dg.refit is not None:
            print(f"    fitted: {_fitted(dg.refit, st.added)}")
    if not dg.found_motion:
        print(f"  the fit did not find the motion (a channel beyond {REWEIGHT_LIMIT:g}× its noise): its estimate is no "
              "minimum, so no test at it is evidence; nothing is named")
    elif not dg.steps and dg.determined:
        explained = not dg.conflicts and max(dg.rigid.residual_level) <= LEVEL_LIMIT
        print("  no extension significant, plausible and cross-validated"
              + (": the model explains the recording" if explained else ""))
    if dg.damping is not None:
        alt = ", ".join(f"{e} z {z:+.1f}" for e, z in dg.damping.alternatives.items())
        f = dg.refit or dg.rigid
        b = f.layout.body_damping
        damp, sd = f.parameters.body_damping, np.sqrt(np.diag(f.covariance[b, b]))
        word = "viscous_damping named" if "viscous_damping" in dg.named else \
            "not named: " + ", ".join(w for w, bad in (("below zero beyond 3 σ", not dg.damping.plausible),
                                                     ("raises χ² held out", not dg.damping.cross_validated)) if bad) \
            if not dg.damping.found else "not told apart" if dg.explained else "not named"
        print(f"  damping: viscous, {max(dg.damping.significance):.0f} σ (linear {damp[0]:.4g} ± {sd[0]:.2g} N·s/m, "
              f"angular {damp[1]:.4g} ± {sd[1]:.2g} N·m·s); in its place (Vuong's z, + viscous better): {alt}: {word}")
    if dg.gyro is not None and dg.gyro.found:
        g = dg.gyro
        print("  gyro bias (the offset the fit removed): " + ", ".join(
            f"{a:.3g} ± {b:.1g}" for a, b in zip(g.values, g.std)) + f" rad/s (IMU axes; |z| up to "
            f"{max(abs(g.z)):.0f}, threshold {g.threshold:.1f}): "
            + ("gyro_bias named" if dg.explained else "not named"))
    for line in dg.advice:
        print(f"  {line}")
    if dg.refit is not None:
        print("  residual over the noise before → after: " + ", ".join(
            f"{c} {a:.2f} → {b:.2f}" for c, a, b in zip(dg.rigid.channels, dg.rigid.residual_level,
                                                     dg.refit.residual_level)))


def _mm(x: np.ndarray) -> str:
    return "(" + ", ".join("—" if not np.isfinite(a) else f"{1e3 * a:.1f}" for a in x) + ")"


def _mm_std(x: np.ndarray) -> str:
    return "(" + ", ".join("—" if not np.isfinite(a) else f"{1e3 * a:.2g}" for a in x) + ")"


def print_rotor(d: dict) -> None:
    """Where the diagnosis found the exciter's rotor, that the mass, CG and tensor are the body's
    without it (``d``: the result's JSON)."""
    if d["exciter_rotor_removed_kg"]:
        print(f"the body without the exciter's rotor: its {d['exciter_rotor_removed_kg']:.2f} kg, on the spin axis at "
              "the exciter's position, taken out of the suspended body's mass, CG and tensor")


def print_cg(cg: CentreOfGravity) -> None:
    """The CG from the static test, the run alone and both, and whether the two tests agree."""
    print("centre of gravity (body frame, mm; — : not determined):")
    print(f"  static   {_mm(cg.static)} ± {_mm_std(cg.static_std)}  from {cg.static_source}")
    print(f"  dynamic  {_mm(cg.dynamic)} ± {_mm_std(cg.dynamic_std)}  the swinging body alone")
    print(f"  combined {_mm(cg.combined)} ± {_mm_std(cg.combined_std)}  the fit's: the tensor above is about it, "
          "its σ in the tensor's")
    d = cg.difference_sigma
    if np.any(np.isfinite(d)):
        words = ("agree" if cg.agree else
                 f"DISAGREE beyond {CONSISTENCY_SIGMA:g} σ: check the static test (dummy mass, its position) "
                 "and rig.yaml")
        print("  static and dynamic " + words + " (" + ", ".join("—" if not np.isfinite(x) else f"{x:+.1f}"
                                                               for x in d) + " σ)")


def saved_cg(args) -> tuple[np.ndarray | None, np.ndarray | None, str | None]:
    """``--cg``'s saved static result as the CG's prior: (CG (3,) m, its σ (3,) m, the file), or
    three None (rig.yaml's)."""
    if not args.cg:
        return None, None, None
    from ..statics.handover import load_cg_result  # the static test's modules load only with --cg
    saved = load_cg_result(args.cg)
    return saved.center_of_gravity, saved.center_of_gravity_std, args.cg


def write_outputs(args, res: RigModelResult | JointResult, axes: Axes, sources: list[str], window: dict | None,
                  printed) -> None:
    """What ``inertia`` writes after a fit of the rig model: ``--yaml`` (the mass properties in
    ``axes``, ``sources`` and ``window`` named), then the JSON (``--json``; ``axes``' block where
    not the body's) or the text (``printed(res, axes, brief)``), the URDF element with ``--urdf``,
    and the YAML's path."""
    urdf = urdf_inertial(res.expressed(BODY)) if args.urdf else None
    if args.yaml:
        content = export_dict(res.expressed(axes), verdict=res.verdict, summary=res.summary, std_kind=STD_IS,
                              sources=sources, window=window,
                              created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
                              version=package_version())
        content["center_of_gravity_source"] = "fitted (the rig model), its prior " + res.cg_source
        atomic_write_text(args.yaml, yaml_text(content))
    args.progress.finish()
    if args.json:
        d = res.to_dict()
        if axes.name != "body":
            d[axes.json_key] = axes_block(res.expressed(axes))
        if urdf is not None:
            d["urdf_inertial"] = urdf
        print(json.dumps(d))
    else:
        printed(res, axes, brief=bool(getattr(args, "quiet", False)))
        if urdf is not None:
            print("URDF inertial element (link frame: rig.yaml's body frame; ixy, ixz, iyz: the tensor's entries):")
            print(urdf)
    if args.yaml:
        print(f"yaml: {args.yaml}", file=sys.stderr if args.json else sys.stdout)


def fitted_and_reported(args, rec: Recording, axes: Axes, what: str) -> tuple[RigModelResult, object | None]:
    """The rig model fitted to ``rec`` (``--cg``'s saved static result as the CG's prior, the
    window ``--start``/``--end``; :func:`~rig_identification.pipeline.rig_model.fit_whole_recording`)
    and, with ``--report``, its report in ``axes`` (the page's index, else None); ``what``: the
    progress heading.  Raises :class:`~rig_identification.report.folder.ReportError` where the
    report cannot be written."""
    heading(what)
    res = fit_whole_recording(rec, *saved_cg(args), args.start, args.end)
    index = None
    if args.report:
        # the page's modules (its figures, matplotlib) load only when a report is asked for
        from ..report.rig_page import write_rig_report
        step(f"writing the report to {args.report}")
        try:
            index = write_rig_report(args.report, res, rec, axes, job_of(args))
        except OSError as e:
            raise ReportError(f"{args.report}: cannot write the report ({e.strerror or e})") from None
    return res, index


def cmd_rig_model(args, rec: Recording, axes: Axes = BODY) -> int:
    """``rig-identify inertia`` (the rig model) on one recording ``rec``; ``axes`` those of the
    printout, the YAML and the JSON's extra block; ``--urdf``, ``--yaml``, ``--report`` as for
    the prediction-error fit.  Returns the exit status."""
    res, index = fitted_and_reported(args, rec, axes, "fitting the rig's model to every sensor (tensions, gyro, "
                                     "accelerometer, inclinometer)")
    write_outputs(args, res, axes, [str(rec.path)],
                  {"start": float(res.start_s), "end": float(res.start_s + res.duration_s)}, print_rig_model)
    if index is not None:
        print(f"report: {index}", file=sys.stderr if args.json else sys.stdout)
    return 0


def cmd_inertia(args) -> int:
    """``rig-identify inertia REC``: the rig model fitted to one recording (several:
    :func:`~rig_identification.cli.joint.cmd_inertia`); returns the exit status (user errors raise,
    see cli.user_errors)."""
    check_common(args)
    recs = read_all(args.recording)
    axes, axes_notes = output_axes(args.axes, recs)
    for note in axes_notes:
        warn(note)
    return cmd_rig_model(args, recs[0], axes)
