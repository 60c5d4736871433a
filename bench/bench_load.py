"""Load bench of the node graph (issue 6): a simulated rig with the IMU, every load cell and
the exciter at 1 kHz each, published in real time to tracker, preprocessor and identifier,
each in its own process over DDS (private ROS_DOMAIN_ID, localhost only).

    bench/bench_load.py [--duration S] [--rate-hz HZ] [--fit-every S] [--window S] [--keep-logs]

The sensor driver simulates ``config/rigs/default.yaml`` (thesis case 16) at ``--rate-hz``
for ``--duration`` s (the simulation runs first, before the clock starts) and publishes it at
1x real time, restamped to the wall clock, so that a header stamp is the time the sample was
taken.  This process listens to /rig/generalized_wrench and /diagnostics only (the nodes count
what they receive) and calls ``/identifier/identify_rig_model`` (window: the last ``--window``
s) every ``--fit-every`` s.  It prints:

* messages in/out per topic: published by the driver, received by each node, rejected,
  dropped (= published − received, end to end down to the wrenches this process received);
* CPU per process (share of one core, from /proc) and the driver's back-pressure stalls
  and achieved real-time factor;
* latency from sensor sample to generalized wrench: wall time at which this process
  received the wrench minus its header stamp (= the IMU sample's time), percentiles;
* the identifier's service: response time and fit time per call, and the result against
  the simulator's truth.

Exit status 1 if a message was lost or a node died.  The acceptance run (10 minutes):
``nice -n 10 .venv/bin/python bench/bench_load.py --duration 600``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from rig_identification.nodes.codec import wrench_layout
from rig_identification.nodes.demo import Graph
from rig_identification.nodes.diagnostics import diagnostic_values
from rig_identification.nodes.frames import BODY_FRAME
from rig_identification.nodes.qos import DIAGNOSTICS_QOS, LATCHED_QOS, SENSOR_QOS
from rig_identification.nodes.runtime import BackgroundSpin
from rig_identification.nodes.topics import (
    DIAGNOSTICS_TOPIC,
    DRIVER_STATUS_TOPIC,
    IMU_TOPIC,
    POSE_TOPIC,
    TRUTH_TOPIC,
    WRENCH_TOPIC,
)

REPO = Path(__file__).resolve().parents[1]
NODES = ("sensor_driver", "tracker", "preprocessor", "identifier")


class Listener:
    """rclpy in this process (own context, EventsExecutor thread): wrench arrival times and
    stamps (raw: no message objects), /diagnostics, the driver's status and the truth."""

    def __init__(self, domain_id: int):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import WrenchStamped
        from rclpy.experimental import EventsExecutor
        from rclpy.signals import SignalHandlerOptions
        from std_msgs.msg import String
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("bench_listener", context=self.ctx)
        self.arrivals: list[float] = []
        self.raws: list[bytes] = []
        self.status: dict = {}
        self.truth: dict = {}
        self.diag: dict[str, dict] = {}
        self.levels: dict[str, int] = {}

        def on_wrench(raw, now=time.time, arr=self.arrivals.append, keep=self.raws.append):
            arr(now())
            keep(raw)
        self.node.create_subscription(WrenchStamped, WRENCH_TOPIC, on_wrench, SENSOR_QOS, raw=True)
        self.node.create_subscription(String, DRIVER_STATUS_TOPIC,
                                      lambda m: setattr(self, "status", json.loads(m.data)), LATCHED_QOS)
        self.node.create_subscription(String, TRUTH_TOPIC,
                                      lambda m: setattr(self, "truth", json.loads(m.data)), LATCHED_QOS)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diag, DIAGNOSTICS_QOS)
        self._spin = BackgroundSpin(EventsExecutor(context=self.ctx), self.node, self.ctx)

    def _on_diag(self, msg):
        for st in msg.status:
            self.diag[st.name] = diagnostic_values(st)
            self.levels[st.name] = max(self.levels.get(st.name, 0), int.from_bytes(st.level, "little")
                                       if isinstance(st.level, bytes) else int(st.level))

    def call(self, service: str, timeout: float = 120.0):
        """std_srvs/Trigger call; returns (response or None, seconds)."""
        from std_srvs.srv import Trigger
        cli = self.node.create_client(Trigger, service)
        try:
            if not cli.wait_for_service(timeout_sec=20.0):
                return None, 0.0
            t0 = time.monotonic()
            fut = cli.call_async(Trigger.Request())
            while not fut.done() and time.monotonic() - t0 < timeout:
                time.sleep(0.005)
            return (fut.result() if fut.done() else None), time.monotonic() - t0
        finally:
            self.node.destroy_client(cli)

    def close(self):
        self._spin.close()


def experiment_file(path: Path, duration: float, rate_hz: float) -> Path:
    d = yaml.safe_load((REPO / "config" / "rigs" / "default.yaml").read_text())
    d["duration"] = float(duration)
    d["sensors"]["rates_hz"].update(imu=rate_hz, load_cells=rate_hz, exciter=rate_hz)
    d["description"] = f"bench_load: {d['description']}, sensors at {rate_hz:g} Hz, {duration:g} s"
    path.write_text(yaml.safe_dump(d, sort_keys=False))
    return path


