"""The forcing of a simulated run: the unbalanced-mass exciter's rotating force and force pulses.

The rotating force (exciter frame, z = spin axis) is
F = A(t) [cos θ, direction sin θ, 0], θ = 2π f (t - start_time) + phase,
A(t) = amplitude min(1, (t - start_time)/ramp_time), zero before start_time and from
stop_time on (``ramp_shape: linear``).  ``ramp_shape: spin_up`` ramps the motor speed
instead, as the reference simulator does (see :class:`RotatingForce`).  It acts at
``rig.exciter.position``, exciter axes given by ``rig.exciter.rpy``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class RotatingForce:
    """Unbalanced-mass force in the exciter frame (see module docstring).  SI units.

    ramp_shape ``linear``: the amplitude ramps linearly over ramp_time at constant frequency.
    ``spin_up``: the motor speed ramps linearly from 0, so the phase is its integral and the
    amplitude grows with the speed squared (the reference simulator's ramp):
    θ = π f τ²/ramp_time + phase and A = amplitude (τ/ramp_time)² for τ < ramp_time, then
    θ = 2π f (τ - ramp_time/2) + phase (τ = t - start_time).
    """

    amplitude: float
    frequency: float
    ramp_time: float = 0.0
    phase: float = 0.0
    direction: int = 1
    start_time: float = 0.0
    stop_time: float | None = None
    ramp_shape: str = "linear"

    def force(self, t: float) -> np.ndarray:
        """Exciter-frame force (3,) N at time t s."""
        tau = t - self.start_time
        if tau < 0 or (self.stop_time is not None and t >= self.stop_time):
            return np.zeros(3)
        T, f = self.ramp_time, self.frequency
        if tau >= T:
            amp = self.amplitude
            theta = 2 * math.pi * f * (tau - (T / 2 if self.ramp_shape == "spin_up" else 0.0))
        elif self.ramp_shape == "spin_up":
            amp = self.amplitude * (tau / T) ** 2
            theta = math.pi * f * tau ** 2 / T
        else:
            amp = self.amplitude * tau / T
            theta = 2 * math.pi * f * tau
        theta += self.phase
        return np.array([amp * math.cos(theta), self.direction * amp * math.sin(theta), 0.0])

    def angle_and_speed(self, t: float) -> tuple[float, float, float]:
        """Rotor angle θ (rad, exciter frame, signed by ``direction``), spin speed dθ/dt
        (rad/s) and spin acceleration (rad/s²) at time t s; (0, 0, 0) when the motor is off."""
        tau = t - self.start_time
        if tau < 0 or (self.stop_time is not None and t >= self.stop_time):
            return 0.0, 0.0, 0.0
        T, w = self.ramp_time, 2 * math.pi * self.frequency
        if self.ramp_shape == "spin_up" and tau < T:
            theta, speed, acc = math.pi * self.frequency * tau ** 2 / T, w * tau / T, w / T
        elif self.ramp_shape == "spin_up":
            theta, speed, acc = w * (tau - T / 2), w, 0.0
        else:
            theta, speed, acc = w * tau, w, 0.0
        d = self.direction
        return d * (theta + self.phase), d * speed, d * acc

    def breakpoints(self) -> list[float]:
        out = [self.start_time, self.start_time + self.ramp_time]
        return out + ([self.stop_time] if self.stop_time is not None else [])


@dataclass(frozen=True)
class Pulse:
    """A constant force (3,) N on for start <= t < end, acting at ``point`` (3,) body frame."""

    force: np.ndarray
    point: np.ndarray
    start: float
    end: float
    frame: str = "body"
    measured: bool = False


@dataclass(frozen=True)
class Excitation:
    rotating: RotatingForce | None = None
    pulses: tuple[Pulse, ...] = ()

    def describe(self) -> dict[str, Any] | None:
        if self.rotating is None and not self.pulses:
            return None
        out: dict[str, Any] = {}
        if self.rotating is not None:
            r = self.rotating
            out.update(type="rotating", amplitude=r.amplitude, frequency=r.frequency, ramp_time=r.ramp_time,
                       ramp_shape=r.ramp_shape, phase=r.phase, direction=r.direction, start_time=r.start_time,
                       stop_time=r.stop_time)
        else:
            out["type"] = "pulses"
        out["pulses"] = [{"force": p.force.tolist(), "point": p.point.tolist(), "start": p.start, "end": p.end,
                          "frame": p.frame, "measured": p.measured} for p in self.pulses]
        return out
