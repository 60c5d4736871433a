"""The static states checked around the CG fit: before it, every cable taut, a pose that fits
each state, and a dummy mass that changed both the load and the tilt; after it, no stream that
contradicts the fitted equilibrium (:func:`~.estimation.estimate_cg` refuses the input
otherwise, with a :class:`~.state.StaticsError` that names the state and the cause).
"""
from __future__ import annotations

import numpy as np

from ..estimation.tracker import StaticPose, TrackerError, inclinometer_elevations, static_pose
from ..io.rig import Rig
from .state import StaticsError, StaticState

SLACK_FRACTION = 0.01            # a cable carrying < 1 % of an even share of the weight is slack
# physical tolerances above which a misfit of more than 20 σ means contradictory input (not noise)
TOL_INCL = 5e-4                  # rad
TOL_TENSION_REL = 5e-3           # of the mean tension per cable
TOL_ACCEL = 5e-3                 # m/s^2


def check_taut(rig: Rig, states: list[StaticState], tensions: list[np.ndarray]) -> None:
    """Refuse a state whose mean tension (N,) N of a cable is below :data:`SLACK_FRACTION` of an
    even share of the weight (rig.yaml's mass)."""
    share = rig.mass * rig.gravity / len(rig.cables)
    for s, T in zip(states, tensions):
        slack = np.flatnonzero(T < SLACK_FRACTION * share)
        if slack.size:
            i = slack[0]
            raise StaticsError(f"{s.label}: cable {rig.cable_names[i]} is slack (mean tension {T[i]:.1f} N, "
                               f"an even share of the weight is {share:.0f} N); the static experiment "
                               "needs every cable taut")


def initial_pose(rig: Rig, tens, elev, label: str) -> StaticPose:
    """Pose at rest of one state from the lengths, tensions (N,) N and inclinometer angles (2,) rad
    (tracker.static_pose; either may be None); when no pose fits, raises :class:`StaticsError`
    naming the input that is out of line (``label``: the state)."""
    try:
        return static_pose(rig, tensions=tens, elevations=elev)
    except TrackerError:
        pass
    deg = "°, ".join(f"{np.degrees(x):.3f}" for x in (elev if elev is not None else [])) + "°"
    if elev is not None:
        try:
            static_pose(rig, tensions=None, elevations=elev)
        except TrackerError:
            raise StaticsError(f"{label}: the inclinometer reads {deg} but no pose of the body on these cables "
                               "has that tilt: angles outside the geometry's reach (check rig.yaml's cable "
                               "lengths and anchors, and inclinometer.rpy)") from None
        if tens is not None and rig.inclinometer is not None:
            try:
                ps = static_pose(rig, tensions=tens, elevations=None)
            except TrackerError:
                pass
            else:
                e = inclinometer_elevations(ps.rotation, rig.inclinometer.rotation)
                raise StaticsError(f"{label}: the inclinometer reads {deg} but the cables and load cells hold the "
                                   f"body at {np.degrees(e[0]):.3f}°, {np.degrees(e[1]):.3f}°: angles outside what "
                                   "the geometry allows (check inclinometer.rpy and its mounting)")
    raise StaticsError(f"{label}: no pose of the body matches the cable lengths and the load cells "
                       "(contradictory geometry: check rig.yaml's anchors and cable lengths)")


def vertical_loads(rig: Rig, tensions: list[np.ndarray], poses: list[StaticPose]) -> list[float]:
    """The load (N) the cables carry vertically in each state: Σ T_i u_iz at its pose, rig.yaml's geometry."""
    out = []
    for T, ps in zip(tensions, poses):
        v = rig.ceiling_anchors - (ps.position + ps.rotation.apply(rig.body_anchors))
        out.append(float(T @ (v[:, 2] / np.linalg.norm(v, axis=1))))
    return out