def percentiles(x: np.ndarray, ps=(50, 90, 99, 99.9)) -> dict:
    return {p: float(np.percentile(x, p)) for p in ps} | {"max": float(np.max(x))}


def span_of(answer: dict) -> float:
    """The seconds of data an ~/identify_rig_model answer fitted."""
    return float(answer["window"]["end_relative"] - answer["window"]["start_relative"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="bench_load", description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of data published in real time (60)")
    ap.add_argument("--rate-hz", type=float, default=1000.0, help="IMU, load cell and exciter rate (1000)")
    ap.add_argument("--fit-every", type=float, default=30.0, help="call identify_rig_model every S s (30)")
    ap.add_argument("--window", type=float, default=120.0, help="fit window: the last S s (120)")
    ap.add_argument("--publish-period", type=float, default=0.002, help="driver timer period, s (0.002)")
    ap.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID (default: random)")
    ap.add_argument("--keep-logs", action="store_true")
    args = ap.parse_args(argv)

    t_start = time.monotonic()
    graph = Graph(domain_id=args.domain_id if args.domain_id is not None else int(np.random.randint(150, 200)))
    say = lambda s: print(f"[bench_load {time.monotonic() - t_start:6.1f} s] {s}", flush=True)  # noqa: E731
    say(f"ROS_DOMAIN_ID={graph.domain_id}, logs in {graph.dir}; load average {os.getloadavg()[0]:.2f} "
        f"on {os.cpu_count()} cores")
    lis = None
    failed = False
    try:
        exp = experiment_file(graph.dir / "experiment.yaml", args.duration, args.rate_hz)
        rig_path = graph.dir / "rig.yaml"
        graph.start("sensor_driver", {
            "experiment": str(exp), "rate": 1.0, "restamp": True, "rig_out": str(rig_path),
            "publish_period": args.publish_period, "wait_timeout": 600.0, "start_delay": 1.0,
            "wait_for": ["/rig/imu:2", "/rig/load_cells/*:3", "/rig/exciter/wrench:3", "/rig/inclinometer:2",
                         "/rig/pose:1", "/rig/generalized_wrench:1"]})
        lis = Listener(graph.domain_id)
        say(f"sensor_driver simulating {args.duration:g} s at {args.rate_hz:g} Hz ...")
        while not rig_path.exists():
            if graph.dead():
                raise RuntimeError("the sensor driver stopped:\n" + graph.log("sensor_driver")[-3000:])
            time.sleep(0.5)
        for name in ("tracker", "preprocessor", "identifier"):
            graph.start(name, {"rig": str(rig_path), "window_last": args.window} if name == "identifier"
                        else {"rig": str(rig_path)})
        while lis.status.get("state") != "publishing":
            if graph.dead():
                raise RuntimeError(f"node(s) {graph.dead()} stopped")
            time.sleep(0.1)
        t_pub = time.monotonic()
        cpu0 = {n: graph.cpu_seconds(n) for n in NODES}
        say(f"publishing {sum(lis.status['total'].values())} messages in real time")
        fits = []
        next_fit = t_pub + max(args.fit_every, 20.0)
        while lis.status.get("state") != "done":
            if graph.dead():
                raise RuntimeError(f"node(s) {graph.dead()} stopped:\n"
                                   + "\n".join(graph.log(n)[-2000:] for n in graph.dead()))
            if time.monotonic() >= next_fit:
                r, dt = lis.call("/identifier/identify_rig_model")
                d = json.loads(r.message) if r is not None else {"error": "no answer"}
                fits.append((time.monotonic() - t_pub, dt, r is not None and r.success, d))
                say(f"identify_rig_model answered in {dt:.2f} s: "
                    + (f"fit {d['fit_seconds']:.2f} s over {span_of(d):.1f} s, verdict {d['verdict']}"
                       if r is not None and r.success else d.get("error", "")))
                next_fit += args.fit_every
            time.sleep(0.05)
        wall = time.monotonic() - t_pub
        cpu1 = {n: graph.cpu_seconds(n) for n in NODES}
        achieved = lis.status.get("achieved", {})
        # let the pipeline drain, then one more round of /diagnostics
        total = lis.status["total"]
        end = time.monotonic() + 30.0
        while time.monotonic() < end:
            d = lis.diag.get("/identifier", {})
            if len(lis.arrivals) == lis.diag.get("/preprocessor", {}).get(f"tx {WRENCH_TOPIC}") \
                    and d.get(f"rx {IMU_TOPIC}") == total[IMU_TOPIC]:
                break
            time.sleep(0.2)
        time.sleep(1.5)
        r, dt = lis.call("/identifier/identify_rig_model")
        d = json.loads(r.message) if r is not None else {"error": "no answer"}
        fits.append((time.monotonic() - t_pub, dt, r is not None and r.success, d))

        # --- report ------------------------------------------------------------------------
        diag = lis.diag
        print(f"\n{args.rate_hz:g} Hz IMU, {len(lis.status.get('cables', []))} load cells and exciter, "
              f"inclinometer {yaml.safe_load(exp.read_text())['sensors']['rates_hz']['inclinometer']:g} Hz; "
              f"{args.duration:g} s published in {achieved.get('wall_seconds', wall):.1f} s "
              f"({achieved.get('rate', 0):.3f}x real time, {achieved.get('back_pressure_stalls', 0)} back-pressure "
              f"stalls); load average now {os.getloadavg()[0]:.2f}\n")
        pub = lis.status.get("published", {})
        header = f"{'topic':<28}{'published':>10}{'tracker':>10}{'preproc':>10}{'identif':>10}{'bench':>10}" \
                 f"{'rejected':>9}{'dropped':>9}"
        print("messages in/out (received per node; dropped = published - min received)")
        print(header)
        drops = 0
        rows = [(t, pub.get(t, 0)) for t in sorted(total)]
        rows.append((POSE_TOPIC, diag.get("/tracker", {}).get(f"tx {POSE_TOPIC}", 0)))
        rows.append((WRENCH_TOPIC, diag.get("/preprocessor", {}).get(f"tx {WRENCH_TOPIC}", 0)))
        for topic, n_pub in rows:
            rx = {node: diag.get(node, {}).get(f"rx {topic}") for node in ("/tracker", "/preprocessor", "/identifier")}
            if topic == WRENCH_TOPIC:
                rx["bench"] = len(lis.arrivals)
            rej = sum(diag.get(node, {}).get(f"rejected {topic}", 0) for node in rx if node.startswith("/"))
            got = [v for v in rx.values() if v is not None]
            lost = n_pub - min(got) if got else 0
            drops += max(lost, 0) + rej
            cells = "".join(f"{'' if rx.get(k) is None else rx[k]:>10}"
                            for k in ("/tracker", "/preprocessor", "/identifier", "bench"))
            print(f"{topic:<28}{n_pub:>10}{cells}{rej:>9}{lost:>9}")
        print(f"\nCPU while publishing ({wall:.1f} s wall)")
        print(f"{'process':<16}{'cpu s':>9}{'share of a core':>17}")
        tot = 0.0
        for n in NODES:
            if cpu0.get(n) is not None and cpu1.get(n) is not None:
                c = cpu1[n] - cpu0[n]
                tot += c
                print(f"{n:<16}{c:>9.1f}{100 * c / wall:>16.1f}%")
        print(f"{'all nodes':<16}{tot:>9.1f}{100 * tot / wall:>16.1f}%  (of {os.cpu_count()} cores)")

        lay = wrench_layout(BODY_FRAME)
        stamps, _, _ = lay.decode(lis.raws)
        lat = (np.array(lis.arrivals) - stamps) * 1e3
        skip = int(2.0 * args.rate_hz)  # the first 2 s: tracker initialisation, DDS warm-up
        if len(lat) > skip + 10:
            p = percentiles(lat[skip:])
            print("\nlatency sensor sample -> generalized wrench received (ms, after the first 2 s): "
                  + ", ".join(f"p{k:g} {v:.1f}" if k != "max" else f"max {v:.1f}" for k, v in p.items()))
        print("\nidentify_rig_model (window_last "
              f"{args.window:g} s): call at s, answered in s, fit s, window s, verdict")
        for t_call, dt, ok, d in fits:
            if ok:
                print(f"  {t_call:7.1f}  {dt:6.2f}  {d['fit_seconds']:6.2f}  {span_of(d):6.1f}  {d['verdict']}")
            else:
                print(f"  {t_call:7.1f}  {dt:6.2f}  refused: {d.get('error')}")
        ok_fits = [f for f in fits if f[2]]
        if ok_fits and lis.truth:
            res, tru = ok_fits[-1][3]["inertia_about_cg"], lis.truth["inertia_about_cg"]
            big = max(abs(tru[k]) for k in ("ixx", "iyy", "izz"))
            print("  last fit vs truth: " + ", ".join(f"{k} {res[k]:.1f} ({100 * (res[k] - tru[k]) / big:+.3f} %)"
                                                      for k in ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")))
        print(f"\nend to end: {drops} message(s) lost or rejected")
        failed = drops > 0
    except RuntimeError as e:
        print(f"bench_load: error: {e}", file=sys.stderr)
        failed = True
    finally:
        if lis is not None:
            lis.close()
        codes = graph.stop()
        if any(c not in (0, None) for c in codes.values()):
            print(f"exit codes: {codes}", file=sys.stderr)
        if failed or args.keep_logs:
            print(f"node logs: {graph.dir}", file=sys.stderr)
        else:
            import shutil
            shutil.rmtree(graph.dir, ignore_errors=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
