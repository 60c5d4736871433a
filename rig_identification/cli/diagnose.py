"""``rig-identify diagnose``: where the model and a recording disagree, and which physics is missing.

The default (``--model rig``) is the rig model's own diagnosis, the same fit and the same
diagnosis as ``rig-identify inertia`` (:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`;
:mod:`~rig_identification.diagnosis.rig_diagnosis`), its output turned to the diagnosis: the
rigid-body rig model's verdict and each channel's residual over its noise, the data errors, each
extension tested (named only where the recording tells it apart from the others, else its
class and what would tell them apart), the residual before and after, and the tensor of the
model with what was added.  ``--json`` prints the same object as ``rig-identify inertia --json``
(its ``diagnosis`` and ``rigid_body_fit``).

``--model pem`` / ``thesis``: the gyro-only fit's diagnosis — two fits, said apart:

* the rigid-body fit — the same pipeline as ``rig-identify inertia --quick --no-diagnose``
  (:func:`~rig_identification.pipeline.offline.identify_recording` without the σ replays: tracker, preprocessor,
  identifier, validation), so that both commands print the same rigid-body tensor for a
  recording;
* diagnose's own model fit (:func:`~rig_identification.diagnosis.selection.diagnose`): the tensor
  fitted jointly with the
  effects found, on its own residual groups (gyro, accelerometer, mean levels), which is what
  its likelihood ratios compare.  Its rigid-body baseline (``inertia_about_cg_before`` in the
  JSON) weighs the accelerometer and the mean moment too, and so differs from the rigid-body
  fit by a fraction of σ to a few σ under model error; the text output does not print it.

Effect parameters print with their units (:data:`~rig_identification.cli.text.EFFECT_UNITS`), p-values as
``p < 1e-300`` when they underflow.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..diagnosis.compliant_body import diagnosis_alternative
from ..diagnosis.distinguish import effect_name
from ..diagnosis.not_rigid import not_rigid_hypothesis, two_body_reason
from ..diagnosis.result import Combination
from ..diagnosis.selection import diagnose
from ..estimation.identification import IdentificationError
from ..estimation.inertia_result import InertiaResult
from ..io.export import BODY, ORDER, axes_for, convention_lines
from ..io.recording import Recording, read_recording
from ..io.verdict import KEYS
from ..pipeline.offline import identify_recording
from ..pipeline.rig_model import RigModelResult
from ..report.diagnosis import diagnosis_json
from ..report.diagnosis_page import write_report
from ..report.page import check_report_dir
from .arg_types import JOB_OPTIONS
from .inertia import truth_columns, window_line
from .progress import heading, step
from .rig_model import fitted_and_reported, print_diagnosis
from .text import TABLE_CAPTION, effect_text, entries_line, evidence_text, fmt, p_text, tensor_table


def same_as(model: str) -> str:
    """The ``rig-identify inertia`` command line whose fit is diagnose's rigid-body fit."""
    return "rig-identify inertia --quick --no-diagnose" + (" --model thesis" if model == "thesis" else "")


def rigid_body_dict(result: InertiaResult, t0: float, model: str) -> dict:
    """The rigid-body fit's part of diagnose's JSON: what ``rig-identify inertia --quick
    --no-diagnose --json`` says of the tensor, its σ, verdict, window and band."""
    d = result.to_dict(t0=t0)
    keep = ("inertia_about_cg", "inertia_std", "products_of_inertia", "uncertainty", "window", "band_hz",
            "residual_rms_rad_s", "method")
    return {"as": same_as(model), **{k: d[k] for k in keep},
            "verdict": None if result.validation is None else result.validation.verdict,
            "summary": None if result.validation is None else result.validation.summary}


def compliant_dict(gate: str, sprung: Combination | None, fitted: bool) -> dict:
    """The sprung body's part of diagnose's JSON: ``run`` (whether the two-body fit ran: the
    gate :func:`~rig_identification.diagnosis.not_rigid.two_body_reason` open and ``--two-body``
    asked, ``fitted``), ``why_run`` (the gate's reason, or None); ``hypothesis``: the effect
    entry — the two-body fit's (``sprung``'s one effect,
    :func:`~rig_identification.diagnosis.compliant_body.diagnosis_alternative`: its modes,
    ``advice``, the evidence; no tensor unless named), the unfitted hypothesis
    (:func:`~rig_identification.diagnosis.not_rigid.not_rigid_hypothesis`) where the gate is open
    and the fit was not asked for, or None (gate shut, or no significant sprung body)."""
    if gate and not fitted:
        sprung = not_rigid_hypothesis(gate)
    return {"run": bool(gate) and fitted, "why_run": gate or None,
            "hypothesis": None if sprung is None else sprung.effects[0]}


