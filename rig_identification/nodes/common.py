"""Shared helpers of the rig_identification nodes: QoS, topic names, rig loading, input
validation with throttled warnings, diagnostics, command line and spinning.  The batch
message codec is in ``codec.py``, frame-id parameters and the start-up interface line in
``frames.py`` (both re-exported here).

QoS (one choice for the whole pipeline, see :data:`SENSOR_QOS`):

* sensor and derived streams (``/rig/imu``, ``/rig/load_cells/*``, ``/rig/exciter/wrench``,
  ``/rig/inclinometer``, ``/rig/pose``, ``/rig/generalized_wrench``): RELIABLE, VOLATILE,
  KEEP_ALL, on writers and readers.  The identifier needs every sample (it integrates the
  moment; a gap makes it refuse the window), so:

  - not ``qos_profile_sensor_data`` (BEST_EFFORT, depth 5): drops under any load;
  - not RELIABLE KEEP_LAST N: a sample lost in transport (a starved reader's shared-memory
    port overflowing) is repaired only while the writer still holds it, and KEEP_LAST
    overwrites it after N newer samples whether acknowledged or not.  Measured on this
    2-core machine (shared with other jobs): KEEP_LAST 1000 lost ~600 of 24000 wrenches at
    3x real time, KEEP_LAST 10000 still lost ~3 % of the load-cell samples; a 20000-message
    burst into a slow reader lost 92 % with KEEP_LAST 1000;
  - RELIABLE KEEP_ALL keeps every sample until each reliable reader has acknowledged it:
    the same burst arrived whole (0 lost); when a reader falls behind, ``publish`` blocks
    (Fast DDS resource limits bound the memory), i.e. back-pressure: a replay slows down
    instead of losing data.  A real sensor driver would buffer instead.

  A RELIABLE writer also serves BEST_EFFORT readers (``ros2 topic echo --qos-profile
  sensor_data``, rviz), which exert no back-pressure.  The consumers' readers are RELIABLE
  by default, which does not match a BEST_EFFORT writer (a hardware driver publishing with
  sensor-data QoS): set their parameter ``input_reliability`` to ``best_effort`` then.
  VOLATILE: samples written before a reader has matched are never delivered to it, and the
  ROS graph can list a reader seconds before the DDS writer has matched it (measured: the
  first 2.4 s of poses missing in 1 run of 5).  So a replay starts only when every writer
  reports its readers as matched (sensor_driver ``wait_for``; the nodes publish
  ``matched <topic>`` on /diagnostics).
* results and one-off information (``/rig/mass_properties``, ``/rig/sim_truth``,
  ``/rig/sensor_driver/status``): RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1 ("latched"):
  a subscriber that joins later still receives the last message.

Inputs at 1 kHz: the consumer nodes subscribe with ``raw=True`` (the callback only queues the
serialized bytes) and decode each topic's queue in one ``np.frombuffer`` every few ms
(:class:`~.codec.MessageLayout` in ``codec.py``, :class:`RawInput`); they publish their outputs serialized the same
way.  A Python message object per sample cost ~35 µs in rclpy, a raw take ~10 µs (6 topics
at 1 kHz, measured).  Validation (:class:`InputGuard`) and the stamp-order merge
(:class:`StampMerger`) work on the batches.

Faults: :class:`InputGuard` records stamp gaps per input topic, :class:`Diagnostics`
reports each input OK / WARN stale / ERROR stopped on /diagnostics.  A node process that is
killed leaves its readers matched to the reliable KEEP_ALL writers until its DDS participant
lease expires; :func:`dds_profile` shortens that lease to 3 s (``config/dds/fastdds.xml``)
so that the writers are not held back for Fast DDS's default 20 s.

Executor: :func:`spin` runs a node on ``rclpy.experimental.EventsExecutor`` (parameter
``executor``: ``events`` (default) or ``single``).  In the pip build of rclpy 7.1.6 the
EventsExecutor's blocking ``spin()``/``spin_once()`` without a timeout hang (no callback
runs), while the timed variants work; :func:`spin` therefore spins in slices of 1 s.
That rclpy also does not support ``async`` service callbacks on the EventsExecutor
(fixed upstream in rclpy 7.1.11), see ``identifier_node`` for how the identifier copes.
"""
from __future__ import annotations

