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
from ..io.rig import DummyMass, Rig, load_rig
from ..model.experiment import load_rig_or_experiment
from ..statics import (
    CgOptions,
    CgPlan,
    PlanLimits,
    SensorNoise,
    StaticsError,
    StaticState,
    plan_static_test,
    predict_cg_std,
)
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


def _plan_rig(args) -> Rig:
    """The rig of ``args.rig``: a rig.yaml file, an experiment file, or a recording folder (its
    rig.yaml), which with a bag in it also gives the noise when ``--noise-from`` names none
    (``args.noise_from`` set to it).  Raises :class:`RecordingError` for a folder without rig.yaml."""
    src = Path(args.rig)
    if not src.is_dir():
        return load_rig_or_experiment(src)
    if not (src / "rig.yaml").exists():
        raise RecordingError(f"{src}: no rig.yaml in the recording folder")
    rig = load_rig(src / "rig.yaml")
    if args.noise_from is None and (src / "bag").exists():
        args.noise_from = str(src)
    return rig


def _sensor_noise(args) -> tuple[SensorNoise, str]:
    """(the planned test's sensor noise, where it came from in words): measured in the recording
    ``--noise-from`` (else the reference recordings' defaults), with the σ and rates given on the
    command line in its place."""
    noise = SensorNoise()
    noise_src = "defaults (the reference recordings' sensors)"
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
    return noise, noise_src


def _cg_guess(args, rig: Rig) -> np.ndarray:
    """(3,) the assumed CG, body frame m: ``--cg-guess``, else rig.yaml's, else 1 m below the body
    anchors' centroid."""
    if args.cg_guess is not None:
        return np.array(args.cg_guess, float)
    if rig.center_of_gravity is not None:
        return rig.center_of_gravity
    return rig.body_anchors.mean(0) - np.array([0.0, 0.0, 1.0])


def _planned_dummy(args, rig: Rig) -> DummyMass | None:
    """The planned dummy mass: ``--dummy-mass`` and ``--dummy-position``, each else rig.yaml's
    dummy_mass; None when neither is given anywhere.  Raises :class:`StaticsError` for one of the
    two options alone when rig.yaml has no dummy_mass."""
    if rig.dummy_mass is None:
        if args.dummy_mass is None and args.dummy_position is None:
            return None
        if args.dummy_mass is None or args.dummy_position is None:
            raise StaticsError("--dummy-mass and --dummy-position go together when rig.yaml has no dummy_mass")
        return DummyMass(float(args.dummy_mass), np.array(args.dummy_position, float))
    m = args.dummy_mass if args.dummy_mass is not None else rig.dummy_mass.mass
    pos = args.dummy_position if args.dummy_position is not None else rig.dummy_mass.position
    return DummyMass(float(m), np.array(pos, float))


def _planned_prediction(rig: Rig, guess: np.ndarray, planned: DummyMass, duration: float, noise: SensorNoise,
                        opts: CgOptions, target: float) -> dict:
    """The ``planned`` entry of the JSON output: the predicted CG σ (3,) m and 95 % half-widths of
    the planned test (dummy ``planned``, ``duration`` s per state) and whether they reach
    ``target`` (m) on every coordinate."""
    step("predicting the CG σ of the planned test")
    r = predict_cg_std(rig, guess, planned, duration, noise, opts)
    return {"dummy_mass": planned.mass, "dummy_position": [float(x) for x in planned.position],
            "duration": duration,
            "center_of_gravity_std": [float(x) for x in r.center_of_gravity_std],
            "half_width_95": [float(1.96 * x) for x in r.center_of_gravity_std],
            "reaches_target": bool(np.all(1.96 * r.center_of_gravity_std <= target)),
            "tilt_change_rad": r.weakly_determined["tilt_change_rad"]}


def _print_assumptions(rig: Rig, guess: np.ndarray, noise: SensorNoise, noise_src: str, opts: CgOptions) -> None:
    """The text output's head: the rig, the assumed CG, the sensor noise and the geometry's σ."""
    print(f"rig: {rig.source}; assumed CG {', '.join(f'{x:.3f}' for x in guess)} m (body); sensor noise {noise_src}: "
          f"load cells {noise.load_cell:.3g} N at {noise.rate_load_cells:.0f} Hz, inclinometer "
          f"{noise.inclinometer:.3g} rad at {noise.rate_inclinometer:.0f} Hz")
    print(f"geometry as surveyed (in σ): anchors {opts.anchor_std * 1e3:g} mm, cable lengths "
          f"{opts.length_std * 1e3:g} mm, dummy position {opts.dummy_position_std * 1e3:g} mm (1 σ per coordinate; "
          "--anchor-std, --length-std, "
          "--dummy-position-std)")


