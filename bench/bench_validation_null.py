"""Calibration of the model-validation checks on clean recordings (no effect concealed).

Usage: python bench/bench_validation_null.py [--seeds N] [--procs P] [--durations 30,60,120]
                                              [--layouts 4splayed,3splayed,...] [--json FILE]

On clean random rigs of the package's own simulator (:mod:`rig_identification.design.scenarios`)
every check of :func:`rig_identification.estimation.validation.validate` should pass about as often as
its false-alarm rate says: this prints, per check, the fraction of clean recordings on
which it failed, the median and largest statistic over its threshold, and per recording the
verdict and the largest |error|/σ — the null distribution the thresholds are set against.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _job(args):
    seed, cables, layout, duration = args
    import warnings
    warnings.simplefilter("ignore")
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.parametrisation import from_tensor
    from rig_identification.pipeline.offline import identify_recording
    from rig_identification.io.recording import Recording
    from rig_identification.design.scenarios import simulate_random
    t0 = time.perf_counter()
    row = {"seed": seed, "cables": cables, "layout": layout, "duration": duration}
    try:
        d, sim = simulate_random(seed, cables, layout, [], duration)
    except Exception as e:  # noqa: BLE001 — a rig the simulator cannot make is skipped
        row["skipped"] = f"{type(e).__name__}: {e}"
        return row
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    try:
        res = identify_recording(rec)
    except ValueError as e:
        row["refused"] = str(e)
        return row
    tru = sim.truth["inertia_about_cg"]
    big = max(tru["ixx"], tru["iyy"], tru["izz"])
    z, pct = [], []
    for k, v, s in zip(KEYS, from_tensor(res.inertia), res.inertia_std):
        if k in res.undetermined:
            continue
        ref = abs(tru[k]) if k in ("ixx", "iyy", "izz") else big
        z.append(float(abs(v - tru[k]) / s) if s > 0 else float("inf"))
        pct.append(float(100 * abs(v - tru[k]) / ref))
    v = res.validation
    row.update(verdict=v.verdict, undetermined=list(v.undetermined),
               checks={c.name: [c.statistic, c.threshold, c.passed] for c in v.checks},
               max_z=max(z) if z else None, max_pct=max(pct) if pct else None, seconds=time.perf_counter() - t0)
    return json.loads(json.dumps(row, default=lambda x: None if x is None else float(x)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--durations", default="30,60,120")
    ap.add_argument("--layouts", default="4splayed,3splayed,5mixed,6splayed")
    ap.add_argument("--json", metavar="FILE")
    a = ap.parse_args(argv)
    lays = [(int(x[0]), x[1:]) for x in a.layouts.split(",")]
    durs = [float(x) for x in a.durations.split(",")]
    jobs = [(a.first_seed + 1000 * i + k, c, lay, dur) for i, (c, lay) in enumerate(lays) for dur in durs
            for k in range(a.seeds)]
    with ProcessPoolExecutor(a.procs) as ex:
        rows = list(ex.map(_job, jobs))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    done = [r for r in rows if "checks" in r]
    print(f"{'seed':>6s} {'rig':10s} {'s':>4s} {'verdict':17s} {'max|e|/σ':>8s} {'max e%':>7s}  failed")
    for r in rows:
        rig = f"{r['cables']}{r['layout']}"
        if "checks" not in r:
            print(f"{r['seed']:6d} {rig:10s} {r['duration']:4.0f} {r.get('skipped') or r.get('refused')}"[:150])
            continue
        failed = [k for k, (s, t, p) in r["checks"].items() if p is False]
        mz = "-" if r["max_z"] is None else f"{r['max_z']:.2f}"
        mp = "-" if r["max_pct"] is None else f"{r['max_pct']:.2f}"
        print(f"{r['seed']:6d} {rig:10s} {r['duration']:4.0f} {r['verdict']:17s} {mz:>8s} {mp:>7s}  "
              f"{','.join(failed)} {','.join(r['undetermined'])}")
    names = sorted({k for r in done for k in r["checks"]})
    print(f"\n{'check':18s} {'failed':>8s} {'median stat/thr':>15s} {'max stat/thr':>12s}")
    for n in names:
        v = [r["checks"][n] for r in done if n in r["checks"] and r["checks"][n][0] is not None
             and r["checks"][n][1]]
        if not v:
            continue
        ratio = np.array([s / t for s, t, _ in v])
        fails = sum(p is False for _, _, p in v)
        print(f"{n:18s} {fails:3d}/{len(v):<4d} {np.median(ratio):15.2f} {np.max(ratio):12.2f}")
    ok = [r for r in done if r["verdict"] == "ok"]
    print(f"\nverdict ok: {len(ok)}/{len(done)}; of them beyond 3 σ: {sum((r['max_z'] or 0) > 3 for r in ok)}; "
          f"beyond 1 %: {sum((r['max_pct'] or 0) > 1 for r in ok)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
