"""White-noise level of a sampled signal, estimated from the signal itself.

The lowest layer of the package's statistics: :func:`white_sigma` is used by the recording's
reader (a saturated channel is one that holds a value while the rest is noisy), the
validation (the accelerometer's noise) and the uncertainty propagation (every stream's σ).
"""
from __future__ import annotations

import math

import numpy as np

THIRD_DIFF_NORM = math.sqrt(20.0)   # ‖(1, −3, 3, −1)‖: σ of the third difference of white noise / σ
MAD_NORM = 1.482602218505602        # σ / median absolute deviation of a normal variable


def white_sigma(x: np.ndarray) -> float:
    """White-noise σ of a sampled signal ``x`` (N,) or (N, k) (pooled over columns), from the
    median absolute deviation of its third differences: a smooth motion sampled ≥ 20× faster
    than it varies contributes < 1 % (its third difference is (2π f/fs)³ times its amplitude),
    and isolated steps do not move a median.  Returns 0.0 for fewer than 8 samples."""
    x = np.asarray(x, float)
    if x.ndim == 1:
        x = x[:, None]
    if len(x) < 8:
        return 0.0
    d = np.diff(x, n=3, axis=0)
    d = d[np.isfinite(d).all(axis=1)]
    if not len(d):
        return 0.0
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return float(np.sqrt(np.mean((MAD_NORM * mad / THIRD_DIFF_NORM) ** 2)))
