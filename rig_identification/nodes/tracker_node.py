"""tracker: pose of the suspended body from the IMU, inclinometer and load cells.

Thin node around rig_identification.estimation.tracker.PoseTracker (the same code as the offline
``rig-identify``).

Parameters:
  rig (string, required)     path of the rig description (rig.yaml)
  use_tensions (bool, true)  feed the load cells to the tracker (cable stretch T/k and the
                             initial pose at rest); false: IMU and inclinometer only
  batch_period (double, 0.005)  the inputs are taken serialized and decoded in batches every
                             this many s (at 1 kHz per sensor a message object per sample
                             costs more CPU than the tracker itself)
  reinit_gap (double, 0.1)   an IMU gap longer than this (s) re-initialises the tracker from
                             the data after it instead of integrating across the hole
  start_timeout (double, 5.0)  at start-up the tracker waits until every input has delivered
                             (streams match at different times, e.g. after a restart in the
                             middle of a run) and starts where all are present; a stream
                             silent for this long (wall time, s) is left out, and when it
                             delivers later the tracker re-initialises with it
  max_delay (double, 5.0)    the inputs are merged in header-stamp order before the tracker
                             sees them (arrival order differs between topics); a stream that
                             lags more than this (data time, s) is not waited for; after 2 s
                             (wall time) without input the rest is handed on (end of data)
  tau_tilt, tau_yaw, f_position, init_time (double)  PoseTracker parameters
                             (defaults: those of PoseTracker)
  input_reliability (string, reliable)  reliable | best_effort (QoS of the subscriptions)
  stale_after, stopped_after (double, 0.5, 2.0)  /diagnostics: an input silent this long (wall
                             time, s) is reported WARN stale, ERROR stopped
  executor (string, events)  events | single
  imu_frame (imu), inclinometer_frame (inclinometer), load_cell_frame (load_cell_{cable}),
  exciter_frame (exciter)    expected header.frame_id of the inputs (frames.py)
  world_frame (world), body_frame (body)  frames written on /rig/pose

The rig parameter may also name a recording folder or an experiment file (parameters.load_rig_source).
Topic names are remapped the ROS way (--ros-args -r /rig/imu:=/my/imu); the node logs its
resolved inputs and outputs once at start-up ("interface: ...").

Subscribes (RELIABLE, KEEP_ALL; input_reliability best_effort for BEST_EFFORT writers):
  /rig/imu                sensor_msgs/Imu, frame imu_frame
  /rig/inclinometer       geometry_msgs/Vector3Stamped, frame inclinometer_frame (if rig.yaml has one)
  /rig/load_cells/<cable> geometry_msgs/WrenchStamped, frame load_cell_frame (use_tensions)
  /rig/exciter/wrench     geometry_msgs/WrenchStamped, frame exciter_frame (initial pose only)

Publishes:
  /rig/pose  nav_msgs/Odometry, one per IMU sample once initialised, stamp = IMU stamp;
             header.frame_id world_frame, child_frame_id body_frame;
             pose.pose.position = world position of the body-frame origin, m;
             pose.pose.orientation = rotation body -> world;
             twist.twist.angular = angular velocity, body axes, rad/s;
             twist.twist.linear = velocity of the body origin in BODY axes, m/s (nav_msgs
             convention: the twist is given in child_frame_id; R * v is the world velocity).
             Covariances are zero (not estimated).  RELIABLE, KEEP_ALL.
  /diagnostics  message counts, readers matched by the /rig/pose writer; one status per
             input topic (OK / WARN stale / ERROR stopped, age, rate, stamp gaps)

Malformed input (NaN, stamp not increasing) is dropped with a throttled warning; a message
with another frame id than expected is dropped with one warning per topic and frame id
(naming the parameter to set), counted on /diagnostics.
"""
from __future__ import annotations

import sys
import time

import numpy as np
from nav_msgs.msg import Odometry
from rclpy.node import Node

from ..estimation.tracker import PoseTracker
from ..estimation.tracker_kernel import EVENT_EXCITER, EVENT_IMU, EVENT_INCLINOMETER, EVENT_TENSIONS
from .codec import imu_layout, odometry_layout, vector_layout, wrench_layout
from .diagnostics import Diagnostics
from .frames import Endpoint, declare_frame_ids, log_interface
from .inputs import InputGuard, RawInput
from .merge import StampMerger
from .parameters import core_params, load_rig_param
from .qos import SENSOR_QOS, input_qos, publish_batch
from .runtime import run
from .topics import EXCITER_TOPIC, IMU_TOPIC, INCLINOMETER_TOPIC, LOAD_CELL_PREFIX, POSE_TOPIC


