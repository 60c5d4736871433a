"""``rig-identify plan`` and ``modes``: experiment design, natural modes.

Tensors on the command line (``plan --inertia``, ``modes --inertia``) are six tensor entries
in the order ixx iyy izz ixy ixz iyz (:data:`~rig_identification.io.export.ORDER`,
:func:`~rig_identification.io.export.tensor_from_option`),
as every option of ``rig-identify`` takes them.
"""
from __future__ import annotations

import json
import math
import sys

import numpy as np

from ..design.planning import PlanError, PlanOptions, geometry_variants, plan_experiment
from ..design.run import Run, load_plan_input, make_body
from ..estimation.precision import precision_of
from ..estimation.rig_record import RigFitError
from ..io.export import ORDER, VEHICLE_SIGN, entries_from_option, tensor_from_option
from ..io.recording import read_recording
from ..io.verdict import KEYS
from ..model.experiment import ExperimentError
from ..model.modes import estimate_modes, match_modes, natural_modes
from ..model.parametrisation import entry_scales, from_tensor, to_tensor
from ..model.rigid_body import SimulationError
from ..pipeline.rig_model import fit_whole_recording
from .arg_types import UsageError
from .progress import heading, step, warn
from .text import TABLE_CAPTION


def cmd_modes(args) -> int:
    """``rig-identify modes``: geometric natural modes beside the recording's."""
    step(f"reading {args.recording}")
    rec = read_recording(args.recording)
    rig = rec.rig
    cg = rig.require_cg()
    if args.inertia is not None:
        J = tensor_from_option(args.inertia)
        source = "--inertia"
    else:
        heading("identifying the tensor (the rig model, as rig-identify inertia)")
        res = fit_whole_recording(rec, diagnose=False)
        if res.verdict == "failed":
            raise UsageError(f"{args.recording}: the rig model did not identify the tensor ({res.summary}); "
                             "give it with --inertia")
        J = to_tensor(res.fit.inertia)
        source = f"identified from the recording (the rig model, verdict {res.verdict})"
    if args.stiffness is not None:
        k, kname = args.stiffness, f"spring cables k = {args.stiffness:g} N/m"
    elif all(c.stiffness is not None for c in rig.cables):
        k, kname = rig.cable_stiffness, "spring cables (rig.yaml stiffness)"
    else:
        k, kname = None, "inextensible cables"
    step("natural modes from the geometry, and from the recording")
    geo = natural_modes(rig, rig.mass, cg, J, k)
    est = estimate_modes(rec)
    pairs = match_modes(geo, est.modes)
    args.progress.finish()
    if args.json:
        print(json.dumps({"recording": str(rec.path), "inertia_source": source, "cable_model": kname,
                          "inertia": [float(x) for x in from_tensor(J)], "inertia_keys": list(KEYS),
                          "exciter_frequency_hz": est.exciter_frequency,
                          "geometric": [m.to_dict() for m in geo],
                          "estimated": [e.to_dict() for e in est.modes],
                          "matches": [{"geometric_hz": m.frequency, "estimated_hz": None if e is None else e.frequency,
                                       "difference_percent": d} for m, e, d in pairs],
                          "warnings": est.warnings}))
        return 0
    print(f"recording: {rec.path}")
    print(f"model: mass {rig.mass:.1f} kg, CG from rig.yaml, inertia {source} ("
          + ", ".join(f"{kk} {J[i, j]:.1f}" for kk, (i, j) in zip(ORDER, ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2),
                                                                          (1, 2)))) + f" kg·m²), {kname}")
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
            print(f"{'-':>11s}  {'(no geometric mode)':32s} {e.frequency:12.4f} {'':8s} {e.damping_ratio:8.4f}  "
                  f"{e.axes}")
    for w in est.warnings:
        print("note: " + w)
    return 0


#: What plan says when neither rig.yaml nor --max-force limits the exciter's force.
UNLIMITED = ("the exciter's force is not limited: rig.yaml gives no exciter.max_force (its largest force amplitude, "
             "N) and no --max-force was given, so the plan may ask more than the exciter makes")


def force_limit(max_force: float, rig) -> str:
    """The force limit as the plan's text says it, with where it came from."""
    in_rig = rig.exciter is not None and rig.exciter.max_force is not None
    if not math.isfinite(max_force):
        return "force not limited (--max-force inf)" if in_rig else \
            "force not limited (rig.yaml gives no exciter.max_force: the plan may ask more than the exciter makes)"
    given = in_rig and rig.exciter.max_force == max_force
    return f"force ≤ {max_force:g} N" + (" (rig.yaml exciter.max_force)" if given else " (--max-force)")


