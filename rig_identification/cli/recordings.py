"""What ``rig-identify inertia``'s two fits share before either runs: the recordings read with
their warnings shown (:func:`read_all`), the output axes (:func:`output_axes`) and the option
checks that need no bag (:func:`check_common`)."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from ..io.export import Axes, AxesError, axes_for
from ..io.recording import read_recording, recording_labels
from ..io.rig import load_rig
from ..io.vehicle import common_vehicle
from ..report.folder import check_report_dir
from .arg_types import JOB_OPTIONS, UsageError
from .progress import step, warn


def read_all(paths: list[str]) -> list:
    """Read the recordings (one progress step each); their reader warnings shown at once."""
    recs = []
    for p in paths:
        step(f"reading {p}")
        recs.append(read_recording(p))
    if len(recs) == 1:
        for w in recs[0].warnings:
            warn(w)
    else:
        for lab, r in zip(recording_labels(recs), recs):
            for w in r.warnings:
                warn(f"{lab}: {w}")
    return recs


def output_axes(option: str | None, recs: list) -> tuple[Axes, list[str]]:
    """The axes of the printout and the YAML: ``--axes`` when given, else the recordings'
    rig.yaml ``output_axes`` (when they state one and agree), else ``body``; made with the
    vehicle's orientation of their rig.yaml ``body.vehicle`` (when those that state one agree:
    :func:`~rig_identification.io.vehicle.common_vehicle`).  ``recs``: objects with a ``rig``.
    Returns (axes, warnings: recordings whose rig.yaml state different axes or vehicles).
    Raises :class:`~rig_identification.io.vehicle.AxesError` for vehicle axes (``sae``,
    ``iso8855``) when rig.yaml does not say where the vehicle lies (naming ``body.vehicle``)."""
    vehicle, vnote = common_vehicle(r.rig.vehicle for r in recs)
    notes = [] if vnote is None else [vnote]
    stated = {r.rig.output_axes for r in recs if r.rig.output_axes is not None}
    name = option if option is not None else stated.pop() if len(stated) == 1 else "body"
    if option is None and len(stated) > 1:
        notes.append(f"the recordings' rig.yaml state different output_axes ({', '.join(sorted(stated))}): "
                     "body axes; --axes chooses")
    try:
        return axes_for(name, vehicle), notes
    except AxesError as e:
        why = f"{e} ({vnote})" if vnote is not None else str(e)
        raise AxesError(f"--axes {name}: {why}" if option is not None else why) from None


def check_common(args) -> None:
    """Refuse, before any bag is read, what neither fit can run: vehicle axes rig.yaml cannot give,
    a report folder that is not an earlier report, a report header option without ``--report`` or
    of more than one line.  Raises :class:`~.arg_types.UsageError`,
    :class:`~rig_identification.io.vehicle.AxesError`,
    :class:`~rig_identification.report.folder.ReportError`."""
    paths = args.recording
    if args.axes is not None and args.axes != "body" and all((Path(p) / "rig.yaml").is_file() for p in paths):
        output_axes(args.axes, [SimpleNamespace(rig=load_rig(Path(p) / "rig.yaml")) for p in paths])  # refused now
    if args.report:
        check_report_dir(Path(args.report))  # before the fit, not after it
    for flag, key, _ in JOB_OPTIONS:
        text = getattr(args, key, None)
        if text is not None and not args.report:
            raise UsageError(f"{flag} names the report's {key.replace('_name', '')}: give --report DIR too")
        if text is not None and ("\n" in text or not text.strip()):
            raise UsageError(f"{flag}: one line of text, not {text!r}")


__all__ = ["check_common", "output_axes", "read_all"]
