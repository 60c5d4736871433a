"""Which sensor's noise biases the identified tensor when an axis hardly moves?

Usage: python bench/bench_noise_paths.py [--seed S] [--duration S] [--angular C] [--paths]

One random rig of the trust benchmark (:mod:`rig_identification.design.scenarios`, 4 wide cables)
with viscous angular damping C N·m·s/rad concealed (default 300: it damps the roll pendulum
mode, so roll hardly moves), identified the ordinary way (``identify_recording``) with the
TRUE damping moment −C ω (ω from the simulator's states, noise-free) added to the measured
wrench — the model is then complete.  The sensor noise is the reference (`REFERENCE_NOISE`)
scaled by 0.1, with one sensor at a time left at the reference, then all at the reference.
Prints per case: verdict, failed checks (and, below, what each failed check saw), the share of
the fit's input that is noise along its noisiest direction (``errors_in_variables.share``),
Ixx's error of the least-squares fit before the compensation for that noise, and the reported
(compensated) entries' error % and error/σ.

With --paths, instead: at the reference noise, the plain least-squares fit (no compensation,
stage 1 of the identifier with the consistent Levenberg–Marquardt stage) with the tracked
pose, with the simulator's true pose (the measured gyro as output), with the true pose and
the true ω; and with extra white gyro noise of λ times its variance (λ = 1, 2, 4; two
antithetic pairs each) — the curve SIMEX extrapolates.

What it shows (docs/results.md): the output-error fit is unbiased for noise on its output
(the gyro as measured), but the gyro also drives the tracker's orientation, whose cable
directions make the measured moment: gyro noise reaches the input too (errors in variables)
and biases the entries whose axis moves little — unless the fit is compensated for it
(:mod:`rig_identification.estimation.errors_in_variables`), as it now is.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig_identification.design.scenarios import REFERENCE_NOISE, simulate_random  # noqa: E402
from rig_identification.diagnosis.result import EffectWrench  # noqa: E402
from rig_identification.estimation.identification import identify_inertia  # noqa: E402
from rig_identification.estimation.preprocessor import generalized_wrench  # noqa: E402
from rig_identification.estimation.uncertainty import add_noise, sensor_noise  # noqa: E402
from rig_identification.io.recording import Recording  # noqa: E402
from rig_identification.io.verdict import KEYS
from rig_identification.pipeline.offline import compare_to_truth, identify_recording
from rig_identification.pipeline.prepare import prepare_recording, replay_window, with_effect_wrench


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
    ixx = sim.truth["inertia_about_cg"]["ixx"]
    # the least-squares fit before the compensation: the compensated entries plus the bias removed
    ls = "-" if r.bias_correction is None else f"{c['ixx']['error_percent'] + 100 * r.bias_correction[0] / ixx:+7.2f}%"
    share = "-" if r.errors_in_variables is None else f"{r.errors_in_variables.share:.3f}"
    entries = " ".join(f"{k} {c[k]['error_percent']:+6.2f}% ({c[k]['error_sigma']:+5.1f}σ)" for k in KEYS)
    failed = "".join(f"\n    {c.name}: {c.detail}" for c in v.checks if c.passed is False)
    return (f"{v.verdict:17s} {','.join(v.failed) or '-':24s} noise share {share:>5s}  "
            f"LS ixx {ls:>8s}  {entries}{failed}")


def paths(seed: int, duration: float, angular: float) -> None:
    """The --paths table (module docstring): Ixx error % of the least-squares fit."""
    _, sim = simulate_random(seed, 4, "wide", [{"name": "viscous_damping", "angular": angular}], duration,
                             noise=dict(REFERENCE_NOISE))
    rec = Recording(sim.rig, sim.sensors, sim.truth, None)
    st = sim.states
    prep = with_effect_wrench(prepare_recording(rec),
                              EffectWrench(st.t, -angular * st.omega, np.zeros_like(st.omega), ("viscous_damping",)))
    rig, s = rec.rig, prep.sensors
    ixx = sim.truth["inertia_about_cg"]["ixx"]

    def err(omega, torque, band=None):
        return 100 * (identify_inertia(rig, prep.t, omega, torque, band_hz=band).inertia[0, 0] - ixx) / ixx

    rot = Slerp(st.t, Rotation.from_quat(st.quaternion))(prep.t)
    pos = np.column_stack([np.interp(prep.t, st.t, st.position[:, i]) for i in range(3)])
    tens = np.column_stack([np.interp(prep.t, s.load_cells[n].t, s.load_cells[n].data[:, 0]) for n in rig.cable_names])
    exc = s.exciter.interp(prep.t) if s.exciter is not None else None
    true_torque = generalized_wrench(rig, pos, rot.as_quat(), tens, exc)[1] + prep.extra_torque
    true_omega = np.column_stack([np.interp(prep.t, st.t, st.omega[:, i]) for i in range(3)])
    band = identify_inertia(rig, prep.t, prep.gyro_body, prep.torque).band_hz
    print(f"seed {seed}, {duration:g} s, angular damping {angular:g} N·m·s/rad, the true damping moment in the "
          "model, the reference noise; least squares, Ixx error:")
    print(f"  tracked pose (as the identifier)      {err(prep.gyro_body, prep.torque, band):+7.2f} %")
    print(f"  the simulator's true pose             {err(prep.gyro_body, true_torque, band):+7.2f} %")
    print(f"  the true pose and the true ω          {err(true_omega, true_torque, band):+7.2f} %")
    noise, _ = sensor_noise(rig, s)
    for lam in (1, 2, 4):
        out = []
        for k in range(2):
            for sign in (1.0, -1.0):
                extra = {key: 0.0 for key in noise} | {"gyro": np.sqrt(lam) * noise["gyro"]}
                rp = replay_window(rig, add_noise(s, extra, np.random.default_rng([k, 7]), sign), *prep.window)
                if len(rp.t) == len(prep.t):
                    out.append(err(rp.gyro_body, rp.torque + prep.extra_torque, band))
        print(f"  tracked pose, extra gyro noise λ = {lam}  {np.mean(out):+7.2f} %")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=8200, help="random rig (default 8200: the trust benchmark's "
                    "first viscous-damping rig)")
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--angular", type=float, default=300.0, help="angular damping, N·m·s/rad")
    ap.add_argument("--paths", action="store_true", help="the noise's paths, least squares (module docstring)")
    a = ap.parse_args(argv)
    if a.paths:
        paths(a.seed, a.duration, a.angular)
        return 0
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
