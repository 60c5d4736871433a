"""Issue 7 part A: predicted uncertainty before the run against the Monte Carlo spread after it,
and the experiment design for case 16.

``crb`` — thesis cases 10–17 (config/cases, each with its own rig, body and excitation;
120 s like the reference recordings, so cases 16 and 17 coincide), sensors at the reference
recordings' rates and noise (gyro 0.002 rad/s,
accelerometer 0.01 m/s², load cells and exciter 0.5 N, inclinometer 0.2 mrad; 200/200/200/50
Hz).  Per case: one noise-free simulation; the prediction of
:func:`rig_identification.estimation.propagation.predict_from_trajectory` (before the run); RUNS noisy
copies (fresh white noise on every sensor, the simulator's noise model) replayed through
tracker -> preprocessor -> identifier; per entry the Monte Carlo spread / predicted σ, with
the spread's own sampling uncertainty (±1/sqrt(2(RUNS-1))), and the identifier's white-gyro
bound ``crb_std`` / spread for comparison.  30 runs leave the ratio ±13 % (1σ) of sampling
noise, enough for a 0.6 on one entry of 48 by chance (case 10 Izz with seeds 10000–10029:
the first-order model itself, on those same gyro draws, spreads 0.66 of its σ).  So each
case also gets a control-variate estimate ``cv``: the first-order model is evaluated on the
runs' own gyro draws (``Prediction.gyro_sensitivity``) and
``cv² = [s²(pipeline) − s²(model, same draws) + σ²(model, gyro)] / σ²(predicted)``;
where the pipeline follows the model (correlation ρ ≈ 0.9) most of the draws' luck cancels.

``plan`` — the recommended plan for case 16 (config/rigs/default.yaml: the thesis rig and the
Jeep Cherokee, 120 s runs) against the thesis's own excitation (200 N at 1.05 Hz at the rig's
exciter), then CONFIRM noisy simulations of the plan (its runs fitted at once by the rig model, as
``rig-identify inertia REC1 REC2``) and of the baseline (the rig model): their
RMS errors against the predictions.  ``vary``: the second run may also use another cable
geometry (:func:`rig_identification.design.planning.geometry_variants`, ceiling anchors moved 1 m;
``rig-identify plan --vary-geometry 1``).

Usage: bench_plan.py [crb [RUNS=30] [PROCESSES=2] [CASES...]] | [plan [CONFIRM=8] [PROCESSES=2] [vary]]
(no arguments: both).
"""
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np

from rig_identification.estimation.propagation import (
    REFERENCE_NOISE,
    REFERENCE_RATES,
    Trajectory,
    predict_from_trajectory,
)
from rig_identification.estimation.uncertainty import add_noise
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import load_experiment
from rig_identification.model.parametrisation import from_tensor
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import identify_recording

ROOT = Path(__file__).resolve().parents[1]
CASES = [f"case{i}" for i in range(10, 18)]
_SIMS: dict = {}


DURATION = 120.0  # s: the reference recordings' length (the thesis ran cases 10-15 for 250 s, 16 for 150, 17 for 100)


def reference_experiment(path):
    """The experiment of ``path`` with the reference recordings' sensor rates and length, noise-free."""
    from dataclasses import replace
    exp = load_experiment(path)
    exp = replace(exp, sensors=replace(exp.sensors, rates=dict(REFERENCE_RATES)))
    return exp.with_overrides(noise_free=True, duration=DURATION)


def _clean(key):
    if key not in _SIMS:
        kind, arg = key
        if kind == "case":
            _SIMS[key] = simulate(reference_experiment(ROOT / "config" / "cases" / f"{arg}.yaml"))
        else:
            _SIMS[key] = simulate(arg)
    return _SIMS[key]


def one_run(args):
    key, seed, band = args
    sim = _clean(key)
    rng = np.random.default_rng(seed)
    # the plain gyro-only fit: the estimator the prediction models (first order); crb_std is the
    # identifier's white-gyro bound
    rec = Recording(sim.rig, add_noise(sim.sensors, REFERENCE_NOISE, rng), sim.truth)
    res = identify_recording(rec, band_hz=band)
    return from_tensor(res.inertia), res.crb_std


