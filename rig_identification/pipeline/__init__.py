"""The offline pipeline: a recording cleaned, put on one grid and fitted with the rig model (its
diagnosis and refit), the gyro-only start's tracker and preprocessor pass, and the thesis's table.
Layer 4."""
