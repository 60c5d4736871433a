"""``rig-identify cg``: the centre of gravity from the static experiment.

    rig-identify cg BASELINE_RECORDING DUMMY_RECORDING [--json] [--write-rig OUT.yaml [--force]]
                    [--start S] [--end S] [--dummy-mass KG --dummy-position X Y Z] [--tare KG X Y Z]
                    [--scale-std KG] [--anchor-std MM] [--length-std MM] [--dummy-position-std MM]
                    [--no-load-cells] [--no-inclinometer] [--accelerometer]
                    [--fit-inclinometer-offset] [--allow-motion]

``cg`` estimates the CG of the suspended body of BASELINE (body at rest without the dummy
mass) from it and DUMMY (with the dummy mass of rig.yaml ``dummy_mass``), see
:mod:`rig_identification.statics`.  Its σ (``center_of_gravity_std``) includes the rig's
geometry as surveyed -- by default rig.yaml's ``survey``, else 1 mm (1 σ per coordinate) on every
anchor, cable length and the dummy's position (:data:`~.statics.DEFAULT_ANCHOR_STD` ...), set with --anchor-std,
--length-std, --dummy-position-std -- and ``center_of_gravity_std_noise`` is the measurement
noise's alone; both are printed.  ``--json`` prints one object, :meth:`~.statics.CgResult.to_dict`
(``schema`` :data:`~.statics.CG_RESULT_SCHEMA`, ``schema_version``, ``units``, body frame, m,
kg) with ``baseline``, ``dummy``, ``created`` and ``written_rig``; saved to a file it is read
back by :func:`~rig_identification.statics.handover.load_cg_result` (e.g. for
``rig-identify inertia --cg CG.json``).
``--write-rig OUT.yaml`` writes a copy of the recordings' rig.yaml with ``body.center_of_gravity``
set to the estimate (comment lines: date, σ, source recordings), atomically; an existing OUT is
replaced only with ``--force``.  truth.yaml is never used for the estimate; when present it is
shown beside it (text output only).

``rig-identify`` (cli/main.py) wires it in with :func:`add_cg_parser` (and ``cg-plan``,
:mod:`~rig_identification.cli.cg_plan`, with the geometry options and number types of this
module); its user errors (a recording, rig.yaml, the statics or the tracker refusing the
input; ``CgResultError`` for the ``--write-rig`` target, a :class:`~.statics.StaticsError`) are
printed by ``rig-identify`` as one line (exit status 2, ``cli.main.user_errors``).
"""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text
from ..io.recording import read_recording
from ..io.rig import DummyMass, Survey
from ..statics import (
    DEFAULT_ANCHOR_STD,
    DEFAULT_DUMMY_POSITION_STD,
    DEFAULT_LENGTH_STD,
    CgOptions,
    CgResult,
    StaticsError,
    StaticState,
    estimate_cg,
)
from ..statics.handover import check_rig_target, rig_with_cg_text
from .arg_types import number

GEOMETRY_NOTE = ("a careful steel-tape or laser survey: class II tape ±(0.3 + 0.2 L/m) mm, ±1.1 mm over 4 m")


def cg_options(args, survey: Survey) -> CgOptions:
    """The CG fit's options of the command line ``args`` (``cg``, ``cg-plan``; the σ of the geometry
    given in mm), the σ not given there rig.yaml's ``survey``."""
    def mm(name, default):
        v = getattr(args, name, None)
        return default if v is None else v * 1e-3
    scale = getattr(args, "scale_std", None)
    return CgOptions(use_load_cells=not getattr(args, "no_load_cells", False),
                     use_inclinometer=not getattr(args, "no_inclinometer", False),
                     use_accelerometer=getattr(args, "accelerometer", False),
                     fit_inclinometer_offset=getattr(args, "fit_inclinometer_offset", False),
                     scale_std=survey.mass if scale is None else scale,
                     anchor_std=mm("anchor_std", survey.anchors),
                     length_std=mm("length_std", survey.lengths),
                     dummy_position_std=mm("dummy_position_std", survey.dummy_position))


