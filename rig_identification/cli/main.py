"""rig-identify: identify mass, centre of gravity and inertia tensor from rig recordings, offline.

The sub-commands replay recording folders (rig.yaml + bag/) through the same tracker,
preprocessor and identifier code as the ROS nodes.  This module builds the command line and
runs the chosen command; the commands are in cli.rig_model (cli.joint for several recordings),
cli.diagnose, cli.plan (plan and modes), cli.cg, cli.cg_plan and cli.thesis_table, imported only
when they run (``rig-identify --help`` does not load scipy).  User errors (a
missing path, bad files, inconsistent input) print one line ``rig-identify: error: …`` and
exit with status 2, no traceback; a path that does not exist is refused before any work.
Progress goes to stderr (one line per step, warnings as they happen; ``--quiet``: warnings only).
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import Callable

from ..io.verdict import package_version
from .arg_types import JOB_OPTIONS, UsageError, number
from .progress import attached

DESCRIPTION = """\
Identify the mass properties of a vehicle hung on cables, offline, from recording folders
(rig.yaml + bag/): the same tracker, preprocessor and identifier code as the ROS nodes.

Every inertia output says its conventions: tensor about the centre of gravity, body frame
of rig.yaml (right-handed, as REP-103; where the vehicle's front and top lie in it is rig.yaml's
body.vehicle, and only then are moments called roll, pitch, yaw), SI units; the tensor's
off-diagonal entries ixy, ixz, iyz are the negated products of inertia (Ixy = -ixy, the
vehicle-dynamics sign).
Options that take a tensor all take ixx iyy izz ixy ixz iyz, in that order.
"""

EPILOG = """\
a rig day:
  rig-identify cg-plan RIG                       plan the static test
  rig-identify cg BASE DUMMY --write-rig R.yaml  centre of gravity from the two static recordings
  rig-identify plan RIG --inertia ...            plan the exciter run(s)
  rig-identify inertia REC                       verdict, tensor, CG, products, principal axes (every sensor fitted)
  rig-identify inertia REC --json                one JSON object (schema rig_identification.rig_model_result)
  rig-identify inertia REC --urdf --yaml F.yaml  a URDF <inertial> element; a YAML file
  rig-identify diagnose REC                      where the model and the recording disagree, and why
research baselines (not for a rig day):
  rig-identify thesis-table                      the thesis's 17 case studies: its errors, ours, its method's
