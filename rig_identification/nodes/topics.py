"""The topic names of the rig's node graph (RECORDING_FORMAT.md and the node contract).

Each node takes these as its defaults; a lab remaps them the ROS way
(``--ros-args -r /rig/imu:=/my/imu``).  Their QoS: :mod:`.qos`.
"""

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
