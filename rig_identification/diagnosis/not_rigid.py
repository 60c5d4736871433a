"""Whether the body may not be rigid, said without fitting it: the gate and the hypothesis.

A vehicle on its unlocked suspension inside the carrying frame is a frame and a sprung body:
its apparent inertia depends on the frequency, and the rigid-body fit fails its ``sub_bands``
check (Ljung 1999 ch. 16: a model whose parameters change across frequency bands misses
dynamics).  Fitting the two-body model (:mod:`~rig_identification.diagnosis.compliant_body`)
costs 50–90 s of CPU and gives a hypothesis only — its tensor at rest is not yet trusted
(:data:`~rig_identification.diagnosis.compliant_body.TENSOR_TRUSTED`) — so
``rig-identify inertia`` does not run it: when :func:`two_body_reason` says the body may not be
rigid, the diagnosis carries :func:`not_rigid_hypothesis`, which costs nothing and says what to
do (lock the suspension; ``rig-identify diagnose --model pem --two-body`` fits the sprung body, experimental).

The exciter's speeds (:func:`exciter_speeds`) decide whether a recording swept through the
body's modes (:func:`sweeps`, :data:`SWEEP_MARGIN`).
"""
from __future__ import annotations

import numpy as np

from ..estimation.inertia_result import InertiaResult
from ..io.recording import Recording, SensorData
from .result import Combination

SWEEP_MARGIN = 1.15
"""The exciter must have run at least this factor below and above each of the sprung body's
modes for a two-body fit to fix it (:func:`sweeps`;
:func:`~rig_identification.diagnosis.compliant_body.swept`).  With one exciter speed the
recording shows the apparent tensor J + Σ ℓ ℓᵀ G(j2πf) near that speed only, and the tensor at
rest (f → 0) is an extrapolation that several (J, ℓ, f, ζ) explain to the noise level
(``bench/bench_compliant_body.py``'s fixed-speed runs: fits that passed their validation 3–9 σ
off).  A sweep through the modes shows each resonance's peak and phase turn, which fix ℓ, f and
ζ, and with them the limit."""

NOT_RIGID_ADVICE = ("lock the suspension (strap the body to the frame) and record again; `rig-identify diagnose "
                    "RECORDING --model pem --two-body` fits a sprung body to this recording (experimental, about a "
                    "minute: its modes as a hypothesis, never a tensor)")


def exciter_speeds(sensors: SensorData, lo: float, hi: float) -> tuple[float, float] | None:
    """(slowest, fastest) Hz the rotating exciter ran at over [lo, hi] (absolute stamps, s):
    the 2nd and 98th percentiles of its speed, the unwrapped phase of the measured force in
    the spin plane (exciter x, y) differentiated over 1 s, where the force exceeds 1 % of its
    95th percentile (a spin-up's slow start, whose force ∝ speed² is lost in the noise, left
    out).  None without an exciter stream or when it hardly turned (< 2 revolutions)."""
    ex = sensors.exciter
    if ex is None or len(ex.t) < 10:
        return None
    m = (ex.t >= lo) & (ex.t <= hi)
    t, f = ex.t[m], ex.data[m, :2]
    mag = np.linalg.norm(f, axis=1)
    if len(t) < 10 or not np.any(mag > 0):
        return None
    ph = np.unwrap(np.arctan2(f[:, 1], f[:, 0]))
    n = max(1, int(round(1.0 / float(np.median(np.diff(t))))))
    if len(t) <= n or abs(ph[-1] - ph[0]) < 4 * np.pi:
        return None
    speed = np.abs(ph[n:] - ph[:-n]) / (2 * np.pi * (t[n:] - t[:-n]))
    on = (mag[n:] > 0.01 * np.percentile(mag, 95)) & (mag[:-n] > 0.01 * np.percentile(mag, 95))
    if on.sum() < 10:
        return None
    return float(np.percentile(speed[on], 2)), float(np.percentile(speed[on], 98))


def sweeps(speeds: tuple[float, float] | None) -> bool:
    """The exciter ran over a range of speeds (:func:`exciter_speeds`) wide enough to hold a mode
    with :data:`SWEEP_MARGIN` on both sides: fastest ≥ slowest × SWEEP_MARGIN²."""
    return speeds is not None and speeds[1] >= speeds[0] * SWEEP_MARGIN ** 2


def two_body_reason(rec: Recording, result: InertiaResult, explained: bool) -> str:
    """Why ``rec`` may hold a body that is not rigid, after its rigid-body fit ``result``; ""
    when it does not.  It may when the rig has an exciter, nothing of the ordinary library
    explained the misfit (``explained`` False: no combination of diagnose's effects passed; the
    caller says) and either the rigid-body fit's validation failed ``sub_bands`` (an apparent
    inertia that depends on the frequency) or the exciter swept (:func:`sweeps` over the fit
    window: the recording made to separate the modes).  The one gate of
    :func:`~rig_identification.pipeline.offline.with_diagnosis` and ``rig-identify diagnose``."""
    if explained or rec.rig.exciter is None:
        return ""
    v = result.validation
    if v is not None and "sub_bands" in v.failed:
        return "the rigid-body fit's apparent inertia depends on the frequency (sub_bands failed)"
    speeds = exciter_speeds(rec.sensors, float(result.t_start), float(result.t_end))
    if sweeps(speeds):
        return f"the exciter swept from {speeds[0]:.2f} to {speeds[1]:.2f} Hz"
    return ""


def not_rigid_hypothesis(gate: str) -> Combination:
    """The hypothesis that the body is not rigid, unfitted: one effect entry (name
    ``compliant_body``, no parameters, ``plausible`` False, ``evidence`` {``fitted``: False,
    ``why``: ``gate``}, ``implausible`` why it is not named, ``advice``
    :data:`NOT_RIGID_ADVICE`), no tensor, no wrench, ``not_named`` set so that
    :func:`~rig_identification.pipeline.offline.with_diagnosis` lists it and never fits it.
    ``gate``: :func:`two_body_reason`'s text."""
    why = f"not fitted ({gate}): a sprung body is a hypothesis the rigid-body model cannot test"
    entry = {"name": "compliant_body", "label": "", "parameters": {}, "parameters_std": {}, "plausible": False,
             "evidence": {"fitted": False, "why": gate}, "implausible": why,
             "advice": f"the body may not be rigid: {gate}; {NOT_RIGID_ADVICE}"}
    return Combination(effects=[entry], applied={}, effect_wrench=None, stiffness=None, inertia=None,
                       covariance=None, relative_std=0.0, likelihood_ratio=0.0, dof=0, bic=0.0,
                       keys=(("compliant_body", ""),), not_named=why)
