"""Command line: ``rig-identify`` (offline identification of recordings) and ``rig-sim``.

``rig-identify inertia RECORDING [--json]`` replays a recording folder through the same
tracker -> preprocessor -> identifier code as the nodes and prints the mass properties.
User errors (bad files, inconsistent input) print one clear line and exit with status 2;
no traceback.
"""
from __future__ import annotations

import argparse
import json
import sys


from .identification import KEYS, IdentificationError, from_tensor
from .recording import RecordingError, read_recording
from .rig import RigError
from .tracker import TrackerError

from .statics import StaticsError  # noqa: E402

USER_ERRORS = (RecordingError, RigError, IdentificationError, TrackerError, StaticsError, FileNotFoundError)


def _print_inertia(result, truth: dict | None, rec_path) -> None:
    from .pipeline import compare_to_truth
    d = result.to_dict()
    print(f"recording: {rec_path}")
    print(f"mass: {d['mass']:.2f} kg   centre of gravity (body): "
          + ", ".join(f"{x:.4f}" for x in d["center_of_gravity"]) + " m")
    print(f"window: {d['window']['end'] - d['window']['start']:.1f} s, {d['window']['samples']} samples; "
          f"band {d['band_hz'][0]:.2f}–{d['band_hz'][1]:.2f} Hz")
    cmp = compare_to_truth(result, truth) if truth and "inertia_about_cg" in truth else None
    head = f"{'entry':6s} {'value kg·m²':>12s} {'std':>8s}"
    if cmp:
        head += f" {'truth':>10s} {'error':>9s} {'err/std':>8s}"
    print(head)
    for k, v, s in zip(KEYS, from_tensor(result.inertia), result.inertia_std):
        line = f"{k:6s} {v:12.2f} {s:8.2f}"
        if cmp:
            c = cmp[k]
            line += f" {c['truth']:10.2f} {c['error_percent']:+8.3f}% {c['error_sigma']:+8.2f}"
        print(line)
    if cmp:
        print("(error: % of the entry for diagonals, % of the largest diagonal for products)")
    for w in d["weakly_determined"][:1]:
        print("note: " + w["text"])


def cmd_inertia(args) -> int:
    rec = read_recording(args.recording)
    from .pipeline import identify_recording
    band = tuple(args.band) if args.band else None
    result = identify_recording(rec, start=args.start, end=args.end, band_hz=band, model=args.model,
                                initial_guess=args.initial_guess)
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        _print_inertia(result, rec.truth, rec.path)
    for w in result.warnings:  # also in the JSON's "warnings" list
        print("warning: " + w, file=sys.stderr)
    return 0


def cmd_thesis_table(args) -> int:
    from .thesis_table import print_table, run_case
    rows = []
    for name in args.cases or [f"case{i:02d}" for i in range(1, 18)]:
        rows.append(run_case(name))
        if not args.json:
            print_table(rows[-1:])
    if args.json:
        print(json.dumps(rows))
    return 0


