"""Which sensor's noise biases the identified tensor when an axis hardly moves?

Usage: python bench/bench_noise_paths.py [--seed S] [--duration S] [--angular C]

One random rig of the trust benchmark (:mod:`rig_identification.scenarios`, 4 wide cables)
with viscous angular damping C N·m·s/rad concealed (default 300: it damps the roll pendulum
mode, so roll hardly moves), identified the ordinary way (``identify_recording``) with the
TRUE damping moment −C ω (ω from the simulator's states, noise-free) added to the measured
wrench — the model is then complete.  The sensor noise is the reference (`REFERENCE_NOISE`)
scaled by 0.1, with one sensor at a time left at the reference, then all at the reference.
Prints per case: verdict, failed checks, the entries' error % and error/σ, and the
second-order bias correction the noise replays measured (SIMEX, ``bias_correction``) on Ixx.

What it shows (docs/results.md): the output-error fit is unbiased for noise on its output
(the gyro as measured), but the gyro also drives the tracker's orientation, whose cable
directions make the measured moment: gyro noise reaches the input too (errors in variables)
and biases the entries whose axis moves little.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig_identification.diagnosis import EffectWrench  # noqa: E402
from rig_identification.identification import KEYS  # noqa: E402
from rig_identification.pipeline import compare_to_truth, identify_recording  # noqa: E402
from rig_identification.recording import Recording  # noqa: E402
from rig_identification.scenarios import REFERENCE_NOISE, simulate_random  # noqa: E402


def run(seed: int, duration: float, angular: float, noise: dict) -> str:
    _, sim = simulate_random(seed, 4, "wide", [{"name": "viscous_damping", "angular": angular}], duration, noise=noise)
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    st = sim.states
    wrench = EffectWrench(st.t, -angular * st.omega, np.zeros_like(st.omega), ("viscous_damping",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = identify_recording(rec, effect_wrench=wrench)
    c = compare_to_truth(r, sim.truth)
    v = r.validation
    entries = " ".join(f"{k} {c[k]['error_percent']:+6.2f}% ({c[k]['error_sigma']:+5.1f}σ)" for k in KEYS)
    bias = "-" if r.bias_correction is None else f"{100 * r.bias_correction[0] / sim.truth['inertia_about_cg']['ixx']:+.2f}%"
    return f"{v.verdict:17s} {','.join(v.failed) or '-':24s} SIMEX ixx {bias:>8s}  {entries}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=8200, help="random rig (default 8200: the trust benchmark's "
                    "first viscous-damping rig)")
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--angular", type=float, default=300.0, help="angular damping, N·m·s/rad")
    a = ap.parse_args(argv)
    cases = [("all ×0.1", {k: 0.1 * v for k, v in REFERENCE_NOISE.items()})]
    for s in ("gyro", "load_cell", "accelerometer", "exciter"):
        cases.append((f"×0.1, {s} ×1", {k: (1.0 if k == s else 0.1) * v for k, v in REFERENCE_NOISE.items()}))
    cases.append(("all ×1 (reference)", dict(REFERENCE_NOISE)))
    print(f"seed {a.seed}, {a.duration:g} s, angular damping {a.angular:g} N·m·s/rad, the true damping moment in "
          "the model")
    for label, noise in cases:
        print(f"{label:22s} {run(a.seed, a.duration, a.angular, noise)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