def _print_planned(planned: DummyMass, p: dict, duration: float, target_mm: float) -> None:
    """The planned test's line: ``p`` its :func:`_planned_prediction`; duration s per state;
    target_mm the 95 % half-width required, mm."""
    print(f"planned: {planned.mass:g} kg at {', '.join(f'{x:.3f}' for x in planned.position)} m, "
          f"{duration:g} s per state: CG σ " + ", ".join(f"{x * 1e3:.3f}" for x in p["center_of_gravity_std"])
          + " mm, ±" + ", ".join(f"{x * 1e3:.2f}" for x in p["half_width_95"]) + " mm (95 %) -> "
          + ("reaches" if p["reaches_target"] else "does NOT reach") + f" ±{target_mm:g} mm")


def _print_candidates(candidates: list[dict]) -> None:
    """The table of the first 12 candidates (:meth:`CgPlan.to_dict`, in the order given)."""
    print(f"{'mass kg':>8s} {'position m':>24s} {'time s':>7s} {'σ x mm':>7s} {'σ y mm':>7s} {'σ z mm':>7s} "
          f"{'tilt mrad':>9s} {'ok':>3s}")
    for p in candidates[:12]:
        print(f"{p['dummy_mass']:8.1f} {'(' + ', '.join(f'{x:.2f}' for x in p['dummy_position']) + ')':>24s} "
              f"{p['duration']:7.0f} " + " ".join(f"{x * 1e3:7.3f}" for x in p["center_of_gravity_std"])
              + f" {p['tilt_change_rad'] * 1e3:9.2f} {'yes' if p['reaches_target'] else 'no':>3s}")


def _print_unreached(plans: list[CgPlan], target_mm: float, max_duration: float) -> None:
    """Why no candidate reaches ±``target_mm`` mm: the surveyed geometry's floor (then survey more
    precisely or widen the target), else the averaging time ``max_duration`` s (then a heavier
    dummy, farther positions or better sensors)."""
    target = target_mm * 1e-3
    floors = [p for p in plans if p.floor is not None]
    best_floor = min(floors, key=lambda p: float(p.floor.max())) if floors else None
    if best_floor is not None and 1.96 * best_floor.floor.max() > target:
        where = ", ".join(f"{x:.2f}" for x in best_floor.dummy.position)
        print(f"no candidate reaches ±{target_mm:g} mm: the rig's geometry as surveyed alone leaves σ "
              + ", ".join(f"{x * 1e3:.2f}" for x in best_floor.floor)
              + f" mm (x, y, z) at best ({best_floor.dummy.mass:g} kg at ({where}) m, however long the averaging): "
              "survey the anchors, cable lengths and dummy position more precisely (and say so with --anchor-std, "
              "--length-std, --dummy-position-std), or accept a wider target (--target-mm)")
    else:
        print(f"no candidate reaches ±{target_mm:g} mm within {max_duration:g} s per state: "
              "use a heavier dummy, positions farther out, or better sensors")


def cmd_cg_plan(args) -> int:
    """``rig-identify cg-plan``: predicted σ of the planned test and the recommended plan; returns 0."""
    rig = _plan_rig(args)
    noise, noise_src = _sensor_noise(args)
    guess = _cg_guess(args, rig)
    planned = _planned_dummy(args, rig)
    opts = cg_options(args, rig.survey)
    target = args.target_mm * 1e-3
    out: dict = {"cg_guess": [float(x) for x in guess], "target_half_width_95": target,
                 "noise": {k: float(v) for k, v in vars(noise).items()}, "noise_source": noise_src,
                 "geometry_std": opts.geometry_std()}
    if planned is not None:
        out["planned"] = _planned_prediction(rig, guess, planned, args.duration, noise, opts, target)
    masses = args.masses or (25.0, 50.0, 100.0, 200.0)
    step(f"searching dummy masses ({', '.join(f'{m:g}' for m in masses)} kg) and positions for ±{args.target_mm:g} mm")
    best, plans = plan_static_test(rig, guess, masses=masses, positions=args.position, noise=noise, options=opts,
                                   limits=PlanLimits(target=target, max_duration=args.max_duration))
    out["recommended"] = None if best is None else best.to_dict()
    out["candidates"] = [p.to_dict() for p in sorted(plans, key=lambda p: (not p.reaches_target, p.duration,
                                                                            p.dummy.mass))]
    if getattr(args, "progress", None) is not None:
        args.progress.finish()
    if args.json:
        print(json.dumps(out))
        return 0
    _print_assumptions(rig, guess, noise, noise_src, opts)
    if planned is not None:
        _print_planned(planned, out["planned"], args.duration, args.target_mm)
    _print_candidates(out["candidates"])
    if best is None:
        _print_unreached(plans, args.target_mm, args.max_duration)
    else:
        print(f"recommended: {best.dummy.mass:g} kg at ({', '.join(f'{x:.3f}' for x in best.dummy.position)}) m, "
              f"average {best.duration:g} s per state: ±" + ", ".join(f"{1.96 * x * 1e3:.2f}" for x in best.std)
              + " mm (95 %) on x, y, z")
    print("the dynamic run fits the CG too (rig-identify inertia: the swinging body's cable moments place it, "
          "the static test's CG its prior): the static test need not reach the target alone, it checks the "
          "dynamic one (docs/rig_model.md)")
    return 0
