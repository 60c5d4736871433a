"""``rig-identify inertia REC1 REC2 …``: several recordings of one body read at once by the rig
model (:mod:`~rig_identification.pipeline.joint`): the verdict, each recording's own verdict and
what it determines alone, the body's tensor, mass and CG; ``--json``, ``--yaml`` and ``--urdf`` as
for one recording (:mod:`~rig_identification.cli.rig_model`, whose printing and outputs this uses).
"""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from ..io.export import BODY, Axes
from ..io.recording import Recording
from ..io.rig import load_rig
from ..pipeline.joint import JointResult, check_same_body, fit_recordings
from .arg_types import UsageError
from .progress import heading, warn
from .recordings import check_common, output_axes, read_all
from .rig_model import (
    print_leaned_less,
    print_mass_and_cg,
    print_nuisance,
    print_other_axes,
    print_tensor,
    saved_cg,
    write_outputs,
)
from .text import origin_line, principal_lines, tensor_entries_line

#: The last line of a joint fit's ``-q`` output: what the full output adds.
JOINT_BRIEF_TAIL = ("(-q: the short result; without -q also the principal moments and axes, the tensor about the "
                    "origin, each recording's cables, damping, modes and channels, and what σ holds; --json gives "
                    "everything)")


def print_joint(res: JointResult, axes: Axes = BODY, brief: bool = False) -> None:
    """The text output of ``rig-identify inertia REC1 REC2 …`` (the rig model over several
    recordings at once): the verdict, each recording with its own verdict, span and what it
    determines alone, the body's tensor (as :func:`print_rig_model`'s), mass and CG; without
    ``brief`` each recording's cables and channels."""
    first = res.first
    d = first.to_dict()
    print(f"verdict: {res.summary}")
    print(f"recordings (one body, fitted at once): {len(res.results)}")
    for r, a in zip(res.results, res.alone):
        alone = "every entry determined" if not (a.undetermined or a.ambiguous) else \
            "not determined: " + ", ".join(a.undetermined or a.ambiguous)
        print(f"  {r.path}: {r.verdict}; span {r.start_s:.1f}–{r.start_s + r.duration_s:.1f} s, band "
              f"0–{r.band_hz:.2f} Hz; alone {a.verdict} ({alone})")
        for w in r.warnings:
            print(f"    warning: {w}")
    if not brief:
        print("model: each recording's rig model (its cables, load cells, surveyed geometry and states), every "
              "sensor an output; the body's mass, CG and tensor shared by all")
    print_tensor(first, d.get("truth_comparison"), res.withheld)
    body = res.expressed(BODY)
    print(tensor_entries_line(body, first.fit.crb))
    print_other_axes(res, axes)
    if brief:
        print_mass_and_cg(first, d)
        print(JOINT_BRIEF_TAIL)
        return
    for line in principal_lines(body) + [origin_line(body)]:
        print(line)
    print_mass_and_cg(first, d)
    for r in res.results:
        print(f"{r.path}:")
        print_nuisance(r.fit, r.to_dict())
        print_leaned_less(r)
    print("σ: the inverse Fisher information of all the recordings at once (each channel's noise as estimated "
          "from its recording, raised where it does not fit) or the sandwich over 12 blocks of each, whichever is "
          "larger; CRB: the bound of these runs at the sensors' own noise")
    print(f"time: {res.seconds:.1f} s")


def cmd_joint(args, recs: list[Recording], axes: Axes = BODY) -> int:
    """``rig-identify inertia REC1 REC2 …``: the rig model fitted to the recordings at once
    (:func:`~rig_identification.pipeline.joint.fit_recordings`); ``--json``, ``--yaml`` and
    ``--urdf`` as for one recording.  Returns the exit status."""
    heading(f"fitting the rig's model to every sensor of {len(recs)} recordings at once")
    res = fit_recordings(recs, *saved_cg(args), args.start, args.end)
    write_outputs(args, res, axes, [str(r.path) for r in recs], None, print_joint)
    return 0


def cmd_inertia(args) -> int:
    """``rig-identify inertia REC1 REC2 …``: the rig model fitted to several recordings of one body at
    once, their rig.yaml's mass and CG checked to agree before any bag is read; returns the exit
    status (user errors raise, see cli.user_errors)."""
    paths = args.recording
    if args.report:
        raise UsageError("--report takes one recording: a joint fit of several has no report page yet "
                         "(give each recording its own --report run)")
    if all((Path(p) / "rig.yaml").is_file() for p in paths):  # different bodies: said before reading bags
        check_same_body([SimpleNamespace(path=Path(p), rig=load_rig(Path(p) / "rig.yaml")) for p in paths])
    check_common(args)
    recs = read_all(paths)
    axes, axes_notes = output_axes(args.axes, recs)
    for note in axes_notes:
        warn(note)
    return cmd_joint(args, recs, axes)
