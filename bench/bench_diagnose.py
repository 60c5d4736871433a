"""Benchmark of ``diagnose``: false alarms on clean recordings and the effect library.

Usage: python bench/bench_diagnose.py [N_CLEAN] [N_PER_EFFECT] [PROCS] [DURATION_S] [EFFECT,EFFECT...]

* the clean reference recordings of ../shared/recordings and N_CLEAN (default 20) simulated
  clean recordings (random vehicle and rig geometry, realistic noise, DURATION_S, default
  120 s): the share with
  "no significant mismatch" (issue: ≥ 95 %);
* each effect of the library concealed in N_PER_EFFECT (default 2) simulated recordings:
  named first, parameter error, residual reduction of the affected channels (plain and
  time-synchronous over the exciter's revolutions), inertia error after (the acceptance of
  test/test_diagnose.py, measured over more seeds);
* gyroscopic_coupling: the thesis's model on N_PER_EFFECT clean recordings of planned runs
  (the planner's amplitude), its scale within 15 % of 1, the torque residuals.
Prints one table; runs PROCS (default 2) worker processes; EFFECT,...: only these effects
(the clean references are run when N_CLEAN > 0).
"""
from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "test"))
sys.path.insert(0, str(ROOT))


def _job(args):
    kind, name, seed, duration = args
    import os
    os.chdir(ROOT)
    import test_diagnose
    test_diagnose.DURATION = duration
    from test_diagnose import CASES, _run, check_inertia, check_parameters
    t0 = time.perf_counter()
    if kind == "ref":
        from rig_identification.diagnosis.selection import diagnose
        from rig_identification.io.recording import read_recording
        rec = read_recording(ROOT.parent / "shared" / "recordings" / name)
        res = diagnose(rec).to_dict()
        res["truth"] = rec.truth
    else:
        eff = [] if name in ("clean", "gyroscopic_coupling") else [CASES[name][0]]
        res = _run((seed, eff, "thesis", duration, True) if name == "gyroscopic_coupling" else
                   (seed, eff, "pem", duration, False))
    out = {"kind": kind, "name": name, "seed": seed, "seconds": time.perf_counter() - t0,
           "mismatch": res["mismatch"], "found": [e["name"] for e in res["effects"]]}
    if kind == "effect":
        group = "torque" if name == "gyroscopic_coupling" else CASES[name][1]
        b, a = res["residual_rms_before"], res["residual_rms_after"]
        out["reduction"] = max(1 - a[k] / b[k] for k in b if k.startswith(group))
        s0, s1 = res["residual_rms_synchronous_before"], res["residual_rms_synchronous_after"]
        out["sync_reduction"] = max(1 - s1[k] / s0[k] for k in s0 if k.startswith(group)) if s0 and s1 else float("nan")
        out["first_ok"] = bool(res["effects"]) and res["effects"][0]["name"] == name
        try:
            if name == "gyroscopic_coupling":
                out["param"] = res["effects"][0]["parameters"]["scale"]
                assert abs(out["param"] - 1.0) < 0.15
            else:
                check_parameters(name, res["effects"][0], res["truth"]["effects"][0], res["excitation"])
            out["param_ok"] = True
        except (AssertionError, IndexError, KeyError):
            out["param_ok"] = False
    try:
        check_inertia(res, before=False)
        tru = res["truth"]["inertia_about_cg"]
        big = max(tru["ixx"], tru["iyy"], tru["izz"])
        out["inertia_ok"] = all(abs(res["inertia_about_cg_after"][k] - tru[k]) <=
                                0.005 * (abs(tru[k]) if k in ("ixx", "iyy", "izz") else big) for k in tru)
    except AssertionError:
        out["inertia_ok"] = False
    tru = res["truth"]["inertia_about_cg"]
    big = max(tru["ixx"], tru["iyy"], tru["izz"])
    out["inertia_err_pct"] = max(abs(res["inertia_about_cg_after"][k] - tru[k]) /
                                 (tru[k] if k in ("ixx", "iyy", "izz") else big) * 100 for k in tru)
    return out


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    n_clean = int(argv[0]) if argv else 20
    n_eff = int(argv[1]) if len(argv) > 1 else 2
    procs = int(argv[2]) if len(argv) > 2 else 2
    duration = float(argv[3]) if len(argv) > 3 else 120.0
    sys.path.insert(0, str(ROOT / "test"))
    from test_diagnose import CASES
    jobs = [("ref", n, 0, duration) for n in ("visible_case16_clean", "visible_case14_clean")] if n_clean else []
    jobs += [("clean", "clean", 1000 + i, duration) for i in range(n_clean)]
    names = list(CASES) + ["gyroscopic_coupling"]
    only = argv[4].split(",") if len(argv) > 4 else names
    unknown = set(only) - set(names)
    if unknown:
        raise SystemExit(f"unknown effect(s) {sorted(unknown)}: choose from {names}")
    jobs += [("effect", name, 2000 + 10 * i + k, duration) for i, name in enumerate(names) for k in range(n_eff)
             if name in only]
    names = [n for n in names if n in only]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(procs) as ex:
        rows = list(ex.map(_job, jobs))
    clean = [r for r in rows if r["kind"] in ("ref", "clean")]
    ok = sum(not r["mismatch"] for r in clean)
    if clean:
        print(f"clean recordings: {ok}/{len(clean)} with no significant mismatch ({100 * ok / len(clean):.0f} %; "
              "issue: ≥ 95 %)")
    for r in clean:
        if r["mismatch"]:
            print(f"  false alarm: {r['name']} seed {r['seed']}: {r['found']}")
    print(f"{'effect':20s} {'runs':>4s} {'named 1st':>9s} {'param≤15%':>9s} {'RMS −≥30%':>9s} {'sync −≥30%':>10s} "
          f"{'≤0.5 %':>10s} {'max err %':>9s} {'s/run':>6s}")
    for name in names:
        rs = [r for r in rows if r["kind"] == "effect" and r["name"] == name]
        if not rs:
            continue
        print(f"{name:20s} {len(rs):4d} {sum(r['first_ok'] for r in rs):9d} {sum(r['param_ok'] for r in rs):9d} "
              f"{sum(r['reduction'] >= 0.3 for r in rs):9d} {sum(r['sync_reduction'] >= 0.3 for r in rs):10d} "
              f"{sum(r['inertia_ok'] for r in rs):10d} "
              f"{max(r['inertia_err_pct'] for r in rs):9.3f} {np.mean([r['seconds'] for r in rs]):6.1f}")
    for r in rows:
        if r["name"] == "gyroscopic_coupling":
            print(f"  gyroscopic_coupling seed {r['seed']}: scale {r.get('param', float('nan')):.3f}, torque RMS "
                  f"−{100 * r['reduction']:.0f} % plain, −{100 * r['sync_reduction']:.0f} % synchronous")
    print(f"total {time.perf_counter() - t0:.0f} s with {procs} processes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
