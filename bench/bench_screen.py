"""How well the design's fast screen ranks runs: the linearised rig's σ against the exact model's bound.

Random candidate runs on the thesis rig (config/rigs/default.yaml, the Jeep Cherokee of case 16):
frequency log-uniform in 0.35–3.8 Hz, a corner of :func:`~rig_identification.design.planning.candidate_positions`,
a spin axis of :data:`~rig_identification.design.run.SPIN_AXES`, the force at the plan's limits (the screen's:
3°, 20 % of static tension, 200 N).  Per run: the screen's σ of each entry
(:class:`~rig_identification.design.screen.RigScreen`) and the rig model's Cramér–Rao bound along a noise-free
simulation of the run by the rig model's integrator (:func:`~rig_identification.design.information.simulate_run`,
:func:`~rig_identification.design.information.run_information`), 30 s each; then the
rank correlation (Spearman) of the two over the runs, per entry and for the worst relative entry
(what the plan ranks by).

Usage: python bench/bench_screen.py [--runs 16] [--seed 1] [--procs 2] [--duration 30]
"""
from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from rig_identification.design.information import body_prior, run_information, simulate_run, tensor_std
from rig_identification.design.planning import candidate_positions
from rig_identification.design.run import SPIN_AXES, Run, load_plan_input, make_body
from rig_identification.design.screen import RigScreen
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import entry_scales, from_tensor

RIG = Path(__file__).resolve().parents[1] / "config" / "rigs" / "default.yaml"
INERTIA = [2894.0, 0.0, 0.0, 695.0, -102.0, 3101.0]     # KEYS order
LIMITS = {"max_force_n": 200.0, "max_rotation_deg": 3.0, "min_tension_ratio": 0.2}


def body():
    rig, _, k = load_plan_input(str(RIG))
    return make_body(rig, None, INERTIA, k)


def one(args):
    """(screen σ (6,), exact bound σ (6,), the run) of one random candidate."""
    seed, n, duration = args
    b = body()
    rng = np.random.default_rng([seed, n])
    f = float(np.exp(rng.uniform(np.log(0.35), np.log(3.8))))
    pts = candidate_positions(b.rig)
    pos = tuple(float(x) for x in pts[rng.integers(len(pts))])
    axis = list(SPIN_AXES)[rng.integers(len(SPIN_AXES))]
    prior = body_prior(b.rig)
    c = RigScreen(b, duration, 5.0).at(f).candidate(pos, SPIN_AXES[axis], LIMITS)
    sim = simulate_run(b, Run(f, c.amplitude, pos, axis, duration=duration))
    return (tensor_std([c.information], prior), tensor_std([run_information(sim)], prior),
            (f, c.amplitude, pos, axis))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--duration", type=float, default=30.0)
    a = ap.parse_args(argv)
    with ProcessPoolExecutor(a.procs) as ex:
        rows = list(ex.map(one, [(a.seed, n, a.duration) for n in range(a.runs)]))
    scale = entry_scales(np.array(INERTIA))
    assert np.allclose(scale, entry_scales(from_tensor(body().inertia)))
    print(f"{a.runs} random runs on {RIG.name}, {a.duration:.0f} s each: σ kg·m², screen / exact bound")
    print(f"{'Hz':>5s} {'N':>5s} {'axis':4s} " + " ".join(f"{k:>15s}" for k in KEYS))
    for s, e, (f, amp, _, axis) in rows:
        print(f"{f:5.2f} {amp:5.0f} {axis:4s} " + " ".join(f"{x:7.3g}/{y:<7.3g}" for x, y in zip(s, e)))
    S, E = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
    ratio = S / E
    print("screen/exact per entry: median " + ", ".join(f"{k} {v:.2f}" for k, v in zip(KEYS, np.median(ratio, 0)))
          + "; range " + f"{ratio.min():.2f}–{ratio.max():.2f}")
    print("rank correlation (Spearman) screen vs exact: " + ", ".join(
        f"{k} {spearmanr(S[:, i], E[:, i])[0]:.2f}" for i, k in enumerate(KEYS))
        + f"; worst relative entry {spearmanr(np.max(S / scale, 1), np.max(E / scale, 1))[0]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