def add_geometry_options(p: argparse.ArgumentParser) -> None:
    """The σ of the scale and of the rig's geometry as surveyed (``cg`` and ``cg-plan``); each
    defaults to rig.yaml's ``survey`` (docs/recording_format.md), else the values shown."""
    p.add_argument("--scale-std", type=number("--scale-std"), metavar="KG",
                   help="σ of the scale's mass reading (default rig.yaml survey.mass, else 0.1 %% of it)")
    p.add_argument("--anchor-std", type=number("--anchor-std", zero=True), metavar="MM",
                   help="σ of each coordinate of every ceiling and body anchor, mm (default rig.yaml survey.anchors, "
                        f"else {DEFAULT_ANCHOR_STD * 1e3:g}: {GEOMETRY_NOTE}; 0: exact)")
    p.add_argument("--length-std", type=number("--length-std", zero=True), metavar="MM",
                   help="σ of the cable lengths of rig.yaml, mm (default rig.yaml survey.lengths, else "
                        f"{DEFAULT_LENGTH_STD * 1e3:g}; 0: exact)")
    p.add_argument("--dummy-position-std", type=number("--dummy-position-std", zero=True), metavar="MM",
                   help="σ of each coordinate of the dummy mass's position, mm (default rig.yaml "
                        f"survey.dummy_position, else {DEFAULT_DUMMY_POSITION_STD * 1e3:g}; 0: exact)")


