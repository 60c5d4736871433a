"""One body over two runs: random clean rigs, each run fitted alone and both at once, judged against the truth.

Usage: python bench/bench_joint.py [--seeds S ...] [--procs P] [--json FILE]

Each seed draws a rig as bench_any_rig does (:func:`~bench_any_rig.draw`,
:func:`~rig_identification.design.scenarios.random_experiment`: an NHTSA vehicle, 3–6 cables,
a layout, an exciter placement, 60–120 s at 200 Hz, reference noise).  Run A is that
experiment; run B the same rig, body and IMU with the exciter where another placement kind puts
it (its position, spin axis, force and frequency: ``random_experiment`` of the same seed with
the next kind of :data:`~bench_any_rig.EXCITERS`), its own noise; each run's force lowered
where a cable would go slack (:func:`~rig_identification.design.scenarios.simulate_taut`).  Both recordings share one
rig.yaml surveyed once with concealed errors of the survey's σ (:func:`~scoring.surveyed`; the
CG by rig.yaml's assumed σ), as a lab's one rig is.  ``rig-identify inertia A B``'s core
(:func:`~rig_identification.pipeline.joint.fit_recordings`) fits each alone and both at once.

Printed per seed: each run alone (verdict, worst σ % of scale: a product's of the largest
moment), the joint fit (verdict, worst error % of scale, worst |error|/σ, worst σ/CRB, the CRB
the joint fit's at its estimate), the
wall time; then the counts: joint ``ok`` fits within 1 % and 3 σ, joint fits that determine
what neither run determined alone, silent failures (``ok`` and beyond 3 σ): 0.
"""
from __future__ import annotations

import argparse
import copy
import json
import sys
import time
import warnings

import numpy as np
from bench_any_rig import EXCITERS, draw
from scoring import entry_scales, run_jobs, surveyed

from rig_identification.design.scenarios import random_experiment, simulate_taut
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.pipeline.joint import fit_recordings
from rig_identification.pipeline.rig_model import RIG_YAML_CG_STD

#: The default seeds: bench_any_rig's first eight (``--rigs 8 --first-seed 21000``).
SEEDS = tuple(range(21000, 21008))


def runs(seed: int) -> tuple[dict, dict]:
    """The experiments of runs A and B (module docstring)."""
    kind = draw(seed)
    a = random_experiment(seed, kind["cables"], kind["layout"], duration=kind["duration"], exciter=kind["exciter"])
    other = EXCITERS[(EXCITERS.index(kind["exciter"]) + 1) % len(EXCITERS)]
    placed = random_experiment(seed, kind["cables"], kind["layout"], duration=kind["duration"], exciter=other)
    b = copy.deepcopy(a)
    b["rig"]["exciter"] = copy.deepcopy(placed["rig"]["exciter"])
    b["excitation"] = copy.deepcopy(placed["excitation"])
    b.update(name=a["name"] + "_b", seed=int(seed) + 100000)
    return a, b


def job(seed: int) -> dict:
    warnings.simplefilter("ignore")
    kind = draw(seed)
    row: dict = {"seed": seed} | kind
    try:
        sims = [simulate_taut(d)[1] for d in runs(seed)]
    except Exception as e:                      # noqa: BLE001 — a rig the simulator cannot make is skipped
        return row | {"skipped": f"{type(e).__name__}: {e}"}
    recs = []
    for sim in sims:                            # one rig.yaml: the same concealed survey errors for both runs
        rig = surveyed(sim.rig, np.random.default_rng([seed, 33]), cg_std=RIG_YAML_CG_STD)
        recs.append(Recording(rig, sim.sensors, sim.truth, None))
    t0 = time.perf_counter()
    try:
        res = fit_recordings(recs)
    except ValueError as e:                     # RigFitError, RigError: refused, with its message
        return row | {"verdict": "refused", "error": str(e)}
    truth = np.array([sims[0].truth["inertia_about_cg"][k] for k in KEYS])
    scale = entry_scales(truth)
    f = res.first.fit
    err = f.inertia - truth
    row.update(verdict=res.verdict, alone=[a.verdict for a in res.alone], truth=list(truth), estimate=list(f.inertia),
               alone_std_percent=[list(100 * a.fit.inertia_std / scale) for a in res.alone],
               error_percent=list(100 * err / scale), error_sigma=list(err / f.inertia_std),
               std_percent=list(100 * f.inertia_std / scale), sigma_over_crb=list(f.inertia_std / f.crb),
               seconds=time.perf_counter() - t0)
    return json.loads(json.dumps(row, default=float))


def summary(rows: list[dict]) -> None:
    print(f"{'seed':>6} {'rig':<28} {'alone A':<17} {'alone B':<17} {'joint':<17} {'err %':>6} {'|e|/σ':>6} "
          f"{'σ/CRB':>6} {'s':>5}")
    ok = good = completed = silent = 0
    for r in rows:
        rig = f"{r['cables']} {r['layout']} {r['exciter']} {r['duration']:.0f}s"
        if "verdict" not in r or r["verdict"] == "refused":
            print(f"{r['seed']:>6} {rig:<28} {r.get('skipped') or r.get('error')}")
            continue
        alone = [f"{v} {max(s):.2g}%" for v, s in zip(r["alone"], r["alone_std_percent"])]
        e, z, q = (np.max(np.abs(r[k])) for k in ("error_percent", "error_sigma", "sigma_over_crb"))
        print(f"{r['seed']:>6} {rig:<28} {alone[0]:<17} {alone[1]:<17} {r['verdict']:<17} {e:>6.3f} {z:>6.2f} "
              f"{q:>6.2f} {r['seconds']:>5.0f}")
        if r["verdict"] == "ok":
            ok += 1
            good += int(e <= 1.0 and z <= 3.0)
            silent += int(z > 3.0)
            completed += int(all(v != "ok" for v in r["alone"]))
    print(f"joint ok: {ok} of {len(rows)}; within 1 % and 3 σ: {good} of {ok}; determined where neither run was "
          f"alone: {completed}; silent failures (ok beyond 3 σ): {silent}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=list(SEEDS))
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    rows = run_jobs(job, a.seeds, a.procs, a.json, lambda r: str(r["seed"]))
    summary(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
