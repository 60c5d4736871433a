"""The effect library as extensions of the diagnosis model (names:
:data:`~rig_identification.model.effects.EFFECT_NAMES`; the method: :mod:`~rig_identification.diagnosis.selection`).

:func:`candidates`: each effect as :class:`~rig_identification.diagnosis.model_extension.Column` s
linear in its parameters — moment and force regressors (damping, drag, friction, the
exciter's rotor, the cables' and the body's mass), output corrections (the IMU's
misalignment), mean offsets (biases), a sensor delay to first order (``M(t − d) ≈ M − d Ṁ``)
— and how its fitted columns become the effect's reported parameters.  The errors of the
data (:data:`CORRECTIONS`: delays, gains, biases, the IMU's pose, the masses) are also
removed exactly: :func:`corrected` gives the recording without them (re-tracked by the
diagnosis), :func:`body_inertia` the body's tensor without the cables' lower halves.
"""
from __future__ import annotations

from dataclasses import replace as _replace

import numpy as np
from scipy.signal import butter, sosfiltfilt
from scipy.spatial.transform import Rotation

from ..io.recording import Recording, SensorData, TimeSeries
from .model_extension import Candidate, Column, Model
from .retracked import bias_path, random_walk
from .structural import mode_filter
from .window import Window

CORRECTIONS = ("sensor_delay", "load_cell_scale", "cg_offset", "imu_offset", "imu_misalignment", "gyro_bias",
               "gyro_scale", "accelerometer_bias", "body_mass", "gyro_bias_drift", "structural_mode")
"""Effects that are errors of the data, not missing physics: :func:`corrected` removes them."""

FORCE_STREAMS = "load_cells+exciter"
"""The ``sensor_delay`` label of the load cells and the exciter late together (one DAQ's clock
behind the IMU's)."""


# --- the effect library ---------------------------------------------------------------

def _unit(x, floor_frac=0.1):
    nrm = np.linalg.norm(x, axis=1)
    floor = floor_frac * max(np.percentile(nrm, 95), 1e-12)
    return np.where(nrm[:, None] > floor, x / np.maximum(nrm, 1e-300)[:, None], 0.0)


def _lowpass(model: Model, x: np.ndarray) -> np.ndarray:
    """x zero-phase low-passed at the band's upper edge: the regressors that are nonlinear in
    a noisy signal (|ω| ω, sign ω) are formed from it, so the noise does not bias them."""
    sos = butter(4, model.band[1], fs=model.fs, output="sos")
    return sosfiltfilt(sos, x, axis=0)


def _vec(vals, stds, key, applied=None):
    a = np.zeros(len(vals)) if applied is None else np.asarray(applied, float)
    return {key: [float(x) for x in a + np.asarray(vals, float)]}, {key: [float(x) for x in stds]}


