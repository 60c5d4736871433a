"""Replay speed and accuracy of `rig-identify inertia` on the reference recordings.

Prints one row per recording: read, track, preprocess, identify and total seconds, and the
largest error (% of the entry for diagonals, % of the largest diagonal for products) and
the largest |error| / reported std.  Issue 2's budget: a 120 s, 200 Hz recording in < 20 s.
"""
import sys
import time
from pathlib import Path

from rig_identification.estimation.identification import identify_inertia
from rig_identification.estimation.inertia_result import compare_to_truth
from rig_identification.estimation.preprocessor import preprocess
from rig_identification.estimation.tracker_replay import track
from rig_identification.io.recording import read_recording

SHARED = Path(__file__).resolve().parents[2] / "shared" / "recordings"


def main(names):
    print(f"{'recording':24s} {'read':>6s} {'track':>6s} {'wrench':>6s} {'fit':>6s} {'total':>6s} "
          f"{'max err %':>9s} {'max err/std':>11s}")
    for name in names:
        t0 = time.perf_counter()
        rec = read_recording(SHARED / name)
        t1 = time.perf_counter()
        poses = track(rec.rig, rec.sensors)
        t2 = time.perf_counter()
        w = preprocess(rec.rig, poses, rec.sensors)
        t3 = time.perf_counter()
        m = w.t >= w.t[0] + 5.0
        gyro = rec.rig.imu.rotation.apply(rec.sensors.imu.interp(w.t[m])[:, :3])
        res = identify_inertia(rec.rig, w.t[m], gyro, w.torque[m])
        t4 = time.perf_counter()
        cmp = compare_to_truth(res, rec.truth)
        err = max(abs(c["error_percent"]) for c in cmp.values())
        sig = max(abs(c["error_sigma"]) for c in cmp.values())
        print(f"{name:24s} {t1 - t0:6.2f} {t2 - t1:6.2f} {t3 - t2:6.2f} {t4 - t3:6.2f} {t4 - t0:6.2f} "
              f"{err:9.3f} {sig:11.2f}")


if __name__ == "__main__":
    main(sys.argv[1:] or ["visible_case16_clean", "visible_case14_clean"])
