"""Diagnosis speed bench (issue "fast at lab scale": diagnosis on 120 s at 200 Hz ≤ 20 s, on 180 s
at 1 kHz ≤ 2 min): CPU and wall time of the diagnosis on recordings of lab length.

    bench/bench_diagnose_speed.py [--runs N] [--dir DIR] [--no-cli] [--no-call] [REC ...]

Recordings (default): the reference ``visible_case16_damped`` (120 s at 200 Hz, an independent
simulator, viscous damping the model lacks: the diagnosis has something to find) and
``config/rigs/default.yaml`` simulated by the package with every stream at 1 kHz for 180 s
(``bench_scaling.recording``, written into ``--dir``, default ``/tmp/bench_scaling``, reused when
there).  Any REC given replaces them.

Two rows per recording, each the median (min–max) of ``--runs`` counted runs (default 3) after
one warm-up run (numba's on-disk cache, the page cache), each in a process of its own with
``OMP_NUM_THREADS=1``:

* ``diagnose()``: :func:`rig_identification.diagnosis.selection.diagnose` alone on the read
  recording, timed inside the child (``time.process_time`` for CPU, ``time.perf_counter`` for
  wall) — the diagnosis's own cost, without start-up, bag reading and the rigid-body fit;
* ``rig-identify diagnose REC --model pem --json``: the whole process (start-up, reading, the rigid-body fit
  the command prints beside the diagnosis, the diagnosis), timed from outside by
  ``/usr/bin/time`` as ``bench_scaling.py`` does; peak resident memory too.

The "named" column is what the diagnosis named (the same in every run, or the bench says so).
On a shared machine quote the CPU column (the work is single-threaded), and paired ratios of
two versions (``farm-bench --vs``) for a before/after.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_scaling import CLI, REPO, TIME, recording  # noqa: E402

DAMPED = REPO.parent / "shared" / "recordings" / "visible_case16_damped"

WORKER = """
import json, sys, time
from rig_identification.io.recording import read_recording
from rig_identification.diagnosis.selection import diagnose
rec = read_recording(sys.argv[1])
c0, w0 = time.process_time(), time.perf_counter()
d = diagnose(rec)
c1, w1 = time.process_time(), time.perf_counter()
print(json.dumps({"cpu": c1 - c0, "wall": w1 - w0, "named": [e["name"] for e in d.effects]}))
"""


def call_once(rec: Path, env: dict) -> dict:
    """``diagnose()`` alone, in a child process: CPU s, wall s, the effects named."""
    p = subprocess.run([sys.executable, "-c", WORKER, str(rec)], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(f"diagnose({rec}) failed ({p.returncode}):\n{p.stderr[-2000:]}")
    return json.loads(p.stdout.strip().splitlines()[-1])


def cli_once(rec: Path, env: dict) -> dict:
    """``rig-identify diagnose REC --model pem --json``, the whole process timed by ``/usr/bin/time``."""
    with tempfile.TemporaryFile() as out, tempfile.NamedTemporaryFile("r") as tm:
        p = subprocess.run([TIME, "-o", tm.name, "-f", "%e %U %S %M", str(CLI), "diagnose", str(rec), "--model", "pem",
                            "--json"], stdout=out, stderr=subprocess.PIPE, env=env)
        if p.returncode != 0:
            raise SystemExit(f"rig-identify diagnose --model pem {rec} failed ({p.returncode}):\n"
                             f"{p.stderr.decode()[-2000:]}")
        wall, user, system, rss_kib = (float(x) for x in tm.read().split()[-4:])
        out.seek(0)
        named = [e["name"] for e in json.loads(out.read()).get("effects", [])]
    return {"cpu": user + system, "wall": wall, "mem": rss_kib / 1024.0, "named": named}


def measure(once, rec: Path, runs: int, env: dict) -> dict:
    once(rec, env)    # warm-up
    rs = [once(rec, env) for _ in range(runs)]
    named = {tuple(r["named"]) for r in rs}
    out = {k: statistics.median(r[k] for r in rs) for k in ("cpu", "wall")}
    out.update(wall_min=min(r["wall"] for r in rs), wall_max=max(r["wall"] for r in rs),
               cpu_min=min(r["cpu"] for r in rs), cpu_max=max(r["cpu"] for r in rs),
               mem=statistics.median(r["mem"] for r in rs) if "mem" in rs[0] else None,
               named=", ".join(next(iter(named))) or "–" if len(named) == 1 else f"differs: {sorted(named)}")
    return out


def describe(rec: Path) -> tuple[str, float, float]:
    """(name, length s, IMU rate Hz) of a recording."""
    from rig_identification.io.recording import read_recording
    s = read_recording(rec).sensors
    return rec.name, float(s.imu.t[-1] - s.imu.t[0]), float((len(s.imu.t) - 1) / (s.imu.t[-1] - s.imu.t[0]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("recordings", nargs="*", type=Path, help="recordings (default: the damped reference and the "
                                                            "default rig 180 s at 1 kHz)")
    p.add_argument("--runs", type=int, default=3, help="counted runs per row (median; default 3)")
    p.add_argument("--dir", type=Path, default=Path("/tmp/bench_scaling"), help="folder of the simulated recording")
    p.add_argument("--no-cli", action="store_true", help="without the rig-identify diagnose --model pem rows")
    p.add_argument("--no-call", action="store_true", help="without the diagnose() rows")
    a = p.parse_args(argv)
    if not a.no_cli and not (CLI.exists() and Path(TIME).exists()):
        raise SystemExit(f"{CLI} and {TIME} are needed for the whole-process rows (or --no-cli)")
    env = dict(os.environ)
    env.setdefault("OMP_NUM_THREADS", "1")
    recs = a.recordings
    if not recs:
        a.dir.mkdir(parents=True, exist_ok=True)
        recs = [DAMPED, recording(a.dir, 180.0, 1000.0)]
    print(f"# load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; {os.cpu_count()} CPUs; "
          f"OMP_NUM_THREADS={env['OMP_NUM_THREADS']}; {a.runs} counted runs after one warm-up, a process each",
          flush=True)
    print("| recording | length s | IMU Hz | what | CPU s median (min–max) | wall s median (min–max) | peak MiB | "
          "named |")
    print("|---|---:|---:|---|---:|---:|---:|---|", flush=True)
    for rec in recs:
        name, length, rate = describe(rec)
        rows = ([] if a.no_call else [("`diagnose()` alone", call_once)]) + \
               ([] if a.no_cli else [("`rig-identify diagnose REC --model pem --json`", cli_once)])
        for what, once in rows:
            m = measure(once, rec, a.runs, env)
            mem = "—" if m["mem"] is None else f"{m['mem']:.0f}"
            print(f"| {name} | {length:.0f} | {rate:.0f} | {what} | {m['cpu']:.2f} ({m['cpu_min']:.2f}–"
                  f"{m['cpu_max']:.2f}) | {m['wall']:.2f} ({m['wall_min']:.2f}–{m['wall_max']:.2f}) | {mem} | "
                  f"{m['named']} |", flush=True)
    print(f"# load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
