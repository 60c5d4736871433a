"""``rig-identify diagnose``: where the model and a recording disagree, and which physics is missing.

The rig model's own diagnosis, the same fit and the same diagnosis as ``rig-identify inertia``
(:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`;
:mod:`~rig_identification.diagnosis.rig_diagnosis`), its output turned to the diagnosis: the
rigid-body rig model's verdict and each channel's residual over its noise, the data errors, each
extension tested (named only where the recording tells it apart from the others, else its
class and what would tell them apart), the residual before and after, and the tensor of the
model with what was added.  ``--json`` prints the same object as ``rig-identify inertia --json``
(its ``diagnosis`` and ``rigid_body_fit``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..io.export import BODY
from ..io.recording import read_recording
from ..pipeline.rig_model import RigModelResult
from ..report.folder import check_report_dir
from .progress import step
from .rig_model import fitted_and_reported, print_diagnosis
from .text import TABLE_CAPTION, tensor_table


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
    if args.report:
        check_report_dir(Path(args.report))     # before the fit, not after it
    step(f"reading {args.recording}")
    rec = read_recording(args.recording)
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
