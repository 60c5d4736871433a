"""From a recording to a validated tensor: the rig model's record, unknowns, fit and Cramér–Rao
bound, its starts (the tracker, preprocessor and gyro-only fit among them), and the joint fit of
several recordings. Layer 2."""