import json
import math
import os
import sys
import time
from pathlib import Path
from typing import Callable, Iterable

import numpy as np
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..io.rig import Rig, RigError
from .codec import (IMU_FIELDS, ODOMETRY_FIELDS, VECTOR_FIELDS, WRENCH_FIELDS, MessageLayout,  # noqa: F401
                    PersistentReason, imu_layout, odometry_layout, split_stamps, vector_layout, wrench_layout)
from .frames import (BODY_FRAME, EXCITER_FRAME, IMU_FRAME, INCLINOMETER_FRAME, WORLD_FRAME,  # noqa: F401
                     Endpoint, FrameIds, declare_frame_ids, log_interface)
from .merge import StampMerger  # noqa: F401
from ..model.simulator import load_rig_or_experiment
from ..io.recording import SHORT_GAP

PACKAGE = "rig_identification"

#: Sensor and derived streams: RELIABLE, VOLATILE, KEEP_ALL (see module docstring).
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
#: Readers for BEST_EFFORT writers (parameter input_reliability: best_effort).
BEST_EFFORT_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10000,
                                   reliability=ReliabilityPolicy.BEST_EFFORT,
                                   durability=DurabilityPolicy.VOLATILE)
#: Latched results: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 1.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: /diagnostics, as the ROS diagnostics tools use it.
DIAGNOSTICS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                             reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)

# topic names (RECORDING_FORMAT.md and the node contract)
IMU_TOPIC = "/rig/imu"
LOAD_CELL_PREFIX = "/rig/load_cells/"
EXCITER_TOPIC = "/rig/exciter/wrench"
INCLINOMETER_TOPIC = "/rig/inclinometer"
POSE_TOPIC = "/rig/pose"
WRENCH_TOPIC = "/rig/generalized_wrench"
MASS_PROPERTIES_TOPIC = "/rig/mass_properties"
TRUTH_TOPIC = "/rig/sim_truth"
DRIVER_STATUS_TOPIC = "/rig/sensor_driver/status"
DIAGNOSTICS_TOPIC = "/diagnostics"
# a service client waits this long after wait_for_service() before its first call: the server's side
# of the discovery (its response writer matched with our reader) can lag the client's, and a response
# sent before it is dropped by Fast DDS ("failed to send response (timeout)"; ros2/ros2#1017)
SERVICE_SETTLE_SECONDS = 0.5

# default frame ids (RECORDING_FORMAT.md); the nodes take theirs from parameters (frames.py)


def load_cell_frame(cable: str) -> str:
    """The default frame id of the load cell of ``cable`` (``load_cell_<cable>``)."""
    return FrameIds().load_cell_frame(cable)


# --- time stamps ------------------------------------------------------------------------

def stamp_to_sec(stamp) -> float:
    """builtin_interfaces/Time -> float seconds."""
    return stamp.sec + stamp.nanosec * 1e-9


def split_stamp(t: float) -> tuple[int, int]:
    """Float seconds -> (sec, nanosec) with 0 <= nanosec < 1e9."""
    sec = math.floor(t)
    nsec = int(round((t - sec) * 1e9))
    if nsec >= 1_000_000_000:
        sec, nsec = sec + 1, nsec - 1_000_000_000
    return int(sec), nsec


def set_stamp(header, t: float, frame_id: str | None = None) -> None:
    """Write float seconds ``t`` (and optionally the frame id) into a std_msgs/Header in place."""
    header.stamp.sec, header.stamp.nanosec = split_stamp(t)
    if frame_id is not None:
        header.frame_id = frame_id


def xyz(v) -> tuple[float, float, float]:
    """geometry_msgs Vector3/Point -> tuple."""
    return (v.x, v.y, v.z)


def set_xyz(msg_vec, values) -> None:
    msg_vec.x, msg_vec.y, msg_vec.z = (float(values[0]), float(values[1]), float(values[2]))


# --- files --------------------------------------------------------------------------------

def package_file(relpath: str) -> Path:
    """A data file of the package: the colcon share directory when installed with colcon
    (found through the ament index), else the source tree (pip editable install, repo)."""
    try:
        from ament_index_python.packages import get_package_share_directory
        p = Path(get_package_share_directory(PACKAGE)) / relpath
        if p.exists():
            return p
    except Exception:  # PackageNotFoundError, or no ament index at all
        pass
    here = Path(__file__).resolve().parent.parent  # rig_identification/
    for base in (here / "data", here.parent):
        p = base / relpath
        if p.exists():
            return p
    return here.parent / relpath


