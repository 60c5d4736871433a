"""The command lines rig-identify and rig-sim. Layer 6."""
