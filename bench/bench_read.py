"""Bag reading bench (issue "fast at lab scale"): the per-message reader (rosbags
deserialisation of every message, ``read_sensor_data(..., bulk=False)``) against the bulk
reader (numpy over the raw CDR bytes, ``bulk=True``), on the reference recordings and on a
synthetic 180 s recording with every stream at 1 kHz (1.26 M messages, as a real rig logs).

    bench/bench_read.py [--runs N] [--synthetic DIR] [--no-synthetic] [--storage mcap|sqlite3]
    bench/bench_read.py [--runs N] RECORDING [RECORDING ...]
    bench/bench_read.py --one RECORDING [--per-message]

Prints one row per recording: messages read, median seconds of each reader over ``--runs``
interleaved runs (in this process, after one warm-up read; each read opens the bag anew),
the speed-up (ratio of the medians), and each reader's peak of traced Python memory
(tracemalloc, numpy buffers included, one extra run each: tracing slows the reader, so
those runs are not timed).  Every bulk read is checked to give exactly the per-message
arrays.

The synthetic recording is simulated from ``config/rigs/default.yaml`` with
``sensors.rates_hz`` 1000 for every stream and written with ``write_recording`` (about two
minutes) into ``--synthetic DIR`` (kept and reused when it exists) or a temporary folder.
Recordings given as arguments are benched instead of the reference and synthetic ones.
``--one`` reads one recording once and exits: for whole-process timings with an external
timer (``/usr/bin/time -v``).
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from rig_identification.io.recording import SensorData, read_sensor_data
from rig_identification.io.recording_writer import write_recording
from rig_identification.io.rig import load_rig

REPO = Path(__file__).resolve().parents[1]
REFERENCES = REPO.parent / "shared" / "recordings"
NAMES = ["visible_case16_clean", "visible_case14_clean", "visible_case16_damped",
         "visible_case16_static/static_baseline", "visible_case16_static/static_dummy"]


def read(rec: Path, bulk: bool) -> SensorData:
    return read_sensor_data(rec / "bag", load_rig(rec / "rig.yaml").cable_names, [], bulk=bulk)


def count(s: SensorData) -> int:
    return sum(len(x) for x in [s.imu, *s.load_cells.values(), s.exciter, s.inclinometer] if x is not None)


def same(a: SensorData, b: SensorData) -> bool:
    pairs = [(a.imu, b.imu), (a.exciter, b.exciter), (a.inclinometer, b.inclinometer),
             *((a.load_cells[n], b.load_cells[n]) for n in a.load_cells)]
    return all((x is None and y is None) or (np.array_equal(x.t, y.t) and np.array_equal(x.data, y.data))
               for x, y in pairs)


def peak_mb(rec: Path, bulk: bool) -> float:
    tracemalloc.start()
    try:
        read(rec, bulk)
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


def synthetic(out: Path, storage: str) -> Path:
    from rig_identification.model.experiment import load_experiment
    from rig_identification.model.simulator import simulate
    if out.exists():
        return out
    exp = load_experiment(str(REPO / "config/rigs/default.yaml")).with_overrides(duration=180.0)
    rates = {k: 1000.0 for k in exp.sensors.rates}   # sensors.rates_hz: every stream at 1 kHz
    exp = dataclasses.replace(exp, sensors=dataclasses.replace(exp.sensors, rates=rates))
    t0 = time.perf_counter()
    res = simulate(exp)
    write_recording(out, res.rig, res.sensors, res.truth, storage=storage)
    print(f"# synthetic recording {out}: simulated and written in {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def bench(label: str, rec: Path, runs: int) -> None:
    ref = read(rec, False)
    bulk = read(rec, True)   # warm-up of both paths (imports, caches)
    if not same(ref, bulk):
        raise SystemExit(f"{label}: the bulk reader's arrays differ from the per-message reader's")
    slow, fast = [], []
    for _ in range(runs):
        for bulk_path, times in ((False, slow), (True, fast)):
            t0 = time.perf_counter()
            read(rec, bulk_path)
            times.append(time.perf_counter() - t0)
    ms, mf = statistics.median(slow), statistics.median(fast)
    print(f"| {label} | {count(ref)} | {ms:.3f} | {mf:.3f} | {ms / mf:.1f}x | "
          f"{peak_mb(rec, False):.0f} | {peak_mb(rec, True):.0f} |", flush=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=3, help="timed runs of each reader (median; default 3)")
    p.add_argument("--synthetic", type=Path, help="folder for the 1 kHz recording (reused if it exists)")
    p.add_argument("--no-synthetic", action="store_true", help="reference recordings only")
    p.add_argument("--storage", choices=("mcap", "sqlite3"), default="mcap", help="storage of the synthetic bag")
    p.add_argument("recordings", type=Path, nargs="*", help="bench these recordings instead")
    p.add_argument("--one", type=Path, metavar="RECORDING", help="read this recording once and exit")
    p.add_argument("--per-message", action="store_true", help="with --one: the per-message reader")
    args = p.parse_args(argv)
    if args.one is not None:
        read(args.one, not args.per_message)
        return 0
    print(f"runs: {args.runs} interleaved per reader, median; peak: tracemalloc, one extra run each")
    print("| recording | messages | per-message s | bulk s | speed-up | per-message peak MB | bulk peak MB |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    if args.recordings:
        for rec in args.recordings:
            bench(str(rec), rec, args.runs)
        return 0
    for name in NAMES:
        bench(name, REFERENCES / name, args.runs)
    if not args.no_synthetic:
        with tempfile.TemporaryDirectory() as tmp:
            rec = synthetic(args.synthetic or Path(tmp) / "synthetic_1khz", args.storage)
            bench(f"synthetic 180 s, 1 kHz ({args.storage})", rec, args.runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
