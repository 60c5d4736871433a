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
    """Print the result as a table; rec_path: one recording path or a list (joint fit)."""
    from .pipeline import compare_to_truth
    d = result.to_dict()
    paths = rec_path if isinstance(rec_path, (list, tuple)) else [rec_path]
    if len(paths) == 1:
        print(f"recording: {paths[0]}")
    else:
        print(f"recordings (joint fit, one tensor): {len(paths)}")
    print(f"mass: {d['mass']:.2f} kg   centre of gravity (body): "
          + ", ".join(f"{x:.4f}" for x in d["center_of_gravity"]) + " m")
    if len(paths) == 1:
        print(f"window: {d['window']['end'] - d['window']['start']:.1f} s, {d['window']['samples']} samples; "
              f"band {d['band_hz'][0]:.2f}–{d['band_hz'][1]:.2f} Hz")
    else:
        for p, s in zip(paths, result.series):
            print(f"  {p}: window {s.t[-1] - s.t[0]:.1f} s, {len(s.t)} samples; "
                  f"band {s.band_hz[0]:.2f}–{s.band_hz[1]:.2f} Hz")
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
    if result.sensor_noise is not None:
        n = result.sensor_noise
        noise = (f"gyro {n['gyro']:.2g} rad/s, accelerometer {n['accelerometer']:.2g} m/s², load cells "
                 f"{n['load_cell']:.2g} N, exciter {n['exciter']:.2g} N, inclinometer {1000 * n['inclinometer']:.2g} mrad")
        if result.uncertainty.startswith("propagated"):
            print(f"std: the sensors' noise, estimated from the recording ({noise}), propagated through tracker, "
                  "preprocessor and identifier")
        else:
            print(f"std: from the fit's residuals (sandwich): they exceed what the sensors' noise ({noise}) explains")
    if result.diagnosis is not None:
        names = ", ".join(e["name"] for e in result.diagnosis["effects"])
        print(("model error diagnosed: " + names + " removed from the data, the tensor above identified again"
               if result.diagnosis["handled"] == "removed from the data" else
               "model error diagnosed: the tensor above is the fit with " + names + " (σ from its residuals)")
              + "; rigid-body fit: " + ", ".join(f"{k} {v:.2f}" for k, v in result.rigid_body["inertia_about_cg"].items()))
    if result.bias_correction is not None:
        print("second-order bias removed (kg·m²): "
              + ", ".join(f"{k} {v:+.3g}" for k, v in zip(KEYS, result.bias_correction)))
    for w in d["weakly_determined"][:1]:
        print("note: " + w["text"])


def cmd_inertia(args) -> int:
    from pathlib import Path
    from types import SimpleNamespace

    from .pipeline import check_same_body, identify_recording, identify_recordings
    paths = args.recording
    if len(paths) > 1:
        if args.model != "pem":
            raise IdentificationError("--model thesis fits one recording at a time: give one RECORDING "
                                      "(the joint fit of several recordings is the prediction-error model's)")
        if all((Path(p) / "rig.yaml").is_file() for p in paths):  # different bodies: say so before reading bags
            from .rig import load_rig
            check_same_body([SimpleNamespace(path=Path(p), rig=load_rig(Path(p) / "rig.yaml")) for p in paths])
    if args.report:
        if args.model != "pem":
            raise IdentificationError("--report needs --model pem (the thesis baseline has no predicted output "
                                      "to plot)")
        from .report import check_report_dir
        check_report_dir(Path(args.report))  # before the fit, not after it
    recs = [read_recording(p) for p in paths]
    band = tuple(args.band) if args.band else None
    if len(recs) > 1:
        result = identify_recordings(recs, start=args.start, end=args.end, band_hz=band, refine=not args.quick)
    else:
        result = identify_recording(recs[0], start=args.start, end=args.end, band_hz=band, model=args.model,
                                    initial_guess=args.initial_guess, refine=not args.quick)
        if args.model == "pem" and not args.quick and not args.no_diagnose:
            from .pipeline import with_diagnosis
            result = with_diagnosis(recs[0], result, args.start, args.end, band)
    index = None
    if args.report:
        from .report import ReportError, write_report
        try:
            index = write_report(args.report, result, recs)
        except OSError as e:
            raise ReportError(f"{args.report}: cannot write the report ({e.strerror or e})") from None
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        from .report import common_truth
        _print_inertia(result, common_truth(recs) if len(recs) > 1 else recs[0].truth,
                       [r.path for r in recs] if len(recs) > 1 else recs[0].path)
    for w in result.warnings:  # also in the JSON's "warnings" list
        print("warning: " + w, file=sys.stderr)
    if index is not None:
        print(f"report: {index}", file=sys.stderr if args.json else sys.stdout)
    return 0


