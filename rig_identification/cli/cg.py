"""``rig-identify cg`` and ``rig-identify cg-plan``: the static centre-of-gravity experiment.

    rig-identify cg BASELINE_RECORDING DUMMY_RECORDING [--json] [--write-rig OUT.yaml [--force]]
                    [--start S] [--end S] [--dummy-mass KG --dummy-position X Y Z] [--tare KG X Y Z]
                    [--scale-std KG] [--anchor-std MM] [--length-std MM] [--dummy-position-std MM]
                    [--no-load-cells] [--no-inclinometer] [--accelerometer]
                    [--fit-inclinometer-offset] [--allow-motion]
    rig-identify cg-plan RIG [--cg-guess X Y Z] [--dummy-mass KG] [--dummy-position X Y Z]
                    [--duration S] [--masses KG ...] [--position X Y Z ...] [--target-mm MM]
                    [--noise-from RECORDING] [--load-cell-noise N] [--inclinometer-noise RAD]
                    [--load-cell-rate HZ] [--inclinometer-rate HZ] [--anchor-std MM]
                    [--length-std MM] [--dummy-position-std MM] [--max-duration S] [--json]

``cg`` estimates the CG of the suspended body of BASELINE (body at rest without the dummy
mass) from it and DUMMY (with the dummy mass of rig.yaml ``dummy_mass``), see
:mod:`rig_identification.statics`.  Its σ (``center_of_gravity_std``) includes the rig's
geometry as surveyed -- by default 1 mm (1 σ per coordinate) on every anchor, cable length
and the dummy's position (:data:`~.statics.DEFAULT_ANCHOR_STD` ...), set with --anchor-std,
--length-std, --dummy-position-std -- and ``center_of_gravity_std_noise`` is the measurement
noise's alone; both are printed.  ``--json`` prints one object, :meth:`~.statics.CgResult.to_dict`
(``schema`` :data:`~.statics.CG_RESULT_SCHEMA`, ``schema_version``, ``units``, body frame, m,
kg) with ``baseline``, ``dummy``, ``created`` and ``written_rig``; saved to a file it is read
back by :func:`load_cg_result` (e.g. for ``rig-identify inertia --cg CG.json``).
``--write-rig OUT.yaml`` writes a copy of the recordings' rig.yaml with ``body.center_of_gravity``
set to the estimate (comment lines: date, σ, source recordings), atomically; an existing OUT is
replaced only with ``--force``.  truth.yaml is never used for the estimate; when present it is
shown beside it (text output only).

``cg-plan`` predicts the CG σ of a planned static test and recommends one that reaches
±2.5 mm (1.96 σ) on every coordinate.  RIG is a rig.yaml file, an experiment file or a
recording folder (whose data give the sensor noise).

``rig-identify`` (cli.py) wires these in with :func:`add_cg_parser`,
:func:`add_cg_plan_parser`; user errors raise the errors listed in :data:`USER_ERRORS`, which
``rig-identify`` prints as one line (exit status 2); :class:`CgResultError` is a
:class:`~.statics.StaticsError`.
"""
from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..io.atomic import atomic_write_text
from ..io.recording import RecordingError, read_recording
from ..io.rig import DummyMass, Rig, RigError, dump_rig, load_rig
from ..model.experiment import load_rig_or_experiment
from ..statics import (CG_RESULT_SCHEMA, CG_RESULT_SCHEMA_VERSION, DEFAULT_ANCHOR_STD, DEFAULT_DUMMY_POSITION_STD,
                      DEFAULT_LENGTH_STD, CgOptions, CgResult, SensorNoise, StaticsError, StaticState, estimate_cg,
                      plan_static_test, predict_cg_std)
from ..estimation.tracker import TrackerError


class CgResultError(StaticsError):
    """A CG result file (the JSON of ``rig-identify cg --json``) or a ``--write-rig`` target
    that cannot be used; the message names the file and the field."""


USER_ERRORS = (RecordingError, RigError, StaticsError, TrackerError, FileNotFoundError)

GEOMETRY_NOTE = ("a careful steel-tape or laser survey: class II tape ±(0.3 + 0.2 L/m) mm, ±1.1 mm over 4 m")


