"""recorder: writes the rig's sensor topics to a recording folder, without ``ros2 bag``.

The folder is the one of docs/recording_format.md: ``rig.yaml`` (a copy
of the rig description given) and ``bag/``, a rosbag2 with storage MCAP written with the
``rosbags`` library (``rosbags.rosbag2.Writer``, ``StoragePlugin.MCAP``, version 9), readable by
``rig-identify``, ``read_recording``, ``ros2 bag play`` and Foxglove.  Messages are stored as
they arrived (serialized CDR, untouched: header stamps and frame ids as the drivers wrote
them); the bag timestamp of each message is its arrival time (system clock, ns), as
``ros2 bag record`` does.

Atomic: the recording is written into ``.<name>.partial/`` beside OUTPUT and renamed to OUTPUT
on a clean stop (Ctrl-C, SIGTERM, ``duration`` reached, ``ros2 launch`` ending), so OUTPUT is
either complete or absent.  A crash (SIGKILL, power kept) leaves OUTPUT absent and the
partial folder holding rig.yaml and the MCAP file up to its last complete chunk: rosbags
writes a chunk every 1 MiB of messages (a few seconds at the rig's rates; 200 Hz sensors
≈ 0.2 MB/s), the messages after it are lost.  The partial folder is not a recording yet
(the MCAP file has no summary and the bag no metadata.yaml); ``rig-record --recover
PARTIAL [OUTPUT]`` turns it into one, keeping every message of its complete chunks.

Parameters:
  rig (string, required)     rig description: rig.yaml (copied as is), a recording folder (its
                             rig.yaml) or an experiment file (its rig: section, written out)
  output (string, required)  the recording folder to create; must not exist (nor its partial)
  duration (double, 0.0)     > 0: stop by itself this many s (wall time) after the first message
  extra_topics (string[], [])  more topics to store beside the rig's, from: /rig/pose,
                             /rig/generalized_wrench, /rig/mass_properties, /rig/markers,
                             /rig/transform, /rig/sim_truth, /diagnostics (the reader ignores them;
                             Foxglove shows them)
  write_period (double, 0.05)  queued messages are written to the bag every this many s
  input_reliability (string, reliable)  reliable | best_effort (QoS of the sensor subscriptions)
  stale_after, stopped_after (double, 0.5, 2.0)  /diagnostics: silent inputs
  executor (string, events)  events | single

Subscribes (RELIABLE, KEEP_ALL: every sample; a recorder that falls behind slows a replay
down rather than losing data), topic names remappable (--ros-args -r /rig/imu:=/my/imu;
stored under the format's names):
  /rig/imu                 sensor_msgs/msg/Imu
  /rig/load_cells/<cable>  geometry_msgs/msg/WrenchStamped, one per cable of rig.yaml
  /rig/exciter/wrench      geometry_msgs/msg/WrenchStamped
  /rig/inclinometer        geometry_msgs/msg/Vector3Stamped
A topic is added to the bag at its first message (a rig without exciter has no such topic).

Publishes:
  /diagnostics             messages received per topic (rx), written, silent inputs

Command line: ``rig-record OUTPUT --rig RIG [--duration S] [--extra TOPIC ...]`` runs this node;
``rig-record --recover PARTIAL [OUTPUT]`` salvages a crashed recording (see above).
"""
from __future__ import annotations

import argparse
import functools
import importlib
import os
import shutil
import struct
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.utilities import remove_ros_args
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from ..io.atomic import atomic_directory
from ..io.rig import RigError, dump_rig, read_yaml
from ..io.verdict import PACKAGE, package_version
from .diagnostics import Diagnostics
from .frames import Endpoint, log_interface
from .inputs import InputGuard
from .parameters import load_rig_source
from .qos import DIAGNOSTICS_QOS, LATCHED_QOS, input_qos
from .runtime import run
from .topics import (
    DIAGNOSTICS_TOPIC,
    EXCITER_TOPIC,
    IMU_TOPIC,
    INCLINOMETER_TOPIC,
    LOAD_CELL_PREFIX,
    MASS_PROPERTIES_TOPIC,
    POSE_TOPIC,
    TRUTH_TOPIC,
    WRENCH_TOPIC,
)

#: suffix of the folder a recording is written into before it is renamed to OUTPUT
PARTIAL_SUFFIX = ".partial"
#: rosbag2 metadata version written (rosbags.rosbag2.Writer: 8 or 9; Jazzy reads both)
BAG_VERSION: Literal[8, 9] = 9

