"""Offline replay: recording -> tracker -> preprocessor -> identifier (the nodes' core code)."""
from __future__ import annotations

import numpy as np

from .identification import InertiaResult, identify_inertia, identify_inertia_thesis
from .preprocessor import preprocess
from .recording import Recording, RecordingError
from .tracker import track


def default_initial_guess(rig) -> np.ndarray:
    """A rough tensor (6,) for the thesis model when none is given: the mass spread over
    a box spanned by the body anchors, diagonal (kg·m²)."""
    half = np.ptp(rig.body_anchors, axis=0) / 2 + 0.1
    sx, sy, sz = half**2
    return rig.mass / 3 * np.array([sy + sz, 0.0, 0.0, sx + sz, 0.0, sx + sy])


def identify_recording(rec: Recording, start: float | None = None, end: float | None = None,
                       settle: float = 5.0, band_hz: tuple[float, float] | None = None,
                       model: str = "pem", initial_guess=None) -> InertiaResult:
    """Identify the inertia tensor of a dynamic recording.

    start/end: window in seconds from the first IMU stamp (default: the whole
    recording after ``settle`` s, the tracker's convergence time, at most a tenth of
    the recording).  model: ``"pem"`` (ours) or ``"thesis"`` (the thesis's model and
    estimator, :func:`~rig_identification.identification.identify_inertia_thesis`, from
    ``initial_guess`` (6,) tensor entries or :func:`default_initial_guess`).  Raises
    :class:`~rig_identification.recording.RecordingError`,
    :class:`~rig_identification.rig.RigError`,
    :class:`~rig_identification.identification.IdentificationError`.
    """
    rig, s = rec.rig, rec.sensors
    rig.require_cg()
    if rig.exciter is not None and s.exciter is None:
        raise RecordingError(f"{rec.path}: rig.yaml describes an exciter but the bag has no "
                             "/rig/exciter/wrench topic")
    poses = track(rig, s)
    wrench = preprocess(rig, poses, s)
    t0 = s.t_start
    settle = min(settle, 0.1 * (s.t_end - t0))
    lo = t0 + (settle if start is None else max(start, settle))
    hi = s.t_end if end is None else t0 + end
    m = (wrench.t >= lo) & (wrench.t <= hi)
    if m.sum() < 10:
        raise RecordingError(f"{rec.path}: no samples in the window [{lo - t0:.1f}, {hi - t0:.1f}] s")
    gyro = s.imu.interp(wrench.t[m])[:, :3]
    gyro_b = rig.imu.rotation.apply(gyro)
    if model == "thesis":
        guess = default_initial_guess(rig) if initial_guess is None else np.asarray(initial_guess, float)
        result = identify_inertia_thesis(rig, wrench.t[m], gyro_b, wrench.torque[m], guess)
    elif model == "pem":
        result = identify_inertia(rig, wrench.t[m], gyro_b, wrench.torque[m], band_hz=band_hz)
    else:
        raise ValueError(f"unknown model {model!r} (pem or thesis)")
    result.warnings[:0] = rec.warnings
    return result


def compare_to_truth(result: InertiaResult, truth: dict) -> dict:
    """Errors of the identified tensor against truth.yaml's ``inertia_about_cg``.

    Returns {key: {"value", "truth", "error", "error_percent", "error_sigma"}}; the
    percentage is of the entry for diagonals and of the largest diagonal for products.
    """
    from .identification import KEYS, from_tensor
    tru = truth["inertia_about_cg"]
    big = max(abs(tru["ixx"]), abs(tru["iyy"]), abs(tru["izz"]))
    out = {}
    for k, v, s in zip(KEYS, from_tensor(result.inertia), result.inertia_std):
        e = float(v - tru[k])
        ref = abs(tru[k]) if k in ("ixx", "iyy", "izz") else big
        out[k] = {"value": float(v), "truth": float(tru[k]), "error": e, "error_percent": 100 * e / ref,
                  "error_sigma": e / s if s > 0 else float(np.inf)}
    return out