class TrackerNode(Node):
    """Node ``tracker``: IMU (+ inclinometer, load cells) -> /rig/pose (see the module docstring)."""

    def __init__(self):
        super().__init__("tracker")
        self.declare_parameter("rig", "")
        self.declare_parameter("use_tensions", True)
        self.declare_parameter("max_delay", 5.0)
        self.declare_parameter("batch_period", 0.005)
        self.declare_parameter("reinit_gap", 0.1)
        self.declare_parameter("executor", "events")
        params = core_params(self, PoseTracker.__init__, skip=("self", "rig"))
        self.params = params
        self.reinit_gap = float(self.get_parameter("reinit_gap").value)
        self.reinitialised = 0
        qos_in = input_qos(self)
        frames = declare_frame_ids(self)
        self.frames = frames
        rig = load_rig_param(self)
        self.rig = rig
        self.tracker = PoseTracker(rig, **params)
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=lambda: {"reinitialised": self.reinitialised,
                                                                        "skipped at start-up": self.skipped_at_start})
        self.pub = self.create_publisher(Odometry, POSE_TOPIC, SENSOR_QOS)
        self.diag.add_writer(POSE_TOPIC, self.pub)
        self.out_layout = odometry_layout(frames.world, frames.body)
        self.names = rig.cable_names
        self._pending: dict[float, dict[str, float]] = {}
        self._latest: dict[str, float] = {}
        self._cells_async = False
        self._poses: list = []
        # inputs: raw subscriptions, decoded in batches (inputs.RawInput) every batch_period s
        R = RawInput
        self.inputs = [(R(self, self.guard, IMU_TOPIC, imu_layout(frames.imu, parameter="imu_frame"),
                          qos_in), IMU_TOPIC)]
        if rig.inclinometer is not None:
            self.inputs.append((R(self, self.guard, INCLINOMETER_TOPIC,
                                  vector_layout(frames.inclinometer, "inclinometer_frame"), qos_in),
                                INCLINOMETER_TOPIC))
        if self.get_parameter("use_tensions").value:
            for name in self.names:
                topic = LOAD_CELL_PREFIX + name
                self.inputs.append((R(self, self.guard, topic,
                                      wrench_layout(frames.load_cell_frame(name), "load_cell_frame"), qos_in),
                                    topic))
        if rig.exciter is not None:
            self.inputs.append((R(self, self.guard, EXCITER_TOPIC,
                                  wrench_layout(frames.exciter, "exciter_frame"), qos_in),
                                EXCITER_TOPIC))
        # the core wants its inputs in stamp order (as the offline replay sorts them)
        self.merger = StampMerger([t for _, t in self.inputs], float(self.get_parameter("max_delay").value))
        # start-up: streams whose subscriptions match later (discovery, a restart in the middle
        # of a run) must not find the tracker initialised without them; hold the feed until
        # every stream has delivered (or start_timeout s of wall time), then start where all
        # streams are present
        self.declare_parameter("start_timeout", 5.0)
        self.start_timeout = float(self.get_parameter("start_timeout").value)
        self.merger.hold = True
        self._first_stamp: dict[str, float] = {}
        self._t_first_msg: float | None = None
        self._left_out: set[str] = set()  # streams silent at start-up (see _apply)
        self.skipped_at_start = 0
        self._last_push = time.monotonic()
        self.create_timer(float(self.get_parameter("batch_period").value), self._drain)
        self.create_timer(0.25, self._flush_idle)
        log_interface(self, [inp.endpoint() for inp, _ in self.inputs],
                             [Endpoint(self.pub, f"frame {frames.world}, child {frames.body}")])
        self.get_logger().info(f"ready: rig {rig.source}, {len(self.names)} cables, parameters {params}")

    # --- inputs: validated, then merged in stamp order -----------------------------------
    # ranks for equal stamps: the core's event kinds (tracker_replay.merge_events' order)
    RANK = {INCLINOMETER_TOPIC: EVENT_INCLINOMETER, IMU_TOPIC: EVENT_IMU,
            EXCITER_TOPIC: EVENT_EXCITER}

    def _drain(self) -> None:
        """Take every queued message, merge by stamp, run the tracker, publish the poses."""
        got = False
        for inp, topic in self.inputs:
            t, vals = inp.take()
            if not len(t):
                continue
            got = True
            if topic == EXCITER_TOPIC:
                if self.tracker.initialised:  # only the initial pose uses it: stop waiting for it
                    self.merger.drop_stream(topic)
                    continue
                rows = vals[:, :2].tolist()
            elif topic == IMU_TOPIC:
                rows = vals.tolist()
            elif topic == INCLINOMETER_TOPIC:
                rows = vals[:, :2].tolist()
            else:
                rows = vals[:, 2].tolist()
            if self.merger.hold:
                self._first_stamp.setdefault(topic, float(t[0]))
            self._push(topic, t.tolist(), rows)
        if self.merger.hold and (got or self._first_stamp):
            self._start_up()
        if got:
            self._publish()
            # after the work: a publish blocked by a slow reader is not "no input"
            self._last_push = time.monotonic()

    def _push(self, topic: str, ts: list, rows: list) -> None:
        events, refused = self.merger.push_many(topic, ts, self.RANK.get(topic, EVENT_TENSIONS), rows)
        for i in refused:
            self.guard.reject(topic, f"stamp {ts[i]:.6f} s arrived after newer samples were processed")
        apply = self._apply
        for t_ev, _, _, stream, data in events:
            apply(stream, t_ev, data)

    def _start_up(self) -> None:
        """Leave the start-up hold once every stream has delivered (or after start_timeout s):
        the buffered events older than the latest first stamp are dropped, so that the
        tracker initialises on all of its streams."""
        now = time.monotonic()
        if self._t_first_msg is None:
            self._t_first_msg = now
        streams = [t for _, t in self.inputs]
        missing = [t for t in streams if t not in self._first_stamp]
        if missing and now - self._t_first_msg < self.start_timeout:
            return
        for topic in missing:
            self.get_logger().warn(f"no data on {topic} within {self.start_timeout:g} s: tracking without it "
                                   "(re-initialising with it if it comes)")
            self.merger.drop_stream(topic)
            if topic != EXCITER_TOPIC:  # only the initial pose uses the exciter
                self._left_out.add(topic)
        t_common = max(self._first_stamp.values())
        self.skipped_at_start = self.merger.discard_before(t_common)
        if self.skipped_at_start:
            self.get_logger().info(f"start-up: {self.skipped_at_start} samples older than the first sample of "
                                   "every stream skipped")
        self.merger.hold = False
        for t_ev, _, _, stream, data in self.merger.release():
            self._apply(stream, t_ev, data)

    def _flush_idle(self) -> None:
        """End of the data (or every input stalled): nothing arrived for 2 s, hand on the rest."""
        if self.merger.hold:
            if self._first_stamp:
                self._start_up()
                self._publish()
            return
        if len(self.merger) and time.monotonic() - self._last_push > 2.0:
            for t_ev, _, _, stream, data in self.merger.flush():
                self._apply(stream, t_ev, data)
            self._publish()

    def _apply(self, topic: str, t: float, data) -> None:
        if topic in self._left_out:
            # a stream left out at start-up delivers after all (slow discovery after a restart):
            # a pose initialised without it stays off (tensor errors of 5-18 % measured with
            # every stream but the IMU left out), so start again with every stream
            self._left_out.discard(topic)
            if self.tracker.initialised:
                self.get_logger().warn(f"first data on {topic} at t={t:.3f} s, after start-up: "
                                       "re-initialising the tracker with it")
                self.tracker = PoseTracker(self.rig, **self.params)
                self.reinitialised += 1
        if topic == IMU_TOPIC:
            tr = self.tracker
            if tr.initialised and t - tr.t > self.reinit_gap:
                # no integration across a hole in the IMU stream: start again from the data after it
                self.get_logger().warn(f"no IMU data for {t - tr.t:.2f} s: re-initialising the tracker")
                self.tracker = PoseTracker(self.rig, **self.params)
                self.reinitialised += 1
            try:
                pose = self.tracker.add_imu(t, data[:3], data[3:])
            except ValueError as e:  # TrackerError (no consistent pose), bad stamps
                self.guard.core_error(topic, e)
                return
            if pose is not None:
                self._poses.append(pose)
        elif topic == INCLINOMETER_TOPIC:
            self.tracker.add_inclinometer(t, data)
        elif topic == EXCITER_TOPIC:
            if not self.tracker.initialised:
                self.tracker.add_exciter(t, data)
        else:
            self._add_tension(topic[len(LOAD_CELL_PREFIX):], t, data)

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
    def _publish(self) -> None:
        """Publish the poses tracked since the last call (one serialized batch)."""
        poses, self._poses = self._poses, []
        if not poses:
            return
        t = np.array([p.t for p in poses])
        M = np.array([p.matrix for p in poses])
        vel = np.array([p.velocity for p in poses])
        vals = np.column_stack([np.array([p.position for p in poses]), np.array([p.quaternion for p in poses]),
                                np.array([p.omega for p in poses]),
                                np.einsum("nji,nj->ni", M, vel)])  # velocity in body axes: R^T v
        publish_batch(self.pub, self.out_layout.encode(t, vals), POSE_TOPIC, self.guard, self.diag)


def main(argv=None) -> int:
    return run(TrackerNode, argv, "tracker", __doc__)


if __name__ == "__main__":
    sys.exit(main())