def _options(args) -> CgOptions:
    def mm(name, default):
        v = getattr(args, name, None)
        return default if v is None else v * 1e-3
    return CgOptions(use_load_cells=not getattr(args, "no_load_cells", False),
                     use_inclinometer=not getattr(args, "no_inclinometer", False),
                     use_accelerometer=getattr(args, "accelerometer", False),
                     fit_inclinometer_offset=getattr(args, "fit_inclinometer_offset", False),
                     scale_std=getattr(args, "scale_std", None),
                     anchor_std=mm("anchor_std", DEFAULT_ANCHOR_STD),
                     length_std=mm("length_std", DEFAULT_LENGTH_STD),
                     dummy_position_std=mm("dummy_position_std", DEFAULT_DUMMY_POSITION_STD))


def _positive(name):
    def f(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(x) and x > 0):
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {text!r}")
        return x
    return f


def _nonneg(name):
    def f(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not (math.isfinite(x) and x >= 0):
            raise argparse.ArgumentTypeError(f"{name} must be >= 0, got {text!r}")
        return x
    return f


def _add_common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scale-std", type=_positive("--scale-std"), metavar="KG",
                   help="σ of the scale's mass reading (default 0.1 %% of it)")
    p.add_argument("--anchor-std", type=_nonneg("--anchor-std"), metavar="MM",
                   help=f"σ of each coordinate of every ceiling and body anchor, mm (default "
                        f"{DEFAULT_ANCHOR_STD * 1e3:g}: {GEOMETRY_NOTE}; 0: exact)")
    p.add_argument("--length-std", type=_nonneg("--length-std"), metavar="MM",
                   help=f"σ of the cable lengths of rig.yaml, mm (default {DEFAULT_LENGTH_STD * 1e3:g}; 0: exact)")
    p.add_argument("--dummy-position-std", type=_nonneg("--dummy-position-std"), metavar="MM",
                   help=f"σ of each coordinate of the dummy mass's position, mm (default "
                        f"{DEFAULT_DUMMY_POSITION_STD * 1e3:g}; 0: exact)")


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
    p.add_argument("--dummy-mass", type=_positive("--dummy-mass"), metavar="KG",
                   help="dummy mass, kg (default: rig.yaml dummy_mass)")
    p.add_argument("--dummy-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="dummy mass position, body frame, m (default: rig.yaml dummy_mass)")
    p.add_argument("--tare", type=float, nargs=4, metavar=("KG", "X", "Y", "Z"),
                   help="a known part of the suspended body (e.g. the carrying frame: mass and CG, body "
                        "frame m): also report the CG of the rest (the vehicle)")
    _add_common(p)
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
    st.warnings = [f"{rec.path}: {w}" for w in rec.warnings] + st.warnings
    return st


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
    sd = _state(rd, "dummy", args)
    sd.added = (dummy,)
    return estimate_cg(rig, sb, sd, _options(args)), rb, rd


def check_rig_target(out: Path, force: bool, recordings: list[Path]) -> None:
    """Refuse a --write-rig target that exists (unless ``force``) or is a recording's own rig.yaml."""
    for rec in recordings:
        own = rec / "rig.yaml"
        if own.exists() and out.exists() and out.resolve() == own.resolve():
            raise CgResultError(f"{out}: --write-rig would replace the recording {rec}'s own rig.yaml; a recording "
                                "stays as it was recorded: write the copy elsewhere")
    if out.is_dir():
        raise CgResultError(f"{out}: --write-rig names a folder; give the file to write (e.g. {out / 'rig.yaml'})")
    if out.exists() and not force:
        raise CgResultError(f"{out}: already exists; refusing to overwrite it (pass --force to replace it)")


def rig_with_cg_text(rig: Rig, result: "CgResult | SavedCgResult", sources: list[str], created: str,
                     original: str | None = None, by: str = "rig-identify cg") -> str:
    """rig.yaml text: ``rig`` with ``body.center_of_gravity`` set to ``result``'s estimate (a
    :class:`~.statics.CgResult`, or the :class:`SavedCgResult` of its JSON: what
    ``mass_properties_client cg-estimate`` receives from the identifier node), headed by
    comment lines (``created``, ``by`` what, the σ with and without the geometry, the validation
    verdict, the ``sources``: the static recordings, or what captured the states) and the
    leading comment lines of ``original`` (the source rig.yaml's text, if given).  The values
    are written exactly (YAML floats round-trip); rig.yaml's other fields are kept
    (:func:`~rig_identification.io.rig.dump_rig`)."""
    c, sd = result.center_of_gravity, result.center_of_gravity_std
    mm = ", ".join(f"{x * 1e3:.2f}" for x in sd)
    noise = result.center_of_gravity_std_noise
    geo = result.geometry_std
    if isinstance(result, SavedCgResult):
        verdict, failed = result.verdict, result.failed
    else:
        verdict, failed = (None, ()) if result.validation is None else (result.validation.verdict,
                                                                          result.validation.failed)
    cg_text = ", ".join(f"{x:.5f}" for x in c)
    lines = [f"body.center_of_gravity = [{cg_text}] m estimated by {by} on {created}",
             f"σ {mm} mm (x, y, z: measurement noise and geometry, anchors {geo.get('anchors', 0) * 1e3:g} mm, "
             f"cable lengths {geo.get('cable_lengths', 0) * 1e3:g} mm, dummy position "
             f"{geo.get('dummy_position', 0) * 1e3:g} mm)"
             + ("" if noise is None else "; noise only " + ", ".join(f"{x * 1e3:.2f}" for x in noise) + " mm"),
             "validation: " + ("not run" if verdict is None else verdict
                               + (f" ({', '.join(failed)} failed)" if failed else "")),
             "from " + " and ".join(sources)]
    head = "".join(f"# {x}\n" for x in lines)
    if original:
        lead = []
        for line in original.splitlines():
            if not line.startswith("#"):
                break
            lead.append(line + "\n")
        head += "".join(lead)
    return head + dump_rig(rig.with_cg(c))


def cmd_cg(args) -> int:
    """``rig-identify cg``: print the CG estimate (text or ``--json``), write ``--write-rig``; returns 0."""
    out = Path(args.write_rig) if getattr(args, "write_rig", None) else None
    if out is not None:
        check_rig_target(out, args.force, [Path(args.baseline), Path(args.dummy)])
    res, rb, rd = run_cg(args)
    created = datetime.now(timezone.utc).isoformat(timespec="seconds")
    d = res.to_dict()
    d["baseline"], d["dummy"], d["created"] = str(rb.path), str(rd.path), created
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


# --- the CG result file ----------------------------------------------------------------------------

@dataclass(frozen=True)
class SavedCgResult:
    """A CG result read from a file (:func:`load_cg_result`).

    center_of_gravity (3,) body frame m; center_of_gravity_std (3,) m (measurement noise and
    geometry); center_of_gravity_std_noise (3,) m or None (files before schema version 1);
    covariance (3, 3) m² or None; mass kg or None; verdict: the validation's (``ok``,
    ``model_error``) or None; schema_version (0: a file without ``schema``, written before
    the field existed); source: the file; geometry_std: the geometry's σ the estimate assumed
    (``uncertainty.geometry_std``: anchors, cable_lengths, dummy_position, m; empty when the
    file has none); failed: the names of the validation's failed checks."""

    center_of_gravity: np.ndarray
    center_of_gravity_std: np.ndarray
    center_of_gravity_std_noise: np.ndarray | None
    covariance: np.ndarray | None
    mass: float | None
    verdict: str | None
    schema_version: int
    source: str
    geometry_std: dict = field(default_factory=dict)
    failed: tuple[str, ...] = ()


def _vec3(d: dict, key: str, src: str, positive: bool = False, required: bool = True) -> np.ndarray | None:
    v = d.get(key)
    if v is None:
        if required:
            raise CgResultError(f"{src}: missing field {key}")
        return None
    if not isinstance(v, list) or len(v) != 3 or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                          for x in v):
        raise CgResultError(f"{src}: field {key} must be a list of 3 numbers, got {v!r}")
    a = np.array(v, float)
    for i, x in enumerate(a):
        if not math.isfinite(x):
            raise CgResultError(f"{src}: field {key}[{i}] must be finite, got {v[i]!r}")
        if positive and x <= 0:
            raise CgResultError(f"{src}: field {key}[{i}] must be > 0, got {v[i]!r}")
    return a


