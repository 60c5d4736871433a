"""Physics tests of the simulator's newer concealed effects (rig_identification.model.effects):
gyro_bias_drift, gyro_scale, structural_mode and compliant_body.

Each test compares the effect's recording with the same experiment simulated without it
(same seed) or recomputes the physics from the simulator's outputs; durations are a few
seconds (a 100 s run at rest for the random walk's statistics).
"""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from rig_identification.design.scenarios import simulate_random
from rig_identification.model.equilibrium import equilibrium
from rig_identification.model.experiment import ExperimentError, experiment_from_dict
from rig_identification.model.rigid_body import bearing_inertial_force
from rig_identification.model.sensors import mode_response
from rig_identification.model.simulator import simulate
from rig_identification.model.suspension import split_body

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "config" / "rigs" / "default.yaml"
COMPLIANT = {"name": "compliant_body", "mass_share": 0.68, "frequencies": [1.6, 1.3, 2.2], "damping_ratio": 0.2}
# the rig's own cable-stretch modes (9–11 Hz on the default rig, 1 % damped) would ring in the same band as a
# 7–9 Hz structural mode: the structural-mode tests damp them (30 %) so that what rings is the mode
DAMPED_CABLES = {"type": "spring", "stiffness": 5.0e6, "damping_ratio": 0.3}
KNOCK = {"pulses": [{"force": [300.0, 200.0, 400.0], "point": [0.8, 1.25, 0.5], "start": 0.5, "end": 0.55}]}


def experiment(effects=(), duration=5.0, noise=False, **changes):
    """The default experiment (thesis case 16 rig), noise-free unless ``noise``, with top-level
    fields replaced by ``changes`` ('a__b' for nested keys)."""
    d = yaml.safe_load(DEFAULT.read_text())
    d["duration"] = duration
    if not noise:
        d["sensors"]["noise"] = {}
    for key, value in changes.items():
        *path, last = key.split("__")
        node = d
        for k in path:
            node = node[k]
        node[last] = copy.deepcopy(value)
    d["effects"] = [dict(e) for e in effects]
    return experiment_from_dict(d, "test.yaml")


def cells(res) -> np.ndarray:
    """(K, N) load-cell readings, N."""
    return np.column_stack([res.sensors.load_cells[n].data[:, 0] for n in res.rig.cable_names])


def peak_frequency(x: np.ndarray, rate: float, low: float = 0.2) -> np.ndarray:
    """Frequency (Hz) of the largest spectral peak above ``low`` Hz of each column of x (K, n),
    zero-padded 8x and Hann-windowed."""
    x = (x - x.mean(0)) * np.hanning(len(x))[:, None]
    n = 8 * len(x)
    f = np.fft.rfftfreq(n, 1.0 / rate)
    S = np.abs(np.fft.rfft(x, n, axis=0))
    S[f < low] = 0.0
    return f[S.argmax(0)]


def tone(x: np.ndarray, t: np.ndarray, f: float) -> np.ndarray:
    """Complex amplitude (n,) of the frequency-f sinusoid in each column of x (K, n) (least squares
    with an offset and a linear trend)."""
    A = np.column_stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t), np.ones_like(t), t - t.mean()])
    c = np.linalg.lstsq(A, x, rcond=None)[0]
    return c[0] - 1j * c[1]


# --- gyro_bias_drift -------------------------------------------------------------------------

def test_gyro_bias_drift_is_a_seeded_random_walk_of_the_stated_sigma():
    rw, rate = 2e-4, 200.0
    drift = [{"name": "gyro_bias_drift", "random_walk": rw}]
    res = simulate(experiment(drift, duration=20.0, excitation={}))
    assert res.experiment.sensors.rates["imu"] == rate
    b = res.sensors.imu.data[:, :3]                     # at rest: the reading is the bias
    assert np.abs(res.states.omega).max() < 1e-9
    np.testing.assert_array_equal(b[0], 0.0)            # a Wiener process from 0
    z = np.diff(b, axis=0) / (rw * math.sqrt(1.0 / rate))
    n = len(z)                                           # 4000 increments per axis
    np.testing.assert_allclose(z.std(0), 1.0, atol=4 / math.sqrt(2 * n))   # 4 σ of the std estimate
    assert np.all(np.abs(z.mean(0)) < 4 / math.sqrt(n))
    assert np.abs(np.corrcoef(z.T)[np.triu_indices(3, 1)]).max() < 4 / math.sqrt(n)   # independent axes
    assert np.abs(np.corrcoef(z[1:].ravel(), z[:-1].ravel())[0, 1]) < 4 / math.sqrt(3 * n)  # white increments
    # the same seed gives the same walk, another seed another one
    again = simulate(experiment(drift, duration=20.0, excitation={}))
    np.testing.assert_array_equal(again.sensors.imu.data, res.sensors.imu.data)
    other = simulate(experiment(drift, duration=20.0, excitation={}, seed=17)).sensors.imu.data[:, :3]
    assert np.abs(other[1:] - b[1:]).min() > 0