#: the extra topics the recorder can store: name -> (ROS type name, latched?)
EXTRA_TOPICS = {
    POSE_TOPIC: ("nav_msgs/msg/Odometry", False),
    WRENCH_TOPIC: ("geometry_msgs/msg/WrenchStamped", False),
    MASS_PROPERTIES_TOPIC: ("geometry_msgs/msg/InertiaStamped", True),
    "/rig/markers": ("visualization_msgs/msg/MarkerArray", False),
    "/rig/transform": ("geometry_msgs/msg/TransformStamped", False),
    TRUTH_TOPIC: ("std_msgs/msg/String", True),
    DIAGNOSTICS_TOPIC: ("diagnostic_msgs/msg/DiagnosticArray", False),
}


class RecorderError(ValueError):
    """A recording that cannot be started or recovered (names the folder and the reason)."""


def partial_folder(output: Path) -> Path:
    """Where the recording of ``output`` is written until a clean stop: ``.<name>.partial``
    beside it."""
    output = Path(output)
    return output.parent / f".{output.name}{PARTIAL_SUFFIX}"


def rig_text(source: str | Path) -> str:
    """rig.yaml text for the rig description ``source``: a rig.yaml file as is (comments
    kept), a recording folder's rig.yaml, or an experiment file's ``rig:`` section written
    out.  Validated first (raises :class:`~rig_identification.io.rig.RigError`)."""
    rig = load_rig_source(source)
    p = Path(source)
    if p.is_dir():
        p = p / "rig.yaml"
    d = read_yaml(p, RigError, "rig description")
    if isinstance(d, dict) and "rig" in d and "gravity" not in d:
        return dump_rig(rig, f"rig description of the experiment file {p}")
    return p.read_text(encoding="utf-8")


