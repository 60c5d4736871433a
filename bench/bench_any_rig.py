"""Any legitimate rig: random clean rigs of every geometry, identified by the rig model, judged against the truth.

Usage: python bench/bench_any_rig.py [--rigs N] [--first-seed S] [--procs P] [--json FILE] [--exact-survey]
       python bench/bench_any_rig.py --pool FILE [FILE ...]   (the counts of several sweeps' --json together)

Draws N random rigs (default 32) with the package's own simulator
(:mod:`rig_identification.design.scenarios`): an NHTSA vehicle in a carrying frame (the body
frame off the CG), 3 to 6 cables, a layout from near-parallel to wide (``wide``, ``splayed``,
``parallel``, ``mixed`` and ``random``: ceiling anchors at different heights in the last two),
the exciter at a bottom corner, a top corner spinning about body x, a random point spinning
about a random body axis, or a random point with a random spin axis; 60–120 s at 200 Hz,
reference noise, no effect.  Unless ``--exact-survey``, rig.yaml's geometry, mass and CG and the
load cells' gains are off by concealed errors of the survey's σ.  Each recording goes through
``rig-identify inertia``'s core (:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`).

What the geometry and the run determine is decided from the truth, independently of the fit:
the Cramér–Rao bound of the noise-free run under the fit's nuisance model (bench_crb's
:func:`~bench_crb.bound`).  A rig is *determined* when every entry's bound is within ±1 % at 95 %.

Printed per rig: the geometry, the worst bound, the verdict, the largest error % (products: of
the largest moment) and |error|/σ over the entries it gives, σ over the bound, the undetermined
and ambiguous entries and the channels that do not fit; then the acceptance counts:

* determined rigs: verdict ``ok`` with every entry within 1 % and 3 σ;
* σ within 2× of the bound on ≥ 90 % of the entries of the ``ok`` fits; coverage of ±1.96 σ
  93–97 % and the RMS of error/σ (1 when calibrated);
* silent failures (``ok`` and beyond 3 σ, or a non-finite number): 0;
* wrong names: a clean rig on which the diagnosis names an extension (the JSON's ``named``): 0;
* the rigs the package determines to ±1 % at 95 % (verdict ok, all six, 1.96 σ ≤ 1 %).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import replace

import numpy as np
from bench_crb import QUIET, bound, channel_noise, truth_parameters
from scoring import (
    entry_scales,
    load_cell_errors,
    print_unscored,
    run_jobs,
    surveyed,
)

from rig_identification.design.scenarios import simulate_random
from rig_identification.estimation.rig_record import record
from rig_identification.io.recording import Recording
from rig_identification.io.rig import Survey
from rig_identification.io.verdict import KEYS
from rig_identification.pipeline.rig_model import RIG_YAML_CG_STD, fit_whole_recording

CABLES = (3, 4, 5, 6)
LAYOUTS = ("wide", "wide", "random", "random", "mixed", "splayed", "parallel")   # determined rigs weigh double
EXCITERS = ("corner", "top_corner", "anywhere", "random")


def draw(seed: int) -> dict:
    """The rig's kind for ``seed``: cables, layout, exciter placement, duration s."""
    rng = np.random.default_rng([seed, 21])
    return {"cables": int(rng.choice(CABLES)), "layout": str(rng.choice(LAYOUTS)),
            "exciter": str(rng.choice(EXCITERS)), "duration": float(rng.choice([60.0, 90.0, 120.0]))}


def claims_one_percent(verdict: str, std, scale) -> bool:
    """The fit says every entry is within ±1 % at 95 %: verdict ok, all six given, 1.96 σ ≤ 1 % of scale."""
    return verdict == "ok" and bool(np.all(1.96 * np.asarray(std) <= 0.01 * np.asarray(scale)))