def check_dummy_load(rig: Rig, states: list[StaticState], loads: list[float], added_mass: np.ndarray) -> list[str]:
    """Refuse a dummy state whose load (:func:`vertical_loads`, N) grew by less than 0.3 of its added
    mass (kg; swapped recordings, a dummy not attached); returns a warning for one outside 0.8–1.25
    (a load-cell gain)."""
    warnings = []
    for s, Wd, md in zip(states[1:], loads[1:], added_mass[1:]):
        ratio = (Wd - loads[0]) / (md * rig.gravity) if md > 0 else 1.0
        if md > 0 and ratio < 0.3:
            hint = " (are the two recordings swapped?)" if ratio < -0.3 else " (was the dummy mass attached?)"
            raise StaticsError(f"{s.label}: the load cells carry {(Wd - loads[0]) / rig.gravity:+.1f} kg more than "
                               f"in the baseline, but the dummy mass is {md:g} kg{hint}")
        if md > 0 and not 0.8 < ratio < 1.25:
            warnings.append(f"{s.label}: the load cells see {(Wd - loads[0]) / rig.gravity:.1f} kg added, the "
                            f"dummy mass is {md:g} kg (load-cell gain {1 / ratio:.3f}?)")
    return warnings


def check_tilt_change(states: list[StaticState], poses: list[StaticPose], have_inclinometer: bool) -> None:
    """Refuse a dummy state that did not change the inclination beyond 5 σ of its noise (measured
    by the inclinometer when there is one, else from the tension poses): the CG height would
    not be determined."""
    baseline = states[0]
    for s, ps in zip(states[1:], poses[1:]):
        if have_inclinometer:
            (e, e_sd), (e0, e0_sd) = s.reading("inclinometer"), baseline.reading("inclinometer")
            d = e - e0
            sd = np.hypot(e_sd, e0_sd)
        else:
            d = (ps.rotation * poses[0].rotation.inv()).as_rotvec()[:2]
            sd = np.full(2, 1e-6)
        if not np.any(np.abs(d) > np.maximum(5 * sd, 1e-7)):
            raise StaticsError(f"{s.label}: the dummy mass did not change the inclination (change "
                               f"{d[0] * 1e6:+.1f}, {d[1] * 1e6:+.1f} µrad, noise σ {sd[0] * 1e6:.1f}, "
                               f"{sd[1] * 1e6:.1f} µrad): the CG height cannot be found; fix the dummy mass "
                               "farther from the vertical through the CG")


def stream_misfits(label: str, rig: Rig, streams: list[str], measured: np.ndarray, predicted: np.ndarray,
                   sigma: np.ndarray) -> dict:
    """The misfit of each stream of one state at the fitted equilibrium: {stream: {"misfit": d,
    "normalised": d / σ}}, d = measured − predicted, in the measurement vector's order (streams
    among ``load_cells`` (N,) N, ``inclinometer`` (2,) rad, ``accelerometer`` (3,) m/s²).
    Raises :class:`StaticsError` naming the state (``label``) and the stream where a misfit is
    both > 20 σ and beyond its physical tolerance (:data:`TOL_TENSION_REL` of the tension,
    :data:`TOL_INCL`, :data:`TOL_ACCEL`): contradictory geometry or data."""
    res, k = {}, 0
    for name in streams:
        w = {"load_cells": len(rig.cables), "inclinometer": 2, "accelerometer": 3}[name]
        m, pr = measured[k:k + w], predicted[k:k + w]
        d = m - pr
        rn = d / sigma[k:k + w]
        res[name] = {"misfit": d, "normalised": rn}
        tol = {"load_cells": TOL_TENSION_REL * np.abs(m), "inclinometer": TOL_INCL, "accelerometer": TOL_ACCEL}[name]
        bad = (np.abs(rn) > 20) & (np.abs(d) > tol)
        if bad.any():
            j = int(np.flatnonzero(bad)[0])
            if name == "load_cells":
                why = (f"the load cell of cable {rig.cable_names[j]} reads {m[j]:.1f} N but the best equilibrium of "
                       f"this geometry needs {pr[j]:.1f} N: contradictory geometry or data (check rig.yaml's "
                       "anchors, lengths, masses)")
            elif name == "inclinometer":
                why = (f"the inclinometer reads {np.degrees(m[0]):.3f}°, {np.degrees(m[1]):.3f}° but the body's "
                       f"equilibrium on these cables has {np.degrees(pr[0]):.3f}°, {np.degrees(pr[1]):.3f}°: angles "
                       "outside what the geometry allows (contradictory geometry or inclinometer mounting)")
            else:
                why = ("the accelerometer's gravity direction contradicts the equilibrium pose (check imu.rpy or "
                       "use_accelerometer=False)")
            raise StaticsError(f"{label}: {why}")
        k += w
    return res
