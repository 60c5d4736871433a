"""Calibration of the model-validation checks on clean recordings (no effect concealed).

Usage: python bench/bench_validation_null.py [--seeds N] [--procs P] [--durations 30,60,120]
                                              [--layouts 4splayed,3splayed,...] [--json FILE]
       python bench/bench_validation_null.py --any-rig SEED --noise-seeds N [--first-noise-seed K] [--procs P]
                                              [--json FILE]

On clean random rigs of the package's own simulator (:mod:`rig_identification.design.scenarios`)
every check of :func:`rig_identification.estimation.validation.validate` should pass about as often as
its false-alarm rate says: this prints, per check, the fraction of clean recordings on
which it failed, the median and largest statistic over its threshold, and per recording the
verdict and the largest |error|/σ — the null distribution the thresholds are set against.

``--any-rig SEED --noise-seeds N``: one rig of ``bench/bench_any_rig.py`` (its ``draw(SEED)``,
the exciter force simulate_random settled on) recorded N times with independent sensor noise
(noise seeds K..K+N−1, default 1..N): per noise seed the verdict, each consistency check's χ²/dof and each
entry's error/σ; then per check the mean χ²/dof (1 under its null) and how many exceed the χ²
quantile 1 − ALPHA (the rate ALPHA says: σ widened) and the failure threshold, and per entry
the RMS of error/σ (1 when σ is calibrated).  Where the quadrature regression's χ² is beyond its failure threshold,
``input_correlation``'s statistic is the Hausman test's of the tensor (validation.quadrature_check) —
printed as it stands.  Whether a false alarm on one recording is the
check's null mis-stated or the rig's own physics: a mis-stated null shows on every rig's noise.
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
    from rig_identification.design.scenarios import simulate_random
    from rig_identification.io.recording import Recording
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.parametrisation import from_tensor
    from rig_identification.pipeline.offline import identify_recording
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


def _noise_job(args):
    seed, noise_seed = args
    import warnings
    warnings.simplefilter("ignore")
    sys.path.insert(0, str(ROOT / "bench"))
    from bench_any_rig import draw

    from rig_identification.design.scenarios import simulate_random
    from rig_identification.io.recording import Recording
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.experiment import experiment_from_dict
    from rig_identification.model.parametrisation import from_tensor
    from rig_identification.model.simulator import simulate
    from rig_identification.pipeline.offline import identify_recording
    kind = draw(seed)
    d, _ = simulate_random(seed, kind["cables"], kind["layout"], [], kind["duration"], exciter=kind["exciter"])
    d = json.loads(json.dumps(d))
    d["seed"] = noise_seed
    sim = simulate(experiment_from_dict(d, d["name"]))
    res = identify_recording(Recording(sim.rig, sim.sensors, sim.truth, None))
    tru = sim.truth["inertia_about_cg"]
    err = from_tensor(res.inertia) - np.array([tru[k] for k in KEYS])
    z = err / res.inertia_std
    v = res.validation

    def vec(x):
        return None if x is None else [float(y) for y in x]
    return {"noise_seed": noise_seed, "verdict": v.verdict, "z": [None if k in v.undetermined else float(x)
                                                                    for k, x in zip(KEYS, z)],
            "checks": {c.name: [c.statistic, c.threshold, c.passed] for c in v.checks},
            "details": {c.name: c.detail for c in v.checks},
            # the pieces of σ: the error (6,) kg·m², the reported σ, the propagated σ on the
            # compensated estimate with the compensation's σ (crb_std, before any widening)
            "error": vec(err), "std": vec(res.inertia_std), "crb_std": vec(res.crb_std)}


def noise_main(a) -> int:
    """The --any-rig mode (see module docstring)."""
    from rig_identification.estimation.validation import EFFECT_FACTOR, WHITENESS_FACTOR
    from rig_identification.io.verdict import KEYS
    with ProcessPoolExecutor(a.procs) as ex:
        rows = list(ex.map(_noise_job, [(a.any_rig, k) for k in range(a.first_noise_seed,
                                                                     a.first_noise_seed + a.noise_seeds)]))
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=1))
    chi = ("segments", "sub_bands", "input_correlation")
    print(f"rig {a.any_rig} of bench_any_rig, {len(rows)} noise seeds")
    print(f"{'noise':>5s} {'verdict':17s} " + " ".join(f"{n[:12]:>12s}" for n in chi) + "  error/σ per entry")
    for r in rows:
        st = [r["checks"].get(n, [None])[0] for n in chi]
        print(f"{r['noise_seed']:5d} {r['verdict']:17s} " + " ".join("           -" if x is None else f"{x:12.2f}"
                                                                    for x in st)
              + "  " + " ".join("    -" if x is None else f"{x:+5.2f}" for x in r["z"]))
    print(f"\n{'check':18s} {'mean χ²/dof':>11s} {'> 1−α quantile':>15s} {'failed':>7s}")
    for n in chi:
        v = [r["checks"][n] for r in rows if n in r["checks"] and r["checks"][n][0] is not None]
        if v:
            x = np.array([s for s, _, _ in v])
            q = np.array([t / EFFECT_FACTOR for _, t, _ in v])
            print(f"{n:18s} {np.mean(x):11.2f} {int(np.sum(x > q)):>9d}/{len(v):<5d} "
                  f"{sum(p is False for *_, p in v):>4d}")
    # the whiteness check (Fisher's g over the noise realisations' spectrum): its statistic over
    # its significance threshold (failed beyond WHITENESS_FACTOR), and where its largest line is
    w = [(r["noise_seed"], r["checks"]["whiteness"], r.get("details", {}).get("whiteness", ""))
         for r in rows if "whiteness" in r["checks"] and r["checks"]["whiteness"][0] is not None]
    if w:
        over = [st / (th / WHITENESS_FACTOR) for _, (st, th, _), _ in w]
        print(f"whiteness: statistic over its significance threshold, median {np.median(over):.2f}; "
              f"significant on {sum(x > 1 for x in over)}/{len(w)}, failed on {sum(p is False for _, (*_, p), _ in w)}")
        for (k, _, det), x in zip(w, over):
            if x > 1:
                print(f"  noise seed {k}: {x:.2f}× — {det}")
    Z = np.array([[np.nan if x is None else x for x in r["z"]] for r in rows], float)
    rms = np.sqrt(np.nanmean(Z**2, axis=0))
    E = np.array([r["error"] for r in rows], float)
    if len(rows) > 1:
        # the spread over the noise seeds against what each fit reported: calibrated σ has
        # the ratio 1 (the bias, the mean error, in σ of the mean)
        print(f"\n{'entry':6s} {'mean error':>11s} {'empirical sd':>13s} {'mean σ':>9s} {'mean crb σ':>11s} "
              f"{'sd/σ':>6s}")
        S = np.array([r["std"] for r in rows], float)
        C = np.array([r["crb_std"] or [np.nan] * 6 for r in rows], float)
        for i, k in enumerate(KEYS):
            print(f"{k:6s} {E[:, i].mean():+11.4g} {E[:, i].std(ddof=1):13.4g} {S[:, i].mean():9.4g} "
                  f"{np.nanmean(C[:, i]):11.4g} {E[:, i].std(ddof=1) / S[:, i].mean():6.2f}")
    print("RMS error/σ per entry: " + ", ".join(f"{k} {x:.2f}" for k, x in zip(KEYS, rms))
          + f"; all {np.sqrt(np.nanmean(Z**2)):.2f}; within ±1.96 σ {100 * np.nanmean(np.abs(Z) <= 1.96):.1f} %; "
          f"beyond 3 σ {int(np.nansum(np.abs(Z) > 3))} of {int(np.sum(np.isfinite(Z)))}")
    silent = [r["noise_seed"] for r, zr in zip(rows, Z) if r["verdict"] == "ok" and np.nanmax(np.abs(zr)) > 3]
    print(f"silent failures (verdict ok, an entry beyond 3 σ): {len(silent)}"
          + (f" (noise seeds {silent})" if silent else ""))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=100)
    ap.add_argument("--procs", type=int, default=2)
    ap.add_argument("--durations", default="30,60,120")
    ap.add_argument("--layouts", default="4splayed,3splayed,5mixed,6splayed")
    ap.add_argument("--json", metavar="FILE")
    ap.add_argument("--any-rig", type=int, metavar="SEED", help="one bench_any_rig rig under many noise seeds")
    ap.add_argument("--noise-seeds", type=int, default=12, help="with --any-rig: N noise seeds (default 12)")
    ap.add_argument("--first-noise-seed", type=int, default=None,
                    help="with --any-rig: the first noise seed (default 1)")
    a = ap.parse_args(argv)
    a.first_noise_seed_given = a.first_noise_seed is not None
    a.first_noise_seed = 1 if a.first_noise_seed is None else a.first_noise_seed
    if a.any_rig is not None:
        return noise_main(a)
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