def default_experiment() -> Path:
    """The embedded default experiment ``config/rigs/default.yaml``."""
    return package_file("config/rigs/default.yaml")


DDS_PROFILE_VARS = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")  # Fast DDS 2.x, 3.x


def dds_profile(env: dict | None = None) -> None:
    """Point Fast DDS at the package's participant profile ``config/dds/fastdds.xml`` (a 3 s
    participant lease instead of 20 s: a killed node's readers stop holding the reliable
    KEEP_ALL writers back after 3 s) unless a profile file is set already
    (``FASTRTPS_DEFAULT_PROFILES_FILE``, read by Fast DDS 2.x as in Jazzy, or
    ``FASTDDS_DEFAULT_PROFILES_FILE``, 3.x).  ``env``: the environment to change (default
    ``os.environ``; call before ``rclpy.init``)."""
    env = os.environ if env is None else env
    if any(env.get(v) for v in DDS_PROFILE_VARS):
        return
    p = package_file("config/dds/fastdds.xml")
    if p.exists():
        for v in DDS_PROFILE_VARS:
            env[v] = str(p)


def load_rig_source(path: str | Path) -> Rig:
    """The rig description of ``path``: a rig.yaml, a recording folder (its rig.yaml) or an
    experiment file (its ``rig:`` section, as ``config/rigs/default.yaml``: what the
    sensor_driver's simulation of that file writes as rig.yaml, unless the experiment has
    effects that change rig.yaml — then give the driver's ``rig_out`` file).

    Raises :class:`~rig_identification.io.rig.RigError` naming the file (missing file, no
    rig.yaml in the folder, bad field)."""
    p = Path(path)
    if p.is_dir():
        if not (p / "rig.yaml").is_file():
            raise RigError(f"{p}: a folder without rig.yaml (expected a rig.yaml, an experiment file or a "
                           "recording folder)")
        p = p / "rig.yaml"
    # simulator (scipy.integrate) imported only here: the nodes that take no rig file skip it
    return load_rig_or_experiment(p)


def load_rig_param(node: Node) -> Rig:
    """Load the rig description named by the node's ``rig`` parameter: a rig.yaml, a
    recording folder or an experiment file (:func:`load_rig_source`).

    Raises :class:`~rig_identification.io.rig.RigError` with a clear message.
    """
    path = node.get_parameter("rig").value
    if not path:
        raise RigError("parameter 'rig' is empty: give the path of the rig description, "
                       "e.g. --ros-args -p rig:=/path/to/rig.yaml")
    return load_rig_source(path)


def core_params(node: Node, func, skip=()) -> dict:
    """Declare a ROS parameter for every keyword argument of the core function ``func`` whose
    default is a number, bool or string (the core's own default, so node and core never
    disagree) and return the current values, ready to pass as ``**kwargs``."""
    import inspect
    out = {}
    for name, p in inspect.signature(func).parameters.items():
        if name in skip or p.default is inspect.Parameter.empty:
            continue
        if isinstance(p.default, (bool, int, float, str)):
            node.declare_parameter(name, p.default)
            out[name] = node.get_parameter(name).value
    return out


def publish_blocking(publisher, msg, patience: float = 30.0) -> None:
    """Publish on a KEEP_ALL reliable writer, waiting while a slow reader holds it full.

    Fast DDS blocks a full KEEP_ALL writer for at most 100 ms (max_blocking_time) and then
    fails; this retries for up to ``patience`` s (back-pressure travels upstream, nothing is
    lost) before raising the last error."""
    end = time.monotonic() + patience
    while True:
        try:
            publisher.publish(msg)
            return
        except Exception:
            if time.monotonic() > end or not rclpy.ok():
                raise


def input_qos(node: Node) -> QoSProfile:
    """QoS of a consumer node's stream subscriptions, from its ``input_reliability`` parameter
    (``reliable``: :data:`SENSOR_QOS`; ``best_effort``: :data:`BEST_EFFORT_INPUT_QOS`)."""
    if not node.has_parameter("input_reliability"):
        node.declare_parameter("input_reliability", "reliable")
    v = node.get_parameter("input_reliability").value
    if v == "reliable":
        return SENSOR_QOS
    if v == "best_effort":
        return BEST_EFFORT_INPUT_QOS
    raise ValueError(f"parameter input_reliability = {v!r}: expected 'reliable' or 'best_effort'")


