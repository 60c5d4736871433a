"""tracker: pose of the suspended body from the IMU, inclinometer and load cells.

Thin node around rig_identification.tracker.PoseTracker (the same code as the offline
``rig-identify``).

Parameters:
  rig (string, required)     path of the rig description (rig.yaml)
  use_tensions (bool, true)  feed the load cells to the tracker (cable stretch T/k and the
                             initial pose at rest); false: IMU and inclinometer only
  max_delay (double, 5.0)    the inputs are merged in header-stamp order before the tracker
                             sees them (arrival order differs between topics); a stream that
                             lags more than this (data time, s) is not waited for; after 2 s
                             (wall time) without input the rest is handed on (end of data)
  tau_tilt, tau_yaw, f_position, init_time (double)  PoseTracker parameters
                             (defaults: those of PoseTracker)
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  executor (string, events)  events | single

Subscribes (RELIABLE, KEEP_ALL; input_reliability best_effort for BEST_EFFORT writers):
  /rig/imu                sensor_msgs/Imu, frame imu
  /rig/inclinometer       geometry_msgs/Vector3Stamped, frame inclinometer (if rig.yaml has one)
  /rig/load_cells/<cable> geometry_msgs/WrenchStamped, frame load_cell_<cable> (use_tensions)
  /rig/exciter/wrench     geometry_msgs/WrenchStamped, frame exciter (initial pose only)

Publishes:
  /rig/pose  nav_msgs/Odometry, one per IMU sample once initialised, stamp = IMU stamp;
             header.frame_id world, child_frame_id body;
             pose.pose.position = world position of the body-frame origin, m;
             pose.pose.orientation = rotation body -> world;
             twist.twist.angular = angular velocity, body axes, rad/s;
             twist.twist.linear = velocity of the body origin in BODY axes, m/s (nav_msgs
             convention: the twist is given in child_frame_id; R * v is the world velocity).
             Covariances are zero (not estimated).  RELIABLE, KEEP_ALL.
  /diagnostics  message counts, readers matched by the /rig/pose writer

Malformed input (wrong frame, NaN, stamp not increasing) is dropped with a throttled warning.
"""
from __future__ import annotations

import sys
import time

import numpy as np
from rclpy.node import Node

from . import common
from .common import SENSOR_QOS


