"""The command line of ``rig-sim`` (argparse only, no scipy): ``rig-sim --help`` and usage
errors answer before the simulator is imported (:func:`~rig_identification.cli.main.sim_main`)."""
from __future__ import annotations

import argparse
import math

from ..io.verdict import PACKAGE, package_version


def sim_parser() -> argparse.ArgumentParser:
    """The ``rig-sim`` parser."""
    p = argparse.ArgumentParser(prog="rig-sim", description="Simulate a rig experiment and write a recording "
                                "folder (rig.yaml, bag/, truth.yaml).")
    p.add_argument("--version", action="version", version=f"rig-sim ({PACKAGE}) {package_version()}")
    p.add_argument("config", help="experiment file (YAML), e.g. config/cases/case16.yaml, or a rig.yaml "
                   "with --inertia")
    p.add_argument("outdir", help="recording folder to create")
    p.add_argument("--duration", type=float, metavar="S", help="override the experiment duration, s")
    p.add_argument("--seed", type=int, metavar="N", help="override the sensor-noise seed")
    p.add_argument("--noise-free", action="store_true", help="no sensor noise (biases are kept)")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="rosbag2 storage (default mcap)")
    p.add_argument("--static", choices=("baseline", "dummy"),
                   help="static CG recording at rest: without (baseline) or with the dummy mass")
    p.add_argument("--dummy-mass", type=float, metavar="KG", help="dummy mass, kg (default: rig.dummy_mass)")
    p.add_argument("--dummy-position", type=float, nargs=3, metavar=("X", "Y", "Z"),
                   help="dummy mass position, body frame, m (default: rig.dummy_mass)")
    p.add_argument("--inertia", type=float, nargs=6, metavar=("IXX", "IYY", "IZZ", "IXY", "IXZ", "IYZ"),
                   help="with a rig.yaml: the body's inertia tensor entries about its CG, body axes, kg m^2, in the "
                   "order ixx iyy izz ixy ixz iyz (moments, then products: the order of every option); ixy, ixz, "
                   "iyz as in truth.yaml, the negated products of inertia")
    p.add_argument("--force", type=float, metavar="N", help="with a rig.yaml: the rotating force's amplitude, N "
                   "(default 200)")
    p.add_argument("--frequency", type=float, metavar="HZ", help="with a rig.yaml: its frequency, Hz (default 1.05)")
    p.add_argument("--ramp", type=float, metavar="S", help="with a rig.yaml: its spin-up, s (default 2)")
    p.add_argument("--overwrite", action="store_true", help="replace OUTDIR if it exists")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines on stderr (warnings still)")
    return p


def parse_sim_args(argv: list[str] | None) -> argparse.Namespace:
    """Parse and check ``rig-sim``'s arguments; a usage error exits with status 2 (argparse)."""
    parser = sim_parser()
    args = parser.parse_args(argv)
    if (args.dummy_mass is None) != (args.dummy_position is None):
        parser.error("--dummy-mass and --dummy-position go together")
    if args.dummy_mass is not None and args.static is None:
        parser.error("--dummy-mass/--dummy-position need --static baseline|dummy")
    if args.dummy_mass is not None and not (math.isfinite(args.dummy_mass) and args.dummy_mass > 0):
        parser.error(f"--dummy-mass must be > 0, got {args.dummy_mass}")
    if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
        parser.error(f"--duration must be > 0, got {args.duration}")
    if args.seed is not None and args.seed < 0:
        parser.error(f"--seed must be >= 0, got {args.seed}")
    given = [f"--{k}" for k in ("force", "frequency", "ramp") if getattr(args, k) is not None]
    if given and args.inertia is None:
        parser.error(f"{', '.join(given)} need --inertia (a rig.yaml to simulate)")
    for k in ("force", "frequency"):
        v = getattr(args, k)
        if v is not None and not (math.isfinite(v) and v > 0):
            parser.error(f"--{k} must be > 0, got {v}")
    if args.ramp is not None and not (math.isfinite(args.ramp) and args.ramp >= 0):
        parser.error(f"--ramp must be >= 0, got {args.ramp}")
    if args.inertia is not None and not all(math.isfinite(v) for v in args.inertia):
        parser.error(f"--inertia must be finite numbers, got {args.inertia}")
    return args
