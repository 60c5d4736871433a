"""The topic names of the rig's node graph (docs/recording_format.md and the node contract).

Each node takes these as its defaults; a lab remaps them the ROS way
(``--ros-args -r /rig/imu:=/my/imu``).  Their QoS: :mod:`.qos`.
"""
from __future__ import annotations

# the sensor streams of the recording format (io.recording), and the graph's own topics
from ..io.recording import EXCITER_TOPIC, IMU_TOPIC, INCLINOMETER_TOPIC, LOAD_CELL_PREFIX

POSE_TOPIC = "/rig/pose"
WRENCH_TOPIC = "/rig/generalized_wrench"
MASS_PROPERTIES_TOPIC = "/rig/mass_properties"
TRUTH_TOPIC = "/rig/sim_truth"
DRIVER_STATUS_TOPIC = "/rig/sensor_driver/status"
DIAGNOSTICS_TOPIC = "/diagnostics"

__all__ = ["IMU_TOPIC", "LOAD_CELL_PREFIX", "EXCITER_TOPIC", "INCLINOMETER_TOPIC", "POSE_TOPIC", "WRENCH_TOPIC",
           "MASS_PROPERTIES_TOPIC", "TRUTH_TOPIC", "DRIVER_STATUS_TOPIC", "DIAGNOSTICS_TOPIC"]