def job_rig(args: tuple[int, bool]) -> dict:
    """One rig: the bound from the noise-free run (bench_crb's nuisance model) and the rig model on
    the noisy recording, judged against the truth.  Unless
    ``exact`` (the second of ``args``), the recording is the lab's: rig.yaml's geometry, mass and
    CG and the load cells' gains off by concealed errors of the survey's σ
    (:func:`~scoring.surveyed`, :func:`~scoring.load_cell_errors`; the CG by rig.yaml's assumed
    :data:`~rig_identification.pipeline.rig_model.RIG_YAML_CG_STD`)."""
    seed, exact = args
    warnings.simplefilter("ignore")
    kind = draw(seed)
    row = {"seed": seed, "model": "rig", "survey": "exact" if exact else "concealed errors"} | kind
    t0 = time.process_time()
    rng = np.random.default_rng([seed, 33])
    args = (seed, kind["cables"], kind["layout"], [], kind["duration"])
    gains = [] if exact else load_cell_errors(kind["cables"], Survey().load_cell_gain, rng)
    try:
        d, sim = simulate_random(seed, kind["cables"], kind["layout"], gains, kind["duration"],
                                 exciter=kind["exciter"])
        _, quiet = simulate_random(*args, noise=QUIET, exciter=kind["exciter"])
    except Exception as e:                      # noqa: BLE001 — a rig the simulator cannot make is skipped
        return row | {"skipped": f"{type(e).__name__}: {e}"}
    row["description"] = d["description"]
    J, _ = truth_parameters(quiet.rig, quiet.truth)
    scale = entry_scales(J)
    rc = record(quiet.sensors, quiet.rig)
    crb = bound(replace(rc, sigma=channel_noise(rc.channels)), quiet.rig, quiet.truth)
    row["crb_percent"] = list(100 * crb / scale)
    row["kind_truth"] = "determined" if 1.96 * np.max(crb / scale) <= 0.01 else "undetermined"
    rig = sim.rig if exact else surveyed(sim.rig, rng, cg_std=RIG_YAML_CG_STD)
    rec = Recording(rig, sim.sensors, sim.truth, None)
    t1 = time.process_time()
    try:
        res = fit_whole_recording(rec)
    except ValueError as e:                     # RigFitError, RigError: refused, with its message
        return row | {"verdict": "refused", "error": str(e), "cpu_s": time.process_time() - t0}
    f = res.fit
    err = f.inertia - J
    row.update(verdict=res.verdict, named=list(res.diagnosis.named if res.diagnosis is not None else ()),
               undetermined=res.undetermined, ambiguous=res.ambiguous,
               poorly_fitted=res.poorly_fitted, errors=list(err), std=list(f.inertia_std),
               error_percent=list(100 * err / scale), error_sigma=list(err / f.inertia_std),
               sigma_over_crb=list(f.inertia_std / crb), finite=bool(np.all(np.isfinite(f.inertia_std))),
               claims=claims_one_percent(res.verdict, f.inertia_std, scale),
               rig_cpu_s=time.process_time() - t1, cpu_s=time.process_time() - t0)
    return json.loads(json.dumps(row, default=float))


