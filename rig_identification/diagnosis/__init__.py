"""Which physics the model is missing: the model extended by effect columns, the candidates,
the residuals, the selection. Layer 3."""
