"""sensor_driver: publishes the rig's sensor streams from a simulation or a recording.

Source (one of):
  experiment (string)  experiment YAML simulated at start-up with simulator.simulate;
                       default (both empty): the package's config/rigs/default.yaml
  recording (string)   recording folder (rig.yaml + bag/ [+ truth.yaml]) replayed

Parameters:
  rate (double, 1.0)          real-time factor of the replay (2.0 = twice as fast)
  duration (double, 0.0)      > 0: simulate / replay only the first DURATION s of data
  restamp (bool, false)       shift the header stamps so that the first sample is "now"
  rig_out (string, "")        write the rig description (rig.yaml) here before publishing
  wait_for (string[], [])     start publishing only once these topics have subscribers:
                              "TOPIC" (>= 1) or "TOPIC:COUNT"; "PREFIX*:COUNT" applies to each
                              own topic with that prefix.  Counted as readers matched by the
                              writer (DDS level, not the ROS graph, which can show a reader
                              seconds before its writer has matched it and then the first
                              samples are lost): own topics from the own writers, other
                              topics from the "matched TOPIC" value that this package's
                              nodes publish on /diagnostics for their writers
  wait_timeout (double, 60.0) give up waiting after this many seconds (then publish anyway)
  start_delay (double, 0.5)   pause after the subscribers are there (endpoint matching settles)
  publish_period (double, 0.01) timer period, s: each tick publishes every sample whose
                              stamp is due, in stamp order (serialized in one batch per topic)
  exit_when_done (bool, false) exit once everything is published (else stay up: latched topics)
  silence (string[], [])      fault injection: "TOPIC:T0:T1" publishes nothing on TOPIC for data
                              times T0 <= t < T1 s after the first sample (a sensor that stops)
  executor (string, events)   events | single
  imu_frame (imu), load_cell_frame (load_cell_{cable}), exciter_frame (exciter),
  inclinometer_frame (inclinometer)  frame ids written (frames.py; to mimic a lab's drivers)

Topic names are remapped the ROS way (--ros-args -r /rig/imu:=/my/imu); the node logs its
resolved outputs once the data is loaded ("interface: ...").

Publishes (stamps = the data's header stamps):
  /rig/imu                 sensor_msgs/Imu, frame imu_frame: gyro rad/s, specific force m/s^2,
                           orientation_covariance[0] = -1
  /rig/load_cells/<cable>  geometry_msgs/WrenchStamped, frame load_cell_frame: force.z = tension N
  /rig/exciter/wrench      geometry_msgs/WrenchStamped, frame exciter_frame: force.x, force.y N
  /rig/inclinometer        geometry_msgs/Vector3Stamped, frame inclinometer_frame: elevations rad
    (all RELIABLE, VOLATILE, KEEP_ALL: no sample is lost; a reliable reader that falls behind
    slows the replay down (back-pressure); BEST_EFFORT readers match too)
  /rig/sim_truth           std_msgs/String JSON of truth.yaml (if any), latched (TRANSIENT_LOCAL)
  /rig/sensor_driver/status std_msgs/String JSON {"state": "loading|waiting|publishing|done",
                           "total": {topic: n}, "published": {topic: n}, ...}, latched
  /diagnostics             message counts
"""
from __future__ import annotations

import bisect
import sys
import time
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import Imu
from std_msgs.msg import String

from ..io.atomic import atomic_write_text
from ..io.recording import SensorData, TimeSeries, read_recording
from ..io.rig import dump_rig
from ..model.experiment import load_experiment
from ..model.simulator import simulate
from .codec import imu_layout, vector_layout, wrench_layout
from .diagnostics import Diagnostics
from .environment import default_experiment
from .frames import Endpoint, declare_frame_ids, log_interface
from .inputs import InputGuard
from .messages import to_json
from .qos import DIAGNOSTICS_QOS, LATCHED_QOS, SENSOR_QOS
from .runtime import run
from .topics import (
    DIAGNOSTICS_TOPIC,
    DRIVER_STATUS_TOPIC,
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    TRUTH_TOPIC,
)

# with exit_when_done, the longest wait for the readers' acknowledgements after the last message, s
LINGER_SECONDS = 5.0