def candidates(w: Window, model: Model, base_kappa: float, applied: dict | None = None,
               allow_elasticity: bool = False, profiled: dict | None = None,
               retracked: dict | None = None, cg_free: bool = False) -> list[Candidate]:
    """The effect library as model extensions for this window (names: effects.EFFECT_NAMES).

    applied: corrections already made to the data (key -> accumulated value, see
    :func:`corrected`), added to the reported parameters.  profiled: keys whose value was
    found by the exact profile likelihood (key -> σ, :func:`~rig_identification.diagnosis.exact.exact_profile`):
    they carry no column and report the applied value.  retracked: the first-order columns
    of the errors that act through the tracker (:func:`~rig_identification.diagnosis.retracked.columns`),
    measured once at the baseline — ``"drift"``: (3K columns, knot stamps (K,) s) of
    ``gyro_bias_drift``; ``"scale"``: 3 columns of ``gyro_scale``; ``"modes"``: {sensor:
    :class:`~rig_identification.diagnosis.structural.ModeFit`} of ``structural_mode`` (no
    column: its parameters come from the transfer above the band).  cg_free: rig.yaml's
    centre of gravity is a candidate error too (``cg_offset``)."""
    applied = applied or {}
    profiled = profiled or {}
    m = w.mass
    om, v = w.omega, w.v
    E = np.eye(3)
    out = []

    def scal(keys):
        def rep(vals, stds):
            return ({k: float(x) for k, x in zip(keys, vals)}, {k: float(s) for k, s in zip(keys, stds)})
        return rep

    # viscous damping: M = -c_a ω, F = -c_l v
    out.append(Candidate("viscous_damping", [Column("angular", rot_D=-om), Column("linear", tr_D=-v / m)],
                         scal(["angular", "linear"])))
    # air drag (quadratic) and Coulomb friction (regularised sign, as the simulator), from
    # the low-passed motion
    om_s, v_s = _lowpass(model, om), _lowpass(model, v)
    nw, nv = np.linalg.norm(om_s, axis=1)[:, None], np.linalg.norm(v_s, axis=1)[:, None]
    out.append(Candidate("air_drag", [Column("angular", rot_D=-nw * om_s), Column("linear", tr_D=-nv * v_s / m)],
                         scal(["angular", "linear"])))
    eps = 1e-3
    out.append(Candidate("coulomb_friction",
                         [Column("torque", rot_D=-om_s / np.sqrt(nw**2 + eps**2)),
                          Column("force", tr_D=-v_s / np.sqrt(nv**2 + eps**2) / m)],
                         scal(["torque", "force"])))
    # the exciter's rotor: its weight turning with the unbalanced mass, M = U û × g
    if np.any(w.f_exc):
        uh = _unit(w.f_exc)
        out.append(Candidate("exciter_rotor", [Column("unbalance", rot_D=np.cross(uh, w.g_body))],
                             scal(["unbalance"])))
    # sensor delays (first order): the stream lags by d -> true = measured + d d/dt(measured)
    # (only the readings lag, not the pose: d/dt of the tension, not of T u)
    t = w.t
    Fd = np.gradient(w.tensions, t, axis=0)[:, :, None] * w.u
    streams = [("load_cells", Fd.sum(1), np.cross(w.r_cables[None], Fd).sum(1))]
    if np.any(w.f_exc):
        dfe = np.gradient(w.f_exc, t, axis=0)
        streams.append(("exciter", dfe, np.cross(w.r_exc, dfe)))
        # both force streams late together (one DAQ's clock behind the IMU's): the same as the
        # IMU early; only the streams' relative time is in the recording
        streams.append((FORCE_STREAMS, streams[0][1] + dfe, streams[0][2] + np.cross(w.r_exc, dfe)))
    for stream, F, Mo in streams:
        done = float(applied.get(("sensor_delay", stream), 0.0))

        def rep_d(vals, stds, stream=stream, done=done):
            return {"stream": stream, "delay": done + float(vals[0])}, {"delay": float(stds[0])}
        out.append(Candidate("sensor_delay", [Column("delay", rot_D=Mo, tr_D=F / m)], rep_d, label=stream,
                             stream=stream, exact=True))
    # load-cell gains, one candidate per cable (a gain error is one cell's fault; the four
    # gains together are nearly collinear with an accelerometer bias and the static pose):
    # true T_i = T_meas,i (1 - e_i) -> -e_i times cable i's wrench
    cable_force, cable_moment = w.cable_force, w.cable_moment     # (N,n,3) each: computed once, not per cable
    for i, name in enumerate(w.cable_names):
        Fi = cable_force[:, i]
        done_e = float(applied.get(("load_cell_scale", name), 0.0))

        if ("load_cell_scale", name) in profiled:   # σ looked up when reported: the profile sets it last
            out.append(Candidate("load_cell_scale", [], lambda vals, stds, name=name, e=done_e: (
                {"cable": name, "scale": 1.0 / (1.0 - e)},
                {"scale": profiled[("load_cell_scale", name)] / (1.0 - e) ** 2}), label=name, exact=True))
            continue

        def rep_scale(vals, stds, name=name, done_e=done_e):
            keep = (1.0 - done_e) * (1.0 - float(vals[0]))      # true / measured
            return {"cable": name, "scale": 1.0 / keep}, {"scale": float(stds[0]) / keep}
        out.append(Candidate("load_cell_scale", [Column(f"gain_error_{name}", rot_D=-cable_moment[:, i],
                                                        tr_D=-Fi / m, dca=(Fi / m).mean(0))],
                             rep_scale, label=name, exact=True))
    # IMU offset δ (body axes): the specific force at the true point is α×δ + ω×(ω×δ) more
    cols = []
    for k in range(3):
        d = np.cross(model.alpha, E[k]) + np.cross(om, np.cross(om, E[k]))
        cols.append(Column(f"offset_{'xyz'[k]}", tr_D=d, dca=-d.mean(0)))
    out.append(Candidate("imu_offset", cols,
                         lambda vals, stds: _vec(vals, stds, "offset", applied.get(("imu_offset", ""))),
                         exact=True))
    # centre of gravity off by δ (body axes; true CG = rig.yaml's + δ; only when asked:
    # cg_free): the moment about the true CG is the computed one + F × δ (F the measured
    # non-gravity force), and the IMU's lever arm from the CG is δ shorter
    if cg_free:
        cols = []
        for k in range(3):
            d = np.cross(model.alpha, E[k]) + np.cross(om, np.cross(om, E[k]))
            cols.append(Column(f"cg_{'xyz'[k]}", rot_D=np.cross(w.force, E[k]), tr_D=-d, dca=d.mean(0)))
        out.append(Candidate("cg_offset", cols,
                             lambda vals, stds: _vec(vals, stds, "offset", applied.get(("cg_offset", ""))),
                             exact=True))
    # IMU misalignment δ (body axes, small): true ω = ω_meas + δ × ω_meas, same for f
    cols = [Column(f"rot_{'xyz'[k]}", rot_O=np.cross(E[k], model.y), tr_O=np.cross(E[k], model.ya),
                   dcg=np.cross(E[k], w.omega.mean(0)), dca=np.cross(E[k], w.f.mean(0))) for k in range(3)]
    done_rv = np.asarray(applied.get(("imu_misalignment", ""), np.zeros(3)), float)
    R0 = w.imu_rot_yaml

    def rep_mis(vals, stds):
        Rb = Rotation.from_rotvec(np.asarray(vals, float)) * Rotation.from_rotvec(done_rv)   # body axes
        Rd = Rotation.from_matrix(R0.T @ Rb.as_matrix() @ R0)                               # IMU axes
        return {"rpy": [float(x) for x in Rd.as_euler("xyz")]}, {"rpy": [float(s) for s in stds]}
    out.append(Candidate("imu_misalignment", cols, rep_mis, exact=True))
    # biases (IMU axes): mean-level offsets
    Rimu = w.imu_rot
    cols = [Column(f"bias_{'xyz'[k]}", dcg=-(Rimu @ E[k])) for k in range(3)]
    out.append(Candidate("gyro_bias", cols,
                         lambda vals, stds: _vec(vals, stds, "bias", applied.get(("gyro_bias", ""))), exact=True))
    # (no gyro_scale candidate: a scale factor on the gyro is the tensor scaled, to first order —
    # ω_meas = S P ∫M — and only the asymmetry of S P tells them apart; the exact iteration ran
    # off to a zero gyro on clean rigs.  corrected() removes a known one; the validation flags one)
    cols = [Column(f"bias_{'xyz'[k]}", dca=-(Rimu @ E[k])) for k in range(3)]
    out.append(Candidate("accelerometer_bias", cols,
                         lambda vals, stds: _vec(vals, stds, "bias", applied.get(("accelerometer_bias", ""))),
                         exact=True))
    # cable mass: half of each cable (mass μ per anchor) moves with the body, outside the load cell
    f_cg = w.force / m
    Dm = np.zeros_like(om)
    Fm = np.zeros_like(om)
    for r in w.r_cables:
        a_i = f_cg + np.cross(model.alpha, r) + np.cross(om, np.cross(om, r))   # anchor specific force
        Dm -= np.cross(r, a_i)
        Fm -= a_i
    # (the first-order column is no guide: the selection evaluates the mass exactly, the rig's
    # body given the cables' lower halves, :func:`corrected`, and places it by its profile)
    key, done_mu = ("cable_mass", ""), float(applied.get(("cable_mass", ""), 0.0))
    if key in profiled:
        out.append(Candidate("cable_mass", [], lambda vals, stds, mu=done_mu: (
            {"mass": 2 * mu}, {"mass": 2 * profiled[("cable_mass", "")]}), exact=True))
    else:
        out.append(Candidate("cable_mass", [Column("mass_half", rot_D=Dm, tr_D=Fm / m, dca=-(Fm / m).mean(0))],
                             lambda vals, stds, mu=done_mu: ({"mass": 2 * (mu + float(vals[0]))},
                                                             {"mass": 2 * float(stds[0])}), exact=True))
    # body mass: rig.yaml's body.mass is off by δ kg (a weighing error; evaluated exactly, as
    # the cables' mass, which it competes with: the same weight surplus, without the cables'
    # lever arms)
    key_b, done_b = ("body_mass", ""), float(applied.get(("body_mass", ""), 0.0))
    if key_b in profiled:
        out.append(Candidate("body_mass", [], lambda vals, stds, d=done_b: (
            {"mass_error": d}, {"mass_error": profiled[("body_mass", "")]}), exact=True))
    else:
        out.append(Candidate("body_mass", [Column("mass_error", tr_D=-f_cg / m, dca=(f_cg / m).mean(0))],
                             lambda vals, stds, d=done_b: ({"mass_error": d + float(vals[0])},
                                                           {"mass_error": float(stds[0])}), exact=True))
    # cable elasticity: the pose re-tracked with stretching cables (compliance fitted by the tracker)
    if allow_elasticity:
        out.append(Candidate("cable_elasticity", [], lambda vals, stds: ({"stiffness": float(vals[0])},
                                                                         {"stiffness": float(stds[0])}),
                             exact=True))
    out.extend(_retracked_candidates(retracked or {}, applied))
    # gyroscopic coupling: only a model without it can miss it
    if base_kappa == 0.0:
        out.append(Candidate("gyroscopic_coupling", [], lambda vals, stds: ({"scale": float(vals[0])},
                                                                            {"scale": float(stds[0])}),
                             gyroscopic=True))
    return out