def cmd_thesis_table(args) -> int:
    from .thesis_table import print_summary, print_table, run_case
    rows = []
    for name in args.cases or [f"case{i:02d}" for i in range(1, 18)]:
        rows.append(run_case(name))
        if not args.json:
            print_table(rows[-1:])
    if args.json:
        print(json.dumps(rows))
    else:
        print_summary(rows)
    return 0


def cmd_diagnose(args) -> int:
    from .diagnosis import diagnose, effect_parameters_text
    rec = read_recording(args.recording)
    d = diagnose(rec, model=args.model)
    if args.report:
        from .diagnosis_report import write_report
        write_report(d, args.report, title=f"diagnosis of {rec.path}")
    out = d.to_dict()
    if args.json:
        print(json.dumps(out))
    else:
        print(f"recording: {rec.path}")
        print(f"model: {'ours (Newton–Euler with ω × Jω)' if args.model == 'pem' else 'the thesis (no ω × Jω)'}; "
              f"band {d.band[0]:.2f}–{d.band[1]:.2f} Hz")
        if not d.mismatch:
            print("no significant mismatch: the rigid-body model explains the recording "
                  f"(best candidate {max(d.tried, key=lambda c: c['likelihood_ratio'])['name']}, "
                  f"p = {max(d.tried, key=lambda c: c['likelihood_ratio'])['p_value']:.2g})" if d.tried else "")
        for e in out["effects"]:
            ps = effect_parameters_text(e)
            red = ", ".join(f"{k} −{100 * r:.0f} %" for k, r in list(e["evidence"]["rms_reduction"].items())[:4])
            print(f"effect: {e['name']}: {ps}")
            print(f"   evidence: likelihood ratio {e['evidence']['likelihood_ratio']:.1f} "
                  f"(p = {e['evidence']['p_value']:.2g}); residual RMS {red}")
        s0, s1 = out["residual_rms_synchronous_before"], out["residual_rms_synchronous_after"]
        if d.mismatch and s0 is not None and s1 is not None:
            red = sorted(((1 - s1[k] / s0[k], k) for k in s0 if s0[k] > 0), reverse=True)[:4]
            print(f"   synchronous residual ({out['synchronous_revolutions']:.0f} exciter revolutions averaged): "
                  + ", ".join(f"{k} −{100 * r:.0f} %" for r, k in red))
        print(f"{'entry':6s} {'before':>10s} {'after':>10s}" + (f" {'truth':>10s}" if rec.truth else ""))
        for k in KEYS:
            line = f"{k:6s} {out['inertia_about_cg_before'][k]:10.2f} {out['inertia_about_cg_after'][k]:10.2f}"
            if rec.truth and "inertia_about_cg" in rec.truth:
                line += f" {rec.truth['inertia_about_cg'][k]:10.2f}"
            print(line)
        for name, loc in out["located"].items():
            if loc["peaks"] or loc["grows_at"]:
                where = [f"peak {p['hz']} Hz ({p['is']})" for p in loc["peaks"][:2]]
                if loc["grows_at"]:
                    where.append("grows " + loc["grows_at"])
                if mismatch_channel(out, name):
                    print(f"located: {name}: " + "; ".join(where))
    for w in d.warnings:
        print("warning: " + w, file=sys.stderr)
    return 0


def mismatch_channel(out: dict, name: str) -> bool:
    """A channel worth naming: the effects found reduced its residual by ≥ 10 %."""
    return any(name in e["evidence"]["rms_reduction"] for e in out["effects"])


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


