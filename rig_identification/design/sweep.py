"""How to record a vehicle that is not rigid: a slow sweep of the exciter through its body modes.

A vehicle on its unlocked suspension inside the carrying frame has a sprung body that rolls
and pitches on springs (modes at about 1–3 Hz, :mod:`~rig_identification.model.suspension`).
Its apparent inertia depends on the frequency (J_app(f) = J + Σ ℓ ℓᵀ G(j2πf),
:mod:`~rig_identification.estimation.two_body`), so one exciter speed shows it near that speed
only and the tensor at rest — what a lab wants — is an extrapolation the data do not fix
(:data:`~rig_identification.diagnosis.not_rigid.SWEEP_MARGIN`).  An unbalanced-mass
exciter spun up slowly from rest sweeps through the modes: each resonance's peak and phase
turn fix the mode's frequency, damping and participation, and with them — to about 1 % on
``bench/bench_compliant_body.py``'s rigs, not yet within the fit's σ — the tensor at rest.

:func:`sweep_excitation` writes that run as an experiment file's ``excitation.rotating``
(``ramp_shape: spin_up``: the motor speed ramps linearly, the force grows with the speed
squared); :data:`NON_RIGID_ADVICE` is the advice in words.
"""
from __future__ import annotations

import math

SWEEP_TOP_HZ = 3.5
"""Hz: the sweep's top speed — above a vehicle body's roll, pitch and heave modes (1–3 Hz)
by the margin the candidate needs to name them (:data:`~rig_identification.diagnosis.not_rigid.SWEEP_MARGIN`)."""

NON_RIGID_ADVICE = (
    "A vehicle whose suspension is not locked is not a rigid body (its sprung body rolls and pitches at 1-3 Hz): "
    "either lock the suspension (strap the body to the frame) and record as usual, or record a slow sweep - spin "
    f"the exciter up from rest to {SWEEP_TOP_HZ:g} Hz over the whole recording (90-120 s; the force grows with the "
    "speed squared: size the unbalance for the cables at the top speed) - so that the compliant_body candidate of "
    "`rig-identify diagnose --model pem --two-body` can fit the sprung body's modes (its tensor at rest is not yet "
    "reported: bench/bench_compliant_body.py).")


def sweep_excitation(unbalance: float, duration: float, top_hz: float = SWEEP_TOP_HZ, settle: float = 5.0) -> dict:
    """The experiment file's ``excitation.rotating`` mapping of a sweep
    (:mod:`~rig_identification.model.excitation`): an exciter of ``unbalance`` kg·m (m·e of
    its rotor: the force at speed f Hz is unbalance (2π f)² N) spun up linearly from rest at
    t = 0 to ``top_hz`` Hz over ``duration`` − ``settle`` s (``ramp_shape: spin_up``), then
    held.  Raises ValueError for a non-positive unbalance, top speed or ramp."""
    ramp = float(duration) - float(settle)
    if not unbalance > 0 or not top_hz > 0 or not ramp > 0:
        raise ValueError(f"sweep_excitation: unbalance {unbalance} kg·m, top speed {top_hz} Hz and the ramp "
                         f"{ramp} s (duration − settle) must be positive")
    amplitude = float(unbalance) * (2 * math.pi * float(top_hz)) ** 2
    return {"amplitude": amplitude, "frequency": float(top_hz), "ramp_time": ramp, "ramp_shape": "spin_up",
            "phase": 0.0, "direction": 1, "start_time": 0.0}
