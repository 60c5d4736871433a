"""The gyro bias drift's intensity as diagnose reports it, against the walk the simulator drew.

    bench/bench_drift_intensity.py [--seeds 8900,8913,...] [--duration S] [--q Q] [--procs P] [--json F]

Per seed: a random 4-cable ``wide`` rig of the package's simulator
(``design.scenarios.simulate_random``) with a gyro bias random walk of intensity ``--q``
(default 1e-4 rad/s/√s), ``--duration`` s (default 60, test_diagnose_search's length), and the
same rig without it — the simulator draws the walk last, so the difference of the two gyro
streams *is* the realised walk.  :func:`~rig_identification.diagnosis.selection.diagnose` on
the first; where it names ``gyro_bias_drift`` (in its best admissible combination or another),
the table gives the realised walk's intensity read at the same knots, the reported intensity
± σ (``retracked.random_walk``) and the error in σ.  The summary: RMS of that ratio and how
many are within 2 σ.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scoring import run_jobs  # noqa: E402  (bench/, beside this script)

from rig_identification.design.scenarios import simulate_random  # noqa: E402
from rig_identification.diagnosis.retracked import knots  # noqa: E402
from rig_identification.diagnosis.selection import diagnose  # noqa: E402
from rig_identification.io.recording import Recording  # noqa: E402

DEFAULT_SEEDS = "8900,8913,8921,8922,8923,8925,8926"


def job(args: tuple) -> dict:
    seed, duration, q = args
    _, sim = simulate_random(seed, 4, "wide", [{"name": "gyro_bias_drift", "random_walk": q}], duration)
    _, sim0 = simulate_random(seed, 4, "wide", [], duration)
    t = sim.sensors.imu.t
    walk = sim.sensors.imu.data[:, :3] - sim0.sensors.imu.data[:, :3]
    d = diagnose(Recording(sim.rig, sim.sensors, sim.truth, None))
    row = {"seed": seed, "named": [[e["name"] for e in a.effects] for a in d.alternatives], "verdict": "done"}
    for alt in d.alternatives:
        e = next((x for x in alt.effects if x["name"] == "gyro_bias_drift"), None)
        if e is None:
            continue
        kt = np.asarray(alt.applied.get(("gyro_bias_drift", "knots"), knots(t[0], t[-1])))
        w = np.array([np.interp(kt, t, walk[:, a]) for a in range(3)])
        row.update(realised=float(np.sqrt(np.mean(np.diff(w, axis=1) ** 2) / np.mean(np.diff(kt)))),
                   reported=e["parameters"]["random_walk"], std=e["parameters_std"]["random_walk"])
        break
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default=DEFAULT_SEEDS, help=f"comma-separated (default {DEFAULT_SEEDS})")
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--q", type=float, default=1e-4, help="simulated intensity, rad/s/√s")
    ap.add_argument("--procs", type=int, default=1)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    seeds = [int(s) for s in a.seeds.split(",")]
    rows = run_jobs(job, [(s, a.duration, a.q) for s in seeds], a.procs, a.json, lambda r: f"seed {r['seed']}")
    print(f"{'seed':>6s} {'realised':>9s} {'reported':>9s} {'σ':>8s} {'(rep−real)/σ':>13s}  "
          "named (admissible combinations)")
    z = []
    for r in rows:
        names = "; ".join("+".join(n) for n in r["named"]) or "-"
        if "reported" not in r:
            print(f"{r['seed']:6d} {'':>9s} {'not found':>9s} {'':>8s} {'':>13s}  {names}")
            continue
        z.append((r["reported"] - r["realised"]) / r["std"])
        print(f"{r['seed']:6d} {r['realised']:9.3g} {r['reported']:9.3g} {r['std']:8.2g} {z[-1]:13.2f}  {names}")
    if z:
        z = np.array(z)
        print(f"drift found on {len(z)}/{len(rows)}; RMS (reported − realised)/σ {np.sqrt(np.mean(z ** 2)):.2f}, "
              f"within 2 σ {int(np.sum(np.abs(z) < 2))}/{len(z)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