def cmd_plan(args) -> int:
    """``rig-identify plan``: the rig's modes, the predicted σ of the baseline excitation and the
    recommended exciter run(s) (:mod:`rig_identification.planning`); returns 0 (2 on a user error)."""
    import numpy as np

    from .planning import KEYS as PKEYS
    from .planning import PlanError, Run, geometry_variants, load_plan_input, make_body, plan_experiment
    from .simulator import ExperimentError, SimulationError
    try:
        rig, base_exc, k = load_plan_input(args.rig)
        ixx, iyy, izz, ixy, ixz, iyz = args.inertia
        body = make_body(rig, args.mass, [ixx, ixy, ixz, iyy, iyz, izz], k)
        if rig.exciter is None and args.baseline_position is None:
            raise PlanError(f"{rig.source}: no exciter in rig.yaml; give the baseline's mounting point with "
                            "--baseline-position X Y Z")
        pos = args.baseline_position if args.baseline_position is not None else rig.exciter.position
        rpy = rig.exciter.rpy if (rig.exciter is not None and args.baseline_position is None) else (0.0, 0.0, 0.0)
        amp = args.baseline_force if args.baseline_force is not None else (base_exc or {}).get("amplitude", 200.0)
        freq = args.baseline_frequency if args.baseline_frequency is not None else (base_exc or {}).get("frequency", 1.05)
        baseline = Run(float(freq), float(amp), tuple(float(x) for x in pos), "z", args.duration, 2.0,
                       tuple(float(x) for x in rpy))
        say = (lambda s: None) if args.quiet else (lambda s: print("  " + s, file=sys.stderr, flush=True))
        geometries = []
        for g in args.geometry or []:
            grig, _, _ = load_plan_input(g)
            geometries.append((f"cables of {g}", grig))
        if args.vary_geometry:
            if not args.vary_geometry > 0:
                raise PlanError(f"--vary-geometry {args.vary_geometry:g}: the shift must be > 0 m")
            geometries += geometry_variants(body, args.vary_geometry)
        if geometries and args.runs < 2:
            raise PlanError("--geometry / --vary-geometry are for a second run: they need --runs 2")
        plan = plan_experiment(body, baseline, duration=args.duration, max_force=args.max_force,
                               max_rotation_deg=args.max_rotation, min_tension_ratio=args.min_tension,
                               frequencies=tuple(args.frequencies), positions=args.position, max_runs=args.runs,
                               objective=args.objective, refine=max(1, args.refine), geometries=geometries,
                               progress=say)
    except (PlanError, ExperimentError, SimulationError) as e:
        print(f"rig-identify: error: {e}", file=sys.stderr)
        return 2
    if args.json:
        out = plan.to_dict()
        out.update({"rig": str(rig.source), "mass": body.mass, "center_of_gravity": [float(x) for x in rig.center_of_gravity],
                    "inertia": {kk: float(v) for kk, v in zip(PKEYS, from_tensor(body.inertia))},
                    "cable_stiffness": [float(x) for x in body.stiffness], "noise": body.noise, "rates_hz": body.rates})
        print(json.dumps(out))
        return 0
    print(f"rig: {rig.source}; body {body.mass:.1f} kg, CG " + ", ".join(f"{x:.3f}" for x in rig.center_of_gravity)
          + " m (body); cables: springs " + ", ".join(f"{x:.3g}" for x in sorted(set(body.stiffness))) + " N/m")
    print("natural modes (linearised about the equilibrium):")
    for m in plan.modes:
        print(f"  {m.frequency:7.3f} Hz  {m.description}")
    lim = plan.limits
    print(f"limits: rotation ≤ {lim['max_rotation_deg']:g}° (peak, start-up included), every cable ≥ "
          f"{100 * lim['min_tension_ratio']:.0f} % of its static tension, force ≤ {lim['max_force_n']:g} N; exciter "
          f"{lim['frequency_range_hz'][0]:g}–{lim['frequency_range_hz'][1]:g} Hz, ≥ {100 * lim['mode_margin']:.0f} % "
          "from every mode, its double and every sum of two (parametric resonance)")

    def describe(c, title):
        r = c.run
        axis = f"spin axis body {r.spin_axis}" if r.rpy is None else f"exciter rpy {np.round(r.exciter_rpy, 3).tolist()}"
        band = "" if c.band is None else f"; identify with --band {c.band[0]:.2f} {c.band[1]:.2f}"
        print(f"{title}: {r.amplitude:.0f} N rotating at {r.frequency:.3f} Hz, exciter at "
              f"({', '.join(f'{x:.2f}' for x in r.position)}) m body, {axis}, {r.duration:.0f} s — peak rotation "
              f"{c.peak_rotation_deg:.2f}°, lowest tension {100 * c.min_tension_ratio:.0f} % of static{band}")
        if c.geometry is not None:
            print(f"  on another cable geometry ({c.geometry}): "
                  + "; ".join(f"{cb.name} ceiling anchor ({', '.join(f'{x:.2f}' for x in cb.ceiling_anchor)}) m, "
                              f"length {cb.length:.3f} m" for cb in c.body.rig.cables))

    describe(plan.baseline, "baseline")
    for i, c in enumerate(plan.runs, 1):
        if i > 1 and c is plan.runs[0]:
            print(f"recommended run {i}: the same run again")
            continue
        describe(c, f"recommended run {i}" if len(plan.runs) > 1 else "recommended run")
    bp, pp = plan.baseline.prediction, plan.prediction
    print(f"predicted σ at the noise levels {', '.join(f'{kk} {v:g}' for kk, v in body.noise.items())} "
          "(rad/s, m/s², N, N, rad):")
    print(f"{'entry':6s} {'value':>9s} {'baseline σ':>11s} {'plan σ':>9s} {'ratio':>6s} {'plan σ rel.':>11s}")
    for kk, v, b, p, rel in zip(PKEYS, from_tensor(body.inertia), bp.std, pp.std, pp.relative_std):
        print(f"{kk:6s} {v:9.1f} {b:11.3f} {p:9.3f} {b / p:6.1f} {100 * rel:10.4f}%")
    print("(kg·m²; relative: of the entry for diagonals, of the largest diagonal for products)")
    for title, pr in (("baseline", bp), ("plan", pp)):
        for w in pr.weak(1):
            print(f"{title}: {w['text']}")
    for n in plan.notes:
        print("note: " + n)
    return 0


