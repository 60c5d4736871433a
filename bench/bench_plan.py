"""The experiment design for case 16, and whether its σ is what the fits reach.

The recommended plan for case 16 (config/rigs/default.yaml: the thesis rig and the Jeep
Cherokee, 120 s runs) against the thesis's own excitation (200 N at 1.05 Hz at the rig's
exciter), then CONFIRM noisy simulations of the plan (its runs fitted at once by the rig model, as
``rig-identify inertia REC1 REC2``) and of the baseline (the rig model): their RMS errors against
the plan's σ (the rig model's Cramér–Rao bound along each run's simulation).  ``vary``: the
second run may also use another cable geometry
(:func:`rig_identification.design.planning.geometry_variants`, ceiling anchors moved 1 m;
``rig-identify plan --vary-geometry 1``).

Usage: bench_plan.py [CONFIRM=8] [PROCESSES=2] [vary]
"""
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from rig_identification.estimation.uncertainty import add_noise
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import REFERENCE_NOISE, REFERENCE_RATES, load_experiment
from rig_identification.model.parametrisation import from_tensor
from rig_identification.model.simulator import simulate

ROOT = Path(__file__).resolve().parents[1]


def plan_table(confirm=8, procs=2, vary=False):
    from rig_identification.design.planning import Body, PlanOptions, Run, geometry_variants, plan_experiment
    t0 = time.perf_counter()
    exp = load_experiment(ROOT / "config" / "rigs" / "default.yaml")
    rig = exp.rig
    body = Body(rig, exp.mass, exp.inertia, np.full(len(rig.cables), 5e6), dict(REFERENCE_RATES), dict(REFERENCE_NOISE))
    base = Run(1.05, 200.0, tuple(rig.exciter.position), "z", 120.0, 2.0, tuple(rig.exciter.rpy))
    geometries = tuple(geometry_variants(body, 1.0)) if vary else ()
    plan = plan_experiment(body, base, PlanOptions(geometries=geometries),
                           progress=lambda s: print("  " + s, flush=True))
    print(f"plan for case 16{' (cable geometry variants: ceiling anchors moved 1 m)' if vary else ''} "
          f"({time.perf_counter() - t0:.0f} s):")
    for i, c in enumerate(plan.runs, 1):
        r = c.run
        print(f"  run {i}: {r.frequency:.3f} Hz, {r.amplitude:.0f} N, exciter at {np.round(r.position, 3).tolist()} m, "
              f"spin axis body {r.spin_axis}{'' if r.direction > 0 else ' (reversed)'}; peak rotation "
              f"{c.peak_rotation_deg:.2f}°, lowest tension {100 * c.min_tension_ratio:.0f} % of static ({c.limit} "
              f"limit); cables: {'the rig' if c.geometry is None else c.geometry}")
    print(f"{'entry':6s} {'baseline σ':>11s} {'plan σ':>9s} {'ratio':>6s}")
    for k, b, p in zip(KEYS, plan.baseline_std, plan.std):
        print(f"{k:6s} {b:11.3f} {p:9.3f} {b / p:6.2f}")
    print(f"least improvement {plan.improvement().min():.2f}x; notes: {'; '.join(plan.notes)}")
    if confirm <= 0:
        return plan
    # confirmation: noisy simulations of the plan's runs identified jointly (rig-identify inertia REC1 REC2),
    # and of the baseline, with the ordinary pipeline
    print(f"confirmation: {confirm} noisy simulations of the plan (its runs identified jointly) and of the baseline")
    exps = [(c.body or body).experiment(c.run) for c in plan.runs]
    with Pool(procs) as pool:
        est = np.array(pool.map(one_run_plan, [(("plan",), exps, 500 + 10 * k) for k in range(confirm)]))
        eb = np.array(pool.map(one_run_plan, [(("base",), [body.experiment(plan.baseline.run)], 900 + k)
                                              for k in range(confirm)]))
    truth = from_tensor(exp.inertia)
    print(f"{'entry':6s} {'plan rms err':>12s} {'pred σ':>8s} {'base rms err':>12s} {'pred σ':>8s} "
          f"{'ratio of rms':>12s}")
    for k, i in zip(KEYS, range(6)):
        ep, ebb = np.sqrt(np.mean((est[:, i] - truth[i])**2)), np.sqrt(np.mean((eb[:, i] - truth[i])**2))
        print(f"{k:6s} {ep:12.3f} {plan.std[i]:8.3f} {ebb:12.3f} {plan.baseline_std[i]:8.3f} "
              f"{ebb / ep:12.2f}")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return plan


_EXP_SIMS: dict = {}


def one_run_plan(args):
    """Worker: noisy copies (seed, seed+1, ...) of the noise-free simulations of ``exps``
    (cached per worker), fitted by the rig model (``rig-identify inertia``: several at once, the body
    shared; no diagnosis)."""
    from rig_identification.pipeline.joint import fit_recordings
    from rig_identification.pipeline.rig_model import fit_whole_recording
    key, exps, seed = args
    if key not in _EXP_SIMS:
        _EXP_SIMS.clear()
        _EXP_SIMS[key] = [simulate(e) for e in exps]
    recs = [Recording(sim.rig, add_noise(sim.sensors, REFERENCE_NOISE, np.random.default_rng(seed + i)), sim.truth)
            for i, sim in enumerate(_EXP_SIMS[key])]
    fit = fit_recordings(recs).first.fit if len(recs) > 1 else fit_whole_recording(recs[0], diagnose=False).fit
    return np.asarray(fit.inertia, float)


if __name__ == "__main__":
    argv = sys.argv[1:]
    nums = [int(x) for x in argv[:2] if x.isdigit()]
    plan_table(*nums, vary="vary" in argv)
