"""Where in frequency does a fit's residual exceed what the noise explains?

Usage: python bench/bench_residual_spectrum.py ROW SEED [--duration S] [--every K]

One recording of the trust benchmark (``bench_trust.py``'s ROW and SEED: the same random rig
of :mod:`rig_identification.design.scenarios`), identified the ordinary way (``identify_recording``:
the fit compensated for the noise in its input, validated).  Prints the residual excess per
gyro axis (``residual_excess``), then, on the axis with the largest, per frequency of the fit
band (Welch, 2048 samples, every K-th bin): the residual's spectral level over the one the
replays' residual realisations give (the noise's residual, every path included) and the
measured output's level over the same noise level (the signal-to-noise ratio there).  A
residual excess at one frequency where the signal is 10⁵ times the noise is a misfit of a
fraction of a percent of the motion there; a broadband one is the noise's prediction missing.
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.signal import welch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bench_trust import ROWS  # noqa: E402

from rig_identification.design.scenarios import simulate_random  # noqa: E402
from rig_identification.io.recording import Recording  # noqa: E402
from rig_identification.pipeline.offline import identify_recording  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("row", choices=sorted(ROWS))
    ap.add_argument("seed", type=int)
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--every", type=int, default=3, help="print every K-th Welch bin (default 3)")
    a = ap.parse_args(argv)
    cables, layout, effects, _clean, *rest = ROWS[a.row]
    _, sim = simulate_random(a.seed, cables, layout, effects, a.duration, exciter=rest[0] if rest else "corner")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = identify_recording(Recording(sim.rig, sim.sensors, sim.truth, None))
    print(f"{a.row} seed {a.seed}: verdict {r.validation.verdict} ({', '.join(r.validation.failed) or '-'}); "
          f"residual over the noise's, gyro x y z: {' '.join(f'{x:.2f}' for x in r.residual_excess)}")
    s = r.series[0]
    if s.noise_residual is None:
        print("no noise realisations (the fit was not compensated)")
        return 1
    f, Pr = welch(s.residual, fs=s.fs, nperseg=2048, axis=0)
    Pn = np.mean([welch(x, fs=s.fs, nperseg=2048, axis=0)[1] for x in s.noise_residual], axis=0)
    Py = welch(s.measured, fs=s.fs, nperseg=2048, axis=0)[1]
    lo, hi = s.band_hz
    m = (f >= lo) & (f <= hi)
    ax = int(np.argmax(r.residual_excess))
    print(f"gyro {'xyz'[ax]}, band {lo:.2f}-{hi:.2f} Hz")
    print("     Hz  residual/noise  signal/noise")
    for fi, a_, b_, c_ in list(zip(f[m], Pr[m, ax], Pn[m, ax], Py[m, ax]))[::a.every]:
        print(f"{fi:7.2f}  {a_ / b_:14.2f}  {c_ / b_:12.3g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