def test_gyro_bias_drift_leaves_the_other_noise_unchanged():
    plain = simulate(experiment(duration=2.0, noise=True))
    drift = simulate(experiment([{"name": "gyro_bias_drift", "random_walk": 1e-3}], duration=2.0, noise=True))
    np.testing.assert_array_equal(drift.sensors.imu.data[:, 3:], plain.sensors.imu.data[:, 3:])
    np.testing.assert_array_equal(cells(drift), cells(plain))
    np.testing.assert_array_equal(drift.sensors.exciter.data, plain.sensors.exciter.data)
    np.testing.assert_array_equal(drift.sensors.inclinometer.data, plain.sensors.inclinometer.data)
    walk = drift.sensors.imu.data[:, :3] - plain.sensors.imu.data[:, :3]
    assert np.all(np.abs(walk[-1]) > 0) and np.abs(walk).max() < 10 * 1e-3 * math.sqrt(2.0)


# --- gyro_scale ------------------------------------------------------------------------------

def test_gyro_scale_multiplies_the_true_rate_per_imu_axis_before_noise():
    scale = [1.0, 1.005, 0.99]
    imu = {"position": [0.3, -0.2, 0.1], "rpy": [0.2, -0.1, math.pi / 2]}     # IMU axes != body axes
    res = simulate(experiment([{"name": "gyro_scale", "scale": scale}], rig__imu=imu))
    R_imu = Rotation.from_euler("xyz", imu["rpy"]).as_matrix()
    true = res.states.omega @ R_imu                       # true rate, IMU axes
    gyro = res.sensors.imu.data[:, :3]
    big = np.abs(true) > 1e-3
    assert big.sum(0).min() > 100
    for k in range(3):
        np.testing.assert_allclose(gyro[big[:, k], k] / true[big[:, k], k], scale[k], rtol=1e-12)
    # with noise: the reading is scale * true + the run's own noise (the scale does not touch the noise)
    noisy = simulate(experiment([{"name": "gyro_scale", "scale": scale}], noise=True, rig__imu=imu))
    plain = simulate(experiment(noise=True, rig__imu=imu))
    np.testing.assert_allclose(noisy.sensors.imu.data[:, :3] - plain.sensors.imu.data[:, :3],
                               true * (np.array(scale) - 1), atol=1e-15)
    np.testing.assert_array_equal(noisy.sensors.imu.data[:, 3:], plain.sensors.imu.data[:, 3:])


# --- structural_mode -------------------------------------------------------------------------

@pytest.mark.parametrize("sensor", ["imu", "load_cells"])
def test_structural_mode_rings_at_its_frequency(sensor):
    f_mode = 7.5
    mode = {"name": "structural_mode", "sensor": sensor, "frequency": f_mode, "damping_ratio": 0.03}
    kw = dict(duration=10.0, excitation=KNOCK, cable_model=DAMPED_CABLES)
    rigid, ringing = simulate(experiment(**kw)), simulate(experiment([mode], **kw))
    if sensor == "imu":
        diff = ringing.sensors.imu.data - rigid.sensors.imu.data
        np.testing.assert_array_equal(cells(ringing), cells(rigid))
    else:
        diff = cells(ringing) - cells(rigid)
        np.testing.assert_array_equal(ringing.sensors.imu.data, rigid.sensors.imu.data)
    assert np.abs(diff).max(0).min() > 0
    # above the rig's pendulum modes (< 1.5 Hz; there G ≈ (f / f_mode)² of a large swing)
    np.testing.assert_allclose(peak_frequency(diff, 200.0, low=3.0), f_mode, atol=0.2)
    # participation 0: the rigid readings, bit for bit
    still = simulate(experiment([dict(mode, participation=0.0)], **kw))
    np.testing.assert_array_equal(still.sensors.imu.data, rigid.sensors.imu.data)
    np.testing.assert_array_equal(cells(still), cells(rigid))


