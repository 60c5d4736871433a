"""demo: the whole node graph on the embedded default experiment, as separate processes.

Starts, each as its own process talking over DDS on a private ROS_DOMAIN_ID with
discovery limited to this machine:

  1. sensor_driver   simulates config/rigs/default.yaml (thesis case 16, 120 s) and writes
                     its rig.yaml to a temporary folder;
  2. tracker, preprocessor, identifier   with that rig.yaml;
  3. the driver publishes at ``--rate`` times real time once every consumer is subscribed;
  4. mass_properties_client (identify), once the driver is done and the identifier's buffer is
     complete: the rig model of the buffered raw streams (``~/identify_rig_model``, the core of
     ``rig-identify inertia``), its mass properties printed beside the truth.

Then it prints the message counts of every node (received / rejected / published, from
/diagnostics), stops the nodes (SIGINT, then SIGKILL after a grace period) and exits with
the client's status.  Node logs are kept in the temporary folder (printed on failure).
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import BinaryIO

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import String

from ..io.verdict import PACKAGE, package_version
from .diagnostics import diagnostic_values
from .environment import default_experiment, ros_env
from .qos import DIAGNOSTICS_QOS, LATCHED_QOS
from .runtime import BackgroundSpin
from .topics import DIAGNOSTICS_TOPIC, DRIVER_STATUS_TOPIC

NODE_MODULES = {
    "sensor_driver": "rig_identification.nodes.sensor_driver",
    "tracker": "rig_identification.nodes.tracker_node",
    "preprocessor": "rig_identification.nodes.preprocessor_node",
    "identifier": "rig_identification.nodes.identifier_node",
    "mass_properties_client": "rig_identification.nodes.client",
}


class Graph:
    """A set of node processes on one private ROS domain.

    ``start(name, params)`` writes a parameter file and starts
    ``python -m <module> --ros-args --params-file FILE`` with its output in ``<dir>/<name>.log``.
    ``stop()`` sends SIGINT to every process, waits up to ``grace`` s, then kills.
    """

    def __init__(self, workdir: Path | None = None, domain_id: int | None = None, python: str | None = None):
        self.dir = Path(workdir) if workdir else Path(tempfile.mkdtemp(prefix="rig_graph_"))
        self.dir.mkdir(parents=True, exist_ok=True)
        self.domain_id = domain_id if domain_id is not None else random.Random().randint(20, 99)
        self.env = ros_env(self.domain_id)
        self.python = python or sys.executable
        self.procs: dict[str, subprocess.Popen] = {}
        self._logs: dict[str, BinaryIO] = {}

    def params_file(self, name: str, params: dict) -> Path:
        p = self.dir / f"{name}.params.yaml"
        p.write_text(yaml.safe_dump({name: {"ros__parameters": params}}, sort_keys=False))
        return p

    def start(self, name: str, params: dict | None = None, module: str | None = None, args=(),
              stdout=None) -> subprocess.Popen:
        cmd = [self.python, "-m", module or NODE_MODULES[name], *args]
        if params:
            cmd += ["--ros-args", "--params-file", str(self.params_file(name, params))]
        if stdout is None:
            log = open(self.dir / f"{name}.log", "wb")
            self._logs[name] = log
            proc = subprocess.Popen(cmd, env=self.env, stdout=log, stderr=subprocess.STDOUT,
                                    stdin=subprocess.DEVNULL)
        else:
            proc = subprocess.Popen(cmd, env=self.env, stdout=stdout, stdin=subprocess.DEVNULL)
        self.procs[name] = proc
        return proc

    def log(self, name: str) -> str:
        p = self.dir / f"{name}.log"
        return p.read_text(errors="replace") if p.exists() else ""

    def cpu_seconds(self, name: str) -> float | None:
        """User + system CPU time of a running node process, s (Linux /proc)."""
        p = self.procs.get(name)
        if p is None:
            return None
        try:
            fields = Path(f"/proc/{p.pid}/stat").read_text().rsplit(")", 1)[1].split()
            return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            return None

    def dead(self) -> list[str]:
        return [n for n, p in self.procs.items() if p.poll() is not None]

    def stop(self, grace: float = 5.0) -> dict[str, int]:
        """SIGINT every process, wait ``grace`` s, SIGKILL the rest.  Returns exit codes."""
        for p in self.procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        end = time.monotonic() + grace
        for p in self.procs.values():
            try:
                p.wait(timeout=max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in self._logs.values():
            f.close()
        return {n: p.returncode for n, p in self.procs.items()}


class Monitor:
    """A small rclpy node in this process (own context, background thread) that keeps the
    latest driver status and each node's /diagnostics values."""

    def __init__(self, domain_id: int):
        # discovery limited to this machine, like the node processes (read by the rmw at init)
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
        os.environ.pop("ROS_LOCALHOST_ONLY", None)
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("demo_monitor", context=self.context)
        self.status: dict = {}
        self.diagnostics: dict[str, dict] = {}
        self.node.create_subscription(String, DRIVER_STATUS_TOPIC, self._on_status, LATCHED_QOS)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diag,
                                      DIAGNOSTICS_QOS)
        self._spin = BackgroundSpin(SingleThreadedExecutor(context=self.context), self.node, self.context)

    def _on_status(self, msg):
        self.status = json.loads(msg.data)

    def _on_diag(self, msg):
        for st in msg.status:
            self.diagnostics[st.name] = diagnostic_values(st)

    def close(self):
        self._spin.close()


