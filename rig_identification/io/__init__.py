"""Reading and writing: rig.yaml, recordings (rosbag2, read in bulk), atomic output, the data's
quality checks, and the formats of the results (verdict, exports). Layer 0: imports nothing of the package above it."""
