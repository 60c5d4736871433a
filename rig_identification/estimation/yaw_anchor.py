"""The yaw of a tracked pose anchored by the moment balance where the cables leave it free.

The tracker (:mod:`rig_identification.estimation.tracker`) corrects position and yaw toward the cables' length
constraints.  Cables splayed radially from the body's centre — their horizontal directions
through the body anchors' centroid, a common rig — do not change length when the body turns
about the vertical, to first order: the yaw is then the gyro's integral alone
(:data:`~rig_identification.estimation.tracker.YAW_PRIOR`), and its starting error stays for the whole recording.  A
constant yaw error ψ₀ turns every cable's horizontal pull in the body axes: the torque the
preprocessor computes is off by ∂M/∂ψ · ψ₀ wherever the tensions vary — on a 3-cable rig,
1.3 mrad put three entries 4–5 σ off while every validation check passed.

The cables do hold the yaw through their *forces* (the bifilar pendulum's restoring moment,
first order in ψ).  Over a window of bounded motion the yaw moment about the CG averages to
the change of angular momentum over the window, ≈ 0 (Newton–Euler: dL/dt = M), so the
computed mean world-z moment is K ψ₀ with K = ∂M̄_z/∂ψ, evaluated by turning the tracked
poses about the vertical through the CG.  :func:`anchor_yaw` removes ψ₀ = M̄_z / K from the
poses when the lengths leave the yaw weakly determined (:func:`yaw_information` below
:data:`YAW_WEAK`); where they determine it, the tracker's yaw is kept.  On the 3-cable rig
the estimate matched the true offset to 1 % (−1.314 vs 1.327 mrad) and the three entries
came back within 2 σ.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

from ..io.rig import Rig
from .preprocessor import generalized_wrench
from .tracker import PoseTrack

if TYPE_CHECKING:
    from ..io.recording import SensorData

YAW_WEAK = 1e-2      # yaw information / position information below which the yaw is anchored
MAX_OFFSET = 0.05    # rad: a larger estimate is not a tracker's starting error; the poses are left as they are
STEP = 1e-4          # rad: the finite difference of K


@dataclass(frozen=True)
class YawAnchor:
    """What :func:`anchor_yaw` did: information — the yaw's information from the cable
    lengths over the position's (:func:`yaw_information`); offset rad — the yaw turned
    out of the poses (0 when not applied); stiffness N·m/rad — K = ∂M̄_z/∂ψ; applied;
    note — why not, when not."""

    information: float
    offset: float = 0.0
    stiffness: float = 0.0
    applied: bool = False
    note: str = ""


def yaw_information(rig: Rig, position: np.ndarray, rotation: Rotation) -> float:
    """How well the cable lengths determine the yaw at a pose: the Schur complement of the
    yaw in the Gauss–Newton matrix GᵀG of the length constraints (rows
    G_i = (−u_i, −(R b_i × u_i)_z), the tracker's; thesis eqs. 2.13–2.19), over the mean
    information per position coordinate (tr of the position block / 3).  Dimensionless,
    m² per m²: 0 for radially splayed cables, ~0.1 for the thesis's rigs.

    position (3,) world m of the body origin; rotation body -> world."""
    rb = rotation.apply(rig.body_anchors)
    v = rig.ceiling_anchors - (position + rb)
    u = v / np.linalg.norm(v, axis=1)[:, None]
    G = np.column_stack([-u, -np.cross(rb, u)[:, 2]])
    A = G.T @ G
    pp, py, yy = A[:3, :3], A[:3, 3], A[3, 3]
    schur = yy - py @ np.linalg.pinv(pp) @ py
    return float(max(schur, 0.0) / max(np.trace(pp) / 3.0, 1e-300))


def anchor_yaw(rig: Rig, track: PoseTrack, sensors: SensorData, lo: float, hi: float) -> tuple[PoseTrack, YawAnchor]:
    """The poses ``track`` with the yaw anchored by the moment balance over the window
    [lo, hi] (absolute stamps, s) where the cable lengths leave it free (module docstring).

    sensors: the cleaned :class:`~rig_identification.io.recording.SensorData` the poses were tracked from (its
    tensions and exciter force give the moments).  Returns (poses, :class:`YawAnchor`): the
    poses turned about the vertical through the CG by −ψ₀ (attitude and the body origin's
    position; the CG and the velocities unchanged), or ``track`` itself when the yaw is
    determined by the lengths, the window is empty or the estimate is beyond
    :data:`MAX_OFFSET`."""
    cg = rig.require_cg()
    m = (track.t >= lo) & (track.t <= hi)
    if m.sum() < 10:
        return track, YawAnchor(float("nan"), note="no poses in the window")
    R = Rotation.from_quat(track.quaternion[m])
    info = yaw_information(rig, track.position[m].mean(axis=0), R.mean())
    if info >= YAW_WEAK:
        return track, YawAnchor(info, note="the cable lengths determine the yaw")
    t = track.t[m]
    tens = np.column_stack([np.interp(t, sensors.load_cells[n].t, sensors.load_cells[n].data[:, 0])
                            for n in rig.cable_names])
    exc = sensors.exciter.interp(t) if (sensors.exciter is not None and rig.exciter is not None) else None
    # the mean world-z moment about the CG with the poses turned by +STEP, -STEP and 0 about
    # the vertical through the CG: the attitude R_z(ψ) R, the body origin p_cg − R_z(ψ) R cg.
    # The world z-axis is R_z's own, so the moment's world z-component is R's third row (as a
    # matrix) times the body-axes moment: R, R cg once for the three trials
    Rm = R.as_matrix()                                              # (n,3,3)
    rc = R.apply(cg)                                                # (n,3) world
    p_cg = track.position[m] + rc
    mz = np.empty(3)
    for k, Rz in enumerate(Rotation.from_rotvec(np.outer([STEP, -STEP, 0.0], [0.0, 0.0, 1.0])).as_matrix()):
        _, M = generalized_wrench(rig, p_cg - rc @ Rz.T, np.matmul(Rz, Rm), tens, exc)
        mz[k] = np.mean(np.einsum("nj,nj->n", Rm[:, 2, :], M))
    K = float((mz[0] - mz[1]) / (2 * STEP))
    if not np.isfinite(K) or K == 0.0:
        return track, YawAnchor(info, note="the cables' forces do not hold the yaw either")
    psi = -float(mz[2]) / K
    if abs(psi) > MAX_OFFSET:
        return track, YawAnchor(info, psi, K, False, f"the moment balance asks for {psi:.3g} rad: not a tracker's "
                                                    "starting error, the poses are left as they are")
    Rz = Rotation.from_rotvec([0.0, 0.0, psi])
    R_all = Rotation.from_quat(track.quaternion)
    cg_w = track.position + R_all.apply(cg)
    R_new = Rz * R_all
    return replace(track, position=cg_w - R_new.apply(cg), quaternion=R_new.as_quat()), YawAnchor(info, psi, K, True)
