"""Thesis case studies 10–17, noise-free, at their full length: our pipeline vs the thesis.

Prints, per case and tensor entry, the thesis's reported error (from its chapter 4,
stored under `thesis.reported_error_percent` in config/cases/) beside ours (% of the entry
for diagonals, % of the largest diagonal for products), and the wall time.
Usage: bench_thesis_cases.py [case10 case16 ...]
"""
import sys
import time
from pathlib import Path

from rig_identification.estimation.inertia_result import compare_to_truth
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import load_experiment
from rig_identification.model.parametrisation import PAIRS
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import identify_recording

CASES = Path(__file__).resolve().parents[1] / "config" / "cases"


def main(names):
    print(f"{'case':7s} {'entry':5s} {'thesis %':>9s} {'ours %':>9s}   sim s  fit s")
    worst = 0.0
    for name in names:
        exp = load_experiment(CASES / f"{name}.yaml")
        t0 = time.perf_counter()
        sim = simulate(exp)
        t1 = time.perf_counter()
        res = identify_recording(Recording(sim.rig, sim.sensors, sim.truth))
        t2 = time.perf_counter()
        cmp = compare_to_truth(res, sim.truth)
        rep = (exp.thesis or {}).get("reported_error_percent")
        for n, (k, (i, j)) in enumerate(zip(KEYS, PAIRS)):
            th = f"{rep[i][j]:9.2f}" if rep is not None else f"{'-':>9s}"
            ours = cmp[k]["error_percent"]
            worst = max(worst, abs(ours))
            tail = f"  {t1 - t0:6.1f} {t2 - t1:6.1f}" if n == 0 else ""
            print(f"{name:7s} {k:5s} {th} {ours:+9.4f}{tail}")
    print(f"largest error of ours: {worst:.4f} %")


if __name__ == "__main__":
    main(sys.argv[1:] or [f"case{i}" for i in range(10, 18)])
