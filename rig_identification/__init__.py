"""Mass properties of a vehicle on a cable-suspended rig (ROS-free core + ROS 2 nodes)."""