def identify_main(argv=None) -> int:
    """Entry point of ``rig-identify``."""
    ap = argparse.ArgumentParser(prog="rig-identify", description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    from .cg_cli import add_cg_parser, add_cg_plan_parser
    p = sub.add_parser("inertia", help="identify the inertia tensor from one or more dynamic recordings")
    p.set_defaults(func=cmd_inertia)
    p.add_argument("recording", nargs="+",
                   help="recording folder (rig.yaml + bag/); several recordings of the same body (other exciter "
                        "frequencies or positions, cable geometries) are fitted jointly with one tensor")
    p.add_argument("--report", metavar="DIR",
                   help="also write an HTML report (index.html + figures) to the folder DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--start", type=float, help="window start, s from the first IMU sample")
    p.add_argument("--end", type=float, help="window end, s from the first IMU sample")
    p.add_argument("--band", type=float, nargs=2, metavar=("LOW_HZ", "HIGH_HZ"),
                   help="pass band of the fit (default: around the spectral peaks of the gyro)")
    p.add_argument("--model", choices=["pem", "thesis"], default="pem",
                   help="pem: ours (default); thesis: the thesis's model and estimator, as a baseline")
    p.add_argument("--initial-guess", type=float, nargs=6, metavar=("IXX", "IXY", "IXZ", "IYY", "IYZ", "IZZ"),
                   help="starting tensor entries for --model thesis (kg·m², products negated)")
    p.add_argument("--quick", action="store_true",
                   help="the plain fit: no second-order bias correction, σ from the fit's residuals (sandwich) "
                        "instead of the propagated sensor noise, no diagnosis; about 3× faster")
    p.add_argument("--no-diagnose", action="store_true",
                   help="report the rigid-body fit even when its residual shows model error (by default one "
                        "recording with model error is diagnosed, as rig-identify diagnose, and the tensor of the "
                        "fit with the physics found is reported)")
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
    dp = sub.add_parser("diagnose", help="where the rigid-body model and a recording disagree, and which physics "
                                         "is missing (effect library, likelihood-ratio selection)")
    dp.add_argument("recording", help="recording folder (rig.yaml + bag/)")
    dp.add_argument("--json", action="store_true", help="print one JSON object")
    dp.add_argument("--report", metavar="DIR", help="write plots (residuals and spectra before/after) and the JSON")
    dp.add_argument("--model", choices=["pem", "thesis"], default="pem",
                    help="pem: ours (default); thesis: the thesis's model without gyroscopic terms")
    dp.set_defaults(func=cmd_diagnose)
    pp = sub.add_parser("plan", help="know before you shake: the rig's modes, predicted inertia σ and the "
                                     "recommended exciter run(s) for a nominal body")
    pp.add_argument("rig", help="rig.yaml, experiment file or recording folder (CG from rig.yaml)")
    pp.add_argument("--inertia", type=float, nargs=6, required=True, metavar=("IXX", "IYY", "IZZ", "IXY", "IXZ", "IYZ"),
                    help="nominal inertia tensor entries about the CG, body axes, kg·m² (products negated, as "
                         "truth.yaml)")
    pp.add_argument("--mass", type=float, metavar="KG", help="nominal mass (default: rig.yaml body.mass)")
    pp.add_argument("--duration", type=float, default=120.0, metavar="S", help="length of each run (default 120)")
    pp.add_argument("--max-force", type=float, default=float("inf"), metavar="N",
                    help="largest force amplitude the exciter can make (default: no limit but the rig's)")
    pp.add_argument("--max-rotation", type=float, default=3.0, metavar="DEG",
                    help="largest rotation of the body, start-up included (default 3)")
    pp.add_argument("--min-tension", type=float, default=0.2, metavar="RATIO",
                    help="lowest cable tension as a fraction of its static tension (default 0.2)")
    pp.add_argument("--frequencies", type=float, nargs=2, default=(0.3, 4.0), metavar=("LO_HZ", "HI_HZ"),
                    help="exciter frequency range (default 0.3 4)")
    pp.add_argument("--position", type=float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                    help="a candidate exciter mounting point, body frame m (repeatable; default: the corners of the "
                         "box spanned by the body anchors and the rig's exciter)")
    pp.add_argument("--runs", type=int, choices=(1, 2), default=2, help="at most this many runs (default 2)")
    pp.add_argument("--objective", choices=("baseline", "relative"), default="baseline",
                    help="baseline: improve the least-improved entry over the baseline most (default); relative: "
                         "minimise the largest relative σ")
    pp.add_argument("--baseline-force", type=float, metavar="N",
                    help="baseline force amplitude (default: the experiment file's, else the thesis's 200 N)")
    pp.add_argument("--baseline-frequency", type=float, metavar="HZ",
                    help="baseline frequency (default: the experiment file's, else the thesis's 1.05 Hz)")
    pp.add_argument("--baseline-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                    help="baseline exciter position, body m (default: rig.yaml exciter)")
    pp.add_argument("--refine", type=int, default=3, metavar="N",
                    help="how many screened runs to simulate before choosing (default 3; 1 is quicker)")
    pp.add_argument("--geometry", action="append", metavar="RIG.yaml",
                    help="another cable geometry the rig can take, for the second run (rig.yaml, experiment file or "
                         "recording folder: its cables are used, the body is this one; repeatable)")
    pp.add_argument("--vary-geometry", type=float, metavar="M",
                    help="also try, for the second run, the ceiling anchors moved M m farther apart (and closer "
                         "together) along world x and along world y, cable lengths re-set to the same hanging pose")
    pp.add_argument("--json", action="store_true", help="print one JSON object")
    pp.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    pp.set_defaults(func=cmd_plan)
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
