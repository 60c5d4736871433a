"""The HTML reports (rig-identify inertia --report, diagnose --report). Layer 5."""