def summary_rig(rows: list[dict], t0: float, procs: int) -> None:
    """The per-rig table and the acceptance counts."""
    surveys = sorted({r.get("survey", "exact") for r in rows})
    print(f"rig.yaml and load cells: {' and '.join(surveys)} (of the survey's σ: anchors and lengths 1 mm, mass and "
          f"gains 0.1 %, CG {1e3 * RIG_YAML_CG_STD:g} mm)")
    print(f"{'seed':>6s} {'rig':27s} {'CRB %':>6s} {'truth':12s} {'verdict':16s} {'max e%':>7s} "
          f"{'max|e|/σ':>8s} {'σ/CRB':>9s} {'cpu s':>5s}  undetermined | ambiguous | misfit")
    for r in rows:
        if print_unscored(r, f"{r['seed']:6d} {short(r):27s}", 0):
            continue
        given = [] if r["verdict"] == "failed" else [i for i, k in enumerate(KEYS) if k not in r["undetermined"]]
        ep = max((abs(r["error_percent"][i]) for i in given), default=None)
        es = max((abs(r["error_sigma"][i]) for i in given), default=None)
        soc = r["sigma_over_crb"] if given else [np.nan]
        print(f"{r['seed']:6d} {short(r):27s} {max(r['crb_percent']):6.3f} {r['kind_truth']:12s} "
              f"{r['verdict']:16s} {'-' if ep is None else f'{ep:.3f}':>7s} "
              f"{'-' if es is None else f'{es:.2f}':>8s} {min(soc):4.2f}–{max(soc):4.2f} {r['rig_cpu_s']:5.0f}  "
              f"{','.join(r['undetermined']) or '-'} | {','.join(r.get('ambiguous', [])) or '-'} | "
              f"{','.join(r['poorly_fitted']) or '-'}")
    done = [r for r in rows if "skipped" not in r and r.get("verdict") != "refused"]
    det = [r for r in done if r["kind_truth"] == "determined"]
    ok = [r for r in done if r["verdict"] == "ok"]
    print(f"\nrigs: {len(rows)}; skipped {sum('skipped' in r for r in rows)}, refused "
          f"{sum(r.get('verdict') == 'refused' for r in rows)}; the bound determines {len(det)} to ±1 % at 95 %")

    def good(r):
        return (r["verdict"] == "ok" and r["finite"] and max(map(abs, r["error_percent"])) <= 1.0
                and max(map(abs, r["error_sigma"])) <= 3.0)
    if det:
        print(f"determined rigs ok with every entry within 1 % and 3 σ: {sum(map(good, det))}/{len(det)} "
              "[goal all]" + "".join(f"\n  seed {r['seed']} {short(r)}: {r['verdict']} "
                                     f"{','.join(r['undetermined'] + r.get('ambiguous', []) + r['poorly_fitted'])}"
                                     for r in det if not good(r)))
    print(f"rigs the package determines to ±1 % at 95 % (ok, all six, 1.96 σ ≤ 1 %): "
          f"{sum(r['claims'] for r in done)}/{len(done)}")
    if ok:
        z = np.concatenate([r["error_sigma"] for r in ok])
        soc = np.concatenate([r["sigma_over_crb"] for r in ok])
        print(f"over the {len(ok)} ok fits: σ within 2× of the bound on {np.mean(soc <= 2):.1%} of {len(soc)} entries "
              f"[goal ≥ 90 %]; coverage of ±1.96 σ {np.mean(np.abs(z) <= 1.96):.1%} [goal 93–97 %]; "
              f"RMS error/σ {np.sqrt(np.mean(z ** 2)):.2f}")
    silent = [r for r in done if r["verdict"] == "ok" and (not r["finite"] or max(map(abs, r["error_sigma"])) > 3)]
    print(f"silent failures (ok and an entry beyond 3 σ, or non-finite): {len(silent)} [goal 0]"
          + "".join(f"\n  seed {r['seed']}: {max(map(abs, r['error_sigma'])):.1f} σ" for r in silent))
    recorded = [r for r in done if "named" in r]           # rows of older runs do not record it
    named = [r for r in recorded if r["named"]]
    print(f"clean rigs with an extension named (wrong names): {len(named)} of {len(recorded)} [goal 0]"
          + "".join(f"\n  seed {r['seed']}: {', '.join(r['named'])}" for r in named))
    print("verdicts: " + ", ".join(f"{v} {sum(r.get('verdict') == v for r in done)}" for v in
                                    ("ok", "model_error", "not_identifiable", "inconsistent", "failed")))
    cpu = sum(r.get("rig_cpu_s", 0) for r in rows)
    print(f"rig model: {cpu:.0f} s CPU over {len(done)} rigs (median "
          f"{np.median([r['rig_cpu_s'] for r in done]) if done else 0:.0f} s); total "
          f"{time.perf_counter() - t0:.0f} s wall with {procs} processes" if procs else "")


def short(kind: dict) -> str:
    ex = {"corner": "corner", "top_corner": "top-x", "anywhere": "any-ax", "random": "rnd-ax"}[kind["exciter"]]
    return f"{kind['cables']} {kind['layout']:8s} {ex:7s} {kind['duration']:4.0f}s"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", type=int, default=32, help="random rigs (default 32)")
    ap.add_argument("--first-seed", type=int, default=21000, help="seed of the first rig (default 21000)")
    ap.add_argument("--procs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--json", metavar="FILE", help="also write the rows to FILE (after each rig)")
    ap.add_argument("--exact-survey", action="store_true",
                    help="rig.yaml and the load cells exact (default: off by concealed errors of the "
                         "survey's σ)")
    ap.add_argument("--pool", nargs="+", metavar="FILE",
                    help="run nothing: the acceptance counts of the rows of these --json files together")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    if a.pool:
        rows = [r for f in a.pool for r in json.loads(open(f, encoding="utf-8").read())]
        print(f"pooled: {len(rows)} rigs from {len(a.pool)} sweeps ({', '.join(a.pool)})")
        summary_rig(rows, t0, 0)
        return 0
    seeds = list(range(a.first_seed, a.first_seed + a.rigs))
    rows = run_jobs(job_rig, [(s, a.exact_survey) for s in seeds], a.procs, a.json,
                    lambda r: f"seed {r['seed']} {short(r)}")
    summary_rig(rows, t0, a.procs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