def cmd_modes(args) -> int:
    from .modes import estimate_modes, match_modes, natural_modes
    from .identification import to_tensor
    rec = read_recording(args.recording)
    rig = rec.rig
    cg = rig.require_cg()
    if args.inertia is not None:
        ixx, iyy, izz, ixy, ixz, iyz = args.inertia
        J = to_tensor([ixx, ixy, ixz, iyy, iyz, izz])
        source = "--inertia"
    else:
        from .pipeline import identify_recording
        J = identify_recording(rec).inertia
        source = "identified from the recording"
    if args.stiffness is not None:
        k, kname = args.stiffness, f"spring cables k = {args.stiffness:g} N/m"
    elif all(c.stiffness is not None for c in rig.cables):
        k, kname = rig.cable_stiffness, "spring cables (rig.yaml stiffness)"
    else:
        k, kname = None, "inextensible cables"
    geo = natural_modes(rig, rig.mass, cg, J, k)
    est = estimate_modes(rec)
    pairs = match_modes(geo, est.modes)
    if args.json:
        print(json.dumps({"recording": str(rec.path), "inertia_source": source, "cable_model": kname,
                          "inertia": [float(x) for x in from_tensor(J)],
                          "exciter_frequency_hz": est.exciter_frequency,
                          "geometric": [m.to_dict() for m in geo],
                          "estimated": [e.to_dict() for e in est.modes],
                          "matches": [{"geometric_hz": m.frequency, "estimated_hz": None if e is None else e.frequency,
                                       "difference_percent": d} for m, e, d in pairs],
                          "warnings": est.warnings}))
        return 0
    print(f"recording: {rec.path}")
    print(f"model: mass {rig.mass:.1f} kg, CG from rig.yaml, inertia {source}, {kname}")
    if est.exciter_frequency is not None:
        print(f"exciter: {est.exciter_frequency:.4f} Hz (excluded with its harmonics)")
    print(f"{'geometry Hz':>11s}  {'mode shape (world axes)':32s} {'recording Hz':>12s} {'diff %':>8s} "
          f"{'damping':>8s}  gyro")
    for m, e, d in pairs:
        if e is None:
            print(f"{m.frequency:11.4f}  {m.description:32s} {'-':>12s}")
        else:
            print(f"{m.frequency:11.4f}  {m.description:32s} {e.frequency:12.4f} {d:+8.2f} "
                  f"{e.damping_ratio:8.4f}  {e.axes}")
    used = {id(e) for _, e, _ in pairs if e is not None}
    for e in est.modes:
        if id(e) not in used:
            print(f"{'-':>11s}  {'(no geometric mode)':32s} {e.frequency:12.4f} {'':8s} {e.damping_ratio:8.4f}  {e.axes}")
    for w in est.warnings:
        print("note: " + w)
    return 0


def identify_main(argv=None) -> int:
    """Entry point of ``rig-identify``."""
    ap = argparse.ArgumentParser(prog="rig-identify", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    from .cg_cli import add_cg_parser, add_cg_plan_parser
    p = sub.add_parser("inertia", help="identify the inertia tensor from a dynamic recording")
    p.set_defaults(func=cmd_inertia)
    p.add_argument("recording", help="recording folder (rig.yaml + bag/)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--start", type=float, help="window start, s from the first IMU sample")
    p.add_argument("--end", type=float, help="window end, s from the first IMU sample")
    p.add_argument("--band", type=float, nargs=2, metavar=("LOW_HZ", "HIGH_HZ"),
                   help="pass band of the fit (default: around the spectral peaks of the gyro)")
    p.add_argument("--model", choices=["pem", "thesis"], default="pem",
                   help="pem: ours (default); thesis: the thesis's model and estimator, as a baseline")
    p.add_argument("--initial-guess", type=float, nargs=6, metavar=("IXX", "IXY", "IXZ", "IYY", "IYZ", "IZZ"),
                   help="starting tensor entries for --model thesis (kg·m², products negated)")
    t = sub.add_parser("thesis-table", help="the thesis's 17 case studies: reported errors vs ours vs --model thesis")
    t.add_argument("cases", nargs="*", help="case names (default: case01 … case17)")
    t.add_argument("--json", action="store_true", help="print one JSON list")
    t.set_defaults(func=cmd_thesis_table)
    add_cg_parser(sub)
    mp = sub.add_parser("modes", help="natural frequencies: from the geometry vs estimated from a recording")
    mp.add_argument("recording", help="recording folder (rig.yaml + bag/)")
    mp.add_argument("--json", action="store_true", help="print one JSON object")
    mp.add_argument("--inertia", type=float, nargs=6, metavar=("IXX", "IYY", "IZZ", "IXY", "IXZ", "IYZ"),
                    help="inertia tensor entries about the CG, body axes, kg·m² (products negated, as "
                         "truth.yaml); default: identified from the recording")
    mp.add_argument("--stiffness", type=float, metavar="N_PER_M",
                    help="cable stiffness for the model (default: rig.yaml's, else inextensible cables)")
    mp.set_defaults(func=cmd_modes)
    add_cg_plan_parser(sub)
    args = ap.parse_args(argv)
    try:
        return args.func(args)
    except USER_ERRORS as e:
        print(f"rig-identify: error: {e}", file=sys.stderr)
        return 2


def sim_main(argv=None) -> int:
    """Entry point of ``rig-sim`` (implemented in :mod:`rig_identification.sim_cli`)."""
    from .sim_cli import sim_main as _main
    return _main(argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(identify_main())