def gyro_draw(sim, seed):
    """The gyro noise (N,3) that :func:`one_run` adds with ``seed`` (add_noise draws the IMU first)."""
    z = np.random.default_rng(seed).standard_normal(sim.sensors.imu.data.shape)[:, :3]
    return REFERENCE_NOISE["gyro"] * z


def first_order(sim, traj, pred, seeds):
    """(runs, 6) first-order estimate errors of the gyro noise of ``seeds`` (same draws as the runs)."""
    t_imu = sim.sensors.imu.t - sim.experiment.stamp_origin
    idx = np.searchsorted(t_imu, traj.t - 1e-4)   # stamps ~1.75e9 s: rounding ~1e-7 s
    assert np.allclose(t_imu[idx], traj.t, atol=1e-6), "trajectory samples are not the IMU samples"
    S = pred.gyro_sensitivity
    return np.array([np.einsum("ndk,nd->k", S, gyro_draw(sim, s)[idx]) for s in seeds])


def crb_table(runs=30, procs=2, cases=None):
    cases = cases or CASES
    t0 = time.perf_counter()
    print(f"Predicted σ (before the run) against the Monte Carlo spread (after it): {runs} noisy runs per case, "
          "reference noise levels and rates")
    print("(spread/pred: 1 is perfect; the spread's own 1σ sampling uncertainty is "
          f"±{100 / np.sqrt(2 * (runs - 1)):.0f} %)")
    print(f"{'case':7s} {'s':>4s} " + " ".join(f"{k:>17s}" for k in KEYS))
    print(f"{'':7s} {'':>4s} " + " ".join(f"{'pred  spread/pred':>17s}" for _ in KEYS))
    ratios, crb_ratios, cv_ratios = [], [], []
    pool = Pool(procs) if procs > 1 else None
    try:
        for case in cases:
            tc = time.perf_counter()
            sim = _clean(("case", case))
            traj = Trajectory.from_simulation(sim)
            pred = predict_from_trajectory(traj, gyro_sensitivity=True)
            seeds = [1000 * int(case[4:]) + k for k in range(runs)]
            jobs = [(("case", case), s, None) for s in seeds]
            out = pool.map(one_run, jobs) if pool else [one_run(j) for j in jobs]
            est = np.array([o[0] for o in out])
            crb = np.array([o[1] for o in out]).mean(0)
            spread = est.std(0, ddof=1)
            r = spread / pred.std
            ratios.append(r)
            crb_ratios.append(crb / spread)
            lin = first_order(sim, traj, pred, seeds)
            S = pred.gyro_sensitivity
            var_lin = REFERENCE_NOISE["gyro"] ** 2 * np.einsum("ndk,ndk->k", S, S)
            cv = np.sqrt(np.clip(spread**2 - lin.std(0, ddof=1) ** 2 + var_lin, 0, None)) / pred.std
            rho = np.array([np.corrcoef(est[:, i], lin[:, i])[0, 1] for i in range(6)])
            cv_ratios.append(cv)
            dur = sim.experiment.duration
            print(f"{case:7s} {dur:4.0f} " + " ".join(f"{p:8.3f} {x:8.2f}" for p, x in zip(pred.std, r))
                  + f"   ({time.perf_counter() - tc:.0f} s)", flush=True)
            print(f"{'':7s} {'':>4s} " + " ".join(f"{'crb/spread':>8s} {x:8.2f}" for x in crb_ratios[-1]))
            print(f"{'':7s} {'':>4s} " + " ".join(f"{'ρ ' + format(c, '.2f'):>8s} {x:8.2f}" for c, x in zip(rho, cv))
                  + "   (cv: control-variate spread/pred; ρ: pipeline vs first-order model, same draws)")
    finally:
        if pool:
            pool.close()
    R = np.array(ratios)
    C = np.array(crb_ratios)
    V = np.array(cv_ratios)
    print(f"spread/pred over {R.size} entries: median {np.median(R):.2f}, range {R.min():.2f}–{R.max():.2f}, "
          f"{np.mean(np.abs(R - 1) <= 0.2) * 100:.0f} % within ±20 %; "
          f"RMS of log ratio {np.sqrt(np.mean(np.log(R)**2)):.3f} "
          f"(pure sampling noise: {1 / np.sqrt(2 * (runs - 1)):.3f})")
    print(f"control-variate spread/pred: median {np.median(V):.2f}, range {V.min():.2f}–{V.max():.2f}, "
          f"{np.mean(np.abs(V - 1) <= 0.2) * 100:.0f} % within ±20 %; "
          f"RMS of log ratio {np.sqrt(np.mean(np.log(V)**2)):.3f}")
    print(f"identifier's white-gyro crb_std / spread: median {np.median(C):.2f}, range {C.min():.2f}–{C.max():.2f}")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return R


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
              f"limit); band {'auto' if c.band is None else np.round(c.band, 3).tolist()}; cables: "
              f"{'the rig' if c.geometry is None else c.geometry}")
    print(f"{'entry':6s} {'baseline σ':>11s} {'plan σ':>9s} {'ratio':>6s}")
    for k, b, p in zip(KEYS, plan.baseline.prediction.std, plan.prediction.std):
        print(f"{k:6s} {b:11.3f} {p:9.3f} {b / p:6.2f}")
    print(f"least improvement {plan.improvement().min():.2f}x; notes: {'; '.join(plan.notes)}")
    if confirm <= 0:
        return plan
    # confirmation: noisy simulations of the plan's runs identified jointly (rig-identify inertia REC1 REC2),
    # and of the baseline, with the ordinary pipeline
    print(f"confirmation: {confirm} noisy simulations of the plan (its runs identified jointly) and of the baseline")
    exps = [(c.body or body).experiment(c.run) for c in plan.runs]
    bands = [c.band for c in plan.runs]
    band = bands[0] if all(b == bands[0] for b in bands) else None
    with Pool(procs) as pool:
        est = np.array(pool.map(one_run_plan, [(("plan",), exps, 500 + 10 * k, band) for k in range(confirm)]))
        eb = np.array(pool.map(one_run_plan, [(("base",), [body.experiment(plan.baseline.run)], 900 + k, None)
                                              for k in range(confirm)]))
    truth = from_tensor(exp.inertia)
    print(f"{'entry':6s} {'plan rms err':>12s} {'pred σ':>8s} {'base rms err':>12s} {'pred σ':>8s} "
          f"{'ratio of rms':>12s}")
    for k, i in zip(KEYS, range(6)):
        ep, ebb = np.sqrt(np.mean((est[:, i] - truth[i])**2)), np.sqrt(np.mean((eb[:, i] - truth[i])**2))
        print(f"{k:6s} {ep:12.3f} {plan.prediction.std[i]:8.3f} {ebb:12.3f} {plan.baseline.prediction.std[i]:8.3f} "
              f"{ebb / ep:12.2f}")
    print(f"total {time.perf_counter() - t0:.0f} s")
    return plan