Exit status: 0 done, 2 a user error (one line on stderr, naming the file or the option)."""


def lazy(module: str, name: str) -> Callable:
    """The command ``module.name``, imported when it runs (the heavy modules stay out of --help)."""
    def run(args) -> int:
        return getattr(importlib.import_module(module), name)(args)
    run.__qualname__ = f"{module}.{name}"
    return run


TENSOR = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")   # metavars of every option that takes a tensor (export.ORDER)
TENSOR_HELP = ("tensor entries about the CG, body axes of rig.yaml, kg·m², in the order ixx iyy izz ixy ixz iyz "
               "(moments, then products: the order of every option); ixy, ixz, iyz are the tensor's off-diagonal "
               "entries as in truth.yaml and the JSON, i.e. the negated products of inertia (ixy = −Ixy)")


def inertia_command(args) -> int:
    """``rig-identify inertia``: one recording's command (cli.rig_model), or several recordings' at
    once (cli.joint: the joint fit's modules load only then)."""
    module = "rig_identification.cli.joint" if len(args.recording) > 1 else "rig_identification.cli.rig_model"
    return lazy(module, "cmd_inertia")(args)


def add_command(sub, name: str, help: str | None, description: str, run: Callable, inputs=(),
                outputs=(), output_dirs=()) -> argparse.ArgumentParser:
    """A sub-command parser with a description paragraph, its runner, the destinations of its
    input paths (checked to exist before any work), of its output files and of its output folders
    (:func:`check_paths`: the folder an output goes into must exist).  ``help`` None: not in the
    list of commands (a research baseline, named in :data:`EPILOG` instead)."""
    p = sub.add_parser(name, description=description, **({} if help is None else {"help": help}))
    p.set_defaults(func=run, inputs=tuple(inputs), outputs=tuple(outputs), output_dirs=tuple(output_dirs))
    p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress lines on stderr (warnings still)")
    return p


def add_report_options(p: argparse.ArgumentParser) -> None:
    """``--report DIR`` and the report header's job options (:data:`~.arg_types.JOB_OPTIONS`)."""
    p.add_argument("--report", metavar="DIR", help="also write an HTML report (index.html + figures) to the folder DIR")
    for flag, _, what in JOB_OPTIONS:
        p.add_argument(flag, metavar="TEXT", help=f"with --report: {what}, named in the report's header (one line)")


def add_inertia_parser(sub) -> None:
    p = add_command(sub, "inertia", "identify the inertia tensor from one or more dynamic recordings",
                    "Fit the rig's grey-box model to every sensor of a dynamic recording (tensions, gyro, "
                    "accelerometer, inclinometer; the mass, CG and tensor together) and print the mass "
                    "properties: the verdict first (ok / model_error / not_identifiable / inconsistent / failed), "
                    "the tensor about the CG with σ beside the Cramér–Rao bound (and the truth when truth.yaml is "
                    "there), the principal moments and axes, the tensor about the body frame's origin, the mass "
                    "and the CG from the static test, the run and both, and each channel's residual against its "
                    "noise. Several recordings of one body: fitted at once, each with its own rig model, the "
                    "body's mass, CG and tensor shared.",
                    inertia_command, inputs=("recording", "cg"),
                    outputs=("yaml",), output_dirs=("report",))
    p.add_argument("recording", nargs="+",
                   help="recording folder (rig.yaml + bag/); several recordings of the same body (other exciter "
                        "frequencies or positions, cable geometries) are fitted at once, one body shared")
    add_report_options(p)
    p.add_argument("--json", action="store_true",
                   help="print one JSON object (schema rig_identification.rig_model_result; "
                        "rig_identification.joint_rig_model_result for several recordings; units per field)")
    p.add_argument("--urdf", action="store_true",
                   help="also print a URDF <inertial> element (origin at the CG, mass, tensor entries; always in "
                        "rig.yaml's body axes, REP-103, whatever --axes says)")
    p.add_argument("--yaml", metavar="FILE", help="also write the mass properties to FILE (YAML, atomically)")
    p.add_argument("--axes", choices=("body", "sae", "iso8855"), default=None,
                   help="axes of the printout and the YAML: body (rig.yaml's body frame, right-handed), sae (SAE "
                        "J670: x forward, y right, z down) or iso8855 (ISO 8855: x forward, y left, z up), the "
                        "vehicle axes turned from the body frame by rig.yaml's body.vehicle (front and top; without "
                        "it they are refused); default: rig.yaml's output_axes, else body. The JSON stays in body "
                        "axes and gains a 'sae_j670' or 'iso_8855' block")
    p.add_argument("--start", type=float, metavar="S", help="window start, s from the first IMU sample")
    p.add_argument("--end", type=float, metavar="S", help="window end, s from the first IMU sample")
    p.add_argument("--cg", metavar="CG.json",
                   help="take the centre of gravity from a saved 'rig-identify cg --json' result instead of "
                        "rig.yaml's body.center_of_gravity")


def add_diagnose_parser(sub) -> None:
    dp = add_command(sub, "diagnose",
                     "where the model and a recording disagree, and which physics is missing",
                     "Fit the rig's grey-box model to every sensor as 'rig-identify inertia' does, print its verdict "
                     "and each channel's residual over its noise; then test what the model may leave out (quadratic "
                     "drag, dry friction, the exciter's unbalance, the load cells' and the exciter's delay, the "
                     "IMU's position, gyro scale and drift), name an extension only where the recording tells it "
                     "apart from the others (else its class, and what would tell them apart), add it, fit again and "
                     "print each channel's residual before and after and the tensor of the model with it.",
                     lazy("rig_identification.cli.diagnose", "cmd_diagnose"), inputs=("recording", "cg"),
                     output_dirs=("report",))
    dp.add_argument("recording", help="recording folder (rig.yaml + bag/)")
    dp.add_argument("--json", action="store_true",
                    help="print one JSON object (rig-identify inertia's, schema "
                         "rig_identification.rig_model_result)")
    add_report_options(dp)
    dp.add_argument("--cg", metavar="CG.json",
                    help="the centre of gravity's prior from a saved 'rig-identify cg --json' result "
                         "(its σ) instead of rig.yaml's")
    dp.add_argument("--start", type=float, metavar="S", help="window start, s from the first IMU sample")
    dp.add_argument("--end", type=float, metavar="S", help="window end, s from the first IMU sample")


def add_plan_parser(sub) -> None:
    pp = add_command(sub, "plan", "know before you shake: the rig's modes, predicted inertia σ and the recommended "
                     "exciter run(s) for a nominal body",
                     "Experiment design for the dynamic test: the rig's natural modes, the σ a baseline exciter run "
                     "would give the tensor of a nominal body, and the run(s) that would do better within the rig's "
                     "limits (rotation, cable tension, exciter force and frequency). The σ is the rig model's "
                     "Cramér–Rao bound along a simulation of each run (every sensor an output: what inertia "
                     "reaches); a screen of the rig linearised ranks the candidates first.",
                     lazy("rig_identification.cli.plan", "cmd_plan"), inputs=("rig", "geometry"))
    pp.add_argument("rig", help="rig.yaml, experiment file or recording folder (CG from rig.yaml)")
    pp.add_argument("--inertia", type=float, nargs=6, required=True, metavar=TENSOR,
                    help="nominal " + TENSOR_HELP)
    pp.add_argument("--mass", type=float, metavar="KG", help="nominal mass (default: rig.yaml body.mass)")
    pp.add_argument("--duration", type=float, default=120.0, metavar="S", help="length of each run (default 120)")
    pp.add_argument("--max-force", type=float, metavar="N",
                    help="largest force amplitude the exciter can make (default: rig.yaml exciter.max_force; "
                         "without it no limit but the rig's)")
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
    pp.add_argument("--target", type=number("--target"), default=1.0, metavar="PCT",
                    help="the precision asked of every entry, %% at 95 %% (as rig-identify inertia --target; "
                         "default 1): whether the baseline and the plan reach it, and how long a run would")
    pp.add_argument("--json", action="store_true", help="print one JSON object")


def add_modes_parser(sub) -> None:
    mp = add_command(sub, "modes", "natural frequencies: from the geometry vs estimated from a recording",
                     "The rig's natural modes from its geometry (cables, mass, CG and a tensor) beside the modes "
                     "estimated from a recording's gyro, matched one to one.",
                     lazy("rig_identification.cli.plan", "cmd_modes"), inputs=("recording",))
    mp.add_argument("recording", help="recording folder (rig.yaml + bag/)")
    mp.add_argument("--json", action="store_true", help="print one JSON object")
    mp.add_argument("--inertia", type=float, nargs=6, metavar=TENSOR,
                    help=TENSOR_HELP + "; default: identified from the recording")
    mp.add_argument("--stiffness", type=float, metavar="N_PER_M",
                    help="cable stiffness for the model (default: rig.yaml's, else inextensible cables)")


def add_thesis_table_parser(sub) -> None:
    t = add_command(sub, "thesis-table", None,
                    "Simulate the thesis's case studies (config/cases) noise-free, identify each with the rig model "
                    "(the cases whose cables stretch) and with the thesis's method, and print the errors beside "
                    "those the thesis reported.",
                    lazy("rig_identification.cli.thesis_table", "cmd_thesis_table"))
    t.add_argument("cases", nargs="*", help="case names (default: case01 … case17)")
    t.add_argument("--json", action="store_true", help="print one JSON list")


STATIC = {"cg": ("centre of gravity from the two static recordings (without and with the dummy mass)",
                 ("baseline", "dummy"), ("write_rig",)),
          "cg-plan": ("predict the CG uncertainty of a planned static test and recommend one reaching ±2 mm",
                      ("rig", "noise_from"), ())}
"""The static-test commands (cli.cg, cli.cg_plan): their one-line help (for the top-level help, which does
not import them), the destinations of their input paths and of their output files."""


def add_static_parser(sub, name: str, wanted: str | None) -> None:
    """cg or cg-plan (:mod:`rig_identification.cli.cg`, :mod:`rig_identification.cli.cg_plan`, which load
    scipy): the real parser only when it is the command; otherwise a placeholder that carries its
    one-line help."""
    if wanted != name:
        sub.add_parser(name, help=STATIC[name][0], add_help=False)
        return
    if name == "cg":
        from .cg import add_cg_parser as add_parser
    else:
        from .cg_plan import add_cg_plan_parser as add_parser
    p = add_parser(sub)
    p.set_defaults(inputs=STATIC[name][1], outputs=STATIC[name][2], output_dirs=())
    p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress lines on stderr (warnings still)")


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``rig-identify`` parser; ``argv`` tells which command will run (only its heavy parser,
    if any, is built)."""
    argv = sys.argv[1:] if argv is None else argv
    wanted = next((a for a in argv if not a.startswith("-")), None)
    ap = argparse.ArgumentParser(prog="rig-identify", description=DESCRIPTION, epilog=EPILOG,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--version", action="version", version=f"rig-identify (rig_identification) {package_version()}")
    ap.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr (warnings still)")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_inertia_parser(sub)
    add_diagnose_parser(sub)
    add_static_parser(sub, "cg", wanted)
    add_static_parser(sub, "cg-plan", wanted)
    add_plan_parser(sub)
    add_modes_parser(sub)
    add_thesis_table_parser(sub)
    return ap


def check_paths(args) -> None:
    """Refuse, before any work, an input path that does not exist, and an output — a file
    (``outputs``: ``--yaml``, ``--write-rig``) or a folder (``output_dirs``: ``--report``) — whose
    parent folder does not: one rule for every output, no folder is created but the output itself;
    a file output that is a folder, or a folder output that is a file, is refused too.
    :class:`UsageError` naming the path and the option."""
    for dest in getattr(args, "inputs", ()):
        value = getattr(args, dest, None)
        for p in ([] if value is None else [value] if isinstance(value, str) else value):
            if not os.path.exists(p):
                raise UsageError(f"{p}: no such file or directory ({dest.replace('_', '-')})")
    for dest, kind in [(d, "file") for d in getattr(args, "outputs", ())] + \
                      [(d, "folder") for d in getattr(args, "output_dirs", ())]:
        value = getattr(args, dest, None)
        if value is None:
            continue
        option = "--" + dest.replace("_", "-")
        folder = os.path.dirname(os.path.abspath(value))
        if not os.path.isdir(folder):
            raise UsageError(f"{value}: cannot write it: no folder {folder} ({option})")
        if kind == "file" and os.path.isdir(value):
            raise UsageError(f"{value}: is a folder ({option} takes a file)")
        if kind == "folder" and os.path.exists(value) and not os.path.isdir(value):
            raise UsageError(f"{value}: is not a folder ({option} takes a folder)")


def user_errors() -> tuple:
    """The exceptions that are the user's to fix: printed as one line, exit status 2."""
    from ..estimation.gyro_fit import IdentificationError
    from ..estimation.rig_record import RigFitError
    from ..estimation.tracker import TrackerError
    from ..io.recording import RecordingError
    from ..io.rig import RigError
    from ..io.vehicle import AxesError
    from ..report.folder import ReportError
    from ..statics import StaticsError
    return (UsageError, RecordingError, RigError, IdentificationError, TrackerError, StaticsError, RigFitError,
            AxesError, ReportError, FileNotFoundError)


def identify_main(argv: list[str] | None = None) -> int:
    """Entry point of ``rig-identify``: parse, check the paths, run the command with progress on
    stderr.  Returns the exit status (0, or 2 on a user error)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser(argv).parse_args(argv)
    with attached(quiet=args.quiet) as printer:
        try:
            check_paths(args)
            args.progress = printer
            return args.func(args)
        except UsageError as e:
            printer.fail()
            print(f"rig-identify: error: {e}", file=sys.stderr)
            return 2
        except Exception as e:  # noqa: BLE001 — sorted below: the user's errors become one line
            printer.fail()
            if isinstance(e, user_errors()):
                print(f"rig-identify: error: {e}", file=sys.stderr)
                return 2
            raise


def sim_main(argv: list[str] | None = None) -> int:
    """Entry point of ``rig-sim`` (implemented in :mod:`rig_identification.cli.sim`): its command
    line is checked first (:mod:`~rig_identification.cli.sim_args`), so that ``--help`` and usage
    errors answer without importing the simulator (scipy)."""
    from .sim_args import parse_sim_args
    parse_sim_args(argv)
    from .sim import sim_main as run
    return run(argv)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(identify_main())
