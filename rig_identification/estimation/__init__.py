"""From a recording to a validated tensor: the rig model's record, unknowns, fit and Cramér–Rao
bound, its starts (the tracker, preprocessor and gyro-only fit among them), the joint fit of
several recordings and the data's quality checks. Layer 2."""