@pytest.mark.parametrize("rate", [200.0, 1000.0])
def test_structural_mode_response_is_the_mount_transfer_function(rate):
    """A sinusoid u sampled at 200 Hz or 1 kHz: once the start's ringing has decayed the
    response is e = p G(jω) u, G(s) = −s² / (s² + 2ζω_n s + ω_n²), below, at and above the mode."""
    fn, zeta, p = 8.0, 0.05, 1.5
    mode = experiment([{"name": "structural_mode", "sensor": "imu", "frequency": fn, "damping_ratio": zeta,
                        "participation": p}]).effects[0]
    t = np.arange(int(12 * rate) + 1) / rate
    late = t > 6.0                                        # ringing decays as exp(−ζ ω_n t): 1e-5 by 6 s
    for f in (1.05, 7.7, 20.0):
        u = np.column_stack([np.sin(2 * np.pi * f * t + 0.3), 2.0 * np.cos(2 * np.pi * f * t)])
        e = mode_response(t, u, mode)
        s = 2j * np.pi * f
        G = -s ** 2 / (s ** 2 + 2 * zeta * 2 * np.pi * fn * s + (2 * np.pi * fn) ** 2)
        np.testing.assert_allclose(tone(e[late], t[late], f) / tone(u[late], t[late], f), p * G, rtol=1e-4)


