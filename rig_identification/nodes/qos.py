"""Quality of service of the node graph, and what it implies for publishing and service calls.

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
"""
from __future__ import annotations

import time
from typing import Iterable

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

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

# a service client waits this long after wait_for_service() before its first call: the server's side
# of the discovery (its response writer matched with our reader) can lag the client's, and a response
# sent before it is dropped by Fast DDS ("failed to send response (timeout)"; ros2/ros2#1017)
SERVICE_SETTLE_SECONDS = 0.5


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


def publish_batch(publisher, messages: Iterable, topic: str, guard, diagnostics) -> None:
    """Publish serialized ``messages`` (a batch, :meth:`~.codec.MessageLayout.encode`) on
    ``topic`` with :func:`publish_blocking`; a message still blocked after its patience is lost:
    the input guard (:class:`~.inputs.InputGuard`) counts and warns it as ``<topic> (publish)``,
    and the rest are published.  The diagnostics (:class:`~.diagnostics.Diagnostics`) count what
    was sent."""
    sent = 0
    for raw in messages:
        try:
            publish_blocking(publisher, raw)
        except Exception as e:  # blocked too long by a slow reader: lost, say so
            guard.reject(topic + " (publish)", f"{type(e).__name__}: {e}")
            continue
        sent += 1
    diagnostics.count_tx(topic, sent)


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