def load_cg_result(path: str | Path) -> SavedCgResult:
    """Read a CG result file: the JSON object ``rig-identify cg --json`` prints (schema
    :data:`~.statics.CG_RESULT_SCHEMA`, versions up to :data:`~.statics.CG_RESULT_SCHEMA_VERSION`;
    a file without ``schema``, from before it existed, is read as version 0), e.g. for
    ``rig-identify inertia --cg CG.json``.

    Returns :class:`SavedCgResult` (CG (3,) body frame m and its σ).  Raises
    :class:`CgResultError` naming the file and the field: unreadable, not JSON, another
    schema or a newer version, frame not ``body``, CG or σ not 3 finite numbers (σ > 0),
    a covariance that is not (3, 3) finite and symmetric."""
    p = Path(path)
    src = str(p)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise CgResultError(f"{src}: cannot read the CG result ({e.strerror})") from None
    except UnicodeDecodeError as e:
        raise CgResultError(f"{src}: not a text file (byte {e.start} is not UTF-8)") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as e:
        raise CgResultError(f"{src}: not JSON ({e.msg} at line {e.lineno}, column {e.colno}); save the output of "
                            "rig-identify cg --json") from None
    return cg_result_from_dict(d, src)


def cg_result_from_dict(d, src: str) -> SavedCgResult:
    """:class:`SavedCgResult` of a CG result's JSON object ``d`` (as :func:`load_cg_result`
    reads it from a file; also the identifier node's ~/estimate_cg answer); ``src`` names it
    in errors.  Raises :class:`CgResultError` as :func:`load_cg_result`."""
    if not isinstance(d, dict):
        raise CgResultError(f"{src}: a CG result is a JSON object, got {type(d).__name__}")
    schema = d.get("schema")
    if schema is None:
        version = 0
    elif schema != CG_RESULT_SCHEMA:
        raise CgResultError(f"{src}: field schema is {schema!r}, not {CG_RESULT_SCHEMA!r} "
                            "(not a rig-identify cg result)")
    else:
        version = d.get("schema_version")
        if not isinstance(version, int) or isinstance(version, bool) or version < 1:
            raise CgResultError(f"{src}: field schema_version must be an integer >= 1, got {version!r}")
        if version > CG_RESULT_SCHEMA_VERSION:
            raise CgResultError(f"{src}: field schema_version is {version}, written by a newer rig_identification; "
                                f"this one reads up to {CG_RESULT_SCHEMA_VERSION}")
    frame = d.get("frame", "body")
    if frame != "body":
        raise CgResultError(f"{src}: field frame is {frame!r}; the CG must be in the body frame")
    c = _vec3(d, "center_of_gravity", src)
    sd = _vec3(d, "center_of_gravity_std", src, positive=True)
    sdn = _vec3(d, "center_of_gravity_std_noise", src, positive=True, required=False)
    cov = None
    raw = d.get("center_of_gravity_covariance")
    if raw is not None:
        try:
            cov = np.array(raw, float)
        except (TypeError, ValueError):
            cov = None
        if cov is None or cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-9,
                                                                                                   atol=0.0):
            raise CgResultError(f"{src}: field center_of_gravity_covariance must be a symmetric 3×3 list of "
                                "finite numbers")
    mass = d.get("mass")
    if mass is not None and (isinstance(mass, bool) or not isinstance(mass, (int, float)) or not math.isfinite(mass)
                             or mass <= 0):
        raise CgResultError(f"{src}: field mass must be a number > 0, got {mass!r}")
    val = d.get("validation")
    verdict = val.get("verdict") if isinstance(val, dict) else None
    failed = tuple(str(x) for x in val.get("failed") or ()) if isinstance(val, dict) else ()
    unc = d.get("uncertainty")
    geo = unc.get("geometry_std") if isinstance(unc, dict) else None
    geo = {str(k): float(v) for k, v in geo.items() if isinstance(v, (int, float)) and not isinstance(v, bool)} \
        if isinstance(geo, dict) else {}
    return SavedCgResult(c, sd, sdn, cov, None if mass is None else float(mass), verdict, int(version), src, geo, failed)


