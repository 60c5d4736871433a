"""Monte Carlo of the inertia identification (issue 4): case 16 at the reference noise levels.

One noise-free simulation of config/rigs/default.yaml (thesis case 16, 200 Hz, 120 s); each
run adds fresh white noise at the reference recordings' levels (gyro 0.002 rad/s,
accelerometer 0.01 m/s², load cells and exciter 0.5 N, inclinometer 0.2 mrad) — the
simulator's own noise model — and replays tracker -> preprocessor -> identifier.
Prints per entry: bias / spread (also without the second-order bias correction), spread /
mean Cramér–Rao std (``crb_std``: the sensors' noise, estimated from each run, propagated
through tracker, preprocessor and identifier), spread / mean reported std, and the coverage
of the reported 95 % intervals (also of the identifier's own sandwich σ).
Usage: bench_montecarlo_inertia.py [RUNS=200] [PROCESSES=2] [SAVE.npz]
"""
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np
import yaml

from rig_identification.estimation.uncertainty import add_noise
from rig_identification.io.recording import Recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import REFERENCE_NOISE, experiment_from_dict
from rig_identification.model.parametrisation import from_tensor
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.offline import identify_recording

DEFAULT = Path(__file__).resolve().parents[1] / "config" / "rigs" / "default.yaml"
_SIM = None


def clean_simulation():
    d = yaml.safe_load(DEFAULT.read_text())
    d["rig"].pop("dummy_mass", None)
    d["sensors"]["noise"] = {k: 0.0 for k in d["sensors"]["noise"]}
    return simulate(experiment_from_dict(d, "monte carlo"))


def one_run(seed):
    global _SIM
    if _SIM is None:
        _SIM = clean_simulation()
    rng = np.random.default_rng(seed)
    res = identify_recording(Recording(_SIM.rig, add_noise(_SIM.sensors, REFERENCE_NOISE, rng), _SIM.truth))
    bias = res.bias_correction if res.bias_correction is not None else np.zeros(6)
    return from_tensor(res.inertia), res.inertia_std, res.crb_std, bias, res.sandwich_std


def main(runs=200, procs=2, save=None):
    t0 = time.perf_counter()
    truth = clean_simulation().truth["inertia_about_cg"]
    true = np.array([truth[k] for k in KEYS])
    with Pool(procs) as pool:
        out = pool.map(one_run, range(runs))
    est = np.array([o[0] for o in out])
    std = np.array([o[1] for o in out])
    crb = np.array([o[2] for o in out])
    corr = np.array([o[3] for o in out])
    sand = np.array([o[4] if o[4] is not None else o[1] for o in out])
    if save:
        np.savez(save, est=est, std=std, crb=crb, correction=corr, sandwich=sand, truth=true)
    err = est - true
    err0 = err + corr   # without the second-order bias correction
    spread = err.std(0, ddof=1)
    print(f"Monte Carlo, case 16 at the reference noise levels: {runs} runs, {time.perf_counter() - t0:.0f} s")
    print(f"{'entry':5s} {'truth':>9s} {'bias':>9s} {'spread':>8s} {'bias/spread':>11s} {'uncorrected':>11s} "
          f"{'spread/CRB':>10s} {'spread/std':>10s} {'95% cover':>9s} {'sandwich':>9s}")
    for i, k in enumerate(KEYS):
        cover = np.mean(np.abs(err[:, i]) <= 1.96 * std[:, i])
        cover_s = np.mean(np.abs(err0[:, i]) <= 1.96 * sand[:, i])
        print(f"{k:5s} {true[i]:9.1f} {err[:, i].mean():+9.3f} {spread[i]:8.3f} {err[:, i].mean() / spread[i]:+11.3f} "
              f"{err0[:, i].mean() / err0[:, i].std(ddof=1):+11.3f} "
              f"{spread[i] / crb[:, i].mean():10.3f} {spread[i] / std[:, i].mean():10.3f} {100 * cover:8.1f}% "
              f"{100 * cover_s:8.1f}%")
    n = len(err)
    print(f"(95 % coverage from {n} runs has a sampling σ of {100 * np.sqrt(0.95 * 0.05 / n):.1f} points; "
          f"bias/spread one of {1 / np.sqrt(n):.2f})")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(*(int(x) for x in a[:2]), *a[2:3])
