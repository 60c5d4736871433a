"""``rig-sim``: simulate an experiment file and write a recording folder (docs/recording_format.md).

    rig-sim CONFIG OUTDIR [--duration S] [--seed N] [--noise-free] [--storage mcap|sqlite3]
            [--static baseline|dummy [--dummy-mass KG --dummy-position X Y Z]] [--overwrite]

CONFIG is an experiment file (schema: :mod:`rig_identification.model.simulator`), e.g.
``config/cases/case16.yaml`` or ``config/rigs/default.yaml``.  OUTDIR receives ``rig.yaml``,
``bag/`` and ``truth.yaml``.  ``--static`` writes a static centre-of-gravity recording (body at
rest, no excitation; ``dummy`` adds the dummy mass to the suspended body; rig.yaml then has no
centre of gravity and carries ``dummy_mass`` when one is known).  Errors in the config or the
simulation: one message naming the file and field on stderr, exit status 2.
"""
from __future__ import annotations

import argparse
import math
import sys
from ..io.recording import RecordingError
from ..io.recording_writer import write_recording
from ..io.rig import DummyMass, RigError
from ..model.experiment import ExperimentError, load_experiment
from ..model.dynamics import SimulationError
from ..model.simulator import simulate


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rig-sim", description="Simulate a rig experiment and write a recording "
                                "folder (rig.yaml, bag/, truth.yaml).")
    p.add_argument("config", help="experiment file (YAML), e.g. config/cases/case16.yaml")
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
    p.add_argument("--overwrite", action="store_true", help="replace OUTDIR if it exists")
    return p


def sim_main(argv: list[str] | None = None) -> int:
    """Entry point of ``rig-sim``.  Returns the exit status (0 ok, 2 bad input or failed simulation)."""
    parser = _parser()
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
    # the simulator (scipy) only once the command line is known good: rig-sim --help stays quick
    import numpy as np

    dummy = None
    if args.dummy_mass is not None:
        dummy = DummyMass(float(args.dummy_mass), np.array(args.dummy_position, float))
    try:
        exp = load_experiment(args.config).with_overrides(duration=args.duration, seed=args.seed,
                                                         noise_free=args.noise_free, static=args.static,
                                                         dummy=dummy)
        res = simulate(exp)
        write_recording(args.outdir, res.rig, res.sensors, res.truth, storage=args.storage,
                        rig_comment=f"rig description (rig_identification simulator, experiment {exp.name})",
                        overwrite=args.overwrite)
    except (ExperimentError, SimulationError, RecordingError, RigError) as e:
        print(f"rig-sim: error: {e}", file=sys.stderr)
        return 2
    kind = f"static {exp.static.kind}" if exp.static is not None else "dynamic"
    duration = exp.static.duration if exp.static is not None else exp.duration
    s = res.sensors
    print(f"rig-sim: wrote {args.outdir}: {exp.name}, {kind}, {exp.cable_model.type} cables, {duration:g} s, "
          f"imu {len(s.imu)} samples, {len(s.load_cells)} load cells, simulated in {res.wall_time:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(sim_main())
