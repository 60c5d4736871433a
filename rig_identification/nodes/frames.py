"""Frame ids and topic names of the rig nodes: node parameters, and the start-up line that
says what a node reads and writes.

Frame ids (``header.frame_id``; defaults as in docs/recording_format.md) are ROS parameters of the
nodes that check or write them, so that a driver publishing the usual ROS names (an IMU in
``imu_link``) is accepted without a relay:

* ``imu_frame`` (``imu``): /rig/imu
* ``load_cell_frame`` (``load_cell_{cable}``): /rig/load_cells/<cable>; ``{cable}`` is
  replaced by the cable name of rig.yaml
* ``exciter_frame`` (``exciter``): /rig/exciter/wrench
* ``inclinometer_frame`` (``inclinometer``): /rig/inclinometer
* ``world_frame`` (``world``): /rig/pose header, TF parent, the visualizer's markers
* ``body_frame`` (``body``): /rig/pose child, /rig/generalized_wrench, /rig/mass_properties,
  TF child

Topic names are fixed in the code (``/rig/...``) and changed the standard ROS way, by
remapping: ``--ros-args -r /rig/imu:=/my/imu``.  Every node logs once at start-up the
resolved (remapped) names of what it reads and writes with their types and frames
(:func:`log_interface`).
"""
from __future__ import annotations

from dataclasses import dataclass

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription

WORLD_FRAME = "world"
BODY_FRAME = "body"
IMU_FRAME = "imu"
EXCITER_FRAME = "exciter"
INCLINOMETER_FRAME = "inclinometer"
LOAD_CELL_FRAME = "load_cell_{cable}"

#: role -> (parameter name, default, description)
FRAME_PARAMETERS = {
    "imu": ("imu_frame", IMU_FRAME, "header.frame_id of /rig/imu"),
    "load_cell": ("load_cell_frame", LOAD_CELL_FRAME,
                  "header.frame_id of /rig/load_cells/<cable>; {cable} stands for the cable name"),
    "exciter": ("exciter_frame", EXCITER_FRAME, "header.frame_id of /rig/exciter/wrench"),
    "inclinometer": ("inclinometer_frame", INCLINOMETER_FRAME, "header.frame_id of /rig/inclinometer"),
    "world": ("world_frame", WORLD_FRAME, "the world frame: /rig/pose header.frame_id, TF parent"),
    "body": ("body_frame", BODY_FRAME, "the body frame: /rig/pose child_frame_id, /rig/generalized_wrench, "
                                       "/rig/mass_properties, TF child"),
}


@dataclass(frozen=True)
class FrameIds:
    """The frame ids a node expects on its inputs and writes on its outputs.

    ``load_cell`` is a pattern: ``{cable}`` is replaced by the cable name
    (:meth:`load_cell_frame`)."""

    imu: str = IMU_FRAME
    load_cell: str = LOAD_CELL_FRAME
    exciter: str = EXCITER_FRAME
    inclinometer: str = INCLINOMETER_FRAME
    world: str = WORLD_FRAME
    body: str = BODY_FRAME

    def load_cell_frame(self, cable: str) -> str:
        """Frame id of the load cell of ``cable`` (``load_cell_c0`` by default)."""
        return self.load_cell.format(cable=cable)


def declare_frame_ids(node: Node, roles=tuple(FRAME_PARAMETERS)) -> FrameIds:
    """Declare the frame-id parameters of ``roles`` (keys of :data:`FRAME_PARAMETERS`) on
    ``node`` and return the frame ids (defaults for the roles not declared).

    Raises ValueError naming the parameter when a value is empty, contains white space, or
    (``load_cell_frame``) is not a pattern with only ``{cable}`` in braces."""
    values = {}
    for role in roles:
        name, default, description = FRAME_PARAMETERS[role]
        if not node.has_parameter(name):
            node.declare_parameter(name, default, ParameterDescriptor(description=description))
        v = node.get_parameter(name).value
        if not isinstance(v, str) or not v or any(c.isspace() for c in v):
            raise ValueError(f"parameter {name} = {v!r}: expected a frame id (a non-empty string without spaces)")
        values[role] = v
    frames = FrameIds(**values)
    try:
        frames.load_cell_frame("c0")
    except (KeyError, IndexError, ValueError):
        raise ValueError(f"parameter load_cell_frame = {frames.load_cell!r}: expected a frame id in which "
                         "{cable} stands for the cable name, e.g. load_cell_{cable}") from None
    return frames


def type_name(msg_type) -> str:
    """``sensor_msgs/msg/Imu`` for the rclpy message class ``sensor_msgs.msg.Imu``."""
    package = msg_type.__module__.split(".")[0]
    return f"{package}/msg/{msg_type.__name__}"


@dataclass(frozen=True)
class Endpoint:
    """One topic a node reads or writes, for :func:`log_interface`: the rclpy subscription or
    publisher (its resolved name and type are read from it) and a note (frames, QoS)."""

    entity: Subscription | Publisher
    note: str = ""

    def describe(self) -> str:
        note = f", {self.note}" if self.note else ""
        return f"{self.entity.topic_name} [{type_name(self.entity.msg_type)}{note}]"


def log_interface(node: Node, inputs: list[Endpoint], outputs: list[Endpoint], services=()) -> str:
    """Log once (info) the resolved names of the node's inputs, outputs and services, with
    their types and frames; returns the line.  Remapped names appear as remapped
    (``--ros-args -r /rig/imu:=/my/imu`` shows ``/my/imu``)."""
    parts = ["reads " + ("; ".join(e.describe() for e in inputs) or "nothing"),
             "writes " + ("; ".join(e.describe() for e in outputs) or "nothing")]
    if services:
        parts.append("services " + ", ".join(s.srv_name for s in services))
    line = "interface: " + " | ".join(parts)
    node.get_logger().info(line)
    return line
