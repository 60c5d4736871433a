"""The information limit of a rig and run: the Cramér–Rao bound of the tensor, and the rig model's fit against it.

Usage: python bench/bench_crb.py [--rigs N] [--first-seed S] [--duration S] [--no-fit] [--json FILE]
       python bench/bench_crb.py --recording DIR [DIR ...]

Random rigs (default 6) of the package's own simulator (:mod:`rig_identification.design.scenarios`:
NHTSA vehicles in carrying frames, 3–6 cables, the five layouts, the exciter placements; reference
noise).  For each rig the bound is computed under the fit's own nuisance model
(:func:`~rig_identification.estimation.rig_fit.cramer_rao`: the rig model's Fisher information at the
true parameters along the noise-free run, each channel at the reference noise; mass under the
scale's σ, CG free, per-cable stiffness and gain under their priors, the damping time and the
initial state free, every anchor coordinate and cable length under a 1 mm survey prior).  Then the
noisy recording is identified by ``rig-identify inertia --model rig``'s core
(:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`), and its errors and σ are
judged against the truth and the bound.

With ``--recording``: the bound of each recording with a truth.yaml (its own input and noise levels,
at the true tensor, mass and CG; cable stiffness and damping from truth.yaml) beside the fit.

Printed per rig: cables, layout, exciter placement; the worst entry's bound in % (1 σ; products of
the largest moment); for the fit: the verdict on its residual, the largest error %, the largest
|error|/σ, the σ/CRB range.  Then: the share of rigs the bound determines to ±1 % at 95 %, how many of
those the fit gets within 1 % and 3 σ, σ within 2× of the bound (share of entries), the coverage
of ±1.96 σ, and silent failures (an entry beyond 3 σ with no channel said to misfit).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace

import numpy as np

from rig_identification.design import information
from rig_identification.design.scenarios import EXCITER_PLACEMENTS, LAYOUTS, REFERENCE_NOISE, simulate_random
from rig_identification.estimation.rig_record import record
from rig_identification.io.recording import Recording, read_recording
from rig_identification.io.rig import inertia_tensor
from rig_identification.io.verdict import KEYS
from rig_identification.model.linear_rig import RigParameters
from rig_identification.model.parametrisation import entry_scales, from_tensor
from rig_identification.model.rigid_body import SimulationError
from rig_identification.pipeline.rig_model import fit_whole_recording

QUIET = {k: 0.0 for k in REFERENCE_NOISE}


def channel_noise(channels) -> np.ndarray:
    """The reference noise σ per channel of the rig model."""
    return information.channel_noise(channels, REFERENCE_NOISE)


def truth_parameters(rig, truth: dict) -> tuple[np.ndarray, RigParameters]:
    """The true tensor entries (6,) and the rig model's true parameters of a truth mapping."""
    return from_tensor(inertia_tensor(truth["inertia_about_cg"])), information.true_parameters(rig, truth)


def bound(rec_record, rig, truth: dict) -> np.ndarray:
    """The tensor entries' bound (6,) kg·m² (1 σ) of the record ``rec_record`` of ``rig`` at the
    truth mapping ``truth`` (truth.yaml's)."""
    p = information.true_parameters(rig, truth)
    return np.sqrt(np.diag(information.record_covariance(rec_record, rig, p)))


def judge(J: np.ndarray, crb: np.ndarray, rec: Recording | None) -> dict:
    row = {"crb_percent": (100 * crb / entry_scales(J)).tolist()}
    if rec is None:
        return row
    t = time.perf_counter()
    res = fit_whole_recording(rec)
    f = res.fit
    err = f.inertia - J
    row.update(error_percent=(100 * err / entry_scales(J)).tolist(), error_sigma=(err / f.inertia_std).tolist(),
               sigma_over_crb=(f.inertia_std / crb).tolist(), poorly_fitted=res.poorly_fitted,
               verdict=res.verdict, undetermined=res.undetermined, ambiguous=res.ambiguous,
               start_error_sigma=((res.inertia_start - J) / res.start_std).tolist(), seconds=time.perf_counter() - t)
    return row


def line(name: str, row: dict) -> str:
    s = f"{name:<34} CRB worst {max(row['crb_percent']):7.3f} %"
    if row.get("verdict") == "failed":
        s += f" | fit failed ({len(row['poorly_fitted'])} channels beyond their noise)  {row['seconds']:.0f} s"
    elif "error_percent" in row:
        soc = row["sigma_over_crb"]
        s += (f" | err max {max(np.abs(row['error_percent'])):6.3f} %  "
              f"|err/σ| max {max(np.abs(row['error_sigma'])):5.2f}"
              f"  σ/CRB {min(soc):.2f}–{max(soc):.2f}  {row['verdict']}  misfit {','.join(row['poorly_fitted']) or '-'}"
              f"  {row['seconds']:.0f} s")
        for k in row.get("ambiguous", []):
            i = list(KEYS).index(k)
            s += f"\n{'':<34} {k} ambiguous: the rig model {row['error_sigma'][i]:+.1f} σ, the gyro-only start " \
                 f"{row['start_error_sigma'][i]:+.1f} σ from the truth"
    return s


