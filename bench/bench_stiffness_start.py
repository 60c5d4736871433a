"""Where the rig model's cable stiffness starts when rig.yaml gives none, on random rigs of the
package's simulator: steel cables (the default's own) and soft ones (the ``cable_elasticity``
effect).

For each rig (seed, 3–6 cables in turn, ``random`` layout) and each stiffness it simulates 30 s,
runs :func:`~rig_identification.estimation.harmonic_start.forced_response_start` from the starts the
pipeline gives it (the body anchors' box at its three scales; the CG at its truth, σ 5 mm) and
prints whether the start moved, its ratio to the true stiffness, the misfit there and at the
default's, and the seconds it took.  A steel rig whose start moved, or a soft rig whose start is
not within 25 % of the truth, is marked ``WRONG``.

    python bench/bench_forced_response_start.py --rigs 8 --first-seed 1 --soft 5e5 1.5e5
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from rig_identification.design.scenarios import simulate_random
from rig_identification.estimation.harmonic_start import box_tensor, forced_response_start
from rig_identification.estimation.rig_record import record
from rig_identification.estimation.rig_unknowns import Prior
from rig_identification.model.rigid_body import SimulationError
from rig_identification.pipeline.rig_model import BOX_SCALES


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", type=int, default=8)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--soft", type=float, nargs="*", default=[5.0e5, 1.5e5], help="soft stiffnesses, N/m")
    ap.add_argument("--duration", type=float, default=30.0)
    a = ap.parse_args(argv)
    print("| seed | cables | cable N/m | moved | start/truth | misfit there | at default | s | |")
    print("|---|---|---|---|---|---|---|---|---|")
    wrong, seconds = 0, []
    for seed in range(a.first_seed, a.first_seed + a.rigs):
        cables = 3 + (seed - a.first_seed) % 4
        for k in [None, *a.soft]:
            effects = [] if k is None else [{"name": "cable_elasticity", "stiffness": k}]
            try:
                _, sim = simulate_random(seed, cables, "random", effects, a.duration)
            except SimulationError as e:
                print(f"| {seed} | {cables} | {k or 'steel'} | not simulated: {e} |")
                continue
            rc = record(sim.sensors, sim.rig)
            prior = Prior.from_rig(sim.rig, np.asarray(sim.truth["center_of_gravity"]), np.full(3, 5e-3))
            box = box_tensor(sim.rig)
            t = time.perf_counter()
            s = forced_response_start(rc, sim.rig, prior, np.vstack([f * box for f in BOX_SCALES]))
            seconds.append(time.perf_counter() - t)
            truth = np.asarray(sim.truth["simulator"]["cable_stiffness"], float)
            ratio = s.stiffness / truth
            bad = s.moved if k is None else not np.all(np.abs(ratio - 1) < 0.25)
            wrong += bad
            print(f"| {seed} | {cables} | {'steel' if k is None else f'{k:.3g}'} | {'yes' if s.moved else 'no'} | "
                  f"{np.median(ratio):.3f} | {s.level:.3g} | {s.prior_level:.3g} | {seconds[-1]:.1f} | "
                  f"{'WRONG' if bad else ''} |")
    print(f"\nwrong starts {wrong}; seconds a scan: median {np.median(seconds):.1f}, max {np.max(seconds):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
