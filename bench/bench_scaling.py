"""Scaling bench (issue "fast at lab scale"): wall time, CPU time and peak memory of
``rig-identify inertia REC --json`` (the rig model fitted to every sensor, with its diagnosis)
against the recording's length, at 200 Hz and with every stream at 1 kHz, so that a user sees
how the cost grows with the recording.

    bench/bench_scaling.py [--runs N] [--dir DIR] [--durations S ...] [--rates HZ ...]
                           [--no-reference] [--help-row]

The "verdict" column says what the fit's validation found.

Recordings: ``config/rigs/default.yaml`` simulated by the package's simulator (4 cables,
the exciter; at 200 Hz its own rates — IMU, load cells, exciter 200 Hz, inclinometer 50 Hz —
at 1 kHz every stream at 1000 Hz) for each length in ``--durations`` (default 60 120 240 s)
and written with ``write_recording`` into ``--dir`` (default ``/tmp/bench_scaling``; kept and
reused when they exist: a 240 s recording at 1 kHz takes a few minutes to simulate); plus the
reference ``visible_case16_clean`` (120 s at 200 Hz, an independent simulator) unless
``--no-reference``.

Every figure is a whole process (the ``rig-identify`` entry point beside this interpreter:
start-up, imports, bag reading, everything), timed from outside by ``/usr/bin/time -f "%e %U %S
%M"``: one warm-up run (numba's on-disk cache, the page cache), then ``--runs`` counted runs
(default 3); wall, CPU (user + sys) and peak resident memory (``ru_maxrss``) of that one process.
The table gives the median (min–max) of the wall time and the medians of CPU and memory;
"CPU s / min" is the CPU time per minute of recording, constant when the cost grows linearly.
The machine's load average is printed before and after: on a shared machine quote the CPU time
(the process is single-threaded with ``OMP_NUM_THREADS=1``, which the children get unless it is
set).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from rig_identification.io.recording import read_recording
from rig_identification.io.recording_writer import write_recording
from rig_identification.model.experiment import load_experiment
from rig_identification.model.simulator import simulate

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO.parent / "shared" / "recordings" / "visible_case16_clean"
CLI = Path(sys.executable).with_name("rig-identify")
TIME = "/usr/bin/time"   # GNU time: -f "%e %U %S %M" (wall, user, sys, peak resident KiB)


def recording(folder: Path, duration: float, rate: float) -> Path:
    """The default rig simulated for ``duration`` s (every stream at ``rate`` Hz; 200: the
    config's own rates), written into ``folder`` unless it is there already."""
    out = folder / f"default_{int(rate)}hz_{int(duration)}s"
    if (out / "rig.yaml").exists():
        return out
    exp = load_experiment(str(REPO / "config/rigs/default.yaml")).with_overrides(duration=duration)
    if rate != 200.0:
        exp = dataclasses.replace(exp, sensors=dataclasses.replace(exp.sensors,
                                                                   rates={k: rate for k in exp.sensors.rates}))
    t0 = time.perf_counter()
    res = simulate(exp)
    write_recording(out, res.rig, res.sensors, res.truth)
    print(f"# simulated and wrote {out} in {time.perf_counter() - t0:.0f} s", flush=True)
    return out


def messages(rec: Path) -> int:
    s = read_recording(rec).sensors
    return sum(len(x) for x in [s.imu, *s.load_cells.values(), s.exciter, s.inclinometer] if x is not None)


def run_once(args: list[str], env: dict) -> tuple[float, float, float, str]:
    """One child process, timed by ``/usr/bin/time`` (its own wait4 of the child: the figures of
    that process alone — a child forked from this big interpreter would report this
    interpreter's memory as its peak): (wall s, CPU s user + sys, peak resident MiB, the verdict
    of its JSON)."""
    with tempfile.TemporaryFile() as out, tempfile.NamedTemporaryFile("r") as tm:
        p = subprocess.run([TIME, "-o", tm.name, "-f", "%e %U %S %M", str(CLI), *args], stdout=out,
                           stderr=subprocess.PIPE, env=env)
        if p.returncode != 0:
            raise SystemExit(f"rig-identify {' '.join(args)} failed ({p.returncode}):\n{p.stderr.decode()[-2000:]}")
        wall, user, system, rss_kib = (float(x) for x in tm.read().split()[-4:])
        out.seek(0)
        verdict = "—"
        if "--json" in args:
            verdict = json.loads(out.read()).get("verdict", "—")
    return wall, user + system, rss_kib / 1024.0, verdict


def measure(args: list[str], runs: int, env: dict) -> dict:
    run_once(args, env)   # warm-up
    rows = [run_once(args, env) for _ in range(runs)]
    wall, cpu, mem, verdict = zip(*rows)
    return {"wall": statistics.median(wall), "wall_min": min(wall), "wall_max": max(wall),
            "cpu": statistics.median(cpu), "mem": statistics.median(mem), "verdict": verdict[-1]}


def row(label: str, rate: str, seconds: float, n_msg: int | str, command: str, m: dict) -> str:
    per_min = f"{60.0 * m['cpu'] / seconds:.2f}" if seconds else "—"
    return (f"| {label} | {rate} | {seconds:.0f} | {n_msg} | `{command}` | {m['wall']:.2f} "
            f"({m['wall_min']:.2f}–{m['wall_max']:.2f}) | {m['cpu']:.2f} | {per_min} | {m['mem']:.0f} | "
            f"{m['verdict']} |")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=3, help="counted runs per command (median; default 3)")
    p.add_argument("--dir", type=Path, default=Path("/tmp/bench_scaling"), help="folder of the simulated recordings")
    p.add_argument("--durations", type=float, nargs="+", default=[60.0, 120.0, 240.0], help="lengths, s")
    p.add_argument("--rates", type=float, nargs="+", default=[200.0, 1000.0],
                   help="200: the config's rates (inclinometer 50 Hz); any other: every stream at that rate")
    p.add_argument("--no-reference", action="store_true", help="without visible_case16_clean")
    p.add_argument("--help-row", action="store_true", help="also time rig-identify --help")
    a = p.parse_args(argv)
    if not CLI.exists():
        raise SystemExit(f"{CLI}: no rig-identify entry point beside this interpreter (make setup)")
    if not Path(TIME).exists():
        raise SystemExit(f"{TIME}: GNU time is needed for the per-process figures (apt install time)")
    env = dict(os.environ)
    env.setdefault("OMP_NUM_THREADS", "1")
    a.dir.mkdir(parents=True, exist_ok=True)
    cases = []
    for rate in a.rates:
        for d in a.durations:
            rec = recording(a.dir, d, rate)
            cases.append(("default rig", f"{rate:.0f}" + (" (incl. 50)" if rate == 200.0 else ""), d, rec))
    if not a.no_reference:
        cases.append(("visible_case16_clean", "200 (incl. 50)", 120.0, REFERENCE))
    print(f"# load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} CPUs; "
          f"OMP_NUM_THREADS={env['OMP_NUM_THREADS']}; {a.runs} counted runs after one warm-up, whole processes",
          flush=True)
    print("| recording | rate Hz | length s | messages | command | wall s median (min–max) | CPU s | "
          "CPU s / min | peak MiB | verdict |")
    print("|---|---|---:|---:|---|---:|---:|---:|---:|---|", flush=True)
    if a.help_row:
        print(row("—", "—", 0.0, "—", "rig-identify --help", measure(["--help"], a.runs, env)), flush=True)
    for label, rate, d, rec in cases:
        m = measure(["inertia", str(rec), "--json"], a.runs, env)
        print(row(label, rate, d, messages(rec), "rig-identify inertia REC --json", m), flush=True)
    print(f"# load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