def summary(rows: list[dict]) -> None:
    det = [r for r in rows if 1.96 * max(r["crb_percent"]) <= 1.0]
    print(f"\nrigs the bound determines to ±1 % at 95 %: {len(det)}/{len(rows)}")
    fitted = [r for r in rows if "error_percent" in r and r["verdict"] != "failed"]
    failed = [r["name"] for r in rows if r.get("verdict") == "failed"]
    print(f"fits failed (said so): {len(failed)} {' '.join(failed)}")
    if not fitted:
        return
    good = [r for r in det if "error_percent" in r and r["verdict"] == "ok" and max(np.abs(r["error_percent"])) <= 1
            and max(np.abs(r["error_sigma"])) <= 3]
    print(f"  of those, the fit ok and within 1 % and 3 σ on every entry: {len(good)}/"
          f"{len([r for r in det if 'error_percent' in r])}")
    ok = [r for r in fitted if r["verdict"] == "ok"] or fitted
    z = np.concatenate([r["error_sigma"] for r in ok])
    soc = np.concatenate([r["sigma_over_crb"] for r in ok])
    print("verdicts: " + ", ".join(f"{v} {sum(r.get('verdict') == v for r in rows)}" for v in
                                    ("ok", "model_error", "not_identifiable", "inconsistent", "failed")))
    print(f"over the ok fits: σ within 2× of the bound: {np.mean(soc <= 2):.1%} of {len(soc)} entries")
    print(f"coverage of ±1.96 σ: {np.mean(np.abs(z) <= 1.96):.1%} of {len(z)} entries; "
          f"RMS error/σ {np.sqrt(np.mean(z ** 2)):.2f}")
    silent = [r["name"] for r in fitted if r["verdict"] == "ok" and any(
        abs(z) > 3 for k, z in zip(KEYS, r["error_sigma"]) if k not in r["undetermined"])]
    print(f"silent failures (verdict ok, a determined entry beyond 3 σ): {len(silent)} {' '.join(silent)}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rigs", type=int, default=6)
    ap.add_argument("--first-seed", type=int, default=31000)
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--no-fit", action="store_true", help="the bound only")
    ap.add_argument("--recording", nargs="+", metavar="DIR", help="recordings with truth.yaml instead of random rigs")
    ap.add_argument("--json", metavar="FILE")
    args = ap.parse_args(argv)
    rows = []
    if args.recording:
        for path in args.recording:
            rec = read_recording(path)
            J, _ = truth_parameters(rec.rig, rec.truth)
            crb = bound(record(rec.sensors, rec.rig), rec.rig, rec.truth)
            row = judge(J, crb, None if args.no_fit else rec)
            row["name"] = path
            rows.append(row)
            print(line(path.rstrip("/").split("/")[-1], row), flush=True)
    else:
        for seed in range(args.first_seed, args.first_seed + args.rigs):
            cables = 3 + (seed % 4)
            layout = LAYOUTS[seed % len(LAYOUTS)]
            exciter = EXCITER_PLACEMENTS[(seed // 5) % len(EXCITER_PLACEMENTS)]
            name = f"{seed} {cables} {layout} {exciter}"
            try:
                _, quiet = simulate_random(seed, cables, layout, duration=args.duration, noise=QUIET, exciter=exciter)
                rc = record(quiet.sensors, quiet.rig)
                rc = replace(rc, sigma=channel_noise(rc.channels))
                J, _ = truth_parameters(quiet.rig, quiet.truth)
                crb = bound(rc, quiet.rig, quiet.truth)
                rec = None
                if not args.no_fit:
                    _, noisy = simulate_random(seed, cables, layout, duration=args.duration, exciter=exciter)
                    rec = Recording(noisy.rig, noisy.sensors, noisy.truth, None)
                row = judge(J, crb, rec)
            except SimulationError as e:
                print(f"{name:<34} skipped: {e}", flush=True)
                continue
            row["name"] = name
            rows.append(row)
            print(line(name, row), flush=True)
    summary(rows)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"rows": rows, "keys": list(KEYS)}, fh)
    return 0


if __name__ == "__main__":
    sys.exit(main())
