"""Monte Carlo of the gyro-only prediction-error fit (``rig-identify inertia --model pem``): case 16
at the reference noise levels.

One noise-free simulation of config/rigs/default.yaml (thesis case 16, 200 Hz, 120 s); each
run adds fresh white noise at the reference recordings' levels (gyro 0.002 rad/s,
accelerometer 0.01 m/s², load cells and exciter 0.5 N, inclinometer 0.2 mrad) — the
simulator's own noise model — and replays tracker -> preprocessor -> identifier.
Prints per entry: bias / spread (the errors-in-variables bias of least squares on an input
carrying the gyro's noise through the tracked pose), spread / mean white-gyro bound
(``crb_std``), spread / mean reported σ, and the coverage of the reported 95 % intervals.
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
    return from_tensor(res.inertia), res.inertia_std, res.crb_std


def main(runs=200, procs=2, save=None):
    t0 = time.perf_counter()
    truth = clean_simulation().truth["inertia_about_cg"]
    true = np.array([truth[k] for k in KEYS])
    with Pool(procs) as pool:
        out = pool.map(one_run, range(runs))
    est = np.array([o[0] for o in out])
    std = np.array([o[1] for o in out])
    crb = np.array([o[2] for o in out])
    if save:
        np.savez(save, est=est, std=std, crb=crb, truth=true)
    err = est - true
    spread = err.std(0, ddof=1)
    print(f"Monte Carlo, case 16 at the reference noise levels: {runs} runs, {time.perf_counter() - t0:.0f} s")
    print(f"{'entry':5s} {'truth':>9s} {'bias':>9s} {'spread':>8s} {'bias/spread':>11s} "
          f"{'spread/CRB':>10s} {'spread/std':>10s} {'95% cover':>9s}")
    for i, k in enumerate(KEYS):
        cover = np.mean(np.abs(err[:, i]) <= 1.96 * std[:, i])
        print(f"{k:5s} {true[i]:9.1f} {err[:, i].mean():+9.3f} {spread[i]:8.3f} {err[:, i].mean() / spread[i]:+11.3f} "
              f"{spread[i] / crb[:, i].mean():10.3f} {spread[i] / std[:, i].mean():10.3f} {100 * cover:8.1f}%")
    n = len(err)
    print(f"(95 % coverage from {n} runs has a sampling σ of {100 * np.sqrt(0.95 * 0.05 / n):.1f} points; "
          f"bias/spread one of {1 / np.sqrt(n):.2f})")


if __name__ == "__main__":
    a = sys.argv[1:]
    main(*(int(x) for x in a[:2]), *a[2:3])