def _retracked_candidates(retracked: dict, applied: dict) -> list[Candidate]:
    """``gyro_bias_drift``, ``gyro_scale`` and ``structural_mode`` from their re-tracked
    columns (:func:`candidates`' ``retracked``); the reported values add what ``applied``
    already removed from the data."""
    out = []
    if "drift" in retracked:
        cols, knot_t = retracked["drift"]
        done = np.asarray(applied.get(("gyro_bias_drift", ""), np.zeros(len(cols))), float)

        def rep_drift(vals, stds, done=done, knot_t=knot_t):
            c = done + np.asarray(vals, float)
            rw = random_walk(c, stds, knot_t)
            return ({"random_walk": rw.intensity, "knot_spacing": float(np.mean(np.diff(knot_t))),
                     "bias_range": [float(np.ptp(x)) for x in c.reshape(3, -1)]},
                    {"random_walk": rw.std})
        out.append(Candidate("gyro_bias_drift", cols, rep_drift, exact=True))
    if "scale" in retracked:
        done_s = np.asarray(applied.get(("gyro_scale", ""), np.zeros(3)), float)

        def rep_scale(vals, stds, done=done_s):
            return ({"scale": [float(1.0 + x) for x in done + np.asarray(vals, float)]},
                    {"scale": [float(x) for x in stds]})
        out.append(Candidate("gyro_scale", retracked["scale"], rep_scale, exact=True))
    for sensor, fit in retracked.get("modes", {}).items():
        def rep_mode(vals, stds, sensor=sensor, fit=fit):
            # not located: only p / f_n² is determined, the frequency is the physical
            # oscillator's (p = 1, no σ of its own) and says so
            return ({"sensor": sensor, "frequency": fit.frequency, "damping_ratio": fit.damping_ratio,
                     "participation": fit.participation, "frequency_located": fit.located},
                    {k: v for k, v in fit.std.items() if np.isfinite(v)})
        # no column: the mode is placed by the transfer above the band (inside it, the tensor
        # absorbs most of it), and evaluated exactly with those values (the selection's FIXED)
        out.append(Candidate("structural_mode", [], rep_mode, label=sensor, exact=True))
    return out


