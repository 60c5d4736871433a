"""Adjoints (transposes) of the identifier's linear signal operations — the zero-phase band-pass
and the cumulative integral — so that the noise propagation
(:mod:`rig_identification.estimation.propagation`) applies them to the fit's Jacobian once instead
of to every noise channel.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import sosfilt, sosfilt_zi


def sosfiltfilt_adjoint(sos: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Transpose of ``scipy.signal.sosfiltfilt(sos, ·, axis=0)`` (default odd padding)
    applied to v (N, k): <sosfiltfilt(x), v> = <x, adjoint(v)> for every x."""
    n_sec = sos.shape[0]
    ntaps = 2 * n_sec + 1 - min((sos[:, 2] == 0).sum(), (sos[:, 5] == 0).sum())
    pad = 3 * ntaps
    N = v.shape[0]
    L = N + 2 * pad
    zi = sosfilt_zi(sos)
    r = sosfilt(sos, np.zeros(L), zi=zi)[0]              # zero-input response per unit initial value

    def causal_T(g: np.ndarray) -> np.ndarray:   # transpose of zero-state causal filtering: reverse, filter, reverse
        out: np.ndarray = sosfilt(sos, g[::-1], axis=0)[::-1]
        return out

    g3 = np.zeros((L,) + v.shape[1:])
    g3[pad:pad + N] = v
    g2 = g3[::-1]
    gw = causal_T(g2)
    gw[0] += np.tensordot(r, g2, axes=(0, 0))
    gy1 = gw[::-1]
    ge = causal_T(gy1)
    ge[0] += np.tensordot(r, gy1, axes=(0, 0))
    # odd extension: ext = [2 x0 - x[pad:0:-1], x, 2 x[-1] - x[-2:-(pad+2):-1]]
    gx = ge[pad:pad + N].copy()
    left, right = ge[:pad], ge[pad + N:]
    gx[0] += 2 * left.sum(0)
    gx[1:pad + 1] -= left[::-1]
    gx[-1] += 2 * right.sum(0)
    gx[N - 1 - pad:N - 1] -= right[::-1]
    return gx


def cumtrapz_adjoint(g: np.ndarray, dt: float) -> np.ndarray:
    """Transpose of the cumulative trapezoid integral (initial 0) along axis 0 — the
    identifier's cumulative Simpson rule to O((f dt)²) in the pass band."""
    C = np.cumsum(g[::-1], axis=0)[::-1]   # C[k] = Σ_{i≥k} g[i]
    out = np.zeros_like(g)
    out[1:] += C[1:]
    out[:-1] += C[1:]
    return 0.5 * dt * out