# --- input validation --------------------------------------------------------------------

class InputGuard:
    """Validate incoming messages; count and report the rejected ones; watch each input
    stream for gaps and silence.

    A message is rejected when its frame id is not the expected one, a value is not
    finite, or its stamp is not after the previous accepted stamp of the same topic.
    Rejections are logged as warnings throttled per topic (every ``period`` s at most,
    with the number suppressed since), and counted for the diagnostics.  A reason that
    will hold for every later message (:class:`~.codec.PersistentReason`: a frame id that
    is not the expected one) is warned once per topic and reason, naming the parameter to
    set; the messages are still counted.  Warnings name a remapped topic by its resolved
    name (:meth:`alias`); the keys stay the node's own names (``/rig/imu``).

    Gaps: two consecutive accepted stamps of a topic further apart than
    ``max(max_gap, 1.5 × the topic's typical sampling period)`` (the offline rule of
    :func:`~rig_identification.io.recording.find_bad_spans`) are recorded in ``gaps[topic]``
    as (t0, t1) header stamps (the last ``keep_gaps``).  ``last_arrival[topic]`` is the
    monotonic wall time of the latest message (silence: see :class:`Diagnostics`).
    """

    def __init__(self, node: Node, period: float = 5.0, max_gap: float | None = None, keep_gaps: int = 100):
        self.node = node
        self.period = period
        self.max_gap = SHORT_GAP if max_gap is None else max_gap
        self.keep_gaps = keep_gaps
        self.last: dict[str, float] = {}
        self.received: dict[str, int] = {}
        self.rejected: dict[str, int] = {}
        self.gaps: dict[str, list[tuple[float, float]]] = {}
        self.last_arrival: dict[str, float] = {}
        self._dt: dict[str, list[float]] = {}  # first intervals of each topic (typical period)
        self._period: dict[str, float] = {}
        self._warned: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}
        self._said_once: set[tuple[str, str]] = set()
        self.resolved: dict[str, str] = {}

    def alias(self, topic: str, resolved: str) -> None:
        """Name ``topic`` (the node's own name) as ``resolved`` (after remapping) in warnings."""
        if resolved != topic:
            self.resolved[topic] = resolved

    def label(self, topic: str) -> str:
        """``topic``, or ``/my/imu (remapped /rig/imu)`` when it is remapped."""
        r = self.resolved.get(topic)
        return topic if r is None else f"{r} (remapped {topic})"

    def expect(self, topic: str) -> None:
        """Declare an input topic (reported on /diagnostics before its first message)."""
        self.received.setdefault(topic, 0)
        self.rejected.setdefault(topic, 0)

    def accept(self, topic: str, header, frame: str | None, values: Iterable[float]) -> float | None:
        """Return the stamp (s) of an acceptable message, else None (after counting/warning)."""
        self.received[topic] = self.received.get(topic, 0) + 1
        self.last_arrival[topic] = time.monotonic()
        if frame is not None and header.frame_id != frame:
            return self.reject(topic, PersistentReason(f"frame_id {header.frame_id!r}, expected {frame!r}"))
        t = stamp_to_sec(header.stamp)
        for v in values:
            if not math.isfinite(v):
                return self.reject(topic, f"non-finite value at stamp {t:.6f}")
        prev = self.last.get(topic)
        if prev is not None and t <= prev:
            return self.reject(topic, f"stamp {t:.6f} s not after the previous one ({prev:.6f} s)")
        if prev is not None and t - prev > self.max_gap:
            self._watch_gaps(topic, np.array([prev, t]))
        self.last[topic] = t
        return t

    def accept_batch(self, topic: str, t: np.ndarray, values: np.ndarray, bad: dict | None = None) -> np.ndarray:
        """:meth:`accept` for a batch: stamps t (n,) s, values (n, k), ``bad`` {row: reason}
        for rows refused before (decoding).  Returns the (n,) mask of accepted rows."""
        n = len(t)
        self.received[topic] = self.received.get(topic, 0) + n
        if n == 0:
            return np.ones(0, bool)
        self.last_arrival[topic] = time.monotonic()
        finite = np.isfinite(values).all(1) & np.isfinite(t)
        prev = self.last.get(topic, -math.inf)
        if not bad and finite.all() and t[0] > prev and (n == 1 or (t[1:] > t[:-1]).all()):
            self._watch_gaps(topic, t if prev == -math.inf else np.concatenate([[prev], t]))
            self.last[topic] = float(t[-1])
            return finite
        good = finite.copy()
        for i in (bad or {}):
            good[i] = False
        before = np.maximum.accumulate(np.concatenate([[prev], np.where(good, t, -math.inf)]))[:-1]
        ok = good & (t > before)
        if not ok.all():
            for i in np.nonzero(~ok)[0].tolist():
                if bad and i in bad:
                    why = bad[i]
                elif not finite[i]:
                    why = f"non-finite value at stamp {t[i]:.6f}"
                else:
                    why = f"stamp {t[i]:.6f} s not after the previous one ({before[i]:.6f} s)"
                self.reject(topic, why)
        if ok.any():
            ta = t[ok]
            self._watch_gaps(topic, ta if prev == -math.inf else np.concatenate([[prev], ta]))
            self.last[topic] = float(ta[-1])
        return ok

    def _watch_gaps(self, topic: str, ts: np.ndarray) -> None:
        """Record the gaps between consecutive accepted stamps ``ts`` of ``topic``."""
        if len(ts) < 2:
            return
        dt = ts[1:] - ts[:-1]
        period = self._period.get(topic)
        if period is None:  # typical period: median of the first 50 intervals
            first = self._dt.setdefault(topic, [])
            first.extend(dt[:50 - len(first)].tolist())
            if len(first) >= 50:
                self._period[topic] = period = float(np.median(first))
                del self._dt[topic]
            else:
                period = float(np.median(first))
        limit = max(self.max_gap, 1.5 * period)
        if dt.max() <= limit:
            return
        big = np.nonzero(dt > limit)[0]
        if len(big):
            spans = self.gaps.setdefault(topic, [])
            spans.extend((float(ts[i]), float(ts[i + 1])) for i in big.tolist())
            del spans[:-self.keep_gaps]

    def gaps_in(self, lo: float, hi: float, topics=None) -> list[tuple[str, float, float]]:
        """Gaps (topic, t0, t1) overlapping the stamp window [lo, hi], including an open one
        when a topic's last stamp is older than ``hi`` by more than its gap threshold."""
        out = []
        for topic in (self.gaps if topics is None else topics):
            for a, b in self.gaps.get(topic, []):
                if a < hi and b > lo:
                    out.append((topic, a, b))
        for topic in (self.last if topics is None else topics):
            last = self.last.get(topic)
            if last is None:
                continue
            limit = max(self.max_gap, 1.5 * self._period.get(topic, 0.0))
            if hi - last > limit and last < hi:
                out.append((topic, last, hi))
        return sorted(out, key=lambda g: g[1])

    def reject(self, topic: str, why: str) -> None:
        """Count a rejected message of ``topic`` and warn: throttled per topic, or once per
        topic and reason for a :class:`~.codec.PersistentReason`."""
        self.rejected[topic] = self.rejected.get(topic, 0) + 1
        if isinstance(why, PersistentReason):
            if (topic, why) not in self._said_once:
                self._said_once.add((topic, why))
                self.node.get_logger().warn(
                    f"dropped a malformed message on {self.label(topic)}: {why}; every further message like it "
                    "is dropped without a warning (counted on /diagnostics as rejected)")
            return None
        now = time.monotonic()
        if now - self._warned.get(topic, -math.inf) >= self.period:
            extra = self._suppressed.pop(topic, 0)
            more = f" ({extra} more rejected since the last warning)" if extra else ""
            self.node.get_logger().warn(f"dropped a malformed message on {self.label(topic)}: {why}{more}")
            self._warned[topic] = now
        else:
            self._suppressed[topic] = self._suppressed.get(topic, 0) + 1
        return None

    def core_error(self, topic: str, err: Exception) -> None:
        """The core refused an input that passed the checks: count it like a malformed message."""
        self.reject(topic, f"{type(err).__name__}: {err}")


