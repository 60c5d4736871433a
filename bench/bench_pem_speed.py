"""Speed of the prediction-error fit (issue 4) against a plain output-error fit as a user
would write it: scipy ``least_squares`` with finite-difference Jacobians, the Euler equation
integrated by ``solve_ivp`` from the measured moment at every residual evaluation.

Both fit the same 120 s, 200 Hz reference recording (visible_case16_clean) after the same
tracker and preprocessor, with the same band-pass on both sides; the table gives the wall
time of the fit alone and the largest error against truth.yaml.  A second table times the
whole gyro-only path of ``rig-identify inertia --model pem`` (``pipeline.identify_recording``:
cleaning, tracker, preprocessor, fit, validation).
Usage: bench_pem_speed.py [--no-naive]
"""
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt

from rig_identification.estimation.identification import identify_inertia
from rig_identification.estimation.preprocessor import preprocess
from rig_identification.estimation.tracker_replay import track
from rig_identification.io.recording import read_recording
from rig_identification.io.verdict import KEYS
from rig_identification.model.parametrisation import from_tensor, to_tensor

REC = Path(__file__).resolve().parents[2] / "shared" / "recordings" / "visible_case16_clean"


def naive_output_error(t, w, M, band, j0):
    fs = 1 / np.median(np.diff(t))
    sos = butter(4, band, btype="bandpass", fs=fs, output="sos")
    y = sosfiltfilt(sos, w, axis=0)

    def simulate(j):
        J = to_tensor(j)
        Ji = np.linalg.inv(J)
        rhs = lambda tt, x: Ji @ (np.array([np.interp(tt, t, M[:, k]) for k in range(3)])  # noqa: E731
                                  - np.cross(x, J @ x))
        sol = solve_ivp(rhs, (t[0], t[-1]), w[0], t_eval=t, rtol=1e-6, atol=1e-9)
        return sol.y.T

    def fun(j):
        return (y - sosfiltfilt(sos, simulate(j), axis=0)).ravel()

    return least_squares(fun, j0, method="trf", x_scale="jac").x


def main():
    rec = read_recording(REC)
    poses = track(rec.rig, rec.sensors)
    wr = preprocess(rec.rig, poses, rec.sensors)
    m = wr.t >= wr.t[0] + 5
    t, M = wr.t[m], wr.torque[m]
    w = rec.rig.imu.rotation.apply(rec.sensors.imu.interp(t)[:, :3])
    truth = np.array([rec.truth["inertia_about_cg"][k] for k in KEYS])
    big = truth[[0, 3, 5]].max()
    print(f"{'method':44s} {'fit s':>8s} {'max error % of largest moment':>30s}")
    t0 = time.perf_counter()
    res = identify_inertia(rec.rig, t, w, M)
    t1 = time.perf_counter()
    print(f"{'ours (prediction error, analytic Jacobian)':44s} {t1 - t0:8.2f} "
          f"{100 * np.abs(from_tensor(res.inertia) - truth).max() / big:30.3f}")
    if "--no-naive" not in sys.argv:
        t0 = time.perf_counter()
        j = naive_output_error(t, w, M, res.band_hz, from_tensor(res.inertia) * 1.05)
        t1 = time.perf_counter()
        print(f"{'naive least_squares, FD Jacobian, solve_ivp':44s} {t1 - t0:8.2f} "
              f"{100 * np.abs(j - truth).max() / big:30.3f}")
    from rig_identification.pipeline.offline import identify_recording
    print(f"\n{'whole path (recording in memory)':44s} {'s':>8s}")
    t0 = time.perf_counter()
    identify_recording(rec)
    print(f"{'identify_recording':44s} {time.perf_counter() - t0:8.2f}")


if __name__ == "__main__":
    main()