def counts_table(diagnostics: dict[str, dict], status: dict) -> str:
    """Message counts per node: what the driver published and what each node received."""
    lines = []
    total = status.get("total", {})
    lines.append(f"{'node':<16}{'topic':<28}{'published':>10}{'received':>10}{'rejected':>10}")
    pub = status.get("published", {})
    for topic in sorted(total):
        lines.append(f"{'/sensor_driver':<16}{topic:<28}{pub.get(topic, 0):>10}{'':>10}{'':>10}")
    for name in sorted(diagnostics):
        if name == "/sensor_driver":
            continue
        d = diagnostics[name]
        topics = sorted({k.split(" ", 1)[1] for k in d if k.startswith(("rx ", "tx "))})
        for topic in topics:
            lines.append(f"{name:<16}{topic:<28}{d.get('tx ' + topic, ''):>10}{d.get('rx ' + topic, ''):>10}"
                         f"{d.get('rejected ' + topic, ''):>10}")
    lines.append("rejected: messages a node refused and logged (malformed, not finite, a stamp not after the "
                 "previous one, not a unit quaternion); 0 on a clean run")
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="demo", description=__doc__.split("\n\n")[0])
    ap.add_argument("--version", action="version", version=f"demo ({PACKAGE}) {package_version()}")
    ap.add_argument("--rate", type=float, default=3.0,
                    help="replay speed, times real time (default 3: measured without backlog on 2 cores)")
    ap.add_argument("--experiment", help="experiment YAML (default: the package's config/rigs/default.yaml)")
    ap.add_argument("--recording", help="replay this recording folder instead of simulating")
    ap.add_argument("--duration", type=float, default=0.0, help="only the first DURATION s of data")
    ap.add_argument("--domain-id", type=int, help="ROS_DOMAIN_ID (default: random 20-99)")
    ap.add_argument("--keep-logs", action="store_true", help="print where the node logs are and keep them")
    return ap


def _driver_params(args: argparse.Namespace, rig_path: Path) -> dict:
    """The sensor driver's parameters: the recording replayed or the experiment simulated, at
    ``args.rate``, its rig.yaml written to ``rig_path``, publishing once the nodes subscribe."""
    driver: dict = {"rate": args.rate, "rig_out": str(rig_path), "duration": args.duration,
                    "wait_for": ["/rig/imu:2", "/rig/load_cells/*:2", "/rig/exciter/wrench:2",
                                 "/rig/inclinometer:1", "/rig/pose:1"],
                    "wait_timeout": 120.0, "start_delay": 1.0}
    if args.recording:
        driver["recording"] = str(Path(args.recording).resolve())
    else:
        driver["experiment"] = str(Path(args.experiment).resolve() if args.experiment else default_experiment())
    return driver