def corrected(rec: Recording, applied: dict) -> Recording:
    """The recording with the sensor and rig errors of ``applied`` removed (key -> value):
    ("sensor_delay", stream) s: the stream's stamps − d (:data:`FORCE_STREAMS`: the load cells'
    and the exciter's); ("load_cell_scale", cable) e:
    the cable's tension T (1 − e); ("imu_offset", "") (3,) m body: imu.position + δ; ("imu_misalignment", "")
    (3,) rotation vector, body axes: IMU axes turned by it; ("gyro_bias" | "accelerometer_bias",
    "") (3,) IMU axes: subtracted; ("gyro_bias_drift", "") (3K,) rad/s: the drifting bias
    through those knot values (axis-major) at the knot stamps ("gyro_bias_drift", "knots")
    (K,) s, subtracted (:func:`~rig_identification.diagnosis.retracked.bias_path`);
    ("gyro_scale", "") (3,) ε per IMU axis: the gyro divided by 1 + ε (after the biases);
    ("structural_mode", sensor) participation p of a mode of shape ("structural_mode",
    sensor + " shape") = (frequency Hz, damping ratio): removed from that sensor's readings
    (``imu``: gyro and accelerometer, after their biases and scale; ``load_cells``: every
    tension, after its gain; :func:`~rig_identification.diagnosis.structural.mode_filter`);
    ("body_mass", "") δ kg: body.mass + δ; ("cg_offset", "") (3,) m body: body.center_of_gravity + δ
    (before the cables' mass moves it); ("cable_mass", "") μ kg: the rig's body carries μ at each
    body anchor (the lower half of each cable, outside its load cell at the ceiling): mass
    + n μ, the centre of gravity moved to the combined one (the tensor fitted is then the
    combined body's, :func:`body_inertia` gives the body's).  ("cable_elasticity", "") is
    handled by the tracker."""

    rig, s = rec.rig, rec.sensors
    imu = s.imu.data.copy()
    imu[:, :3] -= np.asarray(applied.get(("gyro_bias", ""), np.zeros(3)))
    if ("gyro_bias_drift", "") in applied:
        imu[:, :3] -= bias_path(s.imu.t, applied[("gyro_bias_drift", "knots")], applied[("gyro_bias_drift", "")])
    imu[:, :3] /= 1.0 + np.asarray(applied.get(("gyro_scale", ""), np.zeros(3)))
    imu[:, 3:] -= np.asarray(applied.get(("accelerometer_bias", ""), np.zeros(3)))
    p_imu = float(applied.get(("structural_mode", "imu"), 0.0))
    if p_imu:
        imu = mode_filter(s.imu.t, imu, *applied[("structural_mode", "imu shape")], p_imu)
    cells = {}
    d_both = float(applied.get(("sensor_delay", FORCE_STREAMS), 0.0))
    d_cells = applied.get(("sensor_delay", "load_cells"), 0.0) + d_both
    gains = np.array([float(applied.get(("load_cell_scale", n), 0.0)) for n in rig.cable_names])
    p_cells = float(applied.get(("structural_mode", "load_cells"), 0.0))
    for n, ts in s.load_cells.items():
        T = ts.data * (1.0 - gains[rig.cable_names.index(n)])
        if p_cells:
            T = mode_filter(ts.t, T, *applied[("structural_mode", "load_cells shape")], p_cells)
        cells[n] = TimeSeries(ts.t - d_cells, T)
    exc = s.exciter
    if exc is not None and (("sensor_delay", "exciter") in applied or d_both):
        exc = TimeSeries(exc.t - applied.get(("sensor_delay", "exciter"), 0.0) - d_both, exc.data)
    s2 = SensorData(TimeSeries(s.imu.t, imu), cells, exc, s.inclinometer)
    imu_m = rig.imu
    if ("imu_offset", "") in applied:
        imu_m = _replace(imu_m, position=imu_m.position + np.asarray(applied[("imu_offset", "")]))
    if ("imu_misalignment", "") in applied:
        Rb = Rotation.from_rotvec(np.asarray(applied[("imu_misalignment", "")], float))
        imu_m = _replace(imu_m, rpy=(Rb * imu_m.rotation).as_euler("xyz"))
    rig = _replace(rig, imu=imu_m, mass=rig.mass + float(applied.get(("body_mass", ""), 0.0)))
    if ("cg_offset", "") in applied:
        rig = _replace(rig, center_of_gravity=rig.require_cg() + np.asarray(applied[("cg_offset", "")], float))
    mu = float(applied.get(("cable_mass", ""), 0.0))
    if mu:
        rig = _replace(rig, mass=rig.mass + mu * len(rig.cables), center_of_gravity=_combined_cg(rig, mu))
    return _replace(rec, rig=rig, sensors=s2)