class TrackerNode(Node):
    """Node ``tracker``: IMU (+ inclinometer, load cells) -> /rig/pose (see the module docstring)."""

    def __init__(self):
        super().__init__("tracker")
        from geometry_msgs.msg import Vector3Stamped, WrenchStamped
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import Imu

        from ..tracker import PoseTracker
        self.declare_parameter("rig", "")
        self.declare_parameter("use_tensions", True)
        self.declare_parameter("max_delay", 5.0)
        self.declare_parameter("executor", "events")
        params = common.core_params(self, PoseTracker.__init__, skip=("self", "rig"))
        qos_in = common.input_qos(self)
        rig = common.load_rig_param(self)
        self.rig = rig
        self.tracker = PoseTracker(rig, **params)
        self.guard = common.InputGuard(self)
        self.diag = common.Diagnostics(self, self.guard)
        self.pub = self.create_publisher(Odometry, common.POSE_TOPIC, SENSOR_QOS)
        self.diag.add_writer(common.POSE_TOPIC, self.pub)
        self.odom = Odometry()
        self.odom.header.frame_id = common.WORLD_FRAME
        self.odom.child_frame_id = common.BODY_FRAME
        self.names = rig.cable_names
        self._pending: dict[float, dict[str, float]] = {}
        self._latest: dict[str, float] = {}
        self._cells_async = False
        streams = [common.IMU_TOPIC]
        self.create_subscription(Imu, common.IMU_TOPIC, self.on_imu, qos_in)
        if rig.inclinometer is not None:
            self.create_subscription(Vector3Stamped, common.INCLINOMETER_TOPIC, self.on_inclinometer, qos_in)
            streams.append(common.INCLINOMETER_TOPIC)
        if self.get_parameter("use_tensions").value:
            for name in self.names:
                self.create_subscription(WrenchStamped, common.LOAD_CELL_PREFIX + name,
                                         lambda m, n=name: self.on_load_cell(n, m), qos_in)
                streams.append(common.LOAD_CELL_PREFIX + name)
        if rig.exciter is not None:
            self.create_subscription(WrenchStamped, common.EXCITER_TOPIC, self.on_exciter, qos_in)
            streams.append(common.EXCITER_TOPIC)
        # the core wants its inputs in stamp order (as the offline replay sorts them)
        self.merger = common.StampMerger(streams, float(self.get_parameter("max_delay").value))
        self._last_push = time.monotonic()
        self.create_timer(0.25, self._flush_idle)
        self.get_logger().info(f"ready: rig {rig.source}, {len(self.names)} cables, parameters {params}")

    # --- inputs: validated, then merged in stamp order -----------------------------------
    # ranks for equal stamps, as tracker.track(): inclinometer, tensions, IMU, exciter
    RANK = {common.INCLINOMETER_TOPIC: 0, common.IMU_TOPIC: 2, common.EXCITER_TOPIC: 3}

    def _push(self, topic: str, t: float, payload) -> None:
        events = self.merger.push(topic, t, self.RANK.get(topic, 1), payload)
        if events is None:
            self.guard.reject(topic, f"stamp {t:.6f} s arrived more than max_delay after newer samples")
            return
        for t_ev, _, _, stream, data in events:
            self._apply(stream, t_ev, data)
        # after the work: a publish blocked by a slow reader is not "no input"
        self._last_push = time.monotonic()

    def _flush_idle(self) -> None:
        """End of the data (or every input stalled): nothing arrived for 2 s, hand on the rest."""
        if len(self.merger) and time.monotonic() - self._last_push > 2.0:
            for t_ev, _, _, stream, data in self.merger.flush():
                self._apply(stream, t_ev, data)

    def _apply(self, topic: str, t: float, data) -> None:
        if topic == common.IMU_TOPIC:
            try:
                pose = self.tracker.add_imu(t, data[:3], data[3:])
            except ValueError as e:  # TrackerError (no consistent pose), bad stamps
                self.guard.core_error(topic, e)
                return
            if pose is not None:
                self.publish(pose)
        elif topic == common.INCLINOMETER_TOPIC:
            self.tracker.add_inclinometer(t, data)
        elif topic == common.EXCITER_TOPIC:
            if not self.tracker.initialised:
                self.tracker.add_exciter(t, data)
        else:
            self._add_tension(topic[len(common.LOAD_CELL_PREFIX):], t, data)

    def on_imu(self, msg) -> None:
        w, a = msg.angular_velocity, msg.linear_acceleration
        vals = (w.x, w.y, w.z, a.x, a.y, a.z)
        t = self.guard.accept(common.IMU_TOPIC, msg.header, common.IMU_FRAME, vals)
        if t is not None:
            self._push(common.IMU_TOPIC, t, vals)

    def on_inclinometer(self, msg) -> None:
        v = msg.vector
        t = self.guard.accept(common.INCLINOMETER_TOPIC, msg.header, common.INCLINOMETER_FRAME, (v.x, v.y, v.z))
        if t is not None:
            self._push(common.INCLINOMETER_TOPIC, t, (v.x, v.y))

    def on_load_cell(self, name: str, msg) -> None:
        topic = common.LOAD_CELL_PREFIX + name
        tension = msg.wrench.force.z
        t = self.guard.accept(topic, msg.header, common.load_cell_frame(name), (tension,))
        if t is not None:
            self._push(topic, t, tension)

    def on_exciter(self, msg) -> None:
        f = msg.wrench.force
        t = self.guard.accept(common.EXCITER_TOPIC, msg.header, common.EXCITER_FRAME, (f.x, f.y))
        if t is None:
            return
        if self.tracker.initialised:  # only the initial pose uses it: stop waiting for it
            self.merger.drop_stream(common.EXCITER_TOPIC)
            return
        self._push(common.EXCITER_TOPIC, t, (f.x, f.y))

    def _add_tension(self, name: str, t: float, tension: float) -> None:
        self._latest[name] = tension
        if self._cells_async:
            # load cells on different clocks: the latest value of each cable
            if len(self._latest) == len(self.names):
                self.tracker.add_tensions(t, self._latest)
            return
        group = self._pending.setdefault(t, {})
        group[name] = tension
        if len(group) == len(self.names):  # every cable sampled at this stamp
            self.tracker.add_tensions(t, group)
            for k in [k for k in self._pending if k <= t]:
                del self._pending[k]
        elif len(self._pending) > 200:
            self.get_logger().warn("the load cells do not share sample stamps: using the latest tension "
                                   "of each cable")
            self._cells_async = True
            self._pending.clear()

    # --- output ------------------------------------------------------------------------
    def publish(self, pose) -> None:
        o = self.odom
        common.set_stamp(o.header, pose.t)
        p = o.pose.pose.position
        p.x, p.y, p.z = pose.position.tolist()
        q = o.pose.pose.orientation
        q.x, q.y, q.z, q.w = pose.quaternion.tolist()
        tw = o.twist.twist
        tw.angular.x, tw.angular.y, tw.angular.z = np.asarray(pose.omega, float).tolist()
        tw.linear.x, tw.linear.y, tw.linear.z = (pose.matrix.T @ pose.velocity).tolist()
        try:
            common.publish_blocking(self.pub, o)
        except Exception as e:  # blocked too long by a slow reader: the pose is lost, say so
            self.guard.reject(common.POSE_TOPIC + " (publish)", f"{type(e).__name__}: {e}")
            return
        self.diag.count_tx(common.POSE_TOPIC)


def main(argv=None) -> int:
    return common.run(TrackerNode, argv, "tracker", __doc__)


if __name__ == "__main__":
    sys.exit(main())