def test_structural_mode_does_not_depend_on_the_sensor_rate():
    """The mount's response sampled at 200 Hz equals the one sampled at 1 kHz within 0.2 % of
    its amplitude (the cubic spline's error on the 10–16 Hz cable-mode ringing and at the
    spin-up's end, where the force has a kink)."""
    mode = {"name": "structural_mode", "sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03}
    fast = {"imu": 1000.0, "load_cells": 1000.0, "exciter": 1000.0, "inclinometer": 50.0}
    rigid = simulate(experiment(duration=6.0))
    res = simulate(experiment([mode], duration=6.0))
    res_fast = simulate(experiment([mode], duration=6.0, sensors__rates_hz=fast))
    np.testing.assert_allclose(res_fast.sensors.imu.t[::5], res.sensors.imu.t)
    e, e_fast = res.sensors.imu.data - rigid.sensors.imu.data, res_fast.sensors.imu.data[::5] - rigid.sensors.imu.data
    assert np.abs(e).max(0).min() > 0
    assert np.all(np.abs(e_fast - e).max(0) < 2e-3 * np.abs(e).max(0))


# --- compliant_body ------------------------------------------------------------------------

def steiner(m, d):
    return m * (d @ d * np.eye(3) - np.outer(d, d))


def whole_body_check(exp, res):
    """The compliant_body split in truth.yaml recombines to the experiment's mass, CG and
    inertia (plus the static dummy's point mass, which the frame carries)."""
    cb = res.truth["simulator"]["compliant_body"]
    ms, mf = cb["sprung_mass"], cb["frame_mass"]
    cs, cf = np.array(cb["sprung_cg"]), np.array(cb["frame_cg"])
    m, c, J0 = exp.mass, exp.cg, exp.inertia
    if exp.static is not None and exp.static.kind == "dummy":
        dm = exp.rig.dummy_mass
        m = exp.mass + dm.mass
        c = (exp.mass * exp.cg + dm.mass * dm.position) / m
        J0 = J0 + steiner(exp.mass, exp.cg - c) + steiner(dm.mass, dm.position - c)
    assert ms + mf == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose((ms * cs + mf * cf) / (ms + mf), c, atol=1e-12)

    def tensor(d):
        return np.array([[d["ixx"], d["ixy"], d["ixz"]], [d["ixy"], d["iyy"], d["iyz"]],
                         [d["ixz"], d["iyz"], d["izz"]]])

    J = (tensor(cb["sprung_inertia_about_cg"]) + tensor(cb["frame_inertia_about_cg"])
         + steiner(ms, cs - c) + steiner(mf, cf - c))
    np.testing.assert_allclose(J, J0, atol=1e-9 * np.abs(J0).max())
    for key in ("sprung_inertia_about_cg", "frame_inertia_about_cg"):
        p = np.linalg.eigvalsh(tensor(cb[key]))
        assert p[0] > 0 and p[0] + p[1] >= p[2]


@pytest.mark.parametrize("static", [None, "dummy"])
def test_compliant_body_at_rest_is_the_rigid_equilibrium(static):
    exp = experiment([COMPLIANT], duration=2.0, excitation={})
    if static:
        exp = exp.with_overrides(static=static, duration=2.0)
    res = simulate(exp)
    rigid = simulate(experiment(duration=2.0, excitation={}).with_overrides(static=static, duration=2.0)
                     if static else experiment(duration=2.0, excitation={}))
    assert res.truth["effects"] == [COMPLIANT]
    whole_body_check(exp, res)
    st = res.states
    assert np.abs(st.suspension).max() < 1e-10           # the sprung body sits at its nominal place
    # at rest to the integrator's tolerance (COMPLIANT_RTOL 1e-9 on a 36-state system): measured
    # 0.7-14 nm/s and nrad/s over 2 s depending on the BLAS build, against 1e-4 rad/s of gyro noise
    assert np.abs(st.velocity).max() < 1e-7 and np.abs(st.omega).max() < 1e-7
    np.testing.assert_allclose(st.position, rigid.states.position, atol=1e-9)
    assert (st.rotation * rigid.states.rotation.inv()).magnitude().max() < 1e-10
    # tensions to the integrator's tolerance on the stiff cables: k · COMPLIANT_ATOL = 5e6 N/m · 1e-11 m
    # = 5e-5 N per step (seen: 8e-5 N), against 0.5 N of load-cell noise
    np.testing.assert_allclose(st.tensions, rigid.states.tensions, rtol=0, atol=1e-3)
    np.testing.assert_allclose(res.sensors.imu.data, rigid.sensors.imu.data, atol=1e-6)   # 1e-7 g
    np.testing.assert_allclose(res.sensors.inclinometer.data, rigid.sensors.inclinometer.data, atol=1e-12)
    # the load cells carry the whole weight (with the dummy's)
    mass = exp.mass + (exp.rig.dummy_mass.mass if static else 0.0)
    R = st.rotation.as_matrix()[-1]
    P = st.position[-1] + exp.rig.body_anchors @ R.T
    u = (exp.rig.ceiling_anchors - P) / np.linalg.norm(exp.rig.ceiling_anchors - P, axis=1)[:, None]
    np.testing.assert_allclose(st.tensions[-1] @ u, [0, 0, mass * exp.rig.gravity], rtol=1e-9, atol=1e-6)
    if not static:
        _, rot, T = equilibrium(exp.rig, exp.mass, exp.cg, exp.cable_model)
        np.testing.assert_allclose(st.tensions[-1], T, rtol=1e-9)


@pytest.mark.parametrize("variant,tolerance", [("tiny_share", 2e-3), ("stiff", 1e-2)])
def test_compliant_body_tends_to_the_rigid_body(variant, tolerance):
    """1e-4 of the mass sprung, or a 60 Hz suspension: the readings are the rigid body's within
    0.2 % resp. 1 % of their swing (the stiff suspension still shifts the 9–16 Hz cable modes
    the spin-up sets ringing by ~(f_cable / 60 Hz)² · share / 2)."""
    eff = (dict(COMPLIANT, mass_share=1e-4) if variant == "tiny_share" else
           dict(COMPLIANT, frequencies=[60.0, 60.0, 60.0], lock_frequency=60.0, damping_ratio=0.3))
    rigid = simulate(experiment(duration=4.0))
    res = simulate(experiment([eff], duration=4.0))
    for a, b in ((res.sensors.imu.data, rigid.sensors.imu.data), (cells(res), cells(rigid))):
        swing = np.abs(b - b.mean(0)).max(0)
        assert np.all(np.abs(a - b).max(0) < tolerance * swing), np.abs(a - b).max(0) / swing
    assert np.abs(rigid.sensors.imu.data[:, :3]).max() > 0.01
    # and the compliance is seen: with the bench's suspension the same readings differ by far more
    soft = simulate(experiment([COMPLIANT], duration=4.0))
    gyro = rigid.sensors.imu.data[:, :3]
    assert np.abs(soft.sensors.imu.data[:, :3] - gyro).max() > 0.1 * np.abs(gyro).max()


def test_compliant_body_modes_with_the_frame_held_are_the_stated_frequencies():
    """The sprung body's linearised modes with the frame held at its rest pose (the joint's
    forces differentiated numerically): roll, pitch, heave at the stated frequencies (up to
    the coupling by the sprung tensor's products of inertia, here 0.2 %), x, y, yaw at the
    lock frequency (25 Hz)."""
    res = simulate(experiment([COMPLIANT], duration=0.1, excitation={}))
    sus = res.model.suspension
    y0 = res.trajectory(np.array([0.0]))[0]
    frame = (y0[0:3], y0[3:12].reshape(3, 3), y0[12:15], y0[15:18])

    def accelerations(x):
        """Sprung linear (world) and angular (its axes) acceleration at position offset x[:3]
        (world, m) and attitude turned by x[3:] (its axes, rad), at rest."""
        y = y0.copy()
        y[18:21] += x[:3]
        y[21:30] = (y0[21:30].reshape(3, 3) @ Rotation.from_rotvec(x[3:]).as_matrix()).ravel()
        return sus.coupling(y, *frame)[2][12:18]

    assert np.abs(accelerations(np.zeros(6))).max() < 1e-9        # the pre-load holds it at rest
    eps = 1e-7
    D = np.column_stack([(accelerations(eps * e) - accelerations(-eps * e)) / (2 * eps) for e in np.eye(6)])
    f = np.sort(np.sqrt(np.linalg.eigvals(-D).real)) / (2 * np.pi)
    np.testing.assert_allclose(f[:3], sorted(COMPLIANT["frequencies"]), rtol=3e-3)
    np.testing.assert_allclose(f[3:], 25.0, rtol=3e-3)


def test_compliant_body_rings_at_its_roll_pitch_heave_frequencies():
    """A small sprung share (5 %), undamped: the frame hardly moves at the suspension's
    frequencies, so after a knock the sprung body's motion relative to the frame rings at the
    stated roll, pitch and heave frequencies.  The frequencies are away from the rig's own
    modes (0.85, 1.18, 2.78 Hz and 9–11 Hz: near one the two would repel), and the cables are
    damped (30 %) so that its stretch modes do not ring."""
    freqs = [1.6, 1.9, 2.2]
    eff = dict(COMPLIANT, mass_share=0.05, frequencies=freqs, damping_ratio=0.0)
    res = simulate(experiment([eff], duration=20.0, excitation=KNOCK, cable_model=DAMPED_CABLES,
                              sensors__rates_hz={"imu": 50.0, "load_cells": 50.0, "exciter": 50.0,
                                                 "inclinometer": 50.0}))
    rel = res.states.suspension                          # δ (frame axes, m), rotation vector (rad)
    found = peak_frequency(rel[:, [3, 4, 2]], 50.0, low=0.9)
    np.testing.assert_allclose(found, freqs, rtol=0.03)
    assert np.abs(rel[:, 3:5]).max() > 1e-5 and np.abs(rel[:, 2]).max() > 1e-6


def test_compliant_body_conserves_energy_and_momentum():
    """No damping anywhere: total energy (both bodies' kinetic and gravity energy, cable and
    suspension springs) stays constant; and the joint's forces are internal: the cables and
    the weights give the two bodies' momentum and angular momentum (about the world origin)
    their rates of change."""
    eff = dict(COMPLIANT, damping_ratio=0.0, lock_damping_ratio=0.0)
    exp = experiment([eff], duration=5.0, excitation={}, rig__body__center_of_gravity=[0.05, -0.1, 0.2],
                     cable_model={"type": "spring", "stiffness": 5.0e6, "damping": 0.0},
                     initial={"equilibrium": True, "displacement": {"position": [0.05, -0.03, 0.01],
                                                                    "rpy": [0.04, -0.03, 0.05]}})
    res = simulate(exp)
    model, sus = res.model, res.model.suspension
    t = np.linspace(0.0, 5.0, 401)
    Y = res.trajectory(t)
    R = Y[:, 3:12].reshape(-1, 3, 3)
    w = Y[:, 15:18]
    kinetic = 0.5 * model.m * (Y[:, 12:15] ** 2).sum(1) + 0.5 * np.einsum("ki,ij,kj->k", w, model.J, w)
    gravity = model.m * exp.rig.gravity * Y[:, 2]
    P = Y[:, None, 0:3] + np.einsum("kij,nj->kni", R, model.r)
    stretch = np.maximum(np.linalg.norm(model.A - P, axis=2) - model.L, 0.0)
    cables = 0.5 * (exp.cable_model.stiffness * stretch ** 2).sum(1)
    E = kinetic + gravity + cables + sus.energy(Y)
    swing = kinetic + 0.5 * sus.m * (Y[:, 30:33] ** 2).sum(1)
    assert swing.max() > 10.0 and np.abs(res.states.suspension[:, 2]).max() > 1e-4
    assert np.abs(E - E[0]).max() < 1e-6 * swing.max()
    # momentum balance with the accelerations of the equations of motion
    g = np.array([0.0, 0.0, -exp.rig.gravity])
    for k in range(5, 400, 20):
        y, dy = Y[k], model.rhs(t[k], Y[k])
        T = res.model.evaluate_one(t[k], y)[1]
        u = (model.A - P[k]) / np.linalg.norm(model.A - P[k], axis=1)[:, None]
        F = T[:, None] * u
        force = F.sum(0) + (model.m + sus.m) * g
        torque = np.cross(P[k], F).sum(0) + np.cross(y[0:3], model.m * g) + np.cross(y[18:21], sus.m * g)
        dp = model.m * dy[12:15] + sus.m * dy[30:33]
        dL = np.zeros(3)
        for o, m, J in ((0, model.m, model.J), (18, sus.m, sus.J)):   # d/dt [m p × v + R J ω]
            Rb, wb = y[o + 3:o + 12].reshape(3, 3), y[o + 15:o + 18]
            dL += m * np.cross(y[o:o + 3], dy[o + 12:o + 15]) + Rb @ (J @ dy[o + 15:o + 18] + np.cross(wb, J @ wb))
        np.testing.assert_allclose(dp, force, atol=1e-9 * np.abs(F).sum())
        np.testing.assert_allclose(dL, torque, atol=1e-9 * np.abs(F).sum() * 10)


def test_compliant_body_on_inextensible_cables():
    """The KKT cable model takes the joint's forces like any external force: the cables keep
    their lengths, and cables + exciter + weights accelerate the two bodies' masses."""
    exp = experiment([COMPLIANT], duration=3.0, cable_model={"type": "inextensible"})
    res = simulate(exp)
    model, sus = res.model, res.model.suspension
    t = np.linspace(0.5, 3.0, 11)
    Y = res.trajectory(t)
    R = Y[:, 3:12].reshape(-1, 3, 3)
    P = Y[:, None, 0:3] + np.einsum("kij,nj->kni", R, model.r)
    np.testing.assert_allclose(np.linalg.norm(model.A - P, axis=2), np.tile(model.L, (len(t), 1)), atol=1e-9)
    assert np.abs(res.states.suspension[:, 3:5]).max() > 1e-3          # the sprung body rocks in the frame
    for k in range(len(t)):
        dy, T, exciter = model.evaluate_one(t[k], Y[k])
        u = (model.A - P[k]) / np.linalg.norm(model.A - P[k], axis=1)[:, None]
        f_exc = R[k] @ exp.rig.exciter.rotation.as_matrix() @ np.append(exciter, 0.0)
        force = T @ u + f_exc + np.array([0.0, 0.0, -exp.mass * exp.rig.gravity])
        np.testing.assert_allclose(model.m * dy[12:15] + sus.m * dy[30:33], force, atol=1e-9 * T.sum())


def test_split_body_keeps_the_whole_body_and_rejects_an_impossible_split():
    exp = experiment([COMPLIANT])
    sprung, rest = split_body(exp.mass, exp.cg, exp.inertia, exp.effects[0])
    assert sprung.mass == pytest.approx(0.68 * exp.mass)
    assert 0 < sprung.cg[2] - exp.cg[2] <= 0.2                    # raised (at most 0.2 m)
    np.testing.assert_allclose(sprung.cg[:2], exp.cg[:2])
    with pytest.raises(ExperimentError, match=r"bad.yaml: effects\[0\].sprung_cg"):
        experiment_from_dict(dict(yaml.safe_load(DEFAULT.read_text()),
                                  effects=[dict(COMPLIANT, sprung_cg=[0.0, 0.0, 1.5])]), "bad.yaml")


# --- the bench's parameter dictionaries on random rigs ------------------------------------------

@pytest.mark.parametrize("effects", [
    [COMPLIANT],
    [{"name": "gyro_bias_drift", "random_walk": 1e-4}, {"name": "gyro_scale", "scale": [1.0, 1.005, 1.0]}],
    [{"name": "structural_mode", "sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03}],
], ids=["compliant_body", "gyro_drift_scale", "structural_mode"])
def test_bench_effects_simulate_on_a_random_rig(effects):
    d, sim = simulate_random(7000, 4, "splayed", effects, 4.0)
    assert [e["name"] for e in sim.truth["effects"]] == [e["name"] for e in effects]
    assert sim.truth["mass"] == d["rig"]["body"]["mass"]
    assert np.all(np.isfinite(sim.sensors.imu.data))


# --- parse errors ----------------------------------------------------------------------------

@pytest.mark.parametrize("effect,field", [
    ({"name": "gyro_bias_drift"}, "needs the parameter random_walk"),
    ({"name": "gyro_bias_drift", "random_walk": -1e-4}, "effects[0].random_walk"),
    ({"name": "gyro_scale", "scale": [1.0, 1.0]}, "effects[0].scale"),
    ({"name": "gyro_scale", "scale": [1.0, 0.0, 1.0]}, "effects[0].scale"),
    ({"name": "structural_mode", "sensor": "gps", "frequency": 8.0, "damping_ratio": 0.03}, "effects[0].sensor"),
    ({"name": "structural_mode", "sensor": "imu", "frequency": 0.0, "damping_ratio": 0.03}, "effects[0].frequency"),
    ({"name": "structural_mode", "sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03, "gain": 2},
     "effects[0].gain"),
    ({"name": "structural_mode", "sensor": "imu", "frequency": 8.0}, "needs the parameter damping_ratio"),
    (dict(COMPLIANT, mass_share=1.2), "effects[0].mass_share"),
    (dict(COMPLIANT, frequencies=[1.6, 1.3]), "effects[0].frequencies"),
    (dict(COMPLIANT, damping_ratio=[0.2, 0.2]), "effects[0].damping_ratio"),
    (dict(COMPLIANT, damping_ratio=-0.1), "effects[0].damping_ratio"),
    (dict(COMPLIANT, sprung_cg=[0.0, 0.0]), "effects[0].sprung_cg"),
    (dict(COMPLIANT, sprung_inertia_share=1.0), "effects[0].sprung_inertia_share"),
    (dict(COMPLIANT, stiffness=1e5), "effects[0].stiffness"),
    ({"name": "pivot_friction"}, "needs the parameter mu_r"),
    ({"name": "pivot_friction", "mu_r": -1e-3}, "effects[0].mu_r"),
    ({"name": "pivot_friction", "mu_r": 1e-3, "velocity_scale": 0.0}, "effects[0].velocity_scale"),
])
def test_effect_parameter_errors_name_the_field(effect, field):
    d = yaml.safe_load(DEFAULT.read_text())
    d["effects"] = [effect]
    with pytest.raises(ExperimentError) as e:
        experiment_from_dict(d, "bad.yaml")
    assert "bad.yaml" in str(e.value) and field in str(e.value)


def test_pivot_friction_needs_spring_cables():
    """The pins' friction grows with the tensions, which inextensible cables solve for from the
    accelerations: an experiment with both is refused, naming the file and the cable model."""
    d = yaml.safe_load(DEFAULT.read_text())
    d["effects"] = [{"name": "pivot_friction", "mu_r": 1e-3}]
    experiment_from_dict(d, "good.yaml")
    d["cable_model"] = {"type": "inextensible"}
    with pytest.raises(ExperimentError, match=r"bad.yaml: effects: pivot_friction needs spring cables"):
        experiment_from_dict(d, "bad.yaml")


def test_compliant_body_damping_ratio_may_be_per_axis():
    exp = experiment([dict(COMPLIANT, damping_ratio=[0.1, 0.2, 0.3])], duration=0.5)
    res = simulate(exp)
    sus = res.model.suspension
    z = sus.c_r / (2 * np.sqrt(sus.k_r * np.diag(sus.J)))
    np.testing.assert_allclose(z[:2], [0.1, 0.2])
    np.testing.assert_allclose(sus.c_t[2] / (2 * np.sqrt(sus.k_t[2] * sus.m)), 0.3)
    np.testing.assert_allclose(np.sqrt(sus.k_r[:2] / np.diag(sus.J)[:2]) / (2 * np.pi), [1.6, 1.3])
    np.testing.assert_allclose(np.sqrt(sus.k_t[2] / sus.m) / (2 * np.pi), 2.2)


def test_structural_mode_once_per_sensor():
    imu = {"name": "structural_mode", "sensor": "imu", "frequency": 8.0, "damping_ratio": 0.03}
    both = experiment([imu, dict(imu, sensor="load_cells", frequency=7.0)], duration=1.0)
    assert [e.get("sensor") for e in both.effects] == ["imu", "load_cells"]
    d = yaml.safe_load(DEFAULT.read_text())
    d["effects"] = [imu, dict(imu, frequency=9.0)]
    with pytest.raises(ExperimentError, match=r"bad.yaml: effects\[1\]: structural_mode of sensor imu listed twice"):
        experiment_from_dict(d, "bad.yaml")


def test_the_unbalances_inertial_force_is_the_eccentric_masss_acceleration_in_the_turning_body():
    # a mass at e û(t) from the exciter axis, û spinning at Ω about ẑ in a body turning with ω(t):
    # its world acceleration less the axis point's, by second differences of the positions, in body
    # axes, is e[α × û + ω × (ω × û) + 2 Ω ω × (ẑ × û) − Ω² û]; bearing_inertial_force is −m_u e times
    # all but the spin's own centripetal term (which the exciter's force is)
    e, m_u, spin = 0.34, 3.7, 7.85
    z = np.array([0.2, -0.1, 1.0]) / np.linalg.norm([0.2, -0.1, 1.0])
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    axis = np.array([2.4, -0.85, -0.35])                    # the exciter axis's point, body m

    def rotvec(t):                                          # the body's attitude, a smooth tumble
        return np.array([0.03 * math.sin(1.3 * t), 0.05 * math.sin(0.7 * t + 0.4), 0.02 * t + 0.04 * math.cos(2.1 * t)])

    def u(t):
        return math.cos(spin * t) * x + math.sin(spin * t) * y

    def mass(t):                                            # world position of the mass less the axis point's
        return Rotation.from_rotvec(rotvec(t)).apply(axis + e * u(t)) - Rotation.from_rotvec(rotvec(t)).apply(axis)

    t, h = 0.9, 1e-4
    acc = (mass(t + h) - 2 * mass(t) + mass(t - h)) / h ** 2
    R = Rotation.from_rotvec(rotvec(t))
    # the body's angular velocity and acceleration, body axes, by differences of the attitude
    w_of = [(Rotation.from_rotvec(rotvec(s - 1e-6)).inv() * Rotation.from_rotvec(rotvec(s + 1e-6))).as_rotvec() / 2e-6
            for s in (t - h, t, t + h)]
    w, alpha = w_of[1], (w_of[2] - w_of[0]) / (2 * h)
    relative = R.inv().apply(acc) + e * spin ** 2 * u(t)     # the spin's own centripetal term taken out
    f = bearing_inertial_force(m_u * e, u(t), z, spin, w, alpha)           # the unbalance m_u e, kg·m
    np.testing.assert_allclose(f, -m_u * relative, rtol=2e-3, atol=1e-6 * m_u * e * spin ** 2)
    assert np.linalg.norm(f) > 0.05                          # the Coriolis term: 2 m_u e Ω |ω| ~ 1 N here