def compliant_lines(cb: dict) -> list[str]:
    """The sprung body in the text output: the hypothesis and its advice line (none for modes no
    sprung body can have), or why there is none."""
    if not cb["why_run"]:
        return []
    h = cb["hypothesis"]
    if not cb["run"]:
        return [f"hypothesis (not a finding): compliant_body: {h['implausible']}", f"advice: {h['advice']}"]
    if h is None:
        return [f"sprung body: fitted ({cb['why_run']}): no significant sprung body (or the fit could not be made)"]
    if h.get("plausible"):
        return [f"sprung body: compliant_body named: {effect_text(h)}"]
    return [f"hypothesis (not a finding): compliant_body: {effect_text(h)}"] + (
        [f"advice: {h['advice']}"] if h.get("advice") else [])


def print_gyro_diagnosis(rec, result: InertiaResult, d, out: dict, model: str) -> None:
    """The text output of ``rig-identify diagnose --model pem`` / ``thesis``."""
    t0 = float(rec.sensors.t_start)
    print(f"recording: {rec.path}")
    body = axes_for("body", rec.rig.vehicle)
    for line in convention_lines(body):
        print(line)
    print(f"rigid-body fit (the same as {same_as(model)}):")
    print("  " + (result.validation.summary if result.validation is not None else "verdict: none"))
    print("  " + window_line(result, t0))
    ex = result.expressed(body)
    print("  " + TABLE_CAPTION)
    for line in tensor_table(ex, truth_columns(result, rec.truth, body)):
        print("  " + line)
    name = "ours (Newton–Euler with ω × Jω)" if model == "pem" else "the thesis (no ω × Jω)"
    print(f"diagnose: model {name}; "
          f"band {d.band[0]:.2f}–{d.band[1]:.2f} Hz")
    if not d.mismatch:
        if d.tried:
            best = max(d.tried, key=lambda c: c["likelihood_ratio"])
            print("no significant mismatch: the rigid-body model explains the recording (best candidate "
                  f"{best['name']}, p {p_text(best['p_value'])})")
        else:
            print("no significant mismatch: the rigid-body model explains the recording")
    for e in out["effects"]:
        red = ", ".join(f"{k} −{100 * r:.0f} %" for k, r in list(e["evidence"]["rms_reduction"].items())[:4])
        plausible = "" if e.get("plausible", True) else f" — NOT plausible: {e.get('implausible')}"
        if e.get("told_apart", True):
            print(f"effect: {e['name']}: {effect_text(e)}{plausible}")
        else:
            print(f"effect class: {effect_name(e)}; modelled as {e['name']}: {effect_text(e)}{plausible}")
            riv = e["evidence"]["rivals"]
            lams = ", ".join(f"{x:.1f}" for x in riv["likelihood_ratios"])
            print(f"   not told apart: the combinations' likelihood ratios {lams} differ by less than {riv['bar']:.3g};"
                  f" what would tell them apart: {e['tells_apart']}")
        print(f"   evidence: {evidence_text(e)}; residual RMS {red}")
    s0, s1 = out["residual_rms_synchronous_before"], out["residual_rms_synchronous_after"]
    if d.mismatch and s0 is not None and s1 is not None:
        red = sorted(((1 - s1[k] / s0[k], k) for k in s0 if s0[k] > 0), reverse=True)[:4]
        print(f"   synchronous residual ({out['synchronous_revolutions']:.0f} exciter revolutions averaged): "
              + ", ".join(f"{k} −{100 * r:.0f} %" for r, k in red))
    if d.mismatch:
        std = dict(zip(KEYS, d.inertia_std_after))
        print("tensor with the effects (diagnose's joint fit of the tensor and the effects), kg·m²: "
              + entries_line(out["inertia_about_cg_after"], {k: std[k] for k in ORDER}))
        if rec.truth and "inertia_about_cg" in rec.truth:
            print("truth (truth.yaml), kg·m²: " + entries_line(rec.truth["inertia_about_cg"]))
        print("(rig-identify inertia --model pem adds what diagnose names to the model, fits again and validates: "
              "its tensor is the one to use)")
    for line in compliant_lines(out["compliant_body"]):
        print(line)
    for name, loc in out["located"].items():
        if (loc["peaks"] or loc["grows_at"]) and mismatch_channel(out, name):
            where = [f"peak {fmt(p['hz'], '.3g')} Hz ({p['is']})" for p in loc["peaks"][:2]]
            if loc["grows_at"]:
                where.append("grows " + loc["grows_at"])
            print(f"located: {name}: " + "; ".join(where))


def mismatch_channel(out: dict, name: str) -> bool:
    """A channel worth naming: the effects found reduced its residual by ≥ 10 %."""
    return any(name in e["evidence"]["rms_reduction"] for e in out["effects"])


