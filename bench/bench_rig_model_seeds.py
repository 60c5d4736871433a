"""The rig model's errors against its σ over noise seeds of one rig: is σ calibrated there?

One experiment file (default: thesis case 16 as the reference recordings run it — the exciter
spun up over 2 s, 120 s, IMU, load cells and exciter at 200 Hz, inclinometer at 50 Hz, the
reference noise, the cables' damping of the reference recordings) simulated by the package with
``--seeds`` noise seeds, each fitted by ``rig-identify inertia --model rig``
(:func:`~rig_identification.pipeline.rig_model.fit_whole_recording`).  Prints per seed the
verdict, the mass's error, each tensor entry's error in σ and the largest channel's residual
level, then the RMS of error/σ per entry over the seeds (1 where σ is calibrated).

    python bench/bench_rig_model_seeds.py --seeds 4
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from rig_identification.io.recording import Recording
from rig_identification.io.rig import inertia_tensor, read_yaml
from rig_identification.io.verdict import KEYS
from rig_identification.model.experiment import (
    REFERENCE_NOISE,
    REFERENCE_RATES,
    ExperimentError,
    experiment_from_dict,
)
from rig_identification.model.parametrisation import entry_scales, from_tensor
from rig_identification.model.simulator import simulate
from rig_identification.pipeline.rig_model import fit_whole_recording

#: What the reference recordings' case 16 changes of ``config/cases/case16.yaml`` beside their
#: sensors (REFERENCE_RATES, REFERENCE_NOISE).
REFERENCE_RUN = {
    "duration": 120.0,
    "ramp_time": 2.0,
    "cable_damping": 951.3148795220224,
}


def reference_like(d: dict, exciter_noise: float | None, noise_scale: float = 1.0) -> dict:
    """The experiment mapping ``d`` run as the reference recordings are (:data:`REFERENCE_RUN`),
    every sensor's noise σ times ``noise_scale``."""
    d = dict(d)
    d["duration"] = REFERENCE_RUN["duration"]
    d["cable_model"] = dict(d.get("cable_model") or {"type": "spring"}, damping=REFERENCE_RUN["cable_damping"])
    ex = {k: dict(v) for k, v in d["excitation"].items()}
    ex["rotating"]["ramp_time"] = REFERENCE_RUN["ramp_time"]
    d["excitation"] = ex
    noise = {k: v * noise_scale for k, v in REFERENCE_NOISE.items()}
    if exciter_noise is not None:
        noise["exciter"] = exciter_noise
    d["sensors"] = {"rates_hz": dict(REFERENCE_RATES), "noise": noise}
    return d


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--experiment", default="config/cases/case16.yaml", help="experiment file (a rotating exciter)")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--first-seed", type=int, default=1)
    ap.add_argument("--exciter-noise", type=float, help="the exciter's noise σ, N (default the reference's 0.5)")
    ap.add_argument("--noise-scale", type=float, default=1.0,
                    help="every sensor's noise σ times this (0.01: the estimator's bias shows beside its σ)")
    args = ap.parse_args(argv)
    try:
        base = reference_like(read_yaml(args.experiment, ExperimentError, "experiment file"), args.exciter_noise,
                              args.noise_scale)
    except (ExperimentError, KeyError) as e:
        print(f"{args.experiment}: {e}", file=sys.stderr)
        return 2
    print(f"{'seed':>4} {'verdict':<18} {'mass err kg':>11} {'±σ':>6} "
          + " ".join(f"{k + ' err/σ':>11}" for k in KEYS) + f" {'worst %':>8} {'worst level':>11} {'s':>5}")
    z_all = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        d = dict(base, seed=seed)
        sim = simulate(experiment_from_dict(d, args.experiment))
        rec = Recording(sim.rig, sim.sensors, sim.truth, None)
        t = time.perf_counter()
        res = fit_whole_recording(rec)
        fit = res.fit
        J = from_tensor(inertia_tensor(sim.truth["inertia_about_cg"]))
        z = (fit.inertia - J) / fit.inertia_std
        z_all.append(z)
        sd = float(np.sqrt(fit.covariance[fit.layout.mass, fit.layout.mass]))
        worst = int(np.argmax(fit.residual_level))
        print(f"{seed:>4} {res.verdict:<18} {fit.parameters.mass - sim.truth['mass']:>+11.3f} {sd:>6.3f} "
              + " ".join(f"{v:>+11.1f}" for v in z)
              + f" {np.max(np.abs(fit.inertia - J) / entry_scales(J)) * 100:>8.4f}"
              + f" {fit.channels[worst]:>7} {fit.residual_level[worst]:.2f} {time.perf_counter() - t:>5.0f}",
              flush=True)
    rms = np.sqrt(np.mean(np.square(z_all), axis=0))
    print(f"{'RMS of error/σ over the seeds':<43} " + " ".join(f"{v:>11.1f}" for v in rms))
    return 0


if __name__ == "__main__":
    sys.exit(main())