def plan_from_args(args):
    """The rig, the nominal body and the plan (:func:`~rig_identification.design.planning.plan_experiment`) the options
    ask for; the force limit is ``--max-force``, else rig.yaml's ``exciter.max_force``, else none, with
    the warning :data:`UNLIMITED` on stderr.  Raises PlanError, ExperimentError, SimulationError."""
    rig, base_exc, k = load_plan_input(args.rig)
    body = make_body(rig, args.mass, entries_from_option(args.inertia), k)
    if rig.exciter is None and args.baseline_position is None:
        raise PlanError(f"{rig.source}: no exciter in rig.yaml; give the baseline's mounting point with "
                        "--baseline-position X Y Z")
    pos = args.baseline_position if args.baseline_position is not None else rig.exciter.position
    rpy = rig.exciter.rpy if (rig.exciter is not None and args.baseline_position is None) else (0.0, 0.0, 0.0)
    amp = args.baseline_force if args.baseline_force is not None else (base_exc or {}).get("amplitude", 200.0)
    freq = args.baseline_frequency if args.baseline_frequency is not None else (base_exc or {}).get("frequency", 1.05)
    baseline = Run(float(freq), float(amp), tuple(float(x) for x in pos), "z", args.duration, 2.0,
                   tuple(float(x) for x in rpy))
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
    max_force = args.max_force if args.max_force is not None else (
        rig.exciter.max_force if rig.exciter is not None and rig.exciter.max_force is not None else math.inf)
    if args.max_force is None and not math.isfinite(max_force):
        warn(UNLIMITED)
    options = PlanOptions(duration=args.duration, max_force=max_force, max_rotation_deg=args.max_rotation,
                          min_tension_ratio=args.min_tension, frequencies=tuple(args.frequencies),
                          positions=None if not args.position else tuple(tuple(p) for p in args.position),
                          max_runs=args.runs, objective=args.objective, refine=max(1, args.refine),
                          geometries=tuple(geometries))
    plan = plan_experiment(body, baseline, options, progress=step)
    return rig, body, plan


def describe_run(c, title: str) -> None:
    """One exciter run of a plan, with its limits."""
    r = c.run
    axis = f"spin axis body {r.spin_axis}" if r.rpy is None else f"exciter rpy {np.round(r.exciter_rpy, 3).tolist()}"
    print(f"{title}: {r.amplitude:.0f} N rotating at {r.frequency:.3f} Hz, exciter at "
          f"({', '.join(f'{x:.2f}' for x in r.position)}) m body, {axis}, {r.duration:.0f} s — peak rotation "
          f"{c.peak_rotation_deg:.2f}°, lowest tension {100 * c.min_tension_ratio:.0f} % of static")
    if c.geometry is not None:
        print(f"  on another cable geometry ({c.geometry}): "
              + "; ".join(f"{cb.name} ceiling anchor ({', '.join(f'{x:.2f}' for x in cb.ceiling_anchor)}) m, "
                          f"length {cb.length:.3f} m" for cb in c.body.rig.cables))


def plan_precision(body, plan, args) -> dict:
    """The baseline's and the plan's predicted σ against ``--target``
    (:func:`~rig_identification.estimation.precision.precision_of`; each run of ``--duration``):
    {"baseline": Precision, "plan": Precision}."""
    return {title: precision_of(body.inertia, std, args.duration, args.target / 100, subject="each run's")
            for title, std in (("baseline", plan.baseline_std), ("plan", plan.std))}


def cmd_plan(args) -> int:
    """``rig-identify plan``: the rig's modes, the predicted σ of the baseline excitation and the
    recommended exciter run(s), both against ``--target`` (:mod:`rig_identification.design.planning`);
    returns 0 (2 on a user error)."""
    try:
        rig, body, plan = plan_from_args(args)
    except (PlanError, ExperimentError, SimulationError, RigFitError) as e:
        args.progress.fail()
        print(f"rig-identify: error: {e}", file=sys.stderr)
        return 2
    args.progress.finish()
    reach = plan_precision(body, plan, args)
    if args.json:
        out = plan.to_dict()
        out["precision"] = {title: p.to_dict() for title, p in reach.items()}
        out.update({"rig": str(rig.source), "mass": body.mass,
                    "center_of_gravity": [float(x) for x in rig.center_of_gravity],
                    "inertia": {kk: float(v) for kk, v in zip(KEYS, from_tensor(body.inertia))},
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
          f"{100 * lim['min_tension_ratio']:.0f} % of its static tension, " + force_limit(lim['max_force_n'], rig)
          + "; exciter "
          f"{lim['frequency_range_hz'][0]:g}–{lim['frequency_range_hz'][1]:g} Hz, "
          f"≥ {100 * lim['mode_margin']:.0f} % "
          "from every mode, its double and every sum of two (parametric resonance)")
    describe_run(plan.baseline, "baseline")
    for i, c in enumerate(plan.runs, 1):
        if i > 1 and c is plan.runs[0]:
            print(f"recommended run {i}: the same run again")
            continue
        describe_run(c, f"recommended run {i}" if len(plan.runs) > 1 else "recommended run")
    print(f"predicted σ at the noise levels {', '.join(f'{kk} {v:g}' for kk, v in body.noise.items())} "
          "(rad/s, m/s², N, N, rad):")
    print(TABLE_CAPTION)
    print("σ: the rig model's Cramér–Rao bound along a simulation of each run (every sensor an output: what "
          "rig-identify inertia reaches); the runs fitted at once")
    print(f"{'':6s} {'value':>9s} {'baseline σ':>11s} {'plan σ':>9s} {'ratio':>6s} {'plan σ rel.':>11s}")
    theta = from_tensor(body.inertia)
    scale = entry_scales(theta)
    for kk in ORDER:
        i = KEYS.index(kk)
        b, p = plan.baseline_std[i], plan.std[i]
        print(f"{'I' + kk[1:]:6s} {VEHICLE_SIGN[i] * theta[i] + 0.0:9.1f} {b:11.3f} {p:9.3f} {b / p:6.1f} "
              f"{100 * p / scale[i]:10.4f}%")
    print("(relative: of the entry for moments, of the largest moment for products)")
    for title, p in reach.items():
        print(f"{title}: {p.text()}")
    out = plan.to_dict()
    for title, pr in (("baseline", out["baseline"]["prediction"]), ("plan", out["prediction"])):
        for w in pr["weakly_determined"][:1]:
            print(f"{title}: {w['text']}")
    for n in plan.notes:
        print("note: " + n)
    return 0
