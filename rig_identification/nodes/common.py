"""Shared helpers of the rig_identification nodes: QoS, message <-> array conversion,
input validation with throttled warnings, diagnostics, command line and spinning.

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

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

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

# frame ids
WORLD_FRAME = "world"
BODY_FRAME = "body"
IMU_FRAME = "imu"
EXCITER_FRAME = "exciter"
INCLINOMETER_FRAME = "inclinometer"


def load_cell_frame(cable: str) -> str:
    return f"load_cell_{cable}"


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


def load_rig_param(node: Node):
    """Load the rig description named by the node's ``rig`` parameter (path to a rig.yaml).

    Raises :class:`~rig_identification.rig.RigError` with a clear message.
    """
    from ..rig import RigError, load_rig
    path = node.get_parameter("rig").value
    if not path:
        raise RigError("parameter 'rig' is empty: give the path of the rig description, "
                       "e.g. --ros-args -p rig:=/path/to/rig.yaml")
    return load_rig(path)


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
    """Validate incoming messages; count and report the rejected ones.

    A message is rejected when its frame id is not the expected one, a value is not
    finite, or its stamp is not after the previous accepted stamp of the same topic.
    Rejections are logged as warnings throttled per topic (every ``period`` s at most,
    with the number suppressed since), and counted for the diagnostics.
    """

    def __init__(self, node: Node, period: float = 5.0):
        self.node = node
        self.period = period
        self.last: dict[str, float] = {}
        self.received: dict[str, int] = {}
        self.rejected: dict[str, int] = {}
        self._warned: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def accept(self, topic: str, header, frame: str | None, values: Iterable[float]) -> float | None:
        """Return the stamp (s) of an acceptable message, else None (after counting/warning)."""
        self.received[topic] = self.received.get(topic, 0) + 1
        if frame is not None and header.frame_id != frame:
            return self.reject(topic, f"frame_id {header.frame_id!r}, expected {frame!r}")
        t = stamp_to_sec(header.stamp)
        for v in values:
            if not math.isfinite(v):
                return self.reject(topic, f"non-finite value at stamp {t:.6f}")
        prev = self.last.get(topic)
        if prev is not None and t <= prev:
            return self.reject(topic, f"stamp {t:.6f} s not after the previous one ({prev:.6f} s)")
        self.last[topic] = t
        return t

    def reject(self, topic: str, why: str) -> None:
        """Count a rejected message of ``topic`` and warn (throttled per topic)."""
        self.rejected[topic] = self.rejected.get(topic, 0) + 1
        now = time.monotonic()
        if now - self._warned.get(topic, -math.inf) >= self.period:
            extra = self._suppressed.pop(topic, 0)
            more = f" ({extra} more rejected since the last warning)" if extra else ""
            self.node.get_logger().warn(f"dropped a malformed message on {topic}: {why}{more}")
            self._warned[topic] = now
        else:
            self._suppressed[topic] = self._suppressed.get(topic, 0) + 1
        return None

    def core_error(self, topic: str, err: Exception) -> None:
        """The core refused an input that passed the checks: count it like a malformed message."""
        self.reject(topic, f"{type(err).__name__}: {err}")


class StampMerger:
    """Merge several stamped streams into one feed in header-stamp order.

    Topics are delivered independently (and, under back-pressure or a DDS repair, with
    different delays), so arrival order is not stamp order.  ``push`` buffers an event
    and returns the events that are now safe to hand on, sorted by ``(stamp, rank)``: those
    with a stamp no later than every stream's latest stamp (each stream is increasing, so
    nothing earlier can still come), or older than the newest stamp minus ``max_delay``
    (a silent or stalled stream delays the feed by at most that much).  An event that
    arrives after its stamp was passed is refused (``push`` returns None).  ``flush`` hands
    on everything buffered: for the end of the data (call it when nothing arrived for a
    while of wall time), when no later sample will ever raise the streams' stamps.
    """

    def __init__(self, streams, max_delay: float):
        import heapq
        self._heapq = heapq
        self.streams = set(streams)
        self.max_delay = max_delay
        self.last: dict[str, float] = {}
        self.newest = -math.inf
        self.released = -math.inf
        self._heap: list = []
        self._seq = 0

    def __len__(self) -> int:
        return len(self._heap)

    def flush(self) -> list:
        """Hand on every buffered event, in order."""
        hq, heap = self._heapq, self._heap
        out = [hq.heappop(heap) for _ in range(len(heap))]
        if out:
            self.released = max(self.released, out[-1][0])
        return out

    def drop_stream(self, stream: str) -> None:
        """Stop waiting for ``stream`` (its later events are still merged)."""
        self.streams.discard(stream)

    def push(self, stream: str, t: float, rank: int, payload) -> list | None:
        """Buffer one event; return the releasable events as (t, rank, seq, stream, payload)."""
        if t < self.released:
            return None
        self.last[stream] = t
        if t > self.newest:
            self.newest = t
        self._seq += 1
        hq = self._heapq
        hq.heappush(self._heap, (t, rank, self._seq, stream, payload))
        mark = min((self.last.get(s, -math.inf) for s in self.streams), default=self.newest)
        mark = max(mark, self.newest - self.max_delay)
        out = []
        heap = self._heap
        while heap and heap[0][0] <= mark:
            ev = hq.heappop(heap)
            out.append(ev)
        if out:
            self.released = out[-1][0]
        return out


# --- diagnostics ---------------------------------------------------------------------------

class Diagnostics:
    """Publish the node's message counts on ``/diagnostics`` (diagnostic_msgs/DiagnosticArray)
    once per ``period`` s: ``rx <topic>``, ``rejected <topic>``, ``tx <topic>``,
    ``matched <topic>`` (readers matched by this node's writer, DDS level: what a sensor
    driver waits for before it starts) plus any extra key/values; level WARN when a message
    was rejected."""

    def __init__(self, node: Node, guard: InputGuard, period: float = 1.0,
                 extra: Callable[[], dict] | None = None):
        from diagnostic_msgs.msg import DiagnosticArray
        self.node, self.guard, self.extra = node, guard, extra
        self.sent: dict[str, int] = {}
        self.writers: dict[str, object] = {}
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

    def publish(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
        vals = self.values()
        rejected = sum(self.guard.rejected.values())
        st = DiagnosticStatus(name=self.node.get_fully_qualified_name(), hardware_id="rig")
        st.level = DiagnosticStatus.WARN if rejected else DiagnosticStatus.OK
        st.message = f"{rejected} malformed message(s) dropped" if rejected else "ok"
        st.values = [KeyValue(key=k, value=str(v)) for k, v in vals.items()]
        arr = DiagnosticArray(status=[st])
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


def run(node_factory: Callable[[], Node], argv: list[str] | None, prog: str, doc: str) -> int:
    """Standard ``main`` of a node: help, rclpy init, construct, spin, clean shutdown.

    A start-up error that the user can fix (bad rig.yaml, missing file, bad parameter)
    prints one line on stderr and returns 2, no traceback.
    """
    from ..rig import RigError
    argv = handle_help(argv, prog, doc)
    rclpy.init(args=argv)
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
