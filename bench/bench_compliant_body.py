"""The compliant-body candidate on random rigs: named with an honest tensor, or a hypothesis?

Usage: python bench/bench_compliant_body.py [--rigs N] [--first-seed S] [--duration S] [--procs P]
                                            [--kinds fixed,sweep] [--grid F,F,..] [--keep K]
                                            [--truth-start] [--draws N] [--json FILE]

Builds, with the package's own simulator (:func:`rig_identification.design.scenarios.random_experiment`:
random NHTSA vehicles in carrying frames, 4 wide cables, the exciter at a frame corner,
reference noise, 200 Hz), N random rigs (default 6) whose body is not rigid: effect
``compliant_body`` with the mass share drawn from 0.60–0.75, the roll, pitch and heave
frequencies from 1.2–3 Hz and the damping ratio from 0.15–0.3 (per rig, from its seed).
Each rig is recorded twice (``--kinds``): ``fixed``, the exciter at the one speed
``simulate_random`` draws (1.15–1.4 Hz, away from the rig's modes), and ``sweep``, the same
unbalance spun up from rest to 3.5 Hz over the recording (:func:`simulate`).  On each
recording it runs the rigid-body identification (``identify_recording``: its verdict and
error), then the candidate (:func:`rig_identification.diagnosis.compliant_body.fit_compliant_body`,
its search from ``--grid``) and prints per rig: the truth's modes and share, the fitted
ones, named or not (and why), the largest |error|/σ and error % over the entries, the
criterion V against its degrees of freedom and the rigid body's V, how many other optima
fit to the noise level; when named, the ordinary fit again with the candidate's wrench
(what ``with_diagnosis`` validates and reports: σ at least the two-body fit's).  Then per
kind the counts: named, silent failures among them (an entry beyond 3 σ, or a non-finite
number); the fits that *passed* (validation ok, parameters plausible, whether or not the
exciter swept) and how many of them were beyond 3 σ or 1 %; named by with_diagnosis's rule;
the |error|/σ of every entry.

--truth-start adds the truth's modes as a starting point of the search: when that finds a
lower V than the search alone, the search missed the optimum; when V is as low with another
tensor, the data do not determine it.

--draws N: bias or noise?  Each rig is simulated again at 1/1000 of the reference noise and
fitted N times with fresh reference noise added (``estimation.uncertainty.add_noise``); printed
per entry: the mean error and its spread over the draws against the median σ the fits report.
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


def draw(seed: int) -> dict:
    """The compliant_body effect of rig ``seed``: share 0.60–0.75, frequencies 1.2–3 Hz, ζ 0.15–0.3."""
    rng = np.random.default_rng([seed, 17])
    return {"name": "compliant_body", "mass_share": float(np.round(rng.uniform(0.60, 0.75), 3)),
            "frequencies": [float(f) for f in np.round(rng.uniform(1.2, 3.0, 3), 2)],
            "damping_ratio": float(np.round(rng.uniform(0.15, 0.30), 3))}


def truth_modes(truth: dict):
    """The truth's roll and pitch modes with the frame held, as a starting point: the sprung
    body's rotational stiffness K (diagonal, body axes: roll, pitch, and the yaw lock) against
    its tensor J_s, K v = ω² J_s v (scipy ``eigh``), the two lowest; ℓ = J_s v with vᵀ J_s v = 1."""
    from scipy.linalg import eigh

    from rig_identification.estimation.two_body import SprungModes
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.parametrisation import to_tensor
    cb = truth["simulator"]["compliant_body"]
    Js = to_tensor([cb["sprung_inertia_about_cg"][k] for k in KEYS])
    K = np.diag(cb["stiffness_rotation"])
    w2, V = eigh(K, Js)
    L = (Js @ V[:, :2]).T
    eff = truth["effects"][0]
    z = np.broadcast_to(eff["damping_ratio"], (3,))
    return SprungModes(np.array([truth["inertia_about_cg"][k] for k in KEYS]), L, np.sqrt(w2[:2]) / (2 * np.pi),
                       np.array(z[:2], float))


SWEEP_HZ = 3.5        # the sweep's top speed, Hz (spin_up from rest: 0 → SWEEP_HZ over the recording)


def simulate(seed: int, duration: float, kind: str, noise: dict | None = None):
    """Rig ``seed`` with its compliant body (:func:`draw`): ``kind`` "fixed" as
    ``simulate_random`` draws it (one speed), or "sweep": the same rig and exciter, the motor
    spun up from rest to :data:`SWEEP_HZ` over the recording less 5 s (``ramp_shape:
    spin_up``, a linear chirp), the unbalance the fixed run's (force ∝ speed², so the force at
    the fixed run's speed is the fixed run's), lowered by a third while a cable drops below
    ``MIN_TENSION`` of its static tension (as ``simulate_random``)."""
    from rig_identification.design.scenarios import MIN_TENSION, random_experiment, simulate_random
    from rig_identification.design.sweep import sweep_excitation
    from rig_identification.model.experiment import experiment_from_dict
    from rig_identification.model.simulator import SimulationError
    from rig_identification.model.simulator import simulate as run
    if kind == "fixed":
        return simulate_random(seed, 4, "wide", [draw(seed)], duration, noise=noise)
    d = random_experiment(seed, 4, "wide", [draw(seed)], duration, noise=noise)
    r = d["excitation"]["rotating"]
    r.update(sweep_excitation(r["amplitude"] / (2 * np.pi * r["frequency"]) ** 2, duration, SWEEP_HZ))
    for _ in range(6):
        sim = run(experiment_from_dict(d, d["name"]))
        T = np.column_stack([sim.sensors.load_cells[n].data[:, 0] for n in sim.rig.cable_names])
        static = np.median(T[:100], axis=0)
        if np.all(T.min(axis=0) >= MIN_TENSION * static):
            return d, sim
        r["amplitude"] *= 2 / 3
    raise SimulationError(f"{d['name']}: the sweep slackens a cable even at {r['amplitude']:.0f} N")


def _draws(seed: int, duration: float, n: int, kind: str, grid: tuple, keep: int) -> dict:
    """The rig's noise-free trajectory (1/1000 of the reference noise) fitted n times with
    fresh reference noise: per entry the errors (n,6) and σ (n,6), % of the reference."""
    from rig_identification.design.scenarios import REFERENCE_NOISE
    from rig_identification.diagnosis.compliant_body import fit_compliant_body
    from rig_identification.estimation.uncertainty import add_noise
    from rig_identification.io.recording import Recording
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.parametrisation import from_tensor
    _, sim = simulate(seed, duration, kind, noise={k: 1e-3 * v for k, v in REFERENCE_NOISE.items()})
    tru = sim.truth["inertia_about_cg"]
    jt = np.array([tru[k] for k in KEYS])
    big = max(tru["ixx"], tru["iyy"], tru["izz"])
    ref = np.array([abs(tru["ixx"]), big, big, abs(tru["iyy"]), big, abs(tru["izz"])])
    errs, stds = [], []
    for k in range(n):
        s = add_noise(sim.sensors, REFERENCE_NOISE, np.random.default_rng([seed, 1000 + k]))
        cb = fit_compliant_body(Recording(sim.rig, s, sim.truth, None), seed=k, grid=grid, keep=keep)
        errs.append(100 * (from_tensor(cb.inertia) - jt) / ref)
        stds.append(100 * cb.inertia_std / ref)
    return {"err_pct": np.array(errs).tolist(), "std_pct": np.array(stds).tolist()}


def _job(args):
    seed, duration, truth_start, n_draws, kind, grid, keep = args
    import warnings
    warnings.simplefilter("ignore")
    from rig_identification.diagnosis.compliant_body import fit_compliant_body
    from rig_identification.io.recording import Recording
    from rig_identification.io.verdict import KEYS
    from rig_identification.model.parametrisation import from_tensor
    from rig_identification.pipeline.offline import identify_recording
    eff = draw(seed)
    t0 = time.process_time()
    d, sim = simulate(seed, duration, kind)
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    tru = sim.truth["inertia_about_cg"]
    jt = np.array([tru[k] for k in KEYS])
    big = max(tru["ixx"], tru["iyy"], tru["izz"])
    ref = np.array([abs(tru["ixx"]), big, big, abs(tru["iyy"]), big, abs(tru["izz"])])
    rigid = identify_recording(rec)
    row = {"seed": seed, "kind": kind, "effect": eff, "vehicle": d["description"],
           "exciter_hz": d["excitation"]["rotating"]["frequency"],
           "rigid_verdict": rigid.validation.verdict,
           "rigid_err_pct": (100 * (from_tensor(rigid.inertia) - jt) / ref).tolist()}
    runs = [("search", ())] + ([("truth_start", (truth_modes(sim.truth),))] if truth_start else [])
    for name, starts in runs:
        cb = fit_compliant_body(rec, starts=starts, grid=grid if name == "search" else (), keep=keep)
        j = from_tensor(cb.inertia)
        e, s = j - jt, cb.inertia_std
        given = [k not in cb.undetermined for k in KEYS]
        z = e / np.where(s > 0, s, np.nan)
        row[name] = {"named": cb.named, "passed": cb.passed, "significant": cb.significant, "why": cb.why,
                     "err_pct": (100 * e / ref).tolist(), "z": z.tolist(),
                     "std_pct": (100 * s / ref).tolist(), "given": given, "undetermined": list(cb.undetermined),
                     "finite": bool(np.all(np.isfinite(j)) and np.all(np.isfinite(s))),
                     "modes": [[m.frequency, m.damping_ratio, m.share] for m in cb.modes],
                     "heave": cb.heave.to_dict(), "V": cb.cost, "dof": cb.dof, "V_rigid": cb.cost_rigid,
                     "alternatives": len(cb.alternatives), "verdict": cb.validation.verdict if cb.validation else None,
                     "failed": list(cb.validation.failed) if cb.validation else [],
                     "unexplained": list(cb.unexplained), "exciter_hz": cb.exciter_hz}
        if cb.wrench is not None:
            # what with_diagnosis does with a named candidate: identify again with its wrench,
            # σ at least the two-body fit's; named only when that fit's validation is ok
            fit = identify_recording(rec, effect_wrench=cb.wrench)
            sd = np.maximum(fit.inertia_std, cb.inertia_std)
            e2 = from_tensor(fit.inertia) - jt
            row[name]["refit"] = {"verdict": fit.validation.verdict, "failed": list(fit.validation.failed),
                                  "err_pct": (100 * e2 / ref).tolist(), "z": (e2 / sd).tolist()}
    if n_draws:
        row["draws"] = _draws(seed, duration, n_draws, kind, grid, keep)
    row["cpu_s"] = time.process_time() - t0
    return json.loads(json.dumps(row, default=float))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rigs", type=int, default=6)
    ap.add_argument("--first-seed", type=int, default=9100)
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--procs", type=int, default=1)
    ap.add_argument("--truth-start", action="store_true", help="also search from the truth's modes (diagnostic)")
    ap.add_argument("--draws", type=int, default=0, help="fits of each rig's noise-free run with fresh noise (bias?)")
    ap.add_argument("--kinds", default="fixed,sweep", help="experiments per rig: fixed (one speed), sweep (0 → 3.5 Hz)")
    ap.add_argument("--grid", default="1.0,1.5,2.2,3.2", help="the search's starting frequencies per mode, Hz")
    ap.add_argument("--keep", type=int, default=4, help="grid points refined with every parameter free")
    ap.add_argument("--json", metavar="FILE")
    ap.add_argument("--show", metavar="FILE", help="print the table of a former run's --json FILE (no run)")
    a = ap.parse_args(argv)
    grid = tuple(float(g) for g in a.grid.split(","))
    jobs = [(a.first_seed + k, a.duration, a.truth_start, a.draws, kind, grid, a.keep) for k in range(a.rigs)
            for kind in a.kinds.split(",")]
    t0 = time.perf_counter()
    rows = json.loads(Path(a.show).read_text()) if a.show else []
    if not a.show:
        with ProcessPoolExecutor(a.procs) as ex:
            for r in ex.map(_job, jobs):
                rows.append(r)
                print(f"done {len(rows)}/{len(jobs)}: seed {r['seed']} ({r['cpu_s']:.0f} s CPU)", file=sys.stderr,
                      flush=True)
                if a.json:
                    Path(a.json).write_text(json.dumps(rows, indent=1))
    print(f"{'seed':>5s} {'kind':5s} {'share':>5s} {'f roll/pitch/heave Hz':>21s} {'ζ':>5s} | "
          f"{'rigid':>11s} {'max e%':>6s} | "
          f"{'run':11s} {'named':5s} {'roll f,ζ':>11s} {'pitch f,ζ':>11s} {'share':>5s} {'max|e|/σ':>8s} "
          f"{'max e%':>7s} "
          f"{'V/dof':>11s} {'V_rigid':>8s} {'alt':>3s} {'pass':4s}  why")
    for r in rows:
        eff = r["effect"]
        head = (f"{r['seed']:5d} {r['kind']:5s} {eff['mass_share']:5.2f} "
                f"{'/'.join(f'{f:.2f}' for f in eff['frequencies']):>21s} "
                f"{eff['damping_ratio']:5.2f} | {r['rigid_verdict']:>11s} {np.max(np.abs(r['rigid_err_pct'])):6.1f} |")
        for name in ("search", "truth_start"):
            if name not in r:
                continue
            c = r[name]
            zs = [abs(z) for z, g in zip(c["z"], c["given"]) if g and z is not None and np.isfinite(z)]
            es = [abs(e) for e, g in zip(c["err_pct"], c["given"]) if g]
            md = c["modes"]
            share = c["heave"]["mass_share"]
            print(f"{head} {name:11s} {str(c['named']):5s} {md[0][0]:5.2f},{md[0][1]:.2f} "
                  f"{md[1][0]:5.2f},{md[1][1]:.2f} "
                  f"{'-' if share is None or not c['heave']['determined'] else f'{share:.2f}':>5s} "
                  f"{(max(zs) if zs else float('nan')):8.2f} {(max(es) if es else float('nan')):7.2f} "
                  f"{c['V']:5.0f}/{c['dof']:<5d} {c['V_rigid']:8.0f} {c['alternatives']:3d} "
                  f"{'yes' if c.get('passed') else 'no':4s}  "
                  f"{c['why'][:110]}" + (f" [undetermined {','.join(c['undetermined'])}]" if c["undetermined"] else ""))
            if c.get("refit"):
                rf = c["refit"]
                print(f"{'':>{len(head)}s}   refit with its wrench: {rf['verdict']} {','.join(rf['failed'])}, max|e|/σ "
                      f"{max(abs(z) for z in rf['z']):.2f}, max e% {max(abs(e) for e in rf['err_pct']):.2f}")
            head = " " * len(head)
    for r in rows:
        if "draws" in r:
            e, sd = np.array(r["draws"]["err_pct"]), np.array(r["draws"]["std_pct"])
            print(f"seed {r['seed']}, {len(e)} noise draws on its noise-free run — per entry "
                  "(ixx ixy ixz iyy iyz izz), "
                  "% of the reference:")
            print("  mean error  " + " ".join(f"{x:+7.2f}" for x in e.mean(0)))
            print("  its spread  " + " ".join(f"{x:7.2f}" for x in e.std(0, ddof=1 if len(e) > 1 else 0)))
            print("  median σ    " + " ".join(f"{x:7.2f}" for x in np.median(sd, 0)))

    def wrong(r):
        c = r["search"]
        return not c["finite"] or any(g and (z is None or not np.isfinite(z) or abs(z) > 3)
                                      for z, g in zip(c["z"], c["given"]))

    for kind in dict.fromkeys(r["kind"] for r in rows):
        rk = [r for r in rows if r["kind"] == kind]
        named = [r for r in rk if r["search"]["named"]]
        passed = [r for r in rk if r["search"].get("passed")]
        big = [r for r in passed if max(abs(e) for e, g in zip(r["search"]["err_pct"], r["search"]["given"]) if g) > 1]
        print(f"\n[{kind}] named: {len(named)}/{len(rk)}; silent failures among them (an entry given beyond 3 σ, or "
              f"non-finite): {sum(wrong(r) for r in named)}   [goal 0]")
        print(f"[{kind}] passed (validation ok, plausible): {len(passed)}/{len(rk)}; beyond 3 σ among them: "
              f"{sum(wrong(r) for r in passed)} (seeds {[r['seed'] for r in passed if wrong(r)]}), beyond 1 %: "
              f"{len(big)} (seeds {[r['seed'] for r in big]}); significant against the rigid body: "
              f"{sum(r['search'].get('significant', False) for r in rk)}/{len(rk)}")
        final = [r for r in named if r["search"].get("refit", {}).get("verdict") == "ok"]
        print(f"[{kind}] named by with_diagnosis's rule (refit with the wrench ok): {len(final)}/{len(rk)}; beyond 3 σ "
              f"among them: {sum(max(abs(z) for z in r['search']['refit']['z']) > 3 for r in final)}, beyond 1 %: "
              f"{sum(max(abs(e) for e in r['search']['refit']['err_pct']) > 1 for r in final)}")
        zall = np.array([z for r in rk for z, g in zip(r["search"]["z"], r["search"]["given"]) if g and z is not None])
        if len(zall):
            print(f"[{kind}] every entry given, named or not ({len(zall)}): |error|/σ ≤ 3 on "
                  f"{np.mean(np.abs(zall) <= 3) * 100:.0f} %, ≤ 1.96 on {np.mean(np.abs(zall) <= 1.96) * 100:.0f} %; "
                  f"median {np.median(np.abs(zall)):.2f}, max {np.max(np.abs(zall)):.1f}")
    print("rigid-body fit: verdict model_error on "
          f"{sum(r['rigid_verdict'] == 'model_error' for r in rows)}/{len(rows)}; "
          f"total {time.perf_counter() - t0:.0f} s with {a.procs} process(es)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
