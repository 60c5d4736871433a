"""preprocessor: cable tensions + tracked pose + exciter force -> generalized wrench.

Thin node around rig_identification.preprocessor.WrenchPreprocessor (the same code as
the offline ``rig-identify``): aligns the streams by header stamp and publishes, for each
pose that every stream covers, the force and the moment about the CG on the body.

Parameters:
  rig (string, required)     path of the rig description (rig.yaml, with body.center_of_gravity)
  max_buffer (int)           samples buffered per stream (WrenchPreprocessor default)
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  executor (string, events)  events | single

Subscribes (RELIABLE, KEEP_ALL):
  /rig/pose               nav_msgs/Odometry, frame world, child body (from the tracker)
  /rig/load_cells/<cable> geometry_msgs/WrenchStamped, frame load_cell_<cable>, force.z = tension N
                          (one per cable of rig.yaml)
  /rig/exciter/wrench     geometry_msgs/WrenchStamped, frame exciter (if rig.yaml has an exciter)

Publishes:
  /rig/generalized_wrench geometry_msgs/WrenchStamped, frame body, stamp = pose stamp:
                          force N and torque N·m about the CG, body axes (gravity excluded:
                          force / mass is the specific force of the CG).  RELIABLE, KEEP_ALL.
  /diagnostics            message counts (and poses that could not be aligned), readers matched
                          by the /rig/generalized_wrench writer

Malformed input (wrong frame, NaN, stamp not increasing, non-unit quaternion) is dropped
with a throttled warning.
"""
from __future__ import annotations

import sys

import numpy as np
from rclpy.node import Node
from scipy.spatial.transform import Rotation

from . import common
from .common import SENSOR_QOS


class PreprocessorNode(Node):
    """Node ``preprocessor``: pose + tensions + exciter -> /rig/generalized_wrench (module docstring)."""

    def __init__(self):
        super().__init__("preprocessor")
        from geometry_msgs.msg import WrenchStamped
        from nav_msgs.msg import Odometry

        from ..preprocessor import WrenchPreprocessor
        self.declare_parameter("rig", "")
        self.declare_parameter("executor", "events")
        params = common.core_params(self, WrenchPreprocessor.__init__, skip=("self", "rig"))
        qos_in = common.input_qos(self)
        rig = common.load_rig_param(self)
        self.pre = WrenchPreprocessor(rig, **params)
        self.guard = common.InputGuard(self)
        self.diag = common.Diagnostics(self, self.guard, extra=lambda: {"poses not aligned": self.pre.dropped})
        self.pub = self.create_publisher(WrenchStamped, common.WRENCH_TOPIC, SENSOR_QOS)
        self.diag.add_writer(common.WRENCH_TOPIC, self.pub)
        self.out = WrenchStamped()
        self.out.header.frame_id = common.BODY_FRAME
        self.create_subscription(Odometry, common.POSE_TOPIC, self.on_pose, qos_in)
        for name in rig.cable_names:
            self.create_subscription(WrenchStamped, common.LOAD_CELL_PREFIX + name,
                                     lambda m, n=name: self.on_load_cell(n, m), qos_in)
        if rig.exciter is not None:
            self.create_subscription(WrenchStamped, common.EXCITER_TOPIC, self.on_exciter, qos_in)
        self.get_logger().info(f"ready: rig {rig.source}, cables {', '.join(rig.cable_names)}, "
                               f"exciter {'yes' if rig.exciter is not None else 'no'}")

    def on_pose(self, msg) -> None:
        from ..tracker import PoseEstimate
        topic = common.POSE_TOPIC
        if msg.child_frame_id != common.BODY_FRAME:
            self.guard.received[topic] = self.guard.received.get(topic, 0) + 1
            self.guard.reject(topic, f"child_frame_id {msg.child_frame_id!r}, expected {common.BODY_FRAME!r}")
            return
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        tw = msg.twist.twist
        vals = (p.x, p.y, p.z, q.x, q.y, q.z, q.w, tw.angular.x, tw.angular.y, tw.angular.z,
                tw.linear.x, tw.linear.y, tw.linear.z)
        t = self.guard.accept(topic, msg.header, common.WORLD_FRAME, vals)
        if t is None:
            return
        quat = np.array(vals[3:7])
        if abs(np.dot(quat, quat) - 1.0) > 1e-3:
            self.guard.reject(topic, f"orientation is not a unit quaternion (|q|^2 = {np.dot(quat, quat):.4f})")
            return
        R = Rotation.from_quat(quat).as_matrix()
        pose = PoseEstimate(t, np.array(vals[:3]), R, np.array(vals[7:10]), R @ np.array(vals[10:13]))
        self.publish(self.pre.add_pose(pose))

    def on_load_cell(self, name: str, msg) -> None:
        topic = common.LOAD_CELL_PREFIX + name
        tension = msg.wrench.force.z
        t = self.guard.accept(topic, msg.header, common.load_cell_frame(name), (tension,))
        if t is not None:
            try:
                self.publish(self.pre.add_tension(name, t, tension))
            except ValueError as e:
                self.guard.core_error(topic, e)

    def on_exciter(self, msg) -> None:
        f = msg.wrench.force
        t = self.guard.accept(common.EXCITER_TOPIC, msg.header, common.EXCITER_FRAME, (f.x, f.y))
        if t is not None:
            try:
                self.publish(self.pre.add_exciter(t, f.x, f.y))
            except ValueError as e:
                self.guard.core_error(common.EXCITER_TOPIC, e)

    def publish(self, wrenches) -> None:
        m = self.out
        for w in wrenches:
            common.set_stamp(m.header, w.t)
            f, tq = m.wrench.force, m.wrench.torque
            f.x, f.y, f.z = np.asarray(w.force, float).tolist()
            tq.x, tq.y, tq.z = np.asarray(w.torque, float).tolist()
            try:
                common.publish_blocking(self.pub, m)
            except Exception as e:  # blocked too long by a slow reader: lost, say so
                self.guard.reject(common.WRENCH_TOPIC + " (publish)", f"{type(e).__name__}: {e}")
        if wrenches:
            self.diag.count_tx(common.WRENCH_TOPIC, len(wrenches))


def main(argv=None) -> int:
    return common.run(PreprocessorNode, argv, "preprocessor", __doc__)


if __name__ == "__main__":
    sys.exit(main())
