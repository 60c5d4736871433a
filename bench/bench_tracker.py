"""Speed of the tracker's offline replay (the compiled filter in one loop) against the tracker node's
path (``PoseTracker.add_*``: one call of the compiled filter per sample).

Recordings: the reference visible_case16_clean (120 s, 200 Hz) and a simulated random 4-cable
rig, 180 s with every sensor at 1 kHz (a lab rig's logging rate; ~45 s to simulate).  For
``track`` (two passes: the rig.yaml gives no stiffness) and for one ``replay`` pass, one row
each: IMU samples, merged events, the median seconds of ``--runs`` runs of each path (after a
first call), the speed-up, the per-sample path's CPU µs per IMU sample (the tracker node's cost
of the filter; 1 kHz leaves 1000 µs), and the largest relative difference between the paths
(position, velocity, omega, quaternion, compliance updates; each the largest |difference| over
the largest magnitude).  Then the cost of the first compiled call: numba's import and its
on-disk cache (warm), and a compilation from an empty cache (cold, a child process with its own
NUMBA_CACHE_DIR).

Usage: bench_tracker.py [--runs N]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from rig_identification.design.scenarios import random_experiment
from rig_identification.estimation.tracker_replay import merge_events, replay, track
from rig_identification.io.recording import read_recording
from rig_identification.model.experiment import experiment_from_dict
from rig_identification.model.simulator import simulate

SHARED = Path(__file__).resolve().parents[2] / "shared" / "recordings"
REFERENCE = "visible_case16_clean"
COLD = """
import time, sys
from rig_identification.io.recording import read_recording, crop
rec = read_recording(sys.argv[1])
s = crop(rec.sensors, rec.sensors.t_start, rec.sensors.t_start + 2.0)
t1 = time.perf_counter()
from rig_identification.estimation.tracker_replay import replay
t2 = time.perf_counter(); replay(rec.rig, s)
t3 = time.perf_counter(); replay(rec.rig, s)
t4 = time.perf_counter()
print(t2 - t1, (t3 - t2) - (t4 - t3))
"""


def rel(a, b) -> float:
    """Largest |a - b| over the largest |b|."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)) if b.size else 0.0


def difference(pc, pp, tc=None, tp=None) -> float:
    """Largest relative difference between two PoseTracks (and the trackers' compliance updates)."""
    d = [rel(getattr(pc, f), getattr(pp, f)) for f in ("position", "quaternion", "velocity", "omega")]
    if tc is not None and tp.compliance_history:
        d.append(rel([c for _, c in tc.compliance_history], [c for _, c in tp.compliance_history]))
    return max(d)


def timed(f, runs: int) -> tuple[float, float, object]:
    """Median wall seconds and CPU seconds of ``runs`` calls of f() and its last result."""
    times, cpu = [], []
    for _ in range(runs):
        t0, c0 = time.perf_counter(), time.process_time()
        out = f()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(times), statistics.median(cpu), out


def lab_scale():
    """A random 4-cable rig (no stiffness in its rig.yaml), 180 s, every sensor at 1 kHz."""
    d = random_experiment(3, 4, "wide", [], 180.0)
    d["sensors"]["rates_hz"] = {k: 1000.0 for k in d["sensors"]["rates_hz"]}
    sim = simulate(experiment_from_dict(d, d["name"]))
    return sim.rig, sim.sensors


def main(runs: int) -> None:
    rec = read_recording(SHARED / REFERENCE)
    cases = [(f"{REFERENCE} (200 Hz)", rec.rig, rec.sensors)]
    print("simulating the 1 kHz recording ...", flush=True)
    rig, sensors = lab_scale()
    cases.append(("random_3_4wide 180 s (1 kHz)", rig, sensors))
    print(f"{'recording':30s} {'path':6s} {'samples':>8s} {'events':>8s} {'per-sample s':>12s} {'one loop s':>10s} "
          f"{'speed-up':>8s} {'CPU µs/IMU':>10s} {'max rel diff':>12s}")
    first, median_replay = [], []
    for name, rig, sensors in cases:
        t0 = time.perf_counter()
        replay(rig, sensors)
        first.append(time.perf_counter() - t0)
        n_events = len(merge_events(rig, sensors, 0.1).t)
        for path in ("track", "replay"):
            if path == "track":
                tc_, _, pc = timed(lambda: track(rig, sensors), runs)
                tp_, cpu, pp = timed(lambda: track(rig, sensors, per_sample=True), runs)
                diff = difference(pc, pp)
                passes = 2 if not np.isfinite(rig.cable_stiffness).all() else 1
            else:
                tc_, _, (pc, trc) = timed(lambda: replay(rig, sensors), runs)
                tp_, cpu, (pp, trp) = timed(lambda: replay(rig, sensors, per_sample=True), runs)
                diff = difference(pc, pp, trc, trp)
                median_replay.append(tc_)
                passes = 1
            per_imu = cpu / (passes * len(sensors.imu.t)) * 1e6
            print(f"{name:30s} {path:6s} {len(sensors.imu.t):8d} {n_events:8d} {tp_:12.3f} {tc_:10.4f} "
                  f"{tp_ / tc_:8.1f} {per_imu:10.1f} {diff:12.1e}", flush=True)
    with tempfile.TemporaryDirectory() as cache:
        out = subprocess.run([sys.executable, "-c", COLD, str(SHARED / REFERENCE)], capture_output=True, text=True,
                             check=True, env={**os.environ, "NUMBA_CACHE_DIR": cache}).stdout.split()
    print(f"first compiled call in this process, numba's cache warm: {first[0] - median_replay[0]:.2f} s "
          f"more than the next ones (loading the cached machine code)")
    print(f"cold start, empty cache: import numba + kernel {float(out[0]):.2f} s, compilation {float(out[1]):.2f} s")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3, help="runs per timing (median; default 3)")
    main(ap.parse_args().runs)
