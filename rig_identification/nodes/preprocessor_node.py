"""preprocessor: cable tensions + tracked pose + exciter force -> generalized wrench.

Thin node around rig_identification.estimation.preprocessor.WrenchPreprocessor (the same code as
the offline ``rig-identify``): aligns the streams by header stamp and publishes, for each
pose that every stream covers, the force and the moment about the CG on the body.

Parameters:
  rig (string, required)     path of the rig description (rig.yaml, with body.center_of_gravity)
  max_buffer (int)           samples buffered per stream (WrenchPreprocessor default)
  max_gap (double, 0.1)      a pose between two samples of a stream further apart than this
                             (s) is not processed: no interpolation over a sensor that stopped
  batch_period (double, 0.005)  the inputs are taken serialized and decoded in batches every
                             this many s
  stale_after, stopped_after (double, 0.5, 2.0)  /diagnostics: an input silent this long (wall
                             time, s) is reported WARN stale, ERROR stopped
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  executor (string, events)  events | single
  load_cell_frame (load_cell_{cable}), exciter_frame (exciter)  expected frame ids of the inputs
  world_frame (world), body_frame (body)  expected frames of /rig/pose; body_frame is written
                             on /rig/generalized_wrench

Topic names are remapped the ROS way (--ros-args -r /rig/pose:=/my/pose); the node logs its
resolved inputs and outputs once at start-up ("interface: ...").

Subscribes (RELIABLE, KEEP_ALL):
  /rig/pose               nav_msgs/Odometry, frame world_frame, child body_frame (from the tracker)
  /rig/load_cells/<cable> geometry_msgs/WrenchStamped, frame load_cell_frame, force.z = tension N
                          (one per cable of rig.yaml)
  /rig/exciter/wrench     geometry_msgs/WrenchStamped, frame exciter_frame (if rig.yaml has an exciter)

Publishes:
  /rig/generalized_wrench geometry_msgs/WrenchStamped, frame body_frame, stamp = pose stamp:
                          force N and torque N·m about the CG, body axes (gravity excluded:
                          force / mass is the specific force of the CG).  RELIABLE, KEEP_ALL.
  /diagnostics            message counts (and poses that could not be aligned), readers matched
                          by the /rig/generalized_wrench writer; one status per input topic
                          (OK / WARN stale / ERROR stopped, age, rate, stamp gaps)

Malformed input (NaN, stamp not increasing, non-unit quaternion) is dropped with a throttled
warning; a message with another frame id than expected with one warning per topic and frame id.
"""
from __future__ import annotations

import sys

import numpy as np
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from scipy.spatial.transform import Rotation

from ..estimation.preprocessor import WrenchPreprocessor
from .codec import odometry_layout, wrench_layout
from .diagnostics import Diagnostics
from .frames import Endpoint, declare_frame_ids, log_interface
from .inputs import InputGuard, RawInput
from .parameters import core_params, load_rig_param
from .qos import SENSOR_QOS, input_qos, publish_batch
from .runtime import run
from .topics import EXCITER_TOPIC, LOAD_CELL_PREFIX, POSE_TOPIC, WRENCH_TOPIC


class PreprocessorNode(Node):
    """Node ``preprocessor``: pose + tensions + exciter -> /rig/generalized_wrench (module docstring)."""

    def __init__(self):
        super().__init__("preprocessor")

        self.declare_parameter("rig", "")
        self.declare_parameter("executor", "events")
        self.declare_parameter("batch_period", 0.005)
        params = core_params(self, WrenchPreprocessor.__init__, skip=("self", "rig"))
        qos_in = input_qos(self)
        frames = declare_frame_ids(self, ("load_cell", "exciter", "world", "body"))
        rig = load_rig_param(self)
        self.pre = WrenchPreprocessor(rig, **params)
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=lambda: {"poses not aligned": self.pre.dropped,
                                                                        "poses in stream gaps": self.pre.gaps})
        self.pub = self.create_publisher(WrenchStamped, WRENCH_TOPIC, SENSOR_QOS)
        self.diag.add_writer(WRENCH_TOPIC, self.pub)
        self.out_layout = wrench_layout(frames.body)
        # inputs: raw subscriptions, decoded in batches every batch_period s
        self.poses = RawInput(self, self.guard, POSE_TOPIC,
                                     odometry_layout(frames.world, frames.body, hinted=True), qos_in)
        self.cells = {name: RawInput(self, self.guard, LOAD_CELL_PREFIX + name,
                                            wrench_layout(frames.load_cell_frame(name), "load_cell_frame"),
                                            qos_in)
                      for name in rig.cable_names}
        self.exciter = None
        if rig.exciter is not None:
            self.exciter = RawInput(self, self.guard, EXCITER_TOPIC,
                                           wrench_layout(frames.exciter, "exciter_frame"), qos_in)
        self.create_timer(float(self.get_parameter("batch_period").value), self._drain)
        inputs = [self.poses, *self.cells.values()] + ([self.exciter] if self.exciter is not None else [])
        log_interface(self, [i.endpoint() for i in inputs], [Endpoint(self.pub, f"frame {frames.body}")])
        self.get_logger().info(f"ready: rig {rig.source}, cables {', '.join(rig.cable_names)}, "
                               f"exciter {'yes' if rig.exciter is not None else 'no'}")

    def _drain(self) -> None:
        """Take every queued message, compute the wrenches every stream covers, publish them."""
        for name, inp in self.cells.items():
            t, v = inp.take()
            self.pre.add_tension_samples(name, t, v[:, 2])
        if self.exciter is not None:
            t, v = self.exciter.take()
            self.pre.add_exciter_samples(t, v[:, :2])
        t, v = self.poses.take()
        if len(t):
            q = v[:, 3:7]
            n2 = np.einsum("ij,ij->i", q, q)
            unit = np.abs(n2 - 1.0) <= 1e-3
            for i in np.nonzero(~unit)[0].tolist():
                self.guard.reject(POSE_TOPIC, f"orientation is not a unit quaternion (|q|^2 = {n2[i]:.4f})")
            if not unit.all():
                t, v = t[unit], v[unit]
            if len(t):
                self.pre.add_poses(t, v[:, :3], Rotation.from_quat(v[:, 3:7]).as_matrix())
        self.publish(self.pre.process())

    def publish(self, w) -> None:
        """Publish a WrenchSeries (one serialized batch)."""
        if not len(w.t):
            return
        publish_batch(self.pub, self.out_layout.encode(w.t, np.column_stack([w.force, w.torque])), WRENCH_TOPIC,
                      self.guard, self.diag)


def main(argv=None) -> int:
    return run(PreprocessorNode, argv, "preprocessor", __doc__)


if __name__ == "__main__":
    sys.exit(main())