class _Stream:
    """One topic's samples, published serialized (codec.MessageLayout): the samples due at a
    tick are encoded in one batch.  cols: the layout fields that ``data``'s columns fill."""

    def __init__(self, topic: str, publisher, layout, cols, t: np.ndarray, data: np.ndarray):
        self.topic, self.publisher, self.layout, self.cols = topic, publisher, layout, list(cols)
        self.t = np.asarray(t, float)
        self.data = np.asarray(data, float).reshape(len(self.t), -1)
        self.offset = 0.0
        self.published = 0
        self._c0 = 0
        self._cache: list[bytes] = []

    def raw(self, j: int) -> bytes:
        """The serialized message of sample ``j`` (encoded 1000 samples at a time)."""
        k = j - self._c0
        if 0 <= k < len(self._cache):
            return self._cache[k]
        idx = slice(j, min(j + 1000, len(self.t)))
        vals = np.zeros((idx.stop - j, len(self.layout.fields)))
        vals[:, self.cols] = self.data[idx]
        self._c0, self._cache = j, self.layout.encode(self.t[idx] + self.offset, vals)
        return self._cache[0]


class SensorDriver(Node):
    """Publish simulated or recorded sensor streams in real time (times ``rate``)."""

    def __init__(self):
        super().__init__("sensor_driver")
        p = self.declare_parameter
        p("experiment", "")
        p("recording", "")
        p("rate", 1.0)
        p("duration", 0.0)
        p("restamp", False)
        p("rig_out", "")
        p("wait_for", None, ParameterDescriptor(dynamic_typing=True, description="TOPIC[:COUNT] list"))
        p("wait_timeout", 60.0)
        p("start_delay", 0.5)
        p("publish_period", 0.01)
        p("exit_when_done", False)
        p("silence", None, ParameterDescriptor(dynamic_typing=True, description="TOPIC:T0:T1 list"))
        p("executor", "events")
        self.frames = declare_frame_ids(self, ("imu", "load_cell", "exciter", "inclinometer"))
        get = lambda n: self.get_parameter(n).value  # noqa: E731
        self.rate = float(get("rate"))
        if not self.rate > 0:
            raise ValueError(f"parameter rate = {self.rate}: must be > 0")
        self.restamp = bool(get("restamp"))
        self.wait_for = [w for w in (get("wait_for") or []) if w]
        self.wait_timeout = float(get("wait_timeout"))
        self.start_delay = float(get("start_delay"))
        self.exit_when_done = bool(get("exit_when_done"))
        self.silence = [w for w in (get("silence") or []) if w]
        self.stop_future = Future()
        self.exit_code = 0

        self.status_pub = self.create_publisher(String, DRIVER_STATUS_TOPIC, LATCHED_QOS)
        self.truth_pub = self.create_publisher(String, TRUTH_TOPIC, LATCHED_QOS)
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=self._diag_values)
        self._matched: dict[str, dict[str, int]] = {}  # topic -> {node: matched readers}
        if self.wait_for:
            self._diag_sub = self.create_subscription(DiagnosticArray, DIAGNOSTICS_TOPIC, self._on_diag,
                                                      DIAGNOSTICS_QOS)
        self.state = "loading"
        self.source = ""
        self._publish_status()

        rig, sensors, truth = self._load(get("experiment"), get("recording"), float(get("duration")))
        self.rig = rig
        self._hand_out(rig, truth, get("rig_out"))
        self.streams = self._make_streams(rig, sensors)
        fr = {IMU_TOPIC: self.frames.imu, EXCITER_TOPIC: self.frames.exciter,
              INCLINOMETER_TOPIC: self.frames.inclinometer}
        log_interface(self, [], [Endpoint(st.publisher, "frame " + fr.get(
            st.topic, self.frames.load_cell_frame(st.topic[len(LOAD_CELL_PREFIX):]))) for st in self.streams]
            + [Endpoint(self.truth_pub, "latched"), Endpoint(self.status_pub, "latched")])
        self._schedule()
        self._t_wait = time.monotonic()
        self._t_ready = None
        self._last_status = 0.0
        self.state = "waiting" if self.wait_for else "publishing"
        if self.state == "publishing":
            self._begin()
        else:
            self.get_logger().info("waiting for subscribers: " + ", ".join(self.wait_for))
        self._publish_status()
        self.timer = self.create_timer(float(get("publish_period")), self._tick)

    def _hand_out(self, rig, truth: dict | None, rig_out: str) -> None:
        """rig.yaml written to ``rig_out`` (atomically: readers never see half a file; "" none) and
        the truth published (latched), before anything else."""
        if rig_out:
            out = Path(rig_out)
            out.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(out, dump_rig(rig, f"rig description published by sensor_driver ({self.source})"))
            self.get_logger().info(f"wrote the rig description to {out}")
        if truth is not None:
            self.truth_pub.publish(String(data=to_json(truth)))

    def _schedule(self) -> None:
        """The merged publication order of every stream's samples: by stamp, ties in stream order
        (as recording.sensor_messages), the silenced spans left out."""
        t_all = np.concatenate([s.t for s in self.streams])
        k_all = np.concatenate([np.full(len(s.t), k) for k, s in enumerate(self.streams)])
        i_all = np.concatenate([np.arange(len(s.t)) for s in self.streams])
        order = np.lexsort((k_all, t_all))
        keep = self._silence_mask(t_all[order] - t_all.min(), k_all[order])
        order = order[keep]
        self.ev_t = t_all[order].tolist()
        self.ev_k_arr, self.ev_i_arr = k_all[order], i_all[order]
        self.ev_k, self.ev_i = self.ev_k_arr.tolist(), self.ev_i_arr.tolist()
        self.n_events = len(self.ev_t)
        self.next = 0
        self.stalls = 0  # publish attempts refused by a full KEEP_ALL writer (back-pressure)
        self.t_first = self.ev_t[0]
        self.total = {s.topic: int(np.count_nonzero(self.ev_k_arr == k)) for k, s in enumerate(self.streams)}

    # --- source ------------------------------------------------------------------------
    def _load(self, experiment: str, recording: str, duration: float):
        if experiment and recording:
            raise ValueError("give either parameter experiment or recording, not both")
        if recording:
            rec = read_recording(recording)
            for w in rec.warnings:
                self.get_logger().warn(w)
            self.source = f"recording {recording}"
            sensors = rec.sensors
            if duration > 0:
                sensors = _cut(sensors, sensors.t_start + duration)
            self.get_logger().info(f"replaying {self.source}: {sensors.t_end - sensors.t_start:.1f} s of data")
            return rec.rig, sensors, rec.truth
        path = experiment or str(default_experiment())
        exp = load_experiment(path)
        if duration > 0:
            exp = exp.with_overrides(duration=duration)
        self.source = f"simulation of {path}"
        self.get_logger().info(f"simulating {path} ({exp.static.duration if exp.static else exp.duration:.0f} s)...")
        sim = simulate(exp)
        self.get_logger().info(f"simulated in {sim.wall_time:.1f} s")
        return sim.rig, sim.sensors, sim.truth

    def _make_streams(self, rig, sensors) -> list[_Stream]:
        streams = []

        def pub(topic, mtype):
            return self.create_publisher(mtype, topic, SENSOR_QOS)

        imu = Imu()
        imu.orientation.w = 1.0
        imu.orientation_covariance[0] = -1.0
        fr = self.frames
        streams.append(_Stream(IMU_TOPIC, pub(IMU_TOPIC, Imu), imu_layout(fr.imu, imu),
                               range(6), sensors.imu.t, sensors.imu.data))
        for name in rig.cable_names:
            topic = LOAD_CELL_PREFIX + name
            s = sensors.load_cells[name]
            streams.append(_Stream(topic, pub(topic, WrenchStamped), wrench_layout(fr.load_cell_frame(name)),
                                   [2], s.t, s.data))
        if sensors.exciter is not None:
            streams.append(_Stream(EXCITER_TOPIC, pub(EXCITER_TOPIC, WrenchStamped),
                                   wrench_layout(fr.exciter), [0, 1], sensors.exciter.t,
                                   sensors.exciter.data))
        if sensors.inclinometer is not None:
            streams.append(_Stream(INCLINOMETER_TOPIC, pub(INCLINOMETER_TOPIC, Vector3Stamped),
                                   vector_layout(fr.inclinometer), [0, 1], sensors.inclinometer.t,
                                   sensors.inclinometer.data))
        return streams

    def _silence_mask(self, t_rel: np.ndarray, k: np.ndarray) -> np.ndarray:
        """Events to publish: all but those of the ``silence`` entries "TOPIC:T0:T1" (the
        topic publishes nothing for data times T0 <= t < T1 s after the first sample: a
        sensor that stops, for fault tests)."""
        keep = np.ones(len(t_rel), bool)
        topics = [s.topic for s in self.streams]
        for entry in self.silence:
            try:
                topic, a, b = entry.rsplit(":", 2)
                a, b = float(a), float(b)
            except ValueError:
                raise ValueError(f"parameter silence: {entry!r} is not TOPIC:T0:T1") from None
            if topic not in topics:
                raise ValueError(f"parameter silence: {topic} is not published ({', '.join(topics)})")
            keep &= ~((k == topics.index(topic)) & (t_rel >= a) & (t_rel < b))
            self.get_logger().warn(f"fault injection: {topic} silent from t={a:g} to {b:g} s")
        return keep

    # --- publishing ----------------------------------------------------------------------
    def _ready(self) -> bool:
        own = {s.topic: s.publisher for s in self.streams}
        for w in self.wait_for:
            topic, _, n = w.partition(":")
            need = int(n) if n else 1
            if topic.endswith("*"):  # every own topic with this prefix
                topics = [t for t in own if t.startswith(topic[:-1])]
            else:
                topics = [topic]
            for tp in topics:
                have = own[tp].get_subscription_count() if tp in own else \
                    max(self._matched.get(tp, {}).values(), default=0)
                if have < need:
                    return False
        return True

    def _on_diag(self, msg) -> None:
        for st in msg.status:
            for kv in st.values:
                if kv.key.startswith("matched "):
                    try:
                        self._matched.setdefault(kv.key[8:], {})[st.name] = int(kv.value)
                    except ValueError:
                        pass

    def _begin(self) -> None:
        offset = 0.0
        if self.restamp:
            offset = self.get_clock().now().nanoseconds * 1e-9 - self.t_first
        for s in self.streams:
            s.offset = offset
        self.state = "publishing"
        self.wall0 = time.monotonic()
        self.get_logger().info(f"publishing {self.n_events} messages on {len(self.streams)} topics "
                               f"({self.ev_t[-1] - self.t_first:.1f} s of data at {self.rate:g}x real time)")

    def _tick(self) -> None:
        now = time.monotonic()
        if self.state == "waiting":
            if self._t_ready is None:
                if self._ready():
                    self._t_ready = now
                elif now - self._t_wait > self.wait_timeout:
                    self.get_logger().warn(f"subscribers still missing after {self.wait_timeout:.0f} s; "
                                           "publishing anyway")
                    self._t_ready = now
            if self._t_ready is not None and now - self._t_ready >= self.start_delay:
                self._begin()
                self._publish_status()
            return
        if self.state == "done":
            self._linger(now)
            return
        if self.state != "publishing":
            return
        target = self.t_first + (now - self.wall0) * self.rate
        i, n = self.next, self.n_events
        j = bisect.bisect_right(self.ev_t, target, lo=i)
        streams, ev_k, ev_i = self.streams, self.ev_k, self.ev_i
        while i < j:
            s = streams[ev_k[i]]
            try:
                s.publisher.publish(s.raw(ev_i[i]))
            except Exception:  # a slow reliable reader holds the writer full: retry next tick
                self.next = i
                self.stalls += 1
                return
            s.published += 1
            i += 1
        self.next = i
        if i >= n:
            self.state = "done"
            wall = now - self.wall0
            self.achieved = {"wall_seconds": wall, "rate": (self.ev_t[-1] - self.t_first) / max(wall, 1e-9),
                             "back_pressure_stalls": self.stalls}
            self.get_logger().info(f"done: published {n} messages in {wall:.1f} s "
                                   f"({self.achieved['rate']:.2f}x real time)")
            self._publish_status()
            self._t_done = now
        elif now - self._last_status > 1.0:
            self._publish_status()

    def _linger(self, now: float) -> None:
        """With exit_when_done: stop once every reliable reader has acknowledged every message
        (the latched status included), at most :data:`LINGER_SECONDS` after the last one. A
        process that exits at once loses what DDS has not yet delivered."""
        if not self.exit_when_done or self.stop_future.done():
            return
        pubs = [s.publisher for s in self.streams] + [self.status_pub]
        if all(p.wait_for_all_acked(Duration(seconds=0)) for p in pubs) or now - self._t_done > LINGER_SECONDS:
            self.stop_future.set_result(True)

    def _diag_values(self) -> dict:
        d = {"state": self.state, "back-pressure stalls": getattr(self, "stalls", 0)}
        for s in getattr(self, "streams", []):
            d[f"tx {s.topic}"] = s.published
        return d

    def _publish_status(self) -> None:
        self._last_status = time.monotonic()
        d = {"state": self.state, "source": self.source, "rate": self.rate}
        if hasattr(self, "streams"):
            d["total"] = self.total
            d["published"] = {s.topic: s.published for s in self.streams}
            d["t_start"] = self.t_first
            d["t_end"] = self.ev_t[-1]
            d["cables"] = self.rig.cable_names
        if getattr(self, "achieved", None):
            d["achieved"] = self.achieved
        self.status_pub.publish(String(data=to_json(d)))


def _cut(sensors, t_end: float):
    """SensorData restricted to stamps <= t_end."""

    def cut(s):
        if s is None:
            return None
        m = s.t <= t_end
        return TimeSeries(s.t[m], s.data[m])
    return SensorData(cut(sensors.imu), {k: cut(v) for k, v in sensors.load_cells.items()},
                      cut(sensors.exciter), cut(sensors.inclinometer))


def main(argv=None) -> int:
    return run(SensorDriver, argv, "sensor_driver", __doc__)


if __name__ == "__main__":
    sys.exit(main())
