"""From a recording to a validated tensor: tracker, preprocessor, the prediction-error fit,
noise propagation, σ, errors in variables and model validation. Layer 2."""
