"""Which physics the rig model leaves out: its extensions tested, named where the recording
tells them apart (:mod:`~rig_identification.diagnosis.rig_diagnosis`). Layer 3."""
