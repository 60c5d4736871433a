"""The offline pipeline: a recording cleaned, put on one grid and fitted with the rig model (its
diagnosis and refit), several recordings of one body jointly, and the thesis's table. Layer 4."""