# --- cg-plan -------------------------------------------------------------------------------------

def add_cg_plan_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``cg-plan`` sub-command (experiment design of the static test); returns it."""
    p = subparsers.add_parser("cg-plan", help="predict the CG uncertainty of a planned static test and "
                                              "recommend one reaching ±2.5 mm",
                              description="Experiment design for the static CG test: predicted CG σ of a "
                                          "planned test and a recommended plan.")
    p.add_argument("rig", help="rig.yaml file, an experiment file (config/cases/*.yaml), or a recording folder "
                               "(its rig.yaml; its data give the noise)")
    p.add_argument("--cg-guess", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="assumed CG, body frame m (default: rig.yaml's, else 1 m below the body anchors' centroid)")
    p.add_argument("--dummy-mass", type=_positive("--dummy-mass"), metavar="KG",
                   help="planned dummy mass (default: rig.yaml dummy_mass)")
    p.add_argument("--dummy-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="planned dummy position, body frame m (default: rig.yaml dummy_mass)")
    p.add_argument("--duration", type=_positive("--duration"), default=10.0, metavar="S",
                   help="planned averaging time per state, s (default 10)")
    p.add_argument("--masses", type=_positive("--masses"), nargs="+", metavar="KG",
                   help="dummy masses to consider (default 25 50 100 200)")
    p.add_argument("--position", type=float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="a dummy position to consider, body frame m (repeatable; default: the body "
                        "anchors and the corners 1 m below them)")
    p.add_argument("--target-mm", type=_positive("--target-mm"), default=2.5, metavar="MM",
                   help="required half-width of the 95 %% interval (1.96 σ) on every coordinate, mm")
    p.add_argument("--max-duration", type=_positive("--max-duration"), default=600.0, metavar="S",
                   help="longest acceptable averaging time per state, s (default 600)")
    p.add_argument("--noise-from", metavar="RECORDING", help="measure the sensor noise in this static recording")
    p.add_argument("--load-cell-noise", type=_nonneg("--load-cell-noise"), metavar="N", help="σ per sample, N")
    p.add_argument("--inclinometer-noise", type=_nonneg("--inclinometer-noise"), metavar="RAD",
                   help="σ per sample, rad")
    p.add_argument("--load-cell-rate", type=_positive("--load-cell-rate"), metavar="HZ")
    p.add_argument("--inclinometer-rate", type=_positive("--inclinometer-rate"), metavar="HZ")
    _add_common(p)
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
    opts = _options(args)
    target = args.target_mm * 1e-3
    out: dict = {"cg_guess": [float(x) for x in guess], "target_half_width_95": target,
                 "noise": {k: float(v) for k, v in vars(noise).items()}, "noise_source": noise_src,
                 "geometry_std": opts.geometry_std()}
    if planned is not None:
        r = predict_cg_std(rig, guess, planned, args.duration, noise, opts)
        out["planned"] = {"dummy_mass": planned.mass, "dummy_position": [float(x) for x in planned.position],
                          "duration": args.duration, "center_of_gravity_std": [float(x) for x in r.center_of_gravity_std],
                          "half_width_95": [float(1.96 * x) for x in r.center_of_gravity_std],
                          "reaches_target": bool(np.all(1.96 * r.center_of_gravity_std <= target)),
                          "tilt_change_rad": r.weakly_determined["tilt_change_rad"]}
    best, plans = plan_static_test(rig, guess, masses=args.masses or (25.0, 50.0, 100.0, 200.0),
                                   positions=args.position, target=target, noise=noise,
                                   max_duration=args.max_duration, options=opts)
    out["recommended"] = None if best is None else best.to_dict()
    out["candidates"] = [p.to_dict() for p in sorted(plans, key=lambda p: (not p.reaches_target, p.duration,
                                                                            p.dummy.mass))]
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
    return 0
