"""The physics: the rig's Newton–Euler model, its equilibrium and natural modes, the effects
beyond the rigid body, the experiment description and the simulator. Layer 1."""
