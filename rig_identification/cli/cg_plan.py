"""``rig-identify cg-plan``: the predicted CG σ of a planned static test and a recommended one.

    rig-identify cg-plan RIG [--cg-guess X Y Z] [--dummy-mass KG] [--dummy-position X Y Z]
                    [--duration S] [--masses KG ...] [--position X Y Z ...] [--target-mm MM]
                    [--noise-from RECORDING] [--load-cell-noise N] [--inclinometer-noise RAD]
                    [--load-cell-rate HZ] [--inclinometer-rate HZ] [--anchor-std MM]
                    [--length-std MM] [--dummy-position-std MM] [--max-duration S] [--json]

It recommends a test that reaches ±2 mm (1.96 σ; --target-mm) on every coordinate
(:func:`~rig_identification.statics.plan.plan_static_test`).  RIG is a rig.yaml file, an
experiment file or a recording folder (whose data give the sensor noise).
"""
from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..io.recording import RecordingError, read_recording
from ..io.rig import DummyMass, load_rig
from ..model.experiment import load_rig_or_experiment
from ..statics import SensorNoise, StaticsError, StaticState, plan_static_test, predict_cg_std
from .arg_types import number
from .cg import add_geometry_options, cg_options
from .progress import step


def add_cg_plan_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``cg-plan`` sub-command (experiment design of the static test); returns it."""
    p = subparsers.add_parser("cg-plan", help="predict the CG uncertainty of a planned static test and "
                                              "recommend one reaching ±2 mm",
                              description="Experiment design for the static CG test: predicted CG σ of a "
                                          "planned test and a recommended plan.")
    p.add_argument("rig", help="rig.yaml file, an experiment file (config/cases/*.yaml), or a recording folder "
                               "(its rig.yaml; its data give the noise)")
    p.add_argument("--cg-guess", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="assumed CG, body frame m (default: rig.yaml's, else 1 m below the body anchors' centroid)")
    p.add_argument("--dummy-mass", type=number("--dummy-mass"), metavar="KG",
                   help="planned dummy mass (default: rig.yaml dummy_mass)")
    p.add_argument("--dummy-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="planned dummy position, body frame m (default: rig.yaml dummy_mass)")
    p.add_argument("--duration", type=number("--duration"), default=10.0, metavar="S",
                   help="planned averaging time per state, s (default 10)")
    p.add_argument("--masses", type=number("--masses"), nargs="+", metavar="KG",
                   help="dummy masses to consider (default 25 50 100 200)")
    p.add_argument("--position", type=float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="a dummy position to consider, body frame m (repeatable; default: the body "
                        "anchors and the corners 1 m below them)")
    p.add_argument("--target-mm", type=number("--target-mm"), default=2.0, metavar="MM",
                   help="required half-width of the 95 %% interval (1.96 σ) on every coordinate, mm (default 2)")
    p.add_argument("--max-duration", type=number("--max-duration"), default=600.0, metavar="S",
                   help="longest acceptable averaging time per state, s (default 600)")
    p.add_argument("--noise-from", metavar="RECORDING", help="measure the sensor noise in this static recording")
    p.add_argument("--load-cell-noise", type=number("--load-cell-noise", zero=True), metavar="N",
                   help="σ per sample, N")
    p.add_argument("--inclinometer-noise", type=number("--inclinometer-noise", zero=True), metavar="RAD",
                   help="σ per sample, rad")
    p.add_argument("--load-cell-rate", type=number("--load-cell-rate"), metavar="HZ")
    p.add_argument("--inclinometer-rate", type=number("--inclinometer-rate"), metavar="HZ")
    add_geometry_options(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=cmd_cg_plan)
    return p


def cmd_cg_plan(args) -> int:
    """``rig-identify cg-plan``: predicted σ of the planned test and the recommended plan; returns 0."""
    src = Path(args.rig)
    noise = SensorNoise()
    noise_src = "defaults (the reference recordings' sensors)"
    if src.is_dir():
        rig = load_rig(src / "rig.yaml") if (src / "rig.yaml").exists() else None
        if rig is None:
            raise RecordingError(f"{src}: no rig.yaml in the recording folder")
        if args.noise_from is None and (src / "bag").exists():
            args.noise_from = str(src)
    else:
        rig = load_rig_or_experiment(src)
    if args.noise_from is not None:
        step(f"reading {args.noise_from} (its sensor noise)")
        rec = read_recording(args.noise_from)
        noise = SensorNoise.from_state(StaticState.from_window(rec.sensors, label=str(rec.path), allow_motion=True))
        noise_src = f"measured in {rec.path}"
    kw = {}
    for a, k in (("load_cell_noise", "load_cell"), ("inclinometer_noise", "inclinometer"),
                 ("load_cell_rate", "rate_load_cells"), ("inclinometer_rate", "rate_inclinometer")):
        if getattr(args, a) is not None:
            kw[k] = getattr(args, a)
    if kw:
        noise = replace(noise, **kw)
        noise_src += " (with command-line overrides)"
    if args.cg_guess is not None:
        guess = np.array(args.cg_guess, float)
    elif rig.center_of_gravity is not None:
        guess = rig.center_of_gravity
    else:
        guess = rig.body_anchors.mean(0) - np.array([0.0, 0.0, 1.0])
    if (args.dummy_mass is None) != (args.dummy_position is None) and rig.dummy_mass is None:
        raise StaticsError("--dummy-mass and --dummy-position go together when rig.yaml has no dummy_mass")
    planned = None
    if args.dummy_mass is not None or args.dummy_position is not None or rig.dummy_mass is not None:
        m = args.dummy_mass if args.dummy_mass is not None else rig.dummy_mass.mass
        pos = args.dummy_position if args.dummy_position is not None else rig.dummy_mass.position
        planned = DummyMass(float(m), np.array(pos, float))
    opts = cg_options(args, rig.survey)
    target = args.target_mm * 1e-3
    out: dict = {"cg_guess": [float(x) for x in guess], "target_half_width_95": target,
                 "noise": {k: float(v) for k, v in vars(noise).items()}, "noise_source": noise_src,
                 "geometry_std": opts.geometry_std()}
    if planned is not None:
        step("predicting the CG σ of the planned test")
        r = predict_cg_std(rig, guess, planned, args.duration, noise, opts)
        out["planned"] = {"dummy_mass": planned.mass, "dummy_position": [float(x) for x in planned.position],
                          "duration": args.duration,
                          "center_of_gravity_std": [float(x) for x in r.center_of_gravity_std],
                          "half_width_95": [float(1.96 * x) for x in r.center_of_gravity_std],
                          "reaches_target": bool(np.all(1.96 * r.center_of_gravity_std <= target)),
                          "tilt_change_rad": r.weakly_determined["tilt_change_rad"]}
    masses = args.masses or (25.0, 50.0, 100.0, 200.0)
    step(f"searching dummy masses ({', '.join(f'{m:g}' for m in masses)} kg) and positions for ±{args.target_mm:g} mm")
    best, plans = plan_static_test(rig, guess, masses=masses,
                                   positions=args.position, target=target, noise=noise,
                                   max_duration=args.max_duration, options=opts)
    out["recommended"] = None if best is None else best.to_dict()
    out["candidates"] = [p.to_dict() for p in sorted(plans, key=lambda p: (not p.reaches_target, p.duration,
                                                                            p.dummy.mass))]
    if getattr(args, "progress", None) is not None:
        args.progress.finish()
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"rig: {rig.source}; assumed CG {', '.join(f'{x:.3f}' for x in guess)} m (body); sensor noise {noise_src}: "
          f"load cells {noise.load_cell:.3g} N at {noise.rate_load_cells:.0f} Hz, inclinometer "
          f"{noise.inclinometer:.3g} rad at {noise.rate_inclinometer:.0f} Hz")
    print(f"geometry as surveyed (in σ): anchors {opts.anchor_std * 1e3:g} mm, cable lengths "
          f"{opts.length_std * 1e3:g} mm, dummy position {opts.dummy_position_std * 1e3:g} mm (1 σ per coordinate; "
          "--anchor-std, --length-std, "
          "--dummy-position-std)")
    if planned is not None:
        p = out["planned"]
        print(f"planned: {planned.mass:g} kg at {', '.join(f'{x:.3f}' for x in planned.position)} m, "
              f"{args.duration:g} s per state: CG σ " + ", ".join(f"{x * 1e3:.3f}" for x in p["center_of_gravity_std"])
              + " mm, ±" + ", ".join(f"{x * 1e3:.2f}" for x in p["half_width_95"]) + " mm (95 %) -> "
              + ("reaches" if p["reaches_target"] else "does NOT reach") + f" ±{args.target_mm:g} mm")
    print(f"{'mass kg':>8s} {'position m':>24s} {'time s':>7s} {'σ x mm':>7s} {'σ y mm':>7s} {'σ z mm':>7s} "
          f"{'tilt mrad':>9s} {'ok':>3s}")
    for p in out["candidates"][:12]:
        print(f"{p['dummy_mass']:8.1f} {'(' + ', '.join(f'{x:.2f}' for x in p['dummy_position']) + ')':>24s} "
              f"{p['duration']:7.0f} " + " ".join(f"{x * 1e3:7.3f}" for x in p["center_of_gravity_std"])
              + f" {p['tilt_change_rad'] * 1e3:9.2f} {'yes' if p['reaches_target'] else 'no':>3s}")
    if best is None:
        target = args.target_mm * 1e-3
        floors = [p for p in plans if p.floor is not None]
        best_floor = min(floors, key=lambda p: float(p.floor.max())) if floors else None
        if best_floor is not None and 1.96 * best_floor.floor.max() > target:
            where = ", ".join(f"{x:.2f}" for x in best_floor.dummy.position)
            print(f"no candidate reaches ±{args.target_mm:g} mm: the rig's geometry as surveyed alone leaves σ "
                  + ", ".join(f"{x * 1e3:.2f}" for x in best_floor.floor)
                  + f" mm (x, y, z) at best ({best_floor.dummy.mass:g} kg at ({where}) m, however long the averaging): "
                  "survey the anchors, cable lengths and dummy position more precisely (and say so with --anchor-std, "
                  "--length-std, --dummy-position-std), or accept a wider target (--target-mm)")
        else:
            print(f"no candidate reaches ±{args.target_mm:g} mm within {args.max_duration:g} s per state: "
                  "use a heavier dummy, positions farther out, or better sensors")
    else:
        print(f"recommended: {best.dummy.mass:g} kg at ({', '.join(f'{x:.3f}' for x in best.dummy.position)}) m, "
              f"average {best.duration:g} s per state: ±" + ", ".join(f"{1.96 * x * 1e3:.2f}" for x in best.std)
              + " mm (95 %) on x, y, z")
    print("the dynamic run fits the CG too (rig-identify inertia: the swinging body's cable moments place it, "
          "the static test's CG its prior): the static test need not reach the target alone, it checks the "
          "dynamic one (docs/rig_model.md)")
    return 0