class RawInput:
    """A stream subscription that takes serialized messages (``raw=True``: the callback only
    queues the bytes) and decodes and validates them in batches (:meth:`take`)."""

    def __init__(self, node: Node, guard: "InputGuard", topic: str, layout: MessageLayout, qos):
        self.topic, self.layout, self.guard = topic, layout, guard
        self.pending: list[bytes] = []
        self.sub = node.create_subscription(layout.msg_type, topic, self.pending.append, qos, raw=True)
        guard.expect(topic)
        guard.alias(topic, self.sub.topic_name)

    def endpoint(self) -> Endpoint:
        """This input for :func:`~.frames.log_interface` (resolved name, type, expected frames)."""
        names = {"header.frame_id": "frame", "child_frame_id": "child"}
        note = ", ".join(f"{names.get(path, path)} {value}" for path, value in self.layout.strings.items())
        return Endpoint(self.sub, note)

    def take(self) -> tuple[np.ndarray, np.ndarray]:
        """Decode, validate (:meth:`InputGuard.accept_batch`) and return the accepted
        messages queued so far: stamps (m,) s and values (m, k)."""
        raws = self.pending[:]
        if not raws:
            return np.empty(0), np.empty((0, len(self.layout.fields)))
        del self.pending[:len(raws)]
        t, vals, bad = self.layout.decode(raws)
        ok = self.guard.accept_batch(self.topic, t, vals, bad)
        if ok.all():
            return t, vals
        return t[ok], vals[ok]


