"""The offline pipeline, recording → clean → track → preprocess → identify → σ → validate →
diagnose, and the thesis's table. Layer 4."""
