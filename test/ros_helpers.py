"""Helpers of the node-graph tests (test_nodes and the modules beside it): a listener on every
topic in this process, and a wait that reports the nodes' logs when it times out."""
from __future__ import annotations

import json
import threading
import time

import pytest

rclpy = pytest.importorskip("rclpy")

from rig_identification.nodes.demo import Graph  # noqa: E402
from rig_identification.nodes.diagnostics import diagnostic_values  # noqa: E402
from rig_identification.nodes.messages import stamp_to_sec  # noqa: E402
from rig_identification.nodes.qos import DIAGNOSTICS_QOS, LATCHED_QOS, SENSOR_QOS, SERVICE_SETTLE_SECONDS  # noqa: E402
from rig_identification.nodes.runtime import BackgroundSpin  # noqa: E402
from rig_identification.nodes.topics import (  # noqa: E402
    DIAGNOSTICS_TOPIC,
    DRIVER_STATUS_TOPIC,
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    POSE_TOPIC,
    TRUTH_TOPIC,
    WRENCH_TOPIC,
)

SETTLE = SERVICE_SETTLE_SECONDS


class Listener:
    """rclpy in this process (own context, EventsExecutor in a thread): records every topic."""

    def __init__(self, domain_id: int, cables: list[str], executor: str = "events"):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import InertiaStamped, Vector3Stamped, WrenchStamped
        from nav_msgs.msg import Odometry
        from rclpy.signals import SignalHandlerOptions
        from sensor_msgs.msg import Imu
        from std_msgs.msg import String
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("test_listener", context=self.ctx)
        self.lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self.poses: list[tuple] = []
        self.frames: dict[str, set] = {}
        self.status: dict = {}
        self.diag: dict[str, dict] = {}
        self.diag_times: dict[str, list[float]] = {}
        self.truth: dict = {}
        topics = {IMU_TOPIC: Imu, EXCITER_TOPIC: WrenchStamped,
                  INCLINOMETER_TOPIC: Vector3Stamped, WRENCH_TOPIC: WrenchStamped}
        topics.update({LOAD_CELL_PREFIX + c: WrenchStamped for c in cables})
        for topic, mtype in topics.items():
            self.node.create_subscription(mtype, topic, lambda m, t=topic: self._count(t, m), SENSOR_QOS)
        self.node.create_subscription(Odometry, POSE_TOPIC, self._pose, SENSOR_QOS)
        self.node.create_subscription(String, DRIVER_STATUS_TOPIC,
                                      lambda m: setattr(self, "status", json.loads(m.data)), LATCHED_QOS)
        self.node.create_subscription(String, TRUTH_TOPIC,
                                      lambda m: setattr(self, "truth", json.loads(m.data)), LATCHED_QOS)
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._diag, DIAGNOSTICS_QOS)
        self.InertiaStamped = InertiaStamped
        if executor == "events":
            from rclpy.experimental import EventsExecutor
            ex = EventsExecutor(context=self.ctx)
        else:
            from rclpy.executors import SingleThreadedExecutor
            ex = SingleThreadedExecutor(context=self.ctx)
        self._spin = BackgroundSpin(ex, self.node, self.ctx)

    def _count(self, topic, msg):
        with self.lock:
            self.counts[topic] = self.counts.get(topic, 0) + 1
            self.frames.setdefault(topic, set()).add(msg.header.frame_id)

    def _pose(self, m):
        p, q, tw = m.pose.pose.position, m.pose.pose.orientation, m.twist.twist
        with self.lock:
            self.counts[POSE_TOPIC] = self.counts.get(POSE_TOPIC, 0) + 1
            self.frames.setdefault(POSE_TOPIC, set()).add((m.header.frame_id, m.child_frame_id))
            self.poses.append((stamp_to_sec(m.header.stamp), p.x, p.y, p.z, q.x, q.y, q.z, q.w,
                               tw.angular.x, tw.angular.y, tw.angular.z, tw.linear.x, tw.linear.y, tw.linear.z))

    def _diag(self, msg):
        for st in msg.status:
            self.diag[st.name] = diagnostic_values(st)
            self.diag_times.setdefault(st.name, []).append(time.monotonic())

    def call(self, service: str, timeout: float = 60.0):
        """Call a std_srvs/Trigger service from a fresh client; returns the response."""
        from std_srvs.srv import Trigger
        cli = self.node.create_client(Trigger, service)
        try:
            assert cli.wait_for_service(timeout_sec=20.0), f"service {service} not available"
            time.sleep(SETTLE)   # the service's side of the discovery (qos.SERVICE_SETTLE_SECONDS)
            fut = cli.call_async(Trigger.Request())
            end = time.monotonic() + timeout
            while not fut.done() and time.monotonic() < end:
                time.sleep(0.02)
            assert fut.done(), f"no answer from {service} within {timeout} s"
            return fut.result()
        finally:
            self.node.destroy_client(cli)

    def close(self):
        self._spin.close()


def wait_until(cond, timeout: float, what: str, graph: Graph | None = None, step: float = 0.1, info=None):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return
        if graph is not None and graph.dead():
            dead = graph.dead()
            # a node that ends by design (exit_when_done) may exit before its last message reaches us
            grace = time.monotonic() + 3.0
            while time.monotonic() < grace:
                if cond():
                    return
                time.sleep(step)
            pytest.fail(f"node(s) {dead} died while waiting for {what}:\n"
                        + "\n".join(graph.log(n)[-3000:] for n in dead))
        time.sleep(step)
    logs = "" if graph is None else "\n".join(f"--- {n}:\n{graph.log(n)[-1500:]}" for n in graph.procs)
    pytest.fail(f"timed out after {timeout} s waiting for {what}\n{info() if info else ''}\n{logs}")