# --- diagnostics ---------------------------------------------------------------------------

class Diagnostics:
    """Publish the node's state on ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) once per
    ``period`` s.

    * One status named after the node: ``rx <topic>``, ``rejected <topic>``, ``tx <topic>``,
      ``matched <topic>`` (readers matched by this node's writer, DDS level: what a sensor
      driver waits for before it starts) plus any extra key/values; level WARN when a
      message was rejected or an input is stale, ERROR when an input stopped.
    * One status per input topic, named ``<node>: <topic>``: OK while messages arrive;
      WARN "stale" when none came for ``stale_after`` s (wall time); ERROR "stopped" after
      ``stopped_after`` s; WARN "no message yet" before the first.  Values: ``age_s`` since
      the last message, ``rate_hz`` over the last period, ``received``, ``rejected``,
      ``gaps`` (stamp gaps seen, :class:`InputGuard`) and ``last_gap`` (its stamps).
      The node parameters ``stale_after`` (0.5 s) and ``stopped_after`` (2.0 s) set the
      thresholds.
    """

    def __init__(self, node: Node, guard: InputGuard, period: float = 1.0,
                 extra: Callable[[], dict] | None = None):
        from diagnostic_msgs.msg import DiagnosticArray
        self.node, self.guard, self.extra = node, guard, extra
        for name, default in (("stale_after", 0.5), ("stopped_after", 2.0)):
            if not node.has_parameter(name):
                node.declare_parameter(name, default)
        self.stale_after = float(node.get_parameter("stale_after").value)
        self.stopped_after = float(node.get_parameter("stopped_after").value)
        self.sent: dict[str, int] = {}
        self.writers: dict[str, object] = {}
        self._rx_prev: dict[str, int] = {}
        self._t_prev = time.monotonic()
        self.pub = node.create_publisher(DiagnosticArray, DIAGNOSTICS_TOPIC, DIAGNOSTICS_QOS)
        self.timer = node.create_timer(period, self.publish)

    def add_writer(self, topic: str, publisher) -> None:
        """Report the matched-reader count of ``publisher`` as ``matched <topic>``."""
        self.writers[topic] = publisher

    def count_tx(self, topic: str, n: int = 1) -> None:
        self.sent[topic] = self.sent.get(topic, 0) + n

    def values(self) -> dict:
        g = self.guard
        out = {}
        for topic in sorted(set(g.received) | set(g.rejected)):
            out[f"rx {topic}"] = g.received.get(topic, 0)
            out[f"rejected {topic}"] = g.rejected.get(topic, 0)
        for topic in sorted(self.sent):
            out[f"tx {topic}"] = self.sent[topic]
        for topic, pub in self.writers.items():
            out[f"matched {topic}"] = pub.get_subscription_count()
        if self.extra is not None:
            out.update(self.extra())
        return out

    def input_states(self) -> dict[str, tuple[int, str, dict]]:
        """topic -> (level, message, values) of each input stream (see the class)."""
        from diagnostic_msgs.msg import DiagnosticStatus as S
        g, now = self.guard, time.monotonic()
        dt = max(now - self._t_prev, 1e-9)
        out = {}
        for topic in sorted(g.received):
            n = g.received.get(topic, 0)
            last = g.last_arrival.get(topic)
            age = None if last is None else now - last
            if age is None:
                level, msg = S.WARN, "no message yet"
            elif age >= self.stopped_after:
                level, msg = S.ERROR, f"stopped: no message for {age:.1f} s"
            elif age >= self.stale_after:
                level, msg = S.WARN, f"stale: no message for {age:.1f} s"
            else:
                level, msg = S.OK, "ok"
            gaps = g.gaps.get(topic, [])
            rate = (n - self._rx_prev.get(topic, 0)) / dt
            vals = {"age_s": "" if age is None else f"{age:.3f}", "rate_hz": f"{rate:.1f}",
                    "received": n, "rejected": g.rejected.get(topic, 0), "gaps": len(gaps)}
            if gaps:
                vals["last_gap"] = f"{gaps[-1][0]:.6f} {gaps[-1][1]:.6f}"
            out[topic] = (level, msg, vals)
        return out

    def publish(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        vals = self.values()
        inputs = self.input_states()
        self._rx_prev = dict(self.guard.received)
        self._t_prev = time.monotonic()
        name = self.node.get_fully_qualified_name()
        rejected = sum(self.guard.rejected.values())
        st = DiagnosticStatus(name=name, hardware_id="rig")
        worst = max((lv for lv, _, _ in inputs.values()), default=DiagnosticStatus.OK)
        problems = [f"{t} {m.split(':')[0]}" for t, (lv, m, _) in inputs.items() if lv != DiagnosticStatus.OK]
        st.level = max(worst, DiagnosticStatus.WARN if rejected else DiagnosticStatus.OK)
        parts = ([f"{rejected} malformed message(s) dropped"] if rejected else []) + problems
        st.message = "; ".join(parts) if parts else "ok"
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        statuses = [st]
        for topic, (level, msg, v) in inputs.items():
            s = DiagnosticStatus(name=f"{name}: {topic}", hardware_id="rig", level=level, message=msg)
            s.values = [KeyValue(key=k, value=str(x)) for k, x in v.items()]
            statuses.append(s)
        arr = DiagnosticArray(status=statuses)
        arr.header.stamp = self.node.get_clock().now().to_msg()
        self.pub.publish(arr)


def diagnostic_values(status) -> dict:
    """DiagnosticStatus -> {key: int|float|str} (numbers parsed back)."""
    out = {}
    for kv in status.values:
        v = kv.value
        try:
            out[kv.key] = int(v)
        except ValueError:
            try:
                out[kv.key] = float(v)
            except ValueError:
                out[kv.key] = v
    return out


# --- command line and spinning -----------------------------------------------------------

def handle_help(argv: list[str] | None, prog: str, doc: str) -> list[str]:
    """Print the node's documentation and exit 0 on ``-h``/``--help`` (before any ROS set-up).

    ROS arguments (after ``--ros-args``) are left for ``rclpy.init``.  Returns ``argv``.
    """
    argv = list(sys.argv if argv is None else argv)
    user = argv[1:argv.index("--ros-args")] if "--ros-args" in argv else argv[1:]
    if "-h" in user or "--help" in user:
        print(f"usage: {prog} [--ros-args -p NAME:=VALUE ... | --params-file FILE]\n")
        print(doc.strip())
        raise SystemExit(0)
    unknown = [a for a in user if a.startswith("-")]
    if unknown:
        print(f"{prog}: error: unknown option(s) {' '.join(unknown)} "
              "(node parameters go after --ros-args, e.g. --ros-args -p rate:=2.0; see --help)",
              file=sys.stderr)
        raise SystemExit(2)
    return argv


def make_executor(kind: str):
    if kind == "events":
        from rclpy.experimental import EventsExecutor
        return EventsExecutor()
    if kind == "single":
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor()
    if kind == "multi":
        from rclpy.executors import MultiThreadedExecutor
        return MultiThreadedExecutor()
    raise ValueError(f"parameter executor = {kind!r}: expected 'events', 'single' or 'multi'")


def spin(node: Node, stop=None) -> None:
    """Spin ``node`` until Ctrl-C / SIGTERM (rclpy's signal handler shuts the context down)
    or until the rclpy Future ``stop`` completes.  Executor from the node's ``executor``
    parameter (declared here when the node has not), default EventsExecutor."""
    from rclpy.task import Future
    if not node.has_parameter("executor"):
        node.declare_parameter("executor", "events")
    kind = node.get_parameter("executor").value
    ex = make_executor(kind)
    ex.add_node(node)
    stop = Future() if stop is None else stop
    try:
        while rclpy.ok() and not stop.done():
            # timed slices: the EventsExecutor of rclpy 7.1.6 hangs in untimed spins
            ex.spin_until_future_complete(stop, timeout_sec=1.0)
    except KeyboardInterrupt:
        pass
    except Exception as e:  # ExternalShutdownException and friends at shutdown
        if rclpy.ok():
            raise
        del e
    finally:
        try:
            ex.shutdown()
        except Exception:
            pass


#: s a node may take to finish after rclpy's context is shut down (Ctrl-C, SIGTERM)
SHUTDOWN_GRACE = 8.0


def shutdown_watchdog(prog: str, grace: float = SHUTDOWN_GRACE) -> None:
    """Daemon thread: once rclpy's context is shut down (the node was told to stop), give
    the node ``grace`` s to finish; if it has not, print every thread's stack on stderr (to
    find the hang) and end the process with status 0 — the stop was requested, and results
    are written atomically (:mod:`..atomic`), so nothing is half-written.  Guards against a
    rare hang of the executor at shutdown (seen once in CI: the tracker did not exit within
    15 s of SIGINT)."""
    import faulthandler
    import threading

    def watch():
        while rclpy.ok():
            time.sleep(0.2)
        time.sleep(grace)
        print(f"{prog}: shutdown did not finish within {grace:g} s of the stop request; exiting "
              "(thread stacks follow)", file=sys.stderr, flush=True)
        faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
        sys.stderr.flush()
        os._exit(0)

    threading.Thread(target=watch, name="shutdown-watchdog", daemon=True).start()


def run(node_factory: Callable[[], Node], argv: list[str] | None, prog: str, doc: str) -> int:
    """Standard ``main`` of a node: help, rclpy init, construct, spin, clean shutdown
    (bounded: :func:`shutdown_watchdog`).

    A start-up error that the user can fix (bad rig.yaml, missing file, bad parameter)
    prints one line on stderr and returns 2, no traceback.
    """
    argv = handle_help(argv, prog, doc)
    dds_profile()
    rclpy.init(args=argv)
    shutdown_watchdog(prog)
    node = None
    try:
        try:
            node = node_factory()
        except (RigError, ValueError, OSError, RuntimeError) as e:  # SimulationError too
            print(f"{prog}: error: {e}", file=sys.stderr)
            return 2
        spin(node, getattr(node, "stop_future", None))
        return int(getattr(node, "exit_code", 0))
    except KeyboardInterrupt:
        return 0
    finally:
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                close()
            node.destroy_node()
        rclpy.try_shutdown()


def ros_env(domain_id: int, base: dict | None = None) -> dict:
    """Environment for a child process of an isolated graph: ``ROS_DOMAIN_ID`` and discovery
    limited to this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``); Python output
    unbuffered so that logs arrive in order."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
    dds_profile(env)
    return env


def to_json(obj) -> str:
    """JSON with NaN/inf written as null (strict JSON readers reject NaN)."""
    def clean(o):
        if isinstance(o, float):
            return o if math.isfinite(o) else None
        if isinstance(o, dict):
            return {str(k): clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if hasattr(o, "tolist"):
            return clean(o.tolist())
        return o
    return json.dumps(clean(obj))


class BackgroundSpin:
    """Spin ``executor`` (with ``node`` added) in a daemon thread until :meth:`close`, which
    then shuts the executor down, destroys the node and shuts ``context`` down.  The
    listening side of a tool that watches the graph from its own process and context (the
    demo's monitor, the node tests, the load benchmark); the nodes themselves spin in
    their main thread."""

    def __init__(self, executor, node, context):
        import threading
        from rclpy.task import Future
        self.executor, self.node, self.context = executor, node, context
        executor.add_node(node)
        self._never = Future()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self):
        while not self._stop.is_set() and self.context.ok():
            try:
                self.executor.spin_until_future_complete(self._never, timeout_sec=0.1)
            except Exception:
                if self.context.ok():
                    raise

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()