def print_rig_diagnosis_text(res: RigModelResult) -> None:
    """The text output of ``rig-identify diagnose`` (the rig model): the rigid-body rig model's
    verdict and channels, what it leaves out (:func:`~rig_identification.cli.rig_model.print_diagnosis`),
    and the model with what was added: its verdict and tensor with σ (and truth.yaml's)."""
    print(f"recording: {res.path}")
    for w in res.warnings:
        print(f"warning: {w}")
    rigid = res.rigid_body or res
    print("rigid-body rig model (every sensor an output; as rig-identify inertia fits it first):")
    print(f"  verdict: {rigid.summary}")
    print("  residual in the band over the noise (1: noise alone): "
          + ", ".join(f"{c} {v:.2f}" for c, v in zip(rigid.fit.channels, rigid.fit.residual_level)))
    if res.diagnosis is None:
        print("not diagnosed: the fit gave no finite σ (the motion was not found), so there is no estimate to "
              "test extensions at")
        return
    print_diagnosis(res.diagnosis)
    if res.rigid_body is None:
        print("the model is the rigid-body rig model: the tensor is rig-identify inertia's")
        return
    print(f"the model with {', '.join(res.diagnosis.extensions)}: verdict {res.verdict_line}")
    body = res.expressed(BODY)
    d = res.to_dict()
    truth = d.get("truth_comparison")
    print("  " + TABLE_CAPTION)
    for line in tensor_table(body, truth):
        print("  " + line)
    print("(rig-identify inertia reports this fit with everything else it measures: mass, CG, cables)")


def cmd_diagnose(args) -> int:
    """``rig-identify diagnose``; returns the exit status (user errors raise)."""
    rig_only = [flag for flag, k in (("--cg", "cg"), ("--start", "start"), ("--end", "end")) if getattr(args, k)]
    rig_only += [flag for flag, k, _ in JOB_OPTIONS if getattr(args, k, None)]
    pem_only = [flag for flag, k in (("--cg-free", "cg_free"), ("--two-body", "two_body")) if getattr(args, k)]
    if args.model == "rig" and pem_only:
        raise IdentificationError(f"{', '.join(pem_only)}: options of --model pem, the gyro-only diagnosis; the rig "
                                  "model fits the CG always and has no sprung body")
    if args.model != "rig" and rig_only:
        raise IdentificationError(f"{', '.join(rig_only)}: options of the rig model (the default --model rig)")
    if args.report:
        check_report_dir(Path(args.report))     # before the fit, not after it
    step(f"reading {args.recording}")
    rec = read_recording(args.recording)
    if args.model == "rig":
        return cmd_rig_diagnose(args, rec)
    return cmd_gyro_diagnose(args, rec)


def cmd_rig_diagnose(args, rec: Recording) -> int:
    """``rig-identify diagnose`` with the rig model (the default); returns the exit status."""
    res, index = fitted_and_reported(args, rec, BODY, "fitting the rig's model to every sensor, then testing what "
                                     "it leaves out")
    args.progress.finish()
    if args.json:
        print(json.dumps(res.to_dict()))
    else:
        print_rig_diagnosis_text(res)
    if index is not None:
        print(f"report: {index}", file=sys.stderr if args.json else sys.stdout)
    return 0


def cmd_gyro_diagnose(args, rec: Recording) -> int:
    """``rig-identify diagnose --model pem`` / ``thesis``: the gyro-only fit's diagnosis; returns
    the exit status."""
    heading(f"the rigid-body fit, as {same_as(args.model)} (tracker, preprocessor, fit, validation)")
    result = identify_recording(rec, refine=False, model=args.model)
    step("diagnosing (effect library, likelihood-ratio selection)")
    d = diagnose(rec, model=args.model, cg_free=args.cg_free)
    # a body that is not rigid: the two-body fit only when it can matter (the gate of rig-identify
    # inertia's diagnosis; here "explained" is diagnose's own answer: plausible effects found)
    explained = bool(d.mismatch and all(e.get("plausible", True) for e in d.effects))
    gate = two_body_reason(rec, result, explained)
    sprung = None
    if gate and args.two_body:
        step(f"fitting a sprung body (two-body model, experimental): {gate}")
        sprung = diagnosis_alternative(rec)
    if args.report:
        step(f"writing the report to {args.report}")
        write_report(d, args.report, title=f"diagnosis of {rec.path}")
    args.progress.finish()
    out = d.to_dict()
    out["rigid_body_fit"] = rigid_body_dict(result, float(rec.sensors.t_start), args.model)
    out["compliant_body"] = compliant_dict(gate, sprung, args.two_body)
    if args.json:
        print(json.dumps(diagnosis_json(out)))
    else:
        print_gyro_diagnosis(rec, result, d, out, args.model)
    args.progress.warn_rest(result.warnings + d.warnings)
    if result.validation is not None and result.validation.verdict != "ok":
        print(f"note: the rigid-body fit's verdict is {result.validation.verdict}: rig-identify inertia --model pem "
              "(without --no-diagnose) adds what diagnose names to the model and reports that fit", file=sys.stderr)
    return 0
