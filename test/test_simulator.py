"""Physics tests of the ROS-free simulator (rig_identification.model.simulator) and of rig-sim.

Every check recomputes the physics independently from the simulator's outputs (poses,
sensor streams, rig geometry) instead of comparing with stored numbers, and validates the
simulator against the independent reference recordings in /work/shared/recordings.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import recording
from scipy.spatial.transform import Rotation

from rig_identification.cli.sim import sim_main
from rig_identification.io.quality import white_sigma
from rig_identification.io.recording import read_recording
from rig_identification.io.rig import inertia_tensor, load_rig
from rig_identification.model.cables import CableModel
from rig_identification.model.equilibrium import equilibrium
from rig_identification.model.experiment import ExperimentError, experiment_from_dict, load_experiment
from rig_identification.model.rigid_body import SimulationError
from rig_identification.model.simulator import simulate

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "config" / "rigs" / "default.yaml"
CASES = sorted((ROOT / "config" / "cases").glob("case*.yaml"))


def default_dict() -> dict:
    return yaml.safe_load(DEFAULT.read_text())


def experiment(changes: dict | None = None, base: dict | None = None, source: str = "test.yaml"):
    """The default experiment with top-level (or nested via 'a.b' keys) fields replaced."""
    d = copy.deepcopy(base if base is not None else default_dict())
    for key, value in (changes or {}).items():
        *path, last = key.split(".")
        node = d
        for k in path:
            node = node[k]
        node[last] = value
    return experiment_from_dict(d, source)


def body_frame(exp, states):
    """(p_cg (K, 3), R (K, 3, 3), v_cg (K, 3)) from the states (which give the body origin)."""
    R = Rotation.from_quat(states.quaternion).as_matrix()
    c = exp.cg
    p_cg = states.position + R @ c
    v_cg = states.velocity + np.einsum("kij,kj->ki", R, np.cross(states.omega, c))
    return p_cg, R, v_cg


def cable_directions(exp, p_origin, R):
    """Unit vectors body anchor -> ceiling anchor (K, N, 3), lengths (K, N), anchors (K, N, 3)."""
    P = p_origin[:, None, :] + np.einsum("kij,nj->kni", R, exp.rig.body_anchors)
    d = exp.rig.ceiling_anchors[None] - P
    l = np.linalg.norm(d, axis=2)
    return d / l[..., None], l, P


# --- (1) equilibrium ---------------------------------------------------------------------

@pytest.mark.parametrize("model", ["spring", "inextensible"])
def test_equilibrium_balances_forces_and_moments(model):
    # a body frame whose origin is not the CG, to exercise the position convention
    exp = experiment({"rig.body.center_of_gravity": [0.05, -0.1, 0.2]})
    cables = exp.cable_model if model == "spring" else CableModel.inextensible()
    p, rot, T = equilibrium(exp.rig, exp.mass, exp.cg, cables)
    R = rot.as_matrix()
    P = p + exp.rig.body_anchors @ R.T
    d = exp.rig.ceiling_anchors - P
    l = np.linalg.norm(d, axis=1)
    u = d / l[:, None]
    p_cg = p + R @ exp.cg
    force = (T[:, None] * u).sum(0) + exp.mass * np.array([0, 0, -exp.rig.gravity])
    moment = np.cross(P - p_cg, T[:, None] * u).sum(0)
    assert np.abs(force).max() < 1e-6 and np.abs(moment).max() < 1e-6
    assert np.all(T > 0)
    if model == "spring":
        np.testing.assert_allclose(T, cables.stiffness * (l - exp.rig.cable_lengths), rtol=1e-9)
    else:
        np.testing.assert_allclose(l, exp.rig.cable_lengths, atol=1e-10)


@pytest.mark.parametrize("model", ["spring", "inextensible"])
def test_body_at_rest_stays_at_rest(model):
    changes = {"excitation": {}, "duration": 5.0, "sensors.noise": {}}
    if model == "inextensible":
        changes["cable_model"] = {"type": "inextensible"}
    res = simulate(experiment(changes))
    s = res.states
    assert np.abs(s.velocity).max() < 1e-9 and np.abs(s.omega).max() < 1e-9
    assert np.abs(s.position - s.position[0]).max() < 1e-9
    assert np.abs(s.tensions - s.tensions[0]).max() < 1e-5


# --- (2) energy conservation ------------------------------------------------------------------

def energy(exp, states):
    """Kinetic + gravity + spring energy (K,), J; spring energy is 0 for inextensible cables."""
    p_cg, R, v_cg = body_frame(exp, states)
    w = states.omega
    kinetic = 0.5 * exp.mass * (v_cg ** 2).sum(1) + 0.5 * np.einsum("ki,ij,kj->k", w, exp.inertia, w)
    gravity = exp.mass * exp.rig.gravity * p_cg[:, 2]
    spring = 0.0
    if exp.cable_model.type == "spring":
        _, l, _ = cable_directions(exp, states.position, R)
        stretch = np.maximum(l - exp.rig.cable_lengths, 0.0)
        spring = 0.5 * (exp.cable_model.stiffness * stretch ** 2).sum(1)
    return kinetic + gravity + spring, kinetic


@pytest.mark.parametrize("model", ["spring", "inextensible"])
def test_energy_is_conserved_without_damping(model):
    cables = {"type": "spring", "stiffness": 5.0e6, "damping": 0.0} if model == "spring" else {"type": "inextensible"}
    exp = experiment({"cable_model": cables, "excitation": {}, "duration": 20.0, "sensors.noise": {},
                      "rig.body.center_of_gravity": [0.05, -0.1, 0.2],      # body origin != CG
                      "sensors.rates_hz": {"imu": 50, "load_cells": 50, "exciter": 50, "inclinometer": 50},
                      "initial": {"equilibrium": True, "displacement": {"position": [0.05, -0.03, 0.0],
                                                                        "rpy": [0.04, -0.03, 0.05]}}})
    res = simulate(exp)
    E, kinetic = energy(exp, res.states)
    assert kinetic.max() > 1.0                      # it really swings (J)
    assert np.abs(E - E[0]).max() < 1e-6 * kinetic.max()
    if model == "inextensible":
        _, l, _ = cable_directions(exp, res.states.position, res.states.rotation.as_matrix())
        assert np.abs(l - exp.rig.cable_lengths).max() < 1e-8


def test_absolute_initial_pose_is_projected_onto_the_cables():
    base = yaml.safe_load((ROOT / "config/cases/case08.yaml").read_text())
    pose = base["initial"]["pose"]
    for cables in ({"type": "spring", "stiffness": 5.0e6}, {"type": "inextensible", "compression": True}):
        exp = experiment({"cable_model": cables, "duration": 0.1}, base)
        st = simulate(exp).states
        _, l, _ = cable_directions(exp, st.position[:1], st.rotation.as_matrix()[:1])
        if cables["type"] == "spring":     # every cable starts at its equilibrium tension
            _, _, T_eq = equilibrium(exp.rig, exp.mass, exp.cg, exp.cable_model)
            np.testing.assert_allclose(st.tensions[0], T_eq, rtol=1e-9)
        else:
            np.testing.assert_allclose(l[0], exp.rig.cable_lengths, atol=1e-12)
        np.testing.assert_allclose(st.position[0], pose["cg_position"], atol=2e-3)
        rel = st.rotation[0] * Rotation.from_euler("xyz", pose["rpy"]).inv()
        assert rel.magnitude() < 2e-3
        assert np.abs(st.velocity[0]).max() == 0 and np.abs(st.omega[0]).max() == 0


# --- (3) sensors at rest -----------------------------------------------------------------

@pytest.mark.parametrize("imu_rpy,imu_pos,incl_rpy", [
    ([0, 0, 0], [0, 0, 0], [0, 0, 0]),
    ([0.3, -1.2, 2.0], [0.4, -0.2, 0.3], [0.1, -0.05, 0.7]),
])
def test_sensors_at_rest(imu_rpy, imu_pos, incl_rpy):
    exp = experiment({"excitation": {}, "duration": 1.0, "sensors.noise": {},
                      "rig.imu": {"position": imu_pos, "rpy": imu_rpy}, "rig.inclinometer": {"rpy": incl_rpy}})
    res = simulate(exp)
    imu = res.sensors.imu.data
    np.testing.assert_allclose(imu[:, :3], 0.0, atol=1e-9)
    R = res.states.rotation.as_matrix()
    R_imu = Rotation.from_euler("xyz", imu_rpy).as_matrix()
    f_world = np.einsum("kij,jl,kl->ki", R, R_imu, imu[:, 3:])
    np.testing.assert_allclose(f_world, np.tile([0, 0, exp.rig.gravity], (len(f_world), 1)), atol=1e-8)
    # the inclinometer samples at 50 Hz, the states at the IMU's 200 Hz
    incl = res.sensors.inclinometer
    st = res.states_at(incl.t - exp.stamp_origin)
    axes = st.rotation.as_matrix() @ Rotation.from_euler("xyz", incl_rpy).as_matrix()
    np.testing.assert_allclose(incl.data, np.arcsin(axes[:, 2, :2]), atol=1e-12)


# --- (4) Newton–Euler consistency of trajectory and sensors --------------------------------

def derivative(res, t, field, h=1e-3):
    """5-point central difference of a States field on the dense trajectory (simulation time)."""
    f = [getattr(res.states_at(t + k * h), field) for k in (-2, -1, 1, 2)]
    return (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * h)


@pytest.mark.parametrize("config,model,duration", [(DEFAULT, "spring", 6.0), (ROOT / "config/cases/case01.yaml",
                                                                               "inextensible", 6.0)])
def test_newton_euler_consistency(config, model, duration):
    base = yaml.safe_load(Path(config).read_text())
    changes = {"duration": duration, "sensors.noise": {}}
    if model == "inextensible":
        changes["cable_model"] = {"type": "inextensible"}
    exp = experiment(changes, base)
    res = simulate(exp)
    rate = exp.sensors.rates["imu"]
    assert all(exp.sensors.rates[k] == rate for k in ("load_cells", "exciter"))
    idx = np.arange(5, len(res.states.t) - 5, 7)
    t = idx / rate                                  # exact sample times (stamps - origin would round)
    edges = [b for p in exp.excitation.pulses for b in (p.start, p.end)]
    if exp.excitation.rotating is not None:
        edges += exp.excitation.rotating.breakpoints()
    smooth = np.all(np.abs(t[:, None] - np.array(edges + [-1.0])[None]) > 0.005, axis=1)  # no force step
    idx, t = idx[smooth], t[smooth]                                                        # in the stencil
    st = res.states_at(t)
    p_cg, R, _ = body_frame(exp, st)
    u, _, P = cable_directions(exp, st.position, R)
    T = np.column_stack([res.sensors.load_cells[n].data[idx, 0] for n in exp.rig.cable_names])
    F_cables = np.einsum("kn,kni->ki", T, u)
    f_exc = np.column_stack([res.sensors.exciter.data[idx], np.zeros(len(idx))])
    F_exc_body = f_exc @ exp.rig.exciter.rotation.as_matrix().T
    F_exc = np.einsum("kij,kj->ki", R, F_exc_body)
    # rotation: J dω/dt + ω × Jω = moment about the CG, body axes
    M_world = np.cross(P - p_cg[:, None, :], T[..., None] * u).sum(1)
    M = np.einsum("kji,kj->ki", R, M_world) + np.cross(exp.rig.exciter.position - exp.cg, F_exc_body)
    w, J = st.omega, exp.inertia
    lhs = derivative(res, t, "omega") @ J + np.cross(w, w @ J)
    assert np.abs(M).max() > 10.0
    assert np.abs(lhs - M).max() < 1e-6 * np.abs(M).max()
    # translation: m dv/dt = cable forces + exciter + weight, and the accelerometer (IMU at the CG)
    gravity = np.array([0, 0, -exp.rig.gravity])
    F = F_cables + F_exc + exp.mass * gravity
    acc = derivative(res, t, "velocity")
    assert np.abs(exp.mass * acc - F).max() < 1e-6 * np.abs(F_cables).max()
    f_imu = np.einsum("kij,kj->ki", R, res.sensors.imu.data[idx, 3:])
    assert np.abs(exp.mass * (f_imu + gravity) - F).max() < 1e-9 * np.abs(F_cables).max()


def test_inextensible_rejects_slack_and_indeterminate_cables():
    lift = {"pulses": [{"force": [0, 0, 40000.0], "point": [0, 0, 0], "start": 0.1, "end": 0.5, "frame": "world"}]}
    exp = experiment({"cable_model": {"type": "inextensible"}, "duration": 1.0, "excitation": lift})
    with pytest.raises(SimulationError, match="slack"):
        simulate(exp)
    # rigid two-way links may push: the lifted body is held by compression
    exp = experiment({"cable_model": {"type": "inextensible", "compression": True}, "duration": 1.0,
                      "excitation": lift, "sensors.noise": {}})
    T = simulate(exp).states.tensions
    assert T.min() < -1000.0
    d = default_dict()
    d["rig"]["cables"] += [dict(c, name=c["name"] + "b") for c in d["rig"]["cables"]]
    d["cable_model"] = {"type": "inextensible"}
    with pytest.raises(ExperimentError, match="cable_model.type"):
        experiment_from_dict(d, "eight.yaml")


# --- config files ---------------------------------------------------------------------------

@pytest.mark.parametrize("path", CASES, ids=[p.stem for p in CASES])
def test_case_configs(path):
    exp = load_experiment(path)
    n = int(path.stem[4:])
    assert exp.name == f"case{n:02d}"
    assert len(exp.thesis["initial_guess"]) == 6 and exp.thesis["sampling"] == 0.01
    assert exp.thesis["duration"] == exp.duration and set(exp.sensors.rates.values()) == {100.0}
    assert all(v == 0 for v in exp.sensors.noise.values())
    L = exp.rig.cable_lengths
    if n <= 9:
        cg0 = np.array([2, 2.5, -2.5616])
        assert np.allclose(L, 2.5)
    else:
        cg0 = np.array(exp.thesis["initial_cg_position"])
    np.testing.assert_allclose(np.linalg.norm(exp.rig.ceiling_anchors - (cg0 + exp.rig.body_anchors), axis=1), L,
                               atol=1e-4 if n <= 9 else 1e-12)
    assert np.all(np.linalg.eigvalsh(exp.inertia) > 0)
    if exp.thesis["reported_inertia"] is not None:
        assert np.shape(exp.thesis["reported_inertia"]) == (3, 3)
        assert np.shape(exp.thesis["reported_error_percent"]) == (3, 3)


def test_case16_geometry_matches_reference_rig():
    ref = load_rig(recording("visible_case16_clean") / "rig.yaml")
    for path in (ROOT / "config/cases/case16.yaml", DEFAULT):
        rig = load_experiment(path).rig
        assert rig.cable_names == ref.cable_names
        np.testing.assert_allclose(rig.cable_lengths, ref.cable_lengths, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rig.ceiling_anchors, ref.ceiling_anchors)
        np.testing.assert_allclose(rig.body_anchors, ref.body_anchors)
        np.testing.assert_allclose(rig.exciter.position, ref.exciter.position)


@pytest.mark.parametrize("changes,field", [
    ({"inertia_about_cg.ixx": -1.0}, "inertia_about_cg"),
    ({"cable_model": {"type": "rope"}}, "cable_model.type"),
    ({"excitation.rotating.frequency": "fast"}, "excitation.rotating.frequency"),
    ({"sensors.rates_hz": {"imu": 0}}, "sensors.rates_hz.imu"),
    ({"initial": {"pose": {"rpy": [0, 0, 0]}}}, "initial.pose.cg_position"),
    ({"duration": None}, "duration"),
    ({"colour": "red"}, "colour"),
    ({"rig.body.mass": "heavy"}, "body.mass"),
])
def test_config_errors_name_file_and_field(changes, field):
    with pytest.raises(ExperimentError) as e:
        experiment(changes, source="bad.yaml")
    assert "bad.yaml" in str(e.value) and field in str(e.value)


# --- (5) rig-sim ------------------------------------------------------------------------------

def test_rig_sim_writes_a_readable_recording(tmp_path, capsys):
    out = tmp_path / "dyn"
    assert sim_main([str(DEFAULT), str(out), "--duration", "2", "--seed", "3"]) == 0
    assert "rig-sim: wrote" in capsys.readouterr().out
    rec = read_recording(out)
    exp = load_experiment(DEFAULT)
    s = rec.sensors
    assert sorted(s.load_cells) == sorted(exp.rig.cable_names)
    for series, rate in [(s.imu, 200), (s.exciter, 200), (s.inclinometer, 50)] + [(c, 200) for c in
                                                                                  s.load_cells.values()]:
        assert len(series) == 2 * rate + 1
        np.testing.assert_allclose(np.diff(series.t), 1 / rate, atol=1e-6)
        assert series.t[0] == exp.stamp_origin
    np.testing.assert_allclose(rec.rig.center_of_gravity, exp.cg)
    assert rec.truth["mass"] == exp.mass and rec.truth["effects"] == []
    np.testing.assert_allclose(inertia_tensor(rec.truth["inertia_about_cg"]), exp.inertia)
    np.testing.assert_allclose(rec.rig.cable_lengths, exp.rig.cable_lengths, atol=1e-12)


def test_rig_sim_static_recordings_and_noise(tmp_path):
    base, dummy = tmp_path / "base", tmp_path / "dummy"
    dummy_args = ["--dummy-mass", "80", "--dummy-position", "0.4", "-0.3", "0.2"]
    assert sim_main([str(DEFAULT), str(base), "--static", "baseline", "--storage", "sqlite3"] + dummy_args) == 0
    assert sim_main([str(DEFAULT), str(dummy), "--static", "dummy"] + dummy_args) == 0
    exp = load_experiment(DEFAULT)
    sigma = exp.sensors.noise
    rb, rd = read_recording(base), read_recording(dummy)
    for rec in (rb, rd):
        assert rec.rig.center_of_gravity is None
        assert rec.rig.dummy_mass.mass == 80.0           # the same rig.yaml for both
        np.testing.assert_allclose(rec.rig.dummy_mass.position, [0.4, -0.3, 0.2])
        assert len(rec.sensors.imu) == 10 * 200 + 1            # static: 10 s by default
        s = rec.sensors
        np.testing.assert_allclose(s.imu.data[:, :3].std(0), sigma["gyro"], rtol=0.1)
        np.testing.assert_allclose(s.imu.data[:, 3:].std(0), sigma["accelerometer"], rtol=0.1)
        np.testing.assert_allclose(s.exciter.data.std(0), sigma["exciter"], rtol=0.1)
        np.testing.assert_allclose(s.inclinometer.data.std(0), sigma["inclinometer"], rtol=0.15)
        for c in s.load_cells.values():
            np.testing.assert_allclose(c.data.std(), sigma["load_cell"], rtol=0.1)
        np.testing.assert_allclose(rec.truth["center_of_gravity"], exp.cg)
    # the dummy adds its weight to the cables; the two recordings have independent noise
    total = lambda rec: sum(c.data.mean() for c in rec.sensors.load_cells.values())
    assert total(rd) - total(rb) > 0.9 * 80 * exp.rig.gravity
    assert abs(np.corrcoef(rb.sensors.imu.data[:, 0], rd.sensors.imu.data[:, 0])[0, 1]) < 0.1


def test_rig_sim_reports_bad_input_without_traceback(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    d = default_dict()
    d["excitation"]["rotating"]["amplitude"] = -5
    bad.write_text(yaml.safe_dump(d))
    assert sim_main([str(bad), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "excitation.rotating.amplitude" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()
    assert sim_main([str(ROOT / "config/cases/case16.yaml"), str(tmp_path / "out"), "--static", "dummy"]) == 2
    assert "dummy_mass" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        sim_main([str(DEFAULT), str(tmp_path / "out"), "--dummy-mass", "5"])
    assert e.value.code == 2


def test_rig_sim_simulates_a_labs_rig_yaml_with_a_force_given_by_options(tmp_path, capsys):
    """``rig-sim RIG.yaml --inertia …``: the lab's own rig.yaml, its body (mass, CG) with the given
    tensor, a rotating force of the given amplitude and frequency at its exciter after the
    spin-up, the reference sensors' rates and noise.  Without --inertia the error says so and
    names the file; an experiment file refuses the options (it states its own)."""
    rig_yaml = tmp_path / "lab" / "rig.yaml"
    rig_yaml.parent.mkdir()
    rig_yaml.write_text(yaml.safe_dump(default_dict()["rig"]))
    out = tmp_path / "run"
    assert sim_main([str(rig_yaml), str(out), "--inertia", "900", "1100", "1500", "5", "-20", "10",
                     "--force", "150", "--frequency", "1.3", "--ramp", "1", "--duration", "12", "--seed", "4"]) == 0
    rec = read_recording(out)
    assert rec.truth["mass"] == load_rig(rig_yaml).mass
    assert rec.truth["inertia_about_cg"] == {"ixx": 900.0, "ixy": 5.0, "ixz": -20.0, "iyy": 1100.0, "iyz": 10.0,
                                             "izz": 1500.0}
    ex = rec.sensors.exciter
    assert len(rec.sensors.imu) == 12 * 200 + 1 and len(rec.sensors.inclinometer) == 12 * 50 + 1
    after = ex.t - ex.t[0] > 3.0
    assert np.median(np.hypot(*ex.data[after, :2].T)) == pytest.approx(150.0, abs=0.5)
    spectrum = np.abs(np.fft.rfft(ex.data[after, 0]))
    assert np.fft.rfftfreq(after.sum(), 1 / 200.0)[np.argmax(spectrum)] == pytest.approx(1.3, abs=0.1)
    assert white_sigma(ex.data[after, 0]) == pytest.approx(0.5, rel=0.2)    # the reference exciter noise
    capsys.readouterr()
    assert sim_main([str(rig_yaml), str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert str(rig_yaml) in err and "--inertia" in err and not (tmp_path / "none").exists()
    assert sim_main([str(DEFAULT), str(tmp_path / "none"), "--inertia", "1", "0", "0", "1", "0", "1"]) == 2
    assert "experiment file" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:
        sim_main([str(rig_yaml), str(tmp_path / "none"), "--force", "100"])
    assert e.value.code == 2


# --- (6) against the independent reference simulator --------------------------------------------

@pytest.mark.parametrize("folder", ["static_baseline", "static_dummy"])
def test_static_equilibrium_matches_reference(folder):
    ref = read_recording(recording("visible_case16_static") / folder)
    exp = load_experiment(ROOT / "config/cases/case16.yaml")
    mass, cg = exp.mass, exp.cg
    if folder == "static_dummy":
        dm = ref.rig.dummy_mass
        cg = (mass * cg + dm.mass * dm.position) / (mass + dm.mass)
        mass += dm.mass
    _, rot, T = equilibrium(exp.rig, mass, cg, CableModel.spring(exp.rig, mass, 5.0e6))
    R = rot.as_matrix()
    incl = np.arcsin(R[2, :2])
    np.testing.assert_allclose(incl, ref.sensors.inclinometer.data.mean(0), atol=1e-4)
    if folder == "static_baseline":
        np.testing.assert_allclose(incl, [-0.0869, -0.0165], atol=5e-4)
    np.testing.assert_allclose(T, [ref.sensors.load_cells[n].data.mean() for n in exp.rig.cable_names], atol=0.2)
    f_ref = ref.sensors.imu.data[:, 3:].mean(0)
    np.testing.assert_allclose(R.T @ [0, 0, exp.rig.gravity], f_ref, atol=2e-3)


def test_dynamic_run_matches_reference():
    ref = read_recording(recording("visible_case16_clean"))
    exp = load_experiment(DEFAULT).with_overrides(duration=60.0, noise_free=True)
    res = simulate(exp)
    t0 = exp.stamp_origin
    ours, theirs = res.sensors.imu.window(t0 + 10, t0 + 60), ref.sensors.imu.window(t0 + 10, t0 + 60)
    np.testing.assert_allclose(ours.t, theirs.t, atol=1e-6)
    rms = lambda x: np.sqrt((x ** 2).mean(0))
    np.testing.assert_allclose(rms(ours.data[:, :3]), rms(theirs.data[:, :3]), rtol=0.05)
    # same phase: the dominant gyro axis and the load cells follow the reference sample by sample
    assert np.corrcoef(ours.data[:, 1], theirs.data[:, 1])[0, 1] > 0.99
    for name in exp.rig.cable_names:
        a = res.sensors.load_cells[name].window(t0 + 10, t0 + 60).data[:, 0]
        b = ref.sensors.load_cells[name].window(t0 + 10, t0 + 60).data[:, 0]
        assert rms(a - b) < 0.02 * rms(b - b.mean())