_EXP_SIMS: dict = {}


def one_run_plan(args):
    """Worker: noisy copies (seed, seed+1, ...) of the noise-free simulations of ``exps``
    (cached per worker), fitted by the rig model (``rig-identify inertia``: several at once, the body
    shared; no diagnosis); ``band`` is the gyro-only prediction's and unused."""
    from rig_identification.pipeline.rig_model import fit_recordings, fit_whole_recording
    key, exps, seed, band = args
    if key not in _EXP_SIMS:
        _EXP_SIMS.clear()
        _EXP_SIMS[key] = [simulate(e) for e in exps]
    recs = [Recording(sim.rig, add_noise(sim.sensors, REFERENCE_NOISE, np.random.default_rng(seed + i)), sim.truth)
            for i, sim in enumerate(_EXP_SIMS[key])]
    fit = fit_recordings(recs).first.fit if len(recs) > 1 else fit_whole_recording(recs[0], diagnose=False).fit
    return np.asarray(fit.inertia, float)


if __name__ == "__main__":
    argv = sys.argv[1:]
    if not argv or argv[0] == "crb":
        nums = [int(x) for x in argv[1:3] if x.isdigit()]
        names = [x for x in argv[1:] if not x.isdigit()]
        crb_table(*(nums or [30]), cases=names or None)
    if not argv or argv[0] == "plan":
        nums = [int(x) for x in argv[1:3] if x.isdigit()]
        plan_table(*nums, vary="vary" in argv)
