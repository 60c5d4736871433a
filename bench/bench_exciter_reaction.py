"""The exciter's readings against the body's acceleration: is the rotor's reaction in them?

The exciter measures the force its bearing puts on the body: the unbalanced mass's centripetal
force and, where the rotor's mass is not negligible, its reaction to the body's own
acceleration, −m_r·a.  The rig model takes the force's smooth rotating part as its input and
its readings as an output without that term.  For each recording this prints the slope (kg) of
the readings' departure from the denoised force (:func:`~rig_identification.estimation.rig_record.record`)
on the accelerometer's x and y, both band-passed to the swing (``--band``), with the correlation
and the share of the departure it explains: a rotor of mass m_r gives a slope near −m_r.  The
accelerometer stands for the exciter point's acceleration (the lever arm left out).

    python bench/bench_exciter_reaction.py ../shared/recordings/visible_effect_exciter_rotor \\
        ../shared/recordings/visible_case16_clean
"""
from __future__ import annotations

import argparse

import numpy as np
from scipy.signal import butter, sosfiltfilt

from rig_identification.estimation.rig_record import record
from rig_identification.io.quality import clean_sensors
from rig_identification.io.recording import read_recording


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("recordings", nargs="+")
    ap.add_argument("--band", type=float, nargs=2, default=(0.2, 0.9), metavar=("LOW_HZ", "HIGH_HZ"))
    a = ap.parse_args(argv)
    print("| recording | axis | slope kg | correlation | departure RMS N | left RMS N |")
    print("|---|---|---|---|---|---|")
    for path in a.recordings:
        rec = read_recording(path)
        rc = record(clean_sensors(rec, []), rec.rig, None, None)
        ch = list(rc.channels)
        if "exciter_x" not in ch:
            print(f"| {path} | — | the exciter's force is not an output |")
            continue
        y, u = rc.y[rc.start:], rc.u[rc.start:]
        sos = butter(4, a.band, btype="band", fs=1.0 / rc.dt, output="sos")
        for j, axis in enumerate("xy"):
            r = sosfiltfilt(sos, y[:, ch.index(f"exciter_{axis}")] - u[:, j])
            acc = sosfiltfilt(sos, y[:, ch.index(f"accel_{axis}")])
            slope = float(acc @ r / (acc @ acc))
            print(f"| {rec.path.name} | {axis} | {slope:.2f} | {np.corrcoef(r, acc)[0, 1]:+.2f} | {r.std():.3f} | "
                  f"{(r - slope * acc).std():.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
