"""``rig-sim``: simulate an experiment file and write a recording folder (docs/recording_format.md).

    rig-sim CONFIG OUTDIR [--duration S] [--seed N] [--noise-free] [--storage mcap|sqlite3]
            [--static baseline|dummy [--dummy-mass KG --dummy-position X Y Z]] [--overwrite] [-q]
            [--inertia IXX IYY IZZ IXY IXZ IYZ [--force N] [--frequency HZ] [--ramp S]]

CONFIG is an experiment file (schema: :mod:`rig_identification.model.experiment`, docs/cli.md), e.g.
``config/cases/case16.yaml`` or ``config/rigs/default.yaml``, or a lab's rig.yaml with
``--inertia`` (:func:`~rig_identification.model.experiment.load_simulation`: a rotating force
at its exciter, the reference sensors).  OUTDIR receives ``rig.yaml``,
``bag/`` and ``truth.yaml``.  ``--static`` writes a static centre-of-gravity recording (body at
rest, no excitation; ``dummy`` adds the dummy mass to the suspended body; rig.yaml then has no
centre of gravity and carries ``dummy_mass`` when one is known).  Errors in the config or the
simulation: one message naming the file and field on stderr, exit status 2.  The command line
is :mod:`~rig_identification.cli.sim_args`'s (``rig-sim --help`` does not import the simulator).
"""
from __future__ import annotations

import sys

import numpy as np

from ..io.export import entries_from_option
from ..io.recording import RecordingError
from ..io.recording_writer import write_recording
from ..io.rig import DummyMass, RigError
from ..model.experiment import ExperimentError, RigRun, load_simulation
from ..model.rigid_body import SimulationError
from ..model.simulator import simulate
from .progress import attached, step
from .sim_args import parse_sim_args


def sim_main(argv: list[str] | None = None) -> int:
    """Entry point of ``rig-sim``.  Returns the exit status (0 ok, 2 bad input or failed simulation).
    Progress on stderr (``rig-sim: simulating … 12.3 s``; ``-q``: none)."""
    args = parse_sim_args(argv)
    dummy = None
    if args.dummy_mass is not None:
        dummy = DummyMass(float(args.dummy_mass), np.array(args.dummy_position, float))
    with attached(quiet=args.quiet, prog="rig-sim") as printer:
        try:
            given = {k: getattr(args, k) for k in ("force", "frequency", "ramp") if getattr(args, k) is not None}
            run = None if args.inertia is None else RigRun(tuple(entries_from_option(args.inertia)), **given)
            exp = load_simulation(args.config, run).with_overrides(duration=args.duration, seed=args.seed,
                                                             noise_free=args.noise_free, static=args.static,
                                                             dummy=dummy)
            kind = f"static {exp.static.kind}" if exp.static is not None else "dynamic"
            duration = exp.static.duration if exp.static is not None else exp.duration
            step(f"simulating {exp.name} ({kind}, {duration:g} s)")
            res = simulate(exp)
            step(f"writing {args.outdir}")
            write_recording(args.outdir, res.rig, res.sensors, res.truth, storage=args.storage,
                            rig_comment=f"rig description (rig_identification simulator, experiment {exp.name})",
                            overwrite=args.overwrite)
        except (ExperimentError, SimulationError, RecordingError, RigError) as e:
            printer.fail()
            print(f"rig-sim: error: {e}", file=sys.stderr)
            return 2
    s = res.sensors
    print(f"rig-sim: wrote {args.outdir}: {exp.name}, {kind}, {exp.cable_model.type} cables, {duration:g} s, "
          f"imu {len(s.imu)} samples, {len(s.load_cells)} load cells, simulated in {res.wall_time:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(sim_main())