def _start_nodes(graph: Graph, rig_path: Path, say) -> None:
    """The tracker, preprocessor and identifier on the rig.yaml the driver writes, once it is
    there.  Raises RuntimeError when the driver stops first."""
    while not rig_path.exists():
        if graph.dead():
            raise RuntimeError("the sensor driver stopped:\n" + graph.log("sensor_driver")[-3000:])
        time.sleep(0.2)
    say(f"rig description ready ({rig_path}); starting tracker, preprocessor, identifier")
    for name in ("tracker", "preprocessor", "identifier"):
        graph.start(name, {"rig": str(rig_path)})


def _wait_for_driver(graph: Graph, monitor: Monitor, rate: float, say) -> None:
    """Until the driver has published everything, saying when it starts and ends.  Raises
    RuntimeError when a node stops."""
    state = None
    while True:
        st = monitor.status.get("state")
        if st != state:
            state = st
            if st == "publishing":
                total = sum(monitor.status.get("total", {}).values())
                say(f"every node subscribed; driver publishing {total} messages at {rate:g}x real time")
            elif st == "done":
                a = monitor.status.get("achieved", {})
                say(f"driver done publishing: {a.get('wall_seconds', 0):.1f} s, "
                    f"{a.get('rate', 0):.2f}x real time")
                break
        dead = graph.dead()
        if dead:
            raise RuntimeError(f"node(s) {', '.join(dead)} stopped:\n"
                               + "\n".join(graph.log(n)[-2000:] for n in dead))
        time.sleep(0.1)


def _run_client(graph: Graph, monitor: Monitor, say) -> int:
    """mass_properties_client's default verb once the identifier's buffer is complete, then the
    message counts; the client's exit status."""
    cpu = {n: graph.cpu_seconds(n) for n in ("sensor_driver", "tracker", "preprocessor", "identifier")}
    say("CPU time so far: " + ", ".join(f"{n} {c:.1f} s" for n, c in cpu.items() if c is not None))
    say("running mass_properties_client")
    client = graph.start("mass_properties_client", module=NODE_MODULES["mass_properties_client"],
                         args=["identify", "--wait-stable", "1.5", "--timeout", "60"], stdout=sys.stdout)
    rc = client.wait()
    time.sleep(1.2)  # one more round of /diagnostics
    print("\nmessage counts (driver status and /diagnostics):")
    print(counts_table(monitor.diagnostics, monitor.status))
    say(f"client exit status {rc}")
    return int(rc)


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    t_start = time.monotonic()
    graph = Graph(domain_id=args.domain_id)
    say = lambda s: print(f"[demo {time.monotonic() - t_start:6.1f} s] {s}", flush=True)  # noqa: E731
    say(f"ROS_DOMAIN_ID={graph.domain_id}, node logs in {graph.dir} (kept where something fails or with "
        "--keep-logs, else removed at the end)")
    monitor = None
    rc = 1
    try:
        rig_path = graph.dir / "rig.yaml"
        driver = _driver_params(args, rig_path)
        graph.start("sensor_driver", driver)
        monitor = Monitor(graph.domain_id)
        say("sensor_driver: " + (f"replaying {driver['recording']}" if args.recording
                                 else f"simulating {driver['experiment']}"))
        _start_nodes(graph, rig_path, say)
        _wait_for_driver(graph, monitor, args.rate, say)
        rc = _run_client(graph, monitor, say)
    except KeyboardInterrupt:
        rc = 130
    except RuntimeError as e:
        print(f"demo: error: {e}", file=sys.stderr)
        rc = 1
    finally:
        if monitor is not None:
            monitor.close()
        codes = graph.stop()
        bad = {n: c for n, c in codes.items() if c not in (0, None) and n != "mass_properties_client"}
        say("nodes stopped" + (f" (exit codes {bad})" if bad else " cleanly"))
        if rc != 0 or args.keep_logs:
            print(f"node logs: {graph.dir}", file=sys.stderr)
        else:
            shutil.rmtree(graph.dir, ignore_errors=True)
    return rc


if __name__ == "__main__":
    sys.exit(main())
