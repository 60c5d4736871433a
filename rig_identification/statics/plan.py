"""Design of the static experiment: the predicted CG σ of a planned test and a recommended one.

:func:`predict_cg_std` solves the baseline and dummy states at equilibrium for a guessed CG
(:func:`~rig_identification.statics.model.static_equilibrium`), gives them the σ of the mean
a window of the planned length would have with the sensors' noise (:class:`SensorNoise`) and
returns the estimator's result at these noise-free means; :func:`plan_static_test` searches
dummy masses and positions for the shortest test reaching a target (:class:`CgPlan`).

Frames and units: body frame; SI units (m, kg, N, rad, s).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from ..io.rig import DummyMass, Rig
from .estimation import estimate_cg
from .model import CgOptions, Z, static_equilibrium
from .result import CgResult
from .state import StaticsError, StaticState


@dataclass(frozen=True)
class SensorNoise:
    """White-noise σ and rates of the rig's sensors (defaults: the reference recordings).

    load_cell N, inclinometer rad, accelerometer m/s², gyro rad/s, exciter N; rates Hz.
    """

    load_cell: float = 0.5
    inclinometer: float = 2e-4
    accelerometer: float = 0.01
    gyro: float = 0.002
    exciter: float = 0.5
    rate_load_cells: float = 200.0
    rate_inclinometer: float = 50.0
    rate_imu: float = 200.0
    rate_exciter: float = 200.0

    @classmethod
    def from_state(cls, st: StaticState, duration: float | None = None) -> "SensorNoise":
        """The scatter and rates measured in a :class:`StaticState` (window length = duration)."""
        d = duration or (st.window[1] - st.window[0])
        kw = {}
        s = st.stats
        cells = [v for k, v in s.items() if k.startswith("load_cell:")]
        if cells:
            kw["load_cell"] = float(np.sqrt(np.mean([c.scatter[0] ** 2 for c in cells])))
            kw["rate_load_cells"] = (cells[0].n - 1) / d
        if "inclinometer" in s:
            kw["inclinometer"] = float(np.sqrt(np.mean(s["inclinometer"].scatter ** 2)))
            kw["rate_inclinometer"] = (s["inclinometer"].n - 1) / d
        if "imu" in s:
            kw["accelerometer"] = float(np.sqrt(np.mean(s["imu"].scatter[3:] ** 2)))
            kw["gyro"] = float(np.sqrt(np.mean(s["imu"].scatter[:3] ** 2)))
            kw["rate_imu"] = (s["imu"].n - 1) / d
        return cls(**kw)


def _ideal_state(rig: Rig, R, T, duration: float, noise: SensorNoise, added, label) -> StaticState:
    """The noise-free means of a state with the σ of the mean a ``duration`` s window would give."""
    n_T = max(1, int(duration * noise.rate_load_cells))
    n_e = max(1, int(duration * noise.rate_inclinometer))
    n_a = max(1, int(duration * noise.rate_imu))
    elev = None
    if rig.inclinometer is not None:
        ax = R @ rig.inclinometer.rotation.as_matrix()
        elev = np.arcsin(np.clip(ax[2, :2], -1, 1))
    f = rig.imu.rotation.as_matrix().T @ R.T @ (rig.gravity * Z)
    return StaticState(tuple(rig.cable_names), T.copy(), np.full(len(T), noise.load_cell / math.sqrt(n_T)),
                       elev, None if elev is None else np.full(2, noise.inclinometer / math.sqrt(n_e)),
                       f, np.full(3, noise.accelerometer / math.sqrt(n_a)), tuple(added), (0.0, duration),
                       label=label)


def predict_cg_std(rig: Rig, cg, dummy: DummyMass, duration: float, noise: SensorNoise | None = None,
                   options: CgOptions | None = None, compliance: float | None = None) -> CgResult:
    """Predicted estimate of a planned static test (experiment design).

    The two states are solved at equilibrium for the assumed CG ``cg`` (3,) body m (a
    guess), the rig's mass and the dummy mass ``dummy`` (mass kg, position body m), each
    averaged for ``duration`` s with the sensor ``noise``; the estimator's covariance at
    these noise-free means is the CG covariance the test will have (``center_of_gravity_std``
    (3,) m, with the geometry σ of ``options`` -- by default the 1 mm survey; the noise alone:
    ``center_of_gravity_std_noise``).  Raises :class:`StaticsError` (no equilibrium, slack
    cable, ineffective dummy).
    """
    noise = noise or SensorNoise()
    opts = options or CgOptions.from_survey(rig.survey)
    R0, p0, T0 = static_equilibrium(rig, rig.mass, cg, (), compliance)
    R1, p1, T1 = static_equilibrium(rig, rig.mass, cg, (dummy,), compliance)
    b = _ideal_state(rig, R0, T0, duration, noise, (), "baseline")
    d = _ideal_state(rig, R1, T1, duration, noise, (dummy,), "dummy")
    return estimate_cg(rig, b, d, replace(opts, inflate=False))


@dataclass(frozen=True)
class CgPlan:
    """A planned static test: dummy mass kg, position (3,) body m, averaging time s per
    state, predicted CG σ (3,) m, the tilt change it causes rad, the lowest cable
    tension N over both states, whether it reaches the target, and ``floor``: the CG σ (3,) m
    no averaging time goes below (the systematic inputs' share: geometry σ of :class:`CgOptions`)."""

    dummy: DummyMass
    duration: float
    std: np.ndarray
    tilt_change: float
    min_tension: float
    reaches_target: bool
    floor: np.ndarray | None = None

    def to_dict(self) -> dict:
        return {"dummy_mass": float(self.dummy.mass), "dummy_position": [float(x) for x in self.dummy.position],
                "duration": float(self.duration), "center_of_gravity_std": [float(x) for x in self.std],
                "center_of_gravity_std_floor": None if self.floor is None else [float(x) for x in self.floor],
                "half_width_95": [float(1.96 * x) for x in self.std], "tilt_change_rad": float(self.tilt_change),
                "min_tension": float(self.min_tension), "reaches_target": bool(self.reaches_target)}


def candidate_positions(rig: Rig) -> list[np.ndarray]:
    """Default dummy-mass positions to try (body frame): the body anchors and the corners of
    their horizontal bounding box 1 m below them (where a carrying frame has mounting points)."""
    b = rig.body_anchors
    lo, hi = b.min(0), b.max(0)
    out = [x.copy() for x in b]
    ztop = b[:, 2].mean()
    for x in (lo[0], hi[0]):
        for y in (lo[1], hi[1]):
            out.append(np.array([x, y, ztop - 1.0]))
    uniq: list[np.ndarray] = []
    for p in out:
        if not any(np.allclose(p, q) for q in uniq):
            uniq.append(p)
    return uniq


@dataclass(frozen=True)
class PlanLimits:
    """What a static test's plan must reach and may not do (:func:`plan_static_test`).

    target: the CG's 95 % half-width asked of every coordinate, m.  max_duration: the longest
    averaging per state, s.  max_tilt: the most the dummy may tilt the body, rad.
    min_tension_fraction: the least tension a cable may keep, as a share of an even share of the
    weight.
    """

    target: float = 2.5e-3
    max_duration: float = 600.0
    max_tilt: float = math.radians(5.0)
    min_tension_fraction: float = 0.1


def plan_static_test(rig: Rig, cg_guess, masses: Sequence[float] = (25.0, 50.0, 100.0, 200.0),
                     positions: Sequence | None = None, noise: SensorNoise | None = None,
                     options: CgOptions | None = None, limits: PlanLimits = PlanLimits()
                     ) -> tuple[CgPlan | None, list[CgPlan]]:
    """Recommend a static test reaching ±``limits.target`` m (1.96 σ) on every CG coordinate.

    For every dummy mass (kg) in ``masses`` and position (body m; default
    :func:`candidate_positions`), the CG variance is predicted (:func:`predict_cg_std`) at 10 s
    and 100 s of averaging per state and modelled per coordinate as σ²(t) = a/t + b (the
    noise of the means averages down, priors such as the dummy-position σ do not); the
    shortest time (rounded up to 5 s, at least 10 s) reaching the target is re-checked.
    Plans that tilt the body by more than ``limits.max_tilt`` rad or leave a cable below
    ``limits.min_tension_fraction`` of an even share of the weight are skipped.  The
    recommendation is the plan reaching the target within ``limits.max_duration`` s with the
    shortest time, then the smallest mass, then the smallest σ.

    Returns (recommended :class:`CgPlan` or None, every evaluated plan -- for those that cannot
    reach the target, ``duration`` is ``max_duration`` and ``reaches_target`` false).
    """
    noise = noise or SensorNoise()
    target, max_duration = limits.target, limits.max_duration
    positions = candidate_positions(rig) if positions is None else [np.asarray(p, float) for p in positions]
    share = rig.mass * rig.gravity / len(rig.cables)
    s2 = (target / 1.96) ** 2
    plans = []
    for m in masses:
        for pos in positions:
            dm = DummyMass(float(m), np.asarray(pos, float))
            try:
                r10 = predict_cg_std(rig, cg_guess, dm, 10.0, noise, options)
                r100 = predict_cg_std(rig, cg_guess, dm, 100.0, noise, options)
            except StaticsError:
                continue
            tilt = r10.weakly_determined["tilt_change_rad"]
            tmin = min(float(st.tensions.min()) for st in r10.states)
            if tilt > limits.max_tilt or tmin < limits.min_tension_fraction * share:
                continue
            v10, v100 = r10.center_of_gravity_std ** 2, r100.center_of_gravity_std ** 2
            a = np.maximum((v10 - v100) / (1 / 10.0 - 1 / 100.0), 0.0)
            bb = np.maximum(v100 - a / 100.0, 0.0)
            if np.any(bb >= s2):
                need = np.inf
            else:
                need = float(np.max(a / (s2 - bb)))
            dur = max(10.0, 5.0 * math.ceil(min(need, 1e9) / 5.0 - 1e-9))
            floor = np.sqrt(bb)
            if dur > max_duration:
                r = predict_cg_std(rig, cg_guess, dm, max_duration, noise, options)
                plans.append(CgPlan(dm, max_duration, r.center_of_gravity_std, tilt, tmin, False, floor))
                continue
            r = r10 if dur == 10.0 else predict_cg_std(rig, cg_guess, dm, dur, noise, options)
            while np.any(1.96 * r.center_of_gravity_std > target) and dur + 5.0 <= max_duration:
                dur += 5.0
                r = predict_cg_std(rig, cg_guess, dm, dur, noise, options)
            ok = bool(np.all(1.96 * r.center_of_gravity_std <= target))
            plans.append(CgPlan(dm, dur, r.center_of_gravity_std, tilt, tmin, ok, floor))
    feasible = [p for p in plans if p.reaches_target]
    best = min(feasible, key=lambda p: (p.duration, p.dummy.mass, float(p.std.max()))) if feasible else None
    return best, plans