def add_cg_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``cg`` sub-command to an ``argparse`` sub-parser collection; returns it."""
    p = subparsers.add_parser("cg", help="centre of gravity from the two static recordings (without and "
                                         "with the dummy mass)",
                              description="Centre of gravity of the suspended body (body frame) from a "
                                          "baseline and a dummy-mass static recording (thesis chapter 2).")
    p.add_argument("baseline", help="recording folder of the body at rest WITHOUT the dummy mass")
    p.add_argument("dummy", help="recording folder of the body at rest WITH the dummy mass")
    p.add_argument("--json", action="store_true", help="print one JSON object (save it for rig-identify inertia --cg)")
    p.add_argument("--write-rig", metavar="OUT.yaml",
                   help="write a copy of the recordings' rig.yaml with body.center_of_gravity set to the estimate "
                        "(for the dynamic experiment), atomically")
    p.add_argument("--force", action="store_true", help="let --write-rig replace an existing file")
    p.add_argument("--start", type=float, metavar="S", help="window start, s from each recording's first IMU sample")
    p.add_argument("--end", type=float, metavar="S", help="window end, s from each recording's first IMU sample")
    p.add_argument("--dummy-mass", type=number("--dummy-mass"), metavar="KG",
                   help="dummy mass, kg (default: rig.yaml dummy_mass)")
    p.add_argument("--dummy-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="dummy mass position, body frame, m (default: rig.yaml dummy_mass)")
    p.add_argument("--tare", type=float, nargs=4, metavar=("KG", "X", "Y", "Z"),
                   help="a known part of the suspended body (e.g. the carrying frame: mass and CG, body "
                        "frame m): also report the CG of the rest (the vehicle)")
    add_geometry_options(p)
    p.add_argument("--no-load-cells", action="store_true",
                   help="ignore the load cells (the thesis's method: inclinometer angles only)")
    p.add_argument("--no-inclinometer", action="store_true", help="ignore the inclinometer")
    p.add_argument("--accelerometer", action="store_true",
                   help="also use the accelerometer's gravity direction (its bias is not modelled)")
    p.add_argument("--fit-inclinometer-offset", action="store_true",
                   help="fit the inclinometer's two zero offsets")
    p.add_argument("--allow-motion", action="store_true",
                   help="use a state even if the body never comes to rest (batch-means uncertainty)")
    p.set_defaults(func=cmd_cg)
    return p


def _rig_geometry(rig) -> dict:
    d = rig.to_dict()
    d["body"].pop("center_of_gravity", None)
    d.pop("dummy_mass", None)
    return d


def _state(rec, label: str, args) -> StaticState:
    t_first = rec.sensors.t_start
    t0 = None if args.start is None else t_first + args.start
    t1 = None if args.end is None else t_first + args.end
    if args.start is not None and args.end is not None and args.end <= args.start:
        raise StaticsError(f"--end ({args.end} s) must be after --start ({args.start} s)")
    st = StaticState.from_window(rec.sensors, t0, t1, label=label, allow_motion=args.allow_motion)
    return replace(st, warnings=[f"{rec.path}: {w}" for w in rec.warnings] + st.warnings)


def run_cg(args):
    """Read the two recordings and estimate; returns (CgResult, baseline Recording, dummy Recording)."""
    if (args.dummy_mass is None) != (args.dummy_position is None):
        raise StaticsError("--dummy-mass and --dummy-position go together")
    rb = read_recording(args.baseline)
    rd = read_recording(args.dummy)
    gb, gd = _rig_geometry(rb.rig), _rig_geometry(rd.rig)
    if gb != gd:
        diff = sorted(k for k in set(gb) | set(gd) if gb.get(k) != gd.get(k))
        raise StaticsError(f"{rb.rig.source} and {rd.rig.source} describe different rigs (field(s) "
                           f"{', '.join(diff)} differ); both static recordings need the same rig.yaml")
    rig = rb.rig
    if args.dummy_mass is not None:
        dummy = DummyMass(float(args.dummy_mass), np.array(args.dummy_position, float))
    else:
        dummy = rig.dummy_mass or rd.rig.dummy_mass
        if dummy is None:
            raise StaticsError(f"{rd.rig.source}: missing field dummy_mass (or pass --dummy-mass and "
                               "--dummy-position)")
    sb = _state(rb, "baseline", args)
    sd = replace(_state(rd, "dummy", args), added=(dummy,))
    return estimate_cg(rig, sb, sd, cg_options(args, rig.survey)), rb, rd


def cmd_cg(args) -> int:
    """``rig-identify cg``: print the CG estimate (text or ``--json``), write ``--write-rig``; returns 0."""
    out = Path(args.write_rig) if getattr(args, "write_rig", None) else None
    if out is not None:
        check_rig_target(out, args.force, [Path(args.baseline), Path(args.dummy)])
    res, rb, rd = run_cg(args)
    created = datetime.now(timezone.utc).isoformat(timespec="seconds")
    d = res.to_dict()
    d["baseline"], d["dummy"], d["created"] = str(rb.path), str(rd.path), created
    # each state's window also in s from its recording's first IMU sample, as --start/--end take it
    first = {"baseline": float(rb.sensors.t_start), "dummy": float(rd.sensors.t_start)}
    for s in d["states"]:
        if s.get("label") in first and s.get("window") is not None:
            s["window_s"] = [float(w) - first[s["label"]] for w in s["window"]]
    d["units"]["states.window_s"] = "s from the first IMU sample of the state's recording (as --start/--end)"
    if args.tare is not None:
        c, s = res.without(args.tare[0], args.tare[1:])
        d["tare"] = {"mass": float(args.tare[0]), "center_of_gravity": [float(x) for x in args.tare[1:]]}
        d["center_of_gravity_without_tare"] = [float(x) for x in c]
        d["center_of_gravity_without_tare_std"] = [float(x) for x in s]
    d["written_rig"] = None
    if out is not None:
        check_rig_target(out, args.force, [rb.path, rd.path])     # again: the fit took a while
        src = rb.path / "rig.yaml"
        text = rig_with_cg_text(rb.rig, res, [f"the static recordings {rb.path}", str(rd.path)], created,
                                src.read_text(encoding="utf-8"))
        atomic_write_text(out, text)
        d["written_rig"] = str(out)
    if args.json:
        print(json.dumps(d))
        return 0
    _print_cg(res, d, rb)
    return 0


def _print_cg(res: CgResult, d: dict, rb) -> None:
    truth = rb.truth.get("center_of_gravity") if isinstance(rb.truth, dict) else None
    if res.validation is not None:
        print(res.validation.summary)
    for s in res.states:
        print(f"{s.label:9s} averaged {s.window[1] - s.window[0]:.1f} s; tilt rpy "
              + ", ".join(f"{math.degrees(a):+.4f}" for a in s.rpy) + " deg; tensions "
              + ", ".join(f"{t:.1f}" for t in s.tensions) + " N")
    print(f"streams: {', '.join(res.streams)}; fit χ² = {res.chi2:.1f} for {res.dof} degrees of freedom")
    head = f"{'CG (body frame)':16s} {'value m':>10s} {'σ mm':>8s} {'σ noise mm':>10s}"
    if truth is not None:
        head += f" {'truth m':>10s} {'error mm':>9s} {'err/σ':>7s}"
    print(head)
    noise = res.center_of_gravity_std_noise
    for i, a in enumerate("xyz"):
        line = (f"{a:16s} {res.center_of_gravity[i]:10.5f} {res.center_of_gravity_std[i] * 1e3:8.3f} "
                f"{noise[i] * 1e3 if noise is not None else float('nan'):10.3f}")
        if truth is not None:
            e = res.center_of_gravity[i] - float(truth[i])
            line += f" {float(truth[i]):10.5f} {e * 1e3:+9.3f} {e / res.center_of_gravity_std[i]:+7.2f}"
        print(line)
    if truth is not None:
        print("(truth from truth.yaml, shown for comparison only)")
    geo = res.geometry_std
    fitted = [f"{n.replace('_', ' ')} {geo[k] * 1e3:g} mm" for k, n in
              (("anchors", "anchors"), ("cable_lengths", "cable_lengths"), ("dummy_position", "dummy_position"))
              if geo.get(k, 0) > 0]
    if geo.get("dummy_mass", 0) > 0:
        fitted.append(f"dummy mass {geo['dummy_mass']:g} kg")
    if fitted:
        print("σ: measurement noise and the rig's geometry as surveyed (" + ", ".join(fitted)
              + ", 1 σ per coordinate; set with --anchor-std, --length-std, --dummy-position-std); "
                "σ noise: the measurement noise alone, the geometry taken as exact")
    else:
        print("σ: the measurement noise alone: every geometry input taken as exact (--anchor-std, --length-std, "
              "--dummy-position-std 0)")
    if res.budget:
        print("σ budget, x, y, z mm (adds in quadrature to σ): " + "; ".join(
            f"{k.replace('_', ' ')} " + ", ".join(f"{x * 1e3:.2f}" for x in v) for k, v in res.budget.items()))
    if "center_of_gravity_without_tare" in d:
        c, s = d["center_of_gravity_without_tare"], d["center_of_gravity_without_tare_std"]
        print(f"without the tare ({d['tare']['mass']:g} kg): " + ", ".join(f"{x:.5f}" for x in c) + " m, σ "
              + ", ".join(f"{x * 1e3:.3f}" for x in s) + " mm")
    line = f"mass: {res.mass:.2f} kg (scale)"
    if res.mass_from_load_cells is not None:
        line += f"; load cells {res.mass_from_load_cells:.3f} ± {res.mass_from_load_cells_std:.3f} kg"
    if res.load_cell_gain is not None:
        line += f"; load-cell gain {res.load_cell_gain:.5f} ± {res.load_cell_gain_std:.5f} (from the dummy mass)"
    print(line)
    if res.cable_compliance is not None:
        k = (f"{res.cable_stiffness:.4g} ± {res.cable_stiffness_std:.2g} N/m" if res.cable_stiffness is not None
             else "not significantly extensible")
        print(f"cable stiffness (fitted): {k}")
    print("note: " + res.weakly_determined["text"])
    exact = _exact_inputs_note(res)
    if exact:
        print("note: " + exact)
    if res.validation is not None:
        print("checks: " + "; ".join(
            f"{ck.name} {ck.statistic:.2f} (threshold {ck.threshold:.2f}) {'passed' if ck.passed else 'FAILED'}"
            if ck.passed is not None else f"{ck.name} not applicable" for ck in res.validation.checks)
            + " (σ; fit_chi2: χ²/dof; details in --json)")
    for x in res.warnings:
        print("warning: " + x)
    if d.get("written_rig"):
        print(f"wrote {d['written_rig']}: the rig.yaml with body.center_of_gravity for the dynamic experiment")


def _exact_inputs_note(res: CgResult) -> str:
    """What a 1 mm error of each systematic input taken as exact (σ 0) would do to the CG (the
    same sensitivity, ∂CG/∂rig.yaml value, as for the fitted ones); empty when none is exact."""
    geo, sens = res.geometry_std, res.sensitivity
    parts = []
    for key, sk, what in (("dummy_position", "dummy_position", "the dummy's position (all 3 coordinates)"),
                          ("cable_lengths", "cable_lengths", "one cable's length"),
                          ("anchors", "body_anchors", "one anchor coordinate")):
        if geo.get(key, 0) > 0 or sk not in sens:
            continue
        S = np.asarray(sens[sk])
        if key == "dummy_position":
            eff = 1e-3 * np.sqrt(np.sum(S**2, axis=1))
        else:
            if key == "anchors":
                S = np.hstack([S, np.asarray(sens["ceiling_anchors"])])
            eff = 1e-3 * np.max(np.abs(S), axis=1)
        parts.append(f"a 1 mm error of {what} would move the CG by up to "
                     + ", ".join(f"{x * 1e3:.2f}" for x in eff) + " mm")
    if not parts:
        return ""
    return ("inputs taken as exact (σ 0, not in σ): " + "; ".join(parts)
            + " (x, y, z; such an error would also show in the fit's χ²)")


