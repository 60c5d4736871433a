"""Trust benchmark: does `rig-identify inertia` ever print a wrong number without saying so?

Usage: python bench/bench_trust.py [--seeds N] [--procs P] [--duration S] [--only ROW,ROW]

Builds, with the package's own simulator (:mod:`rig_identification.design.scenarios`: random NHTSA
vehicles in carrying frames, the body frame off the CG, random exciter placement, realistic
noise, 200 Hz), N random rigs (default 2) for each row below, runs the whole inertia command
on each (the rig model fitted to every sensor, its verdict and its diagnosis) and
prints per recording: verdict, largest |error|/σ and error % of the entries it reports,
named effects, what stayed unexplained; then the acceptance counts of the "never silently
wrong" issue:

* silent failures — verdict ``ok`` and some entry beyond 3 σ, or a non-finite number: 0;
* wrong names — an effect named that the recording does not contain, or a class of effects the
  recording does not tell apart (``told_apart`` false) none of whose candidates it contains: 0;
* data errors (an unknown with a prior — a load cell's gain, a cable's stiffness, the survey —
  pulled beyond 3 σ of it): none on a clean recording, and the effect that is a data error
  (:data:`DATA_ERROR_OF`: one load cell's gain off) found as one;
* clean recordings with verdict ``ok``: ≥ 95 %, and on them every entry within 1 % (products:
  of the largest diagonal) and 3 σ;
* on those, the share of the entries within ±1.96 σ of the truth: 93–97 % (σ calibrated; the
  "any legitimate rig" issue's sweep is ``--only`` the clean rows with ``--seeds 5``).

Rows whose effect the simulator does not know are skipped with a note.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scoring import print_unscored, run_jobs  # noqa: E402  (bench/, beside this script)

# row name -> (cables, layout, effects, clean?[, exciter placement]) (rig_identification.design.scenarios)
ROWS = {
    "clean_4_wide": (4, "wide", [], True),
    "clean_3_wide": (3, "wide", [], True),
    "clean_5_mixed": (5, "mixed", [], True),
    "clean_6_wide": (6, "wide", [], True),
    "clean_4_splayed": (4, "splayed", [], True),
    "clean_4_parallel": (4, "parallel", [], True),
    "clean_4_anywhere": (4, "wide", [], True, "anywhere"),
    "compliant_body": (4, "wide", [{"name": "compliant_body", "mass_share": 0.68,
                                    "frequencies": [1.6, 1.3, 2.2], "damping_ratio": 0.2}], False),
    "gyro_drift_scale": (4, "wide", [{"name": "gyro_bias_drift", "random_walk": 1e-4},
                                     {"name": "gyro_scale", "scale": [1.0, 1.005, 1.0]}], False),
    "delay_damping": (4, "wide", [{"name": "sensor_delay", "stream": "load_cells", "delay": 0.008},
                                  {"name": "viscous_damping", "linear": 150.0, "angular": 300.0}], False),
    "imu_offset_gyro_bias": (4, "wide", [{"name": "imu_offset", "offset": [0.25, -0.1, 0.1]},
                                         {"name": "gyro_bias", "bias": [0.003, -0.002, 0.004]}], False),
    "structural_mode": (4, "wide", [{"name": "structural_mode", "sensor": "imu", "frequency": 8.0,
                                     "damping_ratio": 0.03}], False),
    "viscous_damping": (4, "wide", [{"name": "viscous_damping", "linear": 150.0, "angular": 300.0}], False),
    "exciter_rotor": (4, "wide", [{"name": "exciter_rotor", "rotor_mass": 10.0}], False),
    "soft_cables": (4, "wide", [{"name": "cable_elasticity", "stiffness": 5.0e5}], False),
    "air_drag": (4, "wide", [{"name": "air_drag", "linear": 5000.0, "angular": 5000.0}], False),
    "sensor_delay": (4, "wide", [{"name": "sensor_delay", "stream": "load_cells", "delay": 0.02}], False),
    "load_cell_scale": (4, "wide", [{"name": "load_cell_scale", "cable": "c1", "scale": 1.03}], False),
    "pivot_friction": (4, "wide", [{"name": "pivot_friction", "mu_r": 1e-3}], False),
    "rotor_structural_mode": (4, "wide", [{"name": "exciter_rotor", "rotor_mass": 10.0},
                                          {"name": "structural_mode", "sensor": "imu", "frequency": 8.0,
                                           "damping_ratio": 0.03}], False),
}


def _rig_model_row(row: dict, rec, sim, t0: float) -> dict:
    """The row of the rig model (``rig-identify inertia``'s default): its verdict, the channels
    it does not fit (``failed``), the entries it gives, the extensions its diagnosis named (an
    extension's effect name: :data:`EFFECT_OF`) and the classes it did not tell apart."""
    from scoring import score_entries, worst

    from rig_identification.pipeline.rig_model import fit_whole_recording
    try:
        res = fit_whole_recording(rec)
    except ValueError as e:                     # a user error: refused, with its message
        row.update(verdict="refused", error=str(e), seconds=time.perf_counter() - t0)
        return row
    f = res.fit
    entries = score_entries(f.inertia, f.inertia_std, res.withheld, sim.truth["inertia_about_cg"])
    max_pct, max_z = worst(entries)
    row.update(verdict=res.verdict, failed=res.poorly_fitted,
               undetermined=list(dict.fromkeys(res.undetermined + res.ambiguous)),
               finite=all(e["finite"] for e in entries.values()), max_err_pct=max_pct, max_err_sigma=max_z,
               z=[e["z"] for e in entries.values() if e["finite"]], **_named(res.diagnosis), unexplained=[],
               truth_effects=[n for e in sim.truth.get("effects", [])
                              for n in (e["name"],) + CONTAINS.get(e["name"], ())],
               levels={c: float(v) for c, v in zip(f.channels, f.residual_level)},
               seconds=time.perf_counter() - t0)
    return json.loads(json.dumps(row, default=float))


#: The simulator's effect each rig-model extension stands for.
EFFECT_OF = {"load_cell_delay": "sensor_delay"}
#: What else a simulator's effect puts in the recording: a gyro bias that drifts from zero as a
#: random walk has a mean over the record, which the gyro reads as a constant bias (``gyro_bias``).
CONTAINS = {"gyro_bias_drift": ("gyro_bias",)}
#: The simulator's effects that the rig model holds as an unknown with a prior (a data error, not an
#: extension), and the label of that unknown (:func:`~rig_identification.estimation.rig_unknowns.labels`
#: less the cable's name): found where the diagnosis lists it among the data errors.
DATA_ERROR_OF = {"load_cell_scale": "load-cell gain"}


def _named(dg) -> dict:
    """``named`` (the extensions told apart, as effect names), ``classes`` (the candidates of
    each class not told apart), ``data_errors`` (the unknowns pulled off their prior, labels) and
    ``extensions`` (what the model holds, named or not) of a rig-model diagnosis (None: none)."""
    if dg is None:
        return {"named": [], "classes": [], "data_errors": [], "extensions": []}
    return {"named": [EFFECT_OF.get(e, e) for e in dg.named], "extensions": list(dg.extensions),
            "classes": [[EFFECT_OF.get(e, e) for e in g] for g in dg.classes],
            "data_errors": [c.unknown for c in dg.conflicts]}


def _job(args):
    name, seed, duration = args
    import warnings
    warnings.simplefilter("ignore")
    from dataclasses import replace

    from bench_crb import bound, channel_noise, truth_parameters

    from rig_identification.design.scenarios import simulate_random
    from rig_identification.estimation.rig_record import record
    from rig_identification.io.recording import Recording
    from rig_identification.model.parametrisation import entry_scales
    cables, layout, effects, clean, *rest = ROWS[name]
    exciter = rest[0] if rest else "corner"
    t0 = time.perf_counter()
    row = {"row": name, "seed": seed, "clean": clean}
    try:
        d, sim = simulate_random(seed, cables, layout, effects, duration, exciter=exciter)
    except Exception as e:                      # noqa: BLE001 — a rig the simulator cannot make is skipped
        row.update(skipped=f"{type(e).__name__}: {e}")
        return row
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    row["vehicle"] = d["description"]
    # determined: every entry's Cramér–Rao bound (the rig model's, at the truth) within ±1 % at 95 %
    try:
        rc = record(sim.sensors, sim.rig)
        crb = bound(replace(rc, sigma=channel_noise(rc.channels)), sim.rig, sim.truth)
        J, _ = truth_parameters(sim.rig, sim.truth)
        row["crb_percent"] = list(100 * crb / entry_scales(J))
        row["identifiable_truth"] = bool(1.96 * np.max(crb / entry_scales(J)) <= 0.01)
    except Exception as e:   # noqa: BLE001 — the bound is the bench's aid, not the tool's result
        row["identifiable_truth"] = None
        row["prediction_error"] = str(e)
    return _rig_model_row(row, rec, sim, t0)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2, help="random rigs per row (default 2)")
    ap.add_argument("--procs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--duration", type=float, default=90.0, help="seconds per recording (default 90)")
    ap.add_argument("--only", help="comma-separated rows (default all): " + ", ".join(ROWS))
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--json", metavar="FILE", help="also write the rows to FILE")
    a = ap.parse_args(argv)
    names = a.only.split(",") if a.only else list(ROWS)
    bad = set(names) - set(ROWS)
    if bad:
        ap.error(f"unknown rows {sorted(bad)}")
    jobs = [(n, 7000 + 100 * i + a.first_seed + k, a.duration)
            for i, n in enumerate(ROWS) if n in names for k in range(a.seeds)]
    t0 = time.perf_counter()
    rows = run_jobs(_job, jobs, a.procs, a.json, lambda r: f"{r['row']} seed {r['seed']}")
    print(f"{'row':22s} {'seed':>5s} {'verdict':17s} {'max|e|/σ':>8s} {'max e %':>8s}  failed checks / undetermined; "
          "named [data errors]; unexplained")
    for r in rows:
        if print_unscored(r, f"{r['row']:22s} {r['seed']:5d}", 17):
            continue
        es = "-" if r["max_err_sigma"] is None else f"{r['max_err_sigma']:.2f}"
        ep = "-" if r["max_err_pct"] is None else f"{r['max_err_pct']:.2f}"
        what = ",".join(r["failed"]) + (" | undetermined " + ",".join(r["undetermined"]) if r["undetermined"] else "")
        named = ",".join(r["named"] + ["(" + " or ".join(c) + ")" for c in r.get("classes", [])]
                         + [f"[{e}]" for e in r.get("data_errors", [])]) or "-"
        idt = {True: "", False: " [weak rig]", None: ""}[r.get("identifiable_truth")]
        print(f"{r['row']:22s} {r['seed']:5d} {r['verdict']:17s} {es:>8s} {ep:>8s}  {what}{idt}; {named}; "
              f"{len(r['unexplained'])} unexplained  ({r['seconds']:.0f} s)")
    done = [r for r in rows if "skipped" not in r and r["verdict"] != "refused"]
    silent = [r for r in done if r["verdict"] == "ok" and ((r["max_err_sigma"] or 0) > 3 or not r["finite"])]
    # a class not told apart is wrong when none of its candidates is in the recording
    wrong = [r for r in done if set(r["named"]) - set(r["truth_effects"])
             or any(not {p.split()[0] for x in c for p in x.split(" + ")} & set(r["truth_effects"])
                    for c in r.get("classes", []))]
    false_errors = [r for r in done if r["clean"] and r.get("data_errors")]
    as_error = [r for r in done if set(r["truth_effects"]) & set(DATA_ERROR_OF)]
    found_errors = [r for r in as_error if any(e.startswith(DATA_ERROR_OF[t]) for t in r["truth_effects"]
                                               if t in DATA_ERROR_OF for e in r.get("data_errors", []))]
    clean = [r for r in rows if r["clean"] and "skipped" not in r and r.get("identifiable_truth")]
    ok = [r for r in clean if r.get("verdict") == "ok"]
    good = [r for r in ok if r["max_err_pct"] is not None and r["max_err_pct"] <= 1.0 and r["max_err_sigma"] <= 3.0]
    weak = [r for r in rows if r["clean"] and "skipped" not in r and r.get("identifiable_truth") is False]
    print(f"\nsilent failures (ok and beyond 3 σ, or non-finite): {len(silent)}   [goal 0]")
    for r in silent:
        print(f"  {r['row']} seed {r['seed']}: {r['max_err_sigma']:.1f} σ, {r['max_err_pct']:.2f} %")
    print(f"wrong names: {len(wrong)}   [goal 0]")
    for r in wrong:
        print(f"  {r['row']} seed {r['seed']}: named {r['named']}, truth {r['truth_effects']}")
    print(f"data errors on clean recordings: {len(false_errors)}   [goal 0]")
    for r in false_errors:
        print(f"  {r['row']} seed {r['seed']}: {r['data_errors']}")
    if as_error:
        print(f"effects the model holds as a data error found as one: {len(found_errors)}/{len(as_error)}")
    if clean:
        print(f"clean recordings of rigs that determine the tensor (predicted σ ≤ half the limit, from the truth) "
              f"with verdict ok: {len(ok)}/{len(clean)} ({100 * len(ok) / len(clean):.0f} %) "
              f"[goal ≥ 95 %]; of them within 1 % and 3 σ: {len(good)}/{len(ok)}")
    if weak:
        named = [r for r in weak if r.get("verdict") == "not_identifiable"]
        print(f"clean recordings of rigs that leave an entry undetermined (predicted σ beyond half the limit): "
              f"{len(weak)}, verdict not_identifiable on {len(named)}, ok on "
              f"{sum(r.get('verdict') == 'ok' for r in weak)} (those within 3 σ: "
              f"{sum(r.get('verdict') == 'ok' and (r['max_err_sigma'] or 0) <= 3 for r in weak)})")
    # calibration of σ: the share of the entries given on clean recordings with verdict ok that
    # lie within ±1.96 σ of the truth (a calibrated σ: 95 %; goal 93-97 %)
    z_ok = [z for r in ok for z in r.get("z", [])]
    if z_ok:
        cover = float(np.mean(np.abs(z_ok) <= 1.96))
        print(f"coverage of ±1.96 σ over the {len(z_ok)} entries of the {len(ok)} clean recordings with verdict ok: "
              f"{100 * cover:.1f} %   [goal 93-97 %]; RMS of error/σ {np.sqrt(np.mean(np.square(z_ok))):.2f} [1 if "
              "calibrated]")
    zs = [r["max_err_sigma"] for r in rows if r.get("verdict") == "ok" and r.get("max_err_sigma") is not None]
    if zs:
        print(f"largest |error|/σ per recording with verdict ok: median {np.median(zs):.2f}, "
              f"{sum(z > 3 for z in zs)} of {len(zs)} beyond 3")
    print(f"refused: {sum(r.get('verdict') == 'refused' for r in rows)}, skipped: {sum('skipped' in r for r in rows)}; "
          f"total {time.perf_counter() - t0:.0f} s with {a.procs} processes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