def _combined_cg(rig, mu: float) -> np.ndarray:
    """Centre of gravity (3,) m, body frame, of the rig's body with μ kg at each body anchor."""
    m, b = rig.mass, rig.body_anchors
    return (m * rig.require_cg() + mu * b.sum(0)) / (m + mu * len(b))


def with_stiffness(rec: Recording, k: np.ndarray) -> Recording:
    """``rec`` with every cable's axial stiffness (n,) N/m set in its rig."""
    return _replace(rec, rig=_replace(rec.rig, cables=tuple(_replace(c, stiffness=float(ki))
                                                            for c, ki in zip(rec.rig.cables, k))))


def body_inertia(J: np.ndarray, rig, mu: float) -> np.ndarray:
    """The body's inertia tensor about its own centre of gravity (3,3) kg·m² from ``J``
    (3,3), that of the body with μ kg at each body anchor about their combined centre of
    gravity (:func:`corrected`'s cable mass): parallel-axis theorem (Huygens–Steiner),
    J_b = J − m S(c_b − c) − μ Σ S(r_i − c), S(d) = |d|² I − d dᵀ; ``rig`` the rig.yaml's
    (with the body's mass as diagnosed)."""
    if not mu:
        return J
    m, cb, b = rig.mass, rig.require_cg(), rig.body_anchors
    c = _combined_cg(rig, mu)
    S = lambda d: float(d @ d) * np.eye(3) - np.outer(d, d)  # noqa: E731
    return J - m * S(cb - c) - mu * sum(S(r - c) for r in b)