def message_class(type_name: str):
    """The rclpy message class of ``pkg/msg/Name``."""
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def fsync_tree(folder: Path) -> None:
    """fsync every file under ``folder`` and the folders themselves (the data is on disk
    before the rename that publishes it)."""
    for f in sorted(folder.rglob("*")):
        if f.is_file():
            with open(f, "rb") as fh:
                os.fsync(fh.fileno())
    for d in [folder, *[p for p in folder.rglob("*") if p.is_dir()]]:
        fd = os.open(d, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


# --- the node --------------------------------------------------------------------------------

class RecorderNode(Node):
    """Node ``recorder``: rig topics -> recording folder (see the module docstring)."""

    def __init__(self, overrides: list[Parameter] | None = None):
        super().__init__("recorder", parameter_overrides=overrides or [])
        self.declare_parameter("rig", "")
        self.declare_parameter("output", "")
        self.declare_parameter("duration", 0.0)
        self.declare_parameter("extra_topics", [""], ParameterDescriptor(
            description="more topics to store: " + ", ".join(EXTRA_TOPICS)))
        self.declare_parameter("write_period", 0.05)
        self.declare_parameter("executor", "events")
        get = lambda n: self.get_parameter(n).value  # noqa: E731
        qos_in = input_qos(self)
        self.stop_future = Future()
        self.exit_code = 0
        out = str(get("output"))
        if not out:
            raise ValueError("parameter 'output' is empty: give the recording folder to create, "
                             "e.g. --ros-args -p output:=/data/run1")
        rig_path = str(get("rig"))
        if not rig_path:
            raise RigError("parameter 'rig' is empty: give the rig description (rig.yaml) of the recording, "
                                  "e.g. --ros-args -p rig:=/lab/rig.yaml")
        self.duration = float(get("duration"))
        if not self.duration >= 0:
            raise ValueError(f"parameter duration = {self.duration}: must be >= 0 s")
        extras = [t for t in (get("extra_topics") or []) if t]
        unknown = [t for t in extras if t not in EXTRA_TOPICS]
        if unknown:
            raise ValueError(f"parameter extra_topics: {', '.join(unknown)} not recordable (choose from "
                             f"{', '.join(EXTRA_TOPICS)})")
        text = rig_text(rig_path)
        rig = load_rig_source(rig_path)
        self.output = Path(out).absolute()
        self.partial = partial_folder(self.output)
        if self.output.exists():
            raise RecorderError(f"{self.output}: already exists (a recording is never overwritten: choose another "
                                "output)")
        if self.partial.exists():
            raise RecorderError(f"{self.partial}: an interrupted recording of {self.output} is there; recover it "
                                f"(rig-record --recover {self.partial}) or delete it first")
        self.output.parent.mkdir(parents=True, exist_ok=True)
        self.partial.mkdir()
        (self.partial / "rig.yaml").write_text(text, encoding="utf-8")
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self.writer = Writer(self.partial / "bag", version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.connections: dict = {}
        self.types: dict[str, str] = {}
        self.queue: list[tuple[int, str, bytes]] = []  # (arrival ns, topic, serialized message)
        self.written: dict[str, int] = {}
        self.t_first: float | None = None
        self.closed = False
        self.guard = InputGuard(self)
        self.diag = Diagnostics(self, self.guard, extra=lambda: {
            "written": sum(self.written.values()), "output": str(self.output)})
        topics = {IMU_TOPIC: ("sensor_msgs/msg/Imu", False)}
        topics.update({LOAD_CELL_PREFIX + n: ("geometry_msgs/msg/WrenchStamped", False)
                       for n in rig.cable_names})
        topics[EXCITER_TOPIC] = ("geometry_msgs/msg/WrenchStamped", False)
        topics[INCLINOMETER_TOPIC] = ("geometry_msgs/msg/Vector3Stamped", False)
        topics.update({t: EXTRA_TOPICS[t] for t in extras})
        self.subs = []
        for topic, (type_name, latched) in topics.items():
            self.types[topic] = type_name
            qos = LATCHED_QOS if latched else (DIAGNOSTICS_QOS if topic == DIAGNOSTICS_TOPIC
                                                      else qos_in)
            self.subs.append(self.create_subscription(message_class(type_name), topic,
                                                      functools.partial(self._arrived, topic), qos, raw=True))
            if topic != DIAGNOSTICS_TOPIC:
                self.guard.expect(topic)
        self.create_timer(float(get("write_period")), self._write_queued)
        log_interface(self, [Endpoint(s) for s in self.subs], [Endpoint(self.diag.pub)])
        self.get_logger().info(f"ready: recording to {self.output} (written into {self.partial} until stopped)"
                               + (f", for {self.duration:g} s" if self.duration else ", until stopped (Ctrl-C)"))

    def _arrived(self, topic: str, raw: bytes) -> None:
        self.queue.append((time.time_ns(), topic, raw))
        if topic != DIAGNOSTICS_TOPIC:
            g = self.guard
            g.received[topic] = g.received.get(topic, 0) + 1
            g.last_arrival[topic] = time.monotonic()

    def _write_queued(self) -> None:
        """Write the queued messages (arrival order) to the bag; stop after ``duration``."""
        queue, self.queue = self.queue, []
        for t_ns, topic, raw in queue:
            conn = self.connections.get(topic)
            if conn is None:
                conn = self.connections[topic] = self.writer.add_connection(topic, self.types[topic],
                                                                            typestore=self.typestore)
            self.writer.write(conn, t_ns, raw)
            self.written[topic] = self.written.get(topic, 0) + 1
        if queue and self.t_first is None:
            self.t_first = time.monotonic()
        if self.duration and self.t_first is not None and time.monotonic() - self.t_first >= self.duration \
                and not self.stop_future.done():
            self.get_logger().info(f"duration {self.duration:g} s reached")
            self.stop_future.set_result(True)

    def close(self) -> None:
        """Finish the bag (summary, metadata.yaml), put it on disk and rename the partial
        folder to OUTPUT (called by :func:`~.runtime.run` at a clean stop)."""
        if self.closed:
            return
        self.closed = True
        self._write_queued()
        self.writer.close()
        fsync_tree(self.partial)
        os.replace(self.partial, self.output)
        fd = os.open(self.output.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        counts = ", ".join(f"{t} {n}" for t, n in self.written.items()) or "nothing"
        needed = [t for t in self.types if t == IMU_TOPIC or t.startswith(LOAD_CELL_PREFIX)]
        missing = [t for t in needed if not self.written.get(t)]
        # after Ctrl-C the context is shut down: the ROS logger could not reach /rosout any more
        say = (lambda text: print(f"recorder: {text}", file=sys.stderr, flush=True)) if not self.context.ok() \
            else self.get_logger().info
        say(f"recording complete: {self.output} ({counts})")
        if missing:
            say(f"warning: no message on {', '.join(missing)}: the recording lacks data the identification needs "
                "(wrong topic names? remap them with --ros-args -r /rig/imu:=/my/imu)")


# --- recovery of a crashed recording -----------------------------------------------------

MCAP_MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True)
class McapRecord:
    """One record of an MCAP stream that :func:`salvage_mcap` yields: a channel (``topic`` and
    ``schema``, the message type name) or a message (``channel`` id, ``log_time`` ns, ``data``)."""

    kind: str  # "channel" | "message"
    channel: int
    topic: str = ""
    schema: str = ""
    log_time: int = 0
    data: bytes = b""


def _string(buf: bytes, i: int) -> tuple[str, int]:
    (n,) = struct.unpack_from("<I", buf, i)
    return buf[i + 4:i + 4 + n].decode(), i + 4 + n


def _decompress(data: bytes, compression: str) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        try:
            from compression import zstd  # Python 3.14
        except ImportError:
            from backports import zstd  # what rosbags uses before 3.14
        return zstd.decompress(data)
    raise RecorderError(f"chunk compression {compression!r} not supported (recorder bags are uncompressed)")


def _records(buf: bytes, start: int, schemas: dict[int, str]) -> Iterator[McapRecord | tuple[str, bytes]]:
    """The complete records of ``buf`` from ``start``: channels and messages as
    :class:`McapRecord`, chunks as ("chunk", content); stops at a truncated record or the footer."""
    i, n = start, len(buf)
    while i + 9 <= n:
        op = buf[i]
        (length,) = struct.unpack_from("<Q", buf, i + 1)
        body_start, body_end = i + 9, i + 9 + length
        if body_end > n:
            return  # truncated: the crash happened while this record was written
        body = buf[body_start:body_end]
        i = body_end
        if op == 0x02:  # footer
            return
        if op == 0x03:  # schema: id u16, name, encoding, data
            (sid,) = struct.unpack_from("<H", body, 0)
            schemas[sid] = _string(body, 2)[0]
        elif op == 0x04:  # channel: id u16, schema id u16, topic, encoding, metadata
            cid, sid = struct.unpack_from("<HH", body, 0)
            topic, _ = _string(body, 4)
            yield McapRecord("channel", cid, topic=topic, schema=schemas.get(sid, ""))
        elif op == 0x05:  # message: channel u16, sequence u32, log time u64, publish time u64, data
            cid, _, log_time, _ = struct.unpack_from("<HIQQ", body, 0)
            yield McapRecord("message", cid, log_time=log_time, data=body[22:])
        elif op == 0x06:
            yield ("chunk", body)


def salvage_mcap(path: Path) -> Iterator[McapRecord]:
    """The channels and messages of an MCAP file that may be cut short (a writer killed
    mid-recording): every complete chunk (and top-level record) up to the first truncated
    one, in file order.  Raises :class:`RecorderError` when the file is not MCAP."""
    buf = Path(path).read_bytes()
    if not buf.startswith(MCAP_MAGIC):
        raise RecorderError(f"{path}: not an MCAP file")
    schemas: dict[int, str] = {}
    for rec in _records(buf, len(MCAP_MAGIC), schemas):
        if isinstance(rec, McapRecord):
            yield rec
            continue
        body = rec[1]
        compression, j = _string(body, 28)  # after start, end, uncompressed size (u64) and crc (u32)
        (csize,) = struct.unpack_from("<Q", body, j)
        inner = _decompress(body[j + 8:j + 8 + csize], compression)
        yield from (r for r in _records(inner, 0, schemas) if isinstance(r, McapRecord))


@dataclass(frozen=True)
class Recovered:
    """What :func:`recover` made: the recording folder and the messages kept per topic."""

    output: Path
    messages: dict[str, int] = field(default_factory=dict)
    complete: bool = False  # the partial bag had been closed already (crash during the rename)


def recover(partial: str | Path, output: str | Path | None = None) -> Recovered:
    """Turn the partial folder of a crashed recording into a recording folder at ``output``
    (default: the OUTPUT the recorder was writing, i.e. ``partial``'s name without the
    leading dot and ``.partial``): rig.yaml and a new bag with every message of the MCAP
    file's complete chunks.  Written atomically; the partial folder is left as it was.

    Raises :class:`RecorderError` naming the folder (no rig.yaml, no MCAP file, output exists)."""
    partial = Path(partial)
    if output is None:
        name = partial.name
        if not (name.startswith(".") and name.endswith(PARTIAL_SUFFIX)):
            raise RecorderError(f"{partial}: not named .<name>{PARTIAL_SUFFIX}; give the output folder")
        output = partial.parent / name[1:-len(PARTIAL_SUFFIX)]
    output = Path(output)
    if output.exists():
        raise RecorderError(f"{output}: already exists (refusing to overwrite)")
    if not (partial / "rig.yaml").is_file():
        raise RecorderError(f"{partial}: no rig.yaml (not a partial recording)")
    files = sorted((partial / "bag").glob("*.mcap"))
    if not files:
        raise RecorderError(f"{partial}: no bag/*.mcap file")
    if (partial / "bag" / "metadata.yaml").is_file():  # the bag was closed: only the rename was missing
        shutil.copytree(partial, output)
        return Recovered(output, {}, complete=True)
    ts = get_typestore(Stores.ROS2_JAZZY)
    counts: dict[str, int] = {}
    with atomic_directory(output, overwrite=False) as tmp:
        shutil.copy2(partial / "rig.yaml", tmp / "rig.yaml")
        with Writer(tmp / "bag", version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as w:
            conns, topics = {}, {}
            for f in files:
                for rec in salvage_mcap(f):
                    if rec.kind == "channel":
                        if rec.channel not in conns:
                            conns[rec.channel] = w.add_connection(rec.topic, rec.schema, typestore=ts)
                            topics[rec.channel] = rec.topic
                    elif rec.channel in conns:
                        w.write(conns[rec.channel], rec.log_time, rec.data)
                        counts[topics[rec.channel]] = counts.get(topics[rec.channel], 0) + 1
    return Recovered(output, counts)


# --- command line --------------------------------------------------------------------------

def main(argv=None) -> int:
    """``recorder``: the node (parameters after --ros-args)."""
    return run(RecorderNode, argv, "recorder", __doc__)


def record_main(argv=None) -> int:
    """``rig-record``: record (runs the node) or ``--recover`` a crashed recording."""
    argv = list(sys.argv if argv is None else argv)
    ap = argparse.ArgumentParser(prog="rig-record", description=(
        "Record the rig topics into a recording folder (rig.yaml + bag/, MCAP) without ros2 bag; "
        "or recover the partial folder a crashed recording left."),
        epilog="ROS arguments (remapping, -p NAME:=VALUE) may follow --ros-args. Stop with Ctrl-C.")
    ap.add_argument("--version", action="version", version=f"rig-record ({PACKAGE}) {package_version()}")
    ap.add_argument("output", nargs="?", help="recording folder to create (must not exist)")
    ap.add_argument("--rig", help="rig description: rig.yaml, recording folder or experiment file")
    ap.add_argument("--duration", type=float, default=0.0, metavar="S",
                    help="stop after S s from the first message (default: until Ctrl-C)")
    ap.add_argument("--extra", nargs="+", default=[], metavar="TOPIC",
                    help="also store these topics (" + ", ".join(EXTRA_TOPICS) + ")")
    ap.add_argument("--best-effort", action="store_true", help="subscribe BEST_EFFORT (drivers with sensor-data QoS)")
    ap.add_argument("--recover", metavar="PARTIAL",
                    help="turn the partial folder of a crashed recording into a recording (at OUTPUT, default "
                         "the folder it was recording to)")
    user = remove_ros_args(argv)[1:]
    args = ap.parse_args(user)
    if args.recover:
        try:
            r = recover(args.recover, args.output)
        except (RecorderError, OSError) as e:
            print(f"rig-record: error: {e}", file=sys.stderr)
            return 2
        what = "complete bag" if r.complete else ", ".join(f"{t} {n}" for t, n in r.messages.items()) or "no message"
        print(f"recovered {r.output}: {what}")
        return 0
    if not args.output or not args.rig:
        ap.error("give OUTPUT and --rig RIG (or --recover PARTIAL)")
    overrides = [Parameter("rig", value=args.rig), Parameter("output", value=args.output),
                 Parameter("duration", value=float(args.duration))]
    if args.extra:
        overrides.append(Parameter("extra_topics", value=list(args.extra)))
    if args.best_effort:
        overrides.append(Parameter("input_reliability", value="best_effort"))
    ros = argv[argv.index("--ros-args"):] if "--ros-args" in argv else []
    return run(lambda: RecorderNode(overrides), [argv[0], *ros], "rig-record", __doc__)


if __name__ == "__main__":
    sys.exit(main())
